#include "io/scene/colmap_beside.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <vector>

#include "core/error.h"
#include "core/similarity.h"
#include "io/colmap/colmap.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

constexpr double kMaxCentreRms = 0.01;      // of the centres' RMS spread
constexpr double kMaxMedianAngleDeg = 1.0;  // camera orientations
constexpr double kRadToDeg = 57.29577951308232;

// Camera poses of the views both describe, matched by file stem.
struct Matched {
  std::vector<core::Vec3> colmap_centres, file_centres;
  std::vector<core::Mat3> colmap_c2w, file_c2w;  // camera-to-world rotations, OpenCV axes
};

Matched match_cameras(const ColmapModel& model, const TransformsFile& tf) {
  std::map<std::string, const TransformsFrame*> frames;
  for (const auto& f : tf.frames)
    frames
        [fs::path(f.file_path.empty() ? f.hyperspectral_file_path : f.file_path).stem().string()] =
            &f;
  Matched m;
  for (const auto& image : model.images) {
    auto it = frames.find(fs::path(image.name).stem().string());
    if (it == frames.end()) continue;
    const core::Camera colmap = colmap_camera(model, image);
    const core::Mat4 file_c2w =
        core::opengl_c2w_to_opencv_w2c(it->second->camera_to_world_gl).rigid_inverse();
    m.colmap_centres.push_back(colmap.center());
    m.colmap_c2w.push_back(colmap.camera_to_world().rotation());
    m.file_centres.push_back(file_c2w.translation());
    m.file_c2w.push_back(file_c2w.rotation());
  }
  return m;
}

// A 3x4 (or 4x4) map given in the file, as a similarity; nullopt when it is
// not one (a shear or a reflection).
std::optional<core::Similarity> as_similarity(const core::Mat4& map) {
  core::Mat3 linear = map.rotation();
  double det = linear.determinant();
  if (!(det > 0)) return std::nullopt;
  core::Similarity s;
  s.scale = std::cbrt(det);
  for (double& v : linear.m) v /= s.scale;
  s.rotation = core::orthonormalize(linear);
  for (size_t i = 0; i < 9; ++i)
    if (std::abs(s.rotation.m[i] - linear.m[i]) > 1e-6) return std::nullopt;
  s.translation = map.translation();
  return s;
}

struct Fit {
  core::Similarity map;
  double centre_rms = 0;  // fraction of the file's centre spread
  double median_deg = 0;  // orientation difference
  std::string source;     // how the map was found
  bool good() const { return centre_rms <= kMaxCentreRms && median_deg <= kMaxMedianAngleDeg; }
};

Fit evaluate(const core::Similarity& map, const Matched& m, std::string source) {
  Fit fit{map, 0, 0, std::move(source)};
  double spread = core::rms_spread(m.file_centres);
  fit.centre_rms =
      spread > 0 ? core::rms_residual(map, m.colmap_centres, m.file_centres) / spread : INFINITY;
  std::vector<double> angles;
  for (size_t i = 0; i < m.file_c2w.size(); ++i) {
    // Rotation between the file's orientation and the mapped COLMAP one.
    core::Mat3 d = m.file_c2w[i].transposed() * (map.rotation * m.colmap_c2w[i]);
    double c = std::clamp((d(0, 0) + d(1, 1) + d(2, 2) - 1) / 2, -1.0, 1.0);
    angles.push_back(std::acos(c) * kRadToDeg);
  }
  std::nth_element(angles.begin(), angles.begin() + long(angles.size() / 2), angles.end());
  fit.median_deg = angles[angles.size() / 2];
  return fit;
}

std::string percent(double fraction) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2g %%", 100 * fraction);
  return buf;
}

std::string degrees(double deg) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2g degrees", deg);
  return buf;
}

PointCloud mapped_points(const ColmapModel& model, const core::Similarity& map) {
  PointCloud cloud = colmap_points(model);
  auto xyz = cloud.xyz.accessor<float, 2>();
  for (int64_t i = 0; i < cloud.xyz.size(0); ++i) {
    core::Vec3 p = map.apply({xyz[i][0], xyz[i][1], xyz[i][2]});
    xyz[i][0] = float(p.x);
    xyz[i][1] = float(p.y);
    xyz[i][2] = float(p.z);
  }
  return cloud;
}

}  // namespace

PointsBeside points_beside(const fs::path& model_dir, const TransformsFile& tf,
                           const fs::path& file) {
  const std::string model_name = "the COLMAP model " + model_dir.string();
  PointsBeside out;
  ColmapModel model;
  Matched matched;
  try {
    model = read_colmap(model_dir);
    matched = match_cameras(model, tf);
  } catch (const core::Error& e) {
    out.message = file.string() + ": " + model_name + " beside it is unreadable (" + e.what() +
                  "); its points are not used";
    return out;
  }
  const std::string prefix = file.string() + " names no points; " + model_name + " beside it ";
  if (model.points.empty()) {
    out.message = prefix + "has none either";
    return out;
  }
  const size_t n = matched.file_centres.size();
  std::optional<Fit> best;
  if (tf.applied_transform)
    if (auto map = as_similarity(*tf.applied_transform))
      best = evaluate(*map, matched, "the file's applied_transform");
  if ((!best || !best->good()) && n >= 3) {
    try {
      core::Similarity map = core::fit_similarity(matched.colmap_centres, matched.file_centres);
      Fit fitted =
          evaluate(map, matched, "a similarity fitted to " + std::to_string(n) + " camera centres");
      if (!best || fitted.good() || fitted.centre_rms < best->centre_rms) best = fitted;
    } catch (const core::Error&) {
      // Centres on one line: no similarity, reported below as a poor fit.
    }
  }
  if (!best || n < 3) {
    out.message = prefix + "shares only " + std::to_string(n) +
                  " image names with its frames (3 needed to relate the frames); its points are "
                  "not used";
    return out;
  }
  const std::string agreement = "camera centres agree to " + percent(best->centre_rms) +
                                " of their spread, orientations to " + degrees(best->median_deg) +
                                " (median)";
  if (!best->good()) {
    out.message = prefix + "is in another frame: after " + best->source + ", " + agreement +
                  " (at most " + percent(kMaxCentreRms) + " and " + degrees(kMaxMedianAngleDeg) +
                  " needed); its points are not used";
    return out;
  }
  out.points = mapped_points(model, best->map);
  out.message = file.string() + ": using the " + std::to_string(model.points.size()) +
                " points of " + model_name + ", mapped by " + best->source + " (" + agreement + ")";
  return out;
}

}  // namespace ddhgs::io
