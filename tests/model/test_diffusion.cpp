#include <gtest/gtest.h>
#include <torch/optim/adam.h>

#include <cmath>

#include "core/error.h"
#include "denoiser_fixtures.h"
#include "model/diffusion.h"
#include "support/test_support.h"

using namespace ddhgs;

namespace {

constexpr double kPi = 3.14159265358979323846;

double value_at(const torch::Tensor& table, int64_t t) {
  return table[t].item<double>();
}

torch::Tensor abar_of(const model::NoiseSchedule& schedule, const torch::Tensor& t,
                      const torch::Tensor& like) {
  return schedule.alphas_cumprod.index_select(0, t).to(like.dtype()).reshape({-1, 1, 1, 1});
}

// The exact noise predictor when every sample's clean image is x0 (model
// space): eps = (x_t - sqrt(abar) x0) / sqrt(1 - abar).
model::NoisePredictor point_predictor(const model::NoiseSchedule& schedule,
                                      const torch::Tensor& x0_model) {
  return [&schedule, x0_model](const torch::Tensor& x_t, const torch::Tensor&,
                               const torch::Tensor& t) {
    auto abar = abar_of(schedule, t, x_t);
    return (x_t - abar.sqrt() * x0_model) / (1 - abar).sqrt();
  };
}

// The exact (posterior-mean) noise predictor for pixels drawn independently
// from N(mean, var) in model space: x_t ~ N(a mean, a^2 var + b^2), so
// E[eps | x_t] = b (x_t - a mean) / (a^2 var + b^2).
model::NoisePredictor gaussian_predictor(const model::NoiseSchedule& schedule, double mean,
                                         double var) {
  return [&schedule, mean, var](const torch::Tensor& x_t, const torch::Tensor&,
                                const torch::Tensor& t) {
    auto abar = abar_of(schedule, t, x_t);
    auto a = abar.sqrt(), b = (1 - abar).sqrt();
    return b * (x_t - a * mean) / (abar * var + (1 - abar));
  };
}

}  // namespace

TEST(NoiseSchedule, LinearConstantsMatchClosedForms) {
  model::NoiseSchedule s;  // T = 1000, linear 1e-4 .. 0.02
  ASSERT_EQ(s.steps, 1000);
  ASSERT_EQ(s.alphas_cumprod.scalar_type(), torch::kFloat32);
  EXPECT_NEAR(s.beta(0), 1e-4, 1e-12);
  EXPECT_NEAR(s.beta(999), 0.02, 1e-12);
  EXPECT_NEAR(s.beta(500), 1e-4 + (0.02 - 1e-4) * 500.0 / 999.0, 1e-12);
  double product = 1.0;
  for (int64_t t = 0; t < 1000; ++t) {
    const double beta = 1e-4 + (0.02 - 1e-4) * double(t) / 999.0;
    const double prev = product;
    product *= 1.0 - beta;
    if (t % 111 != 0 && t != 999) continue;
    EXPECT_NEAR(s.beta(t), beta, 1e-12) << t;
    EXPECT_NEAR(s.alpha_bar(t), product, 1e-12) << t;
    EXPECT_NEAR(s.alpha_bar_prev(t), prev, 1e-12) << t;
    EXPECT_NEAR(value_at(s.alphas_cumprod, t), product, 1e-6 * product + 1e-9) << t;
    EXPECT_NEAR(value_at(s.sqrt_alphas_cumprod, t), std::sqrt(product), 1e-6) << t;
    EXPECT_NEAR(value_at(s.sqrt_one_minus_alphas_cumprod, t), std::sqrt(1 - product), 1e-6) << t;
    const auto q = s.posterior(t);
    const double var = beta * (1 - prev) / (1 - product);
    EXPECT_NEAR(q.variance, var, 1e-9 * var + 1e-15) << t;
    EXPECT_NEAR(q.coef_x0, std::sqrt(prev) * beta / (1 - product), 1e-9) << t;
    EXPECT_NEAR(q.coef_xt, std::sqrt(1 - beta) * (1 - prev) / (1 - product), 1e-9) << t;
  }
  // Known value of the standard DDPM schedule: almost no signal left at T.
  EXPECT_NEAR(value_at(s.alphas_cumprod, 999), 4.04e-5, 0.01e-5);
  EXPECT_EQ(s.posterior(0).variance, 0.0);
  EXPECT_EQ(s.alphas_cumprod_f64().size(), 1000u);
}

