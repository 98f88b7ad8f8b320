#include "core/camera.h"

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
         k4 == o.k4 && p1 == o.p1 && p2 == o.p2;
}

Vec3 Camera::forward() const {
  Mat3 r = world_to_camera.rotation();
  return Vec3{r(2, 0), r(2, 1), r(2, 2)};  // third row of R = camera z in world
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
