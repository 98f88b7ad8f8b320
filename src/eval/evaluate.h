// Evaluation of a trained model on a scene's views: metrics per view against
// the stored (noisy) views and, when the scene has it, the clean ground
// truth; render speed; metrics.json, per_view.csv and a printed table.
#pragma once
#include "core/tensor.h"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "eval/metrics.h"
#include "eval/pose_alignment.h"
#include "io/scene/scene.h"
#include "model/gaussians.h"

namespace ddhgs::eval {

// The model's render of one view as it is measured (no autograd). band_offsets:
// the wavelength encoder's [N, K+1] while training (a run's PLY has them baked in).
torch::Tensor render_view(const io::Scene& scene, const model::Gaussians& gaussians,
                          const torch::Tensor& background,  // [N]
                          int view, const torch::Tensor& band_offsets = {});

// A masked view's object (io/scene/backdrop.h): the pixels of the truth that
// differ from the backdrop, and their interior (without the one-pixel outline
// where a novel view's silhouette error sits).
struct ObjectMetrics {
  RegionMetrics object;
  std::optional<RegionMetrics> interior;  // none when the object has no interior
  double share = 0;                       // object pixels / all pixels
};

// Object metrics of a render against a masked truth; none when no pixel of
// the truth differs from the backdrop. The render is clamped as measure_view
// clamps it.
std::optional<ObjectMetrics> measure_object(const torch::Tensor& image,      // [H, W, N]
                                            const torch::Tensor& truth,      // [H, W, N]
                                            const torch::Tensor& backdrop);  // [N]

// A view's metrics against the stored view and, when the scene has it, the
// clean ground truth; with a backdrop, its object's against each truth too.
struct ViewMetrics {
  ImageMetrics stored;
  std::optional<ImageMetrics> clean;
  std::optional<ObjectMetrics> stored_object, clean_object;
};

// The one way ddhgs measures an image of a view: eval, the report, the
// denoiser's evaluation and the trainer's held-out check all call it, so
// their numbers agree. The image is clamped to [0, 1], the range of
// reflectance (and of every picture ddhgs writes), before it is compared.
// backdrop ([N], io::masked_backdrop): also measure the object, against the
// same truth tensors; undefined: whole images only.
ViewMetrics measure_view(const io::Scene& scene, int view,
                         const torch::Tensor& image,  // [H, W, N]
                         const torch::Tensor& backdrop = {});

// View indices of "test", "train" or "all"; core::Error for another name.
std::vector<int> split_views(const io::Scene& scene, const std::string& split);

// A view measured from its pose aligned to the stored view (pose_alignment.h).
struct AlignedMetrics {
  ImageMetrics metrics;  // against the stored view
  bool moved = false;    // false: the recorded pose was kept
  double motion_px = 0;  // AlignedView::motion_px
};

struct ViewResult {
  std::string view;   // file stem
  std::string truth;  // "views" (as stored, noisy for synthetic scenes) or "clean"
  ImageMetrics metrics;
  std::optional<ObjectMetrics> object;    // when the scene has a masked backdrop
  std::optional<AlignedMetrics> aligned;  // rows of the stored views, with --align-poses
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
  torch::Tensor backdrop;                    // [N]; undefined: not a masked scene
  std::optional<ObjectMetrics> mean_object;  // over views, against the stored views
  std::optional<ObjectMetrics> mean_object_clean;
  std::optional<AlignOptions> align;         // set when the poses were aligned
  std::optional<ImageMetrics> mean_aligned;  // over views, against the stored views
};

struct EvalOptions {
  int fps_repeats = 5;  // 0: no timing
  // [N]: the scene's views are masked to this backdrop (io::masked_backdrop);
  // the object is then measured on its own too. Undefined: whole images only.
  torch::Tensor backdrop;
  // Also measure each view from its pose aligned to the stored view.
  std::optional<AlignOptions> align;
};

// Renders each view (no autograd) and measures it; with options.align, also
// aligns its pose (autograd through a frozen model, pose_alignment.h) and
// measures it again. FPS is timed on the scene's test views (the given views
// when the scene has none).
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
