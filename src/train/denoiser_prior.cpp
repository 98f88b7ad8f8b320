#include "train/denoiser_prior.h"

#include <torch/optim/adam.h>
#include <torch/serialize/input-archive.h>
#include <torch/serialize/output-archive.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"
#include "core/log.h"
#include "eval/metrics.h"
#include "io/scene/scene_report.h"
#include "train/checkpoint.h"
#include "train/seed.h"

namespace ddhgs::train {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr const char* kPriorKey = "prior";
constexpr const char* kPriorFormat = "ddhgs-denoiser-prior";
constexpr int kPriorVersion = 1;
constexpr uint64_t kDrawStream = 0x70726f72;  // "pror"

// One random crop of a pair, flipped and turned by a multiple of 90 degrees:
// [K, c, c] each.
std::pair<torch::Tensor, torch::Tensor> augmented_crop(const PriorPair& pair, int64_t crop,
                                                       at::Generator& generator) {
  auto draw = [&](int64_t high) {
    return torch::randint(0, high, {1}, generator, torch::kLong).item<int64_t>();
  };
  const int64_t y0 = draw(pair.render.size(0) - crop + 1);
  const int64_t x0 = draw(pair.render.size(1) - crop + 1);
  const int64_t turns = draw(4);
  const bool flip = draw(2) == 1;
  auto take = [&](const torch::Tensor& image) {
    torch::Tensor c = image.slice(0, y0, y0 + crop).slice(1, x0, x0 + crop).permute({2, 0, 1});
    if (flip) c = c.flip(2);
    return torch::rot90(c, turns, {1, 2}).contiguous();
  };
  return {take(pair.render), take(pair.truth)};
}

}  // namespace

PriorObjective parse_prior_objective(const std::string& name, const std::string& where) {
  if (name == "restoration") return PriorObjective::Restoration;
  if (name == "diffusion") return PriorObjective::Diffusion;
  throw core::Error(where, "objective '" + name + "' is neither restoration nor diffusion");
}

std::string to_string(PriorObjective objective) {
  return objective == PriorObjective::Restoration ? "restoration" : "diffusion";
}

model::SpectralSubspace fit_scene_subspace(const io::Scene& scene, int64_t channels) {
  // Every training view, as the colour model samples its few (io::sample_spectra
  // refuses a scene without training views or with band-per-view views).
  const int views = std::max<int>(1, int(scene.train.size()));
  const io::SpectraSample sample =
      io::sample_spectra(scene, views, std::max<int64_t>(1, kSubspacePixels / views));
  return model::fit_spectral_subspace(sample.spectra, channels);
}

std::unique_ptr<DiffusionTerm> prior_term(DiffusionTermOptions options, const io::Scene& scene) {
  PriorFile prior = read_prior(options.prior);
  prior.denoiser.subspace = fit_scene_subspace(scene, prior.denoiser.unet->options().bands);
  options.joint = false;
  options.finetune_steps = options.prior_finetune_steps;
  options.unet = prior.denoiser.unet->options();
  options.prediction = prior.denoiser.prediction;
  const model::NoiseSchedule& schedule = prior.denoiser.schedule;
  options.schedule_steps = schedule.steps;
  options.schedule = schedule.kind;
  options.beta_start = schedule.beta_start;
  options.beta_end = schedule.beta_end;
  options.sampler.validate(schedule.steps, options.prior);
  core::log_info("diffusion: the denoiser prior " + options.prior + " (" +
                 std::to_string(prior.info.value("steps", int64_t(0))) +
                 " steps of pretraining) in this scene's " + std::to_string(options.unet.bands) +
                 "-component spectral subspace" +
                 (options.finetune_steps > 0
                      ? ", fine-tuned " + std::to_string(options.finetune_steps) + " steps"
                      : ", not fine-tuned"));
  return std::make_unique<DiffusionTerm>(options, std::move(prior.denoiser));
}

void write_prior(const fs::path& path, model::Denoiser& denoiser, const json& info) {
  core::require(!denoiser.subspace, "write_prior: a prior holds no scene's subspace");
  torch::serialize::OutputArchive archive;
  json record = info;
  record["format"] = kPriorFormat;
  record["version"] = kPriorVersion;
  record["channels"] = denoiser.unet->options().bands;
  archive.write("prior_json", c10::IValue(record.dump()));
  model::save_denoiser(archive, kPriorKey, denoiser);
  write_archive(path, archive);
}

PriorFile read_prior(const fs::path& path) {
  core::require(fs::exists(path), path, "no such denoiser prior file");
  torch::serialize::InputArchive archive;
  read_archive(path, archive, "not a ddhgs denoiser prior (unreadable or truncated)");
  c10::IValue stored;
  core::require(archive.try_read("prior_json", stored) && stored.isString(), path,
                "not a ddhgs denoiser prior (no prior record)");
  PriorFile file;
  try {
    file.info = json::parse(stored.toStringRef());
  } catch (const json::exception& e) {
    throw core::Error(path, "prior record is malformed: " + core::message_of(e));
  }
  core::require(file.info.value("format", "") == kPriorFormat, path,
                "not a ddhgs denoiser prior (format '" + file.info.value("format", "") + "')");
  core::require(file.info.value("version", 0) == kPriorVersion, path,
                "prior version " + std::to_string(file.info.value("version", 0)) +
                    ", this build reads version " + std::to_string(kPriorVersion));
  file.denoiser = model::load_denoiser(archive, kPriorKey, path);
  core::require(!file.denoiser.subspace, path, "a prior must not hold a scene's subspace");
  return file;
}

