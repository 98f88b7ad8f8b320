// Small Gaussian scenes shared by tests of several layers (camera
// refinement in train, pose alignment in eval).
#pragma once
#include "core/tensor.h"

#include <cmath>
#include <cstdint>

#include "model/gaussians.h"

namespace ddhgs::test {

// `count` coloured blobs (3 bands, degree 0) spread over a 1.6-wide cube
// around the origin, drawn after torch::manual_seed(seed).
inline model::Gaussians blob_scene(int64_t count, uint64_t seed) {
  torch::manual_seed(seed);
  model::Gaussians g;
  g.means = (torch::rand({count, 3}) - 0.5) * 1.6;
  g.log_scales = torch::full({count, 3}, std::log(0.08));
  g.quats = torch::tensor({1.0f, 0.0f, 0.0f, 0.0f}).repeat({count, 1});
  g.logit_opacities = torch::full({count, 1}, 2.0);
  g.sh_dc = torch::randn({count, 3}) * 1.5;
  g.sh_rest = torch::zeros({count, 3, 0});
  return g;
}

}  // namespace ddhgs::test
