// The fast rasterizer against the dense double-precision reference: images,
// alpha, depth, radii, 2D means and every gradient, on random scenes.
#include <gtest/gtest.h>

#include <vector>

#include "render/blend.h"
#include "render/reference.h"
#include "render_fixture.h"

namespace ddhgs::test {
namespace {

using render::RenderOutput;
using torch::Tensor;

struct Case {
  int seed, g, n, width, height;
};

std::string name(const Case& c) {
  return "seed " + std::to_string(c.seed) + ", G " + std::to_string(c.g) + ", N " +
         std::to_string(c.n) + ", " + std::to_string(c.width) + "x" + std::to_string(c.height);
}

// A loss touching every output, with fixed random weights.
Tensor loss_of(const RenderOutput& out, int seed) {
  torch::manual_seed(seed + 1000);
  // Drawn in double for both paths so they see the same weights.
  auto weights = [](const Tensor& t) {
    return torch::randn(t.sizes(), torch::kFloat64).to(t.scalar_type());
  };
  return (out.image * weights(out.image)).sum() + (out.alpha * weights(out.alpha)).sum() +
         (out.depth * weights(out.depth)).sum() + (out.means2d * weights(out.means2d)).sum();
}

// The blender's paths: images of at most 8 channels take the lane path
// (render/lane_blend.h) unless it is switched off, wider ones the row path,
// whose channel loops use 512-bit vectors where the build targets AVX-512
// and 256-bit ones otherwise. Every path must match the reference.
enum class Path { kLanes, kRows256, kRows512 };

std::string path_name(Path p) {
  return p == Path::kLanes     ? "lane path (at most 8 channels)"
         : p == Path::kRows256 ? "row path, 256-bit loops"
                               : "row path, 512-bit loops";
}

class FastVsReference : public ::testing::TestWithParam<std::tuple<Case, Path>> {
 protected:
  void TearDown() override {
    render::set_wide_kernels(true);
    render::set_lane_path(true);
  }
};

TEST_P(FastVsReference, ValuesAndGradientsMatch) {
  const auto [c, path] = GetParam();
  render::set_lane_path(path == Path::kLanes);
  render::set_wide_kernels(path == Path::kRows512);
  const SplatScene base = random_scene(c.seed, c.g, c.n, c.width, c.height);

  const SplatScene fast = base.leaves(torch::kFloat32);
  const Tensor sink = torch::zeros({c.g, 2}, torch::requires_grad());
  const RenderOutput out =
      render::rasterize(fast.means, fast.log_scales, fast.quats, fast.logit_opacities, fast.colors,
                        fast.camera, fast.background, sink);
  loss_of(out, c.seed).backward();

  const SplatScene ref = base.leaves(torch::kFloat64);
  const RenderOutput expect =
      render::rasterize_reference(ref.means, ref.log_scales, ref.quats, ref.logit_opacities,
                                  ref.colors, ref.camera, ref.background);
  expect.means2d.retain_grad();
  loss_of(expect, c.seed).backward();

  SCOPED_TRACE(name(c) + ", " + path_name(path));
  EXPECT_TRUE(torch::equal(out.radii, expect.radii));
  EXPECT_LT(scaled_error(out.image, expect.image), 1e-4);
  EXPECT_LT(scaled_error(out.alpha, expect.alpha), 1e-4);
  EXPECT_LT(scaled_error(out.depth, expect.depth), 1e-4);
  EXPECT_LT(scaled_error(out.means2d, expect.means2d), 1e-5);
  // The scene must exercise the hard paths, not just render background.
  EXPECT_GT(out.alpha.max().item<float>(), 0.999f);
  EXPECT_GT((out.radii > 0).sum().item<int64_t>(), c.g / 3);

  const std::vector<Tensor> got = fast.params(), want = ref.params();
  const char* names[] = {"means", "log_scales", "quats", "logit_opacities", "colors", "background"};
  for (size_t i = 0; i < got.size(); ++i) {
    ASSERT_TRUE(got[i].grad().defined()) << names[i];
    EXPECT_LT(scaled_error(got[i].grad(), want[i].grad()), 1e-4) << names[i];
  }
  ASSERT_TRUE(sink.grad().defined());
  EXPECT_LT(scaled_error(sink.grad(), expect.means2d.grad()), 1e-4) << "means2d";
}

// The blend paths this build has: the lane path where it is built (AVX2 and
// FMA), the 256-bit row loops always, the 512-bit ones where the build
// targets AVX-512 (a build for an AVX2-only CPU has none, and a skipped case
// would be a check that never runs). Wider images take the row path with the
// lane path on, so the lane case checks them there too.
std::vector<Path> blend_paths() {
  std::vector<Path> paths = {Path::kRows256};
  if (render::lane_path_built()) paths.push_back(Path::kLanes);
  if (render::wide_kernels_built()) paths.push_back(Path::kRows512);
  return paths;
}

// N = 300 pads to 304 channels: two blocks of the 512-bit loops (192 + 112).
// N = 1, 3, 5 and 8 take the lane path.
INSTANTIATE_TEST_SUITE_P(
    RandomScenes, FastVsReference,
    ::testing::Combine(::testing::Values(Case{1, 40, 1, 37, 29}, Case{2, 60, 3, 64, 48},
                                         Case{3, 50, 17, 37, 29}, Case{4, 70, 128, 64, 48},
                                         Case{5, 45, 3, 16, 16}, Case{6, 30, 141, 37, 29},
                                         Case{7, 24, 300, 20, 33}, Case{8, 50, 5, 37, 29},
                                         Case{9, 60, 8, 48, 40}),
                       ::testing::ValuesIn(blend_paths())));

}  // namespace
}  // namespace ddhgs::test
