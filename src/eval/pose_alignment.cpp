#include "eval/pose_alignment.h"

#include <torch/optim/adam.h>
#include <cmath>

#include "core/error.h"
#include "model/rigid_motion.h"

namespace ddhgs::eval {
namespace {

// means [G, 3] in the camera's frame (OpenCV axes), float64, no autograd.
torch::Tensor camera_points(const torch::Tensor& means, const core::Camera& camera) {
  const core::Mat4& w = camera.world_to_camera;
  torch::Tensor rows = torch::empty({3, 3}, torch::kFloat64);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) rows[i][j] = w(i, j);
  return torch::matmul(means.detach().to(torch::kFloat64), rows.t()) +
         torch::tensor({w(0, 3), w(1, 3), w(2, 3)}, torch::kFloat64);
}

// Median depth of the Gaussians in front of the camera; 0 when none is.
double median_depth(const torch::Tensor& means, const core::Camera& camera) {
  const torch::Tensor z = camera_points(means, camera).select(1, 2);
  const torch::Tensor ahead = z.masked_select(z > 0);
  return ahead.numel() > 0 ? ahead.median().item<double>() : 0.0;
}

// Pixel positions [G, 2] of means seen by camera, and which lie ahead of it
// and inside the frame.
std::pair<torch::Tensor, torch::Tensor> project(const torch::Tensor& means,
                                                const core::Camera& camera) {
  const torch::Tensor x = camera_points(means, camera);
  const torch::Tensor z = x.select(1, 2);
  const core::Intrinsics& k = camera.intrinsics;
  const torch::Tensor u = k.fx * x.select(1, 0) / z + k.cx, v = k.fy * x.select(1, 1) / z + k.cy;
  const torch::Tensor inside = (z > 0) & (u >= 0) & (u < k.width) & (v >= 0) & (v < k.height);
  return {torch::stack({u, v}, 1), inside};
}

}  // namespace

AlignedView align_view(const model::Gaussians& gaussians, const core::Camera& camera,
                       const torch::Tensor& background, const torch::Tensor& truth,
                       const AlignOptions& options) {
  core::require(options.steps >= 0 && options.step_px > 0,
                "pose alignment: expected steps >= 0 and a positive step");
  auto move = [&](const torch::Tensor& rotation, const torch::Tensor& shift) {
    model::Gaussians moved = gaussians;
    std::tie(moved.means, moved.quats) =
        model::move_rigidly(gaussians.means, gaussians.quats, rotation, shift, camera.center());
    return moved;
  };
  auto render = [&](const model::Gaussians& g) {
    return model::render_gaussians(g, camera, background).image;
  };
  auto l1 = [&](const torch::Tensor& image) { return (image - truth).abs().mean(); };

  AlignedView result;
  {
    torch::NoGradGuard no_grad;
    result.image = render(gaussians);
    result.l1_before = result.l1_after = l1(result.image).item<double>();
  }
  const double focal = 0.5 * (camera.intrinsics.fx + camera.intrinsics.fy);
  const double depth = median_depth(gaussians.means, camera);
  if (options.steps == 0 || depth <= 0 || focal <= 0) return result;

  torch::AutoGradMode grad(true);  // evaluation runs without autograd
  // Pixels to radians and to world units.
  const double per_px_rad = 1.0 / focal, per_px_shift = depth / focal;
  torch::Tensor pixels = torch::zeros({6}, torch::requires_grad());
  auto rotation = [&] { return pixels.slice(0, 0, 3) * per_px_rad; };
  auto shift = [&] { return pixels.slice(0, 3, 6) * per_px_shift; };
  torch::optim::Adam adam({pixels}, torch::optim::AdamOptions(options.step_px));
  for (int step = 0; step < options.steps; ++step) {
    const double anneal = 0.5 * (1 + std::cos(M_PI * step / options.steps));
    static_cast<torch::optim::AdamOptions&>(adam.param_groups()[0].options())
        .lr(options.step_px * anneal);
    adam.zero_grad();
    l1(render(move(rotation(), shift()))).backward();
    adam.step();
  }

  torch::NoGradGuard no_grad;
  const model::Gaussians moved = move(rotation(), shift());
  const torch::Tensor image = render(moved);
  const double after = l1(image).item<double>();
  if (!(after < result.l1_before)) return result;
  result.image = image;
  result.moved = true;
  result.l1_after = after;
  const auto [before, inside] = project(gaussians.means, camera);
  const torch::Tensor after_px = project(moved.means, camera).first;
  if (inside.any().item<bool>())
    result.motion_px = (after_px - before).norm(2, 1).masked_select(inside).mean().item<double>();
  return result;
}

}  // namespace ddhgs::eval
