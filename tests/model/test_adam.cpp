#include <gtest/gtest.h>
#include <torch/optim/adam.h>

#include <cmath>

#include "model/adam.h"

using namespace ddhgs;

TEST(Adam, FusedStepMatchesTorchAdamOverSeveralSteps) {
  torch::manual_seed(7);
  auto a0 = torch::randn({64, 5, 15});
  auto b0 = torch::randn({33, 3});
  auto a = a0.clone().requires_grad_(true);
  auto b = b0.clone().requires_grad_(true);
  auto ra = a0.clone().requires_grad_(true);
  auto rb = b0.clone().requires_grad_(true);

  model::Adam fused({0.9, 0.999, 1e-15});
  fused.add("a", a, 2.5e-3);
  fused.add("b", b, 1e-2);
  std::vector<torch::optim::OptimizerParamGroup> groups;
  groups.emplace_back(std::vector<torch::Tensor>{ra},
                      std::make_unique<torch::optim::AdamOptions>(2.5e-3));
  groups.emplace_back(std::vector<torch::Tensor>{rb},
                      std::make_unique<torch::optim::AdamOptions>(1e-2));
  for (auto& g : groups) static_cast<torch::optim::AdamOptions&>(g.options()).eps(1e-15);
  torch::optim::Adam reference(groups);

  for (int step = 0; step < 6; ++step) {
    auto ga = torch::randn(a.sizes()) * (step + 1);
    auto gb = torch::randn(b.sizes()) * 1e-3;
    a.mutable_grad() = ga.clone();
    b.mutable_grad() = gb.clone();
    ra.mutable_grad() = ga.clone();
    rb.mutable_grad() = gb.clone();
    fused.step();
    reference.step();
  }
  EXPECT_LT((a - ra).abs().max().item<double>(), 1e-6);
  EXPECT_LT((b - rb).abs().max().item<double>(), 1e-6);
  EXPECT_EQ(fused.group("a").step, 6);
  // The parameter actually moved.
  EXPECT_GT((a - a0).abs().max().item<double>(), 1e-3);
}

TEST(Adam, RowStepInBlocksEqualsTheWholeStepBitForBit) {
  torch::manual_seed(9);
  auto start = torch::randn({50, 7, 15});
  auto whole = start.clone().requires_grad_(true);
  auto rows = start.clone().requires_grad_(true);
  model::Adam a({0.9, 0.999, 1e-15}), b({0.9, 0.999, 1e-15});
  a.add("p", whole, 2e-3);
  b.add("p", rows, 2e-3);
  // Blocks of uneven sizes, delivered out of order, as threads would.
  const std::vector<std::pair<int64_t, int64_t>> blocks = {{32, 18}, {0, 7}, {7, 25}};
  for (int step = 0; step < 4; ++step) {
    auto grad = torch::randn(start.sizes()) * (step + 1);
    if (step == 2) grad.slice(0, 10, 20).zero_();  // rows the view did not touch
    whole.mutable_grad() = grad.clone();
    a.step();
    a.zero_grad();
    auto update = b.row_step("p");
    for (const auto& [first, count] : blocks)
      update(first, count, grad.slice(0, first, first + count).contiguous().data_ptr<float>());
    b.step();  // skips the group: its .grad() is undefined
  }
  EXPECT_EQ(a.group("p").step, 4);
  EXPECT_EQ(b.group("p").step, 4);
  EXPECT_TRUE(torch::equal(whole, rows));
  EXPECT_TRUE(torch::equal(a.group("p").exp_avg, b.group("p").exp_avg));
  EXPECT_TRUE(torch::equal(a.group("p").exp_avg_sq, b.group("p").exp_avg_sq));
}

