#include "train/novel_views.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>

#include "train/seed.h"

namespace ddhgs::train {

namespace {

// A uniform double in [0, 1) from stream `stream` of `seed`.
double uniform(uint64_t seed, uint64_t stream) {
  return double(mix_seed(seed, stream) >> 11) * 0x1.0p-53;
}

}  // namespace

core::Camera turned(const core::Camera& camera, double degrees, uint64_t seed) {
  const double z = 2 * uniform(seed, 0) - 1, phi = 2 * M_PI * uniform(seed, 1);
  const double r = std::sqrt(std::max(0.0, 1 - z * z));
  const double half = 0.5 * degrees * M_PI / 180, s = std::sin(half);
  const core::Mat3 turn =
      core::quat_to_rotation(std::cos(half), s * r * std::cos(phi), s * r * std::sin(phi), s * z);
  const core::Mat4 c2w = camera.camera_to_world();
  core::Camera out = camera;
  out.world_to_camera = core::Mat4::from(c2w.rotation() * turn, c2w.translation()).rigid_inverse();
  return out;
}

std::vector<std::vector<int>> interleaved_folds(const std::vector<int>& views, int k) {
  k = std::clamp(k, 1, std::max(1, int(views.size())));
  std::vector<std::vector<int>> folds(static_cast<size_t>(k));
  for (size_t i = 0; i < views.size(); ++i) folds[i % size_t(k)].push_back(views[i]);
  return folds;
}

core::Camera midway(const core::Camera& a, const core::Camera& b) {
  const core::Mat4 a_c2w = a.camera_to_world(), b_c2w = b.camera_to_world();
  const auto qa = core::rotation_to_quat(a_c2w.rotation());
  auto qb = core::rotation_to_quat(b_c2w.rotation());
  // q and -q are the same rotation: take the one on a's side, so the sum
  // (the normalised linear mean, which at one half is the slerp midpoint)
  // follows the short arc.
  double dot = 0;
  for (int i = 0; i < 4; ++i) dot += qa[size_t(i)] * qb[size_t(i)];
  if (dot < 0)
    for (double& v : qb) v = -v;
  std::array<double, 4> q{};
  double norm = 0;
  for (size_t i = 0; i < 4; ++i) {
    q[i] = qa[i] + qb[i];
    norm += q[i] * q[i];
  }
  norm = std::sqrt(norm);
  for (double& v : q) v /= norm;
  const core::Vec3 centre = (a_c2w.translation() + b_c2w.translation()) * 0.5;
  core::Camera out;
  out.intrinsics = a.intrinsics;
  out.world_to_camera =
      core::Mat4::from(core::quat_to_rotation(q[0], q[1], q[2], q[3]), centre).rigid_inverse();
  return out;
}

std::vector<core::Camera> between_cameras(const std::vector<core::Camera>& cameras) {
  std::vector<core::Camera> out;
  std::set<std::pair<size_t, size_t>> seen;
  for (size_t i = 0; i < cameras.size(); ++i) {
    // The two nearest: on a path of cameras (a turntable ring, a flight
    // line) every gap between consecutive cameras is met.
    std::vector<std::pair<double, size_t>> by_distance;
    for (size_t j = 0; j < cameras.size(); ++j)
      if (j != i) by_distance.push_back({(cameras[j].center() - cameras[i].center()).norm(), j});
    const size_t keep = std::min<size_t>(2, by_distance.size());
    std::partial_sort(by_distance.begin(), by_distance.begin() + std::ptrdiff_t(keep),
                      by_distance.end());
    for (size_t n = 0; n < keep; ++n) {
      const size_t j = by_distance[n].second;
      if (seen.insert({std::min(i, j), std::max(i, j)}).second)
        out.push_back(midway(cameras[i], cameras[j]));
    }
  }
  return out;
}

}  // namespace ddhgs::train
