// Small scenes for tests of the colour model (model/colour_model.h), in the
// model layer and in the layers above it (its PLY form, exports).
#pragma once
#include "core/tensor.h"

#include "model/gaussians.h"
#include "render/render_fixture.h"

namespace ddhgs::test {

constexpr int kWidth = 40, kHeight = 30;

// Gaussians from the rasterizer's random scene with SH of degree 1 over
// `channels` channels: small view-dependent terms on colours in [0, 1], so a
// per-band model never clamps.
inline model::Gaussians scene_gaussians(int seed, int g, int channels) {
  const SplatScene s = random_scene(seed, g, channels, kWidth, kHeight);
  model::Gaussians gaussians;
  gaussians.means = s.means;
  gaussians.log_scales = s.log_scales;
  gaussians.quats = s.quats;
  gaussians.logit_opacities = s.logit_opacities;
  gaussians.sh_dc = ((s.colors * 0.8 + 0.1 - 0.5) / model::kShC0).contiguous();
  gaussians.sh_rest = (torch::randn({g, channels, 3}) * 0.05).contiguous();
  gaussians.active_sh_degree = 1;
  return gaussians;
}

// A latent model of 9 bands and 3 channels with a random basis and mean.
inline model::Gaussians latent_scene(int seed) {
  model::Gaussians g = scene_gaussians(seed, 50, 3);
  g.colour.basis = torch::randn({9, 3}) * 0.5;
  g.colour.mean = torch::rand({9});
  return g;
}

}  // namespace ddhgs::test