TEST(NoiseSchedule, CosineFollowsNicholDhariwal) {
  model::NoiseSchedule s(1000, model::BetaSchedule::Cosine);
  auto f = [](double t) {
    const double c = std::cos((t / 1000.0 + 0.008) / 1.008 * kPi / 2);
    return c * c;
  };
  for (int64_t t : {0, 1, 250, 500, 750, 900}) {
    const double abar = f(double(t + 1)) / f(0.0);
    EXPECT_NEAR(value_at(s.alphas_cumprod, t), abar, 1e-6 + 1e-5 * abar) << t;
    EXPECT_NEAR(s.beta(t), 1 - f(double(t + 1)) / f(double(t)), 1e-9) << t;
  }
  // f(T) = 0 would make the last beta 1: it is clipped.
  EXPECT_NEAR(s.beta(999), 0.999, 1e-9);
  for (int64_t t = 0; t < 1000; ++t) EXPECT_LE(s.beta(t), 0.999 + 1e-9) << t;
  EXPECT_EQ(model::parse_beta_schedule("cosine", "x"), model::BetaSchedule::Cosine);
  EXPECT_THROW(model::parse_beta_schedule("sigmoid", "preset.json"), core::Error);
}

TEST(NoiseSchedule, QSampleMixesPerSample) {
  model::NoiseSchedule s;
  auto x0 = torch::full({2, 1, 2, 2}, 0.5), eps = torch::full({2, 1, 2, 2}, -1.0);
  auto t = torch::tensor({0, 999});
  auto x_t = model::q_sample(s, x0, t, eps);
  for (int b = 0; b < 2; ++b) {
    const int64_t step = t[b].item<int64_t>();
    const double abar = s.alphas_cumprod_f64()[step];
    const double expected = std::sqrt(abar) * 0.5 - std::sqrt(1 - abar);
    EXPECT_TRUE(torch::allclose(x_t[b], torch::full({1, 2, 2}, expected), 1e-6, 1e-6)) << b;
  }
}

TEST(Samplers, TimestepsAndStartSteps) {
  EXPECT_EQ(model::ddim_timesteps(999, 10),
            (std::vector<int64_t>{999, 888, 777, 666, 555, 444, 333, 222, 111, 0}));
  EXPECT_EQ(model::ddim_timesteps(4, 10), (std::vector<int64_t>{4, 3, 2, 1, 0}));
  EXPECT_EQ(model::ddim_timesteps(7, 1), (std::vector<int64_t>{7}));
  auto all = model::ddim_timesteps(999, 1000);
  ASSERT_EQ(all.size(), 1000u);
  for (int64_t i = 0; i < 1000; ++i) ASSERT_EQ(all[i], 999 - i);
  EXPECT_EQ(model::start_step(1000, 1.0), 999);
  EXPECT_EQ(model::start_step(1000, 0.5), 499);
  EXPECT_EQ(model::start_step(1000, 1e-6), 0);

  model::SamplerOptions bad;
  bad.steps = 0;
  EXPECT_THROW(bad.validate(1000, "--steps"), core::Error);
  bad.steps = 10;
  bad.eta = 1.5;
  EXPECT_THROW(bad.validate(1000, "--eta"), core::Error);
  bad.eta = 0;
  bad.start_strength = 0;
  EXPECT_THROW(bad.validate(1000, "--strength"), core::Error);
}

