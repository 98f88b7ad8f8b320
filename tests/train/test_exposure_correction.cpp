// Exposure correction: the gain's gradient against its closed form and finite
// differences, the centring over the training views, the prior, the entries a
// scene trains, and known gain errors recovered by fitting renders.
#include <gtest/gtest.h>

#include <cmath>

#include "model/adam.h"
#include "model/gaussian_fixtures.h"
#include "model/gaussians.h"
#include "train/exposure_correction.h"
#include "train/losses.h"

namespace ddhgs::train {
namespace {

// [3 views, 4 bands]: views 0 and 2 train bands {0, 1} and {1, 3}; view 1
// is held out.
torch::Tensor small_mask() {
  torch::Tensor trained = torch::zeros({3, 4}, torch::kBool);
  trained[0][0] = trained[0][1] = true;
  trained[2][1] = trained[2][3] = true;
  return trained;
}

TEST(ExposureCorrection, GainGradientMatchesTheClosedFormAndFiniteDifferences) {
  torch::manual_seed(3);
  ExposureCorrection exposure(small_mask());
  exposure->to(torch::kFloat64);
  {
    torch::NoGradGuard no_grad;
    exposure->log_gain.copy_(0.2 * torch::randn({3, 4}, torch::kFloat64));
  }
  const torch::Tensor bands = torch::tensor({1, 3}, torch::kInt64);
  const torch::Tensor render = torch::rand({5, 6, 2}, torch::kFloat64).requires_grad_(true);
  const torch::Tensor target = torch::rand({5, 6, 2}, torch::kFloat64);

  // L1: d/ds_b = mean over pixels of sign(r g - t) r g, per band b.
  train::l1_loss(exposure->apply(2, render, bands), target).backward();
  const torch::Tensor gain = exposure->log_gain.detach()[2].index_select(0, bands).exp();
  const torch::Tensor residual_sign = (render.detach() * gain - target).sign();
  const torch::Tensor closed =
      (residual_sign * render.detach() * gain).sum(std::vector<int64_t>{0, 1}) /
      double(render.numel());
  const torch::Tensor grad = exposure->log_gain.grad();
  for (int b = 0; b < 2; ++b)
    EXPECT_NEAR(grad[2][bands[b].item<int64_t>()].item<double>(), closed[b].item<double>(), 1e-12);
  // Only the view's own bands have a gradient; the render's is the gain's.
  EXPECT_EQ(grad[2][0].item<double>(), 0.0);
  EXPECT_EQ(grad[0].abs().sum().item<double>(), 0.0);
  EXPECT_TRUE(
      torch::allclose(render.grad(), residual_sign * gain / double(render.numel()), 0, 1e-15));

  // A smooth loss (squared error plus the prior) against central differences.
  auto loss = [&] {
    return (exposure->apply(2, render.detach(), bands) - target).pow(2).mean() +
           0.3 * exposure->prior(2);
  };
  exposure->log_gain.mutable_grad() = torch::Tensor();
  loss().backward();
  const torch::Tensor analytic = exposure->log_gain.grad().clone();
  const double h = 1e-6;
  for (int v = 0; v < 3; ++v)
    for (int b = 0; b < 4; ++b) {
      torch::NoGradGuard no_grad;
      const double x = exposure->log_gain[v][b].item<double>();
      exposure->log_gain[v][b] = x + h;
      const double up = loss().item<double>();
      exposure->log_gain[v][b] = x - h;
      const double down = loss().item<double>();
      exposure->log_gain[v][b] = x;
      EXPECT_NEAR(analytic[v][b].item<double>(), (up - down) / (2 * h), 1e-8) << v << "," << b;
    }
}

TEST(ExposureCorrection, ApplyWithoutBandsScalesEveryBandByItsGain) {
  ExposureCorrection exposure(torch::ones({2, 3}, torch::kBool));
  {
    torch::NoGradGuard no_grad;
    exposure->log_gain[1] = torch::tensor({0.0f, std::log(2.0f), std::log(0.5f)});
  }
  const torch::Tensor render = torch::rand({4, 5, 3});
  const torch::Tensor out = exposure->apply(1, render, {});
  EXPECT_TRUE(torch::allclose(out, render * torch::tensor({1.0f, 2.0f, 0.5f}), 0, 1e-6));
  EXPECT_TRUE(torch::equal(exposure->apply(0, render, {}), render));  // gain 1: the render itself
}

TEST(ExposureCorrection, PriorIsTheMeanSquaredLogGainOfTheViewsTrainedBands) {
  ExposureCorrection exposure(small_mask());
  {
    torch::NoGradGuard no_grad;
    exposure->log_gain.copy_(torch::tensor(
        {{0.1f, -0.3f, 5.0f, 5.0f}, {1.0f, 1.0f, 1.0f, 1.0f}, {5.0f, 0.2f, 5.0f, 0.4f}}));
  }
  EXPECT_NEAR(exposure->prior(0).item<double>(), (0.01 + 0.09) / 2, 1e-7);
  EXPECT_NEAR(exposure->prior(2).item<double>(), (0.04 + 0.16) / 2, 1e-7);
  EXPECT_EQ(exposure->prior(1).item<double>(), 0.0);  // a held-out view trains nothing
}

TEST(ExposureCorrection, RecentreTakesOutEachBandsMeanOverItsTrainedEntriesOnly) {
  torch::Tensor trained = torch::zeros({4, 2}, torch::kBool);
  trained[0][0] = trained[1][0] = trained[3][0] = true;  // band 0: views 0, 1, 3
  trained[1][1] = trained[2][1] = true;                  // band 1: views 1, 2
  ExposureCorrection exposure(trained);
  const torch::Tensor start =
      torch::tensor({{0.3f, 9.0f}, {0.1f, 0.5f}, {7.0f, -0.1f}, {-0.1f, 8.0f}});
  {
    torch::NoGradGuard no_grad;
    exposure->log_gain.copy_(start);
  }
  exposure->recentre();
  const torch::Tensor expected =
      torch::tensor({{0.2f, 9.0f}, {0.0f, 0.3f}, {7.0f, -0.3f}, {-0.2f, 8.0f}});
  EXPECT_TRUE(torch::allclose(exposure->log_gain.detach(), expected, 0, 1e-6))
      << exposure->log_gain;
}

TEST(ExposureCorrection, TrainedEntriesAreTheTrainingViewsOwnBands) {
  io::Scene scene;
  scene.wavelengths_nm = {475, 560, 668};
  scene.views.resize(4);
  scene.views[0].bands = {0};
  scene.views[1].bands = {1, 2};
  scene.views[2].bands = {2};
  // views[3] holds every band
  scene.train = {0, 1, 3};
  scene.test = {2};
  const torch::Tensor expected = torch::tensor(
      {{true, false, false}, {false, true, true}, {false, false, false}, {true, true, true}});
  EXPECT_TRUE(torch::equal(trained_entries(scene), expected));
}

// Three views of a fixed scene whose captures were lit at known gains per
// band (their log gains summing to zero over the views, which is what
// recentre() keeps): fitting the gains alone to the renders, as training
// steps them (one view a step, its row only, then recentred), finds them
// within 2 %.
TEST(ExposureCorrection, RecoversKnownGainsByFittingRenders) {
  const model::Gaussians scene = test::blob_scene(60, 7);
  const torch::Tensor background = torch::zeros({3});
  const torch::Tensor truth =
      torch::tensor({{0.85, 1.10, 1.00},
                     {1.20, 0.95, 0.90},
                     {1.0 / (0.85 * 1.20), 1.0 / (1.10 * 0.95), 1.0 / 0.9}});
  const core::Vec3 eyes[3] = {{4.0, 0.5, 0.8}, {0.5, 4.0, 0.6}, {-3.0, 2.5, 1.0}};
  std::vector<core::Camera> cameras(3);
  std::vector<torch::Tensor> renders, targets;
  for (int v = 0; v < 3; ++v) {
    cameras[v].intrinsics = {90, 90, 32, 28, 64, 56};
    cameras[v].world_to_camera = core::look_at(eyes[v], {0, 0, 0}, {0, 0, 1});
    renders.push_back(model::render_gaussians(scene, cameras[v], background).image.detach());
    targets.push_back(renders.back() * truth[v].to(torch::kFloat32));
  }
  ExposureCorrection exposure(torch::ones({3, 3}, torch::kBool));
  model::Adam adam;
  adam.add("exposure/log_gain", exposure->log_gain, 0.01);
  for (int step = 0; step < 600; ++step) {
    const int v = step % 3;
    (train::l1_loss(exposure->apply(v, renders[v], {}), targets[v]) + 1e-3 * exposure->prior(v))
        .backward();
    adam.step({{{"exposure/"}, torch::tensor({int64_t(v)})}});
    adam.zero_grad();
    exposure->recentre();
  }
  EXPECT_TRUE(
      torch::allclose(exposure->gains().to(torch::kFloat64), truth.to(torch::kFloat64), 0.02, 0))
      << exposure->gains();
}

}  // namespace
}  // namespace ddhgs::train
