// What `ddhgs info` tells about a dataset: sizes, memory, and every problem
// found by probing each view's file header (not its samples).
#pragma once
#include <cstddef>
#include <string>
#include <vector>

#include "io/scene/scene.h"

namespace ddhgs::io {

// How far apart the views look: the angle (degrees) between viewing
// directions, for each training view to its nearest other training view and
// for each test view to its nearest training view (in split order). Views
// 10-15 degrees apart, as on a turntable with 25 stops, leave each held-out
// view's appearance to be interpolated across that gap.
struct ViewSpacing {
  std::vector<double> train_nearest_deg;  // empty with fewer than 2 training views
  std::vector<double> test_nearest_deg;   // empty without training views
};
ViewSpacing view_spacing(const Scene& scene);
// "13.3-14.9": the smallest and largest angle, one decimal each; "" when empty.
std::string degree_range(const std::vector<double>& deg);

struct SceneReport {
  int width = 0, height = 0;  // pixels of the first view, as loaded
  bool mixed_sizes = false;   // views differ in size (several COLMAP cameras)
  int distorted_views = 0;    // views whose camera has lens distortion (undistorted at load)
  size_t scene_bytes = 0;     // all views in the stored type, as loaded
  size_t scene_bytes_f32 = 0;
  int clean_views = 0;
  int64_t points = 0;
  bool point_colors = false, point_spectra = false;
  std::vector<std::string> errors;      // files that would fail to load
  double fov_x_deg = 0, fov_y_deg = 0;  // first view's field of view
  ViewSpacing spacing;
};

// Probes every view (and clean file) header for band counts and sizes, and
// reads up to `sample_reads` cubes in full to catch NaN/Inf samples.
SceneReport inspect_scene(const Scene& scene, int sample_reads = 3);

// Pixel spectra for a PCA of the scene (core/spectral_pca.h): up to
// `max_views` training views spread along the split, every k-th pixel so
// that each gives at most `per_view` samples.
struct SpectraSample {
  torch::Tensor spectra;      // [M, N] float32, as loaded
  torch::Tensor noise_sigma;  // [N] float64, the median over the views of core::band_noise_sigma
                              // of every k-th row
  int views = 0;
};
SpectraSample sample_spectra(const Scene& scene, int max_views = 8, int64_t per_view = 20000);

}  // namespace ddhgs::io
