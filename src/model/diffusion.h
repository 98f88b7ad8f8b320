// Conditional denoising diffusion (DDPM, Ho et al. 2020; DDIM, Song et al.
// 2021) around the U-Net: noise schedule, forward process, training loss and
// the reverse-process samplers, conditioned on the Gaussian render.
//
// Data space: reflectance in [0, 1]. The diffusion runs in model space
// x_model = 2 x - 1, so the unit-variance noise matches the data's range;
// every function here that takes or returns images in [0, 1] says so, and
// maps internally. Predicted clean images are clipped to [-1, 1] in model
// space (= [0, 1] in data space) at every reverse step.
#pragma once
#include "core/tensor.h"

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "model/spectral_subspace.h"
#include "model/unet.h"

namespace ddhgs::model {

enum class BetaSchedule { Linear, Cosine };

// "linear" or "cosine"; throws core::Error naming `where` otherwise.
BetaSchedule parse_beta_schedule(const std::string& name, const std::string& where);
std::string to_string(BetaSchedule schedule);

// Per-step constants, computed in double precision and stored as float32 [T]
// tensors (indexed by the 0-based step t; step t adds noise of variance
// betas[t] to the sample of step t - 1, the clean image being "step -1").
struct NoiseSchedule {
  // Linear: betas evenly spaced from beta_start to beta_end (Ho et al.).
  // Cosine: abar(t) = f(t + 1) / f(0), f(u) = cos^2((u / T + s) / (1 + s) pi / 2),
  // s = 0.008, betas clipped at 0.999 (Nichol & Dhariwal); beta_start/end unused.
  explicit NoiseSchedule(int64_t steps = 1000, BetaSchedule kind = BetaSchedule::Linear,
                         double beta_start = 1e-4, double beta_end = 0.02);

  int64_t steps = 0;  // T
  BetaSchedule kind = BetaSchedule::Linear;
  double beta_start = 0, beta_end = 0;  // as constructed (linear only)

  // abar_t = prod_{s <= t} (1 - beta_s), in double: the one source every
  // other quantity of the schedule is derived from.
  const std::vector<double>& alphas_cumprod_f64() const { return abar_; }
  double alpha_bar(int64_t t) const { return abar_[size_t(t)]; }
  double alpha_bar_prev(int64_t t) const { return t > 0 ? abar_[size_t(t - 1)] : 1.0; }
  double beta(int64_t t) const { return 1.0 - alpha_bar(t) / alpha_bar_prev(t); }

  // q(x_{t-1} | x_t, x_0) = N(coef_x0 x_0 + coef_xt x_t, variance): what the
  // DDPM sampler steps by.
  struct Posterior {
    double coef_x0;   // sqrt(abar_{t-1}) beta_t / (1 - abar_t)
    double coef_xt;   // sqrt(1 - beta_t) (1 - abar_{t-1}) / (1 - abar_t)
    double variance;  // beta_t (1 - abar_{t-1}) / (1 - abar_t)
  };
  Posterior posterior(int64_t t) const;

  // float32 [T] copies for per-sample gathers in batched tensor code.
  torch::Tensor alphas_cumprod;                 // abar_t
  torch::Tensor sqrt_alphas_cumprod;            // sqrt(abar_t)
  torch::Tensor sqrt_one_minus_alphas_cumprod;  // sqrt(1 - abar_t)

 private:
  std::vector<double> abar_;
};

// x_t = sqrt(abar_t) x0 + sqrt(1 - abar_t) eps, per sample; model space.
torch::Tensor q_sample(const NoiseSchedule& schedule,
                       const torch::Tensor& x0,    // [B, N, H, W]
                       const torch::Tensor& t,     // [B] int64 steps in [0, T)
                       const torch::Tensor& eps);  // [B, N, H, W]

// What the U-Net's output means.
//  Eps (the paper): the noise, eps_theta = U(x_t, t, cond).
//  Residual: a correction of the condition, x0_theta = cond + U(x_t, t, cond),
//    turned into eps_theta = (x_t - sqrt(abar_t) x0_theta) / sqrt(1 - abar_t).
//    The U-Net's last layer starts at zero, so an untrained (or useless)
//    denoiser returns the render itself instead of noise: the denoised
//    output can only move away from the render where training taught it to.
enum class Prediction { Eps, Residual };

// "eps" or "residual"; throws core::Error naming `where` otherwise.
Prediction parse_prediction(const std::string& name, const std::string& where);
std::string to_string(Prediction prediction);

// What a trained denoiser needs at inference: the network, the schedule it
// was trained with and what its output means. Checkpoints store all three, so
// eval cannot mix them.
struct Denoiser {
  Denoiser() = default;
  Denoiser(UNet unet_, NoiseSchedule schedule_, Prediction prediction_ = Prediction::Eps,
           std::optional<SpectralSubspace> subspace_ = std::nullopt)
      : unet(std::move(unet_)),
        schedule(std::move(schedule_)),
        prediction(prediction_),
        subspace(std::move(subspace_)) {}

