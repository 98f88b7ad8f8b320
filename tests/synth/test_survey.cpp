#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "core/error.h"
#include "synth/generate.h"
#include "synth/render.h"
#include "synth/survey.h"

namespace ddhgs::synth {
namespace {

RigOptions survey_rig(int views) {
  RigOptions rig;
  rig.views = views;
  rig.width = 40;
  rig.height = 30;
  rig.fov_deg = 48;
  return rig;
}

// Where the ray through pixel (x, y) meets the ground z = 0.
core::Vec3 on_ground(const core::Camera& camera, double x, double y) {
  const Ray ray = camera_ray(camera, x, y);
  return ray.origin + ray.dir * (-ray.origin.z / ray.dir.z);
}

TEST(Survey, LinesAreSpacedByTheSideOverlapAndFlownBackAndForth) {
  const PlantScene scene = PlantScene::build(0, true);
  Flight flight;
  flight.lines = 3;
  flight.overlap = 0.75;
  flight.side_overlap = 0.5;
  flight.altitude_m = 6;
  const std::vector<core::Camera> cameras = nadir_survey(scene, survey_rig(12), flight);
  ASSERT_EQ(cameras.size(), 12u);
  // A frame's footprint at 6 m: its width and height on the ground.
  const double width = on_ground(cameras[0], 40, 15).x - on_ground(cameras[0], 0, 15).x;
  const double height = on_ground(cameras[0], 20, 0).y - on_ground(cameras[0], 20, 30).y;
  EXPECT_NEAR(width / height, 40.0 / 30.0, 1e-9);
  std::set<long> ys;
  for (size_t i = 0; i < cameras.size(); ++i) {
    const core::Vec3 c = cameras[i].center();
    EXPECT_NEAR(c.z, 6, 1e-9);
    EXPECT_GT(cameras[i].forward().dot(core::Vec3{0, 0, -1}), 1 - 1e-12);
    ys.insert(std::lround(c.y * 1e6));
    if (i % 4 != 3) {  // along a line: a quarter of a frame's length apart
      const core::Vec3 next = cameras[i + 1].center();
      EXPECT_NEAR(std::abs(next.x - c.x), 0.25 * width, 1e-9);
      EXPECT_NEAR(next.y, c.y, 1e-12);
    }
  }
  EXPECT_EQ(ys.size(), 3u);
  EXPECT_NEAR(cameras[4].center().y - cameras[0].center().y, 0.5 * height, 1e-9);
  // The second line flies back: it starts where the first ended.
  EXPECT_NEAR(cameras[4].center().x, cameras[3].center().x, 1e-12);
  EXPECT_LT(cameras[7].center().x, cameras[4].center().x);
}

TEST(Survey, NovelViewsLieMidwayBetweenNeighbouringCaptures) {
  const PlantScene scene = PlantScene::build(0, true);
  Flight flight;
  flight.lines = 3;
  flight.overlap = 0.75;
  flight.side_overlap = 0.5;
  const std::vector<core::Camera> cameras = nadir_survey(scene, survey_rig(12), flight);
  const std::vector<core::Camera> novel = between_captures(scene, survey_rig(12), flight);
  // (4 - 1) x (3 - 1): each the centre of four neighbouring captures, two
  // on one line and two on the next (line 1 is flown back: index 7 - i).
  ASSERT_EQ(novel.size(), 6u);
  for (int gap = 0; gap < 2; ++gap)
    for (int i = 0; i < 3; ++i) {
      auto at = [&](int line, int k) {  // the capture at grid position k of line
        return cameras[size_t(4 * line + (line % 2 == 0 ? k : 3 - k))].center();
      };
      const core::Vec3 mid =
          (at(gap, i) + at(gap, i + 1) + at(gap + 1, i) + at(gap + 1, i + 1)) * 0.25;
      const core::Camera& c = novel[size_t(3 * gap + i)];
      EXPECT_LT((c.center() - mid).norm(), 1e-9) << gap << " " << i;
      // Same lens and heading as the flight's captures.
      for (int k = 0; k < 9; ++k)
        EXPECT_NEAR(c.world_to_camera.rotation().m[k], cameras[0].world_to_camera.rotation().m[k],
                    1e-12);
      EXPECT_EQ(c.intrinsics.fx, cameras[0].intrinsics.fx);
    }
  // One line: midway between neighbours along it.
  flight.lines = 1;
  const std::vector<core::Camera> strip = nadir_survey(scene, survey_rig(5), flight);
  const std::vector<core::Camera> between = between_captures(scene, survey_rig(5), flight);
  ASSERT_EQ(between.size(), 4u);
  for (size_t i = 0; i < between.size(); ++i)
    EXPECT_LT((between[i].center() - (strip[i].center() + strip[i + 1].center()) * 0.5).norm(),
              1e-9);
}

TEST(Survey, FieldCoversEveryFootprintWithPlantsAndGround) {
  PlantScene scene = PlantScene::build(0, true);
  Flight flight;
  flight.lines = 2;
  const std::vector<core::Camera> cameras = nadir_survey(scene, survey_rig(10), flight);
  plant_field(scene, cameras, 1.5, 7);
  EXPECT_GT(scene.plants.size(), 6u);
  for (const core::Camera& camera : cameras)
    for (const double x : {0.0, 40.0})
      for (const double y : {0.0, 30.0}) {
        // Every frame corner sees the field, not the backdrop.
        SurfaceHit hit;
        ASSERT_TRUE(scene.intersect(camera_ray(camera, x, y), &hit));
        EXPECT_LT(std::hypot(hit.point.x, hit.point.y), scene.ground_radius);
      }
  // A plant away from the origin is hit where its copy stands: a ray
  // straight down onto its top meets a leaf or stem well above the ground.
  const core::Vec3 far = scene.plants.back();
  ASSERT_GT(std::hypot(far.x, far.y), 1.0);
  int tall = 0;
  for (double d = -0.1; d <= 0.1; d += 0.05) {
    SurfaceHit hit;
    ASSERT_TRUE(scene.intersect({far + core::Vec3{d, d, 5}, {0, 0, -1}}, &hit));
    tall += hit.point.z > 0.4;
  }
  EXPECT_GE(tall, 3);
}

TEST(Survey, SynthRefusesLinesThatDoNotDivideTheCaptures) {
  SynthConfig c = preset_config("rig-nadir");
  c.views = 10;
  c.lines = 3;
  EXPECT_THROW(validate(c), core::Error);
  c.lines = 2;
  EXPECT_NO_THROW(validate(c));
  c.field_spacing_m = 1;
  EXPECT_THROW(validate(c), core::Error);
  SynthConfig ring = preset_config("rig");
  ring.lines = 2;
  EXPECT_THROW(validate(ring), core::Error);
  ring.lines = 1;
  ring.novel_views = true;  // no flight lines to fly between
  EXPECT_THROW(validate(ring), core::Error);
  c.field_spacing_m = 0;
  c.novel_views = true;  // 10 captures on 2 lines: 4 between them
  EXPECT_NO_THROW(validate(c));
  c.lines = 10;  // one capture a line: nothing lies between
  EXPECT_THROW(validate(c), core::Error);
}

}  // namespace
}  // namespace ddhgs::synth