TEST(Adam, StepOnRowsLeavesTheOtherRowsAndTheirMomentsAsTheyWere) {
  torch::manual_seed(4);
  auto start = torch::randn({12, 3});
  auto sparse = start.clone().requires_grad_(true);
  auto dense = start.clone().requires_grad_(true);
  auto other = start.clone().requires_grad_(true);
  model::Adam a({0.9, 0.999, 1e-15}), b({0.9, 0.999, 1e-15});
  a.add("band/p", sparse, 1e-2);
  a.add("other", other, 1e-2);
  b.add("band/p", dense, 1e-2);
  const std::vector<std::vector<int64_t>> draws = {{0, 5, 9}, {1, 5, 11}, {2, 6, 9}};
  for (const auto& draw : draws) {
    const auto grad = torch::randn(start.sizes());
    const auto rows = torch::tensor(draw, torch::kInt64);
    auto undrawn = torch::ones({12}, torch::kBool);
    undrawn.index_fill_(0, rows, false);
    // Reference: the whole step, then the undrawn rows put back.
    const auto keep = dense.detach().index({undrawn}).clone();
    const auto keep_m = b.group("band/p").exp_avg.index({undrawn}).clone();
    const auto keep_v = b.group("band/p").exp_avg_sq.index({undrawn}).clone();
    dense.mutable_grad() = grad.clone();
    b.step();
    {
      torch::NoGradGuard no_grad;
      dense.index_put_({undrawn}, keep);
    }
    b.group("band/p").exp_avg.index_put_({undrawn}, keep_m);
    b.group("band/p").exp_avg_sq.index_put_({undrawn}, keep_v);
    sparse.mutable_grad() = grad.clone();
    other.mutable_grad() = grad.clone();
    a.step({{{"band/"}, rows}});
    EXPECT_TRUE(torch::equal(sparse.index({undrawn}), keep));
  }
  EXPECT_TRUE(torch::equal(sparse, dense));
  EXPECT_TRUE(torch::equal(a.group("band/p").exp_avg, b.group("band/p").exp_avg));
  EXPECT_TRUE(torch::equal(a.group("band/p").exp_avg_sq, b.group("band/p").exp_avg_sq));
  // A group the prefixes do not name takes every row: all of it moved.
  EXPECT_TRUE(((other - start).abs() > 0).all().item<bool>());
  EXPECT_EQ(a.group("band/p").step, 3);
}

// Two row sets: each group steps the rows of the first set that names it.
TEST(Adam, EachRowSetStepsItsOwnGroupsRows) {
  torch::manual_seed(5);
  auto bands = torch::randn({6, 2}).requires_grad_(true);
  auto views = torch::randn({4, 3}).requires_grad_(true);
  const auto bands_start = bands.detach().clone(), views_start = views.detach().clone();
  model::Adam adam;
  adam.add("colour/basis", bands, 1e-2);
  adam.add("exposure/log_gain", views, 1e-2);
  bands.mutable_grad() = torch::ones({6, 2});
  views.mutable_grad() = torch::ones({4, 3});
  adam.step({{{"colour/"}, torch::tensor({1, 4}, torch::kInt64)},
             {{"exposure/", "colour/"}, torch::tensor({2}, torch::kInt64)}});
  const auto moved = [](const torch::Tensor& now, const torch::Tensor& before) {
    return (now.detach() != before).any(1);
  };
  EXPECT_TRUE(torch::equal(moved(bands, bands_start),
                           torch::tensor({false, true, false, false, true, false})));
  EXPECT_TRUE(torch::equal(moved(views, views_start), torch::tensor({false, false, true, false})));
}

TEST(Adam, SkipsParametersWithoutGradients) {
  auto p = torch::ones({4}).requires_grad_(true);
  model::Adam adam;
  adam.add("p", p, 0.1);
  adam.step();
  EXPECT_TRUE(torch::equal(p, torch::ones({4})));
  EXPECT_EQ(adam.group("p").step, 0);
  EXPECT_THROW(adam.add("p", p, 0.1), std::exception);
  EXPECT_THROW(adam.group("q"), std::exception);
}

TEST(Adam, RemapRowsMovesMomentsAndZeroesNewRows) {
  auto p = torch::arange(6, torch::kFloat32).view({3, 2}).requires_grad_(true);
  model::Adam adam;
  adam.add("p", p, 0.1);
  p.mutable_grad() = torch::ones({3, 2});
  adam.step();
  auto m = adam.group("p").exp_avg.clone();
  auto index = torch::tensor({2, -1, 0}, torch::kInt64);
  auto next = torch::zeros({3, 2}).requires_grad_(true);
  adam.remap_rows("p", next, index);
  const auto& g = adam.group("p");
  EXPECT_TRUE(torch::equal(g.exp_avg[0], m[2]));
  EXPECT_TRUE(torch::equal(g.exp_avg[1], torch::zeros({2})));
  EXPECT_TRUE(torch::equal(g.exp_avg[2], m[0]));
  EXPECT_TRUE(g.param.is_same(next));
}

