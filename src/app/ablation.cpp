#include "app/ablation.h"

#include "core/tensor.h"

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <sstream>

#include "app/trained_run.h"
#include "core/error.h"
#include "core/log.h"
#include "eval/denoised_eval.h"
#include "eval/evaluate.h"
#include "io/files/atomic_file.h"
#include "io/files/folder_lock.h"
#include "io/files/output_folder.h"
#include "io/files/output_marker.h"
#include "train/config.h"
#include "train/run_config.h"
#include "train/trainer.h"

namespace ddhgs::app {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

json metrics_entry(const eval::ImageMetrics& m) {
  return {{"psnr", m.psnr_db}, {"ssim", m.ssim}, {"sam", m.sam_rad}, {"rmse", m.rmse}};
}

std::string utc_now() {
  const std::time_t now = std::time(nullptr);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M UTC", std::gmtime(&now));
  return buf;
}

// A row without the denoiser never reads the "diffusion" section, so changing
// the denoiser's settings (or adding keys to that section) keeps those rows;
// the sampler's keys only matter at evaluation, which uses the ablation's.
json training_inputs(json config) {
  if (config.at("loss").at("diffusion").get<double>() == 0) {
    config.erase("diffusion");
  } else {
    for (const std::string& key : train::sampler_keys()) config["diffusion"].erase(key);
  }
  return config;
}

bool same_config(const train::RunPaths& paths, const json& config) {
  if (!fs::exists(paths.config())) return false;
  try {
    return training_inputs(train::read_run_config(paths)) == training_inputs(config);
  } catch (const core::Error&) {
    return false;
  }
}

// The config without the denoiser's fine-tuning keys, which act only after
// the Gaussian iterations.
json without_finetuning(json config) {
  if (config.contains("diffusion"))
    for (const std::string& key : train::finetune_keys()) config["diffusion"].erase(key);
  return config;
}

// When DIR/<row> was trained with the same config up to the denoiser's
// fine-tuning, rewinds it to its checkpoint at the end of the Gaussian
// iterations under the new config, so only the fine-tuning runs again.
bool rewind_to_finetuning(const train::RunPaths& paths, const json& config) {
  if (config.at("loss").at("diffusion").get<double>() == 0 || !fs::exists(paths.config()))
    return false;
  const fs::path at_end = paths.checkpoint_at(config.at("iterations").get<int64_t>());
  try {
    if (!fs::exists(at_end) || training_inputs(without_finetuning(train::read_run_config(paths))) !=
                                   training_inputs(without_finetuning(config)))
      return false;
  } catch (const core::Error&) {
    return false;
  }
  core::log_info("  " + paths.root.string() +
                 " differs only in the denoiser's fine-tuning; continuing from " + at_end.string());
  train::rewind_to_gaussian_end(paths, config.at("iterations").get<int64_t>(), config);
  return true;
}

// Trains the row unless DIR/<row> already holds it finished; continues it
// from its checkpoint when an earlier ablation was interrupted, or from the
// end of its Gaussian iterations when only the fine-tuning changed. False
// when this training is interrupted (Ctrl-C).
bool train_row(const train::RunPaths& paths, const json& config, bool force) {
  bool ours = same_config(paths, config);
  if (ours && fs::exists(paths.summary()) && fs::exists(paths.gaussians())) {
    core::log_info("  " + paths.root.string() + " is already trained with this config; reusing it");
    // Keys that do not change training (the sampler's) take the new values,
    // so `ddhgs eval` on the row later agrees with the table.
    if (train::read_run_config(paths) != config)
      io::write_file_atomically(paths.config(), config.dump(2) + "\n");
    return true;
  }
  if (!ours) ours = rewind_to_finetuning(paths, config);
  auto trainer = ours && fs::exists(paths.checkpoint())
                     ? train::Trainer::resume(paths)
                     : train::Trainer::start(config, paths, force || ours);
  return trainer->run() == train::TrainStatus::Finished;
}

// The row's table entries: the raw render, then one per denoiser setting.
json evaluate_row(const AblationOptions& options, const AblationRow& row,
                  const train::RunPaths& paths) {
  TrainedRun run = open_trained_run(paths.root);
  const std::vector<int> views = eval::split_views(*run.scene, "test");
  eval::EvalOptions eval_options;
  eval_options.fps_repeats = options.fps_repeats;
  eval::EvalReport report =
      eval::evaluate(*run.scene, run.gaussians, run.background, views, "test", eval_options);
  const io::OutputRequest eval_folder{
      paths.root / "eval", io::OutputKind::Eval, true, {paths.root, run.scene->root}, ""};
  io::write_into_folder_atomically(eval_folder, [&](const fs::path& tmp) {
    eval::write_metrics_json(tmp / "metrics.json", report);
    eval::write_per_view_csv(tmp / "per_view.csv", report);
  });

  const json summary = json::parse(io::read_file(paths.summary()));
  // The Gaussian iterations only (the denoiser's fine-tuning after them is
  // reported apart).
  const double iterations_per_second = summary.value("iterations_per_second", 0.0);
  const double seconds_per_iteration =
      iterations_per_second > 0
          ? 1.0 / iterations_per_second
          : summary.at("seconds").get<double>() / std::max<double>(1, summary.at("iterations"));
  json base = {{"row", row.name},
               {"spectral_loss", row.spectral_loss},
               {"wavelength_encoder", row.wavelength_encoder},
               {"diffusion", row.diffusion},
               {"seconds_per_iteration", seconds_per_iteration},
               {"gaussians", report.gaussians}};
  if (summary.contains("denoiser_finetune_seconds")) {
    base["denoiser_finetune_steps"] = summary.at("denoiser_finetune_steps");
    base["denoiser_finetune_seconds"] = summary.at("denoiser_finetune_seconds");
  }
  json entries = json::array();
  json raw = base;
  raw["output"] = "render";
  raw["views"] = metrics_entry(report.mean);
  if (report.mean_clean) raw["clean"] = metrics_entry(*report.mean_clean);
  if (report.timing) raw["fps"] = report.timing->fps();
  entries.push_back(raw);
  if (!run.denoiser) return entries;

  model::SamplerOptions sampler = run.sampler;
  if (options.start_strength > 0) sampler.start_strength = options.start_strength;
  if (options.samples > 0) sampler.samples = options.samples;
  auto settings = eval::denoise_settings(options.denoise_steps, false, sampler);
  eval::DenoisedReport denoised = eval::evaluate_denoised(*run.scene, run.gaussians, run.background,
                                                          *run.denoiser, views, "test", settings);
  io::write_into_folder_atomically(eval_folder, [&](const fs::path& tmp) {
    eval::write_denoised_json(tmp / "denoised.json", denoised);
    eval::write_denoised_csv(tmp / "per_view_denoised.csv", denoised);
  });
  for (const eval::DenoisedResult& r : denoised.results) {
    json entry = base;
    entry["output"] = r.setting.name;
    entry["start_strength"] = r.setting.sampler.start_strength;
    entry["views"] = metrics_entry(r.mean);
    if (r.mean_clean) entry["clean"] = metrics_entry(*r.mean_clean);
    entry["fps"] = denoised.fps(r);
    entries.push_back(entry);
  }
  return entries;
}

std::string cell(const json& entry, const char* truth, const char* key, int decimals) {
  if (!entry.contains(truth)) return "-";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, entry.at(truth).at(key).get<double>());
  return buf;
}

