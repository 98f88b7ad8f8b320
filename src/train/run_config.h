// A run's configuration as typed values: one struct per section of
// configs/default.json (the schema, train/config.h), parsed once from the
// resolved JSON and passed to the code that uses it. Nothing outside
// parse_run_config reads a training key from JSON.
//
// The JSON stays what a run folder keeps (config.json) and what runs are
// compared by; the lists of keys that act only at evaluation or only in the
// denoiser's fine-tuning (which ablation and run reuse leave out of that
// comparison) live here too, beside the fields they name.
#pragma once
#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "io/scene/scene.h"
#include "model/densify.h"
#include "model/wavelength_encoder.h"
#include "train/diffusion_term.h"
#include "train/init.h"
#include "train/spectral_loss.h"

namespace ddhgs::train {

struct DataConfig {
  std::filesystem::path path;  // the dataset; empty in presets
  io::LoadOptions load;        // downscale, rgb, band_min_nm, band_max_nm, bin, cache_mb
  // A block of a flight (a scene with partition's block.json) trains as the
  // flight's own model would have trained its ground: the flight's schedule
  // of steps over all its training views (a step whose view lies elsewhere
  // moves the Gaussians on their Adam momentum alone), the flight's extent,
  // and a loss only where a pixel's ground lies in the block's cell and
  // margin. False: the block trains as a scene of its own.
  bool block_as_flight = true;
};

// Whether each training view learns a gain per band for its capture's light
// (train/exposure_correction.h): Auto on band-per-view scenes (rig captures)
// only.
enum class ExposureMode { Auto, On, Off };

struct ModelConfig {
  int sh_degree = 3;
  // The colour model (model/colour_model.h): 0 one SH set per band; K > 0 SH
  // over K latent channels and a band basis (at most the band count); -1 the
  // scene's own signal rank (core::whitened_signal_rank of its views) when
  // it has at least subspace_from_bands bands, else per band.
  int spectral_rank = 0;
  int subspace_from_bands = 0;
  double sh_degree_every_fraction = 0;  // of iterations (train/schedule.h)
  // One value for every band (background_per_band false, one element), or
  // one per band (checked against the scene's band count: background()).
  std::vector<float> background;
  bool background_per_band = false;   // model.background was a list
  bool background_from_views = true;  // start from the training views' border colour
  bool learn_background = true;       // the background is a trained parameter
  ExposureMode exposure_correction = ExposureMode::Auto;
};

struct OptimConfig {
  double means_lr_init = 0, means_lr_final = 0;  // x scene extent
  double means_lr_decay_fraction = 1;            // of iterations
  double sh_dc_lr = 0;
  double sh_rest_lr_divisor = 1;  // sh_rest learns at sh_dc_lr / this
  double basis_lr = 0;            // a latent colour model's basis and mean
  // A latent colour model's SH learn at this times the rates above.
  double latent_sh_lr_scale = 1;
  double opacity_lr = 0, scaling_lr = 0, rotation_lr = 0;
  double adam_eps = 1e-15;
  double background_lr = 0;
  // Every rate above but the positions' (which decay on their own schedule)
  // falls log-linearly from lr_decay_from_fraction of the run to
  // lr_final_scale times its value at the last iteration; 1: constant.
  double lr_decay_from_fraction = 0.9;
  double lr_final_scale = 1;
  double exposure_lr = 0;  // the views' log gains (falls with the rates above)
  // A band-per-view scene (one band image per view, a rig's flight) trains
  // for at most this many iterations per training view, when that is fewer
  // than `iterations` (train/schedule.h); 0: `iterations` as given.
  int64_t iterations_per_band_view = 0;
};

struct LossConfig {
  double l1 = 0, dssim = 0, spectral = 0;  // weights
  // A latent colour model's Gaussian iterations measure every term on this
  // many bands, drawn afresh each iteration (train/band_draw.h); 0: all.
  int bands_per_step = 0;
  // ... for this fraction of the Gaussian iterations (the first ones); every
  // band after.
  double bands_per_step_until_fraction = 1;
  // The Gaussian iterations measure every term on a random crop of their
  // view holding this fraction of its pixels on average (train/view_crop.h);
  // 1: the whole view.
  double view_fraction = 1;
  // ... for this fraction of the Gaussian iterations (the first ones); the
  // whole view after.
  double view_fraction_until_fraction = 1;
  // ... on views of at least this many pixels (crop_fraction); smaller
  // views stay whole.
  int64_t view_fraction_from_pixels = 0;
  // Weight of the mean squared log gain of a step's view (exposure correction).
  double exposure_prior = 0;
  SpectralLossOptions spectral_options;  // spectral_alpha, spectral_beta, spectral_temperature
  // loss.diffusion is DiffusionTermOptions::weight (RunConfig::diffusion).
};

struct WavelengthEncoderConfig {
  bool enabled = false;
  model::WavelengthEncoderOptions network;  // sh_coeffs from model.sh_degree
  double lr = 0;
};

struct CameraRefinementConfig {
  bool enabled = false;  // one correction per training view (train/camera_refinement.h)
  double rotation_lr = 0, translation_lr = 0;
  // One correction per band camera of a rig scene, shared by every capture
  // (train/rig_refinement.h): Adam rates of its rotation (rad) and offset
  // (scene extents), and the weight of its L2 pull towards the factory values;
  // for the first rig_warmup_fraction of the iterations only the reference
  // camera's views train, so the Gaussians settle where it places them;
  // for the next rig_align_fraction the band cameras' views train their
  // corrections and the colours but not the Gaussians' shape, with rates
  // falling to a tenth, and the corrections are held after it (0: no such
  // phase; the rates fall with the others). rig_pivot: each band camera
  // turns about the point the reference camera looks at (the scene's median
  // depth in its views) instead of its centre (train/rig_refinement.h).
  bool rig = false, rig_pivot = false;
  double rig_rotation_lr = 0, rig_offset_lr = 0, rig_pull = 0, rig_warmup_fraction = 0;
  double rig_align_fraction = 0;
  // rig_start: a rig_corrections.json (an earlier run's) the corrections
  // start from instead of the factory values; empty: none.
  std::string rig_start;
};

struct DensifyConfig {
  double from_fraction = 0, until_fraction = 0;  // of iterations
  int64_t every = 100;                           // iterations
  double opacity_reset_every_fraction = 0;       // of iterations; 0: never
  model::DensifyOptions thresholds;              // grad_threshold ... max_gaussians
};

struct OutputConfig {
  int64_t log_every = 10;  // iterations between metrics.jsonl records
  int64_t checkpoint_every = 5000;
  // Iterations between test-view PSNR records in metrics.jsonl (0: none);
  // their time is left out of the records' "seconds".
  int64_t test_every = 1000;
};

struct RunConfig {
  nlohmann::json resolved;  // the JSON it was parsed from (what config.json holds)
  uint64_t seed = 0;
  int64_t iterations = 0;  // Gaussian iterations (the denoiser's fine-tuning follows)
  DataConfig data;
  ModelConfig model;
  InitOptions init;  // sh_degree from model.sh_degree; seed is the run's (unmixed)
  OptimConfig optim;
  LossConfig loss;
  WavelengthEncoderConfig wavelength_encoder;
  CameraRefinementConfig camera_refinement;
  // The "diffusion" section and loss.diffusion; unet.bands is 0 until
  // with_bands() sets it from the data; sampler.seed is the run's seed.
  DiffusionTermOptions diffusion;
  DensifyConfig densify;
  OutputConfig output;
};

// Validates (validate_config) and parses a resolved config read from
// `source`; core::Error naming source and the key on a bad value.
RunConfig parse_run_config(const nlohmann::json& config, const std::string& source);

// The diffusion options for a scene of `bands` bands.
DiffusionTermOptions with_bands(DiffusionTermOptions options, int64_t bands);

// The background colour for N bands (model.background: one value or N).
torch::Tensor background(const ModelConfig& model, int64_t bands);

// Keys of the "diffusion" section that act only when a trained run is
// evaluated or rendered (the sampler's), and those that act only after the
// Gaussian iterations (the denoiser's pairs, fine-tuning and distillation).
const std::vector<std::string>& sampler_keys();
const std::vector<std::string>& finetune_keys();

}  // namespace ddhgs::train
