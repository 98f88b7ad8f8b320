// io::view_spacing: angles between viewing directions, against hand-computed
// values for cameras placed on a ring at known azimuths.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "io/scene/scene_report.h"

namespace ddhgs::io {
namespace {

// A camera 4 units from the origin at `azimuth_deg` in the xz plane, raised
// by `elevation_deg`, looking at the origin.
View ring_view(double azimuth_deg, double elevation_deg = 0) {
  const double a = azimuth_deg * M_PI / 180, e = elevation_deg * M_PI / 180;
  const core::Vec3 eye{4 * std::cos(e) * std::cos(a), 4 * std::sin(e),
                       4 * std::cos(e) * std::sin(a)};
  View v;
  v.camera.intrinsics = {100, 100, 32, 24, 64, 48};
  v.camera.world_to_camera = core::look_at(eye, {0, 0, 0}, {0, 1, 0});
  return v;
}

void ring(Scene& scene, const std::vector<double>& azimuths, const std::vector<int>& test) {
  for (size_t i = 0; i < azimuths.size(); ++i) {
    scene.views.push_back(ring_view(azimuths[i]));
    if (std::find(test.begin(), test.end(), int(i)) != test.end())
      scene.test.push_back(int(i));
    else
      scene.train.push_back(int(i));
  }
}

TEST(ViewSpacing, UnevenRingMatchesHandComputedAngles) {
  // Training views at 0, 10, 25 and 45 degrees; test views at 5 and 300.
  Scene scene;
  ring(scene, {0, 10, 5, 25, 45, 300}, {2, 5});
  ViewSpacing s = view_spacing(scene);
  const std::vector<double> train = {10, 10, 15, 20}, test = {5, 60};
  ASSERT_EQ(s.train_nearest_deg.size(), train.size());
  for (size_t i = 0; i < train.size(); ++i) EXPECT_NEAR(s.train_nearest_deg[i], train[i], 1e-9);
  ASSERT_EQ(s.test_nearest_deg.size(), test.size());
  for (size_t i = 0; i < test.size(); ++i) EXPECT_NEAR(s.test_nearest_deg[i], test[i], 1e-9);
}

TEST(ViewSpacing, TwoRingsSeeTheElevationGap) {
  // One view above another at the same azimuth: 14 degrees apart, as Basil's
  // two turntable rings are; a ring neighbour 30 degrees away is farther.
  Scene scene;
  scene.views = {ring_view(0, 0), ring_view(0, 14), ring_view(30, 0)};
  scene.train = {0, 1, 2};
  ViewSpacing s = view_spacing(scene);
  ASSERT_EQ(s.train_nearest_deg.size(), 3u);
  EXPECT_NEAR(s.train_nearest_deg[0], 14, 1e-9);
  EXPECT_NEAR(s.train_nearest_deg[1], 14, 1e-9);
  EXPECT_NEAR(s.train_nearest_deg[2], 30, 1e-9);
  EXPECT_TRUE(s.test_nearest_deg.empty());
}

TEST(ViewSpacing, DegreeRangeIsTheSmallestAndLargestToOneDecimal) {
  EXPECT_EQ(degree_range({14.96, 13.34, 14.0}), "13.3-15.0");
  EXPECT_EQ(degree_range({1.7}), "1.7-1.7");
  EXPECT_EQ(degree_range({}), "");
}

TEST(ViewSpacing, TooFewViewsGiveEmptyLists) {
  Scene one, only_test;
  ring(one, {0}, {});
  EXPECT_TRUE(view_spacing(one).train_nearest_deg.empty());
  ring(only_test, {0, 10}, {0, 1});
  ViewSpacing s = view_spacing(only_test);
  EXPECT_TRUE(s.train_nearest_deg.empty());
  EXPECT_TRUE(s.test_nearest_deg.empty());
}

}  // namespace
}  // namespace ddhgs::io
