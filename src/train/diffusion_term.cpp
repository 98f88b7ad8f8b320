#include "train/diffusion_term.h"

#include <ATen/CPUGeneratorImpl.h>

#include <cmath>

#include "core/error.h"
#include "train/checkpoint.h"

namespace ddhgs::train {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

const char* const kArchiveKey = "denoiser";

}  // namespace

FinetunePairs parse_finetune_pairs(const std::string& name, const std::string& where) {
  if (name == "training") return FinetunePairs::Training;
  if (name == "folds") return FinetunePairs::Folds;
  if (name == "checkpoint") return FinetunePairs::Checkpoint;
  if (name == "perturbed") return FinetunePairs::Perturbed;
  throw core::Error(
      where, "pairs is '" + name + "'; expected 'training', 'folds', 'checkpoint' or 'perturbed'");
}

std::string to_string(FinetunePairs pairs) {
  switch (pairs) {
    case FinetunePairs::Folds:
      return "folds";
    case FinetunePairs::Checkpoint:
      return "checkpoint";
    case FinetunePairs::Perturbed:
      return "perturbed";
    case FinetunePairs::Training:
      break;
  }
  return "training";
}

DiffusionTerm::DiffusionTerm(const DiffusionTermOptions& options, uint64_t init_seed)
    : options_(options), denoiser_(std::make_shared<model::Denoiser>()) {
  torch::manual_seed(init_seed);
  denoiser_->unet = model::UNet(options_.unet);
  denoiser_->schedule = model::NoiseSchedule(options_.schedule_steps, options_.schedule,
                                             options_.beta_start, options_.beta_end);
  denoiser_->prediction = options_.prediction;
}

DiffusionTerm::DiffusionTerm(const DiffusionTermOptions& options, model::Denoiser denoiser)
    : options_(options), denoiser_(std::make_shared<model::Denoiser>(std::move(denoiser))) {}

LossTerm DiffusionTerm::loss_term() {
  return {"diffusion", options_.weight,
          [denoiser = denoiser_, options = options_](const LossInputs& in) {
            if (in.iteration <= options.warmup) return torch::zeros({});
            return diffusion_term_loss(*denoiser, options, in.render, in.target, in.seed);
          }};
}

torch::Tensor diffusion_term_loss(model::Denoiser& denoiser, const DiffusionTermOptions& options,
                                  const torch::Tensor& render, const torch::Tensor& target,
                                  uint64_t seed) {
  auto generator = at::make_generator<at::CPUGeneratorImpl>(seed);
  torch::Tensor cond = options.condition_grad ? render : render.detach();
  if (options.condition_noise > 0)
    cond = cond + options.condition_noise * torch::randn(cond.sizes(), generator, cond.options());
  return model::view_diffusion_loss(denoiser, target.to(render.dtype()), cond, options.crop_px,
                                    generator, options.min_snr_gamma);
}

FinetuneLosses finetune_losses(model::Denoiser& denoiser, const DiffusionTermOptions& options,
                               size_t views, const FinetuneView& view, uint64_t seed) {
  TORCH_CHECK(views > 0, "finetune_losses: no views to draw from");
  auto generator = at::make_generator<at::CPUGeneratorImpl>(seed);
  auto picks = torch::randint(0, int64_t(views), {options.finetune_batch}, generator, torch::kLong);
  std::vector<torch::Tensor> conds, gts;
  for (int64_t b = 0; b < options.finetune_batch; ++b) {
    auto [render, target] = view(size_t(picks[b].item<int64_t>()));
    torch::Tensor cond = render.detach();
    if (options.condition_noise > 0)
      cond = cond + options.condition_noise * torch::randn(cond.sizes(), generator, cond.options());
    // Both losses in the space the denoiser works in.
    conds.push_back(model::to_denoiser_space(denoiser, cond));
    gts.push_back(model::to_denoiser_space(denoiser, target.to(cond.dtype())));
  }
  // Both losses see the same crops, t and eps.
  at::Generator same = generator.clone();
  FinetuneLosses out;
  out.loss =
      model::views_diffusion_loss(model::as_predictor(denoiser), denoiser.schedule, gts, conds,
                                  options.finetune_crop, generator, options.min_snr_gamma);
  torch::NoGradGuard no_grad;
  out.identity =
      model::views_diffusion_loss(model::identity_predictor(denoiser.schedule), denoiser.schedule,
                                  gts, conds, options.finetune_crop, same, options.min_snr_gamma);
  return out;
}

double finetune_lr(double lr, int64_t k, int64_t steps) {
  constexpr double kPi = 3.14159265358979323846;
  if (steps <= 0) return lr;
  return lr * 0.5 * (1.0 + std::cos(kPi * double(k) / double(steps)));
}

fs::path denoiser_path(const RunPaths& run) {
  return run.root / "denoiser.pt";
}

void write_denoiser(const fs::path& path, model::Denoiser& denoiser) {
  torch::serialize::OutputArchive archive;
  model::save_denoiser(archive, kArchiveKey, denoiser);
  write_archive(path, archive);
}

model::Denoiser read_denoiser(const fs::path& path) {
  core::require(fs::exists(path), path, "no such denoiser file");
  torch::serialize::InputArchive archive;
  read_archive(path, archive, "not a ddhgs denoiser (unreadable or truncated)");
  return model::load_denoiser(archive, kArchiveKey, path);
}

}  // namespace ddhgs::train
