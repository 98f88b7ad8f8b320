// The values a config may hold, beyond their types (config.cpp checks those):
// a nonsense value ends the command before any work, naming the key, instead
// of training on it (a zero divisor made every SH coefficient infinite) or
// failing only when the run is written out (an SH degree the PLY cannot hold).
#include <cmath>

#include "core/error.h"
#include "train/config.h"

namespace ddhgs::train {

namespace {

using nlohmann::json;

struct Range {
  const char* key;  // dotted path
  double min, max;  // bounds
  bool above_min;   // min itself excluded
  bool integer = false;
  bool below_max = false;  // max itself excluded
};

// Every number a config holds has a range here (Config.EveryNumberHasARange
// checks that), with an upper bound where a larger value could only run until
// killed, overflow or train on infinities. Rates above kMaxRate, weights above
// kMaxWeight and counts above the bounds below are nonsense for any scene this
// tool can hold in memory; the bounds are loose on purpose.
constexpr double kMaxRate = 100;                 // learning rates
constexpr double kMaxWeight = 1e6;               // loss weights
constexpr double kMaxCount = 1e9;                // iterations, steps, Gaussians
constexpr double kMaxMiB = 1 << 30;              // memory budgets, MiB
constexpr double kMaxSeed = 9007199254740992.0;  // 2^53: every seed a JSON double holds exactly

constexpr Range kRanges[] = {
    {"seed", 0, kMaxSeed, false, true},
    {"iterations", 1, kMaxCount, false, true},
    {"data.downscale", 1, 4096, false, true},
    {"data.band_min_nm", 0, 1e9, false},
    {"data.band_max_nm", 0, 1e9, false},
    {"data.bin", 1, 100000, false, true},
    {"data.band_step", 1, 100000, false, true},
    {"data.cache_mb", 0, kMaxMiB, false, true},
    {"model.sh_degree", 0, 3, false, true},
    {"model.spectral_rank", -1, 4096, false, true},
    {"model.subspace_from_bands", 0, 100000, false, true},
    // Fractions of the run for intervals may pass 1 (decay over a longer run
    // than this one, never reset): only their sign is nonsense.
    {"model.sh_degree_every_fraction", 0, 1e6, false},
    {"model.background", -1e6, 1e6, false},
    {"init.random_points", 1, 1e8, false, true},
    {"init.extra_random_per_pixel", 0, 1000, false},
    {"init.opacity", 0, 1, true, false, true},
    {"init.neighbours", 1, 1000, false, true},
    {"init.colour_views", 1, 1e6, false, true},
    {"optim.means_lr_init", 0, kMaxRate, false},
    {"optim.means_lr_final", 0, kMaxRate, false},
    {"optim.means_lr_decay_fraction", 0, 1e6, true},
    {"optim.sh_dc_lr", 0, kMaxRate, false},
    {"optim.sh_rest_lr_divisor", 0, 1e9, true},
    {"optim.opacity_lr", 0, kMaxRate, false},
    {"optim.scaling_lr", 0, kMaxRate, false},
    {"optim.rotation_lr", 0, kMaxRate, false},
    {"optim.adam_eps", 0, 1, true},
    {"optim.background_lr", 0, kMaxRate, false},
    {"optim.basis_lr", 0, kMaxRate, false},
    {"optim.latent_sh_lr_scale", 0, 1e6, false},
    {"optim.lr_decay_from_fraction", 0, 1, false},
    {"optim.lr_final_scale", 0, 1, true},
    {"optim.exposure_lr", 0, kMaxRate, false},
    {"optim.iterations_per_band_view", 0, kMaxCount, false, true},
    {"loss.l1", 0, kMaxWeight, false},
    {"loss.dssim", 0, kMaxWeight, false},
    {"loss.spectral", 0, kMaxWeight, false},
    {"loss.spectral_alpha", 0, kMaxWeight, false},
    {"loss.spectral_beta", 0, kMaxWeight, false},
    {"loss.spectral_temperature", 0, 1e6, true},
    {"loss.diffusion", 0, kMaxWeight, false},
    {"loss.bands_per_step", 0, kMaxCount, false, true},
    {"loss.bands_per_step_until_fraction", 0, 1, false},
    {"loss.view_fraction", 0, 1, true},
    {"loss.view_fraction_until_fraction", 0, 1, false},
    {"loss.view_fraction_from_pixels", 0, kMaxCount, false, true},
    {"loss.exposure_prior", 0, kMaxWeight, false},
    {"wavelength_encoder.frequencies", 0, 24, false, true},  // 2^24 x a wavelength stays finite
    {"wavelength_encoder.hidden", 1, 4096, false, true},
    {"wavelength_encoder.layers", 1, 64, false, true},
    {"wavelength_encoder.output_scale", 0, 1e3, false},
    {"wavelength_encoder.lr", 0, kMaxRate, false},
    {"camera_refinement.rotation_lr", 0, kMaxRate, false},
    {"camera_refinement.translation_lr", 0, kMaxRate, false},
    {"camera_refinement.rig_rotation_lr", 0, kMaxRate, false},
    {"camera_refinement.rig_offset_lr", 0, kMaxRate, false},
    {"camera_refinement.rig_pull", 0, kMaxWeight, false},
    {"camera_refinement.rig_warmup_fraction", 0, 1, false},
    {"camera_refinement.rig_align_fraction", 0, 1, false},
    {"diffusion.warmup", 0, kMaxCount, false, true},
    {"diffusion.crop", 0, 65536, false, true},
    {"diffusion.lr", 0, kMaxRate, true},
    {"diffusion.condition_noise", 0, 1e3, false},
    {"diffusion.min_snr_gamma", 0, 1e9, false},
    {"diffusion.finetune_steps", 0, kMaxCount, false, true},
    {"diffusion.finetune_batch", 1, 4096, false, true},
    {"diffusion.finetune_crop", 0, 65536, false, true},
    {"diffusion.finetune_cache_mb", 0, kMaxMiB, false, true},
    {"diffusion.base_channels", 1, 4096, false, true},
    {"diffusion.channel_multipliers", 1, 64, false, true},
    {"diffusion.blocks_per_level", 0, 64, false, true},
    {"diffusion.steps", 1, 100000, false, true},
    {"diffusion.beta_start", 0, 1, true, false, true},
    {"diffusion.beta_end", 0, 1, true, false, true},
    {"diffusion.sampler_steps", 1, 100000, false, true},
    {"diffusion.start_strength", 0, 1, true},
    {"diffusion.eta", 0, 1, false},
    {"diffusion.sampler_samples", 1, 1000, false, true},
    {"diffusion.folds", 2, 1000, false, true},
    {"diffusion.fold_iterations", 0, 100, true},
    {"diffusion.perturb_px", 0, 1e4, false},
    {"diffusion.distill_steps", 0, kMaxCount, false, true},
    {"diffusion.distill_weight", 0, kMaxWeight, false},
    {"diffusion.distill_every", 1, kMaxCount, false, true},
    {"diffusion.validation_every", 0, kMaxCount, false, true},
    {"diffusion.prior_finetune_steps", 0, kMaxCount, false, true},
    {"densify.from_fraction", 0, 1, false},
    {"densify.until_fraction", 0, 1, false},
    {"densify.every", 0, kMaxCount, false, true},
    {"densify.grad_threshold", 0, 1e6, false},
    {"densify.percent_dense", 0, 1, false},
    {"densify.opacity_reset_every_fraction", 0, 1e6, false},
    {"densify.min_opacity", 0, 1, false},
    {"densify.max_screen_px", 0, 1e9, false},
    {"densify.max_world_fraction", 0, 1e6, false},
    {"densify.max_gaussians", 0, 1e9, false, true},
    {"output.log_every", 0, kMaxCount, false, true},
    {"output.checkpoint_every", 0, kMaxCount, false, true},
    {"output.test_every", 0, kMaxCount, false, true},
};

const json* find_key(const json& config, const std::string& dotted) {
  const json* node = &config;
  size_t start = 0;
  while (true) {
    const size_t dot = dotted.find('.', start);
    const std::string key = dotted.substr(start, dot == std::string::npos ? dot : dot - start);
    if (!node->is_object() || !node->contains(key)) return nullptr;
    node = &node->at(key);
    if (dot == std::string::npos) return node;
    start = dot + 1;
  }
}

std::string bound_text(double value) {
  if (std::isinf(value)) return "";
  const auto integer = static_cast<long long>(value);
  return double(integer) == value ? std::to_string(integer) : std::to_string(value);
}

std::string wanted(const Range& r) {
  std::string kind = r.integer ? "an integer" : "a number";
  std::string lower = std::string(r.above_min ? " > " : " >= ") + bound_text(r.min);
  if (std::isinf(r.max)) return kind + lower;
  return kind + lower + (r.below_max ? " and < " : " and <= ") + bound_text(r.max);
}

void check_range(const Range& r, const json& value, const std::string& source) {
  if (value.is_array()) {  // model.background, diffusion.channel_multipliers: each element
    for (const json& element : value) check_range(r, element, source);
    return;
  }
  if (!value.is_number()) return;  // types are checked apart
  const double v = value.get<double>();
  const bool ok = std::isfinite(v) && (r.above_min ? v > r.min : v >= r.min) &&
                  (r.below_max ? v < r.max : v <= r.max) && (!r.integer || v == std::floor(v));
  if (!ok)
    throw core::Error(source, "key '" + std::string(r.key) + "' is " +
                                  (std::isfinite(v) ? value.dump() : std::to_string(v)) +
                                  ", expected " + wanted(r));
}

// Rules across keys: some loss fits the views, the band range keeps a band,
// the noise schedule rises.
void check_config_relations(const json& config, const std::string& source) {
  auto number = [&](const char* key) {
    const json* v = find_key(config, key);
    return v && v->is_number() ? v->get<double>() : std::nan("");
  };
  if (number("loss.l1") == 0 && number("loss.dssim") == 0)
    throw core::Error(source,
                      "keys 'loss.l1' and 'loss.dssim' are both 0: nothing would fit the views "
                      "(give one of them a weight > 0)");
  if (number("data.band_min_nm") > number("data.band_max_nm"))
    throw core::Error(source,
                      "key 'data.band_min_nm' is above 'data.band_max_nm': no band is kept");
  if (number("diffusion.beta_start") > number("diffusion.beta_end"))
    throw core::Error(source, "key 'diffusion.beta_start' is above 'diffusion.beta_end'");
}

}  // namespace

void check_config_values(const json& config, const std::string& source) {
  for (const Range& r : kRanges)
    if (const json* value = find_key(config, r.key)) check_range(r, *value, source);
  check_config_relations(config, source);
}

bool has_range(const std::string& key) {
  for (const Range& r : kRanges)
    if (key == r.key) return true;
  return false;
}

void check_config_value(const std::string& key, const json& value, const std::string& source) {
  for (const Range& r : kRanges)
    if (key == r.key) check_range(r, value, source);
}

}  // namespace ddhgs::train
