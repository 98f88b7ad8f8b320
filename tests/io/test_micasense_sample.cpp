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

#include "core/distortion.h"
#include "io/rig/panel_finder.h"
#include "io/rig/panel_label.h"
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

// How far (x, y) lies inside the convex quadrilateral `corners` (either
// winding): its least distance to an edge's line, negative outside.
double depth_inside(const std::array<std::array<double, 2>, 4>& corners, double x, double y) {
  double area2 = 0;
  for (size_t i = 0; i < 4; ++i)
    area2 += corners[i][0] * corners[(i + 1) % 4][1] - corners[(i + 1) % 4][0] * corners[i][1];
  double depth = 1e300;
  for (size_t i = 0; i < 4; ++i) {
    const auto& a = corners[i];
    const auto& b = corners[(i + 1) % 4];
    const double cross = (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]);
    depth = std::min(depth, (area2 > 0 ? cross : -cross) / std::hypot(b[0] - a[0], b[1] - a[1]));
  }
  return depth;
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
    EXPECT_EQ(c.region.label, "RP02-1603036-SC");  // placed from the QR label
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
  // Band 1, compared in MicaSense's frame. Its library places the region
  // from the QR label in the undistorted image, whose camera is OpenCV's
  // getOptimalNewCameraMatrix with alpha 1 (io::maker_pinhole; the figures
  // below are numpy's reimplementation of OpenCV's, on this file's lens).
  // The reference corners are mapped from there into the raw image (through
  // our lens model) and ours compared with them.
  const RigBandImage& blue = capture.bands[0];
  const core::Intrinsics lens = rig_intrinsics(blue);
  const core::Intrinsics maker = maker_pinhole(lens);
  EXPECT_NEAR(maker.fx, 1424.1, 0.1);
  EXPECT_NEAR(maker.cx, 628.2, 0.1);
  EXPECT_NEAR(maker.cy, 480.1, 0.1);
  const double fx = maker.fx, fy = maker.fy, cx = maker.cx, cy = maker.cy;
  std::printf("MicaSense's frame: focal %.2f %.2f px, principal point (%.2f, %.2f)\n", fx, fy, cx,
              cy);
  const double corners_there[4][2] = {{646, 454}, {808, 452}, {809, 613}, {648, 615}};
  std::array<std::array<double, 2>, 4> reference;
  for (size_t i = 0; i < 4; ++i) {
    const core::Point2 d =
        core::distort(lens, {(corners_there[i][0] - cx) / fx, (corners_there[i][1] - cy) / fy});
    reference[i] = {lens.fx * d.x + lens.cx, lens.fy * d.y + lens.cy};
  }
  EXPECT_EQ(panel[0].region.label, "RP02-1603036-SC");
  for (size_t i = 0; i < 4; ++i) {
    const auto& ours = panel[0].region.corners[i];
    const double apart = std::hypot(ours[0] - reference[i][0], ours[1] - reference[i][1]);
    std::printf(
        "band 1 corner (%.1f, %.1f), MicaSense's (%.1f, %.1f) in this frame: %.1f px apart\n",
        ours[0], ours[1], reference[i][0], reference[i][1], apart);
    EXPECT_LT(apart, 5.0);
  }
  // Every pixel measured lies inside them, to within half a pixel (MicaSense's
  // corners are whole pixels).
  const torch::Tensor at = panel[0].region.mask.nonzero();
  double deepest_out = 0;
  for (int64_t i = 0; i < at.size(0); ++i)
    deepest_out = std::min(deepest_out, depth_inside(reference, double(at[i][1].item<int64_t>()),
                                                     double(at[i][0].item<int64_t>())));
  std::printf("band 1: no pixel more than %.2f px outside MicaSense's corners\n", -deepest_out);
  EXPECT_GT(deepest_out, -0.5);
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

TEST(MicasenseSample, LabelPlacesTheRegionOnlyWhereItIsRead) {
  const RigBandImage blue = read_rig_band_image(kSample / "IMG_0000_1.tif");
  const core::Intrinsics lens = rig_intrinsics(blue);
  torch::Tensor signal = band_signal(blue, read_band_counts(blue));
  const std::optional<PanelRegion> placed = find_labelled_panel(signal, lens);
  ASSERT_TRUE(placed.has_value());
  EXPECT_EQ(placed->label, "RP02-1603036-SC");
  EXPECT_LT(placed->spread, 0.03);  // the panel: 2.2 % with the lens's vignetting
  // The label's corners, in the raw image, around the code (MicaSense's,
  // in its undistorted frame: (460, 599), (583, 599), (584, 478), (462, 477)).
  double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9;
  for (const auto& c : placed->label_corners)
    x0 = std::min(x0, c[0]), x1 = std::max(x1, c[0]), y0 = std::min(y0, c[1]),
    y1 = std::max(y1, c[1]);
  EXPECT_NEAR(x0, 458, 3);
  EXPECT_NEAR(x1, 582, 3);
  EXPECT_NEAR(y0, 476, 3);
  EXPECT_NEAR(y1, 601, 3);
  // The panel painted over by the tarmac beside it: the label still places
  // the region, which now holds tarmac: darker than the finder asks of a panel.
  torch::Tensor covered = signal.clone();
  const torch::Tensor tarmac = signal.slice(0, 100, 300).slice(1, 100, 300).clone();
  for (int64_t y : {400, 480})
    for (int64_t x : {600, 660}) covered.slice(0, y, y + 200).slice(1, x, x + 200).copy_(tarmac);
  const std::optional<PanelRegion> on_tarmac = find_labelled_panel(covered, lens);
  ASSERT_TRUE(on_tarmac.has_value());
  EXPECT_LT(covered.masked_select(on_tarmac->mask).mean().item<double>(),
            0.25 * signal.masked_select(placed->mask).mean().item<double>());
  // The label painted over: no label read, nothing placed.
  torch::Tensor unlabelled = signal.clone();
  unlabelled.slice(0, 440, 640).slice(1, 420, 620).copy_(tarmac);
  EXPECT_FALSE(find_labelled_panel(unlabelled, lens).has_value());
  EXPECT_TRUE(find_panel(unlabelled).has_value());  // the panel itself is still found
}

}  // namespace
}  // namespace ddhgs::io
