#include "train/diffusion_stage.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>

#include "core/error.h"
#include "core/log.h"
#include "core/threads.h"
#include "eval/metrics.h"
#include "model/diffusion.h"
#include "train/checkpoint.h"
#include "train/denoiser_pairs.h"
#include "train/novel_views.h"
#include "train/seed.h"

namespace ddhgs::train {

namespace fs = std::filesystem;
using nlohmann::json;

DiffusionStage::DiffusionStage(StageHost& host, DiffusionTerm& term) : host_(host), term_(term) {}

int64_t DiffusionStage::finetune_end() const {
  return host_.config().iterations + term_.options().finetune_steps;
}

int64_t DiffusionStage::total_steps() const {
  return finetune_end() + term_.options().distill_steps;
}

json DiffusionStage::finetune_step(int64_t iteration) {
  core::TorchThreads torch_threads;  // the denoiser's convolutions
  if (!finetuning_) finetune_setup();
  const RunConfig& config = host_.config();
  json record = finetuning_->step(iteration - config.iterations - 1, host_.state().adam,
                                  mix_seed(config.seed, kTermStream + uint64_t(iteration)));
  record["iter"] = iteration;
  if (iteration == finetune_end()) validate();
  return record;
}

void DiffusionStage::finetune_setup() {
  const io::Scene& scene = host_.scene();
  if (term_.options().pairs != FinetunePairs::Training && pair_renders_.empty())
    pair_renders_ = pair_renders(host_, term_.options());
  std::vector<int> views;
  validation_views_.clear();
  const int64_t every = term_.options().validation_every;
  for (size_t i = 0; i < scene.train.size(); ++i)
    (every > 0 && int64_t(i) % every == every / 2 ? validation_views_ : views)
        .push_back(scene.train[i]);
  if (views.empty()) std::swap(views, validation_views_);
  {
    // How much error the pairs carry: their renders against the captures.
    core::TorchThreads torch_threads;
    torch::NoGradGuard no_grad;
    double sum = 0;
    for (int v : views) sum += eval::psnr_db(condition(v).clamp(0, 1), scene.image(v));
    pairs_psnr_ = sum / double(views.size());
    char text[160];
    std::snprintf(
        text, sizeof text, "denoiser pairs (%s): %zu renders at %.2f dB against their captures",
        to_string(term_.options().pairs).c_str(), views.size(), pairs_psnr_.get<double>());
    core::log_info(text);
  }
  finetuning_ = std::make_unique<DenoiserFinetuning>(
      term_, scene, [this](int v) { return condition(v); }, views);
}

torch::Tensor DiffusionStage::condition(int view) {
  if (term_.options().pairs != FinetunePairs::Training) {
    if (pair_renders_.empty()) pair_renders_ = pair_renders(host_, term_.options());
    return pair_renders_.at(view);
  }
  return host_.render_view(view);
}

void DiffusionStage::validate() {
  validation_ = {{"views", validation_views_.size()}};
  if (validation_views_.empty()) return;
  const io::Scene& scene = host_.scene();
  core::TorchThreads torch_threads;
  torch::NoGradGuard no_grad;
  double raw = 0, denoised = 0;
  for (size_t i = 0; i < validation_views_.size(); ++i) {
    const int v = validation_views_[i];
    const torch::Tensor render = condition(v), target = scene.image(v);
    model::SamplerOptions sampler = term_.options().sampler;
    sampler.seed = mix_seed(host_.config().seed, kTermStream + uint64_t(finetune_end()) + i);
    raw += eval::psnr_db(render.clamp(0, 1), target);
    denoised += eval::psnr_db(model::denoise_view(term_.denoiser(), render, sampler), target);
  }
  const double n = double(validation_views_.size());
  validation_["psnr_render"] = raw / n;
  validation_["psnr_denoised"] = denoised / n;
  char text[200];
  std::snprintf(text, sizeof text,
                "denoiser on %zu training views it did not learn from: %.2f dB denoised against "
                "%.2f dB as rendered (%+.2f dB)",
                validation_views_.size(), denoised / n, raw / n, (denoised - raw) / n);
  core::log_info(text);
}

void DiffusionStage::make_pseudo_views(int64_t iteration) {
  const DiffusionTermOptions& o = term_.options();
  const io::Scene& scene = host_.scene();
  const RunPaths& run = host_.run_paths();
  std::vector<core::Camera> train_cameras;
  for (int v : scene.train) train_cameras.push_back(scene.views[v].camera);
  std::vector<core::Camera> cameras = between_cameras(train_cameras);
  if (cameras.empty())
    throw core::Error(run.root, "distillation needs at least two training views");
  // As many as the fine-tuning's memory budget holds, evenly spread.
  const auto& in = cameras.front().intrinsics;
  const double bytes = double(in.width) * double(in.height) * double(scene.bands()) * 4.0;
  const size_t fit = size_t(std::max(1.0, double(o.finetune_cache_mb) * 1048576.0 / bytes));
  if (cameras.size() > fit) {
    std::vector<core::Camera> kept;
    for (size_t i = 0; i < fit; ++i) kept.push_back(cameras[i * cameras.size() / fit]);
    core::log_info("distillation: " + std::to_string(fit) + " of " +
                   std::to_string(cameras.size()) +
                   " pseudo-views fit diffusion.finetune_cache_mb");
    cameras = kept;
  }
  const fs::path file = run.pseudo_views();
  if (iteration > finetune_end() + 1 && fs::exists(file)) {
    const std::string unreadable = "unreadable or truncated: start the run again with --force";
    torch::serialize::InputArchive archive;
    read_archive(file, archive, unreadable);
    torch::Tensor targets;
    if (!archive.try_read("targets", targets)) throw core::Error(file, unreadable);
    if (targets.dim() != 4 || targets.size(0) != int64_t(cameras.size()))
      throw core::Error(file, "does not hold this run's pseudo-views");
    for (size_t i = 0; i < cameras.size(); ++i)
      pseudo_views_.push_back({cameras[i], targets[int64_t(i)]});
    return;
  }
  if (iteration > finetune_end() + 1)
    throw core::Error(file,
                      "missing: the distillation cannot resume without its pseudo-views; "
                      "resume with --iterations to redo the stage");
  core::TorchThreads torch_threads;  // the denoiser's convolutions
  torch::NoGradGuard no_grad;
  core::ProgressBar bar("pseudo-views", int64_t(cameras.size()));
  std::vector<torch::Tensor> targets;
  for (size_t i = 0; i < cameras.size(); ++i) {
    const torch::Tensor render = host_.render_camera(cameras[i]);
    model::SamplerOptions sampler = o.sampler;
    sampler.seed = mix_seed(host_.config().seed, kTermStream + uint64_t(iteration) + i);
    targets.push_back(model::denoise_view(term_.denoiser(), render, sampler));
    pseudo_views_.push_back({cameras[i], targets.back()});
    bar.update(int64_t(i) + 1);
  }
  bar.finish();
  torch::serialize::OutputArchive archive;
  archive.write("targets", torch::stack(targets));
  write_archive(file, archive);
}

json DiffusionStage::distill_step(int64_t iteration) {
  if (validation_.is_null()) {
    // Resumed after the fine-tuning: the same verdict again.
    if (!finetuning_) finetune_setup();
    validate();
  }
  if (!distilling_) {
    distilling_ = true;  // decided once per process
    const bool gained =
        !validation_.contains("psnr_denoised") ||
        validation_["psnr_denoised"].get<double>() > validation_["psnr_render"].get<double>();
    if (gained) {
      make_pseudo_views(iteration);
    } else if (iteration == finetune_end() + 1) {
      core::log_warn(
          "distillation skipped: the denoiser made the views it did not learn from worse, so "
          "its pseudo-views would teach the Gaussians its errors; the " +
          std::to_string(term_.options().distill_steps) +
          " iterations left train on the training views only");
    }
  }
  const int64_t every = term_.options().distill_every;
  const int64_t k = iteration - finetune_end() - 1;
  const bool on_pseudo = !pseudo_views_.empty() && k % every == every - 1;
  const size_t p = on_pseudo ? size_t(k / every) % pseudo_views_.size() : 0;
  json record = host_.step(iteration, on_pseudo ? &pseudo_views_[p] : nullptr);
  record["phase"] = "distill";
  if (on_pseudo) record["pseudo_view"] = p;
  return record;
}

json DiffusionStage::summary() const {
  json out = json::object();
  if (!validation_.is_null()) out["denoiser_validation"] = validation_;
  out["denoiser_pairs"] = to_string(term_.options().pairs);
  if (!pairs_psnr_.is_null()) out["denoiser_pairs_psnr"] = pairs_psnr_;
  out["distill_steps"] = term_.options().distill_steps;
  out["pseudo_views"] = pseudo_views_.size();
  return out;
}

}  // namespace ddhgs::train
