// Corrections of the training cameras' poses, learned beside the Gaussians.
//
// Structure from motion with a narrow field of view leaves poses off by a
// fraction of a degree, many pixels at 5,000 px focal length; Gaussians fitted
// to inconsistent views blur. Each training view v gets a small rotation
// about its camera centre (rotation vector r_v, radians, world axes) and a
// translation (t_v, in units of the scene extent, world axes). The renderer
// has no gradient for cameras, so the Gaussians move instead:
//   x' = R(r_v) (x - c_v) + c_v + extent t_v,   q' = q(r_v) * q,
// which is what the corrected camera would see (view-dependent colour is
// evaluated in the moved frame; a fraction of a degree does not change it).
// recentre() takes the corrections' mean over the training views out after
// every optimiser step, so the views cannot drift together away from the
// held-out views, which are rendered from their recorded poses. (Centring
// inside the forward pass instead hands every view a 1/T share of each other
// view's gradient, which Adam's per-element scaling turns into full steps:
// the corrections then wander and a known error is not recovered.)
#pragma once
#include <torch/nn/module.h>

#include <utility>
#include <vector>

#include "core/camera.h"
#include "core/tensor.h"

namespace ddhgs::train {

class CameraRefinementImpl : public torch::nn::Module {
 public:
  // views: every view of the scene (rows); train: the rows that are refined.
  CameraRefinementImpl(int64_t views, std::vector<int> train);

  // The correction of one view: rotation [3] (rad) and translation [3]
  // (extent units).
  std::pair<torch::Tensor, torch::Tensor> correction(int view) const;

  // Subtracts the mean over the training views from their corrections
  // (outside autograd); call after each optimiser step.
  void recentre();

  // means: [G, 3], quats: [G, 4] (w, x, y, z) moved for view v seen by
  // camera; differentiable in the corrections and in means and quats.
  std::pair<torch::Tensor, torch::Tensor> move(int view, const core::Camera& camera,
                                               const torch::Tensor& means,
                                               const torch::Tensor& quats, double extent) const;

  torch::Tensor rotation;     // [V, 3] radians
  torch::Tensor translation;  // [V, 3] scene extents

 private:
  torch::Tensor train_;  // [T] int64 rows
};
TORCH_MODULE(CameraRefinement);

}  // namespace ddhgs::train
