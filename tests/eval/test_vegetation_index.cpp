// Vegetation indices: which bands make each broad band, the index of a pixel
// against hand-computed values, and its picture's colours.
#include "eval/vegetation_index.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "core/error.h"

namespace ddhgs::eval {
namespace {

std::vector<double> row(const torch::Tensor& map, int64_t r) {
  torch::Tensor c = map[r].contiguous();
  return {c.data_ptr<double>(), c.data_ptr<double>() + c.numel()};
}

TEST(VegetationIndex, AFiveBandCameraUsesItsOwnBands) {
  // MicaSense RedEdge-MX: blue, green, red, red edge, NIR.
  const std::vector<double> wl = {475, 560, 668, 717, 842};
  EXPECT_EQ(row(index_band_map(find_vegetation_index("ndvi", "--index"), wl), 0),
            (std::vector<double>{0, 0, 0, 0, 1}));
  EXPECT_EQ(row(index_band_map(find_vegetation_index("ndvi", "--index"), wl), 1),
            (std::vector<double>{0, 0, 1, 0, 0}));
  EXPECT_EQ(row(index_band_map(find_vegetation_index("ndre", "--index"), wl), 1),
            (std::vector<double>{0, 0, 0, 1, 0}));
  EXPECT_EQ(row(index_band_map(find_vegetation_index("gndvi", "--index"), wl), 1),
            (std::vector<double>{0, 1, 0, 0, 0}));
}

TEST(VegetationIndex, AHyperspectralSensorAveragesTheBandsInEachWindow) {
  std::vector<double> wl;
  for (int w = 400; w <= 1100; w += 5) wl.push_back(w);
  const torch::Tensor map = index_band_map(find_vegetation_index("ndvi", "--index"), wl);
  // Red: 668 +- 7 nm holds 665, 670 and 675 nm (bands 53, 54, 55).
  std::vector<double> red(wl.size(), 0.0);
  red[53] = red[54] = red[55] = 1.0 / 3;
  const std::vector<double> got = row(map, 1);
  for (size_t i = 0; i < wl.size(); ++i) EXPECT_NEAR(got[i], red[i], 1e-15) << wl[i];
  // NIR: 842 +- 28.5 nm holds 815 ... 870 nm: 12 bands.
  const std::vector<double> nir = row(map, 0);
  for (size_t i = 0; i < wl.size(); ++i)
    EXPECT_NEAR(nir[i], wl[i] >= 815 && wl[i] <= 870 ? 1.0 / 12 : 0.0, 1e-15) << wl[i];
}

TEST(VegetationIndex, AWindowWithoutBandsInterpolatesAtItsCentre) {
  const std::vector<double> wl = {400, 700, 1000};
  const std::vector<double> red =
      row(index_band_map(find_vegetation_index("ndvi", "--index"), wl), 1);
  EXPECT_NEAR(red[0], 32.0 / 300, 1e-12);  // 668 nm: 32 nm below 700
  EXPECT_NEAR(red[1], 268.0 / 300, 1e-12);
  EXPECT_EQ(red[2], 0.0);
}

TEST(VegetationIndex, BandsOutsideTheSensorAreNamed) {
  try {
    index_band_map(find_vegetation_index("ndvi", "--index"), {400, 500, 700});
    FAIL() << "no error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("ndvi: the NIR band at 842 nm"), std::string::npos)
        << e.what();
  }
  try {
    find_vegetation_index("evi", "--index");
    FAIL() << "no error";
  } catch (const core::Error& e) {
    EXPECT_EQ(std::string(e.what()), "--index: unknown index 'evi' (one of ndvi, ndre, gndvi)");
  }
}

TEST(VegetationIndex, ValuesMatchHandComputedPixels) {
  // Two bands, NIR and red, as a [1, 3, 2] image: a plant, bare soil, black.
  const std::vector<double> wl = {668, 842};
  const torch::Tensor map = index_band_map(find_vegetation_index("ndvi", "--index"), wl);
  const torch::Tensor image =
      torch::tensor({0.05f, 0.45f, 0.20f, 0.25f, 0.0f, 0.0f}).view({1, 3, 2});
  const torch::Tensor v = index_values(image, map);
  ASSERT_EQ(v.sizes(), (torch::IntArrayRef{1, 3}));
  EXPECT_NEAR(v[0][0].item<double>(), (0.45 - 0.05) / (0.45 + 0.05), 1e-6);  // 0.8
  EXPECT_NEAR(v[0][1].item<double>(), (0.25 - 0.20) / (0.25 + 0.20), 1e-6);  // 0.111
  EXPECT_TRUE(std::isnan(v[0][2].item<double>()));                           // no signal
}

TEST(VegetationIndex, PictureRunsFromRedThroughYellowToGreenAndGreysNaN) {
  const torch::Tensor p =
      index_picture(torch::tensor({-1.0f, 0.0f, 1.0f, float(NAN)}).view({1, 4}));
  auto rgb = [&](int i) {
    return std::vector<double>{p[0][i][0].item<double>(), p[0][i][1].item<double>(),
                               p[0][i][2].item<double>()};
  };
  // ColorBrewer RdYlGn's ends and middle: #a50026, #ffffbf, #006837 (0 falls
  // half a step of the 256-entry table past the middle anchor: within 2/255).
  auto near = [](const std::vector<double>& got, std::vector<double> want) {
    for (size_t c = 0; c < 3; ++c) EXPECT_NEAR(got[c], want[c] / 255, 2.0 / 255) << c;
  };
  near(rgb(0), {0xa5, 0x00, 0x26});
  near(rgb(1), {0xff, 0xff, 0xbf});
  near(rgb(2), {0x00, 0x68, 0x37});
  EXPECT_EQ(rgb(3), (std::vector<double>{0.5, 0.5, 0.5}));
}

}  // namespace
}  // namespace ddhgs::eval
