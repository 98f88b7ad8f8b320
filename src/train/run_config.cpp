#include "train/run_config.h"

#include "core/error.h"
#include "train/config.h"

namespace ddhgs::train {

using nlohmann::json;

namespace {

// Reads section.key; validate_config has checked types against the schema,
// so a failure here means a key the schema lacks (a programming error named
// for the user all the same).
template <typename T>
T read(const json& section, const char* section_name, const char* key, const std::string& source) {
  try {
    return section.at(key).get<T>();
  } catch (const json::exception&) {
    throw core::Error(source,
                      std::string(section_name) + "." + key + " is missing or has the wrong type");
  }
}

DataConfig parse_data(const json& d, const std::string& source) {
  DataConfig c;
  c.path = read<std::string>(d, "data", "path", source);
  io::LoadOptions& o = c.load;
  o.downscale = read<int>(d, "data", "downscale", source);
  o.rgb = read<bool>(d, "data", "rgb", source);
  o.band_min_nm = read<double>(d, "data", "band_min_nm", source);
  o.band_max_nm = read<double>(d, "data", "band_max_nm", source);
  o.bin = read<int>(d, "data", "bin", source);
  o.band_step = read<int>(d, "data", "band_step", source);
  o.cache_mb = read<size_t>(d, "data", "cache_mb", source);
  c.block_as_flight = read<bool>(d, "data", "block_as_flight", source);
  return c;  // ranges and the band range: validate_config (config_values.cpp)
}

ExposureMode parse_exposure_mode(const std::string& text, const std::string& source) {
  if (text == "auto") return ExposureMode::Auto;
  if (text == "on") return ExposureMode::On;
  if (text == "off") return ExposureMode::Off;
  throw core::Error(source,
                    "key 'model.exposure_correction' is '" + text + "', expected auto, on or off");
}

ModelConfig parse_model(const json& m, const std::string& source) {
  ModelConfig c;
  c.sh_degree = read<int>(m, "model", "sh_degree", source);
  c.spectral_rank = read<int>(m, "model", "spectral_rank", source);
  c.subspace_from_bands = read<int>(m, "model", "subspace_from_bands", source);
  c.sh_degree_every_fraction = read<double>(m, "model", "sh_degree_every_fraction", source);
  const json& b = m.at("background");
  c.background_per_band = !b.is_number();
  c.background = c.background_per_band ? read<std::vector<float>>(m, "model", "background", source)
                                       : std::vector<float>{b.get<float>()};
  c.background_from_views = read<bool>(m, "model", "background_from_views", source);
  c.learn_background = read<bool>(m, "model", "learn_background", source);
  c.exposure_correction =
      parse_exposure_mode(read<std::string>(m, "model", "exposure_correction", source), source);
  return c;
}

InitOptions parse_init(const json& i, int sh_degree, uint64_t seed, const std::string& source) {
  InitOptions o;
  o.random = read<bool>(i, "init", "random", source);
  o.random_points = read<int64_t>(i, "init", "random_points", source);
  o.extra_random_per_pixel = read<double>(i, "init", "extra_random_per_pixel", source);
  o.opacity = read<double>(i, "init", "opacity", source);
  o.neighbours = read<int>(i, "init", "neighbours", source);
  o.colour_views = read<int>(i, "init", "colour_views", source);
  o.sh_degree = sh_degree;
  o.seed = seed;
  return o;
}

OptimConfig parse_optim(const json& o, const std::string& source) {
  OptimConfig c;
  c.means_lr_init = read<double>(o, "optim", "means_lr_init", source);
  c.means_lr_final = read<double>(o, "optim", "means_lr_final", source);
  c.means_lr_decay_fraction = read<double>(o, "optim", "means_lr_decay_fraction", source);
  c.sh_dc_lr = read<double>(o, "optim", "sh_dc_lr", source);
  c.sh_rest_lr_divisor = read<double>(o, "optim", "sh_rest_lr_divisor", source);
  c.opacity_lr = read<double>(o, "optim", "opacity_lr", source);
  c.scaling_lr = read<double>(o, "optim", "scaling_lr", source);
  c.rotation_lr = read<double>(o, "optim", "rotation_lr", source);
  c.adam_eps = read<double>(o, "optim", "adam_eps", source);
  c.background_lr = read<double>(o, "optim", "background_lr", source);
  c.basis_lr = read<double>(o, "optim", "basis_lr", source);
  c.latent_sh_lr_scale = read<double>(o, "optim", "latent_sh_lr_scale", source);
  c.lr_decay_from_fraction = read<double>(o, "optim", "lr_decay_from_fraction", source);
  c.lr_final_scale = read<double>(o, "optim", "lr_final_scale", source);
  c.exposure_lr = read<double>(o, "optim", "exposure_lr", source);
  c.iterations_per_band_view = read<int64_t>(o, "optim", "iterations_per_band_view", source);
  return c;
}

LossConfig parse_loss(const json& l, const std::string& source) {
  LossConfig c;
  c.l1 = read<double>(l, "loss", "l1", source);
  c.dssim = read<double>(l, "loss", "dssim", source);
  c.spectral = read<double>(l, "loss", "spectral", source);
  c.spectral_options.alpha = read<double>(l, "loss", "spectral_alpha", source);
  c.spectral_options.beta = read<double>(l, "loss", "spectral_beta", source);
  c.spectral_options.temperature = read<double>(l, "loss", "spectral_temperature", source);
  c.bands_per_step = read<int>(l, "loss", "bands_per_step", source);
  c.bands_per_step_until_fraction =
      read<double>(l, "loss", "bands_per_step_until_fraction", source);
  c.view_fraction = read<double>(l, "loss", "view_fraction", source);
  c.view_fraction_until_fraction = read<double>(l, "loss", "view_fraction_until_fraction", source);
  c.view_fraction_from_pixels = read<int64_t>(l, "loss", "view_fraction_from_pixels", source);
  c.exposure_prior = read<double>(l, "loss", "exposure_prior", source);
  return c;
}

WavelengthEncoderConfig parse_encoder(const json& w, int sh_degree, const std::string& source) {
  const char* s = "wavelength_encoder";
  WavelengthEncoderConfig c;
  c.enabled = read<bool>(w, s, "enabled", source);
  c.network.frequencies = read<int>(w, s, "frequencies", source);
  c.network.include_input = read<bool>(w, s, "include_input", source);
  c.network.hidden = read<int>(w, s, "hidden", source);
  c.network.layers = read<int>(w, s, "layers", source);
  c.network.output_scale = read<double>(w, s, "output_scale", source);
  c.network.sh_coeffs = (sh_degree + 1) * (sh_degree + 1);
  c.lr = read<double>(w, s, "lr", source);
  return c;
}

CameraRefinementConfig parse_cameras(const json& c, const std::string& source) {
  const char* s = "camera_refinement";
  CameraRefinementConfig o;
  o.enabled = read<bool>(c, s, "enabled", source);
  o.rotation_lr = read<double>(c, s, "rotation_lr", source);
  o.translation_lr = read<double>(c, s, "translation_lr", source);
  o.rig = read<bool>(c, s, "rig", source);
  o.rig_rotation_lr = read<double>(c, s, "rig_rotation_lr", source);
  o.rig_offset_lr = read<double>(c, s, "rig_offset_lr", source);
  o.rig_pull = read<double>(c, s, "rig_pull", source);
  o.rig_warmup_fraction = read<double>(c, s, "rig_warmup_fraction", source);
  o.rig_align_fraction = read<double>(c, s, "rig_align_fraction", source);
  o.rig_pivot = read<bool>(c, s, "rig_pivot", source);
  o.rig_start = read<std::string>(c, s, "rig_start", source);
  return o;
}

DiffusionTermOptions parse_diffusion(const json& d, double weight, uint64_t seed,
                                     const std::string& source) {
  const char* s = "diffusion";
  DiffusionTermOptions o;
  o.weight = weight;
  o.warmup = read<int64_t>(d, s, "warmup", source);
  o.crop_px = read<int64_t>(d, s, "crop", source);
  o.lr = read<double>(d, s, "lr", source);
  o.condition_grad = read<bool>(d, s, "condition_grad", source);
  o.condition_noise = read<double>(d, s, "condition_noise", source);
  o.prediction = model::parse_prediction(read<std::string>(d, s, "prediction", source),
                                         source + ": diffusion");
  o.min_snr_gamma = read<double>(d, s, "min_snr_gamma", source);
  o.finetune_steps = read<int64_t>(d, s, "finetune_steps", source);
  o.finetune_batch = read<int64_t>(d, s, "finetune_batch", source);
  o.finetune_crop = read<int64_t>(d, s, "finetune_crop", source);
  o.finetune_cache_mb = read<int64_t>(d, s, "finetune_cache_mb", source);
  o.unet = model::unet_options_from_json(d, source + ": diffusion");
  o.unet.bands = 0;  // with_bands
  o.schedule_steps = read<int64_t>(d, s, "steps", source);
  o.schedule = model::parse_beta_schedule(read<std::string>(d, s, "schedule", source),
                                          source + ": diffusion");
  o.beta_start = read<double>(d, s, "beta_start", source);
  o.beta_end = read<double>(d, s, "beta_end", source);
  o.sampler.steps = read<int64_t>(d, s, "sampler_steps", source);
  o.sampler.start_strength = read<double>(d, s, "start_strength", source);
  o.sampler.eta = read<double>(d, s, "eta", source);
  o.sampler.samples = read<int64_t>(d, s, "sampler_samples", source);
  o.sampler.seed = seed;
  o.joint = read<bool>(d, s, "joint", source);
  o.pairs = parse_finetune_pairs(read<std::string>(d, s, "pairs", source), source + ": diffusion");
  o.folds = read<int64_t>(d, s, "folds", source);
  o.fold_iterations = read<double>(d, s, "fold_iterations", source);
  o.perturb_px = read<double>(d, s, "perturb_px", source);
  o.distill_steps = read<int64_t>(d, s, "distill_steps", source);
  o.distill_weight = read<double>(d, s, "distill_weight", source);
  o.distill_every = read<int64_t>(d, s, "distill_every", source);
  o.validation_every = read<int64_t>(d, s, "validation_every", source);
  o.prior = read<std::string>(d, s, "prior", source);
  o.prior_finetune_steps = read<int64_t>(d, s, "prior_finetune_steps", source);
  // Each key's range was checked by validate_config (config_values.cpp); what
  // is left is the sampler against the schedule it samples.
  o.sampler.validate(o.schedule_steps, source + ": diffusion");
  return o;
}

DensifyConfig parse_densify(const json& d, const std::string& source) {
  const char* s = "densify";
  DensifyConfig c;
  c.from_fraction = read<double>(d, s, "from_fraction", source);
  c.until_fraction = read<double>(d, s, "until_fraction", source);
  c.every = read<int64_t>(d, s, "every", source);
  c.opacity_reset_every_fraction = read<double>(d, s, "opacity_reset_every_fraction", source);
  model::DensifyOptions& t = c.thresholds;
  t.grad_threshold = read<double>(d, s, "grad_threshold", source);
  t.percent_dense = read<double>(d, s, "percent_dense", source);
  t.min_opacity = read<double>(d, s, "min_opacity", source);
  t.max_screen_px = read<double>(d, s, "max_screen_px", source);
  t.max_world_fraction = read<double>(d, s, "max_world_fraction", source);
  t.max_gaussians = read<int64_t>(d, s, "max_gaussians", source);
  return c;
}

OutputConfig parse_output(const json& o, const std::string& source) {
  OutputConfig c;
  c.log_every = read<int64_t>(o, "output", "log_every", source);
  c.checkpoint_every = read<int64_t>(o, "output", "checkpoint_every", source);
  c.test_every = read<int64_t>(o, "output", "test_every", source);
  return c;
}

}  // namespace

RunConfig parse_run_config(const json& config, const std::string& source) {
  validate_config(config, source);
  RunConfig c;
  c.resolved = config;
  c.seed = config.at("seed").get<uint64_t>();
  c.iterations = config.at("iterations").get<int64_t>();
  c.data = parse_data(config.at("data"), source);
  c.model = parse_model(config.at("model"), source);
  c.init = parse_init(config.at("init"), c.model.sh_degree, c.seed, source);
  c.optim = parse_optim(config.at("optim"), source);
  c.loss = parse_loss(config.at("loss"), source);
  c.wavelength_encoder = parse_encoder(config.at("wavelength_encoder"), c.model.sh_degree, source);
  c.camera_refinement = parse_cameras(config.at("camera_refinement"), source);
  c.diffusion =
      parse_diffusion(config.at("diffusion"),
                      read<double>(config.at("loss"), "loss", "diffusion", source), c.seed, source);
  c.densify = parse_densify(config.at("densify"), source);
  c.output = parse_output(config.at("output"), source);
  return c;
}

DiffusionTermOptions with_bands(DiffusionTermOptions options, int64_t bands) {
  options.unet.bands = bands;
  return options;
}

torch::Tensor background(const ModelConfig& model, int64_t bands) {
  if (!model.background_per_band) return torch::full({bands}, model.background[0]);
  if (int64_t(model.background.size()) != bands)
    throw core::Error("config: model.background has " + std::to_string(model.background.size()) +
                      " values but the scene has " + std::to_string(bands) + " bands");
  return torch::tensor(model.background);
}

const std::vector<std::string>& sampler_keys() {
  static const std::vector<std::string> keys = {"sampler_steps", "start_strength", "eta",
                                                "sampler_samples"};
  return keys;
}

const std::vector<std::string>& finetune_keys() {
  static const std::vector<std::string> keys = {
      "finetune_steps", "finetune_batch", "finetune_crop",   "finetune_cache_mb",
      "pairs",          "folds",          "fold_iterations", "validation_every",
      "distill_steps",  "distill_weight", "distill_every",   "perturb_px"};
  return keys;
}

}  // namespace ddhgs::train
