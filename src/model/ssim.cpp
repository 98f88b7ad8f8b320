#include "model/ssim.h"

#include <cmath>
#include <string>
#include <vector>

#include "core/error.h"

namespace ddhgs::model {

namespace {

torch::Tensor gaussian_window_1d(const torch::TensorOptions& options) {
  auto x = torch::arange(kSsimWindow, torch::TensorOptions().dtype(torch::kFloat64)) -
           double(kSsimWindow / 2);
  auto w = torch::exp(-(x * x) / (2 * kSsimSigma * kSsimSigma));
  return (w / w.sum()).to(options);
}

// Separable valid filtering of every channel of [1, C, H, W].
torch::Tensor blur(const torch::Tensor& x) {
  const int64_t channels = x.size(1);
  auto w = gaussian_window_1d(x.options());
  auto rows = w.view({1, 1, kSsimWindow, 1}).expand({channels, 1, kSsimWindow, 1});
  auto cols = w.view({1, 1, 1, kSsimWindow}).expand({channels, 1, 1, kSsimWindow});
  const std::vector<int64_t> one{1, 1}, none{0, 0};
  auto y = torch::conv2d(x, rows, torch::Tensor(), one, none, one, channels);
  return torch::conv2d(y, cols, torch::Tensor(), one, none, one, channels);
}

}  // namespace

torch::Tensor ssim_map(const torch::Tensor& a, const torch::Tensor& b) {
  core::require(a.dim() == 3 && a.sizes() == b.sizes(),
                "ssim: expected two [H, W, N] images of the same shape");
  core::require(a.size(0) >= kSsimWindow && a.size(1) >= kSsimWindow,
                "ssim: images must be at least 11 x 11 pixels, got " + std::to_string(a.size(1)) +
                    " x " + std::to_string(a.size(0)));
  const int64_t n = a.size(2);
  auto x = a.permute({2, 0, 1});  // [N, H, W]
  auto y = b.permute({2, 0, 1});
  // One grouped convolution for all five moments.
  auto stacked = torch::cat({x, y, x * x, y * y, x * y}, 0).unsqueeze(0);  // [1, 5N, H, W]
  auto moments = blur(stacked).squeeze(0).split(n, 0);
  const auto& mu_x = moments[0];
  const auto& mu_y = moments[1];
  auto mu_xx = mu_x * mu_x;
  auto mu_yy = mu_y * mu_y;
  auto mu_xy = mu_x * mu_y;
  auto var_x = moments[2] - mu_xx;
  auto var_y = moments[3] - mu_yy;
  auto cov = moments[4] - mu_xy;
  constexpr double c1 = 0.01 * 0.01, c2 = 0.03 * 0.03;
  return ((2 * mu_xy + c1) * (2 * cov + c2)) / ((mu_xx + mu_yy + c1) * (var_x + var_y + c2));
}

torch::Tensor ssim(const torch::Tensor& a, const torch::Tensor& b, bool per_band) {
  auto map = ssim_map(a, b);
  return per_band ? map.mean({1, 2}) : map.mean();
}

}  // namespace ddhgs::model
