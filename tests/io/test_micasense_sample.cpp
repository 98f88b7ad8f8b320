// MicaSense's own sample captures (tests/data/micasense-sample, MIT): a
// RedEdge panel capture whose panel lies off-centre beside its QR label.
// Every figure here is checked against the reference values of MicaSense's
// own library and its test suite for these files (tests/data/micasense-sample/
// README.md): the camera in pixels from older firmware's metadata, the DLS
// irradiance on level ground, and the panel found automatically with its raw
// counts, radiance and irradiance within 0.5 % in all five bands.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "io/rig/panel_finder.h"
#include "io/rig/rig_capture.h"
#include "io/rig/rig_radiometry.h"
#include "support/test_support.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;

const fs::path kSample = fs::path(DDHGS_SOURCE_DIR) / "tests/data/micasense-sample/0000SET/000";

RigCapture panel_capture() {
  RigCapture capture;
  for (int band = 1; band <= 5; ++band)
    capture.bands.push_back(
        read_rig_band_image(kSample / ("IMG_0000_" + std::to_string(band) + ".tif")));
  capture.id = capture.bands.front().capture_id;
  return capture;
}

// Whether (x, y) lies inside the convex quadrilateral `corners` (either winding).
bool inside(const std::array<std::array<double, 2>, 4>& corners, double x, double y) {
  int sign = 0;
  for (int i = 0; i < 4; ++i) {
    const auto& a = corners[size_t(i)];
    const auto& b = corners[size_t((i + 1) % 4)];
    const double cross = (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]);
    const int s = cross > 0 ? 1 : (cross < 0 ? -1 : 0);
    if (s == 0) continue;
    if (sign == 0) sign = s;
    if (s != sign) return false;
  }
  return true;
}

TEST(MicasenseSample, CameraInPixelsFromOlderFirmware) {
  // The focal length is written in pixels with no units tag, the principal
  // point in mm; MicaSense's test: 1449.4 px and (627.6, 479.9) px.
  const RigBandImage blue = read_rig_band_image(kSample / "IMG_0000_1.tif");
  EXPECT_EQ(blue.band_name, "Blue");
  EXPECT_EQ(blue.rig_index, 0);  // this rig numbers its cameras from 0
  EXPECT_EQ(blue.focal_length_units, "px");
  EXPECT_TRUE(blue.rig_relatives_deg.empty());  // older firmware: no RigRelatives
  const core::Intrinsics k = rig_intrinsics(blue);
  EXPECT_NEAR(k.fx, 1449.4, 0.1);
  EXPECT_NEAR(k.fy, 1449.4, 0.1);
  EXPECT_NEAR(k.cx, 627.6, 0.1);
  EXPECT_NEAR(k.cy, 479.9, 0.1);
}

TEST(MicasenseSample, DlsIrradianceAsTheMakerDefinesIt) {
  const RigBandImage blue = read_rig_band_image(kSample / "IMG_0000_1.tif");
  EXPECT_TRUE(blue.has_position);
  EXPECT_NEAR(blue.latitude_deg, 36.576096, 1e-6);
  EXPECT_NEAR(blue.longitude_deg, -119.4352689, 1e-6);
  EXPECT_NEAR(blue.altitude_m, 101.861, 1e-3);
  EXPECT_TRUE(blue.has_time);
  EXPECT_EQ(blue.radiometry.irradiance_tag, "SpectralIrradiance");
  EXPECT_NEAR(blue.radiometry.irradiance_raw, 1.0848248, 1e-6);
  // MicaSense's library: 1.010102 W/m^2/nm on level ground.
  EXPECT_NEAR(blue.radiometry.irradiance, 1.010102, 1e-3 * 1.010102)
      << blue.radiometry.irradiance_correction;
  EXPECT_NE(blue.radiometry.irradiance_correction.find("DLS 1"), std::string::npos);
}

TEST(MicasenseSample, PanelFoundInEveryBandMatchesTheReference) {
  const RigCapture capture = panel_capture();
  const std::vector<double> albedo = {0.67, 0.69, 0.68, 0.61, 0.67};
  const double raw[] = {45406.75, 46924.92, 53240.81, 56187.42, 54479.17};
  const double radiance[] = {0.170284, 0.179400, 0.162217, 0.106470, 0.130811};
  const double irradiance[] = {0.798451, 0.816815, 0.749442, 0.548338, 0.613364};
  const std::vector<ReflectanceCalibration> panel =
      panel_calibration(capture, capture.bands, albedo);
  ASSERT_EQ(panel.size(), 5u);
  for (size_t i = 0; i < 5; ++i) {
    const ReflectanceCalibration& c = panel[i];
    SCOPED_TRACE("band " + std::to_string(i + 1));
    EXPECT_TRUE(c.region.found);
    EXPECT_EQ(c.saturated, 0);
    EXPECT_NEAR(c.raw_mean / raw[i], 1, 0.005);
    EXPECT_NEAR(c.panel_radiance / radiance[i], 1, 0.005);
    EXPECT_NEAR(c.irradiance / irradiance[i], 1, 0.005);
    std::printf(
        "band %zu: %lld px, raw %.2f (%+.3f %%), radiance %.6f (%+.3f %%), irradiance "
        "%.6f (%+.3f %%)\n",
        i + 1, (long long)c.region.pixels, c.raw_mean, 100 * (c.raw_mean / raw[i] - 1),
        c.panel_radiance, 100 * (c.panel_radiance / radiance[i] - 1), c.irradiance,
        100 * (c.irradiance / irradiance[i] - 1));
  }
  // Band 1: every pixel measured lies inside MicaSense's panel corners (its
  // region is placed from the QR code, a few pixels off the panel's centre;
  // ours is the panel's middle two thirds).
  const std::array<std::array<double, 2>, 4> reference = {
      std::array<double, 2>{809, 613}, {648, 615}, {646, 454}, {808, 452}};
  const torch::Tensor at = panel[0].region.mask.nonzero();
  int64_t outside = 0;
  for (int64_t i = 0; i < at.size(0); ++i)
    outside +=
        !inside(reference, double(at[i][1].item<int64_t>()), double(at[i][0].item<int64_t>()));
  EXPECT_EQ(outside, 0);
  EXPECT_GT(panel[0].region.pixels, 0.75 * 26005 * 0.8);  // most of MicaSense's ~26,000
  for (const auto& corner : panel[0].region.corners)
    std::printf("band 1 region corner (%.0f, %.0f)\n", corner[0], corner[1]);
}

TEST(MicasenseSample, NoPanelWhereThePanelIsCovered) {
  // Band 1 with the panel painted over by the tarmac beside it: the QR label
  // and the instruction card remain, neither of which is a panel.
  const RigBandImage blue = read_rig_band_image(kSample / "IMG_0000_1.tif");
  torch::Tensor signal = band_signal(blue, read_band_counts(blue));
  ASSERT_TRUE(find_panel(signal).has_value());
  const torch::Tensor tarmac = signal.slice(0, 100, 300).slice(1, 100, 300).clone();
  for (int64_t y : {400, 480})
    for (int64_t x : {600, 660}) signal.slice(0, y, y + 200).slice(1, x, x + 200).copy_(tarmac);
  const std::optional<PanelRegion> none = find_panel(signal);
  EXPECT_FALSE(none.has_value()) << "found at (" << none->corners[0][0] << ", "
                                 << none->corners[0][1] << ") - (" << none->corners[2][0] << ", "
                                 << none->corners[2][1] << ")";
}

}  // namespace
}  // namespace ddhgs::io
