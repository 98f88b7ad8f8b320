#include "model/diffusion.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"
#include "core/threads.h"

namespace ddhgs::model {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kCosineOffset = 0.008;
constexpr double kMaxBeta = 0.999;

torch::Tensor to_model_space(const torch::Tensor& x) {
  return x * 2.0 - 1.0;
}
torch::Tensor to_data_space(const torch::Tensor& x) {
  return ((x + 1.0) * 0.5).clamp(0.0, 1.0);
}

std::vector<double> linear_betas(int64_t steps, double start, double end) {
  std::vector<double> betas(steps);
  for (int64_t t = 0; t < steps; ++t)
    betas[t] = steps == 1 ? start : start + (end - start) * double(t) / double(steps - 1);
  return betas;
}

std::vector<double> cosine_betas(int64_t steps) {
  auto f = [&](double u) {
    const double c = std::cos((u / double(steps) + kCosineOffset) / (1 + kCosineOffset) * kPi / 2);
    return c * c;
  };
  std::vector<double> betas(steps);
  for (int64_t t = 0; t < steps; ++t)
    betas[t] = std::min(1.0 - f(double(t + 1)) / f(double(t)), kMaxBeta);
  return betas;
}

torch::Tensor as_float_tensor(const std::vector<double>& values) {
  return torch::tensor(values, torch::kFloat64).to(torch::kFloat32);
}

// Per-sample constants [B] broadcast against images [B, N, H, W].
torch::Tensor per_sample(const torch::Tensor& table, const torch::Tensor& t,
                         const torch::Tensor& like) {
  return table.to(like.device()).index_select(0, t).to(like.dtype()).reshape({-1, 1, 1, 1});
}

// The noise that makes x_t from x0 at each sample's step t:
// (x_t - sqrt(abar_t) x0) / sqrt(1 - abar_t); a and b are the schedule's
// sqrt_alphas_cumprod and sqrt_one_minus_alphas_cumprod.
torch::Tensor eps_from_x0(const torch::Tensor& a, const torch::Tensor& b, const torch::Tensor& x_t,
                          const torch::Tensor& x0, const torch::Tensor& t) {
  return (x_t - per_sample(a, t, x_t) * x0) / per_sample(b, t, x_t);
}

torch::Tensor full_step(int64_t batch, int64_t t) {
  return torch::full({batch}, t, torch::kLong);
}

// Where the reverse process begins: pure noise for a full-strength start,
// else the condition noised to t_s (the render already holds the scene, so
// fewer steps are needed). Everything in model space.
struct ReverseStart {
  at::Generator generator;
  torch::Tensor cond;  // [B, N, H, W]
  torch::Tensor x;     // [B, N, H, W]
  int64_t t_start;
};

ReverseStart reverse_start(const NoiseSchedule& schedule, const torch::Tensor& cond, uint64_t seed,
                           double start_strength) {
  TORCH_CHECK(cond.dim() == 4, "diffusion: condition must be [B, N, H, W], got ", cond.sizes());
  ReverseStart r{at::make_generator<at::CPUGeneratorImpl>(seed),
                 to_model_space(cond),
                 {},
                 start_step(schedule.steps, start_strength)};
  auto noise = torch::randn(cond.sizes(), r.generator, cond.options());
  r.x = start_strength >= 1.0
            ? noise
            : q_sample(schedule, r.cond, full_step(cond.size(0), r.t_start), noise);
  return r;
}

// x0 implied by the predicted noise, clipped to the data range, and the noise
// consistent with the clipped x0 (so DDIM and DDPM use the same x0).
std::pair<torch::Tensor, torch::Tensor> predict_x0_eps(const NoisePredictor& predictor,
                                                       const torch::Tensor& x,
                                                       const torch::Tensor& cond_model, int64_t t,
                                                       double abar) {
  auto eps = predictor(x, cond_model, full_step(x.size(0), t));
  const double a = std::sqrt(abar), b = std::sqrt(1.0 - abar);
  auto x0 = ((x - b * eps) / a).clamp(-1.0, 1.0);
  return {x0, (x - a * x0) / b};
}

}  // namespace

BetaSchedule parse_beta_schedule(const std::string& name, const std::string& where) {
  if (name == "linear") return BetaSchedule::Linear;
  if (name == "cosine") return BetaSchedule::Cosine;
  throw core::Error(where + ": noise schedule must be 'linear' or 'cosine', got '" + name + "'");
}

std::string to_string(BetaSchedule schedule) {
  return schedule == BetaSchedule::Linear ? "linear" : "cosine";
}

