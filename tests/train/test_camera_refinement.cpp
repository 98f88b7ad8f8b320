// Camera refinement: moving the Gaussians is the same as moving the camera,
// the corrections are centred over the training views, gradients match
// finite differences, and a known pose error is recovered by rendering.
#include <gtest/gtest.h>
#include <torch/optim/adam.h>

#include "model/densify.h"
#include "model/gaussian_fixtures.h"
#include "model/gaussians.h"
#include "model/rigid_motion.h"
#include "train/camera_refinement.h"

namespace ddhgs::train {
namespace {

core::Camera test_camera() {
  core::Camera camera;
  camera.intrinsics = {100, 100, 32, 24, 64, 48};
  camera.world_to_camera = core::look_at({2.0, -3.0, 1.0}, {0.1, 0.2, 0.0}, {0, 0, 1});
  return camera;
}

core::Mat3 rotation_of(const torch::Tensor& r) {  // [3] rotation vector
  const torch::Tensor m = model::quat_to_matrix(model::rotation_vector_quat(r).unsqueeze(0))[0];
  core::Mat3 out;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) out(i, j) = m[i][j].item<double>();
  return out;
}

TEST(CameraRefinement, MovedGaussiansSeenByTheCameraAreTheGaussiansSeenByTheCorrectedCamera) {
  const core::Camera camera = test_camera();
  CameraRefinement refine(4, std::vector<int>{0, 1, 2});
  torch::NoGradGuard no_grad;
  refine->rotation[1] = torch::tensor({0.01f, -0.02f, 0.015f});
  refine->translation[1] = torch::tensor({0.02f, 0.01f, -0.03f});
  const double extent = 2.5;
  const auto [r, t] = refine->correction(1);

  auto means = torch::randn({5, 3}, torch::kFloat64).to(torch::kFloat32);
  auto quats = torch::randn({5, 4}).to(torch::kFloat32);
  const auto [moved, moved_quats] = refine->move(1, camera, means, quats, extent);

  // The corrected camera: rotated by R^T about its centre, shifted by -R^T e t.
  const core::Mat3 rot = rotation_of(r);
  const core::Vec3 c = camera.center();
  const core::Vec3 shift{t[0].item<double>(), t[1].item<double>(), t[2].item<double>()};
  const core::Mat3 cam_rot = camera.world_to_camera.rotation() * rot;
  const core::Vec3 centre = c - rot.transposed() * (shift * extent);
  for (int g = 0; g < 5; ++g) {
    const core::Vec3 x{means[g][0].item<double>(), means[g][1].item<double>(),
                       means[g][2].item<double>()};
    const core::Vec3 x2{moved[g][0].item<double>(), moved[g][1].item<double>(),
                        moved[g][2].item<double>()};
    const core::Vec3 seen = camera.world_to_camera.transform_point(x2);
    const core::Vec3 corrected = cam_rot * (x - centre);
    EXPECT_NEAR((seen - corrected).norm(), 0.0, 1e-5) << g;
  }
  // Orientations turn with the same rotation.
  const auto before = model::quat_to_matrix(quats);
  const auto after = model::quat_to_matrix(moved_quats);
  torch::Tensor r_t = torch::empty({3, 3});
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r_t[i][j] = float(rot(i, j));
  EXPECT_TRUE(torch::allclose(after, torch::matmul(r_t, before), 0, 1e-5));
}

TEST(CameraRefinement, RecentreTakesOutTheTrainingViewsMeanOnly) {
  CameraRefinement refine(4, std::vector<int>{0, 2, 3});
  {
    torch::NoGradGuard no_grad;
    refine->rotation.copy_(torch::randn({4, 3}));
    refine->translation.copy_(torch::randn({4, 3}));
  }
  const torch::Tensor rotation = refine->rotation.detach().clone();
  const torch::Tensor train = torch::tensor({0, 2, 3}, torch::kInt64);
  refine->recentre();
  const torch::Tensor after = refine->rotation.detach();
  EXPECT_TRUE(torch::allclose(after.index_select(0, train).mean(0), torch::zeros({3}), 0, 1e-6));
  // Differences between training views kept; the held-out row untouched.
  EXPECT_TRUE(torch::allclose(after[2] - after[0], rotation[2] - rotation[0], 0, 1e-6));
  EXPECT_TRUE(torch::equal(after[1], rotation[1]));
  EXPECT_TRUE(torch::allclose(refine->translation.detach().index_select(0, train).mean(0),
                              torch::zeros({3}), 0, 1e-6));
}

TEST(CameraRefinement, GradientsMatchFiniteDifferences) {
  const core::Camera camera = test_camera();
  auto means = torch::randn({6, 3}, torch::kFloat64);
  auto quats = torch::randn({6, 4}, torch::kFloat64);
  auto weights = torch::randn({6, 3}, torch::kFloat64);
  auto qweights = torch::randn({6, 4}, torch::kFloat64);
  CameraRefinement refine(3, std::vector<int>{0, 1, 2});
  refine->to(torch::kFloat64);
  {
    torch::NoGradGuard no_grad;
    refine->rotation.copy_(torch::randn({3, 3}, torch::kFloat64) * 0.05);
    refine->translation.copy_(torch::randn({3, 3}, torch::kFloat64) * 0.05);
  }
  auto loss = [&] {
    const auto [m, q] = refine->move(2, camera, means, quats, 1.7);
    return (m * weights).sum() + (q * qweights).sum();
  };
  loss().backward();
  const double h = 1e-6;
  for (torch::Tensor* p : {&refine->rotation, &refine->translation}) {
    const torch::Tensor grad = p->grad().clone();
    for (int v = 0; v < 3; ++v)
      for (int k = 0; k < 3; ++k) {
        torch::NoGradGuard no_grad;
        const double x = (*p)[v][k].item<double>();
        (*p)[v][k] = x + h;
        const double up = loss().item<double>();
        (*p)[v][k] = x - h;
        const double down = loss().item<double>();
        (*p)[v][k] = x;
        EXPECT_NEAR(grad[v][k].item<double>(), (up - down) / (2 * h), 1e-5) << v << "," << k;
      }
  }
}

TEST(CameraRefinement, RecoversKnownRotationErrorsByRendering) {
  // Each recorded pose is turned about its centre by a known rotation vector
  // (the three sum to zero: a common turn of every training view is what
  // recentre() leaves to the Gaussians, frozen here); fitting the rotation
  // corrections to renders from the true poses must find those rotations.
  // Translation is left out: with a small field of view a sideways shift and
  // a turn look alike.
  const model::Gaussians scene = test::blob_scene(60, 7);
  const torch::Tensor background = torch::zeros({3});
  const torch::Tensor errors =
      torch::tensor({{-0.01, 0.015, 0.02}, {0.02, -0.03, 0.015}, {-0.01, 0.015, -0.035}},
                    torch::kFloat64);  // [3, 3] rad
  const core::Vec3 eyes[3] = {{4.0, 0.5, 0.8}, {0.5, 4.0, 0.6}, {-3.0, 2.5, 1.0}};
  std::vector<core::Camera> recorded(3);
  std::vector<torch::Tensor> targets;
  for (int v = 0; v < 3; ++v) {
    recorded[v].intrinsics = {90, 90, 32, 28, 64, 56};
    recorded[v].world_to_camera = core::look_at(eyes[v], {0, 0, 0}, {0, 0, 1});
    core::Camera truth = recorded[v];
    const core::Mat3 turned =
        recorded[v].world_to_camera.rotation() * rotation_of(errors[v].to(torch::kFloat32));
    truth.world_to_camera = core::Mat4::from(turned, (turned * recorded[v].center()) * -1.0);
    targets.push_back(model::render_gaussians(scene, truth, background).image.detach());
  }

  CameraRefinement refine(3, std::vector<int>{0, 1, 2});
  torch::optim::Adam adam({refine->rotation}, torch::optim::AdamOptions(2e-3));
  auto step_loss = [&] {
    adam.zero_grad();
    torch::Tensor loss = torch::zeros({});
    for (int v = 0; v < 3; ++v) {
      model::Gaussians g = scene;
      std::tie(g.means, g.quats) = refine->move(v, recorded[v], scene.means, scene.quats, 1.0);
      loss = loss +
             (model::render_gaussians(g, recorded[v], background).image - targets[v]).abs().mean();
    }
    loss.backward();
    adam.step();
    refine->recentre();
    return loss.item<double>();
  };
  const double first_loss = step_loss();
  double last_loss = first_loss;
  for (int step = 1; step < 300; ++step) last_loss = step_loss();
  const torch::Tensor found = refine->rotation.detach().to(torch::kFloat64);
  for (int v = 0; v < 3; ++v)
    EXPECT_LT((found[v] - errors[v]).norm().item<double>(), 0.15 * errors[v].norm().item<double>())
        << "view " << v << ": found " << found[v] << " expected " << errors[v];
  EXPECT_LT(last_loss, 0.2 * first_loss);
}

TEST(CameraRefinement, RenderedLossGradientMatchesFiniteDifferences) {
  // Through the rasterizer: the gradient the trainer uses.
  const model::Gaussians scene = test::blob_scene(60, 7);
  const torch::Tensor background = torch::zeros({3});
  core::Camera camera;
  camera.intrinsics = {90, 90, 32, 28, 64, 56};
  camera.world_to_camera = core::look_at({0.5, 4.0, 0.6}, {0, 0, 0}, {0, 0, 1});
  const torch::Tensor error = torch::tensor({0.02f, -0.03f, 0.015f});
  core::Camera truth = camera;
  const core::Mat3 turned = camera.world_to_camera.rotation() * rotation_of(error);
  truth.world_to_camera = core::Mat4::from(turned, (turned * camera.center()) * -1.0);
  const torch::Tensor target = model::render_gaussians(scene, truth, background).image.detach();
  CameraRefinement refine(2, std::vector<int>{0, 1});
  auto loss = [&] {
    model::Gaussians g = scene;
    std::tie(g.means, g.quats) = refine->move(1, camera, scene.means, scene.quats, 1.0);
    return (model::render_gaussians(g, camera, background).image - target).pow(2).sum();
  };
  const torch::Tensor at_zero = loss();
  at_zero.backward();
  const torch::Tensor grad = refine->rotation.grad()[1].clone();
  torch::NoGradGuard no_grad;
  const double h = 1e-3;
  for (int k = 0; k < 3; ++k) {
    refine->rotation[1][k] += h;
    const double up = loss().item<double>();
    refine->rotation[1][k] -= 2 * h;
    const double down = loss().item<double>();
    refine->rotation[1][k] += h;
    const double fd = (up - down) / (2 * h);
    EXPECT_NEAR(grad[k].item<double>(), fd, 0.03 * std::abs(fd) + 1.0) << k;
  }
  // The true correction renders the target exactly.
  refine->rotation[1].copy_(error);
  EXPECT_LT(loss().item<double>(), 1e-6 * at_zero.item<double>());
}

}  // namespace
}  // namespace ddhgs::train