// With the exact predictor for a single clean image, the deterministic
// sampler must land on that image from any start.
TEST(Samplers, PerfectPredictorRecoversThePoint) {
  model::NoiseSchedule s;
  torch::manual_seed(10);
  auto x0 = 0.1 + 0.8 * torch::rand({1, 3, 8, 8});
  auto predictor = point_predictor(s, x0 * 2 - 1);
  auto cond = torch::rand({1, 3, 8, 8});
  for (double strength : {1.0, 0.4}) {
    auto out = model::ddim_sample(predictor, s, cond, 10, 0.0, 3, strength);
    EXPECT_LT((out - x0).abs().max().item<double>(), 1e-4) << strength;
  }
  auto ddpm = model::ddpm_sample(predictor, s, cond, 4, 0.2);
  EXPECT_LT((ddpm - x0).abs().max().item<double>(), 1e-4);
}

// Data: every pixel independently N(0.45, 0.08^2) in [0, 1]. DDPM, DDIM with
// K = T and eta = 1, and deterministic DDIM with K = T must all reproduce
// that distribution.
TEST(Samplers, GaussianDataDistributionIsReproduced) {
  model::NoiseSchedule s;
  const double mean = 0.45, sd = 0.08;
  auto predictor = gaussian_predictor(s, 2 * mean - 1, 4 * sd * sd);
  auto cond = torch::zeros({1, 1, 100, 100});
  auto ddpm = model::ddpm_sample(predictor, s, cond, 1);
  auto ddim_stochastic = model::ddim_sample(predictor, s, cond, 1000, 1.0, 2);
  auto ddim_deterministic = model::ddim_sample(predictor, s, cond, 1000, 0.0, 3);
  // 10^4 samples: standard errors 0.0008 (mean) and 0.0006 (std).
  for (const auto& [name, x] : std::vector<std::pair<std::string, torch::Tensor>>{
           {"ddpm", ddpm}, {"ddim eta=1", ddim_stochastic}, {"ddim eta=0", ddim_deterministic}}) {
    EXPECT_NEAR(x.mean().item<double>(), mean, 0.004) << name;
    EXPECT_NEAR(x.std().item<double>(), sd, 0.004) << name;
  }
  EXPECT_NEAR(ddpm.mean().item<double>(), ddim_stochastic.mean().item<double>(), 0.005);
  EXPECT_NEAR(ddpm.std().item<double>(), ddim_stochastic.std().item<double>(), 0.005);
  // Same seed: DDIM(K = T, eta = 1) takes DDPM's steps with DDPM's noise draws.
  auto same_seed = model::ddim_sample(predictor, s, cond, 1000, 1.0, 1);
  EXPECT_LT((same_seed - ddpm).abs().max().item<double>(), 1e-3);
}

// For Gaussian data one deterministic DDIM step is affine: the centred sample
// x - a m is scaled by r = (a' a v + b' b) / (a^2 v + b^2) (a = sqrt(abar_t),
// b = sqrt(1 - abar_t), primes at the next step). r is the cosine between
// (a sqrt(v), b) and (a' sqrt(v), b'), so few large steps shrink the spread:
// the sampler's std must equal the product of the r's.
TEST(Samplers, FewStepDdimMatchesItsAnalyticMapOnGaussianData) {
  model::NoiseSchedule s;
  const double mean = 0.45, sd = 0.08, m = 2 * mean - 1, v = 4 * sd * sd;
  auto predictor = gaussian_predictor(s, m, v);
  auto cond = torch::zeros({1, 1, 100, 100});
  const auto& abar = s.alphas_cumprod_f64();
  const auto steps = model::ddim_timesteps(999, 10);
  double gain = 1;
  for (size_t i = 0; i < steps.size(); ++i) {
    const double a2 = abar[steps[i]], p2 = i + 1 < steps.size() ? abar[steps[i + 1]] : 1.0;
    gain *= (std::sqrt(a2 * p2) * v + std::sqrt((1 - a2) * (1 - p2))) / (a2 * v + 1 - a2);
  }
  const double expected_mean = (m - std::sqrt(abar[999]) * m * gain + 1) / 2;
  auto x = model::ddim_sample(predictor, s, cond, 10, 0.0, 4);
  EXPECT_NEAR(x.mean().item<double>(), expected_mean, 0.003);
  EXPECT_NEAR(x.std().item<double>(), gain / 2, 0.02 * gain / 2);
  EXPECT_LT(gain / 2, 0.95 * sd);  // the shrinkage is real, not a tolerance artefact
}