  UNet unet{nullptr};
  NoiseSchedule schedule;
  Prediction prediction = Prediction::Eps;
  // A prior's denoiser works in a scene's spectral subspace (the U-Net has
  // subspace->channels() channels): the functions below taking a Denoiser
  // encode its views and renders, and denoise_view applies the correction in
  // the scene's bands. None: the U-Net sees the bands themselves.
  std::optional<SpectralSubspace> subspace;

  // The band count the denoiser takes: the subspace's, else the U-Net's.
  int64_t bands() const;
};

// Predicted noise eps_theta(x_t, t | cond), all in model space. The U-Net is
// one; tests plug in analytic predictors.
using NoisePredictor = std::function<torch::Tensor(const torch::Tensor& x_t,   // [B, N, H, W]
                                                   const torch::Tensor& cond,  // [B, N, H, W]
                                                   const torch::Tensor& t)>;   // [B] int64
NoisePredictor as_predictor(const Denoiser& denoiser);

// An image [..., N] as the denoiser's U-Net sees it: its subspace
// coefficients [..., K], or the image itself when there is no subspace.
torch::Tensor to_denoiser_space(const Denoiser& denoiser, const torch::Tensor& image);

// Mean over samples of w(t) * mean over elements of (eps - eps_theta(x_t, t |
// cond))^2 with t uniform in [0, T) per sample and eps standard normal, both
// drawn from `generator`. w(t) = 1 (the paper) when min_snr_gamma <= 0, else
// min(SNR_t, gamma) / SNR_t with SNR_t = abar_t / (1 - abar_t) ("Min-SNR"
// weighting, Hang et al. 2023): in x0 terms the error at nearly clean steps
// is weighted gamma instead of up to 1 / beta_1 = 1e4, which matters when the
// gradient reaches the render through the condition. x_gt and cond in [0, 1].
// Differentiable w.r.t. the predictor's parameters and cond (the render:
// joint training lets the loss reach the Gaussians).
torch::Tensor diffusion_loss(const NoisePredictor& predictor, const NoiseSchedule& schedule,
                             const torch::Tensor& x_gt,  // [B, N, H, W]
                             const torch::Tensor& cond,  // [B, N, H, W]
                             at::Generator& generator, double min_snr_gamma = 0.0);

// The task a sampler started from the condition sets (start_strength < 1,
// one DDIM step): the condition noised to a step t uniform in [0, t_max],
// the clean image predicted from it in one step, and the mean squared error
// of that prediction against x_gt, in model space. diffusion_loss noises
// the ground truth, which no sampler has at inference; a denoiser prior
// trained on this learns what it is asked (Difix3D+ trains its single-step
// model so). x_gt and cond in [0, 1]; t and eps drawn from `generator`.
torch::Tensor restoration_loss(const NoisePredictor& predictor, const NoiseSchedule& schedule,
                               const torch::Tensor& x_gt,  // [B, N, H, W]
                               const torch::Tensor& cond,  // [B, N, H, W]
                               int64_t t_max, at::Generator& generator);

// The same on one view, channels-last as the renderer produces it, on one
// random crop_px x crop_px window (the whole view if it is smaller) shared by
// both images; crop_px <= 0 uses the whole view.
torch::Tensor view_diffusion_loss(const Denoiser& denoiser,
                                  const torch::Tensor& gt,      // [H, W, N] in [0, 1]
                                  const torch::Tensor& render,  // [H, W, N] in [0, 1]
                                  int64_t crop_px, at::Generator& generator,
                                  double min_snr_gamma = 0.0);

// The same on a batch of views, one crop each (corners drawn in order, then t
// and eps for the whole batch). The crop is bounded by the smallest view, so
// "whole views" (crop_px <= 0) of different sizes are cropped to the smallest
// one. With one view it is view_diffusion_loss, draw for draw.
torch::Tensor views_diffusion_loss(const Denoiser& denoiser,
                                   const std::vector<torch::Tensor>& gts,      // [H, W, N] each
                                   const std::vector<torch::Tensor>& renders,  // [H, W, N] each
                                   int64_t crop_px, at::Generator& generator,
                                   double min_snr_gamma = 0.0);
torch::Tensor views_diffusion_loss(const NoisePredictor& predictor, const NoiseSchedule& schedule,
                                   const std::vector<torch::Tensor>& gts,
                                   const std::vector<torch::Tensor>& renders, int64_t crop_px,
                                   at::Generator& generator, double min_snr_gamma = 0.0);

// The noise implied by x0 = cond exactly: what a residual denoiser with a zero
// correction predicts. Its loss is the bar a trained denoiser must beat.
NoisePredictor identity_predictor(const NoiseSchedule& schedule);

enum class SamplerMethod { Ddpm, Ddim };

struct SamplerOptions {
  SamplerMethod method = SamplerMethod::Ddim;
  int64_t steps = 10;  // K, DDIM only (DDPM always runs every step below the start)
  double eta = 0.0;    // DDIM only: 0 deterministic, 1 = DDPM's posterior variance
  // In (0, 1]. 1 starts from pure noise at step T - 1; s < 1 starts from the
  // condition noised to step t_s = round(s T) - 1 and runs only steps <= t_s.
  double start_strength = 1.0;
  uint64_t seed = 0;
  // The output is the mean of this many samples (seeds seed, seed + 1, ...):
  // a Monte-Carlo estimate of the posterior mean E[x0 | render], which PSNR
  // and RMSE reward, instead of one draw whose own noise they penalise.
  int64_t samples = 1;

