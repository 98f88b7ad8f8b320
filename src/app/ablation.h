// The DD-HGS ablation (paper Table 3) on one scene: the same preset, seed and
// iterations trained once per row with components switched on and off, each
// row evaluated on the test views (raw render, and denoised for rows with the
// diffusion term), and the table written as Markdown and JSON. The work
// behind `ddhgs ablate`.
#pragma once
#include <nlohmann/json.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace ddhgs::app {

// What one row switches on; everything else comes from the preset.
struct AblationRow {
  std::string name;  // "3dgs", "sl", "we", "we+sl", "diffusion", "full", "subspace"
  bool spectral_loss = false;
  bool wavelength_encoder = false;
  bool diffusion = false;
  int spectral_rank = 0;  // model.spectral_rank (-1: the scene's signal rank)
  // Novel-view pairs: the denoiser learns from auxiliary models' renders of
  // views they never saw (diffusion.pairs=folds, no joint term), and with
  // `distill` a quarter of the iterations more distil it into the Gaussians.
  bool fold_pairs = false;
  bool distill = false;
};

// The six rows of the paper's Table 3, in its order, then ddhgs's own:
// "subspace", the 3dgs row with a spectral-subspace colour model; "folds",
// the 3dgs row with a denoiser trained on novel-view pairs; "distilled",
// that row with the denoiser distilled back into the Gaussians.
const std::vector<AblationRow>& ablation_rows();
// Rows by name, in the given order; core::Error naming `where` for an
// unknown or repeated name.
std::vector<AblationRow> select_rows(const std::vector<std::string>& names,
                                     const std::string& where);

struct AblationOptions {
  std::filesystem::path data, out;
  std::string preset = "ablation";
  std::vector<std::string> assignments;  // --set key=value, before the row switches
  std::vector<AblationRow> rows;
  double spectral_weight = 0.1;   // loss.spectral of rows with SL (paper w3)
  double diffusion_weight = 0.3;  // loss.diffusion of rows with the denoiser (paper w4)
  std::vector<int64_t> denoise_steps = {1, 10};  // DDIM K evaluated for denoiser rows
  // Sampler start strength for denoiser rows; 0: the preset's
  // diffusion.start_strength. An evaluation setting, so finished rows are reused.
  double start_strength = 0;
  // Samples averaged per denoised view (0: the preset's diffusion.sampler_samples).
  int64_t samples = 0;
  int fps_repeats = 3;
  bool force = false;  // retrain rows whose folder holds another configuration
};

// The resolved config of one row: preset, then assignments, then the row's
// switches (loss.spectral, wavelength_encoder.enabled, loss.diffusion,
// model.spectral_rank; model.subspace_from_bands 0, so that a row's
// colour model does not depend on the scene's band count).
nlohmann::json row_config(const AblationOptions& options, const AblationRow& row);

// Trains (or resumes, or reuses when DIR/<row> already holds a finished run
// of the same config) and evaluates every row, then writes DIR/ablation.json
// and DIR/ablation.md. Returns the JSON, or null when training was
// interrupted (Ctrl-C: the row's checkpoint is saved; the same command resumes).
nlohmann::json run_ablation(const AblationOptions& options);

// The Markdown table of an ablation.json.
std::string ablation_markdown(const nlohmann::json& ablation);

}  // namespace ddhgs::app
