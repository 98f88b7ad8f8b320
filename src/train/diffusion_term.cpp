#include "train/diffusion_term.h"

#include <ATen/CPUGeneratorImpl.h>

#include <cmath>

#include "core/error.h"
#include "io/files/atomic_file.h"

namespace ddhgs::train {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

const char* const kArchiveKey = "denoiser";

template <typename T>
T read_key(const json& section, const char* key, const std::string& where) {
  try {
    return section.at(key).get<T>();
  } catch (const json::exception&) {
    throw core::Error(where + ": diffusion." + key + " is missing or has the wrong type");
  }
}

}  // namespace

DiffusionTermOptions diffusion_term_options(const json& config, int64_t bands,
                                            const std::string& where) {
  DiffusionTermOptions o;
  o.weight = config.at("loss").at("diffusion").get<double>();
  const json& d = config.at("diffusion");
  o.warmup = read_key<int64_t>(d, "warmup", where);
  o.crop_px = read_key<int64_t>(d, "crop", where);
  o.lr = read_key<double>(d, "lr", where);
  o.condition_grad = read_key<bool>(d, "condition_grad", where);
  o.condition_noise = read_key<double>(d, "condition_noise", where);
  o.prediction =
      model::parse_prediction(read_key<std::string>(d, "prediction", where), where + ": diffusion");
  o.min_snr_gamma = read_key<double>(d, "min_snr_gamma", where);
  o.finetune_steps = read_key<int64_t>(d, "finetune_steps", where);
  o.finetune_batch = read_key<int64_t>(d, "finetune_batch", where);
  o.finetune_crop = read_key<int64_t>(d, "finetune_crop", where);
  o.finetune_cache_mb = read_key<int64_t>(d, "finetune_cache_mb", where);
  o.unet = model::unet_options_from_json(d, where + ": diffusion");
  o.unet.bands = bands;
  o.schedule_steps = read_key<int64_t>(d, "steps", where);
  o.schedule = model::parse_beta_schedule(read_key<std::string>(d, "schedule", where),
                                          where + ": diffusion");
  o.beta_start = read_key<double>(d, "beta_start", where);
  o.beta_end = read_key<double>(d, "beta_end", where);
  o.sampler.steps = read_key<int64_t>(d, "sampler_steps", where);
  o.sampler.start_strength = read_key<double>(d, "start_strength", where);
  o.sampler.eta = read_key<double>(d, "eta", where);
  o.sampler.samples = read_key<int64_t>(d, "sampler_samples", where);
  o.sampler.seed = config.at("seed").get<uint64_t>();
  core::require(o.weight >= 0, where + ": loss.diffusion must be >= 0");
  core::require(o.warmup >= 0, where + ": diffusion.warmup must be >= 0");
  core::require(o.lr > 0, where + ": diffusion.lr must be > 0");
  core::require(o.condition_noise >= 0, where + ": diffusion.condition_noise must be >= 0");
  core::require(o.finetune_steps >= 0, where + ": diffusion.finetune_steps must be >= 0");
  core::require(o.finetune_batch >= 1, where + ": diffusion.finetune_batch must be >= 1");
  core::require(o.finetune_cache_mb >= 0, where + ": diffusion.finetune_cache_mb must be >= 0");
  core::require(o.schedule_steps >= 1, where + ": diffusion.steps must be >= 1");
  o.sampler.validate(o.schedule_steps, where + ": diffusion");
  return o;
}

DiffusionTerm::DiffusionTerm(const DiffusionTermOptions& options, uint64_t init_seed)
    : options_(options), denoiser_(std::make_shared<model::Denoiser>()) {
  torch::manual_seed(init_seed);
  denoiser_->unet = model::UNet(options_.unet);
  denoiser_->schedule = model::NoiseSchedule(options_.schedule_steps, options_.schedule,
                                             options_.beta_start, options_.beta_end);
  denoiser_->prediction = options_.prediction;
}

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
    conds.push_back(cond);
    gts.push_back(target.to(cond.dtype()));
  }
  // Both losses see the same crops, t and eps.
  at::Generator same = generator.clone();
  FinetuneLosses out;
  out.loss = model::views_diffusion_loss(denoiser, gts, conds, options.finetune_crop, generator,
                                         options.min_snr_gamma);
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
  // Through a sink: LibTorch's own file writer ends the process when the disk is full.
  io::write_stream_atomically(path, [&](io::FileSink& sink) {
    archive.save_to([&](const void* data, size_t size) { return sink.write(data, size); });
  });
}

model::Denoiser read_denoiser(const fs::path& path) {
  core::require(fs::exists(path), path, "no such denoiser file");
  torch::serialize::InputArchive archive;
  try {
    archive.load_from(path.string());
  } catch (const c10::Error&) {
    throw core::Error(path, "not a ddhgs denoiser (unreadable or truncated)");
  }
  return model::load_denoiser(archive, kArchiveKey, path);
}

}  // namespace ddhgs::train
