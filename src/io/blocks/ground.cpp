#include "io/blocks/ground.h"

#include <algorithm>
#include <cmath>

#include "core/distortion.h"
#include "core/error.h"
#include "core/parallel.h"

namespace ddhgs::io {
using core::Vec3;

PrincipalAxes principal_axes(const std::vector<Vec3>& points) {
  PrincipalAxes out;
  if (points.empty()) return out;
  for (const Vec3& p : points) out.mean = out.mean + p;
  out.mean = out.mean * (1.0 / double(points.size()));
  if (points.size() < 2) return out;
  double a[3][3] = {};
  for (const Vec3& p : points) {
    const Vec3 d = p - out.mean;
    const double x[3] = {d.x, d.y, d.z};
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) a[i][j] += x[i] * x[j] / double(points.size());
  }
  double v[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  // Cyclic Jacobi: each rotation zeroes one off-diagonal pair; a 3x3
  // converges to double precision in a few sweeps.
  for (int sweep = 0; sweep < 50; ++sweep) {
    const double off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    const double scale = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
    if (off <= 1e-30 * scale || off == 0) break;
    for (int p = 0; p < 2; ++p)
      for (int q = p + 1; q < 3; ++q) {
        if (a[p][q] == 0) continue;
        const double theta = (a[q][q] - a[p][p]) / (2 * a[p][q]);
        const double t = (theta >= 0 ? 1 : -1) / (std::abs(theta) + std::sqrt(theta * theta + 1));
        const double c = 1 / std::sqrt(t * t + 1), s = t * c;
        for (int k = 0; k < 3; ++k) {  // a = a J (columns p, q)
          const double akp = a[k][p], akq = a[k][q];
          a[k][p] = c * akp - s * akq;
          a[k][q] = s * akp + c * akq;
        }
        for (int k = 0; k < 3; ++k) {  // a = J^T a (rows p, q)
          const double apk = a[p][k], aqk = a[q][k];
          a[p][k] = c * apk - s * aqk;
          a[q][k] = s * apk + c * aqk;
        }
        for (int k = 0; k < 3; ++k) {
          const double vkp = v[k][p], vkq = v[k][q];
          v[k][p] = c * vkp - s * vkq;
          v[k][q] = s * vkp + c * vkq;
        }
      }
  }
  int order[3] = {0, 1, 2};
  std::sort(order, order + 3, [&](int i, int j) { return a[i][i] < a[j][j]; });
  for (int i = 0; i < 3; ++i) {
    const int k = order[i];
    out.values[size_t(i)] = std::max(0.0, a[k][k]);
    out.vectors[size_t(i)] = Vec3{v[0][k], v[1][k], v[2][k]}.normalized();
  }
  return out;
}

namespace {

// A unit vector's sign fixed so that its largest component is positive:
// the same axes from any run.
Vec3 canonical(const Vec3& d) {
  const double m[3] = {d.x, d.y, d.z};
  int k = 0;
  for (int i = 1; i < 3; ++i)
    if (std::abs(m[i]) > std::abs(m[k])) k = i;
  return m[k] < 0 ? d * -1.0 : d;
}

}  // namespace

GroundFrame ground_frame(const std::vector<Vec3>& points,
                         const std::vector<core::Camera>& cameras) {
  std::vector<Vec3> centres;
  Vec3 forward;
  for (const core::Camera& c : cameras) {
    centres.push_back(c.center());
    forward = forward + c.forward();
  }
  const PrincipalAxes cams = principal_axes(centres);
  const PrincipalAxes cloud = principal_axes(points);
  GroundFrame f;
  if (points.size() >= 3 && cloud.values[0] < 0.25 * cloud.values[1])
    f.n = cloud.vectors[0];
  else if (centres.size() >= 3 && cams.values[1] > 1e-9 * cams.values[2])
    f.n = cams.vectors[0];
  else
    f.n = (forward * -1.0).normalized();
  if (f.n.norm() < 0.5) f.n = Vec3{0, 0, 1};
  // Towards the cameras: the cameras look along -n.
  if (forward.dot(f.n) > 0) f.n = f.n * -1.0;
  if (points.empty()) {
    f.origin = cams.mean;
  } else {
    std::vector<double> heights;
    for (const Vec3& p : points) heights.push_back((p - cloud.mean).dot(f.n));
    std::nth_element(heights.begin(), heights.begin() + heights.size() / 2, heights.end());
    f.origin = cloud.mean + f.n * heights[heights.size() / 2];
  }
  // The flight's direction: the camera centres' main axis in the plane (the
  // points' when the cameras stand at one place).
  Vec3 along = cams.values[2] > 0 ? cams.vectors[2] : cloud.vectors[2];
  along = along - f.n * along.dot(f.n);
  if (along.norm() < 1e-6) {  // along the normal: any direction in the plane
    along = std::abs(f.n.x) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
    along = along - f.n * along.dot(f.n);
  }
  f.u = canonical(along.normalized());
  f.v = f.n.cross(f.u).normalized();
  return f;
}

GroundBox view_footprint(const GroundFrame& frame, const core::Camera& camera, bool with_ground) {
  const Vec3 c = camera.center();
  GroundBox box{frame.along(c), frame.along(c), frame.across(c), frame.across(c)};
  if (!with_ground) return box;
  const core::Intrinsics& k = camera.intrinsics;
  const core::Mat3 to_world = camera.camera_to_world().rotation();
  const double height = (c - frame.origin).dot(frame.n);
  bool any = false;
  for (const double x : {0.0, double(k.width)})
    for (const double y : {0.0, double(k.height)}) {
      const Vec3 d = to_world * Vec3{(x - k.cx) / k.fx, (y - k.cy) / k.fy, 1.0};
      const double down = -d.dot(frame.n);
      // A corner ray at the horizon or above sees no ground near the flight.
      if (height <= 0 || down <= 1e-3 * d.norm()) continue;
      const Vec3 hit = c + d * (height / down);
      const double u = frame.along(hit), v = frame.across(hit);
      if (!any) box = {u, u, v, v};
      box = {std::min(box.u0, u), std::max(box.u1, u), std::min(box.v0, v), std::max(box.v1, v)};
      any = true;
    }
  return box;
}

torch::Tensor ground_box_mask(const GroundFrame& frame, const GroundBox& box,
                              const core::Camera& camera, int x0, int y0, int width, int height) {
  torch::Tensor mask = torch::zeros({std::max(0, height), std::max(0, width)}, torch::kBool);
  const Vec3 c = camera.center();
  const double above = (c - frame.origin).dot(frame.n);
  if (!(above > 0) || width <= 0 || height <= 0) return mask;
  const core::Intrinsics& k = camera.intrinsics;
  const core::Mat3 to_world = camera.camera_to_world().rotation();
  bool* out = mask.data_ptr<bool>();
  core::parallel_for(0, height, 16, [&](int64_t begin, int64_t end) {
    for (int64_t y = begin; y < end; ++y)
      for (int x = 0; x < width; ++x) {
        core::Point2 p{(x0 + x + 0.5 - k.cx) / k.fx, (y0 + y + 0.5 - k.cy) / k.fy};
        if (k.has_distortion()) {
          try {
            p = core::undistort(k, p);
          } catch (const core::Error&) {
            continue;  // beyond the lens model's fold: no ray
          }
        }
        const Vec3 d = to_world * Vec3{p.x, p.y, 1.0};
        const double down = -d.dot(frame.n);
        if (!(down > 1e-9 * d.norm())) continue;  // at or above the horizon
        const Vec3 hit = c + d * (above / down);
        out[y * width + x] = box.contains(frame.along(hit), frame.across(hit));
      }
  });
  return mask;
}

}  // namespace ddhgs::io
