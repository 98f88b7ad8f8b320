#include "core/camera.h"

#include <algorithm>
#include <cmath>

namespace ddhgs::core {

Intrinsics Intrinsics::downscaled(int factor) const {
  Intrinsics out = *this;
  if (factor <= 1) return out;
  // Area averaging over factor x factor blocks keeps pixel-centre geometry
  // when coordinates scale by 1/factor (centres at +0.5 on both grids).
  out.width = width / factor;
  out.height = height / factor;
  out.fx = fx / factor;
  out.fy = fy / factor;
  out.cx = cx / factor;
  out.cy = cy / factor;
  return out;
}

bool Intrinsics::operator==(const Intrinsics& o) const {
  return fx == o.fx && fy == o.fy && cx == o.cx && cy == o.cy && width == o.width &&
         height == o.height && fisheye == o.fisheye && k1 == o.k1 && k2 == o.k2 && k3 == o.k3 &&
         k4 == o.k4 && p1 == o.p1 && p2 == o.p2 && frame_x == o.frame_x && frame_y == o.frame_y &&
         frame_width == o.frame_width && frame_height == o.frame_height;
}

Vec3 Camera::forward() const {
  Mat3 r = world_to_camera.rotation();
  return Vec3{r(2, 0), r(2, 1), r(2, 2)};  // third row of R = camera z in world
}

std::string camera_problem(const Camera& camera) {
  const Intrinsics& in = camera.intrinsics;
  for (double v : {in.fx, in.fy, in.cx, in.cy, in.k1, in.k2, in.k3, in.k4, in.p1, in.p2})
    if (!std::isfinite(v)) return "an intrinsic value is not finite";
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c)
      if (!std::isfinite(camera.world_to_camera(r, c)))
        return "the pose holds a value that is not finite";
  const double size = std::max(in.width, in.height);
  if (in.fx <= 0 || in.fy <= 0 || std::max(in.fx, in.fy) > 1e6 * size)
    return "focal length " + std::to_string(std::max(in.fx, in.fy)) +
           " px is not positive or beyond 1e6 image sizes";
  if (std::abs(in.cx) > 100 * size || std::abs(in.cy) > 100 * size)
    return "principal point (" + std::to_string(in.cx) + ", " + std::to_string(in.cy) +
           ") px lies more than 100 image sizes off the image";
  const Vec3 c = camera.center();
  const double distance = std::sqrt(c.x * c.x + c.y * c.y + c.z * c.z);
  if (!(distance <= kMaxSceneExtent))
    return "camera centre is " + std::to_string(distance) +
           " units from the origin (at most 1e7: float32 cannot place it)";
  return "";
}

namespace {
// Flips camera y and z axes: OpenGL <-> OpenCV camera frames.
Mat3 flip_yz() {
  Mat3 f;
  f.m = {1, 0, 0, 0, -1, 0, 0, 0, -1};
  return f;
}
}  // namespace

Mat4 opengl_c2w_to_opencv_w2c(const Mat4& c2w_gl) {
  Mat3 r = orthonormalize(c2w_gl.rotation()) * flip_yz();
  Mat4 c2w_cv = Mat4::from(r, c2w_gl.translation());
  return c2w_cv.rigid_inverse();
}

Mat4 opencv_w2c_to_opengl_c2w(const Mat4& w2c_cv) {
  Mat4 c2w_cv = w2c_cv.rigid_inverse();
  return Mat4::from(c2w_cv.rotation() * flip_yz(), c2w_cv.translation());
}

Mat4 look_at(const Vec3& eye, const Vec3& target, const Vec3& world_up) {
  Vec3 z = (target - eye).normalized();
  Vec3 x = z.cross(world_up).normalized();  // image x: right of the view
  if (x.norm() < 1e-12) x = z.cross(Vec3{1, 0, 0}).normalized();
  Vec3 y = z.cross(x);  // image y points down
  Mat3 r;
  r.m = {x.x, x.y, x.z, y.x, y.y, y.z, z.x, z.y, z.z};
  return Mat4::from(r, (r * eye) * -1.0);
}

double focal_from_fov(double fov_rad, int extent_px) {
  return 0.5 * extent_px / std::tan(0.5 * fov_rad);
}

}  // namespace ddhgs::core