TEST(Samplers, SeededSamplingIsDeterministic) {
  const model::Denoiser d{test::live_unet(test::tiny_unet_options(3), 11), model::NoiseSchedule()};
  auto render = torch::rand({9, 7, 3});
  model::SamplerOptions o;
  o.steps = 5;
  o.eta = 0.5;
  o.seed = 77;
  auto a = model::denoise_view(d, render, o);
  auto b = model::denoise_view(d, render, o);
  ASSERT_EQ(a.sizes(), render.sizes());
  EXPECT_TRUE(torch::equal(a, b));
  EXPECT_GE(a.min().item<double>(), 0.0);
  EXPECT_LE(a.max().item<double>(), 1.0);
  o.seed = 78;
  EXPECT_FALSE(torch::equal(a, model::denoise_view(d, render, o)));
  o.method = model::SamplerMethod::Ddpm;
  o.start_strength = 0.01;  // 10 steps
  auto c = model::denoise_view(d, render, o);
  EXPECT_TRUE(torch::equal(c, model::denoise_view(d, render, o)));
}

// samples = M is the mean of the M single runs with seeds seed .. seed + M - 1.
TEST(Samplers, MeanOfSamplesAveragesTheSeededRuns) {
  const model::Denoiser d{test::live_unet(test::tiny_unet_options(3), 31), model::NoiseSchedule()};
  auto render = torch::rand({7, 5, 3});
  model::SamplerOptions o;
  o.steps = 3;
  o.eta = 1.0;
  o.start_strength = 0.3;
  o.seed = 40;
  torch::Tensor sum = torch::zeros_like(render);
  for (uint64_t seed : {40, 41, 42}) {
    o.seed = seed;
    sum += model::denoise_view(d, render, o);
  }
  o.seed = 40;
  o.samples = 3;
  auto mean = model::denoise_view(d, render, o);
  EXPECT_LT((mean - sum / 3).abs().max().item<double>(), 1e-6);
  o.samples = 1;
  EXPECT_GT((mean - model::denoise_view(d, render, o)).abs().max().item<double>(), 1e-3);
  o.samples = 0;
  EXPECT_THROW(model::denoise_view(d, render, o), core::Error);
}

// The residual parameterisation's point: a U-Net that has learnt nothing
// (last layer zero, as constructed) predicts x0 = cond at every step, so
// every sampler, from any start, ends at the render itself.
TEST(Samplers, UntrainedResidualDenoiserReturnsTheRender) {
  torch::manual_seed(12);
  const model::Denoiser d{model::UNet(test::tiny_unet_options(4)), model::NoiseSchedule(),
                          model::Prediction::Residual};
  auto render = torch::rand({11, 6, 4}) * 0.98 + 0.01;
  for (double strength : {0.05, 0.4, 1.0}) {
    for (auto method : {model::SamplerMethod::Ddim, model::SamplerMethod::Ddpm}) {
      model::SamplerOptions o;
      o.method = method;
      o.start_strength = method == model::SamplerMethod::Ddpm ? strength / 10 : strength;
      o.steps = 7;
      o.eta = 0.5;
      o.seed = 3;
      auto out = model::denoise_view(d, render, o);
      EXPECT_LT((out - render).abs().max().item<double>(), 1e-5)
          << "strength " << o.start_strength
          << (method == model::SamplerMethod::Ddpm ? " ddpm" : " ddim");
    }
  }
  // The same untrained U-Net as an eps predictor gives noise-driven output.
  const model::Denoiser eps{d.unet, d.schedule, model::Prediction::Eps};
  model::SamplerOptions o;
  o.start_strength = 0.4;
  EXPECT_GT((model::denoise_view(eps, render, o) - render).abs().max().item<double>(), 0.05);
}

