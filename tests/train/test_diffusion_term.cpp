// The joint-training diffusion term: config keys, warm-up, seeded draws,
// gradients into the U-Net and through the condition into the render, and
// the denoiser file.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "core/error.h"
#include "io/files/atomic_file.h"
#include "support/error_text.h"
#include "support/test_support.h"
#include "train/config.h"
#include "train/diffusion_term.h"
#include "train/run_config.h"

namespace ddhgs {
namespace {

using train::DiffusionTerm;
using train::DiffusionTermOptions;

using test::error_of;

DiffusionTermOptions tiny_options(int64_t bands, int64_t crop_px) {
  DiffusionTermOptions o;
  o.weight = 0.3;
  o.warmup = 5;
  o.crop_px = crop_px;
  o.unet.bands = bands;
  o.unet.base_channels = 8;
  o.unet.channel_multipliers = {1, 2};
  o.schedule_steps = 100;
  return o;
}

// The U-Net's last layer starts at zero (no gradient reaches the render);
// a random one makes every path live.
void randomise_last_layer(model::UNet& unet, uint64_t seed) {
  torch::NoGradGuard no_grad;
  auto generator = at::make_generator<at::CPUGeneratorImpl>(seed);
  for (auto& p : unet->named_parameters())
    if (p.key().rfind("output_conv.", 0) == 0)
      p.value().copy_(0.1 * torch::randn(p.value().sizes(), generator, p.value().options()));
}

torch::Tensor random_view(uint64_t seed, int64_t h, int64_t w, int64_t n,
                          torch::Dtype dtype = torch::kFloat32) {
  auto generator = at::make_generator<at::CPUGeneratorImpl>(seed);
  return torch::rand({h, w, n}, generator, torch::TensorOptions().dtype(dtype));
}

TEST(DiffusionTerm, OptionsComeFromLossDiffusionAndTheDiffusionSection) {
  auto config = train::load_preset("default");
  EXPECT_EQ(train::with_bands(train::parse_run_config(config, "default").diffusion, 7).enabled(),
            false);
  train::set_key(config, "loss.diffusion", "0.3");
  train::set_key(config, "diffusion.crop", "24");
  train::set_key(config, "diffusion.schedule", "cosine");
  train::set_key(config, "diffusion.channel_multipliers", "[1, 2]");
  train::set_key(config, "diffusion.start_strength", "0.25");
  train::set_key(config, "diffusion.prediction", "\"residual\"");
  train::set_key(config, "diffusion.min_snr_gamma", "5");
  train::set_key(config, "seed", "9");
  auto o = train::with_bands(train::parse_run_config(config, "default").diffusion, 7);
  EXPECT_EQ(o.prediction, model::Prediction::Residual);
  EXPECT_DOUBLE_EQ(o.min_snr_gamma, 5.0);
  EXPECT_EQ(DiffusionTerm(o, 1).denoiser().prediction, model::Prediction::Residual);
  EXPECT_TRUE(o.enabled());
  EXPECT_DOUBLE_EQ(o.weight, 0.3);
  EXPECT_EQ(o.crop_px, 24);
  EXPECT_EQ(o.unet.bands, 7);
  EXPECT_EQ(o.unet.channel_multipliers, (std::vector<int64_t>{1, 2}));
  EXPECT_EQ(o.schedule, model::BetaSchedule::Cosine);
  EXPECT_DOUBLE_EQ(o.sampler.start_strength, 0.25);
  EXPECT_EQ(o.sampler.seed, 9u);

  auto bad = config;
  train::set_key(bad, "diffusion.schedule", "quadratic");
  EXPECT_NE(error_of([&] {
              train::with_bands(train::parse_run_config(bad, "preset.json").diffusion, 7);
            }).find("cosine"),
            std::string::npos);
  bad = config;
  train::set_key(bad, "diffusion.prediction", "\"x0\"");
  EXPECT_NE(error_of([&] {
              train::with_bands(train::parse_run_config(bad, "preset.json").diffusion, 7);
            }).find("preset.json: diffusion: prediction must be"),
            std::string::npos);
  bad = config;
  bad["diffusion"]["start_strength"] = 0;  // as a hand-edited config.json holds it
  EXPECT_NE(error_of([&] {
              train::with_bands(train::parse_run_config(bad, "preset.json").diffusion, 7);
            }).find("preset.json: key 'diffusion.start_strength' is 0"),
            std::string::npos);
  bad = config;
  bad["diffusion"]["lr"] = -1;
  EXPECT_NE(error_of([&] {
              train::with_bands(train::parse_run_config(bad, "preset.json").diffusion, 7);
            }).find("diffusion.lr"),
            std::string::npos);
}

TEST(DiffusionTerm, ZeroDuringWarmupThenSeededByTheIteration) {
  DiffusionTerm term(tiny_options(4, 8), 1);
  train::LossTerm loss = term.loss_term();
  EXPECT_EQ(loss.name, "diffusion");
  EXPECT_DOUBLE_EQ(loss.weight, 0.3);
  auto render = random_view(2, 12, 10, 4).requires_grad_(true);
  auto target = random_view(3, 12, 10, 4);

  auto during = loss.compute({render, target, 0, 5, 11});
  EXPECT_EQ(during.item<double>(), 0.0);
  EXPECT_FALSE(during.requires_grad());

  const double a = loss.compute({render, target, 0, 6, 11}).item<double>();
  const double again = loss.compute({render, target, 0, 6, 11}).item<double>();
  const double other = loss.compute({render, target, 0, 6, 12}).item<double>();
  EXPECT_TRUE(std::isfinite(a));
  EXPECT_GT(a, 0.1);  // a zero-output U-Net: the loss is the noise's mean square, ~1
  EXPECT_EQ(a, again);
  EXPECT_NE(a, other);
}

TEST(DiffusionTerm, GradientReachesTheUNetAndOnlyTheCropOfTheRender) {
  DiffusionTerm term(tiny_options(3, 6), 4);
  randomise_last_layer(term.denoiser().unet, 5);
  auto render = random_view(6, 12, 10, 3).requires_grad_(true);
  auto target = random_view(7, 12, 10, 3);
  term.loss_term().compute({render, target, 0, 10, 99}).backward();
  for (auto& p : term.denoiser().unet->named_parameters())
    ASSERT_TRUE(p.value().grad().defined()) << p.key();
  ASSERT_TRUE(render.grad().defined());
  auto touched = render.grad().abs().sum(2) > 0;  // [H, W]
  EXPECT_EQ(touched.any(1).sum().item<int64_t>(), 6);
  EXPECT_EQ(touched.any(0).sum().item<int64_t>(), 6);

  auto options = tiny_options(3, 6);
  options.condition_grad = false;
  DiffusionTerm detached(options, 4);
  randomise_last_layer(detached.denoiser().unet, 5);
  auto render2 = random_view(6, 12, 10, 3).requires_grad_(true);
  auto value = detached.loss_term().compute({render2, target, 0, 10, 99});
  // The same draws and weights: the same value, but the render gets nothing.
  auto with_grad = term.loss_term().compute({render, target, 0, 10, 99});
  EXPECT_EQ(value.item<double>(), with_grad.item<double>());
  auto unused = torch::autograd::grad({value}, {render2}, {}, true, false, /*allow_unused=*/true);
  EXPECT_FALSE(unused[0].defined());
}

TEST(DiffusionTerm, RenderGradientMatchesFiniteDifferences) {
  auto options = tiny_options(3, 0);
  DiffusionTerm term(options, 8);
  randomise_last_layer(term.denoiser().unet, 9);
  term.denoiser().unet->to(torch::kFloat64);
  auto render = random_view(10, 8, 8, 3, torch::kFloat64).requires_grad_(true);
  auto target = random_view(11, 8, 8, 3, torch::kFloat64);
  auto f = [&](const torch::Tensor& r) {
    return train::diffusion_term_loss(term.denoiser(), options, r, target, 77);
  };
  auto grad = torch::autograd::grad({f(render)}, {render})[0];
  auto direction = random_view(12, 8, 8, 3, torch::kFloat64) - 0.5;
  const double h = 1e-5;
  torch::NoGradGuard no_grad;
  const double numeric =
      (f(render + h * direction).item<double>() - f(render - h * direction).item<double>()) /
      (2 * h);
  const double analytic = (grad * direction).sum().item<double>();
  EXPECT_GT(std::abs(analytic), 1e-4);
  EXPECT_NEAR(analytic, numeric, 1e-6 + 1e-5 * std::abs(numeric));
}

TEST(DiffusionTerm, ConditionNoiseChangesTheTermDeterministically) {
  auto options = tiny_options(3, 0);
  DiffusionTerm term(options, 13);
  randomise_last_layer(term.denoiser().unet, 14);
  auto render = random_view(15, 8, 8, 3);
  auto target = random_view(16, 8, 8, 3);
  auto plain = train::diffusion_term_loss(term.denoiser(), options, render, target, 5);
  options.condition_noise = 0.05;
  auto noisy = train::diffusion_term_loss(term.denoiser(), options, render, target, 5);
  auto noisy_again = train::diffusion_term_loss(term.denoiser(), options, render, target, 5);
  EXPECT_NE(plain.item<double>(), noisy.item<double>());
  EXPECT_EQ(noisy.item<double>(), noisy_again.item<double>());
}

TEST(DiffusionFinetune, OptionsAndLearningRateSchedule) {
  auto config = train::load_preset("default");
  train::set_key(config, "loss.diffusion", "0.3");
  train::set_key(config, "diffusion.finetune_steps", "250");
  train::set_key(config, "diffusion.finetune_batch", "3");
  train::set_key(config, "diffusion.finetune_crop", "32");
  auto o = train::with_bands(train::parse_run_config(config, "default").diffusion, 4);
  EXPECT_EQ(o.finetune_steps, 250);
  EXPECT_EQ(o.finetune_batch, 3);
  EXPECT_EQ(o.finetune_crop, 32);
  config["diffusion"]["finetune_batch"] = 0;
  EXPECT_NE(error_of([&] {
              train::with_bands(train::parse_run_config(config, "preset.json").diffusion, 4);
            }).find("preset.json: key 'diffusion.finetune_batch' is 0"),
            std::string::npos);

  // The pair-source keys: the defaults are the paper's stage, then each one read.
  config["diffusion"]["finetune_batch"] = 3;
  o = train::parse_run_config(config, "default").diffusion;
  EXPECT_TRUE(o.joint);
  EXPECT_EQ(o.pairs, train::FinetunePairs::Training);
  EXPECT_EQ(o.distill_steps, 0);
  train::set_key(config, "diffusion.joint", "false");
  train::set_key(config, "diffusion.pairs", "folds");
  train::set_key(config, "diffusion.folds", "3");
  train::set_key(config, "diffusion.fold_iterations", "0.25");
  train::set_key(config, "diffusion.distill_steps", "70");
  train::set_key(config, "diffusion.distill_weight", "0.2");
  train::set_key(config, "diffusion.distill_every", "3");
  train::set_key(config, "diffusion.validation_every", "0");
  o = train::parse_run_config(config, "default").diffusion;
  EXPECT_FALSE(o.joint);
  EXPECT_EQ(o.pairs, train::FinetunePairs::Folds);
  EXPECT_EQ(o.folds, 3);
  EXPECT_EQ(o.fold_iterations, 0.25);
  EXPECT_EQ(o.distill_steps, 70);
  EXPECT_EQ(o.distill_weight, 0.2);
  EXPECT_EQ(o.distill_every, 3);
  EXPECT_EQ(o.validation_every, 0);
  EXPECT_EQ(o.perturb_px, 2.0);
  train::set_key(config, "diffusion.pairs", "perturbed");
  train::set_key(config, "diffusion.perturb_px", "2.5");
  o = train::parse_run_config(config, "default").diffusion;
  EXPECT_EQ(o.pairs, train::FinetunePairs::Perturbed);
  EXPECT_EQ(o.perturb_px, 2.5);
  EXPECT_EQ(train::to_string(o.pairs), "perturbed");
  train::set_key(config, "diffusion.pairs", "checkpoint");
  EXPECT_EQ(train::parse_run_config(config, "default").diffusion.pairs,
            train::FinetunePairs::Checkpoint);
  train::set_key(config, "diffusion.pairs", "views");
  EXPECT_NE(error_of([&] { train::parse_run_config(config, "preset.json"); })
                .find("preset.json: diffusion: pairs is 'views'; expected 'training', 'folds', "
                      "'checkpoint' or 'perturbed'"),
            std::string::npos);
  config["diffusion"]["pairs"] = "folds";
  config["diffusion"]["perturb_px"] = -1;
  EXPECT_NE(error_of([&] {
              train::parse_run_config(config, "preset.json");
            }).find("preset.json: key 'diffusion.perturb_px' is -1"),
            std::string::npos);
  config["diffusion"]["perturb_px"] = 2.0;
  config["diffusion"]["pairs"] = "folds";
  config["diffusion"]["folds"] = 1;  // one fold would hold every view out
  EXPECT_NE(error_of([&] {
              train::parse_run_config(config, "preset.json");
            }).find("preset.json: key 'diffusion.folds' is 1"),
            std::string::npos);

  // Cosine from lr to 0: lr (1 + cos(pi k / K)) / 2.
  EXPECT_DOUBLE_EQ(train::finetune_lr(4e-4, 0, 100), 4e-4);
  EXPECT_NEAR(train::finetune_lr(4e-4, 50, 100), 2e-4, 1e-15);
  EXPECT_NEAR(train::finetune_lr(4e-4, 25, 100), 2e-4 * (1 + std::sqrt(0.5)), 1e-15);
  EXPECT_NEAR(train::finetune_lr(4e-4, 99, 100), 2e-4 * (1 - std::cos(3.14159265358979 / 100)),
              1e-15);
}

TEST(DiffusionFinetune, LossTrainsOnlyTheUNetAndTheIdentityLossIsItsUntrainedValue) {
  auto o = tiny_options(3, 8);
  o.prediction = model::Prediction::Residual;
  o.min_snr_gamma = 5;
  o.finetune_batch = 3;
  o.finetune_crop = 6;
  DiffusionTerm term(o, 30);
  std::vector<torch::Tensor> renders, targets;
  for (uint64_t v = 0; v < 4; ++v) {
    renders.push_back(random_view(40 + v, 10, 9, 3).requires_grad_(true));
    targets.push_back(random_view(50 + v, 10, 9, 3));
  }
  int fetched = 0;
  train::FinetuneView view = [&](size_t i) {
    ++fetched;
    return std::make_pair(renders[i], targets[i]);
  };
  // Untrained (zero last layer): the U-Net's loss is the render-as-is loss.
  auto untrained = train::finetune_losses(term.denoiser(), o, renders.size(), view, 7);
  EXPECT_EQ(fetched, 3);  // each drawn view fetched once for both losses
  EXPECT_NEAR(untrained.loss.item<double>(), untrained.identity.item<double>(),
              1e-6 * untrained.identity.item<double>());
  EXPECT_FALSE(untrained.identity.requires_grad());
  const double identity = untrained.identity.item<double>();
  EXPECT_NE(
      identity,
      train::finetune_losses(term.denoiser(), o, renders.size(), view, 8).identity.item<double>());

  randomise_last_layer(term.denoiser().unet, 31);
  auto trained = train::finetune_losses(term.denoiser(), o, renders.size(), view, 7);
  EXPECT_NE(trained.loss.item<double>(), identity);
  EXPECT_EQ(trained.identity.item<double>(), identity);  // independent of the U-Net
  trained.loss.backward();
  for (const auto& r : renders) EXPECT_FALSE(r.grad().defined());
  double unet_grad = 0;
  for (const auto& p : term.denoiser().unet->parameters())
    if (p.grad().defined()) unet_grad += p.grad().abs().sum().item<double>();
  EXPECT_GT(unet_grad, 0.0);
  // Seeded: the same seed gives the same loss.
  EXPECT_EQ(train::finetune_losses(term.denoiser(), o, renders.size(), view, 7).loss.item<double>(),
            trained.loss.item<double>());
}

TEST(DiffusionTerm, DenoiserFileRoundTripsAndRejectsBadFiles) {
  DiffusionTerm term(tiny_options(5, 0), 17);
  randomise_last_layer(term.denoiser().unet, 18);
  const auto dir = test::temp_dir("diffusion_term_file");
  const auto path = train::denoiser_path({dir});
  EXPECT_EQ(path, dir / "denoiser.pt");
  train::write_denoiser(path, term.denoiser());
  model::Denoiser loaded = train::read_denoiser(path);
  EXPECT_EQ(loaded.schedule.steps, 100);
  auto render = random_view(19, 9, 7, 5);
  model::SamplerOptions sampler;
  sampler.steps = 3;
  sampler.start_strength = 0.3;
  auto a = model::denoise_view(term.denoiser(), render, sampler);
  auto b = model::denoise_view(loaded, render, sampler);
  EXPECT_TRUE(torch::equal(a, b));

  EXPECT_NE(error_of([&] { train::read_denoiser(dir / "missing.pt"); }).find("missing.pt"),
            std::string::npos);
  const std::string bytes = io::read_file(path);
  io::write_file_atomically(dir / "cut.pt", bytes.substr(0, bytes.size() / 2));
  EXPECT_NE(error_of([&] { train::read_denoiser(dir / "cut.pt"); }).find("cut.pt: "),
            std::string::npos);
}

}  // namespace
}  // namespace ddhgs
