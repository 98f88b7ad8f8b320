#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "core/colour.h"
#include "core/colour_tables.h"
#include "core/error.h"
#include "support/test_support.h"

namespace ddhgs::core {
namespace {

std::vector<double> grid(double first_nm, double last_nm, int count) {
  std::vector<double> out;
  for (int i = 0; i < count; ++i) out.push_back(first_nm + (last_nm - first_nm) * i / (count - 1));
  return out;
}

// Linear sRGB of an sRGB-encoded value, per channel of pixel (0, 0).
std::array<double, 3> linear_of(const torch::Tensor& rgb) {
  auto p = rgb.index({0, 0}).to(torch::kFloat64);
  return {srgb_decode(p[0].item<double>()), srgb_decode(p[1].item<double>()),
          srgb_decode(p[2].item<double>())};
}

TEST(Colour, TabulatedKnownValues) {
  EXPECT_DOUBLE_EQ(cie1931_cmf(555).y, 1.0);
  EXPECT_NEAR(cie1931_cmf(600).x, 1.0622, 1e-4);
  EXPECT_NEAR(cie1931_cmf(440).z, 1.74706, 1e-5);
  EXPECT_NEAR(cie1931_cmf(450).z, 1.77211, 1e-5);
  // Linear between table rows, zero outside the table.
  EXPECT_NEAR(cie1931_cmf(557.5).y, 0.5 * (1.0 + 0.995), 1e-12);
  EXPECT_EQ(cie1931_cmf(379.9).x, 0.0);
  EXPECT_EQ(cie1931_cmf(781).y, 0.0);
  EXPECT_DOUBLE_EQ(illuminant_power(Illuminant::D65, 560), 100.0);
  EXPECT_NEAR(illuminant_power(Illuminant::D65, 380), 49.9755, 1e-4);
}

TEST(Colour, D65WhitePointFromTables) {
  double x = 0, y = 0, z = 0;
  for (int i = 0; i < kColourTableRows; ++i) {
    x += kD65Power[i] * kCie1931Cmf[i][0];
    y += kD65Power[i] * kCie1931Cmf[i][1];
    z += kD65Power[i] * kCie1931Cmf[i][2];
  }
  EXPECT_NEAR(x / y, 0.95047, 2e-4);
  EXPECT_NEAR(z / y, 1.08883, 2e-4);
}

TEST(Colour, IlluminantAMatchesCieTableAndPlanck) {
  // CIE 15 table values of illuminant A.
  EXPECT_NEAR(illuminant_power(Illuminant::A, 560), 100.0, 1e-9);
  EXPECT_NEAR(illuminant_power(Illuminant::A, 380), 9.7951, 1e-3);
  EXPECT_NEAR(illuminant_power(Illuminant::A, 780), 241.675, 1e-2);
  for (double nm : {400.0, 500.0, 700.0, 1000.0}) {
    double planck = 100 * planck_radiance(nm, 2856) / planck_radiance(560, 2856);
    EXPECT_NEAR(illuminant_power(Illuminant::A, nm) / planck, 1.0, 2e-3) << nm;
  }
}

TEST(Colour, SrgbTransferCurve) {
  EXPECT_NEAR(srgb_encode(0.5), 0.735357, 1e-6);
  EXPECT_NEAR(srgb_encode(0.002), 0.02584, 1e-6);  // linear toe
  for (double v : {0.0, 0.001, 0.01, 0.2, 0.9, 1.0})
    EXPECT_NEAR(srgb_decode(srgb_encode(v)), v, 1e-12);
  auto t = srgb_encode(torch::tensor({0.0, 0.002, 0.5, 1.0}, torch::kFloat64));
  EXPECT_NEAR(t[2].item<double>(), 0.735357, 1e-6);
  EXPECT_NEAR(t[3].item<double>(), 1.0, 1e-9);
}

TEST(Colour, FlatHalfSpectrumIsNeutralGrey) {
  for (const auto& wl : {grid(400, 1000, 40), grid(380, 780, 81), grid(370, 1100, 128)}) {
    auto cube = torch::full({2, 3, int64_t(wl.size())}, 0.5f);
    auto rgb = pseudo_rgb(cube, wl);
    ASSERT_EQ(rgb.sizes(), (std::vector<int64_t>{2, 3, 3}));
    auto lin = linear_of(rgb);
    EXPECT_NEAR(lin[0], lin[1], 1e-3);
    EXPECT_NEAR(lin[1], lin[2], 1e-3);
    EXPECT_NEAR(lin[1], 0.5, 1e-3);
    EXPECT_NEAR(rgb[1][2][0].item<float>(), 0.7354f, 2e-3);
    // Every pixel equal.
    EXPECT_LT((rgb - rgb[0][0]).abs().max().item<float>(), 1e-6);
  }
}

TEST(Colour, FlatOneIsWhiteAndU8) {
  auto wl = grid(400, 1000, 40);
  auto rgb = pseudo_rgb(torch::ones({1, 1, 40}), wl);
  for (int c = 0; c < 3; ++c) EXPECT_GT(rgb[0][0][c].item<float>(), 0.999f);
  auto u8 = pseudo_rgb_u8(torch::ones({1, 1, 40}), wl);
  EXPECT_EQ(u8.scalar_type(), torch::kUInt8);
  for (int c = 0; c < 3; ++c) EXPECT_EQ(u8[0][0][c].item<int>(), 255);
}

TEST(Colour, BandsOutsideVisibleGiveBlack) {
  auto wl = grid(800, 1100, 16);
  auto rgb = pseudo_rgb(torch::rand({3, 4, 16}) + 0.5, wl);
  EXPECT_EQ(rgb.abs().max().item<float>(), 0.0f);
  // Bands beyond 780 nm add nothing to a cube that also covers the visible.
  auto wide = grid(400, 1000, 61);  // 10 nm spacing
  auto cube = torch::full({1, 1, 61}, 0.3f);
  auto reference = pseudo_rgb(cube, wide);
  cube.index_put_({0, 0, torch::indexing::Slice(40, torch::indexing::None)}, 1.0f);  // >= 800 nm
  EXPECT_LT((pseudo_rgb(cube, wide) - reference).abs().max().item<float>(), 1e-6);
}

TEST(Colour, HandComputedThreeBands) {
  // Bands at 500, 600, 700 nm span [450, 550], [550, 650], [650, 750]. With an
  // equal-energy illuminant and piecewise-linear CMFs, the trapezoid rule on
  // the 5 nm table rows is the exact integral.
  auto trapezoid = [](int from_nm, int to_nm, int column) {
    double sum = 0;
    for (int nm = from_nm; nm <= to_nm; nm += 5) {
      double v = kCie1931Cmf[(nm - 380) / 5][column];
      sum += (nm == from_nm || nm == to_nm) ? 2.5 * v : 5 * v;
    }
    return 100 * sum;
  };
  std::vector<double> wl{500, 600, 700};
  auto weights = cie_band_weights(wl, Illuminant::Equal);
  const int edges[4] = {450, 550, 650, 750};
  for (int b = 0; b < 3; ++b)
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(weights[b][c].item<double>(), trapezoid(edges[b], edges[b + 1], c),
                  1e-9 * (1 + trapezoid(edges[b], edges[b + 1], c)))
          << b << " " << c;

  const double r[3] = {0.2, 0.6, 0.9};
  double xyz[3] = {0, 0, 0}, white_y = 0;
  for (int b = 0; b < 3; ++b) {
    white_y += trapezoid(edges[b], edges[b + 1], 1);
    for (int c = 0; c < 3; ++c) xyz[c] += r[b] * trapezoid(edges[b], edges[b + 1], c);
  }
  const auto& m = xyz_to_linear_srgb_matrix();
  auto cube = torch::tensor({0.2f, 0.6f, 0.9f}).reshape({1, 1, 3});
  PseudoRgbOptions options;
  options.illuminant = Illuminant::Equal;
  auto rgb = pseudo_rgb(cube, wl, options);
  for (int c = 0; c < 3; ++c) {
    double lin = (m[c * 3] * xyz[0] + m[c * 3 + 1] * xyz[1] + m[c * 3 + 2] * xyz[2]) / white_y;
    double expected = srgb_encode(std::clamp(lin, 0.0, 1.0));
    EXPECT_NEAR(rgb[0][0][c].item<float>(), expected, 1e-5) << c;
  }
}

TEST(Colour, LinearMapMatchesManualProduct) {
  torch::manual_seed(3);
  auto cube = torch::rand({4, 5, 6});
  auto map = torch::rand({3, 6}) / 6;  // rows sum below 1: no clamping
  PseudoRgbOptions options;
  options.mode = PseudoRgbMode::LinearMap;
  options.linear_map = map;
  auto rgb = pseudo_rgb(cube, {}, options);
  auto c = cube.accessor<float, 3>();
  auto mm = map.accessor<float, 2>();
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 5; ++x)
      for (int k = 0; k < 3; ++k) {
        double s = 0;
        for (int b = 0; b < 6; ++b) s += mm[k][b] * c[y][x][b];
        EXPECT_NEAR(rgb[y][x][k].item<float>(), s, 1e-6);
      }