// Residual: the noise the predictor reports implies x0 = cond + U(x_t, t, cond).
TEST(Samplers, ResidualPredictionImpliesConditionPlusNetworkOutput) {
  const model::Denoiser d{test::live_unet(test::tiny_unet_options(2), 21), model::NoiseSchedule(),
                          model::Prediction::Residual};
  torch::manual_seed(22);
  auto x_t = torch::randn({2, 2, 8, 6}), cond = torch::rand({2, 2, 8, 6}) * 2 - 1;
  auto t = torch::tensor({3, 640}, torch::kLong);
  auto eps = model::as_predictor(d)(x_t, cond, t);
  auto abar = abar_of(d.schedule, t, x_t);
  auto x0 = (x_t - (1 - abar).sqrt() * eps) / abar.sqrt();
  model::UNet unet = d.unet;
  auto correction = unet->forward(x_t, cond, t);
  EXPECT_LT((x0 - (cond + correction)).abs().max().item<double>(), 2e-4);
  EXPECT_GT(correction.abs().max().item<double>(), 1e-3);  // not trivially cond
}

// A predictor that knows the clean image is the condition drives the loss to
// zero: x_gt and cond are mapped the same way and t is shared.
TEST(DiffusionLoss, ZeroForTheExactPredictorAndOneForZeroNoise) {
  model::NoiseSchedule s;
  torch::manual_seed(13);
  auto x = torch::rand({4, 2, 6, 6});
  auto exact = [&s](const torch::Tensor& x_t, const torch::Tensor& cond, const torch::Tensor& t) {
    auto abar = abar_of(s, t, x_t);
    return (x_t - abar.sqrt() * cond) / (1 - abar).sqrt();
  };
  auto generator = at::make_generator<at::CPUGeneratorImpl>(5);
  EXPECT_LT(model::diffusion_loss(exact, s, x, x, generator).item<double>(), 1e-6);
  auto zero = [](const torch::Tensor& x_t, const torch::Tensor&, const torch::Tensor&) {
    return torch::zeros_like(x_t);
  };
  auto big = torch::rand({8, 1, 50, 50});
  EXPECT_NEAR(model::diffusion_loss(zero, s, big, big, generator).item<double>(), 1.0, 0.02);
}

// The restoration loss noises the condition, not the truth: a predictor that
// returns the condition's own noise (x0 = cond) scores the squared distance
// of condition and truth in model space, 4 (cond - gt)^2, at any step; one
// whose implied x0 is the truth scores 0; and the steps stay within t_max.
TEST(DiffusionLoss, RestorationLossMeasuresTheOneStepPredictionFromTheNoisedCondition) {
  model::NoiseSchedule s;
  torch::manual_seed(14);
  const auto gt = torch::rand({3, 2, 5, 5}), cond = torch::rand({3, 2, 5, 5});
  auto generator = at::make_generator<at::CPUGeneratorImpl>(6);
  const double identity =
      model::restoration_loss(model::identity_predictor(s), s, gt, cond, 99, generator)
          .item<double>();
  EXPECT_NEAR(identity, (4 * (cond - gt).square()).mean().item<double>(), 1e-4);
  int64_t largest_t = -1;
  auto knows_truth = [&](const torch::Tensor& x_t, const torch::Tensor&, const torch::Tensor& t) {
    largest_t = std::max(largest_t, t.max().item<int64_t>());
    auto abar = abar_of(s, t, x_t);
    return (x_t - abar.sqrt() * (gt * 2 - 1)) / (1 - abar).sqrt();
  };
  for (int i = 0; i < 20; ++i)
    EXPECT_LT(model::restoration_loss(knows_truth, s, gt, cond, 9, generator).item<double>(), 1e-8);
  EXPECT_LE(largest_t, 9);
  EXPECT_GE(largest_t, 5);  // 60 draws in [0, 9]
}

