// The diffusion stage beside the Gaussian loop. After the `iterations`
// Gaussian iterations (with the joint term, train/diffusion_term.h, inside
// them when diffusion.joint is on) come diffusion.finetune_steps steps that
// train the denoiser alone (train/denoiser_finetuning.h) on pairs of renders
// and captures (diffusion.pairs: the frozen Gaussians' renders, or an
// auxiliary model's, train/denoiser_pairs.h), a validation on the training
// views it left out (diffusion.validation_every), then
// diffusion.distill_steps Gaussian iterations, some on pseudo-views
// (denoised renders between the training cameras, train/novel_views.h). The
// iteration counter runs on through all of them. The stage drives the loop
// through StageHost (train/stage_host.h).
#pragma once
#include <nlohmann/json.hpp>

#include <cstdint>
#include <map>
#include <memory>
#include <vector>

#include "core/tensor.h"
#include "train/denoiser_finetuning.h"
#include "train/diffusion_term.h"
#include "train/stage_host.h"

namespace ddhgs::train {

class DiffusionStage {
 public:
  // term: the denoiser, trained by the host as one of its modules.
  DiffusionStage(StageHost& host, DiffusionTerm& term);

  // The last fine-tuning step (the Gaussian iterations when there is none).
  int64_t finetune_end() const;
  // The last step of the stage: the fine-tuning's and the distillation's.
  int64_t total_steps() const;

  // One denoiser-only step after the Gaussian iterations; the last one
  // validates the denoiser. Returns its metrics record.
  nlohmann::json finetune_step(int64_t iteration);
  // One distillation step after the fine-tuning: a pseudo-view every
  // diffusion.distill_every-th step, else a training view. Returns its
  // metrics record.
  nlohmann::json distill_step(int64_t iteration);

  // The stage's entries of train_summary.json: the validation, the pairs and
  // their PSNR, the distillation's steps and pseudo-views.
  nlohmann::json summary() const;

 private:
  // Makes finetuning_: the training views less the validation ones.
  void finetune_setup();
  // The fine-tuning's condition for a training view (an auxiliary model's
  // render, or the frozen Gaussians').
  torch::Tensor condition(int view);
  // Denoises the training views the fine-tuning left out
  // (diffusion.validation_every) and compares them with their renders:
  // {"views", "psnr_render", "psnr_denoised"}; distillation runs only when
  // the denoiser gained on them.
  void validate();
  // The pseudo-views: made (and kept in RUN/pseudo_views.pt, so a resumed
  // run trains on the same targets) at the first distillation step, read
  // back when resuming after it.
  void make_pseudo_views(int64_t iteration);

  StageHost& host_;
  DiffusionTerm& term_;
  std::unique_ptr<DenoiserFinetuning> finetuning_;  // made on its first step
  std::map<int, torch::Tensor> pair_renders_;       // diffusion.pairs != training
  std::vector<PseudoView> pseudo_views_;            // made on the first distillation step
  std::vector<int> validation_views_;               // training views the denoiser leaves out
  nlohmann::json validation_;                       // null until validate()
  nlohmann::json pairs_psnr_;                       // mean dB of the pairs; null until made
  bool distilling_ = false;                         // whether to distil is decided
};

}  // namespace ddhgs::train