std::string output_label(const json& entry) {
  const std::string output = entry.at("output");
  if (output == "render") return "render";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%s, s=%g", output.c_str(),
                entry.at("start_strength").get<double>());
  return buf;
}

}  // namespace

const std::vector<AblationRow>& ablation_rows() {
  static const std::vector<AblationRow> rows = {{"3dgs", false, false, false},
                                                {"sl", true, false, false},
                                                {"we", false, true, false},
                                                {"we+sl", true, true, false},
                                                {"diffusion", false, false, true},
                                                {"full", true, true, true},
                                                {"subspace", false, false, false, -1},
                                                {"folds", false, false, true, 0, true},
                                                {"distilled", false, false, true, 0, true, true}};
  return rows;
}

std::vector<AblationRow> select_rows(const std::vector<std::string>& names,
                                     const std::string& where) {
  std::vector<AblationRow> selected;
  for (const std::string& name : names) {
    auto it = std::find_if(ablation_rows().begin(), ablation_rows().end(),
                           [&](const AblationRow& r) { return r.name == name; });
    core::require(it != ablation_rows().end(),
                  where + ": unknown row '" + name +
                      "' (rows: 3dgs, sl, we, we+sl, diffusion, full, subspace, folds, distilled)");
    for (const AblationRow& r : selected)
      core::require(r.name != name, where + ": row '" + name + "' is listed twice");
    selected.push_back(*it);
  }
  core::require(!selected.empty(), where + ": no rows selected");
  return selected;
}

