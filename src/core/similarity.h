// Similarity transforms (uniform scale, rotation, translation) between two
// frames, fitted to matched 3D points: how two reconstructions of one scene
// (a COLMAP model and a transforms.json made from it) relate.
#pragma once
#include <vector>

#include "core/mat.h"

namespace ddhgs::core {

struct Similarity {
  double scale = 1;
  Mat3 rotation;  // proper rotation (determinant +1)
  Vec3 translation;
  Vec3 apply(const Vec3& p) const { return (rotation * p) * scale + translation; }
};

// Least-squares similarity with to[i] ~ apply(from[i]) (Umeyama 1991, the
// reflection excluded). core::Error unless there are at least 3 pairs and
// `from` spans a plane (not all on one line).
Similarity fit_similarity(const std::vector<Vec3>& from, const std::vector<Vec3>& to);

// Root mean square of |to[i] - apply(from[i])|.
double rms_residual(const Similarity& s, const std::vector<Vec3>& from,
                    const std::vector<Vec3>& to);

// Root mean square distance of points from their centroid.
double rms_spread(const std::vector<Vec3>& points);

}  // namespace ddhgs::core
