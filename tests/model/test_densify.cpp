#include <gtest/gtest.h>

#include <ATen/CPUGeneratorImpl.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "model/densify.h"
#include "model/knn.h"

using namespace ddhgs;

namespace {

torch::Tensor brute_force_mean_sq(const torch::Tensor& xyz, int k) {
  auto d2 = torch::cdist(xyz.to(torch::kFloat64), xyz.to(torch::kFloat64)).pow(2);
  d2.fill_diagonal_(1e300);
  auto nearest = std::get<0>(d2.topk(k, 1, false));
  return nearest.mean(1);
}

model::Gaussians make_gaussians(int64_t g, int64_t bands) {
  model::Gaussians m;
  m.means = torch::randn({g, 3});
  m.log_scales = torch::full({g, 3}, std::log(0.005f));
  m.quats = torch::randn({g, 4});
  m.logit_opacities = torch::zeros({g, 1});
  m.sh_dc = torch::randn({g, bands});
  m.sh_rest = torch::randn({g, bands, 15});
  for (auto* t : m.tensors()) t->requires_grad_(true);
  return m;
}

model::Adam make_adam(model::Gaussians& g) {
  model::Adam adam;
  auto tensors = g.tensors();
  for (size_t i = 0; i < tensors.size(); ++i)
    adam.add(model::Gaussians::tensor_names()[i], *tensors[i], 0.01);
  return adam;
}

}  // namespace

TEST(Knn, GridSearchMatchesBruteForce) {
  torch::manual_seed(11);
  // A surface-like cloud (points on a sphere) plus a dense cluster and outliers.
  auto sphere = torch::randn({700, 3});
  sphere = sphere / sphere.norm(2, 1, true);
  auto cluster = 0.01 * torch::randn({200, 3}) + 0.3;
  auto outliers = 20 * torch::rand({5, 3});
  auto xyz = torch::cat({sphere, cluster, outliers}, 0).to(torch::kFloat32);
  auto fast = model::mean_sq_distance_to_neighbours(xyz, 3);
  auto slow = brute_force_mean_sq(xyz, 3);
  EXPECT_LT(((fast.to(torch::kFloat64) - slow).abs() / slow.clamp_min(1e-12)).max().item<double>(),
            1e-4);
}

TEST(Knn, HandlesTinyClouds) {
  EXPECT_EQ(model::mean_sq_distance_to_neighbours(torch::zeros({1, 3})).item<float>(), 0.0f);
  auto two = torch::tensor({0.f, 0.f, 0.f, 3.f, 4.f, 0.f}).view({2, 3});
  auto d = model::mean_sq_distance_to_neighbours(two, 3);
  EXPECT_FLOAT_EQ(d[0].item<float>(), 25.0f);
  EXPECT_FLOAT_EQ(d[1].item<float>(), 25.0f);
}

TEST(Densify, ClonesSmallSplitsLargeAndMovesMoments) {
  torch::manual_seed(12);
  auto g = make_gaussians(6, 4);
  {
    torch::NoGradGuard no_grad;
    g.log_scales[1].fill_(std::log(0.5f));  // large: split
    g.logit_opacities[5].fill_(-10.0f);     // transparent: pruned
  }
  auto adam = make_adam(g);
  for (auto* t : g.tensors()) t->mutable_grad() = torch::ones_like(*t);
  adam.step();
  auto sh_moment_row3 = adam.group("sh_rest").exp_avg[3].clone();
  const auto means_before = g.means.detach().clone();
  const float split_log_scale = g.log_scales[1][0].item<float>() - std::log(1.6f);

  model::DensifyStats stats;
  stats.reset(6);
  // Gaussians 0 (small) and 1 (large) have high gradients.
  stats.grad_sum = torch::tensor({1.0f, 1.0f, 0.f, 0.f, 0.f, 0.f});
  stats.count = torch::ones({6});
  model::DensifyOptions options;
  options.grad_threshold = 0.5;
  auto gen = at::make_generator<at::CPUGeneratorImpl>(1);
  auto r = model::densify_and_prune(g, adam, stats, options, 1.0, false, gen);
  EXPECT_EQ(r.cloned, 1);
  EXPECT_EQ(r.split, 1);
  EXPECT_EQ(r.pruned, 1);
  // 6 + 1 clone + 2 children - 1 split parent - 1 pruned.
  ASSERT_EQ(g.size(), 7);
  for (const auto& group : adam.groups()) {
    EXPECT_EQ(group.param.size(0), 7);
    EXPECT_EQ(group.exp_avg.size(0), 7);
    EXPECT_TRUE(group.param.requires_grad());
  }
  // Kept rows in order 0, 2, 3, 4, then the clone of 0, then two children of 1.
  EXPECT_TRUE(torch::equal(adam.group("sh_rest").exp_avg[2], sh_moment_row3));
  EXPECT_TRUE(torch::equal(g.means.detach()[4], means_before[0]));
  EXPECT_EQ(adam.group("means").exp_avg[4].abs().sum().item<float>(), 0.0f);
  EXPECT_NEAR(g.log_scales[5][0].item<float>(), split_log_scale, 1e-5);
  EXPECT_NEAR(g.log_scales[6][2].item<float>(), split_log_scale, 1e-5);
  EXPECT_FALSE(torch::equal(g.means[5], g.means[6]));
  EXPECT_EQ(stats.grad_sum.size(0), 7);
  EXPECT_TRUE(adam.group("means").param.is_same(g.means));
}

