// Random crops of the training views (loss.view_fraction and view_fraction_from_pixels): every
// pixel away from the border is measured equally often, the loss weight makes the expected gradient
// the whole view's, and the crop's camera renders exactly that part of the whole view's render.
#include <gtest/gtest.h>

#include <vector>

#include "core/tensor.h"
#include "render/render_fixture.h"
#include "train/view_crop.h"

namespace {

using namespace ddhgs;

// loss.view_fraction_from_pixels: views of at least that many pixels are
// cropped, smaller ones stay whole.
TEST(ViewCrop, OnlyViewsOfAtLeastTheThresholdAreCropped) {
  EXPECT_EQ(train::crop_fraction(0.5, 65536, 640, 512), 0.5);
  EXPECT_EQ(train::crop_fraction(0.5, 65536, 256, 256), 0.5);
  EXPECT_EQ(train::crop_fraction(0.5, 65536, 255, 256), 1);
  EXPECT_EQ(train::crop_fraction(0.5, 65536, 174, 130), 1);
  EXPECT_EQ(train::crop_fraction(0.3, 0, 16, 16), 0.3);
  EXPECT_EQ(train::crop_fraction(1, 0, 4000, 3000), 1);
  // No overflow at large sizes: 65536 x 65536 pixels.
  EXPECT_EQ(train::crop_fraction(0.5, int64_t(1) << 30, 65536, 65536), 0.5);
}

TEST(ViewCrop, CoversEveryInnerPixelEquallyAndWeightsAverageToOne) {
  const int width = 96, height = 72, draws = 20000;
  for (const double fraction : {0.25, 0.5, 0.8}) {
    std::vector<int> covered(size_t(width) * height, 0);
    double scale_sum = 0, area_sum = 0, coverage = 0;
    for (int d = 0; d < draws; ++d) {
      const train::ViewCrop c = train::draw_view_crop(width, height, fraction, uint64_t(d) * 7919);
      ASSERT_GE(c.width(), train::kMinCropSide);
      ASSERT_GE(c.height(), train::kMinCropSide);
      ASSERT_TRUE(c.x0 >= 0 && c.x1 <= width && c.y0 >= 0 && c.y1 <= height);
      for (int y = c.y0; y < c.y1; ++y)
        for (int x = c.x0; x < c.x1; ++x) ++covered[size_t(y) * width + x];
      scale_sum += c.loss_scale;
      area_sum += double(c.width()) * c.height();
      coverage = c.coverage;  // the same for every draw
    }
    // The mean area the weights assume is the mean area drawn, and it holds
    // about `fraction` of the view.
    EXPECT_NEAR(scale_sum / draws, 1.0, 0.02) << fraction;
    EXPECT_NEAR(area_sum / draws / (width * height), coverage, 0.01) << fraction;
    EXPECT_NEAR(coverage, fraction, 0.08) << fraction;
    // Pixels at least kMinCropSide from the border: one probability, the
    // per-side coverage squared (binomial sd <= 0.0036 for 20000 draws).
    const int m = train::kMinCropSide;
    double lo = 1, hi = 0;
    for (int y = m; y < height - m; ++y)
      for (int x = m; x < width - m; ++x) {
        const double p = double(covered[size_t(y) * width + x]) / draws;
        lo = std::min(lo, p), hi = std::max(hi, p);
      }
    EXPECT_LT(hi - lo, 0.04) << fraction;
    EXPECT_NEAR(0.5 * (lo + hi), fraction, 0.03) << fraction;
  }
}

TEST(ViewCrop, WholeViewForFractionOneOrASmallImageAndBadFractionsThrow) {
  for (const auto& [w, h, f] :
       std::vector<std::tuple<int, int, double>>{{640, 512, 1.0}, {31, 200, 0.5}, {200, 20, 0.5}}) {
    const train::ViewCrop c = train::draw_view_crop(w, h, f, 3);
    EXPECT_EQ(c.x0, 0);
    EXPECT_EQ(c.y0, 0);
    EXPECT_EQ(c.x1, w);
    EXPECT_EQ(c.y1, h);
    EXPECT_EQ(c.loss_scale, 1.0);
    EXPECT_EQ(c.coverage, 1.0);
  }
  EXPECT_THROW(train::draw_view_crop(64, 64, 0.0, 1), std::exception);
  EXPECT_THROW(train::draw_view_crop(64, 64, 1.5, 1), std::exception);
  // The same seed, the same crop (a resumed run draws what a straight one would).
  const train::ViewCrop a = train::draw_view_crop(640, 512, 0.5, 42),
                        b = train::draw_view_crop(640, 512, 0.5, 42);
  EXPECT_TRUE(a.x0 == b.x0 && a.x1 == b.x1 && a.y0 == b.y0 && a.y1 == b.y1);
}

TEST(ViewCrop, TheCropCameraRendersThatPartOfTheWholeRender) {
  const int width = 80, height = 64;
  const test::SplatScene s = test::random_scene(5, 300, 4, width, height);
  const core::Camera whole_camera = test::test_core_camera(width, height);
  auto render = [&](const core::Camera& camera) {
    return render::rasterize(s.means, s.log_scales, s.quats, s.logit_opacities, s.colors,
                             render::RenderCamera::from(camera), s.background);
  };
  const render::RenderOutput whole = render(whole_camera);
  int cropped = 0;
  for (uint64_t seed = 0; seed < 6; ++seed) {
    const train::ViewCrop c = train::draw_view_crop(width, height, 0.4, seed);
    if (c.width() < width || c.height() < height) ++cropped;
    const render::RenderOutput part = render(train::crop_camera(whole_camera, c));
    ASSERT_EQ(part.image.size(0), c.height());
    ASSERT_EQ(part.image.size(1), c.width());
    const torch::Tensor expected = whole.image.slice(0, c.y0, c.y1).slice(1, c.x0, c.x1);
    // Pixel centres move by whole pixels and the Jacobian clamp follows the
    // whole view (the camera's frame): only the float rounding of the
    // projected means differs. Without the frame, large Gaussians beyond the
    // crop's edges changed pixels by up to 0.012.
    EXPECT_LT((part.image - expected).abs().max().item<double>(), 1e-5) << seed;
  }
  EXPECT_GE(cropped, 5);
}

}  // namespace
