// `ddhgs report`: a self-contained folder (index.html + assets/) that shows
// how good a trained run is, where and at which wavelengths: metrics, training
// curves, per-band quality, ground truth | render | error pictures and an
// interactive spectral viewer. Opens from disk; needs no server or network.
#pragma once
#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>
#include <vector>

#include "core/tensor.h"
#include "io/scene/scene.h"
#include "model/gaussians.h"

namespace ddhgs::eval {

// What the run folder holds besides the model (read by the caller, so this
// layer needs no knowledge of the run-folder layout).
struct RunRecords {
  std::string name;                         // shown in the title
  nlohmann::json config;                    // resolved training config
  std::vector<nlohmann::json> metrics_log;  // metrics.jsonl, one object per logged iteration
  nlohmann::json train_summary;             // train_summary.json; null when missing
  nlohmann::json eval_metrics;              // eval/metrics.json; null when missing
};

struct ReportOptions {
  std::filesystem::path out_dir;
  // The run and dataset folders: out_dir may neither be nor contain them.
  std::vector<std::filesystem::path> inputs;
  int max_views = 4;  // test views shown as pictures
  // Test views in the spectral viewer. Each carries every band of the render
  // and of the ground truth as 8-bit images, about 2 x N x 192 x 192 bytes
  // before PNG compression (~10 MB for 141 bands), so the default is small.
  int viewer_views = 2;
  int viewer_max_px = 192;  // longer side of the viewer's band images, pixels
  double diff_max = 0.1;    // reflectance error at the top of the heatmap colour map
};

// Renders the test views (the training views when there are none), measures
// them against the stored views and the clean ground truth (when the scene
// has it), and writes the report. The folder is built under a temporary
// sibling and renamed into place (io::write_folder_atomically), replacing an
// earlier report; anything else in out_dir's place is refused. Returns the
// path of index.html.
std::filesystem::path write_report(const io::Scene& scene, const model::Gaussians& gaussians,
                                   const torch::Tensor& background,  // [N]
                                   const RunRecords& records, const ReportOptions& options);

// Reads RUN/metrics.jsonl; a missing file gives no records, a malformed line
// a core::Error naming the file and line.
std::vector<nlohmann::json> read_metrics_log(const std::filesystem::path& path);

}  // namespace ddhgs::eval
