// core/band_map.h: interpolation to other wavelengths and response-function
// maps, against hand-computed weights.
#include <gtest/gtest.h>

#include "core/band_map.h"
#include "core/error.h"

namespace ddhgs::core {
namespace {

TEST(BandMap, InterpolatesBetweenCapturedBandsAndKeepsCapturedOnes) {
  const std::vector<double> bands = {400, 500, 600, 800};
  const torch::Tensor map = interpolation_map(bands, {400, 450, 575, 700, 800});
  const torch::Tensor expected = torch::tensor({{1.0, 0.0, 0.0, 0.0},
                                                {0.5, 0.5, 0.0, 0.0},
                                                {0.0, 0.25, 0.75, 0.0},
                                                {0.0, 0.0, 0.5, 0.5},
                                                {0.0, 0.0, 0.0, 1.0}},
                                               torch::kFloat64);
  EXPECT_TRUE(torch::allclose(map, expected, 0, 1e-12)) << map;
  EXPECT_THROW(interpolation_map(bands, {399}), Error);
  EXPECT_THROW(interpolation_map(bands, {801}), Error);
  EXPECT_THROW(interpolation_map({500, 400}, {450}), Error);
}

TEST(BandMap, ParsesRangesAndLists) {
  const auto range = parse_wavelength_list("450:950:5", "--wavelengths");
  ASSERT_EQ(range.size(), 101u);
  EXPECT_DOUBLE_EQ(range.front(), 450);
  EXPECT_DOUBLE_EQ(range.back(), 950);
  EXPECT_EQ(parse_wavelength_list("550, 670.5", "--wavelengths"),
            (std::vector<double>{550, 670.5}));
  for (const char* bad : {"450:950", "950:450:5", "450:950:0", "a,b", "450::5", "1:1e9:1e-3"})
    EXPECT_THROW(parse_wavelength_list(bad, "--wavelengths"), Error) << bad;
}

TEST(BandMap, ResponseIsTheResponseWeightedMeanOfTheInterpolatedBands) {
  const std::vector<double> bands = {400, 500, 600};
  ResponseFunctions r;
  r.wavelengths_nm = {450, 500, 550, 650};  // 650 lies outside the bands
  r.channels = {"a", "flat"};
  r.values = torch::tensor({{1.0, 1.0}, {2.0, 1.0}, {1.0, 1.0}, {4.0, 1.0}}, torch::kFloat64);
  const ResponseMap m = response_map(r, bands);
  // Trapezoid weights 25, 50, 75, 50; sample 650 is dropped. Channel a:
  // 25 x 1 at 450 (0.5/0.5 of bands 0, 1), 50 x 2 at 500 (band 1), 75 x 1 at
  // 550 (0.5/0.5 of bands 1, 2): 12.5, 12.5 + 100 + 37.5, 37.5 over 200.
  const torch::Tensor expected_a = torch::tensor({12.5, 150.0, 37.5}, torch::kFloat64) / 200.0;
  EXPECT_TRUE(torch::allclose(m.map[0], expected_a, 0, 1e-12)) << m.map[0];
  EXPECT_NEAR(m.centres_nm[0], (25 * 450 + 100 * 500 + 75 * 550) / 200.0, 1e-9);
  EXPECT_NEAR(m.captured[0], 200.0 / (200.0 + 200.0), 1e-12);  // 650: 50 x 4 = 200 left out
  EXPECT_NEAR(m.map[1].sum().item<double>(), 1.0, 1e-12);

  ResponseFunctions outside = r;
  outside.wavelengths_nm = {700, 710, 720, 730};
  EXPECT_THROW(response_map(outside, bands), Error);
}

}  // namespace
}  // namespace ddhgs::core