NoiseSchedule::NoiseSchedule(int64_t steps_in, BetaSchedule kind_in, double beta_start_in,
                             double beta_end_in)
    : steps(steps_in), kind(kind_in), beta_start(beta_start_in), beta_end(beta_end_in) {
  core::require(steps >= 1, "noise schedule: steps must be >= 1, got " + std::to_string(steps));
  core::require(beta_start > 0 && beta_end < 1 && beta_start <= beta_end,
                "noise schedule: need 0 < beta_start <= beta_end < 1");
  const auto betas = kind == BetaSchedule::Linear ? linear_betas(steps, beta_start, beta_end)
                                                  : cosine_betas(steps);
  abar_.resize(size_t(steps));
  const size_t count = size_t(steps);
  std::vector<double> sqrt_abar(count), sqrt_one_minus(count);
  double product = 1.0;
  for (size_t t = 0; t < size_t(steps); ++t) {
    product *= 1.0 - betas[t];
    abar_[t] = product;
    sqrt_abar[t] = std::sqrt(product);
    sqrt_one_minus[t] = std::sqrt(1.0 - product);
  }
  alphas_cumprod = as_float_tensor(abar_);
  sqrt_alphas_cumprod = as_float_tensor(sqrt_abar);
  sqrt_one_minus_alphas_cumprod = as_float_tensor(sqrt_one_minus);
}

NoiseSchedule::Posterior NoiseSchedule::posterior(int64_t t) const {
  const double abar = alpha_bar(t), prev = alpha_bar_prev(t), b = beta(t);
  return {std::sqrt(prev) * b / (1.0 - abar), std::sqrt(1.0 - b) * (1.0 - prev) / (1.0 - abar),
          b * (1.0 - prev) / (1.0 - abar)};
}

torch::Tensor q_sample(const NoiseSchedule& schedule, const torch::Tensor& x0,
                       const torch::Tensor& t, const torch::Tensor& eps) {
  TORCH_CHECK(x0.dim() == 4 && eps.sizes() == x0.sizes(), "q_sample: x0 ", x0.sizes(), " and eps ",
              eps.sizes(), " must be the same [B, N, H, W]");
  TORCH_CHECK(t.dim() == 1 && t.size(0) == x0.size(0), "q_sample: t must be [B]");
  return per_sample(schedule.sqrt_alphas_cumprod, t, x0) * x0 +
         per_sample(schedule.sqrt_one_minus_alphas_cumprod, t, x0) * eps;
}

Prediction parse_prediction(const std::string& name, const std::string& where) {
  if (name == "eps") return Prediction::Eps;
  if (name == "residual") return Prediction::Residual;
  throw core::Error(where + ": prediction must be \"eps\" or \"residual\", got \"" + name + "\"");
}

std::string to_string(Prediction prediction) {
  return prediction == Prediction::Eps ? "eps" : "residual";
}

NoisePredictor as_predictor(const Denoiser& denoiser) {
  UNet unet = denoiser.unet;
  if (denoiser.prediction == Prediction::Eps)
    return [unet](const torch::Tensor& x_t, const torch::Tensor& cond,
                  const torch::Tensor& t) mutable { return unet->forward(x_t, cond, t); };
  const NoiseSchedule& schedule = denoiser.schedule;
  return [unet, a = schedule.sqrt_alphas_cumprod, b = schedule.sqrt_one_minus_alphas_cumprod](
             const torch::Tensor& x_t, const torch::Tensor& cond, const torch::Tensor& t) mutable {
    return eps_from_x0(a, b, x_t, cond + unet->forward(x_t, cond, t), t);
  };
}

torch::Tensor diffusion_loss(const NoisePredictor& predictor, const NoiseSchedule& schedule,
                             const torch::Tensor& x_gt, const torch::Tensor& cond,
                             at::Generator& generator, double min_snr_gamma) {
  TORCH_CHECK(cond.dim() == 4 && x_gt.sizes() == cond.sizes(), "diffusion_loss: x_gt ",
              x_gt.sizes(), " must match cond ", cond.sizes());
  auto t = torch::randint(0, schedule.steps, {x_gt.size(0)}, generator,
                          torch::TensorOptions().dtype(torch::kLong));
  auto eps = torch::randn(x_gt.sizes(), generator, x_gt.options());
  auto x_t = q_sample(schedule, to_model_space(x_gt.detach()), t, eps);
  auto error = (predictor(x_t, to_model_space(cond), t) - eps).square();
  if (min_snr_gamma <= 0) return error.mean();
  auto abar = per_sample(schedule.alphas_cumprod, t, x_t).to(torch::kDouble);
  auto snr = abar / (1.0 - abar);
  auto weight = (snr.clamp_max(min_snr_gamma) / snr).to(error.dtype()).flatten();  // [B]
  return (error.flatten(1).mean(1) * weight).mean();
}

