#include "io/scene/scene_report.h"

#include <algorithm>
#include <set>

#include "core/error.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

// Records a problem instead of throwing, so one report lists all of them.
template <typename F>
void collect(std::vector<std::string>& errors, F&& check) {
  try {
    check();
  } catch (const core::Error& e) {
    errors.push_back(e.what());
  } catch (const c10::Error& e) {
    errors.push_back(e.what_without_backtrace());
  }
}

void probe_one(const Scene& scene, const fs::path& path, const core::Intrinsics& target,
               std::vector<std::string>& errors) {
  collect(errors, [&] {
    CubeInfo info = probe_cube(path, CubeReadOptions{scene.options.layout});
    require_bands(path, info.bands, scene.source_bands);
    area_factor(path, info.height, info.width, target, scene.options.downscale);
  });
}

}  // namespace

SceneReport inspect_scene(const Scene& scene, int sample_reads) {
  SceneReport report;
  if (scene.views.empty()) return report;
  const core::Intrinsics& first = scene.views.front().camera.intrinsics;
  report.width = first.width;
  report.height = first.height;
  size_t sample_bytes = bytes_per_sample(scene.stored_type);
  for (const View& v : scene.views) {
    const core::Intrinsics& k = v.camera.intrinsics;
    report.mixed_sizes = report.mixed_sizes || k.width != first.width || k.height != first.height;
    if (v.undistortion) ++report.distorted_views;
    size_t values = size_t(k.width) * size_t(k.height) * size_t(scene.bands());
    report.scene_bytes += values * sample_bytes;
    report.scene_bytes_f32 += values * sizeof(float);
    probe_one(scene, v.data_path, k, report.errors);
    if (!v.clean_path.empty()) {
      ++report.clean_views;
      probe_one(scene, v.clean_path, k, report.errors);
    }
  }

  // Headers say nothing about NaN/Inf samples: read a few cubes in full.
  std::set<size_t> picks;
  size_t n = scene.views.size();
  for (int s = 0; s < sample_reads; ++s)
    picks.insert(sample_reads > 1 ? size_t(s) * (n - 1) / size_t(sample_reads - 1) : 0);
  for (size_t i : picks)
    collect(report.errors,
            [&] { read_cube(scene.views[i].data_path, CubeReadOptions{scene.options.layout}); });
  // A file can fail both its probe and its read: list each message once.
  std::vector<std::string> unique;
  for (const auto& e : report.errors)
    if (std::find(unique.begin(), unique.end(), e) == unique.end()) unique.push_back(e);
  report.errors = unique;

  if (scene.points.xyz.defined()) {
    report.points = scene.points.xyz.size(0);
    report.point_colors = scene.points.rgb.defined();
    report.point_spectra = scene.points.spectra.defined();
  }
  return report;
}

}  // namespace ddhgs::io
