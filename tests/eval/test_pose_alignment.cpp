// Pose alignment before measuring (eval/pose_alignment.h): a view rendered
// from a known pose error is matched again and the image motion found is the
// error's; a view whose pose is right keeps it; no steps, no change.
#include <gtest/gtest.h>

#include <cmath>

#include "core/tensor.h"
#include "eval/metrics.h"
#include "eval/pose_alignment.h"
#include "model/gaussian_fixtures.h"
#include "model/gaussians.h"

namespace ddhgs::eval {
namespace {

core::Camera recorded_camera() {
  core::Camera camera;
  camera.intrinsics = {90, 90, 32, 28, 64, 56};
  camera.world_to_camera = core::look_at({4.0, 0.5, 0.8}, {0, 0, 0}, {0, 0, 1});
  return camera;
}

// The camera that took the picture: turned by 0.03 rad about its vertical
// axis and stepped sideways by 0.03, so the image moves by about 2 px.
core::Camera true_camera() {
  core::Camera camera = recorded_camera();
  const core::Mat3 r = camera.world_to_camera.rotation();
  const double a = 0.03;
  core::Mat3 turn;  // about the camera's y axis
  turn(0, 0) = std::cos(a), turn(0, 2) = std::sin(a);
  turn(2, 0) = -std::sin(a), turn(2, 2) = std::cos(a);
  const core::Mat3 turned = turn * r;
  const core::Vec3 centre = camera.center() + r.transposed() * core::Vec3{0.03, 0.0, 0.0};
  camera.world_to_camera = core::Mat4::from(turned, (turned * centre) * -1.0);
  return camera;
}

// Mean image displacement of the blob centres between two cameras.
double mean_motion_px(const torch::Tensor& means, const core::Camera& a, const core::Camera& b) {
  double sum = 0;
  for (int64_t g = 0; g < means.size(0); ++g) {
    const core::Vec3 x{means[g][0].item<double>(), means[g][1].item<double>(),
                       means[g][2].item<double>()};
    const core::Vec3 pa = a.world_to_camera.transform_point(x);
    const core::Vec3 pb = b.world_to_camera.transform_point(x);
    const double du = a.intrinsics.fx * (pa.x / pa.z - pb.x / pb.z);
    const double dv = a.intrinsics.fy * (pa.y / pa.z - pb.y / pb.z);
    sum += std::hypot(du, dv);
  }
  return sum / double(means.size(0));
}

TEST(PoseAlignment, RecoversAKnownPoseError) {
  const model::Gaussians scene = test::blob_scene(80, 11);
  const torch::Tensor background = torch::zeros({3});
  const core::Camera recorded = recorded_camera(), truth_camera = true_camera();
  const torch::Tensor truth =
      model::render_gaussians(scene, truth_camera, background).image.detach();
  const double expected_motion = mean_motion_px(scene.means, recorded, truth_camera);
  ASSERT_GT(expected_motion, 1.5);  // the error is worth finding

  const AlignedView a = align_view(scene, recorded, background, truth);
  ASSERT_TRUE(a.moved);
  EXPECT_LT(a.l1_after, 0.1 * a.l1_before) << a.l1_before << " -> " << a.l1_after;
  EXPECT_GT(psnr_db(a.image.clamp(0, 1), truth), 40.0);
  EXPECT_NEAR(a.motion_px, expected_motion, 0.1 * expected_motion);
  // The unaligned render is far off.
  const torch::Tensor raw = model::render_gaussians(scene, recorded, background).image.detach();
  EXPECT_LT(psnr_db(raw.clamp(0, 1), truth), 25.0);
}

TEST(PoseAlignment, ARightPoseIsKept) {
  const model::Gaussians scene = test::blob_scene(80, 11);
  const torch::Tensor background = torch::zeros({3});
  const core::Camera camera = recorded_camera();
  const torch::Tensor render = model::render_gaussians(scene, camera, background).image.detach();
  const AlignedView a = align_view(scene, camera, background, render, {50, 2.0});
  EXPECT_FALSE(a.moved);  // nothing lowers a zero difference
  EXPECT_EQ(a.motion_px, 0.0);
  EXPECT_TRUE(torch::equal(a.image, render));

  const AlignedView none = align_view(scene, camera, background, render + 0.1, {0, 2.0});
  EXPECT_FALSE(none.moved);
  EXPECT_TRUE(torch::equal(none.image, render));
  EXPECT_NEAR(none.l1_before, 0.1, 1e-6);
}

}  // namespace
}  // namespace ddhgs::eval
