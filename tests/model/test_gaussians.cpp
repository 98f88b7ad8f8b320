#include <gtest/gtest.h>

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