torch::Tensor restoration_loss(const NoisePredictor& predictor, const NoiseSchedule& schedule,
                               const torch::Tensor& x_gt, const torch::Tensor& cond, int64_t t_max,
                               at::Generator& generator) {
  TORCH_CHECK(cond.dim() == 4 && x_gt.sizes() == cond.sizes(), "restoration_loss: x_gt ",
              x_gt.sizes(), " must match cond ", cond.sizes());
  TORCH_CHECK(t_max >= 0 && t_max < schedule.steps, "restoration_loss: t_max ", t_max,
              " outside the schedule's ", schedule.steps, " steps");
  auto t = torch::randint(0, t_max + 1, {x_gt.size(0)}, generator,
                          torch::TensorOptions().dtype(torch::kLong));
  auto eps = torch::randn(cond.sizes(), generator, cond.options());
  const torch::Tensor c = to_model_space(cond);
  auto x_t = q_sample(schedule, c.detach(), t, eps);
  const torch::Tensor eps_hat = predictor(x_t, c, t);
  const torch::Tensor x0 =
      (x_t - per_sample(schedule.sqrt_one_minus_alphas_cumprod, t, x_t) * eps_hat) /
      per_sample(schedule.sqrt_alphas_cumprod, t, x_t);
  return (x0 - to_model_space(x_gt)).square().mean();
}

torch::Tensor view_diffusion_loss(const Denoiser& denoiser, const torch::Tensor& gt,
                                  const torch::Tensor& render, int64_t crop_px,
                                  at::Generator& generator, double min_snr_gamma) {
  return views_diffusion_loss(denoiser, {gt}, {render}, crop_px, generator, min_snr_gamma);
}

torch::Tensor views_diffusion_loss(const Denoiser& denoiser, const std::vector<torch::Tensor>& gts,
                                   const std::vector<torch::Tensor>& renders, int64_t crop_px,
                                   at::Generator& generator, double min_snr_gamma) {
  std::vector<torch::Tensor> gt_inputs, render_inputs;
  for (const torch::Tensor& gt : gts) gt_inputs.push_back(to_denoiser_space(denoiser, gt));
  for (const torch::Tensor& r : renders) render_inputs.push_back(to_denoiser_space(denoiser, r));
  return views_diffusion_loss(as_predictor(denoiser), denoiser.schedule, gt_inputs, render_inputs,
                              crop_px, generator, min_snr_gamma);
}

torch::Tensor to_denoiser_space(const Denoiser& denoiser, const torch::Tensor& image) {
  return denoiser.subspace ? denoiser.subspace->encode(image) : image;
}

int64_t Denoiser::bands() const {
  return subspace ? subspace->bands() : unet->options().bands;
}

NoisePredictor identity_predictor(const NoiseSchedule& schedule) {
  return [a = schedule.sqrt_alphas_cumprod, b = schedule.sqrt_one_minus_alphas_cumprod](
             const torch::Tensor& x_t, const torch::Tensor& cond, const torch::Tensor& t) {
    return eps_from_x0(a, b, x_t, cond, t);
  };
}

torch::Tensor views_diffusion_loss(const NoisePredictor& predictor, const NoiseSchedule& schedule,
                                   const std::vector<torch::Tensor>& gts,
                                   const std::vector<torch::Tensor>& renders, int64_t crop_px,
                                   at::Generator& generator, double min_snr_gamma) {
  TORCH_CHECK(!gts.empty() && gts.size() == renders.size(),
              "views_diffusion_loss: need as many renders as ground-truth views (at least one)");
  // One crop size for the batch: the smallest view bounds it.
  int64_t ch = std::numeric_limits<int64_t>::max(), cw = ch;
  for (size_t i = 0; i < gts.size(); ++i) {
    TORCH_CHECK(gts[i].dim() == 3 && gts[i].sizes() == renders[i].sizes(),
                "views_diffusion_loss: gt ", gts[i].sizes(), " and render ", renders[i].sizes(),
                " must be the same [H, W, N]");
    const int64_t h = gts[i].size(0), w = gts[i].size(1);
    ch = std::min(ch, crop_px > 0 ? std::min(crop_px, h) : h);
    cw = std::min(cw, crop_px > 0 ? std::min(crop_px, w) : w);
  }
  auto corner = [&](int64_t free) {
    return torch::randint(0, free + 1, {1}, generator, torch::kLong).item<int64_t>();
  };
  std::vector<torch::Tensor> gt_crops, render_crops;
  for (size_t i = 0; i < gts.size(); ++i) {
    const int64_t y0 = corner(gts[i].size(0) - ch), x0 = corner(gts[i].size(1) - cw);
    auto crop = [&](const torch::Tensor& image) {
      return image.slice(0, y0, y0 + ch).slice(1, x0, x0 + cw).permute({2, 0, 1});
    };
    gt_crops.push_back(crop(gts[i]));
    render_crops.push_back(crop(renders[i]));
  }
  return diffusion_loss(predictor, schedule, torch::stack(gt_crops), torch::stack(render_crops),
                        generator, min_snr_gamma);
}

