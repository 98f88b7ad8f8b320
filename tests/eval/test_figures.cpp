// Colour maps, band selection, error heatmaps and picture layout.
#include <gtest/gtest.h>

#include "core/error.h"
#include "core/tensor.h"
#include "eval/colormap.h"
#include "eval/figures.h"

namespace ddhgs::eval {
namespace {

TEST(Colormap, ViridisEndpointsAndMidpointMatchTheTable) {
  auto lo = colormap_rgb(Colormap::Viridis, 0.0);
  auto mid = colormap_rgb(Colormap::Viridis, 128.0 / 255.0);
  auto hi = colormap_rgb(Colormap::Viridis, 1.0);
  EXPECT_NEAR(lo[0], 0.267004, 1e-9);
  EXPECT_NEAR(lo[2], 0.329415, 1e-9);
  EXPECT_NEAR(mid[1], 0.566949, 1e-9);  // table entry 128
  EXPECT_NEAR(hi[0], 0.993248, 1e-9);
  EXPECT_NEAR(hi[1], 0.906157, 1e-9);
  // Between anchors: entry 72 of the full table is (0.214298, 0.355619, 0.551184).
  auto e72 = colormap_rgb(Colormap::Viridis, 72.0 / 255.0);
  EXPECT_NEAR(e72[0], 0.214298, 0.005);
  EXPECT_NEAR(e72[1], 0.355619, 0.005);
  EXPECT_NEAR(e72[2], 0.551184, 0.005);
  // Values outside [0, 1] saturate.
  EXPECT_EQ(colormap_rgb(Colormap::Viridis, -3.0), lo);
  EXPECT_EQ(colormap_rgb(Colormap::Viridis, 7.0), hi);
}

TEST(Colormap, ViridisLightnessRisesMonotonically) {
  // Perceptual ordering: luma (Rec. 709 weights on display values) never falls.
  double previous = -1;
  for (int i = 0; i <= 255; ++i) {
    auto c = colormap_rgb(Colormap::Viridis, i / 255.0);
    double luma = 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    EXPECT_GT(luma, previous) << "entry " << i;
    previous = luma;
  }
}

TEST(Colormap, ApplyMatchesPointwiseColours) {
  torch::Tensor values = torch::tensor({0.0f, 0.2f, 0.5f, 1.0f, 1.5f}).view({1, 5});
  torch::Tensor rgb = apply_colormap(values, Colormap::Viridis);
  ASSERT_EQ(rgb.sizes(), (std::vector<int64_t>{1, 5, 3}));
  for (int i = 0; i < 5; ++i) {
    auto expected = colormap_rgb(Colormap::Viridis, values[0][i].item<double>());
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(rgb[0][i][c].item<double>(), expected[size_t(c)], 0.01) << i << "," << c;
  }
  torch::Tensor grey = apply_colormap(values, Colormap::Gray);
  EXPECT_FLOAT_EQ(grey[0][2][1].item<float>(), 0.5f);
  EXPECT_FLOAT_EQ(grey[0][4][0].item<float>(), 1.0f);
  EXPECT_EQ(parse_colormap("grey"), Colormap::Gray);
  EXPECT_THROW(parse_colormap("jet"), core::Error);
}

TEST(Figures, SelectBandsByIndexAndRange) {
  std::vector<double> wl = {700, 710, 720, 730, 740, 750, 760, 770};
  BandSelection rgb = select_bands("", "", wl);
  EXPECT_TRUE(rgb.pseudo_rgb);
  EXPECT_EQ(rgb.label, "rgb");
  BandSelection one = select_bands("3", "", wl);
  EXPECT_FALSE(one.pseudo_rgb);
  EXPECT_EQ(one.first, 3);
  EXPECT_EQ(one.last, 3);
  EXPECT_EQ(one.label, "band3");
  BandSelection range = select_bands("", "715:752", wl);
  EXPECT_EQ(range.first, 2);
  EXPECT_EQ(range.last, 5);
  EXPECT_EQ(range.label, "715-752nm");
  EXPECT_THROW(select_bands("8", "", wl), core::Error);
  EXPECT_THROW(select_bands("x", "", wl), core::Error);
  EXPECT_THROW(select_bands("", "800:900", wl), core::Error);
  EXPECT_THROW(select_bands("", "750", wl), core::Error);
  EXPECT_THROW(select_bands("", "760:750", wl), core::Error);
  EXPECT_THROW(select_bands("1", "700:720", wl), core::Error);
}

TEST(Figures, BandMeanAndGreyPicture) {
  torch::Tensor image = torch::zeros({2, 3, 4});
  for (int b = 0; b < 4; ++b) image.select(2, b).fill_(0.1f * float(b + 1));
  BandSelection s;
  s.pseudo_rgb = false;
  s.first = 1;
  s.last = 3;  // mean of 0.2, 0.3, 0.4
  torch::Tensor mean = band_mean(image, s);
  EXPECT_NEAR(mean[1][2].item<double>(), 0.3, 1e-6);
  torch::Tensor pic = picture(image, {500, 600, 700, 800}, s, Colormap::Gray);
  ASSERT_EQ(pic.sizes(), (std::vector<int64_t>{2, 3, 3}));
  EXPECT_NEAR(pic[0][0][2].item<double>(), 0.3, 1e-6);
}

TEST(Figures, ErrorHeatmapUsesFixedScale) {
  torch::Tensor truth = torch::full({2, 2, 3}, 0.5f);
  torch::Tensor render = truth.clone();
  render[0][0].fill_(0.55f);  // error 0.05 in every band
  render[1][1][0] = 0.8f;     // error 0.3 in one band of three: mean 0.1
  render[0][1].fill_(0.0f);   // error 0.5: saturates
  BandSelection all;          // pseudo-RGB selection averages every band
  torch::Tensor heat = error_heatmap(render, truth, all, 0.1, Colormap::Gray);
  EXPECT_NEAR(heat[0][0][0].item<double>(), 0.5, 1e-3);
  EXPECT_NEAR(heat[1][1][1].item<double>(), 1.0, 1e-3);
  EXPECT_NEAR(heat[0][1][2].item<double>(), 1.0, 1e-6);
  EXPECT_NEAR(heat[1][0][0].item<double>(), 0.0, 1e-6);
  EXPECT_THROW(error_heatmap(render, truth, all, 0.0, Colormap::Gray), core::Error);
}

TEST(Figures, LayoutSideBySideAndStacked) {
  torch::Tensor a = torch::zeros({5, 4, 3}), b = torch::full({5, 6, 3}, 0.5f);
  torch::Tensor row = side_by_side({a, b}, 2);
  ASSERT_EQ(row.sizes(), (std::vector<int64_t>{5, 12, 3}));
  EXPECT_FLOAT_EQ(row[0][4][0].item<float>(), 1.0f);  // white gap
  EXPECT_FLOAT_EQ(row[0][6][0].item<float>(), 0.5f);
  torch::Tensor bar = colour_bar(3, 4, Colormap::Gray);
  EXPECT_FLOAT_EQ(bar[0][0][0].item<float>(), 0.0f);
  EXPECT_FLOAT_EQ(bar[2][3][0].item<float>(), 1.0f);
  torch::Tensor column = stacked(row, bar, 1);
  ASSERT_EQ(column.sizes(), (std::vector<int64_t>{9, 12, 3}));
  EXPECT_FLOAT_EQ(column[6][11][0].item<float>(), 1.0f);  // padding right of the bar
  EXPECT_THROW(side_by_side({a, torch::zeros({4, 4, 3})}), core::Error);
}

}  // namespace
}  // namespace ddhgs::eval