  // Throws core::Error naming `where` (flag or preset) on bad values.
  void validate(int64_t schedule_steps, const std::string& where) const;
};

// The step t_s the reverse process starts from, for a strength in (0, 1].
int64_t start_step(int64_t schedule_steps, double start_strength);
// The K DDIM steps, descending from t_start to 0, evenly spaced (all steps
// when K > t_start).
std::vector<int64_t> ddim_timesteps(int64_t t_start, int64_t steps);

// Ancestral sampling with the posterior variance, one step at a time from
// t_s down to 0. cond in [0, 1]; returns [B, N, H, W] in [0, 1].
torch::Tensor ddpm_sample(const NoisePredictor& predictor, const NoiseSchedule& schedule,
                          const torch::Tensor& cond,  // [B, N, H, W]
                          uint64_t seed, double start_strength = 1.0);

// DDIM over ddim_timesteps(t_s, K) with
// sigma = eta sqrt((1 - abar_prev) / (1 - abar_t)) sqrt(1 - abar_t / abar_prev).
// With K = T and eta = 1 it is DDPM step for step (same noise draws).
torch::Tensor ddim_sample(const NoisePredictor& predictor, const NoiseSchedule& schedule,
                          const torch::Tensor& cond,  // [B, N, H, W]
                          int64_t steps, double eta, uint64_t seed, double start_strength = 1.0);

void save_denoiser(torch::serialize::OutputArchive& archive, const std::string& key,
                   Denoiser& denoiser);
// Throws core::Error naming `file` when the key is missing or malformed.
Denoiser load_denoiser(torch::serialize::InputArchive& archive, const std::string& key,
                       const std::filesystem::path& file);

// Dispatches on options.method (after validating) and averages
// options.samples runs; cond in [0, 1].
torch::Tensor sample(const NoisePredictor& predictor, const NoiseSchedule& schedule,
                     const torch::Tensor& cond,  // [B, N, H, W]
                     const SamplerOptions& options);

// The denoised view for a render, channels-last in and out, [H, W, N]; the
// render goes in unclamped, as the condition did in training, and comes out
// in [0, 1]. With a subspace (a prior) the sampler runs on the render's
// coefficients, their change is applied to the render, and each pixel keeps
// the render's spectral direction (keep_spectral_direction): a prior learned
// across scenes corrects how bright a pixel is, not the shape of its
// spectrum, which it moved where the render had it right (SAM +17 % on
// Basil, +29 % on a sparse ring, PSNR 0.01-0.03 dB lower than with the
// direction kept; docs/benchmarks.md, "The 60-entry corpus").
torch::Tensor denoise_view(const Denoiser& denoiser,
                           const torch::Tensor& render,  // [H, W, N]
                           const SamplerOptions& options);

// Each pixel of `corrected` ([..., N]) projected onto the direction of the
// same pixel of `render`: render x (render . corrected) / (render . render),
// a gain per pixel, so the spectral angle is the render's; a black pixel of
// the render stays black.
torch::Tensor keep_spectral_direction(const torch::Tensor& render, const torch::Tensor& corrected);

}  // namespace ddhgs::model