void SamplerOptions::validate(int64_t schedule_steps, const std::string& where) const {
  core::require(steps >= 1 && steps <= schedule_steps, where + ": sampler steps must be in [1, " +
                                                           std::to_string(schedule_steps) +
                                                           "], got " + std::to_string(steps));
  core::require(eta >= 0.0 && eta <= 1.0, where + ": eta must be in [0, 1]");
  core::require(start_strength > 0.0 && start_strength <= 1.0,
                where + ": start strength must be in (0, 1]");
  core::require(samples >= 1, where + ": samples must be >= 1");
}

int64_t start_step(int64_t schedule_steps, double start_strength) {
  const int64_t t = std::llround(start_strength * double(schedule_steps)) - 1;
  return std::clamp<int64_t>(t, 0, schedule_steps - 1);
}

std::vector<int64_t> ddim_timesteps(int64_t t_start, int64_t steps) {
  TORCH_CHECK(steps >= 1 && t_start >= 0, "ddim_timesteps: need K >= 1 and t_start >= 0");
  if (steps > t_start) steps = t_start + 1;
  std::vector<int64_t> out(steps);
  for (int64_t i = 0; i < steps; ++i) {
    // Evenly spaced from t_start (i = 0) down to 0 (i = K - 1); rounding keeps
    // them distinct because the spacing is >= 1.
    const double u = steps == 1 ? 1.0 : double(steps - 1 - i) / double(steps - 1);
    out[i] = std::llround(u * double(t_start));
  }
  return out;
}

torch::Tensor ddpm_sample(const NoisePredictor& predictor, const NoiseSchedule& schedule,
                          const torch::Tensor& cond, uint64_t seed, double start_strength) {
  torch::NoGradGuard no_grad;
  auto [generator, cond_model, x, t_start] = reverse_start(schedule, cond, seed, start_strength);
  for (int64_t t = t_start; t >= 0; --t) {
    auto x0 = predict_x0_eps(predictor, x, cond_model, t, schedule.alpha_bar(t)).first;
    const NoiseSchedule::Posterior q = schedule.posterior(t);
    x = q.coef_x0 * x0 + q.coef_xt * x;
    if (t > 0) x = x + std::sqrt(q.variance) * torch::randn(x.sizes(), generator, x.options());
  }
  return to_data_space(x);
}

torch::Tensor ddim_sample(const NoisePredictor& predictor, const NoiseSchedule& schedule,
                          const torch::Tensor& cond, int64_t steps, double eta, uint64_t seed,
                          double start_strength) {
  torch::NoGradGuard no_grad;
  auto [generator, cond_model, x, t_start] = reverse_start(schedule, cond, seed, start_strength);
  const auto& abar = schedule.alphas_cumprod_f64();
  const auto timesteps = ddim_timesteps(t_start, steps);
  for (size_t i = 0; i < timesteps.size(); ++i) {
    const int64_t t = timesteps[i];
    const double prev = i + 1 < timesteps.size() ? abar[timesteps[i + 1]] : 1.0;
    auto [x0, eps] = predict_x0_eps(predictor, x, cond_model, t, abar[t]);
    const double sigma = eta * std::sqrt((1.0 - prev) / (1.0 - abar[t]) * (1.0 - abar[t] / prev));
    x = std::sqrt(prev) * x0 + std::sqrt(std::max(0.0, 1.0 - prev - sigma * sigma)) * eps;
    if (sigma > 0) x = x + sigma * torch::randn(x.sizes(), generator, x.options());
  }
  return to_data_space(x);
}

torch::Tensor sample(const NoisePredictor& predictor, const NoiseSchedule& schedule,
                     const torch::Tensor& cond, const SamplerOptions& options) {
  options.validate(schedule.steps, "sampler options");
  core::TorchThreads torch_threads;  // the U-Net's convolutions
  auto one = [&](uint64_t seed) {
    if (options.method == SamplerMethod::Ddpm)
      return ddpm_sample(predictor, schedule, cond, seed, options.start_strength);
    return ddim_sample(predictor, schedule, cond, options.steps, options.eta, seed,
                       options.start_strength);
  };
  torch::Tensor sum = one(options.seed);
  for (int64_t m = 1; m < options.samples; ++m) sum = sum + one(options.seed + uint64_t(m));
  return options.samples > 1 ? sum / double(options.samples) : sum;
}

