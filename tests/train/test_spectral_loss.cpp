#include <gtest/gtest.h>

#include "core/error.h"
#include "train/config.h"
#include "train/losses.h"
#include "train/run_config.h"
#include "train/spectral_loss.h"

using ddhgs::train::spectral_loss;
using ddhgs::train::SpectralLossOptions;

namespace {
torch::Tensor random_image(int64_t seed, int64_t h, int64_t w, int64_t n) {
  auto gen = at::make_generator<at::CPUGeneratorImpl>(seed);
  return torch::rand({h, w, n}, gen, torch::kFloat64);
}
}  // namespace

TEST(SpectralLoss, ZeroForIdenticalPositiveOtherwise) {
  auto a = random_image(1, 5, 4, 17);
  auto b = random_image(2, 5, 4, 17);
  EXPECT_NEAR(spectral_loss(a, a).item<double>(), 0.0, 1e-12);
  EXPECT_GT(spectral_loss(a, b).item<double>(), 1e-6);
}

TEST(SpectralLoss, MatchesHandComputedValue) {
  // One pixel, two bands: pred (0, 1), gt (1, 0) at temperature 1.
  auto pred = torch::tensor({0.0, 1.0}, torch::kFloat64).reshape({1, 1, 2});
  auto gt = torch::tensor({1.0, 0.0}, torch::kFloat64).reshape({1, 1, 2});
  double e = std::exp(1.0);
  double p0 = 1 / (1 + e), p1 = e / (1 + e);  // prediction's softmax
  double q0 = p1, q1 = p0;                    // ground truth's softmax
  double kl = q0 * std::log(q0 / p0) + q1 * std::log(q1 / p1);
  double cos = (p0 * q0 + p1 * q1) / (std::hypot(p0, p1) * std::hypot(q0, q1));
  double expected = 0.5 * kl + 0.5 * (1 - cos);
  EXPECT_NEAR(spectral_loss(pred, gt).item<double>(), expected, 1e-12);
}

TEST(SpectralLoss, InvariantToAddingAConstantToEveryBand) {
  auto a = random_image(3, 3, 3, 8);
  auto b = random_image(4, 3, 3, 8);
  double base = spectral_loss(a, b).item<double>();
  EXPECT_NEAR(spectral_loss(a + 0.3, b).item<double>(), base, 1e-12);
  EXPECT_NEAR(spectral_loss(a, b - 0.2).item<double>(), base, 1e-12);
}

TEST(SpectralLoss, FiniteForZeroAndFlatSpectra) {
  auto zeros = torch::zeros({2, 2, 6}, torch::kFloat32);
  auto flat = torch::full({2, 2, 6}, 0.7, torch::kFloat32);
  auto pred = zeros.clone().requires_grad_(true);
  auto loss = spectral_loss(pred, flat);
  loss.backward();
  EXPECT_TRUE(std::isfinite(loss.item<float>()));
  EXPECT_NEAR(loss.item<float>(), 0.0f, 1e-7);  // both flat: identical distributions
  EXPECT_TRUE(torch::isfinite(pred.grad()).all().item<bool>());
  // Extreme values at a sharp temperature stay finite too.
  auto spiky = torch::zeros({1, 1, 6});
  spiky[0][0][0] = 1.0;
  SpectralLossOptions sharp;
  sharp.temperature = 0.001;
  EXPECT_TRUE(std::isfinite(
      spectral_loss(spiky, zeros.slice(0, 0, 1).slice(1, 0, 1), sharp).item<float>()));
}

TEST(SpectralLoss, GradientMatchesCentralFiniteDifferences) {
  SpectralLossOptions opts;
  opts.alpha = 0.7;
  opts.beta = 0.4;
  opts.temperature = 0.25;
  auto pred = random_image(5, 2, 3, 5).requires_grad_(true);
  auto gt = random_image(6, 2, 3, 5);
  spectral_loss(pred, gt, opts).backward();
  auto analytic = pred.grad().clone();
  const double h = 1e-6;
  auto flat = pred.detach().reshape({-1});
  for (int64_t i = 0; i < flat.numel(); ++i) {
    auto plus = flat.clone(), minus = flat.clone();
    plus[i] += h;
    minus[i] -= h;
    double fd = (spectral_loss(plus.reshape(pred.sizes()), gt, opts).item<double>() -
                 spectral_loss(minus.reshape(pred.sizes()), gt, opts).item<double>()) /
                (2 * h);
    EXPECT_NEAR(analytic.reshape({-1})[i].item<double>(), fd, 1e-7) << "element " << i;
  }
}

TEST(SpectralLoss, RejectsMismatchedShapes) {
  EXPECT_THROW(spectral_loss(torch::zeros({2, 2, 3}), torch::zeros({2, 2, 4})), ddhgs::core::Error);
}

TEST(SpectralLoss, TrainingTermReadsItsConfigKeys) {
  nlohmann::json config = ddhgs::train::load_preset("default");
  config["loss"].update({{"spectral", 0.1},
                         {"spectral_alpha", 0.3},
                         {"spectral_beta", 0.9},
                         {"spectral_temperature", 0.5}});
  const auto loss = ddhgs::train::parse_run_config(config, "test").loss;
  auto term = ddhgs::train::spectral_term(loss.spectral, loss.spectral_options);
  EXPECT_EQ(term.name, "spectral");
  EXPECT_DOUBLE_EQ(term.weight, 0.1);
  auto a = random_image(7, 3, 2, 5);
  auto b = random_image(8, 3, 2, 5);
  SpectralLossOptions opts;
  opts.alpha = 0.3;
  opts.beta = 0.9;
  opts.temperature = 0.5;
  double direct = spectral_loss(a, b, opts).item<double>();
  EXPECT_DOUBLE_EQ(term.compute({a, b, 0, 1}).item<double>(), direct);
}
