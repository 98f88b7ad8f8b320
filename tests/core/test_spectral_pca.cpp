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

// White noise of known level, on an image with a sharp edge: the median of
// neighbour differences finds the level within a few per cent.
TEST(SpectralPca, BandNoiseSigmaMeasuresWhiteNoise) {
  torch::manual_seed(5);
  torch::Tensor image = torch::zeros({200, 200, 3}, torch::kFloat64);
  image.slice(1, 100, 200) += 0.5;  // an edge the median ignores
  const torch::Tensor sigma = torch::tensor({0.01, 0.05, 0.002}, torch::kFloat64);
  const torch::Tensor measured =
      core::band_noise_sigma(image + torch::randn({200, 200, 3}, torch::kFloat64) * sigma);
  EXPECT_TRUE(torch::allclose(measured, sigma, 0.05, 0)) << measured;
}

// A view mostly of black backdrop (noise clipped at 0 there): the level is
// the lit part's, not the median of the black pairs' zero differences.
TEST(SpectralPca, BandNoiseSigmaLooksPastABlackBackdrop) {
  torch::manual_seed(6);
  torch::Tensor image = torch::zeros({200, 200, 2}, torch::kFloat64);
  const torch::Tensor sigma = torch::tensor({0.01, 0.03}, torch::kFloat64);
  image.slice(1, 150, 200) = 0.5 + torch::randn({200, 50, 2}, torch::kFloat64) * sigma;
  const torch::Tensor measured = core::band_noise_sigma(image);
  EXPECT_TRUE(torch::allclose(measured, sigma, 0.08, 0)) << measured;
}

// Shot noise on a view that is mostly dim backdrop (not exactly 0): the
// backdrop's pairs are the median ones, but the level measured is the noise
// the pixels carry on average, the root mean square over both parts; and
// with it the whitened rank of a 2-component object stays 2 (the median
// level, 5 times too low, made every component of the object's noise
// "signal": a rank near the band count, docs/benchmarks.md).
TEST(SpectralPca, BandNoiseSigmaMeasuresShotNoiseAtEveryLevel) {
  torch::manual_seed(7);
  const int64_t H = 120, W = 120, N = 40;
  const torch::Tensor wl = torch::linspace(0, 1, N, torch::kFloat64);
  const torch::Tensor b = torch::stack({0.4 + 0.3 * torch::sin(3 * wl), 0.2 * wl});  // [2, N]
  torch::Tensor a = torch::zeros({H, W, 2}, torch::kFloat64);
  // The object: the right third, varying down its rows (the differences run
  // along them and see noise only).
  const torch::Tensor v = torch::linspace(0, 1, H, torch::kFloat64).view({H, 1});
  a.slice(1, 80, 120).select(2, 0) = 1;
  a.slice(1, 80, 120).select(2, 1) = (v * 2).expand({H, 40});
  torch::Tensor clean = a.matmul(b) + 0.004;            // the backdrop dim, not black
  const torch::Tensor std = 0.03 * torch::sqrt(clean);  // shot noise
  const torch::Tensor image = clean + torch::randn({H, W, N}, torch::kFloat64) * std;
  const torch::Tensor truth = std.pow(2).reshape({-1, N}).mean(0).sqrt();
  const torch::Tensor measured = core::band_noise_sigma(image);
  EXPECT_TRUE(torch::allclose(measured, truth, 0.15, 0)) << measured << truth;
  EXPECT_EQ(core::whitened_signal_rank(image.reshape({-1, N}), measured), 2);
}

// Noise 30 times stronger in a tenth of the bands (a sensor's weak edges):
// the unwhitened floor rule counts those bands' noise as signal, the
// whitened rank finds the 3 signal components.
TEST(SpectralPca, WhitenedRankIgnoresUnevenNoise) {
  torch::manual_seed(6);
  const int64_t H = 100, W = 100, N = 80, K = 3;
  const torch::Tensor wl = torch::linspace(0, 1, N, torch::kFloat64);
  const torch::Tensor b = torch::stack({torch::sin(3 * wl), torch::exp(-wl * 4), wl * wl});
  // Smooth abundances across the image, so neighbour differences see noise only.
  const torch::Tensor u = torch::linspace(0, 1, W, torch::kFloat64).view({1, W, 1});
  const torch::Tensor v = torch::linspace(0, 1, H, torch::kFloat64).view({H, 1, 1});
  const torch::Tensor a =
      torch::cat({torch::sin(6 * u + 0 * v), torch::cos(5 * v + 0 * u), (u * v) * 2 - 0.5},
                 2);  // [H, W, 3]
  torch::Tensor sigma = torch::full({N}, 0.002, torch::kFloat64);
  sigma.slice(0, 0, N / 10) *= 30;
  const torch::Tensor image =
      a.matmul(b) + torch::randn({H, W, N}, torch::kFloat64) * sigma;  // [H, W, N]
  const torch::Tensor spectra = image.reshape({-1, N});
  EXPECT_GT(core::spectral_pca(spectra).signal_rank(), K);
  EXPECT_EQ(core::whitened_signal_rank(spectra, core::band_noise_sigma(image)), K);
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
