// Orbit fitting on rings, ellipses and a tripod arc of cameras.
#include <gtest/gtest.h>

#include <cmath>

#include "core/error.h"
#include "eval/orbit.h"

namespace ddhgs::eval {
namespace {

using core::Vec3;

core::Camera camera_at(const Vec3& eye, const Vec3& target, const Vec3& up) {
  core::Camera cam;
  cam.intrinsics = {50, 50, 16, 12, 32, 24};
  cam.world_to_camera = core::look_at(eye, target, up);
  return cam;
}

// Ring of n cameras on an ellipse (semi-axes a, b) at height h, looking at
// the target, z up.
std::vector<core::Camera> ring(int n, double a, double b, double h, const Vec3& target) {
  std::vector<core::Camera> cams;
  for (int i = 0; i < n; ++i) {
    double t = 2 * M_PI * i / n + 0.3;
    cams.push_back(
        camera_at(target + Vec3{a * std::cos(t), b * std::sin(t), h}, target, {0, 0, 1}));
  }
  return cams;
}

void expect_near(const Vec3& a, const Vec3& b, double tol) {
  EXPECT_NEAR(a.x, b.x, tol);
  EXPECT_NEAR(a.y, b.y, tol);
  EXPECT_NEAR(a.z, b.z, tol);
}

TEST(Orbit, CircularRingIsRecovered) {
  Vec3 target{0.5, -0.2, 0.1};
  OrbitFit fit = fit_orbit(ring(24, 3, 3, 1, target));
  expect_near(fit.target, target, 1e-6);
  expect_near(fit.up, {0, 0, 1}, 1e-6);
  expect_near(fit.centre, target + Vec3{0, 0, 1}, 1e-6);
  for (double t : {0.0, 1.0, 2.5, 4.0}) {
    EXPECT_NEAR(fit.radius_at(t), 3.0, 1e-4);
    EXPECT_NEAR(fit.height_at(t), 0.0, 1e-4);
  }
}

TEST(Orbit, FramesFollowAnEllipseAndLookAtTheTarget) {
  Vec3 target{0, 0, 0};
  std::vector<core::Camera> cams = ring(36, 4, 2, 0.5, target);
  std::vector<core::Camera> path = orbit_cameras(cams, 12);
  ASSERT_EQ(path.size(), 12u);
  // The first frame starts at the first camera.
  expect_near(path[0].center(), cams[0].center(), 0.05);
  for (const core::Camera& cam : path) {
    Vec3 c = cam.center();
    // On the ellipse x^2/16 + y^2/4 = 1 (an exact fit of 1 / r^2).
    EXPECT_NEAR(c.x * c.x / 16 + c.y * c.y / 4, 1.0, 1e-5);
    EXPECT_NEAR(c.z, 0.5, 1e-3);
    expect_near(cam.forward(), (target - c).normalized(), 1e-9);
    // Image up is world +z: the camera's y axis (down) has a negative z.
    EXPECT_LT(cam.world_to_camera(1, 2), 0);
    EXPECT_EQ(cam.intrinsics.width, 32);
  }
}

TEST(Orbit, TiltedHemisphereHeightsAreInterpolated) {
  // Cameras at two heights on alternate sides: the fitted height varies
  // smoothly within the observed range.
  std::vector<core::Camera> cams;
  for (int i = 0; i < 16; ++i) {
    double t = 2 * M_PI * i / 16;
    double h = 1.0 + 0.5 * std::cos(t);
    cams.push_back(camera_at({3 * std::cos(t), 3 * std::sin(t), h}, {0, 0, 0}, {0, 0, 1}));
  }
  std::vector<core::Camera> path = orbit_cameras(cams, 8);
  double lo = 1e9, hi = -1e9;
  for (const auto& cam : path) {
    lo = std::min(lo, cam.center().z);
    hi = std::max(hi, cam.center().z);
  }
  EXPECT_GT(hi - lo, 0.5);
  EXPECT_GE(lo, 0.5 - 1e-6);
  EXPECT_LE(hi, 1.5 + 1e-6);
}

TEST(Orbit, TripodArcStaysFinite) {
  // A narrow arc 2 m away (a tripod moved sideways): no NaN, radius kept in range.
  std::vector<core::Camera> cams;
  for (int i = 0; i < 5; ++i)
    cams.push_back(camera_at({0.05 * i, -2.0, 0.3}, {0, 0, 0}, {0, 0, 1}));
  std::vector<core::Camera> path = orbit_cameras(cams, 6);
  for (const auto& cam : path) {
    Vec3 c = cam.center();
    ASSERT_TRUE(std::isfinite(c.x) && std::isfinite(c.y) && std::isfinite(c.z));
    double r = std::hypot(c.x, c.y);
    EXPECT_GT(r, 1.9);
    EXPECT_LT(r, 2.1);
  }
}

TEST(Orbit, SingleCameraAndBadInput) {
  std::vector<core::Camera> one = {camera_at({0, -3, 0}, {0, 0, 0}, {0, 0, 1})};
  std::vector<core::Camera> path = orbit_cameras(one, 4);
  ASSERT_EQ(path.size(), 4u);
  for (const auto& cam : path) EXPECT_TRUE(std::isfinite(cam.center().norm()));
  EXPECT_THROW(orbit_cameras({}, 4), core::Error);
  EXPECT_THROW(orbit_cameras(one, 0), core::Error);
}

}  // namespace
}  // namespace ddhgs::eval
