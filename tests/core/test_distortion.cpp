// Lens models: distort/undistort round trips for every model COLMAP and
// nerfstudio files use, the Jacobian against finite differences, and the
// pinhole camera a distorted view is undistorted to.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "core/distortion.h"
#include "core/error.h"

namespace ddhgs::core {
namespace {

Intrinsics camera_640x480() {
  Intrinsics k;
  k.width = 640;
  k.height = 480;
  k.fx = 520;
  k.fy = 510;
  k.cx = 322.5;
  k.cy = 238.0;
  return k;
}

struct NamedLens {
  std::string name;
  Intrinsics lens;
};

// One lens per model family, with coefficients of the size real calibrations have.
std::vector<NamedLens> lenses() {
  std::vector<NamedLens> out;
  Intrinsics k = camera_640x480();
  k.k1 = -0.12;  // SIMPLE_RADIAL
  out.push_back({"SIMPLE_RADIAL barrel", k});
  k.k1 = 0.09;
  out.push_back({"SIMPLE_RADIAL pincushion", k});
  k.k1 = -0.2;
  k.k2 = 0.05;  // RADIAL
  out.push_back({"RADIAL", k});
  k.p1 = 0.0013;
  k.p2 = -0.0021;  // OPENCV
  out.push_back({"OPENCV", k});
  k.k3 = -0.01;  // FULL_OPENCV without rational terms
  out.push_back({"FULL_OPENCV", k});
  k.k4 = 0.002;  // nerfstudio's r^8 term
  out.push_back({"nerfstudio OPENCV k4", k});
  Intrinsics f = camera_640x480();
  f.fisheye = true;
  f.k1 = 0.05;
  f.k2 = -0.01;
  f.k3 = 0.003;
  f.k4 = -0.0005;
  out.push_back({"OPENCV_FISHEYE", f});
  f.k2 = f.k3 = f.k4 = 0;
  out.push_back({"SIMPLE_RADIAL_FISHEYE", f});
  return out;
}

// Random normalised points over the frame of the camera (and a little beyond).
std::vector<Point2> frame_points(const Intrinsics& k, int count, double margin) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-margin, k.width + margin),
      v(-margin, k.height + margin);
  std::vector<Point2> out;
  for (int i = 0; i < count; ++i) out.push_back({(u(rng) - k.cx) / k.fx, (v(rng) - k.cy) / k.fy});
  out.push_back({0, 0});
  return out;
}

TEST(Distortion, UndistortInvertsDistortForEveryModel) {
  for (const auto& [name, lens] : lenses()) {
    for (const Point2& p : frame_points(lens, 400, 20)) {
      Point2 d = distort(lens, p);
      Point2 back = undistort(lens, d);
      EXPECT_NEAR(back.x, p.x, 1e-10) << name;
      EXPECT_NEAR(back.y, p.y, 1e-10) << name;
    }
    // And the other way round: distorted pixels of the frame.
    for (const Point2& d : frame_points(lens, 200, 0)) {
      Point2 p = undistort(lens, d);
      Point2 again = distort(lens, p);
      EXPECT_NEAR(again.x, d.x, 1e-11) << name;
      EXPECT_NEAR(again.y, d.y, 1e-11) << name;
    }
  }
}

TEST(Distortion, ModelsMatchTheirClosedForms) {
  // OPENCV at one point, written out by hand.
  Intrinsics k = camera_640x480();
  k.k1 = -0.2, k.k2 = 0.05, k.p1 = 0.001, k.p2 = -0.002;
  const double x = 0.3, y = -0.2, r2 = x * x + y * y, radial = 1 - 0.2 * r2 + 0.05 * r2 * r2;
  Point2 d = distort(k, {x, y});
  EXPECT_NEAR(d.x, x * radial + 2 * 0.001 * x * y - 0.002 * (r2 + 2 * x * x), 1e-15);
  EXPECT_NEAR(d.y, y * radial + 0.001 * (r2 + 2 * y * y) + 2 * -0.002 * x * y, 1e-15);

  // Equidistant fisheye without coefficients: the distorted radius is the angle.
  Intrinsics f = camera_640x480();
  f.fisheye = true;
  Point2 e = distort(f, {0.6, 0.8});  // r = 1: 45 degrees
  EXPECT_NEAR(std::hypot(e.x, e.y), std::atan(1.0), 1e-15);
  EXPECT_NEAR(e.x / e.y, 0.75, 1e-15);

  Intrinsics pinhole = camera_640x480();
  EXPECT_FALSE(pinhole.has_distortion());
  Point2 same = distort(pinhole, {0.4, -0.1});
  EXPECT_EQ(same.x, 0.4);
  EXPECT_EQ(same.y, -0.1);
}

