// The phase after the Gaussian iterations when the denoiser is on:
// diffusion.finetune_steps steps that train the U-Net alone on renders of
// the training views by the frozen Gaussians (train/diffusion_term.h,
// finetune_losses). The renders are made once, on the first step, when they
// fit diffusion.finetune_cache_mb; otherwise each step renders the views it
// draws.
#pragma once
#include <nlohmann/json.hpp>

#include <functional>
#include <vector>

#include "core/tensor.h"
#include "io/scene/scene.h"
#include "model/adam.h"
#include "train/diffusion_term.h"

namespace ddhgs::train {

class DenoiserFinetuning {
 public:
  // render(view) -> the frozen Gaussians' [H, W, N] render of a scene view.
  using RenderView = std::function<torch::Tensor(int view)>;
  // views: the scene views it trains on (the training views, less any kept
  // for validation).
  DenoiserFinetuning(DiffusionTerm& term, const io::Scene& scene, RenderView render,
                     std::vector<int> views);

  // Step k (0-based) of options().finetune_steps: sets the denoiser groups'
  // learning rate (finetune_lr), steps Adam and returns the metrics record
  // (without "iter"). seed: the iteration's loss-term seed.
  nlohmann::json step(int64_t k, model::Adam& adam, uint64_t seed);

 private:
  void cache_renders();

  DiffusionTerm& term_;
  const io::Scene& scene_;
  RenderView render_;
  std::vector<int> views_;
  std::vector<torch::Tensor> renders_;  // of views_, when cached
  bool cache_checked_ = false;
  // Moving averages (over ~100 steps) of the fine-tuning loss and of the
  // loss of returning the render unchanged, for metrics.jsonl; < 0 unset.
  double loss_avg_ = -1, identity_avg_ = -1;
};

}  // namespace ddhgs::train