// With one step (t = 0 always) SNR = (1 - beta) / beta = 4 for beta = 0.2, so
// Min-SNR weighting scales the loss by min(4, gamma) / 4 on the same draws.
TEST(DiffusionLoss, MinSnrWeightScalesByGammaOverSnr) {
  const model::NoiseSchedule s(1, model::BetaSchedule::Linear, 0.2, 0.2);
  auto x = torch::rand({3, 2, 5, 5});
  auto zero = [](const torch::Tensor& x_t, const torch::Tensor&, const torch::Tensor&) {
    return torch::zeros_like(x_t);
  };
  auto loss = [&](double gamma) {
    auto generator = at::make_generator<at::CPUGeneratorImpl>(8);
    return model::diffusion_loss(zero, s, x, x, generator, gamma).item<double>();
  };
  const double plain = loss(0.0);
  EXPECT_GT(plain, 0.5);
  EXPECT_NEAR(loss(1.0) / plain, 0.25, 1e-5);
  EXPECT_NEAR(loss(2.0) / plain, 0.5, 1e-5);
  EXPECT_NEAR(loss(5.0) / plain, 1.0, 1e-6);
}

TEST(DiffusionLoss, AdamStepsLowerTheLossOnAFixedBatch) {
  // Residual with Min-SNR: the condition misses a smooth offset the U-Net can learn.
  for (auto prediction : {model::Prediction::Eps, model::Prediction::Residual}) {
    torch::manual_seed(14);
    const model::Denoiser d{model::UNet(test::tiny_unet_options(3)), model::NoiseSchedule(),
                            prediction};
    const double gamma = prediction == model::Prediction::Residual ? 5.0 : 0.0;
    auto gt = torch::rand({4, 3, 16, 16});
    auto cond = (gt + 0.05 * torch::randn({4, 3, 16, 16}) - 0.1).clamp(0, 1);
    auto predictor = model::as_predictor(d);
    auto fixed_loss = [&] {
      torch::NoGradGuard no_grad;
      auto generator = at::make_generator<at::CPUGeneratorImpl>(99);
      double total = 0;
      for (int i = 0; i < 4; ++i)
        total +=
            model::diffusion_loss(predictor, d.schedule, gt, cond, generator, gamma).item<double>();
      return total / 4;
    };
    const double before = fixed_loss();
    torch::optim::Adam adam(d.unet->parameters(), torch::optim::AdamOptions(2e-3));
    auto generator = at::make_generator<at::CPUGeneratorImpl>(1);
    for (int step = 0; step < 40; ++step) {
      adam.zero_grad();
      model::diffusion_loss(predictor, d.schedule, gt, cond, generator, gamma).backward();
      adam.step();
    }
    const double after = fixed_loss();
    EXPECT_LT(after, 0.7 * before)
        << model::to_string(prediction) << ": " << before << " -> " << after;
  }
}

TEST(DiffusionLoss, ViewLossCropsBothImagesAtOneWindowAndReachesTheRender) {
  const model::Denoiser d{test::live_unet(test::tiny_unet_options(3), 15), model::NoiseSchedule()};
  auto gt = torch::rand({20, 17, 3});
  auto render = torch::rand({20, 17, 3}).requires_grad_(true);
  auto generator = at::make_generator<at::CPUGeneratorImpl>(17);
  auto loss = model::view_diffusion_loss(d, gt, render, 8, generator);
  ASSERT_EQ(loss.dim(), 0);
  loss.backward();
  auto touched = render.grad().abs().sum(2) > 0;  // [H, W]
  EXPECT_EQ(touched.sum().item<int64_t>(), 64);
  auto rows = touched.any(1).nonzero(), cols = touched.any(0).nonzero();
  EXPECT_EQ(rows.size(0), 8);
  EXPECT_EQ(cols.size(0), 8);
  EXPECT_EQ(rows.max().item<int64_t>() - rows.min().item<int64_t>(), 7);

  render.mutable_grad().zero_();
  model::view_diffusion_loss(d, gt, render, 64, generator).backward();
  EXPECT_EQ((render.grad().abs().sum(2) > 0).sum().item<int64_t>(), 20 * 17);
}

