// Recycled output buffers: the renderer reuses an image's storage only after
// every holder has dropped it, so held images and pending backward passes
// never see a later render's pixels.
#include <gtest/gtest.h>

#include "render_fixture.h"

namespace ddhgs::test {
namespace {

using render::RenderOutput;
using torch::Tensor;

RenderOutput render_scene(const SplatScene& s) {
  return render::rasterize(s.means, s.log_scales, s.quats, s.logit_opacities, s.colors, s.camera,
                           s.background);
}

// N = 32 takes the whole-vector paths (rows read in place, streaming writes).
constexpr int kBands = 32;

TEST(RasterizeBuffers, DroppedImageStorageIsReusedWithSameBits) {
  const SplatScene s = random_scene(3, 80, kBands, 48, 40);
  torch::NoGradGuard no_grad;
  Tensor first = render_scene(s).image;
  const Tensor copy = first.clone();
  const void* storage = first.data_ptr();
  first = Tensor();
  const Tensor second = render_scene(s).image;
  EXPECT_EQ(second.data_ptr(), storage);
  EXPECT_TRUE(torch::equal(second, copy));
}

TEST(RasterizeBuffers, HeldImageIsNotOverwrittenByTheNextRender) {
  const SplatScene a = random_scene(4, 80, kBands, 48, 40), b = random_scene(5, 80, kBands, 48, 40);
  torch::NoGradGuard no_grad;
  const Tensor image_a = render_scene(a).image;
  const Tensor copy_a = image_a.clone();
  const Tensor view_b = render_scene(b).image.select(2, 0);  // a view keeps the storage too
  EXPECT_TRUE(torch::equal(image_a, copy_a));
  const Tensor image_c = render_scene(a).image;
  EXPECT_TRUE(torch::equal(image_c, copy_a));
  EXPECT_NE(image_c.data_ptr(), view_b.data_ptr());
  EXPECT_FALSE(torch::equal(view_b, image_c.select(2, 0)));
}

std::vector<Tensor> gradients(const SplatScene& s, const RenderOutput& out) {
  torch::manual_seed(11);
  (out.image * torch::randn(out.image.sizes())).sum().backward();
  std::vector<Tensor> g;
  for (const Tensor& p : s.params()) g.push_back(p.grad().clone());
  return g;
}

TEST(RasterizeBuffers, PendingBackwardSurvivesOtherRenders) {
  const SplatScene base = random_scene(6, 80, kBands, 48, 40);
  const SplatScene other = random_scene(8, 80, kBands, 48, 40).leaves(torch::kFloat32);
  const SplatScene s1 = base.leaves(torch::kFloat32), s2 = base.leaves(torch::kFloat32);
  const std::vector<Tensor> expected = gradients(s1, render_scene(s1));
  const RenderOutput pending = render_scene(s2);
  // Another training-style render and backward between forward and backward.
  const RenderOutput between = render_scene(other);
  gradients(other, between);
  const std::vector<Tensor> got = gradients(s2, pending);
  for (size_t i = 0; i < got.size(); ++i) EXPECT_TRUE(torch::equal(got[i], expected[i])) << i;
}

}  // namespace
}  // namespace ddhgs::test
