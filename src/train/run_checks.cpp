#include "train/run_checks.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/log.h"
#include "core/parallel.h"
#include "io/scene/scene_report.h"

namespace ddhgs::train {

namespace fs = std::filesystem;

namespace {

std::string diverged(int64_t iteration, const std::string& what) {
  return "training diverged at iteration " + std::to_string(iteration) + ": " + what +
         " (learning rates too high?); nothing of this iteration was saved";
}

// Far beyond any reflectance or radiance in [0, 1]: a wrong scale or garbage
// (a cube of 3e38 made every Gaussian NaN).
constexpr double kMaxPlausibleValue = 1e3;

// Samples only a full read checks: float cubes (NaN, absurd values) and
// compressed files (a corrupt strip or scan is found only by decoding it).
bool needs_full_read(const fs::path& path, const io::Scene& scene) {
  const io::CubeInfo info = io::probe_cube(path, io::CubeReadOptions{scene.options.layout});
  const io::SampleType type = info.type;
  return info.compressed || type == io::SampleType::F16 || type == io::SampleType::F32 ||
         type == io::SampleType::F64;
}

void require_plausible(const torch::Tensor& image, const fs::path& path, double scale) {
  const double top = image.abs().max().item<double>();
  // Dark-subtracted radiance dips a little below 0; a cube more negative than
  // it is positive (or than -1) is a sign error or garbage.
  const double lowest = image.min().item<double>(), highest = image.max().item<double>();
  if (-lowest > std::max(highest, 1.0)) {
    char text[200];
    std::snprintf(text, sizeof text,
                  "samples reach %.3g after dividing by the scale %g, more negative than the "
                  "largest sample (%.3g) is positive; ddhgs expects radiance or reflectance",
                  lowest, scale, highest);
    throw core::Error(path, text);
  }
  if (top > kMaxPlausibleValue) {
    char text[160];
    std::snprintf(text, sizeof text,
                  "samples reach %.3g after dividing by the scale %g; ddhgs expects values "
                  "near 0-1 (a wrong \"scale\" in transforms.json?)",
                  top, scale);
    throw core::Error(path, text);
  }
}

bool finite(const torch::Tensor& t) {
  return !t.defined() || torch::isfinite(t).all().item<bool>();
}

}  // namespace

void check_scene_before_training(const io::Scene& scene) {
  // Headers of every file: cheap, and the whole list of problems at once.
  const io::SceneReport report = io::inspect_scene(scene, 0);
  if (!report.errors.empty())
    throw core::Error(report.errors.front() +
                      (report.errors.size() > 1
                           ? " (and " + std::to_string(report.errors.size() - 1) +
                                 " more problems; ddhgs info lists them)"
                           : ""));
  // Samples no header describes: the held-out views (otherwise read only
  // after the last iteration), every float cube, which may hold NaN or
  // absurd values (integer samples are bounded by the scale), and every
  // compressed view, decoded once here rather than when training first draws
  // it, possibly hours in. Raw integer cubes need no read: the header checks
  // above prove them whole.
  // Views are decoded side by side (decoders run on one thread each), a
  // batch at a time so that at most kBatch decoded views are held; the first
  // problem in view order is reported, whichever thread met it.
  std::vector<bool> held_out(scene.views.size(), false);
  for (int v : scene.test) held_out[size_t(v)] = true;
  const int64_t count = int64_t(scene.views.size());
  constexpr int64_t kBatch = 8;
  std::vector<std::string> problems(scene.views.size());
  for (int64_t first = 0; first < count; first += kBatch) {
    core::parallel_for(first, std::min(count, first + kBatch), 1, [&](int64_t begin, int64_t end) {
      for (int64_t v = begin; v < end; ++v) {
        const io::View& view = scene.views[size_t(v)];
        try {
          if (held_out[size_t(v)] || needs_full_read(view.data_path, scene))
            require_plausible(scene.image(int(v)), view.data_path, scene.scale);
          if (!view.clean_path.empty() &&
              (held_out[size_t(v)] || needs_full_read(view.clean_path, scene)))
            require_plausible(scene.clean_image(int(v)), view.clean_path, scene.scale);
        } catch (const core::Error& e) {
          problems[size_t(v)] = e.what();
        }
      }
    });
    for (int64_t v = first; v < std::min(count, first + kBatch); ++v)
      if (!problems[size_t(v)].empty()) throw core::Error(problems[size_t(v)]);
  }
  if (scene.test.empty())
    core::log_warn(scene.root.string() +
                   ": no held-out views (a scene needs 10 or more, or test_filenames); "
                   "training without test metrics");
  // How far the test views are from what training sees: on a sparse capture
  // (Basil: 14 degrees) their PSNR stays well below the training views'.
  if (!report.spacing.test_nearest_deg.empty())
    core::log_info("held-out views are " + io::degree_range(report.spacing.test_nearest_deg) +
                   " degrees from the nearest training view (ddhgs info: spacing)");
}

void require_finite_record(const nlohmann::json& record, const fs::path& run) {
  for (const auto& [key, value] : record.items())
    if (value.is_number_float() && !std::isfinite(value.get<double>()))
      throw core::Error(run, diverged(record.value("iter", int64_t(0)),
                                      "'" + key + "' is " + std::to_string(value.get<double>())));
}

void require_finite_parameters(const TrainState& state, const fs::path& run) {
  const auto& names = model::Gaussians::tensor_names();
  const auto values = state.gaussians.values();
  for (size_t i = 0; i < values.size(); ++i)
    if (!finite(values[i]))
      throw core::Error(
          run, diverged(state.iteration, "the Gaussians' " + names[i] + " hold NaN or Inf"));
  for (const auto& m : state.modules)
    for (const auto& p : m.module->named_parameters())
      if (!finite(p.value()))
        throw core::Error(run,
                          diverged(state.iteration, m.name + "/" + p.key() + " holds NaN or Inf"));
}

}  // namespace ddhgs::train