  // 3 x k on chosen bands, with linear output passed through the sRGB curve.
  options.linear_map = torch::tensor({0.5f, 0.5f, 0.0f, 1.0f, 0.0f, 2.0f}).reshape({3, 2});
  options.band_indices = {4, 1};
  options.map_output_linear = true;
  rgb = pseudo_rgb(cube, {}, options);
  double v4 = c[2][3][4], v1 = c[2][3][1];
  EXPECT_NEAR(rgb[2][3][0].item<float>(), srgb_encode(0.5 * v4 + 0.5 * v1), 1e-6);
  EXPECT_NEAR(rgb[2][3][1].item<float>(), srgb_encode(v1), 1e-6);
  EXPECT_NEAR(rgb[2][3][2].item<float>(), srgb_encode(std::min(1.0, 2.0 * v1)), 1e-6);
}

TEST(Colour, BandsChoiceTakesNearestBands) {
  auto wl = grid(400, 1000, 61);  // 10 nm apart
  auto cube = torch::zeros({1, 1, 61});
  for (int b = 0; b < 61; ++b) cube[0][0][b] = b / 100.0f;
  auto options = parse_pseudo_rgb("bands:652,548,451");
  auto rgb = pseudo_rgb(cube, wl, options);
  EXPECT_NEAR(rgb[0][0][0].item<float>(), srgb_encode(0.25), 1e-6);  // 650 nm = band 25
  EXPECT_NEAR(rgb[0][0][1].item<float>(), srgb_encode(0.15), 1e-6);  // 550 nm
  EXPECT_NEAR(rgb[0][0][2].item<float>(), srgb_encode(0.05), 1e-6);  // 450 nm
}

TEST(Colour, ParsedSpecsAndMapFile) {
  auto a = parse_pseudo_rgb("cie:A:balanced");
  EXPECT_EQ(a.illuminant, Illuminant::A);
  EXPECT_TRUE(a.white_balance);
  // Balanced illuminant A keeps a white reflector neutral; unbalanced is warm.
  auto wl = grid(400, 1000, 40);
  auto white = torch::full({1, 1, 40}, 0.5f);
  auto lin = linear_of(pseudo_rgb(white, wl, a));
  EXPECT_NEAR(lin[0], lin[2], 1e-3);
  a.white_balance = false;
  lin = linear_of(pseudo_rgb(white, wl, a));
  EXPECT_GT(lin[0], 1.5 * lin[2]);

  auto dir = test::temp_dir("colour_map");
  std::ofstream(dir / "map.txt") << "# R G B rows\n1 0\n0 1\n0.5 0.5\n3 0\n";
  auto m = parse_pseudo_rgb("map:" + (dir / "map.txt").string());
  EXPECT_EQ(m.mode, PseudoRgbMode::LinearMap);
  EXPECT_EQ(m.band_indices, (std::vector<int64_t>{3, 0}));
  ASSERT_EQ(m.linear_map.sizes(), (std::vector<int64_t>{3, 2}));
  EXPECT_FLOAT_EQ(m.linear_map[2][1].item<float>(), 0.5f);

  std::ofstream(dir / "bad.txt") << "1 0\n0 1 2\n0 0\n";
  EXPECT_THROW(parse_pseudo_rgb("map:" + (dir / "bad.txt").string()), Error);
  EXPECT_THROW(parse_pseudo_rgb("map:" + (dir / "missing.txt").string()), Error);
  EXPECT_THROW(parse_pseudo_rgb("bands:650,550"), Error);
  EXPECT_THROW(parse_pseudo_rgb("cie:F2"), Error);
  EXPECT_THROW(parse_pseudo_rgb("hsv"), Error);
}

TEST(Colour, BadInputsThrow) {
  auto cube = torch::rand({2, 2, 4});
  EXPECT_THROW(pseudo_rgb(cube, {400, 500, 600}), Error);            // count mismatch
  EXPECT_THROW(pseudo_rgb(cube, {400, 500, 500, 600}), Error);       // not increasing
  EXPECT_THROW(pseudo_rgb(cube, {400, NAN, 500, 600}), Error);       // NaN
  EXPECT_THROW(pseudo_rgb(torch::rand({4, 4}), {400, 500}), Error);  // not [H, W, N]
  PseudoRgbOptions options;
  options.mode = PseudoRgbMode::LinearMap;
  options.linear_map = torch::rand({3, 3});
  EXPECT_THROW(pseudo_rgb(cube, {}, options), Error);  // 3 columns for 4 bands
  options.band_indices = {0, 1, 9};
  EXPECT_THROW(pseudo_rgb(cube, {}, options), Error);  // index out of range
  // A 3-band cube without wavelengths, or with an RGB dataset's (R, G, B at
  // 610, 550, 465 nm: decreasing), is RGB already.
  auto rgb = torch::rand({2, 2, 3});
  EXPECT_LT((pseudo_rgb(rgb, {}) - rgb).abs().max().item<float>(), 1e-6);
  EXPECT_LT((pseudo_rgb(rgb, rgb_channel_wavelengths_nm()) - rgb).abs().max().item<float>(), 1e-6);
  EXPECT_TRUE(is_rgb({}, 3));
  EXPECT_FALSE(is_rgb({465, 550, 610}, 3));  // a 3-band spectral camera
  EXPECT_FALSE(is_rgb({}, 4));
}

TEST(PseudoRgb, CieMapIsTheLinearPartOfPseudoRgb) {
  const std::vector<double> nm = {420, 480, 540, 600, 660, 720};
  auto cube = torch::rand({3, 2, 6}, torch::kFloat64) * 0.6 + 0.2;
  auto linear = cube.reshape({6, 6}).matmul(cie_linear_srgb_map(nm, Illuminant::D65));
  auto expected = srgb_encode(linear.clamp(0, 1)).reshape({3, 2, 3});
  EXPECT_LT((pseudo_rgb(cube, nm).to(torch::kFloat64) - expected).abs().max().item<double>(), 1e-6);
  EXPECT_FALSE(cie_linear_srgb_map({900, 1000}, Illuminant::D65).any().item<bool>());
}

}  // namespace
}  // namespace ddhgs::core
