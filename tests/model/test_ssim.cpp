#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "model/ssim.h"

using namespace ddhgs;

namespace {

// Window-by-window SSIM in double precision, straight from the definition.
std::vector<double> direct_ssim_per_band(const torch::Tensor& a, const torch::Tensor& b) {
  auto x = a.to(torch::kFloat64).contiguous();
  auto y = b.to(torch::kFloat64).contiguous();
  const int64_t h = x.size(0), w = x.size(1), n = x.size(2);
  const int r = 5;
  double weights[11][11];
  double total = 0;
  for (int i = 0; i < 11; ++i)
    for (int j = 0; j < 11; ++j) {
      weights[i][j] = std::exp(-((i - r) * (i - r) + (j - r) * (j - r)) / (2 * 1.5 * 1.5));
      total += weights[i][j];
    }
  auto xa = x.accessor<double, 3>();
  auto ya = y.accessor<double, 3>();
  std::vector<double> out(n, 0.0);
  const double c1 = 1e-4, c2 = 9e-4;
  for (int64_t band = 0; band < n; ++band) {
    double sum = 0;
    int count = 0;
    for (int64_t cy = r; cy < h - r; ++cy)
      for (int64_t cx = r; cx < w - r; ++cx) {
        double mx = 0, my = 0, sxx = 0, syy = 0, sxy = 0;
        for (int i = 0; i < 11; ++i)
          for (int j = 0; j < 11; ++j) {
            double wt = weights[i][j] / total;
            double u = xa[cy - r + i][cx - r + j][band], v = ya[cy - r + i][cx - r + j][band];
            mx += wt * u;
            my += wt * v;
            sxx += wt * u * u;
            syy += wt * v * v;
            sxy += wt * u * v;
          }
        double vx = sxx - mx * mx, vy = syy - my * my, cov = sxy - mx * my;
        sum += ((2 * mx * my + c1) * (2 * cov + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2));
        ++count;
      }
    out[band] = sum / count;
  }
  return out;
}

}  // namespace

TEST(Ssim, MatchesDirectDoublePrecisionComputation) {
  torch::manual_seed(3);
  auto a = torch::rand({17, 23, 4});
  auto b = (a + 0.2 * torch::randn({17, 23, 4})).clamp(0, 1);
  auto expected = direct_ssim_per_band(a, b);
  auto per_band = model::ssim(a, b, true);
  ASSERT_EQ(per_band.numel(), 4);
  double mean = 0;
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(per_band[i].item<double>(), expected[i], 1e-5);
    mean += expected[i] / 4;
  }
  EXPECT_NEAR(model::ssim(a, b).item<double>(), mean, 1e-5);
}

TEST(Ssim, IdenticalImagesGiveOneAndDifferentImagesLess) {
  torch::manual_seed(4);
  auto a = torch::rand({12, 14, 3});
  EXPECT_NEAR(model::ssim(a, a).item<double>(), 1.0, 1e-6);
  EXPECT_LT(model::ssim(a, torch::rand({12, 14, 3})).item<double>(), 0.5);
}

TEST(Ssim, GradientMatchesFiniteDifferences) {
  torch::manual_seed(5);
  auto a = torch::rand({13, 12, 2}, torch::kFloat64).requires_grad_(true);
  auto b = torch::rand({13, 12, 2}, torch::kFloat64);
  auto s = model::ssim(a, b);
  s.backward();
  auto grad = a.grad();
  const double h = 1e-6;
  for (int64_t idx : {0L, 57L, 130L, 311L}) {
    auto flat = a.detach().clone().view(-1);
    flat[idx] += h;
    double plus = model::ssim(flat.view({13, 12, 2}), b).item<double>();
    flat[idx] -= 2 * h;
    double minus = model::ssim(flat.view({13, 12, 2}), b).item<double>();
    EXPECT_NEAR(grad.view(-1)[idx].item<double>(), (plus - minus) / (2 * h), 1e-7);
  }
}

TEST(Ssim, RejectsImagesSmallerThanTheWindow) {
  auto a = torch::rand({10, 30, 2});
  EXPECT_THROW(model::ssim(a, a), std::exception);
  EXPECT_THROW(model::ssim(torch::rand({12, 12, 2}), torch::rand({12, 12, 3})), std::exception);
}
