#include "train/denoiser_finetuning.h"

#include "core/log.h"

namespace ddhgs::train {

DenoiserFinetuning::DenoiserFinetuning(DiffusionTerm& term, const io::Scene& scene,
                                       RenderView render, std::vector<int> views)
    : term_(term), scene_(scene), render_(std::move(render)), views_(std::move(views)) {}

void DenoiserFinetuning::cache_renders() {
  cache_checked_ = true;
  double bytes = 0;
  for (int v : views_) {
    const auto& in = scene_.views[v].camera.intrinsics;
    bytes += double(in.width) * double(in.height) * double(scene_.bands()) * sizeof(float);
  }
  const bool cache = bytes <= double(term_.options().finetune_cache_mb) * 1024.0 * 1024.0;
  core::log_info("denoiser fine-tuning (Gaussians frozen from here on): " +
                 std::string(cache ? "rendering the training views once"
                                   : "the training views' renders exceed the cache budget, "
                                     "rendering them as they are drawn"));
  if (cache)
    for (int v : views_) renders_.push_back(render_(v));
}

nlohmann::json DenoiserFinetuning::step(int64_t k, model::Adam& adam, uint64_t seed) {
  if (!cache_checked_) cache_renders();
  const DiffusionTermOptions& options = term_.options();
  const double lr = finetune_lr(options.lr, k, options.finetune_steps);
  for (auto& group : adam.groups())
    if (group.name.rfind("denoiser/", 0) == 0) group.lr = lr;
  const FinetuneLosses losses = finetune_losses(
      term_.denoiser(), options, views_.size(),
      [&](size_t i) {
        const int v = views_[i];
        return std::make_pair(renders_.empty() ? render_(v) : renders_[i], scene_.image(v));
      },
      seed);
  losses.loss.backward();
  adam.step();
  adam.zero_grad();
  auto average = [](double& avg, double value) {
    avg = avg < 0 ? value : 0.99 * avg + 0.01 * value;
  };
  const double loss = losses.loss.item<double>(), identity = losses.identity.item<double>();
  average(loss_avg_, loss);
  average(identity_avg_, identity);
  return {{"phase", "denoiser"},
          {"diffusion", loss},
          {"diffusion_identity", identity},
          {"diffusion_avg", loss_avg_},
          {"diffusion_identity_avg", identity_avg_},
          {"denoiser_lr", lr}};
}

}  // namespace ddhgs::train
