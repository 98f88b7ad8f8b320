// The DD-HGS joint-training term (paper "End-to-End Joint Training"): after a
// warm-up of plain Gaussian training, every iteration draws a diffusion step t
// and noise eps, noises the ground-truth view to X_t and adds
//   w4 * || eps - eps_theta(X_t, t | X_3DGS) ||^2
// on one random crop shared by the render and the ground truth. Gradients
// reach the U-Net (its own Adam groups and learning rate, see
// Trainer::add_module) and, through the condition X_3DGS, the Gaussians.
// Config: loss.diffusion (w4) and the "diffusion" section of the preset,
// parsed into DiffusionTermOptions by train/run_config.h.
#pragma once
#include <nlohmann/json.hpp>

#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/tensor.h"
#include "model/diffusion.h"
#include "train/losses.h"
#include "train/run_folder.h"

namespace ddhgs::train {

enum class FinetunePairs { Training, Folds, Checkpoint, Perturbed };
// "training" | "folds" | "checkpoint" | "perturbed"; core::Error naming
// `where` otherwise.
FinetunePairs parse_finetune_pairs(const std::string& name, const std::string& where);
std::string to_string(FinetunePairs pairs);

struct DiffusionTermOptions {
  double weight = 0;           // loss.diffusion (paper w4 = 0.3); 0: no denoiser
  int64_t warmup = 0;          // iterations of Gaussians only before the term starts
  int64_t crop_px = 64;        // side of the random square crop (<= 0: whole view)
  double lr = 2e-4;            // the U-Net's Adam learning rate
  bool condition_grad = true;  // let the term's gradient reach the render (paper: yes)
  // Std (data units, reflectance) of Gaussian noise added to the condition
  // during training only, so the U-Net also sees renders worse than those of
  // training views (which the Gaussians fit closely); 0 = paper.
  double condition_noise = 0;
  // What the U-Net predicts (see model::Prediction) and the Min-SNR gamma of
  // the loss weighting (<= 0: unweighted, the paper).
  model::Prediction prediction = model::Prediction::Eps;
  double min_snr_gamma = 0;
  // Steps of denoiser-only training after the joint iterations (Gaussians
  // frozen, conditions cached), finetune_batch crops of finetune_crop px each
  // (<= 0: whole views, the size the denoiser runs at), learning rate
  // cosine-annealed from lr to 0. See finetune_loss.
  int64_t finetune_steps = 0;
  int64_t finetune_batch = 2;
  int64_t finetune_crop = 0;
  // Memory for the training views' renders, kept for the fine-tuning when
  // they fit (at 640x512 and 141 bands one render is 185 MB); otherwise each
  // step renders the views it draws (same result, slower).
  int64_t finetune_cache_mb = 1024;
  model::UNetOptions unet;  // bands set from the data
  int64_t schedule_steps = 1000;
  model::BetaSchedule schedule = model::BetaSchedule::Linear;
  double beta_start = 1e-4, beta_end = 0.02;
  // Inference defaults for eval and render (flags override).
  model::SamplerOptions sampler;

  // Where the denoiser's pairs come from, and when it learns. joint: the
  // paper's term during the Gaussian iterations (false: the denoiser is
  // trained only afterwards, and the Gaussian iterations cost what they cost
  // without the stage).
  bool joint = true;
  // What the fine-tuning learns from: renders of the training views by the
  // Gaussians that fitted them, or renders by an auxiliary model that did not
  // fit the view (train/novel_views.h, train/denoiser_pairs.h):
  //   folds: `folds` interleaved folds, each view rendered by a model trained
  //     without its fold for fold_iterations x the run's iterations;
  //   checkpoint: every view rendered by the run's own Gaussians as they were
  //     after fold_iterations x its iterations (an earlier checkpoint,
  //     recomputed: the same seed and schedule, without the joint term);
  //   perturbed: every view rendered at its pose by a model trained for
  //     fold_iterations x the run's iterations on the same views with each
  //     camera turned about its centre (a random axis) by the angle that moves
  //     the image centre perturb_px pixels.
  FinetunePairs pairs = FinetunePairs::Training;
  int64_t folds = 4;
  double fold_iterations = 0.5;
  double perturb_px = 2.0;
  // Distillation: distill_steps Gaussian iterations after the fine-tuning, of
  // which every distill_every-th trains on a pseudo-view (the denoised render
  // midway between two training cameras) with its losses scaled by
  // distill_weight; the others on the training views as before.
  int64_t distill_steps = 0;
  double distill_weight = 0.5;
  int64_t distill_every = 2;
  // Every validation_every-th training view (0: none, the default) is left
  // out of the fine-tuning and denoised after it, to see whether the denoiser
  // helps views it did not learn from; the distillation then runs only if
  // it does.
  int64_t validation_every = 0;
  // A denoiser prior file (train/denoiser_prior.h; empty: none). With one the
  // stage starts from the prior in the scene's subspace instead of a new
  // U-Net, is not trained jointly, and fine-tunes prior_finetune_steps steps
  // (instead of finetune_steps) on the pairs above.
  std::string prior;
  int64_t prior_finetune_steps = 0;