fs::path prior_state_path(const fs::path& prior) {
  fs::path p = prior;
  p += ".state.pt";
  return p;
}

PriorTraining::PriorTraining(model::Denoiser denoiser, const PriorTrainingOptions& options,
                             std::vector<PriorPair> pairs)
    : denoiser_(std::move(denoiser)), options_(options), pairs_(std::move(pairs)) {
  core::require(!pairs_.empty(), "prior training: no pairs to learn from");
  crop_ = options_.crop;
  const int64_t channels = denoiser_.unet->options().bands;
  for (const PriorPair& p : pairs_) {
    core::require(
        p.render.dim() == 3 && p.render.sizes() == p.truth.sizes() && p.render.size(2) == channels,
        "prior training: a pair is not two [H, W, " + std::to_string(channels) + "]");
    crop_ = std::min({crop_, p.render.size(0), p.render.size(1)});
  }
  denoiser_.subspace.reset();
  adam_ = std::make_unique<torch::optim::Adam>(denoiser_.unet->parameters(),
                                               torch::optim::AdamOptions(options_.lr));
}

double PriorTraining::lr_at(int64_t step) const {
  constexpr double kPi = 3.14159265358979323846;
  const double decay_from = double(options_.steps) * (1 - options_.decay_fraction);
  if (double(step) < decay_from || options_.decay_fraction <= 0) return options_.lr;
  const double u = (double(step) - decay_from) / (double(options_.steps) - decay_from);
  return options_.lr * 0.5 * (1 + std::cos(kPi * std::min(u, 1.0)));
}

std::pair<double, double> PriorTraining::train_step() {
  auto generator = at::make_generator<at::CPUGeneratorImpl>(
      mix_seed(mix_seed(options_.seed, kDrawStream), uint64_t(step_)));
  std::vector<torch::Tensor> conds, truths;
  for (int64_t b = 0; b < options_.batch; ++b) {
    const int64_t pick =
        torch::randint(0, int64_t(pairs_.size()), {1}, generator, torch::kLong).item<int64_t>();
    auto [cond, truth] = augmented_crop(pairs_[size_t(pick)], crop_, generator);
    conds.push_back(cond);
    truths.push_back(truth);
  }
  const torch::Tensor cond = torch::stack(conds), truth = torch::stack(truths);
  at::Generator same = generator.clone();
  for (auto& group : adam_->param_groups())
    static_cast<torch::optim::AdamOptions&>(group.options()).lr(lr_at(step_));
  const int64_t t_max =
      model::start_step(denoiser_.schedule.steps, options_.sampler.start_strength);
  auto loss_of = [&](const model::NoisePredictor& predictor, at::Generator& draws) {
    return options_.objective == PriorObjective::Restoration
               ? model::restoration_loss(predictor, denoiser_.schedule, truth, cond, t_max, draws)
               : model::diffusion_loss(predictor, denoiser_.schedule, truth, cond, draws,
                                       options_.min_snr_gamma);
  };
  adam_->zero_grad();
  torch::Tensor loss = loss_of(model::as_predictor(denoiser_), generator);
  loss.backward();
  adam_->step();
  ++step_;
  torch::NoGradGuard no_grad;
  const torch::Tensor identity = loss_of(model::identity_predictor(denoiser_.schedule), same);
  return {loss.item<double>(), identity.item<double>()};
}

std::pair<double, double> PriorTraining::check(const std::vector<PriorCheckView>& views) const {
  core::require(!views.empty(), "prior training: no views to check on");
  torch::NoGradGuard no_grad;
  double raw = 0, denoised = 0;
  for (const PriorCheckView& v : views) {
    model::Denoiser scene_denoiser = denoiser_;
    scene_denoiser.subspace = v.subspace;
    raw += eval::psnr_db(v.render.clamp(0.0, 1.0), v.truth);
    denoised +=
        eval::psnr_db(model::denoise_view(scene_denoiser, v.render, options_.sampler), v.truth);
  }
  return {raw / double(views.size()), denoised / double(views.size())};
}

void PriorTraining::save_state(const fs::path& path) {
  torch::serialize::OutputArchive archive, adam;
  archive.write("step", torch::tensor(step_, torch::kLong));
  model::save_denoiser(archive, kPriorKey, denoiser_);
  adam_->save(adam);
  archive.write("adam", adam);
  write_archive(path, archive);
}

bool PriorTraining::load_state(const fs::path& path) {
  if (!fs::exists(path)) return false;
  torch::serialize::InputArchive archive, adam;
  read_archive(path, archive, "not a prior training state (unreadable or truncated)");
  torch::Tensor step;
  core::require(
      archive.try_read("step", step) && step.numel() == 1 && archive.try_read("adam", adam), path,
      "not a prior training state (no step or optimiser)");
  model::Denoiser saved = model::load_denoiser(archive, kPriorKey, path);
  const auto mine = denoiser_.unet->named_parameters(), theirs = saved.unet->named_parameters();
  core::require(
      mine.size() == theirs.size() && model::unet_options_to_json(saved.unet->options()) ==
                                          model::unet_options_to_json(denoiser_.unet->options()),
      path, "the saved prior's network differs from the one asked for");
  torch::NoGradGuard no_grad;
  for (const auto& p : mine) p.value().copy_(theirs[p.key()]);
  try {
    adam_->load(adam);
  } catch (const c10::Error&) {
    throw core::Error(path, "the optimiser state does not fit the network");
  }
  step_ = step.item<int64_t>();
  return true;
}

}  // namespace ddhgs::train
