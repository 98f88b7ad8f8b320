// A denoiser prior: the diffusion denoiser trained across a corpus of scenes
// on pairs of novel-view renders and clean truth, instead of on one scene's
// own training views (which its Gaussians fit too closely to teach a
// correction that carries to new views).
//
// Band counts differ between scenes (3 to 141), so the prior works in each
// scene's spectral subspace (model/spectral_subspace.h): K coefficients per
// pixel, scaled by the scene's own spread. Why this and not bands or band
// groups: render errors of a Gaussian model (blur, floaters, a wrong
// silhouette) are errors of where a material is, so they move whole spectra
// and show in the leading components; a band-wise network would learn the
// same correction once per band and could not use the other bands to tell
// an edge from noise. Wavelengths need no conditioning once the spectra are
// coordinates in the scene's own basis; the noise level is the diffusion
// step's; the distance to the training views is left out (the corpus spans
// sparse to dense rigs, and a scene at inference has no single distance).
//
// The training is resumable: the prior file holds the weights (small, to
// ship), PRIOR.state.pt beside it the optimiser and the step; a rerun goes
// on from there with the same draws as one uninterrupted run.
#pragma once
#include <torch/optim/adam.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/tensor.h"
#include "io/scene/scene.h"
#include "model/diffusion.h"
#include "model/spectral_subspace.h"
#include "train/diffusion_term.h"

namespace ddhgs::train {

// Coefficients per pixel the prior sees unless told otherwise: the clean
// synthetic cubes' signal rank, and more than a 3-band scene has.
constexpr int64_t kPriorChannels = 4;

// A training pair: a novel view's render and its clean truth, as subspace
// coefficients [H, W, K] (SpectralSubspace::encode).
struct PriorPair {
  torch::Tensor render, truth;
};

// A view the training checks itself on, in its own bands: render and clean
// truth [H, W, N] and the subspace of its scene.
struct PriorCheckView {
  torch::Tensor render, truth;
  model::SpectralSubspace subspace;
};

// A scene's subspace for the prior, from its training views' pixels (about
// kSubspacePixels over all of them, every k-th pixel of each: io::sample_spectra,
// the same on every run); every view must hold every band.
model::SpectralSubspace fit_scene_subspace(const io::Scene& scene, int64_t channels);
constexpr int64_t kSubspacePixels = 200000;

// The diffusion term of a run whose config names a prior (options.prior):
// the prior's denoiser in the scene's subspace, never trained jointly,
// fine-tuned options.prior_finetune_steps steps. core::Error naming the
// prior file when it is missing or not a prior.
std::unique_ptr<DiffusionTerm> prior_term(DiffusionTermOptions options, const io::Scene& scene);

// What the prior learns: restoration (model::restoration_loss up to the
// sampler's start step: the one-step task the sampler sets at inference) or
// diffusion (model::diffusion_loss, the paper's, over every step).
enum class PriorObjective { Restoration, Diffusion };
// "restoration" | "diffusion"; core::Error naming `where` otherwise.
PriorObjective parse_prior_objective(const std::string& name, const std::string& where);
std::string to_string(PriorObjective objective);

struct PriorTrainingOptions {
  PriorObjective objective = PriorObjective::Restoration;
  int64_t steps = 20000;
  int64_t batch = 8;
  int64_t crop = 64;  // px, square; bounded by the smallest pair
  double lr = 2e-4;   // constant, then cosine to 0 over the last decay_fraction
  double decay_fraction = 0.1;
  double min_snr_gamma = 5;  // diffusion only
  uint64_t seed = 0;
  model::SamplerOptions sampler;  // for the checks; restoration trains up to its start step
};

// The prior file: the denoiser (U-Net, schedule, prediction; no subspace:
// that is each scene's) and a JSON record of how it was made.
struct PriorFile {
  model::Denoiser denoiser;
  nlohmann::json info;
};
void write_prior(const std::filesystem::path& path, model::Denoiser& denoiser,
                 const nlohmann::json& info);
// core::Error naming the file when it is missing or not a prior.
PriorFile read_prior(const std::filesystem::path& path);
// PRIOR.state.pt beside the prior file.
std::filesystem::path prior_state_path(const std::filesystem::path& prior);

class PriorTraining {
 public:
  // pairs: at least one, all with the denoiser's channel count.
  PriorTraining(model::Denoiser denoiser, const PriorTrainingOptions& options,
                std::vector<PriorPair> pairs);

  int64_t step() const { return step_; }
  // One Adam step on a batch of augmented crops (drawn from the seed and the
  // step alone). Returns the loss and the identity's on the same draws.
  std::pair<double, double> train_step();
  // Mean PSNR (dB) of the views' renders and of their denoised renders
  // against the clean truth.
  std::pair<double, double> check(const std::vector<PriorCheckView>& views) const;

  model::Denoiser& denoiser() { return denoiser_; }
  // The optimiser's moments and the step; load returns false when there is
  // no state file, throws core::Error naming it when it does not fit.
  void save_state(const std::filesystem::path& path);
  bool load_state(const std::filesystem::path& path);

 private:
  double lr_at(int64_t step) const;

  model::Denoiser denoiser_;
  PriorTrainingOptions options_;
  std::vector<PriorPair> pairs_;
  std::unique_ptr<torch::optim::Adam> adam_;
  int64_t step_ = 0;
  int64_t crop_ = 0;
};

}  // namespace ddhgs::train