TEST(Adam, SaveAndLoadRestoreTheState) {
  auto p = torch::randn({5, 2}).requires_grad_(true);
  model::Adam adam;
  adam.add("p", p, 0.1);
  p.mutable_grad() = torch::randn({5, 2});
  adam.step();
  torch::serialize::OutputArchive out;
  adam.save(out);
  std::ostringstream bytes;
  out.save_to(bytes);

  model::Adam restored;
  restored.add("p", p, 0.5);
  torch::serialize::InputArchive in;
  std::istringstream stream(bytes.str());
  in.load_from(stream);
  restored.load(in, "ckpt.pt");
  EXPECT_EQ(restored.group("p").step, 1);
  EXPECT_DOUBLE_EQ(restored.group("p").lr, 0.1);
  EXPECT_TRUE(torch::equal(restored.group("p").exp_avg_sq, adam.group("p").exp_avg_sq));

  model::Adam other;
  other.add("q", p, 0.1);
  torch::serialize::InputArchive in2;
  std::istringstream stream2(bytes.str());
  in2.load_from(stream2);
  EXPECT_THROW(other.load(in2, "ckpt.pt"), std::exception);
}

TEST(Adam, CoastingIsAStepWithZeroGradientsOnTheGroupsNamed) {
  torch::manual_seed(11);
  auto start = torch::randn({40, 3});
  auto other_start = torch::randn({5});
  auto coasting = start.clone().requires_grad_(true),
       reference = start.clone().requires_grad_(true);
  auto other = other_start.clone().requires_grad_(true);
  model::Adam a, b;
  a.add("means", coasting, 1e-2);
  a.add("other", other, 1e-2);
  b.add("means", reference, 1e-2);
  for (int step = 0; step < 3; ++step) {  // moments to move on
    const auto grad = torch::randn({40, 3});
    coasting.mutable_grad() = grad.clone();
    reference.mutable_grad() = grad.clone();
    a.step();
    b.step();
    a.zero_grad();
  }
  for (int step = 0; step < 4; ++step) {
    a.coast({"means"});
    reference.mutable_grad() = torch::zeros({40, 3});
    b.step();
  }
  EXPECT_TRUE(torch::equal(coasting, reference));
  EXPECT_TRUE(torch::equal(a.group("means").exp_avg, b.group("means").exp_avg));
  EXPECT_TRUE(torch::equal(a.group("means").exp_avg_sq, b.group("means").exp_avg_sq));
  EXPECT_EQ(a.group("means").step, 7);
  // It moved on its momentum, and the group not named did not move at all.
  EXPECT_GT((coasting - start).abs().max().item<double>(), 0);
  EXPECT_TRUE(torch::equal(other, other_start));
  EXPECT_EQ(a.group("other").step, 0);
  EXPECT_FALSE(coasting.grad().defined());
}

TEST(Adam, ExponentialScheduleIsLogLinear) {
  EXPECT_NEAR(model::exponential_lr(0, 1.6e-4, 1.6e-6, 30000), 1.6e-4, 1e-12);
  EXPECT_NEAR(model::exponential_lr(15000, 1.6e-4, 1.6e-6, 30000), 1.6e-5, 1e-12);
  EXPECT_NEAR(model::exponential_lr(30000, 1.6e-4, 1.6e-6, 30000), 1.6e-6, 1e-14);
  EXPECT_NEAR(model::exponential_lr(90000, 1.6e-4, 1.6e-6, 30000), 1.6e-6, 1e-14);
  // The warm-up starts at delay_mult times the schedule.
  EXPECT_NEAR(model::exponential_lr(0, 1.0, 1.0, 100, 10, 0.01), 0.01, 1e-12);
}
