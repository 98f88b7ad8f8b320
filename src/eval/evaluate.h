// Evaluation of a trained model on a scene's views: metrics per view against
// the stored (noisy) views and, when the scene has it, the clean ground
// truth; render speed; metrics.json, per_view.csv and a printed table.
#pragma once
#include <torch/torch.h>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "eval/metrics.h"
#include "io/scene/scene.h"
#include "model/gaussians.h"

namespace ddhgs::eval {

// View indices of "test", "train" or "all"; core::Error for another name.
std::vector<int> split_views(const io::Scene& scene, const std::string& split);

struct ViewResult {
  std::string view;   // file stem
  std::string truth;  // "views" (as stored, noisy for synthetic scenes) or "clean"
  ImageMetrics metrics;
};

struct Timing {
  int repeats = 0;       // timed passes over the views (after one warm-up pass)
  int views = 0;         // views per pass
  double median_ms = 0;  // median over passes of the mean time per frame
  double fps() const { return median_ms > 0 ? 1000.0 / median_ms : 0; }
};

struct EvalReport {
  std::string split;
  std::vector<double> wavelengths_nm;
  int64_t gaussians = 0;
  int width = 0, height = 0;               // pixels, of the first view
  std::vector<ViewResult> per_view;        // in view order, stored before clean
  ImageMetrics mean;                       // over views, against the stored views
  std::optional<ImageMetrics> mean_clean;  // against clean ground truth
  std::optional<Timing> timing;
};

struct EvalOptions {
  int fps_repeats = 5;  // 0: no timing
};

// Renders each view (no autograd) and measures it; FPS is timed on the
// scene's test views (the given views when the scene has none).
EvalReport evaluate(const io::Scene& scene, const model::Gaussians& gaussians,
                    const torch::Tensor& background,  // [N]
                    const std::vector<int>& views, const std::string& split_name,
                    const EvalOptions& options = {});

// Render time only (SH evaluation and rasterisation): one untimed warm-up
// pass over the views, then `repeats` timed passes.
Timing time_renders(const io::Scene& scene, const model::Gaussians& gaussians,
                    const torch::Tensor& background,  // [N]
                    const std::vector<int>& views, int repeats);

// Atomic writers.
void write_metrics_json(const std::filesystem::path& path, const EvalReport& report);
void write_per_view_csv(const std::filesystem::path& path, const EvalReport& report);

// A short human-readable table of the means (and FPS).
std::string format_report(const EvalReport& report);

}  // namespace ddhgs::eval
