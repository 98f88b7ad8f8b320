// The fused L1 + SSIM pass (model/ssim_fused.h) against its reference twins:
// model::ssim (LibTorch convolutions, run in double precision here) and
// (a - b).abs().mean(), values and gradients, on random images of odd sizes
// and band counts that fill no, one or several band blocks exactly.
#include <gtest/gtest.h>
#include <torch/nn/functional/upsampling.h>

#include <string>
#include <tuple>

#include "core/threads.h"
#include "model/ssim.h"
#include "model/ssim_fused.h"

using namespace ddhgs;

namespace {

// A smooth random image with noise, and a noisier copy of it: SSIM values
// spread over (0, 1) as they do for a render against its target.
std::pair<torch::Tensor, torch::Tensor> image_pair(int64_t h, int64_t w, int64_t n, uint64_t seed) {
  torch::manual_seed(seed);
  auto coarse = torch::rand({1, n, h / 4 + 2, w / 4 + 2});
  auto smooth =
      torch::nn::functional::interpolate(coarse, torch::nn::functional::InterpolateFuncOptions()
                                                     .size(std::vector<int64_t>{h, w})
                                                     .mode(torch::kBilinear)
                                                     .align_corners(false))
          .squeeze(0)
          .permute({1, 2, 0});
  auto a = (smooth + 0.05 * torch::randn({h, w, n})).clamp(0, 1).contiguous();
  auto b = (a + 0.1 * torch::randn({h, w, n})).clamp(0, 1).contiguous();
  return {a, b};
}

// Loss l1_weight * L1 + ssim_weight * (1 - SSIM) and its gradient w.r.t. a,
// by the reference twins in double precision.
std::pair<double, torch::Tensor> reference(const torch::Tensor& a, const torch::Tensor& b,
                                           double l1_weight, double ssim_weight) {
  auto x = a.to(torch::kFloat64).requires_grad_(true);
  auto y = b.to(torch::kFloat64);
  auto loss = l1_weight * (x - y).abs().mean() + ssim_weight * (1 - model::ssim(x, y));
  loss.backward();
  return {loss.item<double>(), x.grad()};
}

std::pair<double, torch::Tensor> fused(const torch::Tensor& a, const torch::Tensor& b,
                                       double l1_weight, double ssim_weight) {
  auto x = a.clone().requires_grad_(true);
  auto v = model::l1_and_ssim(x, b);
  auto loss = l1_weight * v.l1 + ssim_weight * (1 - v.ssim);
  loss.backward();
  return {loss.item<double>(), x.grad()};
}

double max_abs(const torch::Tensor& t) {
  return t.abs().max().item<double>();
}

class FusedSsimShapes : public ::testing::TestWithParam<std::tuple<int64_t, int64_t, int64_t>> {};

TEST_P(FusedSsimShapes, ValuesAndGradientsMatchTheLibTorchTwin) {
  const auto [h, w, n] = GetParam();
  auto [a, b] = image_pair(h, w, n, uint64_t(h * 1000 + w * 10 + n));
  torch::NoGradGuard no_grad_for_values;
  const auto v = model::l1_and_ssim(a, b);
  EXPECT_NEAR(v.ssim.item<double>(),
              model::ssim(a.to(torch::kFloat64), b.to(torch::kFloat64)).item<double>(), 2e-6);
  EXPECT_NEAR(v.l1.item<double>(), (a - b).abs().mean().item<double>(), 1e-6);
  EXPECT_EQ(v.ssim.dim(), 0);
  {
    torch::AutoGradMode enable(true);
    for (const auto& [l1_weight, ssim_weight] :
         std::vector<std::pair<double, double>>{{0.8, 0.2}, {0.0, 1.0}, {1.0, 0.0}}) {
      const auto [ref_loss, ref_grad] = reference(a, b, l1_weight, ssim_weight);
      const auto [loss, grad] = fused(a, b, l1_weight, ssim_weight);
      EXPECT_NEAR(loss, ref_loss, 2e-6);
      ASSERT_EQ(grad.sizes(), a.sizes());
      // Float32 against double: a few ulps of the largest gradient.
      EXPECT_LE(max_abs(grad.to(torch::kFloat64) - ref_grad), 1e-5 * max_abs(ref_grad))
          << "l1 " << l1_weight << " ssim " << ssim_weight;
    }
  }
}

// Heights and widths from the 11-pixel minimum to a few strips, odd sizes;
// bands 1, 3 (RGB), 17 (one block and one band), 141 (BaySpec). Widths over
// 192 columns are cut into column tiles (2 of 101 and 3 of 140 or 139 here),
// whose windows and gradients must be the whole row's.
INSTANTIATE_TEST_SUITE_P(Shapes, FusedSsimShapes,
                         ::testing::Values(std::make_tuple(11, 11, 1), std::make_tuple(13, 29, 3),
                                           std::make_tuple(61, 37, 17),
                                           std::make_tuple(23, 19, 141), std::make_tuple(97, 15, 5),
                                           std::make_tuple(12, 40, 8), std::make_tuple(14, 201, 3),
                                           std::make_tuple(26, 418, 17),
                                           std::make_tuple(11, 418, 141)));

void same_bits_for_any_thread_count(int64_t h, int64_t w, int64_t n) {
  auto [a, b] = image_pair(h, w, n, 7);
  // The kernel runs on ddhgs's own pool (core/parallel.h), sized here.
  auto run = [&](int threads) {
    core::configure_threads(threads);
    auto x = a.clone().requires_grad_(true);
    auto v = model::l1_and_ssim(x, b);
    (0.8 * v.l1 + 0.2 * (1 - v.ssim)).backward();
    return std::make_tuple(v.l1.item<float>(), v.ssim.item<float>(), x.grad());
  };
  const int before = core::thread_count();
  const auto one = run(1);
  const auto two = run(3);
  core::configure_threads(before);
  EXPECT_EQ(std::get<0>(one), std::get<0>(two));
  EXPECT_EQ(std::get<1>(one), std::get<1>(two));
  EXPECT_TRUE(torch::equal(std::get<2>(one), std::get<2>(two)));
}

TEST(FusedSsim, SameBitsForAnyThreadCount) {
  // One tile, and three column tiles.
  for (const auto& [h, w, n] : {std::make_tuple(75, 33, 40), std::make_tuple(30, 400, 20)}) {
    SCOPED_TRACE(std::to_string(w) + " columns");
    same_bits_for_any_thread_count(h, w, n);
  }
}

TEST(FusedSsim, IdenticalAndConstantImages) {
  // Zero variance everywhere: SSIM 1 for equal images and finite gradients.
  auto flat = torch::full({20, 16, 3}, 0.25f);
  auto x = flat.clone().requires_grad_(true);
  auto v = model::l1_and_ssim(x, flat);
  EXPECT_NEAR(v.ssim.item<double>(), 1.0, 1e-6);
  EXPECT_EQ(v.l1.item<double>(), 0.0);
  (1 - v.ssim).backward();
  EXPECT_TRUE(torch::isfinite(x.grad()).all().item<bool>());
  EXPECT_LT(max_abs(x.grad()), 1e-6);
}

TEST(FusedSsim, DoubleInputsGetDoubleGradients) {
  auto [a, b] = image_pair(16, 18, 4, 3);
  auto x = a.to(torch::kFloat64).requires_grad_(true);
  auto v = model::l1_and_ssim(x, b.to(torch::kFloat64));
  (1 - v.ssim).backward();
  EXPECT_EQ(x.grad().scalar_type(), torch::kFloat64);
  const auto ref = reference(a, b, 0.0, 1.0).second;
  EXPECT_LE(max_abs(x.grad() - ref), 1e-5 * max_abs(ref));
}

TEST(FusedSsim, RejectsBadInputs) {
  auto a = torch::rand({10, 12, 2});
  EXPECT_THROW(model::l1_and_ssim(a, a), std::exception);  // below 11 x 11
  auto b = torch::rand({12, 12, 2});
  EXPECT_THROW(model::l1_and_ssim(b, torch::rand({12, 12, 3})), std::exception);
  auto target = torch::rand({12, 12, 2}).requires_grad_(true);
  EXPECT_THROW(model::l1_and_ssim(b, target), std::exception);
}

TEST(FusedSsim, SecondBackwardThroughTheSameGraphIsRefused) {
  auto [a, b] = image_pair(14, 14, 2, 5);
  auto x = a.clone().requires_grad_(true);
  auto v = model::l1_and_ssim(x, b);
  auto loss = 1 - v.ssim;
  loss.backward({}, /*retain_graph=*/true);
  EXPECT_THROW(loss.backward(), std::exception);
}

}  // namespace
