// Each capture's own light, learned beside the Gaussians.
//
// A flight's light changes between captures (a cloud over the field, the sun
// lower) in ways the irradiance sensor or the one panel capture does not see,
// so each capture's reflectance comes out off by a factor per band. Fitted as
// they are, the Gaussians would paint that factor into the scene: dark patches
// or floaters that only one capture's views explain. Each training view v
// therefore has a gain per band b it holds, exp(s_vb), that multiplies its
// render before the loss; the gain takes the capture's light and the Gaussians
// keep the flight's common reflectance. Nothing outside training applies a
// gain: held-out views, eval, render and export see the Gaussians alone.
//
// A gain common to every view is the Gaussians' to hold, so recentre() takes
// the mean log gain of each band over the training views out after every
// optimiser step (as camera_refinement.h does for poses): on average, the
// captures are lit as their calibration says. prior() pulls each view's log
// gains towards 0 (gain 1), so a gain moves only on a view's evidence.
#pragma once
#include <torch/nn/module.h>
#include <nlohmann/json.hpp>

#include <string>

#include "core/tensor.h"
#include "io/scene/scene.h"

namespace ddhgs::train {

class ExposureCorrectionImpl : public torch::nn::Module {
 public:
  // trained: [V, N] bool, whether view v is a training view that holds band b;
  // only those entries learn (the others stay at gain 1).
  explicit ExposureCorrectionImpl(const torch::Tensor& trained);

  // render: [H, W, B], view v's bands `bands` ([B] int64 indices into the N
  // bands; undefined: all N) -> render x gain, per band; differentiable in
  // both.
  torch::Tensor apply(int view, const torch::Tensor& render, const torch::Tensor& bands) const;
  // Mean squared log gain of view v's trained entries (0-d, differentiable;
  // 0 for a view without any).
  torch::Tensor prior(int view) const;
  // Subtracts each band's mean log gain over its trained entries from them
  // (outside autograd); call after each optimiser step.
  void recentre();
  // exp(log_gain), detached: [V, N].
  torch::Tensor gains() const;

  torch::Tensor log_gain;  // [V, N]

 private:
  torch::Tensor trained_;  // [V, N] float, 1 where trained
};
TORCH_MODULE(ExposureCorrection);

// The entries a scene trains: its training views' bands ([V, N] bool).
torch::Tensor trained_entries(const io::Scene& scene);

// The learned gains of the training views for train_summary.json:
// exposure_gain_min, exposure_gain_max and exposure_gains (view name -> the
// gains of the bands it holds, in scene band order).
nlohmann::json exposure_summary(const ExposureCorrectionImpl& exposure, const io::Scene& scene);
// One line for the log: the gains' range over the training views.
std::string describe_exposure(const nlohmann::json& summary);

}  // namespace ddhgs::train
