// Rasterizer invariants, determinism, bad input, and finite differences
// confirming the reference's gradients.
#include <gtest/gtest.h>

#include "core/error.h"
#include "core/threads.h"
#include "render/reference.h"
#include "render_fixture.h"

namespace ddhgs::test {
namespace {

using render::RenderOutput;
using torch::Tensor;

RenderOutput render_scene(const SplatScene& s, const Tensor& sink = {}) {
  return render::rasterize(s.means, s.log_scales, s.quats, s.logit_opacities, s.colors, s.camera,
                           s.background, sink);
}

// Renders with gradients; returns the image and the gradients of a fixed loss.
std::vector<Tensor> image_and_grads(const SplatScene& base) {
  const SplatScene s = base.leaves(torch::kFloat32);
  const RenderOutput out = render_scene(s);
  torch::manual_seed(77);
  (out.image * torch::randn(out.image.sizes())).sum().add(out.alpha.sum()).backward();
  std::vector<Tensor> result = {out.image.detach()};
  for (const Tensor& p : s.params()) result.push_back(p.grad());
  return result;
}

SplatScene select_rows(const SplatScene& s, const Tensor& rows) {
  SplatScene r = s;
  for (Tensor* t : {&r.means, &r.log_scales, &r.quats, &r.logit_opacities, &r.colors})
    *t = t->index_select(0, rows);
  return r;
}

TEST(Rasterize, NoGaussiansGivesTheBackground) {
  SplatScene s = random_scene(3, 20, 5, 37, 29);
  s = select_rows(s, torch::zeros({0}, torch::kLong)).leaves(torch::kFloat32);
  const RenderOutput out = render_scene(s);
  EXPECT_TRUE(torch::equal(out.image, s.background.detach().expand({29, 37, 5})));
  EXPECT_EQ(out.alpha.abs().max().item<float>(), 0.0f);
  EXPECT_EQ(out.depth.abs().max().item<float>(), 0.0f);
  out.image.sum().backward();
  EXPECT_TRUE(torch::allclose(s.background.grad(), torch::full({5}, 37.0f * 29.0f)));
}

TEST(Rasterize, OpaqueGaussianInFrontHidesOneBehind) {
  SplatScene s = random_scene(4, 20, 2, 32, 32);
  s = select_rows(s, torch::tensor({8, 9}, torch::kLong));
  const core::Camera cam = test_core_camera(32, 32);
  const core::Vec3 axis = cam.camera_to_world().rotation() * core::Vec3{0, 0, 1};
  const core::Vec3 eye = cam.center();
  auto on_axis = [&](double depth) {
    const core::Vec3 p = eye + axis * depth;
    return torch::tensor({float(p.x), float(p.y), float(p.z)});
  };
  s.means[0] = on_axis(3.0), s.means[1] = on_axis(4.0);
  s.log_scales.fill_(0.0);                              // ~10 px wide: flat near the centre
  s.logit_opacities = torch::tensor({{8.0f}, {2.0f}});  // alpha 0.99 (clamped) and 0.88
  s.colors = torch::tensor({{1.0f, 0.0f}, {0.0f, 1.0f}});
  s.background = torch::zeros({2});
  // The principal point is near the image centre, which both splats cover.
  const Tensor centre = render_scene(s).image[16][15];
  EXPECT_GT(centre[0].item<float>(), 0.985f);
  EXPECT_LT(centre[1].item<float>(), 0.0089f);  // only 1 % of it shows through
  // Swapping depths swaps which colour wins.
  s.means = torch::stack({on_axis(4.0), on_axis(3.0)});
  const Tensor swapped = render_scene(s).image[16][15];
  EXPECT_GT(swapped[1].item<float>(), 0.85f);
  EXPECT_LT(swapped[0].item<float>(), 0.13f);
}

TEST(Rasterize, GaussianBehindTheCameraContributesNothing) {
  const SplatScene s = random_scene(5, 30, 4, 40, 30);
  const Tensor rows = torch::arange(1, 30);  // row 0 is behind the camera
  const std::vector<Tensor> with = image_and_grads(s);
  const std::vector<Tensor> without = image_and_grads(select_rows(s, rows));
  EXPECT_TRUE(torch::equal(with[0], without[0]));
  EXPECT_EQ(render_scene(s).radii[0].item<int>(), 0);
  EXPECT_EQ(with[1][0].abs().sum().item<float>(), 0.0f);  // no gradient to its mean
}

TEST(Rasterize, InputOrderDoesNotMatter) {
  const SplatScene s = random_scene(6, 50, 7, 48, 40);
  torch::manual_seed(9);
  const Tensor perm = torch::randperm(50);
  const std::vector<Tensor> a = image_and_grads(s);
  const std::vector<Tensor> b = image_and_grads(select_rows(s, perm));
  EXPECT_TRUE(torch::equal(a[0], b[0]));
  for (int i = 1; i <= 5; ++i)
    EXPECT_TRUE(torch::allclose(a[i].index_select(0, perm), b[i], 1e-5, 1e-7)) << i;
  EXPECT_TRUE(torch::allclose(a[6], b[6], 1e-5, 1e-7));
}

TEST(Rasterize, RepeatedCallsGiveIdenticalBits) {
  const SplatScene s = random_scene(7, 60, 33, 50, 40);
  const std::vector<Tensor> a = image_and_grads(s), b = image_and_grads(s);
  for (size_t i = 0; i < a.size(); ++i) EXPECT_TRUE(torch::equal(a[i], b[i])) << i;
}

TEST(Rasterize, ThreadCountChangesOnlySummationOrder) {
  const SplatScene s = random_scene(8, 60, 9, 70, 50);
  const int before = core::thread_count();
  core::configure_threads(1);
  const std::vector<Tensor> one = image_and_grads(s);
  core::configure_threads(3);
  const std::vector<Tensor> three = image_and_grads(s);
  core::configure_threads(before);
  EXPECT_TRUE(torch::equal(one[0], three[0]));  // pixels never share work
  for (size_t i = 1; i < one.size(); ++i) EXPECT_LT(scaled_error(three[i], one[i]), 1e-5) << i;
}

TEST(Rasterize, LargeSceneSameOnOneAndTwoThreads) {
  // Enough Gaussians that LibTorch's parallel loops really split the work.
  SplatScene s = random_scene(13, 6000, 4, 64, 48);
  s.log_scales = s.log_scales - 1.5;
  const int before = core::thread_count();
  core::configure_threads(1);
  const std::vector<Tensor> one = image_and_grads(s);
  core::configure_threads(2);
  const std::vector<Tensor> two = image_and_grads(s);
  core::configure_threads(before);
  EXPECT_TRUE(torch::equal(one[0], two[0]));
  for (size_t i = 1; i < one.size(); ++i) EXPECT_LT(scaled_error(two[i], one[i]), 1e-5) << i;
}

TEST(Rasterize, NoGradRenderMatchesAndKeepsNoGraph) {
  const SplatScene s = random_scene(9, 40, 6, 37, 29).leaves(torch::kFloat32);
  const RenderOutput with_graph = render_scene(s);
  EXPECT_TRUE(with_graph.image.requires_grad());
  torch::NoGradGuard no_grad;
  const RenderOutput plain = render_scene(s);
  EXPECT_FALSE(plain.image.requires_grad());
  EXPECT_FALSE(plain.image.grad_fn());
  EXPECT_TRUE(torch::equal(plain.image, with_graph.image.detach()));
  EXPECT_TRUE(torch::equal(plain.depth, with_graph.depth.detach()));
}

TEST(Rasterize, DoubleInputsGetDoubleGradients) {
  const SplatScene s = random_scene(10, 20, 3, 20, 20).leaves(torch::kFloat64);
  render_scene(s).image.sum().backward();
  EXPECT_EQ(s.means.grad().scalar_type(), torch::kFloat64);
  EXPECT_GT(s.means.grad().abs().sum().item<double>(), 0.0);
}

TEST(Rasterize, BadInputIsAClearError) {
  const SplatScene good = random_scene(11, 20, 3, 20, 20);
  auto expect_error = [](const SplatScene& s, const std::string& what) {
    EXPECT_THROW(render_scene(s), core::Error) << what;
  };
  SplatScene s = good;
  s.log_scales = s.log_scales.index({torch::indexing::Slice(0, 19)});
  expect_error(s, "G mismatch");
  s = good, s.quats = s.quats.index({torch::indexing::Slice(), torch::indexing::Slice(0, 3)});
  expect_error(s, "quats [G, 3]");
  s = good, s.colors = torch::zeros({20, 0}), s.background = torch::zeros({0});
  expect_error(s, "N = 0");
  s = good, s.background = torch::zeros({4});
  expect_error(s, "background size");
  s = good, s.means = s.means.clone(), s.means[3][1] = NAN;
  expect_error(s, "NaN mean");
  s = good, s.colors = s.colors.clone(), s.colors[2][0] = INFINITY;
  expect_error(s, "inf colour");
  s = good, s.quats = s.quats.clone(), s.quats[5] = torch::zeros({4});
  expect_error(s, "zero quaternion");
  s = good, s.camera.world_to_camera[3] = NAN;
  expect_error(s, "NaN pose");
  s = good, s.camera.fx = 0;
  expect_error(s, "zero focal length");
  s = good, s.camera.width = 0;
  expect_error(s, "zero-sized image");
  s = good;
  EXPECT_THROW(render_scene(s, torch::zeros({19, 2})), core::Error) << "sink shape";
  core::Camera distorted = test_core_camera(20, 20);
  distorted.intrinsics.k1 = 0.1;
  EXPECT_THROW(render::RenderCamera::from(distorted), core::Error);
}

// Central differences in double through the reference confirm its autograd
// gradients (which the fast path is compared against).
TEST(RasterizeReference, GradientsMatchFiniteDifferences) {
  const SplatScene base = random_scene(12, 17, 2, 9, 7);
  const SplatScene s = base.leaves(torch::kFloat64);
  torch::manual_seed(5);
  const Tensor wi = torch::randn({7, 9, 2}, torch::kFloat64);
  const Tensor wa = torch::randn({7, 9}, torch::kFloat64);
  const Tensor wd = torch::randn({7, 9}, torch::kFloat64);
  auto loss = [&]() {
    const RenderOutput o = render::rasterize_reference(
        s.means, s.log_scales, s.quats, s.logit_opacities, s.colors, s.camera, s.background);
    return (o.image * wi).sum() + (o.alpha * wa).sum() + (o.depth * wd).sum();
  };
  loss().backward();
  const double eps = 1e-6;
  for (const Tensor& p : s.params()) {
    const Tensor flat = p.detach().view({-1});
    const Tensor grad = p.grad().view({-1});
    // A fixed sample of entries per tensor keeps the test a few seconds long.
    const Tensor picks = torch::randperm(flat.numel()).slice(0, 0, 20);
    Tensor numeric = grad.clone();  // entries not picked compare equal
    for (int64_t i : std::vector<int64_t>(picks.data_ptr<int64_t>(),
                                          picks.data_ptr<int64_t>() + picks.numel())) {
      torch::NoGradGuard no_grad;
      const double v = flat[i].item<double>();
      flat[i] = v + eps;
      const double up = loss().item<double>();
      flat[i] = v - eps;
      const double down = loss().item<double>();
      flat[i] = v;
      numeric[i] = (up - down) / (2 * eps);
    }
    const double error = (grad - numeric).index_select(0, picks).abs().max().item<double>();
    EXPECT_LT(error, 1e-5 * grad.abs().max().item<double>()) << p.sizes();
  }
}

}  // namespace
}  // namespace ddhgs::test
