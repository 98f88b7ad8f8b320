#include <gtest/gtest.h>

#include <cmath>

#include "core/error.h"
#include "denoiser_fixtures.h"
#include "model/unet.h"
#include "support/test_support.h"

using namespace ddhgs;

namespace {}  // namespace

TEST(UNet, GroupCountDividesChannelsWithAtLeastFourPerGroup) {
  for (int64_t c = 1; c <= 600; ++c) {
    const int64_t g = model::group_count(c);
    ASSERT_EQ(c % g, 0) << c;
    ASSERT_LE(g, 32) << c;
    if (g > 1) {
      ASSERT_GE(c / g, 4) << c;
    }
  }
  EXPECT_EQ(model::group_count(32), 8);
  EXPECT_EQ(model::group_count(128), 32);
  EXPECT_EQ(model::group_count(96), 24);
}

TEST(UNet, TimestepEmbeddingMatchesHandValues) {
  // dim 4: frequencies 10000^(-i/2) for i = 0, 1 -> 1 and 0.01.
  auto emb = model::timestep_embedding(torch::tensor({0, 3}, torch::kLong), 4);
  ASSERT_EQ(emb.sizes(), (std::vector<int64_t>{2, 4}));
  auto expected = torch::tensor(
      {{0.0, 0.0, 1.0, 1.0}, {std::sin(3.0), std::sin(0.03), std::cos(3.0), std::cos(0.03)}},
      torch::kFloat32);
  EXPECT_TRUE(torch::allclose(emb, expected, 1e-6, 1e-6)) << emb;
  EXPECT_EQ(model::timestep_embedding(torch::tensor({5}), 5).size(1), 5);
}

TEST(UNet, KeepsShapesForOddSizesAndManyBandCounts) {
  torch::manual_seed(1);
  for (int64_t bands : {1, 3, 17, 40, 128, 141}) {
    model::UNet unet(test::tiny_unet_options(bands));
    for (auto [h, w] : std::vector<std::pair<int64_t, int64_t>>{{16, 16}, {15, 11}, {1, 3}}) {
      auto x = torch::rand({2, bands, h, w});
      auto out = unet->forward(x, torch::rand({2, bands, h, w}), torch::tensor({0, 999}));
      ASSERT_EQ(out.sizes(), x.sizes()) << "N=" << bands << " " << h << "x" << w;
    }
  }
}

TEST(UNet, ThreeLevelsWithAttentionKeepShapes) {
  auto unet = test::live_unet(test::tiny_unet_options(5, {1, 2, 4}, true), 2);
  EXPECT_EQ(unet->options().size_multiple(), 4);
  auto x = torch::rand({1, 5, 13, 7});
  auto out = unet->forward(x, torch::rand({1, 5, 13, 7}), torch::tensor({10}));
  EXPECT_EQ(out.sizes(), x.sizes());
  EXPECT_TRUE(torch::isfinite(out).all().item<bool>());
  EXPECT_GT(out.abs().max().item<double>(), 0.0);
}

TEST(UNet, StartsAtPredictingZeroNoise) {
  model::UNet unet(test::tiny_unet_options(3));
  auto out =
      unet->forward(torch::rand({2, 3, 8, 8}), torch::rand({2, 3, 8, 8}), torch::tensor({1, 2}));
  EXPECT_EQ(out.abs().max().item<double>(), 0.0);
}

TEST(UNet, OutputDependsOnTimestepAndCondition) {
  auto unet = test::live_unet(test::tiny_unet_options(2), 4);
  auto x = torch::rand({1, 2, 8, 8}), cond = torch::rand({1, 2, 8, 8});
  auto base = unet->forward(x, cond, torch::tensor({100}));
  EXPECT_GT((base - unet->forward(x, cond, torch::tensor({700}))).abs().max().item<double>(), 1e-4);
  EXPECT_GT((base - unet->forward(x, cond * 0.5, torch::tensor({100}))).abs().max().item<double>(),
            1e-4);
}

