// Aligning a view's pose to its image before it is measured (`ddhgs eval
// --align-poses`).
//
// The poses of a real capture come from structure from motion and are off by
// a fraction of a pixel to a few pixels; a held-out view is then scored
// against the model seen from a slightly wrong place, and its silhouettes
// count as errors of the model. Aligning the pose first, with the Gaussians
// frozen, separates the two: the aligned figures measure the model, the
// unaligned ones the model and the pose together (they stay the headline).
//
// The correction is a rotation about the camera centre and a translation,
// applied to the Gaussians (model/rigid_motion.h), fitted by Adam to the L1
// difference between render and view, its step cosine-annealed from
// AlignOptions::step_px to zero. Both are measured in pixels so that one rate
// suits every scene: a rotation of p / f radians turns the image centre by p
// pixels, a shift of p * depth / f moves a point at the median depth of the
// Gaussians before the camera by p pixels. The result is kept only when it
// lowers the L1 difference; otherwise the recorded pose stands.
#pragma once
#include "core/tensor.h"

#include "core/camera.h"
#include "model/gaussians.h"

namespace ddhgs::eval {

struct AlignOptions {
  int steps = 300;       // Adam steps per view
  double step_px = 2.0;  // first step size, pixels; annealed to 0
};

struct AlignedView {
  torch::Tensor image;  // [H, W, N], rendered from the aligned pose
  bool moved = false;   // false: the recorded pose was kept
  // How far the correction moves the image: the mean displacement, in
  // pixels, of the centres of the Gaussians that project into the frame.
  // (Its turn and shift are not reported apart: with a narrow field of view
  // the two nearly cancel, a turn of 3 px beside a shift of 3.5 px.)
  double motion_px = 0;
  double l1_before = 0, l1_after = 0;  // mean absolute difference to the view
};

AlignedView align_view(const model::Gaussians& gaussians, const core::Camera& camera,
                       const torch::Tensor& background,  // [N]
                       const torch::Tensor& truth,       // [H, W, N]
                       const AlignOptions& options = {});

}  // namespace ddhgs::eval
