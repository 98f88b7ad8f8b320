// What the denoiser learns from and what it teaches back.
//
// Training pairs that look like novel views: the training views are split
// into interleaved folds, and a short auxiliary model trained without a fold
// renders that fold's views (train/denoiser_pairs.h). A render of a view the
// Gaussians never fitted carries the errors of a test view (interpolation
// across the gaps between cameras), which renders of fitted training views
// do not. Two cheaper sources, one auxiliary model each: the run's own
// Gaussians at an earlier iteration (under-fitted views), and a model fitted
// to the views with every camera turned a little (`turned`), rendered at the
// true poses (views it fitted only approximately).
//
// Pseudo-views for distillation: cameras midway between each training camera
// and its nearest neighbours, where the Gaussians interpolate; their denoised
// renders become down-weighted training targets (train/diffusion_stage.h).
#pragma once
#include <cstdint>
#include <vector>

#include "core/camera.h"

namespace ddhgs::train {

// `camera` turned by `degrees` about its own centre, around an axis drawn
// uniformly on the sphere from `seed`; same centre and intrinsics.
core::Camera turned(const core::Camera& camera, double degrees, uint64_t seed);

// k interleaved folds of `views` (in their order): fold f holds views[i] for
// i % k == f, so on a turntable each held-out view keeps both neighbours.
// k is clamped to [1, views.size()].
std::vector<std::vector<int>> interleaved_folds(const std::vector<int>& views, int k);

// The camera halfway between a and b: centre at the midpoint, rotation the
// geodesic midpoint of the two, a's intrinsics.
core::Camera midway(const core::Camera& a, const core::Camera& b);

// One camera midway between each camera and each of its two nearest
// neighbours (by centre), each unordered pair once, in the order the pairs
// are first met.
// Fewer than two cameras give none.
std::vector<core::Camera> between_cameras(const std::vector<core::Camera>& cameras);

}  // namespace ddhgs::train
