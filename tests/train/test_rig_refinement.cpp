// Rig refinement: moving the Gaussians for a band camera's view is what the
// corrected band camera sees, the reference camera's views stay put, the
// gradients match finite differences, a known rotation and offset of a
// band camera are recovered by rendering, and with a pivot a turn alone
// keeps the point at the pivot's depth where it was, which lets a turn whose
// image shift an offset cancels converge; an earlier run's corrections are
// taken up as they were found.
#include <gtest/gtest.h>

#include <torch/optim/adam.h>
#include <map>
#include <memory>

#include "core/error.h"
#include "io/rig/rig_capture.h"
#include "model/densify.h"
#include "model/gaussian_fixtures.h"
#include "model/gaussians.h"
#include "train/rig_refinement.h"

namespace ddhgs::train {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180;

// A rig of three cameras (2 is the reference) seen in `captures` captures
// around the origin; views in capture order, cameras 1, 2, 3 each.
std::unique_ptr<io::Scene> rig_scene(int captures) {
  auto made = std::make_unique<io::Scene>();
  io::Scene& scene = *made;
  scene.root = "rig";
  io::TransformsRig rig;
  rig.reference_camera = 2;
  rig.unit_m = 1;
  rig.cameras = {
      {1, "Blue", {0.4, -0.3, 0.2}}, {2, "NIR", {0, 0, 0}}, {3, "Red", {-0.5, 0.6, 0.1}}};
  scene.rig = rig;
  for (int c = 0; c < captures; ++c) {
    const double a = 2 * 3.14159265358979323846 * c / captures;
    core::Camera reference;
    reference.intrinsics = {90, 90, 32, 28, 64, 56};
    reference.world_to_camera =
        core::look_at({4 * std::cos(a), 4 * std::sin(a), 1.0 + 0.3 * c}, {0, 0, 0}, {0, 0, 1});
    for (int k = 1; k <= 3; ++k) {
      io::View v;
      v.name = "IMG_" + std::to_string(c) + "_" + std::to_string(k);
      v.rig_camera = k;
      v.camera = reference;
      v.camera.world_to_camera = core::Mat4::from(rig.turn(k), {}) * reference.world_to_camera;
      scene.views.push_back(v);
      scene.train.push_back(int(scene.views.size()) - 1);
    }
  }
  return made;
}

core::Vec3 row_vec(const torch::Tensor& t, int64_t g) {
  return {t[g][0].item<double>(), t[g][1].item<double>(), t[g][2].item<double>()};
}

TEST(RigRefinement, MovedGaussiansSeenByTheViewAreTheGaussiansSeenByTheCorrectedCamera) {
  const std::unique_ptr<io::Scene> made = rig_scene(2);
  const io::Scene& scene = *made;
  RigRefinement rig(scene);
  ASSERT_EQ(rig->rotation.size(0), 2);  // cameras 1 and 3
  torch::NoGradGuard no_grad;
  rig->rotation[1] = torch::tensor({0.01f, -0.02f, 0.015f});
  rig->offset[1] = torch::tensor({0.03f, -0.02f, 0.01f});
  const double extent = 2.5;
  const int view = 5;  // capture 1, camera 3
  const core::Camera& camera = scene.views[view].camera;
  const core::Camera corrected = rig->corrected(view, camera, extent);
  // The corrected camera is the factory placement turned by D and moved by o.
  const core::Vec3 o = row_vec(rig->offset, 1) * extent;
  const core::Camera& reference = scene.views[4].camera;
  const core::Vec3 expected_centre =
      reference.center() + reference.world_to_camera.rotation().transposed() * o;
  EXPECT_NEAR((corrected.center() - expected_centre).norm(), 0, 1e-9);

  const torch::Tensor means = torch::randn({6, 3}) * 0.7;
  const torch::Tensor quats = torch::randn({6, 4});
  const auto [moved, moved_quats] = rig->move(view, camera, means, quats, extent);
  for (int64_t g = 0; g < 6; ++g) {
    const core::Vec3 seen = camera.world_to_camera.transform_point(row_vec(moved, g));
    const core::Vec3 want = corrected.world_to_camera.transform_point(row_vec(means, g));
    EXPECT_NEAR((seen - want).norm(), 0, 2e-5) << g;
  }
  // Orientations: the moved Gaussian in the view's axes is the Gaussian in
  // the corrected camera's.
  auto to_tensor = [](const core::Mat3& m) {
    return torch::tensor(std::vector<double>(m.m.begin(), m.m.end()))
        .view({3, 3})
        .to(torch::kFloat);
  };
  const torch::Tensor seen = torch::matmul(to_tensor(camera.world_to_camera.rotation()),
                                           model::quat_to_matrix(moved_quats));
  const torch::Tensor want =
      torch::matmul(to_tensor(corrected.world_to_camera.rotation()), model::quat_to_matrix(quats));
  EXPECT_TRUE(torch::allclose(seen, want, 0, 1e-5));

  // The reference camera's views are not moved.
  const auto [same, same_quats] = rig->move(4, reference, means, quats, extent);
  EXPECT_TRUE(torch::equal(same, means));
  EXPECT_TRUE(torch::equal(same_quats, quats));
}

TEST(RigRefinement, GradientsMatchFiniteDifferences) {
  const std::unique_ptr<io::Scene> made = rig_scene(2);
  const io::Scene& scene = *made;
  RigRefinement rig(scene);
  rig->to(torch::kFloat64);
  {
    torch::NoGradGuard no_grad;
    rig->rotation.copy_(torch::randn({2, 3}, torch::kFloat64) * 0.02);
    rig->offset.copy_(torch::randn({2, 3}, torch::kFloat64) * 0.02);
  }
  const torch::Tensor means = torch::randn({5, 3}, torch::kFloat64);
  const torch::Tensor quats = torch::randn({5, 4}, torch::kFloat64);
  const torch::Tensor weights = torch::randn({5, 3}, torch::kFloat64);
  const torch::Tensor qweights = torch::randn({5, 4}, torch::kFloat64);
  auto loss = [&] {
    const auto [m, q] = rig->move(3, scene.views[3].camera, means, quats, 1.7);
    return (m * weights).sum() + (q * qweights).sum() + rig->pull(0.3, 1.7);
  };
  loss().backward();
  const double h = 1e-6;
  for (torch::Tensor* p : {&rig->rotation, &rig->offset}) {
    const torch::Tensor grad = p->grad().clone();
    for (int r = 0; r < 2; ++r)
      for (int k = 0; k < 3; ++k) {
        torch::NoGradGuard no_grad;
        const double x = (*p)[r][k].item<double>();
        (*p)[r][k] = x + h;
        const double up = loss().item<double>();
        (*p)[r][k] = x - h;
        const double down = loss().item<double>();
        (*p)[r][k] = x;
        EXPECT_NEAR(grad[r][k].item<double>(), (up - down) / (2 * h), 1e-5) << r << "," << k;
      }
  }
}

TEST(RigRefinement, RecoversAKnownRotationAndOffsetByRendering) {
  // Camera 3's true pose is turned by a degree and moved by 0.15 units from
  // its factory placement; camera 1's is the factory's. Fitting the
  // corrections (Gaussians frozen) to renders from the true cameras finds
  // both.
  const std::unique_ptr<io::Scene> made = rig_scene(4);
  const io::Scene& scene = *made;
  const model::Gaussians blobs = test::blob_scene(80, 7);
  const torch::Tensor background = torch::zeros({3});
  const io::RigCorrection truth{{0.6 * kDeg, -0.7 * kDeg, 0.3 * kDeg}, {0.1, -0.08, 0.07}};
  const core::Mat3 turn3 = scene.rig->turn(3);
  std::vector<torch::Tensor> targets;
  for (size_t v = 0; v < scene.views.size(); ++v) {
    core::Camera camera = scene.views[v].camera;
    if (scene.views[v].rig_camera == 3) camera = io::corrected_band_camera(camera, turn3, truth);
    targets.push_back(model::render_gaussians(blobs, camera, background).image.detach());
  }
  RigRefinement rig(scene);
  torch::optim::Adam adam({rig->rotation, rig->offset}, torch::optim::AdamOptions(1e-3));
  const double extent = 1.0;
  for (int step = 0; step < 400; ++step) {
    adam.zero_grad();
    torch::Tensor loss = rig->pull(1e-4, extent);
    for (size_t v = 0; v < scene.views.size(); ++v) {
      if (scene.views[v].rig_camera == 2) continue;
      model::Gaussians g = blobs;
      std::tie(g.means, g.quats) =
          rig->move(int(v), scene.views[v].camera, blobs.means, blobs.quats, extent);
      loss =
          loss + (model::render_gaussians(g, scene.views[v].camera, background).image - targets[v])
                     .abs()
                     .mean();
    }
    loss.backward();
    adam.step();
  }
  const std::map<int, io::RigCorrection> found = rig->corrections(extent);
  const core::Vec3 rotation_error = found.at(3).rotation_rad - truth.rotation_rad;
  const core::Vec3 offset_error = found.at(3).offset - truth.offset;
  EXPECT_LT(rotation_error.norm() / kDeg, 0.1) << "of " << truth.rotation_rad.norm() / kDeg;
  EXPECT_LT(offset_error.norm(), 0.02) << "of " << truth.offset.norm();
  EXPECT_LT(found.at(1).rotation_rad.norm() / kDeg, 0.05);
  EXPECT_LT(found.at(1).offset.norm(), 0.01);
}

TEST(RigRefinement, APivotTurnKeepsThePointAtItsDepthAndReportsTheOffsetItImplies) {
  const std::unique_ptr<io::Scene> made = rig_scene(2);
  const io::Scene& scene = *made;
  const double depth = 4.0, extent = 2.5;
  RigRefinement rig(scene, depth);
  torch::NoGradGuard no_grad;
  const io::RigCorrection turn{{0.01, -0.02, 0.005}, {}};
  rig->rotation[1] = torch::tensor({0.01f, -0.02f, 0.005f});
  const int view = 5;  // capture 1, camera 3
  const core::Camera& camera = scene.views[view].camera;
  const core::Camera& reference = scene.views[4].camera;
  // The point 4 units ahead of the reference camera: the corrected camera
  // sees it where the factory placement does; about its centre it moves.
  const core::Vec3 ahead = reference.center() + reference.world_to_camera.rotation().transposed() *
                                                    core::Vec3{0, 0, depth};
  const core::Camera corrected = rig->corrected(view, camera, extent);
  const core::Vec3 factory = camera.world_to_camera.transform_point(ahead);
  EXPECT_NEAR((corrected.world_to_camera.transform_point(ahead) - factory).norm(), 0, 1e-5);
  const core::Mat3 turn3 = scene.rig->turn(3);
  const core::Camera about_centre = io::corrected_band_camera(camera, turn3, turn);
  EXPECT_GT((about_centre.world_to_camera.transform_point(ahead) - factory).norm(), 0.05);
  // The offset reported (and applied) is (I - D^T) p, about depth (r_y,
  // -r_x, 0) for a small turn.
  const core::Vec3 p{0, 0, depth};
  const core::Vec3 implied = p - io::rotation_from_vector(turn.rotation_rad).transposed() * p;
  const io::RigCorrection found = rig->corrections(extent).at(3);
  EXPECT_NEAR((found.offset - implied).norm(), 0, 1e-5);
  EXPECT_NEAR(implied.x, depth * -0.02, 1e-3);
  EXPECT_NEAR(implied.y, depth * -0.01, 1e-3);
  // move() and corrected() agree with the pivot too.
  const torch::Tensor means = torch::randn({6, 3}) * 0.7;
  const torch::Tensor quats = torch::randn({6, 4});
  const torch::Tensor moved = rig->move(view, camera, means, quats, extent).first;
  for (int64_t g = 0; g < 6; ++g) {
    const core::Vec3 seen = camera.world_to_camera.transform_point(row_vec(moved, g));
    const core::Vec3 want = corrected.world_to_camera.transform_point(row_vec(means, g));
    EXPECT_NEAR((seen - want).norm(), 0, 2e-5) << g;
  }
}

TEST(RigRefinement, ATurnAnOffsetHidesConvergesAboutThePivotNotAboutTheCentre) {
  // Camera 3 is turned by a degree and moved sideways by the scene's
  // distance times it, so that at that distance the image barely moves and
  // only the blobs' depth spread tells the turn from the offset (the
  // ambiguity of a rig seen from a few metres). Fitting the corrections
  // (Gaussians frozen) for the same number of steps finds it about the
  // pivot, and not about the camera's centre.
  const std::unique_ptr<io::Scene> made = rig_scene(4);
  const io::Scene& scene = *made;
  const model::Gaussians blobs = test::blob_scene(80, 7);
  const torch::Tensor background = torch::zeros({3});
  const double depth = 4.0;  // the cameras' distance from the origin
  const core::Vec3 r{0.8 * kDeg, -0.6 * kDeg, 0.2 * kDeg};
  const io::RigCorrection truth{r, core::Vec3{r.y, -r.x, 0} * depth + core::Vec3{0.01, 0.0, 0.0}};
  const core::Mat3 turn3 = scene.rig->turn(3);
  std::vector<torch::Tensor> targets;
  for (size_t v = 0; v < scene.views.size(); ++v) {
    core::Camera camera = scene.views[v].camera;
    if (scene.views[v].rig_camera == 3) camera = io::corrected_band_camera(camera, turn3, truth);
    targets.push_back(model::render_gaussians(blobs, camera, background).image.detach());
  }
  auto rotation_error_deg = [&](double pivot) {
    RigRefinement rig(scene, pivot);
    torch::optim::Adam adam({rig->rotation, rig->offset}, torch::optim::AdamOptions(1e-3));
    for (int step = 0; step < 150; ++step) {
      adam.zero_grad();
      torch::Tensor loss = torch::zeros({});
      for (size_t v = 0; v < scene.views.size(); ++v) {
        if (scene.views[v].rig_camera != 3) continue;
        model::Gaussians g = blobs;
        std::tie(g.means, g.quats) =
            rig->move(int(v), scene.views[v].camera, blobs.means, blobs.quats, 1.0);
        loss = loss +
               (model::render_gaussians(g, scene.views[v].camera, background).image - targets[v])
                   .abs()
                   .mean();
      }
      loss.backward();
      adam.step();
    }
    return (rig->corrections(1.0).at(3).rotation_rad - truth.rotation_rad).norm() / kDeg;
  };
  const double about_pivot = rotation_error_deg(depth), about_centre = rotation_error_deg(0);
  EXPECT_LT(about_pivot, 0.1) << "about the centre: " << about_centre;
  EXPECT_GT(about_centre, 2 * about_pivot);
}

TEST(RigRefinement, StartsFromAnEarlierRunsCorrectionsWithOrWithoutAPivot) {
  const std::unique_ptr<io::Scene> made = rig_scene(2);
  const io::Scene& scene = *made;
  const double extent = 2.5;
  // As an earlier run's rig_corrections.json gives them (scene units).
  const std::map<int, io::RigCorrection> start{{3, {{0.01, -0.02, 0.004}, {0.03, -0.05, 0.02}}}};
  for (const double depth : {0.0, 4.0}) {
    RigRefinement rig(scene, depth);
    rig->start_from(start, extent, "earlier/rig_corrections.json");
    const std::map<int, io::RigCorrection> found = rig->corrections(extent);
    EXPECT_NEAR((found.at(3).rotation_rad - start.at(3).rotation_rad).norm(), 0, 1e-7) << depth;
    EXPECT_NEAR((found.at(3).offset - start.at(3).offset).norm(), 0, 1e-6) << depth;
    // Camera 1, which the file leaves out, keeps the factory values.
    EXPECT_NEAR(found.at(1).rotation_rad.norm() + found.at(1).offset.norm(), 0, 1e-12) << depth;
    // The corrected camera is the one the file describes.
    const int view = 5;  // capture 1, camera 3
    const core::Camera& camera = scene.views[view].camera;
    const core::Camera want = io::corrected_band_camera(camera, scene.rig->turn(3), start.at(3));
    const core::Camera got = rig->corrected(view, camera, extent);
    const core::Vec3 x{0.3, -0.2, 0.5};
    EXPECT_NEAR(
        (got.world_to_camera.transform_point(x) - want.world_to_camera.transform_point(x)).norm(),
        0, 1e-6)
        << depth;
  }
  // The reference camera (2) and cameras the rig lacks have no correction.
  RigRefinement rig(scene, 0);
  for (const int camera : {2, 7}) {
    try {
      rig->start_from({{camera, {}}}, extent, "earlier/rig_corrections.json");
      ADD_FAILURE() << camera;
    } catch (const core::Error& e) {
      EXPECT_NE(std::string(e.what()).find("earlier/rig_corrections.json"), std::string::npos);
      EXPECT_NE(std::string(e.what()).find("rig camera " + std::to_string(camera)),
                std::string::npos);
    }
  }
}

}  // namespace
}  // namespace ddhgs::train
