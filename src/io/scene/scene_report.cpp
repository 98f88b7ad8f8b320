#include "io/scene/scene_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>

#include "core/error.h"
#include "core/spectral_pca.h"

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

void probe_one(const Scene& scene, const View& view, const fs::path& path,
               std::vector<std::string>& errors) {
  const core::Intrinsics& target = view.camera.intrinsics;
  collect(errors, [&] {
    CubeInfo info = probe_cube(path, CubeReadOptions{scene.options.layout});
    if (view.file_bands.empty())
      require_bands(path, info.bands, scene.source_bands);
    else
      require_named_bands(path, info.bands, view.file_band_count);
    area_factor(path, info.height, info.width, target, scene.options.downscale);
  });
}

double degrees_between(const core::Vec3& a, const core::Vec3& b) {
  // atan2 of |a x b| and a . b stays accurate for small angles (acos does not).
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI;
}

// For each view of `from`, the smallest angle to a view of `to` other than
// itself; forward[v] is view v's viewing direction.
std::vector<double> nearest_angles(const std::vector<core::Vec3>& forward,
                                   const std::vector<int>& from, const std::vector<int>& to) {
  std::vector<double> out;
  for (int f : from) {
    double best = -1;
    for (int t : to) {
      if (t == f) continue;
      const double a = degrees_between(forward[size_t(f)], forward[size_t(t)]);
      if (best < 0 || a < best) best = a;
    }
    if (best >= 0) out.push_back(best);
  }
  return out;
}

}  // namespace

ViewSpacing view_spacing(const Scene& scene) {
  std::vector<core::Vec3> forward;
  for (const View& v : scene.views) forward.push_back(v.camera.forward());
  ViewSpacing s;
  if (scene.train.size() >= 2)
    s.train_nearest_deg = nearest_angles(forward, scene.train, scene.train);
  if (!scene.train.empty()) s.test_nearest_deg = nearest_angles(forward, scene.test, scene.train);
  return s;
}

std::string degree_range(const std::vector<double>& deg) {
  if (deg.empty()) return "";
  auto [lo, hi] = std::minmax_element(deg.begin(), deg.end());
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.1f-%.1f", *lo, *hi);
  return buf;
}

SceneReport inspect_scene(const Scene& scene, int sample_reads) {
  SceneReport report;
  if (scene.views.empty()) return report;
  const core::Intrinsics& first = scene.views.front().camera.intrinsics;
  report.width = first.width;
  report.height = first.height;
  report.fov_x_deg =
      (std::atan(first.cx / first.fx) + std::atan((first.width - first.cx) / first.fx)) * 180.0 /
      M_PI;
  report.fov_y_deg =
      (std::atan(first.cy / first.fy) + std::atan((first.height - first.cy) / first.fy)) * 180.0 /
      M_PI;
  report.spacing = view_spacing(scene);
  size_t sample_bytes = bytes_per_sample(scene.stored_type);
  for (const View& v : scene.views) {
    const core::Intrinsics& k = v.camera.intrinsics;
    report.mixed_sizes = report.mixed_sizes || k.width != first.width || k.height != first.height;
    if (v.undistortion) ++report.distorted_views;
    size_t values = size_t(k.width) * size_t(k.height) * size_t(scene.bands());
    report.scene_bytes += values * sample_bytes;
    report.scene_bytes_f32 += values * sizeof(float);
    probe_one(scene, v, v.data_path, report.errors);
    if (!v.clean_path.empty()) {
      ++report.clean_views;
      probe_one(scene, v, v.clean_path, report.errors);
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

SpectraSample sample_spectra(const Scene& scene, int max_views, int64_t per_view) {
  core::require(!scene.train.empty(), scene.root, "no training views to sample spectra from");
  core::require(!scene.band_per_view(), scene.root,
                "is a band-per-view scene: no view holds whole spectra to sample");
  const int count = std::min<int>(max_views, int(scene.train.size()));
  std::vector<torch::Tensor> samples, sigmas;
  for (int i = 0; i < count; ++i) {
    const int view = scene.train[size_t(int64_t(i) * int64_t(scene.train.size()) / count)];
    const torch::Tensor image = scene.image(view);
    const int64_t step =
        std::max<int64_t>(1, (image.size(0) * image.size(1) + per_view - 1) / per_view);
    // The noise from whole rows (differences run along them), one row in
    // `step`: about per_view pixels, as the spectra, not the whole view in
    // float64.
    if (image.size(1) >= 2)
      sigmas.push_back(core::band_noise_sigma(image.slice(0, 0, image.size(0), step)));
    const torch::Tensor pixels = image.reshape({-1, scene.bands()});
    samples.push_back(pixels.slice(0, 0, pixels.size(0), step).clone());
  }
  SpectraSample out;
  out.spectra = torch::cat(samples);
  out.noise_sigma = sigmas.empty() ? torch::zeros({scene.bands()}, torch::kFloat64)
                                   : std::get<0>(torch::stack(sigmas).median(0));
  out.views = count;
  return out;
}

}  // namespace ddhgs::io