// Gradients w.r.t. the condition (the render) and a weight, against central
// finite differences in double precision.
TEST(UNet, GradientsMatchFiniteDifferences) {
  auto unet = test::live_unet(test::tiny_unet_options(2, {1, 2}, true), 6);
  unet->to(torch::kFloat64);
  auto opts = torch::TensorOptions().dtype(torch::kFloat64);
  auto x = torch::rand({1, 2, 7, 5}, opts);
  auto cond = torch::rand({1, 2, 7, 5}, opts).requires_grad_(true);
  auto t = torch::tensor({321});
  auto weights = torch::randn({1, 2, 7, 5}, opts);
  auto objective = [&](const torch::Tensor& c) { return (unet->forward(x, c, t) * weights).sum(); };
  objective(cond).backward();
  auto grad = cond.grad().clone();
  ASSERT_GT(grad.abs().max().item<double>(), 0.0);

  torch::NoGradGuard no_grad;
  const double h = 1e-6;
  auto flat_grad = grad.flatten();
  for (int64_t i : {0, 9, 17, 34, 69}) {
    auto plus = cond.detach().clone(), minus = cond.detach().clone();
    plus.view(-1)[i] += h;
    minus.view(-1)[i] -= h;
    const double fd = (objective(plus).item<double>() - objective(minus).item<double>()) / (2 * h);
    EXPECT_NEAR(flat_grad[i].item<double>(), fd, 1e-6 + 1e-5 * std::abs(fd)) << "cond[" << i << "]";
  }
  // A weight of the first level's first block, so upstream layers train too.
  auto weight = unet->named_parameters()["down.0.conv1.weight"];
  const double analytic = weight.grad().view(-1)[5].item<double>();
  ASSERT_NE(analytic, 0.0);
  weight.view(-1)[5] += h;
  const double up = objective(cond).item<double>();
  weight.view(-1)[5] -= 2 * h;
  const double down = objective(cond).item<double>();
  EXPECT_NEAR(analytic, (up - down) / (2 * h), 1e-6 + 1e-5 * std::abs(analytic));
}

TEST(UNet, OptionsFromJsonReadPresetKeysAndRejectBadValues) {
  auto o = model::unet_options_from_json(
      nlohmann::json::parse(
          R"({"base_channels": 16, "channel_multipliers": [1, 2], "attention": true})"),
      "preset.json");
  EXPECT_EQ(o.base_channels, 16);
  EXPECT_EQ(o.channel_multipliers, (std::vector<int64_t>{1, 2}));
  EXPECT_EQ(o.blocks_per_level, 1);
  EXPECT_TRUE(o.attention);
  EXPECT_THROW(model::unet_options_from_json(nlohmann::json::parse(R"({"base_channels": "x"})"),
                                             "preset.json"),
               core::Error);
  try {
    model::unet_options_from_json(nlohmann::json::parse(R"({"channel_multipliers": [1, 0]})"),
                                  "preset.json");
    FAIL() << "zero multiplier accepted";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("preset.json"), std::string::npos) << e.what();
  }
}

TEST(UNet, CheckpointRoundTripRestoresOptionsAndOutputs) {
  auto unet = test::live_unet(test::tiny_unet_options(4, {1, 2, 2}, true), 8);
  const auto file = test::temp_dir("unet_roundtrip") / "ckpt.pt";
  {
    torch::serialize::OutputArchive archive;
    model::save_unet(archive, "denoiser", unet);
    archive.save_to(file.string());
  }
  torch::serialize::InputArchive archive;
  archive.load_from(file.string());
  auto loaded = model::load_unet(archive, "denoiser", file);
  EXPECT_EQ(loaded->options().bands, 4);
  EXPECT_EQ(loaded->options().channel_multipliers, (std::vector<int64_t>{1, 2, 2}));
  EXPECT_TRUE(loaded->options().attention);
  auto x = torch::rand({1, 4, 9, 10}), cond = torch::rand({1, 4, 9, 10});
  auto t = torch::tensor({42});
  EXPECT_TRUE(torch::equal(unet->forward(x, cond, t), loaded->forward(x, cond, t)));

  try {
    model::load_unet(archive, "missing", file);
    FAIL() << "missing key accepted";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
  }
}