torch::Tensor denoise_view(const Denoiser& denoiser, const torch::Tensor& render,
                           const SamplerOptions& options) {
  TORCH_CHECK(render.dim() == 3, "denoise_view: render must be [H, W, N], got ", render.sizes());
  auto run = [&](const torch::Tensor& image) {
    auto cond = image.permute({2, 0, 1}).unsqueeze(0).contiguous();
    return sample(as_predictor(denoiser), denoiser.schedule, cond, options)
        .squeeze(0)
        .permute({1, 2, 0})
        .contiguous();
  };
  if (!denoiser.subspace) return run(render);
  const torch::Tensor coeffs = denoiser.subspace->encode(render);
  return keep_spectral_direction(render, denoiser.subspace->apply(render, coeffs, run(coeffs)))
      .clamp(0.0, 1.0);
}

torch::Tensor keep_spectral_direction(const torch::Tensor& render, const torch::Tensor& corrected) {
  TORCH_CHECK(render.sizes() == corrected.sizes(), "keep_spectral_direction: ", render.sizes(),
              " and ", corrected.sizes(), " differ");
  const torch::Tensor dot = (render * corrected).sum(-1, true);
  // A black pixel has dot 0: its gain is 0 / 1e-30, and it stays black.
  const torch::Tensor norm = (render * render).sum(-1, true).clamp_min(1e-30);
  return render * (dot / norm);
}

void save_denoiser(torch::serialize::OutputArchive& archive, const std::string& key,
                   Denoiser& denoiser) {
  const auto& s = denoiser.schedule;
  const nlohmann::json schedule = {{"steps", s.steps},
                                   {"kind", to_string(s.kind)},
                                   {"beta_start", s.beta_start},
                                   {"beta_end", s.beta_end},
                                   {"prediction", to_string(denoiser.prediction)}};
  archive.write(key + "_schedule_json", c10::IValue(schedule.dump()));
  save_unet(archive, key, denoiser.unet);
  if (denoiser.subspace) {
    archive.write(key + "_subspace_mean", denoiser.subspace->mean);
    archive.write(key + "_subspace_basis", denoiser.subspace->basis);
    archive.write(key + "_subspace_scale",
                  torch::tensor(denoiser.subspace->scale, torch::kFloat64));
  }
}

Denoiser load_denoiser(torch::serialize::InputArchive& archive, const std::string& key,
                       const std::filesystem::path& file) {
  c10::IValue stored;
  core::require(archive.try_read(key + "_schedule_json", stored) && stored.isString(), file,
                "denoiser '" + key + "' has no noise schedule");
  Denoiser denoiser;
  try {
    const auto j = nlohmann::json::parse(stored.toStringRef());
    denoiser.schedule =
        NoiseSchedule(j.at("steps").get<int64_t>(),
                      parse_beta_schedule(j.at("kind").get<std::string>(), file.string()),
                      j.at("beta_start").get<double>(), j.at("beta_end").get<double>());
    // Denoisers written before the residual parameterisation predicted eps.
    denoiser.prediction = parse_prediction(j.value("prediction", "eps"), file.string());
  } catch (const nlohmann::json::exception& e) {
    throw core::Error(file, "denoiser noise schedule is malformed: " + core::message_of(e));
  }
  denoiser.unet = load_unet(archive, key, file);
  torch::Tensor mean;
  if (archive.try_read(key + "_subspace_mean", mean)) {
    SpectralSubspace s;
    s.mean = mean;
    torch::Tensor scale;
    core::require(archive.try_read(key + "_subspace_basis", s.basis) &&
                      archive.try_read(key + "_subspace_scale", scale) && scale.numel() == 1,
                  file, "denoiser '" + key + "' has a subspace mean but no basis or scale");
    s.scale = scale.item<double>();
    core::require(mean.dim() == 1 && s.basis.dim() == 2 && s.basis.size(0) == mean.size(0) &&
                      s.basis.size(1) == denoiser.unet->options().bands && s.scale > 0 &&
                      std::isfinite(s.scale),
                  file,
                  "denoiser '" + key + "' has a spectral subspace that does not fit its U-Net");
    denoiser.subspace = s;
  }
  return denoiser;
}

}  // namespace ddhgs::model
