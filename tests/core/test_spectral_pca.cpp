#include <gtest/gtest.h>

#include "core/spectral_pca.h"

namespace ddhgs {
namespace {

// Spectra built with a known rank: mean + A [M, 3] x B [3, N], plus noise far
// below the signal. PCA finds 3 components and their span is B's row space.
TEST(SpectralPca, RecoversTheSubspaceOfAKnownRankCube) {
  torch::manual_seed(3);
  const int64_t M = 4000, N = 40, K = 3;
  const torch::Tensor wl = torch::linspace(0, 1, N, torch::kFloat64);
  const torch::Tensor b =
      torch::stack({torch::sin(3 * wl), torch::exp(-wl * 4), wl * wl});  // [3, N]
  const torch::Tensor a =
      torch::randn({M, K}, torch::kFloat64) * torch::tensor({1.0, 0.6, 0.3}, torch::kFloat64);
  const torch::Tensor mean = 0.2 + 0.1 * wl;
  const torch::Tensor spectra =
      (mean + a.matmul(b) + 1e-4 * torch::randn({M, N}, torch::kFloat64)).to(torch::kFloat32);
  const core::SpectralPca pca = core::spectral_pca(spectra);

  EXPECT_EQ(pca.rank_for(0.999), K);
  EXPECT_GT(pca.kept(K), 0.9999);
  EXPECT_LT(pca.kept(K - 1), 0.99);
  EXPECT_NEAR(pca.kept(N), 1.0, 1e-12);
  EXPECT_TRUE(torch::allclose(pca.mean, mean, 0, 0.02));
  // Orthonormal columns.
  EXPECT_TRUE(
      torch::allclose(pca.basis.t().matmul(pca.basis), torch::eye(N, torch::kFloat64), 0, 1e-9));
  // Every row of B lies in the span of the first K components.
  const torch::Tensor u = pca.basis.slice(1, 0, K);  // [N, K]
  const torch::Tensor residual = b.t() - u.matmul(u.t().matmul(b.t()));
  EXPECT_LT(residual.norm().item<double>() / b.norm().item<double>(), 1e-3);
}

// The same cube under white noise that holds more than 0.1 % of the
// variance: 99.9 % needs nearly every component, the noise floor rule finds
// the 3 that carry the signal.
TEST(SpectralPca, SignalRankStandsAboveTheNoiseFloor) {
  torch::manual_seed(4);
  const int64_t M = 8000, N = 60, K = 3;
  const torch::Tensor wl = torch::linspace(0, 1, N, torch::kFloat64);
  const torch::Tensor b = torch::stack({torch::sin(3 * wl), torch::exp(-wl * 4), wl * wl});
  const torch::Tensor a =
      torch::randn({M, K}, torch::kFloat64) * torch::tensor({1.0, 0.6, 0.3}, torch::kFloat64);
  const torch::Tensor noisy = a.matmul(b) + 0.1 * torch::randn({M, N}, torch::kFloat64);
  const core::SpectralPca pca = core::spectral_pca(noisy);
  EXPECT_GT(pca.rank_for(0.999), 20);
  EXPECT_EQ(pca.signal_rank(), K);
  // Without noise the floor is numerical dust: capped by the 99.9 % rank.
  EXPECT_EQ(core::spectral_pca(a.matmul(b)).signal_rank(), K);
}

// Hand-computed: two bands, independent, variances 4 and 1 (samples +-2 and
// +-1 in all four combinations): 80 % and 20 %, axis-aligned components.
TEST(SpectralPca, EnergiesMatchAHandComputedCovariance) {
  const torch::Tensor spectra =
      torch::tensor({{2.0, 1.0}, {2.0, -1.0}, {-2.0, 1.0}, {-2.0, -1.0}}, torch::kFloat64) + 5;
  const core::SpectralPca pca = core::spectral_pca(spectra);
  ASSERT_EQ(pca.bands(), 2);
  EXPECT_NEAR(pca.energy[0], 0.8, 1e-12);
  EXPECT_NEAR(pca.energy[1], 0.2, 1e-12);
  EXPECT_NEAR(pca.mean[0].item<double>(), 5, 1e-12);
  EXPECT_NEAR(std::abs(pca.basis[0][0].item<double>()), 1, 1e-12);
  EXPECT_GT(pca.basis[0][0].item<double>(), 0);  // the sign convention
  EXPECT_EQ(pca.rank_for(0.8), 1);
  EXPECT_EQ(pca.rank_for(0.81), 2);
  // Spectra that do not vary: no component holds anything.
  const core::SpectralPca flat = core::spectral_pca(torch::ones({10, 5}));
  EXPECT_EQ(flat.rank_for(0.999), 0);
  EXPECT_EQ(flat.kept(5), 0);
}

}  // namespace
}  // namespace ddhgs
