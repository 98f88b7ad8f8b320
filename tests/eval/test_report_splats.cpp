// The report's spectral basis (eval/report_splats.h): the fewest principal
// components within its tolerance, orthonormal, and its reported error true.
#include <gtest/gtest.h>

#include "eval/report_splats.h"

namespace ddhgs::eval {
namespace {

TEST(SpectralBasis, FindsTheRankOfLowRankSpectraAndMeetsItsTolerance) {
  torch::manual_seed(6);
  const int64_t G = 2000, N = 30;
  // Three smooth spectra mixed per row: rank 3 around the mean.
  torch::Tensor nm = torch::linspace(0, 1, N, torch::kFloat64);
  torch::Tensor shapes = torch::stack({nm, (nm * 6).sin(), (-(nm - 0.5).square() * 20).exp()});
  torch::Tensor values = (torch::rand({G, 3}, torch::kFloat64) * 0.3).matmul(shapes) + 0.2;
  const SpectralBasis basis = spectral_basis(values, 0.5 / 255);
  EXPECT_EQ(basis.vectors.size(0), 3);
  EXPECT_TRUE(torch::allclose(basis.vectors.matmul(basis.vectors.t()),
                              torch::eye(3, torch::kFloat64), 1e-9, 1e-9));
  EXPECT_LT(basis.rmse, 1.0 / 255);  // 8-bit coefficients
  EXPECT_NEAR(basis.rmse, (basis.reconstruct() - values).square().mean().sqrt().item<double>(),
              1e-12);
  // Unstructured spectra need every band (up to the cap).
  const SpectralBasis full = spectral_basis(torch::rand({G, 5}, torch::kFloat64), 0.5 / 255);
  EXPECT_EQ(full.vectors.size(0), 5);
  EXPECT_EQ(spectral_basis(torch::rand({G, 40}, torch::kFloat64), 0.5 / 255).vectors.size(0),
            kMaxBasisVectors);
}

}  // namespace
}  // namespace ddhgs::eval
