#include <gtest/gtest.h>

#include "core/camera.h"
#include "core/error.h"
#include "core/log.h"

using namespace ddhgs::core;

namespace {
void expect_near(const Mat4& a, const Mat4& b, double tol) {
  for (int i = 0; i < 16; ++i) EXPECT_NEAR(a.m[i], b.m[i], tol) << "element " << i;
}
}  // namespace

TEST(Mat, OrthonormalizeRemovesUniformScale) {
  Mat3 r = quat_to_rotation(0.9, 0.1, -0.3, 0.2);
  Mat3 scaled = r;
  for (double& v : scaled.m) v *= 2.5;
  Mat3 fixed = orthonormalize(scaled);
  for (int i = 0; i < 9; ++i) EXPECT_NEAR(fixed.m[i], r.m[i], 1e-12);
  EXPECT_NEAR(fixed.determinant(), 1.0, 1e-12);
}

TEST(Mat, QuaternionRoundTrip) {
  for (auto q : std::vector<std::array<double, 4>>{
           {1, 0, 0, 0}, {0.1, 0.9, 0.2, -0.3}, {0.0, 0.0, 1.0, 0.0}, {0.3, -0.2, 0.1, 0.9}}) {
    Mat3 r = quat_to_rotation(q[0], q[1], q[2], q[3]);
    auto back = rotation_to_quat(r);
    Mat3 r2 = quat_to_rotation(back[0], back[1], back[2], back[3]);
    for (int i = 0; i < 9; ++i) EXPECT_NEAR(r.m[i], r2.m[i], 1e-12);
    EXPECT_GE(back[0], 0.0);
  }
}

TEST(Mat, RigidInverse) {
  Mat4 t = Mat4::from(quat_to_rotation(0.7, 0.1, 0.5, -0.2), Vec3{1, -2, 3});
  Mat4 id = t * t.rigid_inverse();
  expect_near(id, Mat4{}, 1e-12);
}

TEST(Camera, LookAtPutsTargetOnOpticalAxisWithImageYDown) {
  Vec3 eye{3, 1, 2}, target{0, 0.5, 0}, up{0, 0, 1};
  Mat4 w2c = look_at(eye, target, up);
  Vec3 t = w2c.transform_point(target);
  EXPECT_NEAR(t.x, 0, 1e-12);
  EXPECT_NEAR(t.y, 0, 1e-12);
  EXPECT_GT(t.z, 0);
  // A point above the target (world up) appears higher in the image: smaller y.
  Vec3 above = w2c.transform_point(target + up * 0.1);
  EXPECT_LT(above.y, 0);
  EXPECT_NEAR(w2c.rotation().determinant(), 1.0, 1e-12);
  Camera cam{{}, w2c};
  EXPECT_NEAR((cam.center() - eye).norm(), 0, 1e-12);
  Vec3 f = cam.forward();
  Vec3 expected = (target - eye).normalized();
  EXPECT_NEAR(f.dot(expected), 1.0, 1e-12);
}

TEST(Camera, OpenGlConversionRoundTripsAndFlipsAxes) {
  Mat4 w2c = look_at(Vec3{0, -4, 1}, Vec3{0, 0, 0}, Vec3{0, 0, 1});
  Mat4 c2w_gl = opencv_w2c_to_opengl_c2w(w2c);
  // OpenGL cameras look down their -z axis.
  Vec3 gl_forward{-c2w_gl(0, 2), -c2w_gl(1, 2), -c2w_gl(2, 2)};
  Camera cam{{}, w2c};
  EXPECT_NEAR(gl_forward.dot(cam.forward()), 1.0, 1e-12);
  expect_near(opengl_c2w_to_opencv_w2c(c2w_gl), w2c, 1e-12);

  // A scaled rotation block (as real transforms.json files carry) is repaired.
  Mat4 scaled = c2w_gl;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) scaled(r, c) *= 0.37;
  expect_near(opengl_c2w_to_opencv_w2c(scaled), w2c, 1e-9);
}

TEST(Camera, DownscaledIntrinsicsKeepPixelCentres) {
  Intrinsics k{400, 410, 320, 256, 640, 512};
  Intrinsics d = k.downscaled(4);
  EXPECT_EQ(d.width, 160);
  EXPECT_EQ(d.height, 128);
  EXPECT_DOUBLE_EQ(d.fx, 100);
  EXPECT_DOUBLE_EQ(d.cy, 64);
  // A ray through full-res pixel centre (u+0.5) hits the same low-res
  // position (u+0.5)/4 when projected with the downscaled intrinsics.
  double x_over_z = (10.5 - k.cx) / k.fx;
  EXPECT_NEAR(d.fx * x_over_z + d.cx, 10.5 / 4, 1e-12);
}

TEST(Camera, FocalFromFov) {
  EXPECT_NEAR(focal_from_fov(M_PI / 2, 200), 100.0, 1e-12);
}

TEST(Log, FormatDuration) {
  EXPECT_EQ(format_duration(12.34), "12.3s");
  EXPECT_EQ(format_duration(185), "3m05s");
  EXPECT_EQ(format_duration(3720), "1h02m");
}

TEST(Error, NamesTheFile) {
  try {
    require(false, std::filesystem::path("/data/x.npy"), "truncated");
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "/data/x.npy: truncated");
  }
}
