#include <gtest/gtest.h>

#include "core/error.h"
#include "model/gaussians.h"

using namespace ddhgs;

TEST(Gaussians, PlyConversionKeepsEveryParameter) {
  torch::manual_seed(1);
  model::Gaussians g;
  g.means = torch::randn({5, 3}).requires_grad_(true);
  g.log_scales = torch::randn({5, 3});
  g.quats = torch::randn({5, 4});
  g.logit_opacities = torch::randn({5, 1});
  g.sh_dc = torch::randn({5, 7});
  g.sh_rest = torch::randn({5, 7, 8});
  g.active_sh_degree = 1;
  EXPECT_EQ(g.max_sh_degree(), 2);
  EXPECT_EQ(g.bands(), 7);
  auto ply = model::to_ply(g, {400, 500, 600, 700, 800, 900, 1000});
  EXPECT_FALSE(ply.means.requires_grad());
  EXPECT_EQ(ply.wavelengths_nm.size(), 7u);
  auto back = model::from_ply(ply);
  EXPECT_EQ(back.active_sh_degree, 2);
  auto original = g.tensors();
  auto restored = back.tensors();
  for (size_t i = 0; i < original.size(); ++i)
    EXPECT_TRUE(torch::equal(original[i]->detach(), *restored[i])) << i;
  // The copy is independent of the model it came from.
  ply.sh_dc.fill_(0);
  EXPECT_FALSE(torch::equal(back.sh_dc, ply.sh_dc));
}

TEST(Gaussians, PlyWithBakedBandOffsetsRendersAsTheOffsetsDid) {
  // The wavelength encoder's offsets are added to the exported coefficients:
  // rendering the PLY without offsets must equal rendering the model with them.
  torch::manual_seed(4);
  const int64_t n = 5, count = 40;
  model::Gaussians g;
  g.means = torch::randn({count, 3}) * 0.3;
  g.log_scales = torch::full({count, 3}, -2.5);
  g.quats = torch::randn({count, 4});
  g.logit_opacities = torch::randn({count, 1});
  g.sh_dc = torch::randn({count, n}) * 0.2;
  g.sh_rest = torch::randn({count, n, 15}) * 0.05;
  g.active_sh_degree = 3;
  core::Camera camera;
  camera.intrinsics = {40, 40, 16, 12, 32, 24};
  camera.world_to_camera = core::look_at({0.4, -0.3, -2.5}, {0, 0, 0}, {0, -1, 0});
  auto background = torch::full({n}, 0.1);
  auto offsets = torch::randn({n, 16}) * 0.1;
  auto with_offsets = model::render_gaussians(g, camera, background, offsets).image;
  auto baked = model::from_ply(model::to_ply(g, {450, 500, 550, 600, 650}, offsets));
  auto from_ply = model::render_gaussians(baked, camera, background).image;
  EXPECT_GT(with_offsets.abs().max().item<double>(), 0.05);
  EXPECT_TRUE(torch::allclose(with_offsets, from_ply, 1e-5, 1e-6));
  // And the offsets matter: without them the image differs.
  auto without = model::render_gaussians(g, camera, background).image;
  EXPECT_GT((without - with_offsets).abs().max().item<double>(), 1e-3);
  EXPECT_THROW(model::to_ply(g, {450, 500, 550, 600, 650}, torch::zeros({n, 9})), core::Error);
}

TEST(Gaussians, TrainingBytesCountParameterGradientAndTwoMoments) {
  // 3 + 3 + 4 + 1 geometry floats plus 141 bands x 16 SH coefficients.
  EXPECT_EQ(model::training_bytes_per_gaussian(141, 3), (11 + 141 * 16) * 4 * 4);
  EXPECT_EQ(model::training_bytes_per_gaussian(3, 0), (11 + 3) * 16);
}

TEST(Gaussians, RejectsAnSHSizeThatIsNoDegree) {
  model::Gaussians g;
  g.sh_rest = torch::zeros({2, 3, 5});
  EXPECT_THROW(g.max_sh_degree(), std::exception);
}