TEST(Distortion, JacobianMatchesFiniteDifferences) {
  const double h = 1e-6;
  for (const auto& [name, lens] : lenses())
    for (const Point2& p : frame_points(lens, 50, 0)) {
      Point2 xp = distort(lens, {p.x + h, p.y}), xm = distort(lens, {p.x - h, p.y});
      Point2 yp = distort(lens, {p.x, p.y + h}), ym = distort(lens, {p.x, p.y - h});
      double jxx = (xp.x - xm.x) / (2 * h), jyx = (xp.y - xm.y) / (2 * h);
      double jxy = (yp.x - ym.x) / (2 * h), jyy = (yp.y - ym.y) / (2 * h);
      std::array<double, 4> j = distortion_jacobian(lens, p);
      EXPECT_NEAR(j[0], jxx, 1e-7) << name;
      EXPECT_NEAR(j[1], jxy, 1e-7) << name;
      EXPECT_NEAR(j[2], jyx, 1e-7) << name;
      EXPECT_NEAR(j[3], jyy, 1e-7) << name;
    }
}

TEST(Distortion, UndistortRefusesPointsBeyondTheFold) {
  // x (1 - 0.5 x^2) peaks at x = 0.816, value 0.544: nothing distorts further.
  Intrinsics k = camera_640x480();
  k.k1 = -0.5;
  EXPECT_THROW(undistort(k, {0.6, 0}), Error);
  EXPECT_NO_THROW(undistort(k, {0.5, 0}));
}

// Every output pixel centre of the pinhole camera, distorted, lands inside
// the source frame's outermost pixel centres.
double worst_overshoot_px(const Intrinsics& lens, const Intrinsics& pinhole) {
  double worst = -1e9;
  for (int j = 0; j < pinhole.height; ++j)
    for (int i = 0; i < pinhole.width; ++i) {
      Point2 n{(i + 0.5 - pinhole.cx) / pinhole.fx, (j + 0.5 - pinhole.cy) / pinhole.fy};
      Point2 d = distort(lens, n);
      double x = lens.fx * d.x + lens.cx, y = lens.fy * d.y + lens.cy;
      worst = std::max({worst, 0.5 - x, x - (lens.width - 0.5), 0.5 - y, y - (lens.height - 0.5)});
    }
  return worst;
}

TEST(Distortion, PinholeCameraHasNoBlankPixelsAndIsTight) {
  for (const auto& [name, lens] : lenses()) {
    Intrinsics pinhole = undistorted_pinhole(lens);
    EXPECT_FALSE(pinhole.has_distortion()) << name;
    EXPECT_EQ(pinhole.width, lens.width);
    EXPECT_EQ(pinhole.height, lens.height);
    EXPECT_EQ(pinhole.cx, lens.cx);
    EXPECT_EQ(pinhole.cy, lens.cy);
    EXPECT_NEAR(pinhole.fx / lens.fx, pinhole.fy / lens.fy, 1e-12) << name;
    EXPECT_LE(worst_overshoot_px(lens, pinhole), 1e-6) << name;
    // Tight: 0.1 % wider and some output pixel would be blank.
    Intrinsics wider = pinhole;
    wider.fx *= 0.999;
    wider.fy *= 0.999;
    EXPECT_GT(worst_overshoot_px(lens, wider), 0) << name;
  }
  // Barrel distortion widens the view, pincushion narrows it.
  EXPECT_LT(undistorted_pinhole(lenses()[0].lens).fx, lenses()[0].lens.fx);
  EXPECT_GT(undistorted_pinhole(lenses()[1].lens).fx, lenses()[1].lens.fx);

  Intrinsics pinhole = camera_640x480();
  EXPECT_TRUE(undistorted_pinhole(pinhole) == pinhole);
}

TEST(Distortion, FoldingLensIsRefused) {
  Intrinsics k = camera_640x480();
  k.k1 = -2000;  // folds over 7 pixels from the centre
  EXPECT_THROW(undistorted_pinhole(k), Error);
  k.k1 = -0.1;
  k.cx = 900;  // principal point outside the image
  EXPECT_THROW(undistorted_pinhole(k), Error);
}

}  // namespace
}  // namespace ddhgs::core