json row_config(const AblationOptions& options, const AblationRow& row) {
  json config = train::load_preset(options.preset);
  for (const std::string& assignment : options.assignments)
    train::apply_assignment(config, assignment);
  const std::string source = "ablation row '" + row.name + "'";
  auto weight = [](bool on, double w) { return on ? json(w).dump() : std::string("0"); };
  train::set_key(config, "loss.spectral", weight(row.spectral_loss, options.spectral_weight),
                 source);
  train::set_key(config, "wavelength_encoder.enabled", row.wavelength_encoder ? "true" : "false",
                 source);
  train::set_key(config, "loss.diffusion", weight(row.diffusion, options.diffusion_weight), source);
  train::set_key(config, "model.spectral_rank", std::to_string(row.spectral_rank), source);
  // The subspace row is a subspace at any band count; the paper's rows are per band.
  train::set_key(config, "model.subspace_from_bands", "0", source);
  if (row.fold_pairs) {
    train::set_key(config, "diffusion.joint", "false", source);
    train::set_key(config, "diffusion.pairs", "folds", source);
  }
  if (row.distill)
    train::set_key(config, "diffusion.distill_steps",
                   std::to_string(std::max<int64_t>(1, config.at("iterations").get<int64_t>() / 4)),
                   source);
  std::error_code ec;
  config["data"]["path"] = fs::absolute(options.data, ec).lexically_normal().string();
  train::validate_config(config, source);
  return config;
}

// Every row is judged on the held-out views: without them the table would
// be empty after hours of training.
void require_test_views(const json& config) {
  const train::DataConfig data = train::parse_run_config(config, "ablation").data;
  if (io::load_scene(data.path, data.load)->test.empty())
    throw core::Error(data.path,
                      "has no held-out views, and an ablation compares test metrics "
                      "(a scene needs 10 or more views, or test_filenames)");
}

