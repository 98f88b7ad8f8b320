#include "app/trained_run.h"

#include "app/registry.h"

#include <cmath>

#include "core/error.h"
#include "io/files/atomic_file.h"
#include "io/ply/ply.h"
#include "train/config.h"
#include "train/diffusion_term.h"
#include "train/run_config.h"
#include "train/run_folder.h"

namespace ddhgs::app {
namespace fs = std::filesystem;

namespace {

// data.path as written by `ddhgs train`; a relative path is tried from the
// current folder, then from the run folder.
fs::path dataset_path(const TrainedRun& run, const std::string& data_override) {
  if (!data_override.empty()) {
    core::require(fs::is_directory(data_override), data_override,
                  "no such dataset folder (--data)");
    return data_override;
  }
  const fs::path config_file = train::RunPaths{run.root}.config();
  fs::path p = run.config.data.path;
  core::require(!p.empty(), config_file,
                "data.path is empty: which dataset was this run trained on? (pass --data DIR)");
  if (p.is_relative() && !fs::exists(p) && fs::exists(run.root / p)) p = run.root / p;
  core::require(
      fs::is_directory(p), config_file,
      "data.path '" + p.string() + "' is not a folder (dataset moved or deleted? pass --data DIR)");
  return p;
}

void check_model_matches_scene(const fs::path& ply_path, const io::GaussianPly& ply,
                               const io::Scene& scene) {
  core::require(ply.bands() == scene.bands(), ply_path,
                "the model has " + std::to_string(ply.bands()) + " bands but the dataset " +
                    scene.root.string() + " loads " + std::to_string(scene.bands()));
  if (ply.wavelengths_nm.empty()) return;
  for (size_t b = 0; b < ply.wavelengths_nm.size(); ++b)
    core::require(std::abs(ply.wavelengths_nm[b] - scene.wavelengths_nm[b]) < 1e-3, ply_path,
                  "band " + std::to_string(b) + " is at " + std::to_string(ply.wavelengths_nm[b]) +
                      " nm in the model but " + std::to_string(scene.wavelengths_nm[b]) +
                      " nm in the dataset");
}

torch::Tensor read_learned_background(const fs::path& path, int64_t bands) {
  core::require(fs::exists(path), path,
                "missing: the run learned its background or took it from the views "
                "(model.learn_background, model.background_from_views) but did not finish "
                "writing it");
  auto j = nlohmann::json::parse(io::read_file(path), nullptr, false);
  core::require(j.is_object() && j.contains("background") && j["background"].is_array() &&
                    int64_t(j["background"].size()) == bands,
                path, "expected {\"background\": [" + std::to_string(bands) + " numbers]}");
  std::vector<float> values;
  for (const auto& v : j["background"]) {
    core::require(v.is_number() && std::isfinite(v.get<double>()), path,
                  "background values must be finite numbers");
    values.push_back(v.get<float>());
  }
  return torch::tensor(values);
}

}  // namespace

void add_sampler_flags(CLI::App* cmd, SamplerFlags& flags) {
  flags.start_strength_option =
      cmd->add_option("--start-strength", flags.start_strength,
                      "Start the reverse process from the render noised to this fraction of the "
                      "schedule (1: pure noise; default diffusion.start_strength of the run)")
          ->check(within(1e-9, 1));
  flags.eta_option =
      cmd->add_option("--eta", flags.eta, "DDIM eta (0: deterministic; default diffusion.eta)")
          ->check(within(0, 1));
  flags.samples_option =
      cmd->add_option("--samples", flags.samples,
                      "Average this many denoised samples (seeds seed, seed+1, ...): the "
                      "posterior mean, which PSNR rewards (default diffusion.sampler_samples)")
          ->check(within(1, 1000));
}

model::SamplerOptions sampler_options(const TrainedRun& run, const SamplerFlags& flags) {
  model::SamplerOptions sampler = run.sampler;
  if (flags.start_strength_option->count() > 0) sampler.start_strength = flags.start_strength;
  if (flags.eta_option->count() > 0) sampler.eta = flags.eta;
  if (flags.samples_option->count() > 0) sampler.samples = flags.samples;
  return sampler;
}

RunModel open_run_model(const fs::path& run_dir) {
  core::require(fs::is_directory(run_dir), run_dir,
                "not a folder (expected a run folder written by ddhgs train)");
  RunModel run;
  run.root = run_dir;
  train::RunPaths paths{run_dir};
  run.config = train::parse_run_config(train::read_run_config(paths), paths.config().string());
  core::require(fs::exists(paths.gaussians()), paths.gaussians(),
                "missing: the run has no final model (did training finish?)");
  run.ply = io::read_gaussian_ply(paths.gaussians());
  run.background = train::background(run.config.model, run.ply.bands());
  const train::ModelConfig& model = run.config.model;
  if (model.learn_background || model.background_from_views)
    run.background = read_learned_background(paths.learned_background(), run.ply.bands());
  return run;
}

TrainedRun open_trained_run(const fs::path& run_dir, const std::string& data_override) {
  RunModel model = open_run_model(run_dir);
  TrainedRun run;
  run.root = run_dir;
  run.config = std::move(model.config);
  train::RunPaths paths{run_dir};
  fs::path data = dataset_path(run, data_override);
  run.scene = io::load_scene(data, run.config.data.load);
  io::log_scene_messages(*run.scene);
  check_model_matches_scene(paths.gaussians(), model.ply, *run.scene);
  if (fs::exists(paths.rig_corrections())) {
    // The band cameras as training corrected them (camera_refinement.rig).
    const auto corrections = io::read_rig_corrections(paths.rig_corrections());
    core::require(run.scene->rig.has_value(), paths.rig_corrections(),
                  "corrects rig cameras, but " + data.string() + " is not a rig scene");
    for (io::View& v : run.scene->views)
      if (const auto it = corrections.find(v.rig_camera); it != corrections.end())
        v.camera =
            io::corrected_band_camera(v.camera, run.scene->rig->turn(v.rig_camera), it->second);
  }
  // The georeference the run was trained with, over the scene's (which may
  // have been processed again since).
  if (fs::exists(paths.georef())) run.scene->georef = io::read_georeference(paths.georef());
  run.gaussians = model::from_ply(model.ply);
  run.background = model.background;
  const fs::path denoiser = train::denoiser_path(paths);
  if (fs::exists(denoiser)) {
    run.denoiser = train::read_denoiser(denoiser);
    core::require(run.denoiser->bands() == run.scene->bands(), denoiser,
                  "the denoiser has " + std::to_string(run.denoiser->bands()) +
                      " bands but the dataset loads " + std::to_string(run.scene->bands()));
    run.sampler = run.config.diffusion.sampler;
  }
  return run;
}

}  // namespace ddhgs::app
