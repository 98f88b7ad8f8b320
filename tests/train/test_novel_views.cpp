// The geometry of the denoiser's novel-view pairs and of the distillation's
// pseudo-views (train/novel_views.h): folds, and cameras between cameras.
#include <gtest/gtest.h>

#include <cmath>

#include "core/camera.h"
#include "train/novel_views.h"

using namespace ddhgs;

namespace {

constexpr double kPi = 3.14159265358979323846;

// A camera on a ring of radius 3 at `deg` degrees, looking at the origin.
core::Camera ring_camera(double deg, double height = 0.5) {
  core::Camera c;
  c.intrinsics.width = 64;
  c.intrinsics.height = 48;
  c.intrinsics.fx = c.intrinsics.fy = 60;
  c.intrinsics.cx = 32;
  c.intrinsics.cy = 24;
  const double a = deg * kPi / 180.0;
  c.world_to_camera =
      core::look_at({3 * std::cos(a), 3 * std::sin(a), height}, {0, 0, 0}, {0, 0, 1});
  return c;
}

double rotation_angle_deg(const core::Mat3& a, const core::Mat3& b) {
  const core::Mat3 r = a.transposed() * b;
  const double c = std::clamp((r(0, 0) + r(1, 1) + r(2, 2) - 1) / 2, -1.0, 1.0);
  return std::acos(c) * 180.0 / kPi;
}

}  // namespace

TEST(NovelViews, InterleavedFoldsHoldEveryViewOnceAndKeepNeighboursApart) {
  const std::vector<int> views = {3, 5, 8, 9, 12, 20, 21};
  const auto folds = train::interleaved_folds(views, 3);
  ASSERT_EQ(folds.size(), 3u);
  EXPECT_EQ(folds[0], (std::vector<int>{3, 9, 21}));
  EXPECT_EQ(folds[1], (std::vector<int>{5, 12}));
  EXPECT_EQ(folds[2], (std::vector<int>{8, 20}));
  // More folds than views: one view each.
  EXPECT_EQ(train::interleaved_folds({1, 2}, 5).size(), 2u);
  EXPECT_EQ(train::interleaved_folds({}, 4).size(), 1u);
}

TEST(NovelViews, MidwayIsTheCameraAtTheHalfAngleOfARing) {
  // Between the cameras at 10 and 30 degrees on a ring looking at the
  // centre: the camera at 20 degrees, except that the midpoint of the two
  // centres lies on the chord (radius 3 cos 10 deg), not on the ring.
  const core::Camera a = ring_camera(10), b = ring_camera(30), expected = ring_camera(20);
  const core::Camera m = train::midway(a, b);
  const core::Vec3 c = m.center();
  const double chord = 3 * std::cos(10 * kPi / 180);
  EXPECT_NEAR(c.x, chord * std::cos(20 * kPi / 180), 1e-9);
  EXPECT_NEAR(c.y, chord * std::sin(20 * kPi / 180), 1e-9);
  EXPECT_NEAR(c.z, 0.5, 1e-9);
  // The ring cameras turn about the vertical by 20 degrees; the midway one
  // by exactly half of it from each (same tilt).
  EXPECT_NEAR(
      rotation_angle_deg(m.camera_to_world().rotation(), expected.camera_to_world().rotation()), 0,
      1e-6);
  EXPECT_NEAR(rotation_angle_deg(a.camera_to_world().rotation(), m.camera_to_world().rotation()),
              10, 1e-6);
  EXPECT_EQ(m.intrinsics.width, a.intrinsics.width);
  // Symmetric, and the midway of a camera with itself is that camera.
  const core::Camera self = train::midway(a, a);
  EXPECT_NEAR(rotation_angle_deg(self.camera_to_world().rotation(), a.camera_to_world().rotation()),
              0, 1e-6);
  EXPECT_NEAR((self.center() - a.center()).norm(), 0, 1e-12);
}

TEST(NovelViews, MidwayTakesTheShortArcWhateverTheQuaternionSigns) {
  // 170 and 190 degrees: the midway looks from 180, not from 0.
  const core::Camera m = train::midway(ring_camera(170), ring_camera(190));
  EXPECT_NEAR(rotation_angle_deg(m.camera_to_world().rotation(),
                                 ring_camera(180).camera_to_world().rotation()),
              0, 1e-6);
}

TEST(NovelViews, BetweenCamerasFillsEveryGapOfARingOnce) {
  // 12 cameras 30 degrees apart: each gap between neighbours once, nothing
  // across the ring.
  std::vector<core::Camera> ring;
  for (int i = 0; i < 12; ++i) ring.push_back(ring_camera(30.0 * i));
  const auto between = train::between_cameras(ring);
  ASSERT_EQ(between.size(), 12u);
  std::vector<bool> met(12, false);
  for (const core::Camera& c : between) {
    const core::Vec3 p = c.center();
    double deg = std::atan2(p.y, p.x) * 180 / kPi;
    if (deg < 0) deg += 360;
    const int gap = int(std::lround((deg - 15) / 30)) % 12;
    EXPECT_NEAR(deg, 15 + 30 * gap, 1e-6);
    EXPECT_FALSE(met[size_t(gap)]) << "gap " << gap << " twice";
    met[size_t(gap)] = true;
  }
  EXPECT_TRUE(train::between_cameras({ring[0]}).empty());
  EXPECT_EQ(train::between_cameras({ring[0], ring[1]}).size(), 1u);
}

TEST(NovelViews, TurnedKeepsTheCentreAndTurnsByTheAngleAboutASeededAxis) {
  const core::Camera c = ring_camera(30);
  const core::Camera a = train::turned(c, 2.0, 7), b = train::turned(c, 2.0, 8);
  EXPECT_NEAR(rotation_angle_deg(c.camera_to_world().rotation(), a.camera_to_world().rotation()),
              2.0, 1e-9);
  EXPECT_LT((a.center() - c.center()).norm(), 1e-12);
  EXPECT_EQ(a.intrinsics.fx, c.intrinsics.fx);
  // The same seed, the same turn; another seed, another axis (so the two
  // turned cameras differ from each other by more than nothing).
  const core::Camera again = train::turned(c, 2.0, 7);
  EXPECT_EQ(a.world_to_camera(0, 1), again.world_to_camera(0, 1));
  EXPECT_EQ(a.world_to_camera(2, 0), again.world_to_camera(2, 0));
  EXPECT_GT(rotation_angle_deg(a.camera_to_world().rotation(), b.camera_to_world().rotation()),
            0.1);
  // Zero degrees: the camera itself.
  EXPECT_NEAR(rotation_angle_deg(c.camera_to_world().rotation(),
                                 train::turned(c, 0.0, 7).camera_to_world().rotation()),
              0.0, 1e-6);
}