TEST(DiffusionLoss, BatchOfViewsIsTheMeanOfItsPerViewLossesAndOneViewIsTheViewLoss) {
  const model::Denoiser d{test::live_unet(test::tiny_unet_options(3), 21), model::NoiseSchedule()};
  auto gt = torch::rand({20, 17, 3}), render = torch::rand({20, 17, 3});
  auto g1 = at::make_generator<at::CPUGeneratorImpl>(5);
  auto g2 = at::make_generator<at::CPUGeneratorImpl>(5);
  EXPECT_TRUE(torch::equal(model::view_diffusion_loss(d, gt, render, 8, g1, 5.0),
                           model::views_diffusion_loss(d, {gt}, {render}, 8, g2, 5.0)));

  // Whole views of different sizes: both cropped to the smallest (12 x 17)
  // and stacked into one predictor call.
  auto small = torch::rand({12, 19, 3}), small_render = torch::rand({12, 19, 3});
  std::vector<torch::Tensor> crops;
  model::NoisePredictor recording = [&](const torch::Tensor& x_t, const torch::Tensor& cond,
                                        const torch::Tensor& t) {
    crops.push_back(cond);
    return model::as_predictor(d)(x_t, cond, t);
  };
  auto g3 = at::make_generator<at::CPUGeneratorImpl>(6);
  auto batch = model::views_diffusion_loss(recording, d.schedule, {gt, small},
                                           {render, small_render}, 0, g3);
  ASSERT_EQ(crops.size(), 1u);
  EXPECT_EQ(crops[0].sizes(), (std::vector<int64_t>{2, 3, 12, 17}));
  EXPECT_TRUE(std::isfinite(batch.item<double>()));
}

TEST(DiffusionLoss, IdentityPredictorIsAnUntrainedResidualDenoiser) {
  // The residual U-Net's last layer starts at zero: x0 = cond, which is what
  // identity_predictor assumes, draw for draw.
  const model::Denoiser d{model::UNet(test::tiny_unet_options(3)), model::NoiseSchedule(),
                          model::Prediction::Residual};
  auto gt = torch::rand({16, 12, 3}), render = torch::rand({16, 12, 3});
  auto g1 = at::make_generator<at::CPUGeneratorImpl>(8);
  auto g2 = at::make_generator<at::CPUGeneratorImpl>(8);
  const double unet =
      model::views_diffusion_loss(d, {gt, gt}, {render, render}, 8, g1, 5.0).item<double>();
  const double identity =
      model::views_diffusion_loss(model::identity_predictor(d.schedule), d.schedule, {gt, gt},
                                  {render, render}, 8, g2, 5.0)
          .item<double>();
  EXPECT_NEAR(unet, identity, 1e-6 * identity);
  // And it is not trivially zero: the render differs from the target.
  EXPECT_GT(identity, 1e-3);
}

TEST(Denoiser, CheckpointKeepsTheScheduleWithTheNetwork) {
  model::Denoiser denoiser{test::live_unet(test::tiny_unet_options(2), 18),
                           model::NoiseSchedule(500, model::BetaSchedule::Cosine),
                           model::Prediction::Residual};
  const auto file = test::temp_dir("denoiser_roundtrip") / "ckpt.pt";
  {
    torch::serialize::OutputArchive archive;
    model::save_denoiser(archive, "denoiser", denoiser);
    archive.save_to(file.string());
  }
  torch::serialize::InputArchive archive;
  archive.load_from(file.string());
  auto loaded = model::load_denoiser(archive, "denoiser", file);
  EXPECT_EQ(loaded.schedule.steps, 500);
  EXPECT_EQ(loaded.schedule.kind, model::BetaSchedule::Cosine);
  EXPECT_EQ(loaded.schedule.alphas_cumprod_f64(), denoiser.schedule.alphas_cumprod_f64());
  EXPECT_EQ(loaded.prediction, model::Prediction::Residual);
  model::SamplerOptions o;
  o.seed = 5;
  auto render = torch::rand({6, 5, 2});
  EXPECT_TRUE(torch::equal(model::denoise_view(denoiser, render, o),
                           model::denoise_view(loaded, render, o)));
  EXPECT_THROW(model::load_denoiser(archive, "other", file), core::Error);
}