json run_ablation(const AblationOptions& options) {
  core::require(fs::is_directory(options.data), options.data, "no such dataset folder");
  std::vector<json> configs;
  for (const AblationRow& row : options.rows) configs.push_back(row_config(options, row));
  require_test_views(configs.front());
  // Rows are trained into an earlier ablation folder (reused or continued),
  // never into a folder ddhgs did not make.
  io::OutputRequest request{options.out, io::OutputKind::Ablation, true, {options.data}, ""};
  request.merge = true;  // rows are added to it, nothing is deleted
  if (io::check_output_folder(request) != io::OutputState::Ours) {
    fs::create_directories(options.out);
    // Its rows are runs with markers of their own.
    io::write_output_marker(
        options.out, {io::OutputKind::Ablation, false, true, {"ablation.json", "ablation.md"}});
  }
  io::FolderLock lock(options.out, "ablate");

  json entries = json::array();
  for (size_t i = 0; i < options.rows.size(); ++i) {
    const AblationRow& row = options.rows[i];
    const train::RunPaths paths{options.out / row.name};
    core::log_info("ablation row " + std::to_string(i + 1) + "/" +
                   std::to_string(options.rows.size()) + " '" + row.name + "' in " +
                   paths.root.string());
    if (!train_row(paths, configs[i], options.force)) return json();
    for (json& entry : evaluate_row(options, row, paths)) entries.push_back(std::move(entry));
  }

  const json& first = configs.front();
  json ablation = {{"data", first.at("data").at("path")},
                   {"preset", options.preset},
                   {"assignments", options.assignments},
                   {"iterations", first.at("iterations")},
                   {"seed", first.at("seed")},
                   {"threads", torch::get_num_threads()},
                   {"spectral_weight", options.spectral_weight},
                   {"diffusion_weight", options.diffusion_weight},
                   {"written", utc_now()},
                   {"rows", entries}};
  io::write_file_atomically(options.out / "ablation.json", ablation.dump(2) + "\n");
  io::write_file_atomically(options.out / "ablation.md", ablation_markdown(ablation));
  return ablation;
}

std::string ablation_markdown(const json& ablation) {
  std::ostringstream md;
  md << "# DD-HGS ablation\n\n"
     << "Data `" << ablation.at("data").get<std::string>() << "`, preset `"
     << ablation.at("preset").get<std::string>() << "`";
  for (const auto& a : ablation.at("assignments")) md << " `--set " << a.get<std::string>() << "`";
  md << ", " << ablation.at("iterations").get<int64_t>() << " iterations, seed "
     << ablation.at("seed").get<int64_t>() << ", " << ablation.at("threads").get<int>()
     << " threads; spectral loss weight " << ablation.at("spectral_weight").get<double>()
     << ", diffusion weight " << ablation.at("diffusion_weight").get<double>() << "; written "
     << ablation.at("written").get<std::string>() << ".\n\n"
     << "Test views; \"clean\" is the noise-free ground truth (synthetic scenes only), "
        "\"captured\" the stored noisy views. SAM in radians. FPS: render only for `render`, "
        "render + reverse diffusion for the denoised outputs.\n\n"
     << "| row | output | PSNR dB clean | SSIM clean | SAM clean | RMSE clean | PSNR dB captured "
        "| SSIM captured | SAM captured | RMSE captured | s / iter | FPS |\n"
     << "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n";
  for (const json& e : ablation.at("rows")) {
    char tail[64];
    std::snprintf(tail, sizeof tail, "| %.3f | %.2f |", e.at("seconds_per_iteration").get<double>(),
                  e.value("fps", 0.0));
    md << "| " << e.at("row").get<std::string>() << " | " << output_label(e) << " | "
       << cell(e, "clean", "psnr", 2) << " | " << cell(e, "clean", "ssim", 4) << " | "
       << cell(e, "clean", "sam", 4) << " | " << cell(e, "clean", "rmse", 4) << " | "
       << cell(e, "views", "psnr", 2) << " | " << cell(e, "views", "ssim", 4) << " | "
       << cell(e, "views", "sam", 4) << " | " << cell(e, "views", "rmse", 4) << " " << tail << "\n";
  }
  // s / iter counts the Gaussian iterations; the denoiser-only steps after
  // them are listed here, once per row.
  std::string last;
  for (const json& e : ablation.at("rows")) {
    if (!e.contains("denoiser_finetune_seconds") || e.at("row") == last) continue;
    last = e.at("row").get<std::string>();
    char line[160];
    std::snprintf(line, sizeof line,
                  "\nRow %s: %lld denoiser fine-tuning steps after training, %.0f s.\n",
                  last.c_str(), (long long)e.at("denoiser_finetune_steps").get<int64_t>(),
                  e.at("denoiser_finetune_seconds").get<double>());
    md << line;
  }
  return md.str();
}

}  // namespace ddhgs::app
