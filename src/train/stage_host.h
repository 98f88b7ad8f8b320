// What a stage beside the Gaussian loop (the diffusion stage,
// train/diffusion_stage.h) asks of the loop that runs it. The Trainer
// implements StageHost; a stage knows no more of it than this.
#pragma once
#include <nlohmann/json.hpp>

#include <cstdint>
#include <memory>
#include <vector>

#include "core/camera.h"
#include "core/tensor.h"
#include "io/scene/scene.h"
#include "train/checkpoint.h"
#include "train/run_config.h"
#include "train/run_folder.h"

namespace ddhgs::train {

// A distillation target: a camera between training cameras and the denoised
// render there.
struct PseudoView {
  core::Camera camera;
  torch::Tensor target;  // [H, W, N]
};

// A model trained beside the run (the denoiser's pairs, train/denoiser_pairs.h).
class AuxiliaryModel {
 public:
  virtual ~AuxiliaryModel() = default;
  // One Gaussian iteration.
  virtual void advance() = 0;
  // Its render [H, W, N] at `camera`, as measured (no autograd, no corrections).
  virtual torch::Tensor render(const core::Camera& camera) = 0;
};

class StageHost {
 public:
  virtual const RunConfig& config() const = 0;
  virtual const io::Scene& scene() const = 0;
  virtual const RunPaths& run_paths() const = 0;
  // The Gaussians, the optimizer (the denoiser's groups among them) and the
  // iteration counter.
  virtual TrainState& state() = 0;
  // The current Gaussians' render [H, W, N] of training view `view` with its
  // camera correction, if any; no autograd.
  virtual torch::Tensor render_view(int view) = 0;
  // Their render [H, W, N] at `camera`, uncorrected; no autograd.
  virtual torch::Tensor render_camera(const core::Camera& camera) = 0;
  // One Gaussian iteration (1-based) on a training view, or on `pseudo` with
  // its losses scaled by diffusion.distill_weight; returns its metrics record.
  virtual nlohmann::json step(int64_t iteration, const PseudoView* pseudo) = 0;
  // A fresh model of the run's scene trained as `config` says, quietly: its
  // training views leave `held_out` out (they become its test views), and its
  // training cameras are turned so that their images move by perturb_px
  // pixels (0: as captured).
  virtual std::unique_ptr<AuxiliaryModel> auxiliary(const RunConfig& config,
                                                    const std::vector<int>& held_out,
                                                    double perturb_px) = 0;

 protected:
  ~StageHost() = default;
};

}  // namespace ddhgs::train