TEST(Densify, CountsWhyEachGaussianWasPruned) {
  torch::manual_seed(14);
  // 0 kept; 1 transparent; 2 large on screen; 3 large in the world; 4 both
  // transparent and large on screen (counted under both, pruned once).
  auto make = [] {
    auto g = make_gaussians(5, 3);
    torch::NoGradGuard no_grad;
    g.logit_opacities[1].fill_(-10.0f);
    g.logit_opacities[4].fill_(-10.0f);
    g.log_scales[3].fill_(std::log(0.5f));  // > 0.1 of an extent of 1
    return g;
  };
  auto prune = [&](double max_screen_px, bool prune_large, model::Gaussians& g) {
    auto adam = make_adam(g);
    model::DensifyStats stats;
    stats.reset(5);
    stats.max_radii = torch::tensor({3.f, 3.f, 40.f, 3.f, 40.f});
    model::DensifyOptions options;
    options.grad_threshold = 1e9;  // no growth
    options.max_screen_px = max_screen_px;
    auto gen = at::make_generator<at::CPUGeneratorImpl>(3);
    return model::densify_and_prune(g, adam, stats, options, 1.0, prune_large, gen);
  };
  auto g = make();
  auto r = prune(20, true, g);
  EXPECT_EQ(r.pruned, 4);
  EXPECT_EQ(r.pruned_transparent, 2);
  EXPECT_EQ(r.pruned_screen, 2);
  EXPECT_EQ(r.pruned_world, 1);
  ASSERT_EQ(g.size(), 1);
  // max_screen_px = 0 turns the screen criterion off.
  auto h = make();
  r = prune(0, true, h);
  EXPECT_EQ(r.pruned, 3);
  EXPECT_EQ(r.pruned_screen, 0);
  EXPECT_EQ(h.size(), 2);
  // Before the first opacity reset only transparency prunes.
  auto k = make();
  r = prune(20, false, k);
  EXPECT_EQ(r.pruned, 2);
  EXPECT_EQ(r.pruned_screen + r.pruned_world, 0);
}

TEST(Densify, RespectsTheCap) {
  torch::manual_seed(13);
  auto g = make_gaussians(10, 2);
  auto adam = make_adam(g);
  model::DensifyStats stats;
  stats.reset(10);
  stats.grad_sum = torch::linspace(0.1, 1.0, 10);
  stats.count = torch::ones({10});
  model::DensifyOptions options;
  options.grad_threshold = 0.05;
  options.max_gaussians = 13;
  auto gen = at::make_generator<at::CPUGeneratorImpl>(2);
  auto r = model::densify_and_prune(g, adam, stats, options, 1.0, false, gen);
  EXPECT_EQ(r.cloned, 3);
  EXPECT_EQ(g.size(), 13);
  // The highest-gradient Gaussians (the last three) were the ones cloned.
  EXPECT_TRUE(torch::equal(g.means.detach().slice(0, 10), g.means.detach().slice(0, 7, 10)));
}

TEST(Densify, StatsUseNdcGradientsOfVisibleGaussians) {
  model::DensifyStats stats;
  stats.reset(2);
  auto radii = torch::tensor({3, 0}, torch::kInt32);
  auto grad = torch::tensor({0.001f, 0.0f, 0.5f, 0.5f}).view({2, 2});
  stats.accumulate(radii, grad, 200, 100);
  EXPECT_NEAR(stats.grad_sum[0].item<float>(), 0.1f, 1e-6);  // 0.001 * 200 / 2
  EXPECT_EQ(stats.grad_sum[1].item<float>(), 0.0f);
  EXPECT_EQ(stats.count[1].item<float>(), 0.0f);
  EXPECT_EQ(stats.max_radii[0].item<float>(), 3.0f);
}

TEST(Densify, OpacityResetCapsAndClearsMoments) {
  auto g = make_gaussians(3, 2);
  {
    torch::NoGradGuard no_grad;
    g.logit_opacities.copy_(torch::tensor({-8.f, 0.f, 4.f}).view({3, 1}));
  }
  auto adam = make_adam(g);
  for (auto* t : g.tensors()) t->mutable_grad() = torch::ones_like(*t);
  adam.step();
  const float low = torch::sigmoid(g.logit_opacities[0][0]).item<float>();
  model::reset_opacity(g, adam, 0.01);
  auto o = torch::sigmoid(g.logit_opacities.detach()).squeeze(1);
  EXPECT_FLOAT_EQ(o[0].item<float>(), low);  // already below the cap
  EXPECT_NEAR(o[1].item<float>(), 0.01f, 1e-6);
  EXPECT_NEAR(o[2].item<float>(), 0.01f, 1e-6);
  EXPECT_EQ(adam.group("logit_opacities").exp_avg.abs().sum().item<float>(), 0.0f);
  EXPECT_GT(adam.group("means").exp_avg.abs().sum().item<float>(), 0.0f);
}

TEST(Densify, QuaternionMatrixIsARotation) {
  torch::manual_seed(14);
  auto r = model::quat_to_matrix(torch::randn({5, 4}));
  auto identity = torch::bmm(r, r.transpose(1, 2));
  EXPECT_LT((identity - torch::eye(3).expand({5, 3, 3})).abs().max().item<float>(), 1e-5);
  auto id = model::quat_to_matrix(torch::tensor({2.f, 0.f, 0.f, 0.f}).view({1, 4}));
  EXPECT_TRUE(torch::allclose(id[0], torch::eye(3)));
}