  bool enabled() const { return weight > 0 || !prior.empty(); }
};

// Holds the denoiser being trained; the trainer registers unet() as a module
// and appends loss_term().
class DiffusionTerm {
 public:
  // The U-Net's initial weights come from `init_seed` (its last layer is zero,
  // so the term starts as a pure eps-prediction task and does not disturb the
  // Gaussians at its first step).
  DiffusionTerm(const DiffusionTermOptions& options, uint64_t init_seed);
  // Starts from a trained denoiser (a prior's, with the scene's subspace).
  DiffusionTerm(const DiffusionTermOptions& options, model::Denoiser denoiser);

  // "diffusion": zero (and no graph) before the warm-up ends; afterwards the
  // eps MSE on a crop, with t, eps and the crop drawn from LossInputs::seed.
  LossTerm loss_term();

  model::Denoiser& denoiser() { return *denoiser_; }
  const DiffusionTermOptions& options() const { return options_; }

 private:
  DiffusionTermOptions options_;
  std::shared_ptr<model::Denoiser> denoiser_;  // shared with the loss closure
};

// One training evaluation of the term (what loss_term() computes after the
// warm-up): view_diffusion_loss on a crop with the options' condition handling.
torch::Tensor diffusion_term_loss(model::Denoiser& denoiser, const DiffusionTermOptions& options,
                                  const torch::Tensor& render,  // [H, W, N]
                                  const torch::Tensor& target,  // [H, W, N]
                                  uint64_t seed);

// The i-th view the fine-tuning draws from: the frozen Gaussians' render and
// the captured image, [H, W, N] each.
using FinetuneView = std::function<std::pair<torch::Tensor, torch::Tensor>(size_t i)>;

struct FinetuneLosses {
  torch::Tensor loss;      // the U-Net's, with a graph to its parameters only
  torch::Tensor identity;  // returning the render as it is (no graph)
};

// One step of the denoiser's fine-tuning: the diffusion loss (as in the joint
// term, condition noise included) on a batch of options.finetune_batch crops
// of options.finetune_crop px, from `views` views drawn with replacement
// (each fetched once), and with the same draws the loss of
// model::identity_predictor, for comparison. Only the U-Net receives
// gradients: renders are detached.
FinetuneLosses finetune_losses(model::Denoiser& denoiser, const DiffusionTermOptions& options,
                               size_t views, const FinetuneView& view, uint64_t seed);

// The fine-tuning learning rate at step k in [0, steps): lr (1 + cos(pi k /
// steps)) / 2, from lr at the first step towards 0 at the last. Averaging
// out the parameter noise of Adam at a constant rate is what the fine-tuning
// is for (a constant rate leaves the correction with a per-image bias).
double finetune_lr(double lr, int64_t k, int64_t steps);

// RUN/denoiser.pt, beside gaussians.ply.
std::filesystem::path denoiser_path(const RunPaths& run);

// The trained U-Net and its schedule, written atomically.
void write_denoiser(const std::filesystem::path& path, model::Denoiser& denoiser);
// Throws core::Error naming the file when it is missing or malformed.
model::Denoiser read_denoiser(const std::filesystem::path& path);

}  // namespace ddhgs::train
