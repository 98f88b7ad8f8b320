// What `ddhgs info` tells about a dataset: sizes, memory, and every problem
// found by probing each view's file header (not its samples).
#pragma once
#include <cstddef>
#include <string>
#include <vector>

#include "io/scene/scene.h"

namespace ddhgs::io {

struct SceneReport {
  int width = 0, height = 0;  // pixels of the first view, as loaded
  bool mixed_sizes = false;   // views differ in size (several COLMAP cameras)
  int distorted_views = 0;    // views whose camera has lens distortion (undistorted at load)
  size_t scene_bytes = 0;     // all views in the stored type, as loaded
  size_t scene_bytes_f32 = 0;
  int clean_views = 0;
  int64_t points = 0;
  bool point_colors = false, point_spectra = false;
  std::vector<std::string> errors;  // files that would fail to load
};

// Probes every view (and clean file) header for band counts and sizes, and
// reads up to `sample_reads` cubes in full to catch NaN/Inf samples.
SceneReport inspect_scene(const Scene& scene, int sample_reads = 3);

}  // namespace ddhgs::io
