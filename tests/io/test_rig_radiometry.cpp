// Rig radiometry: metadata written and read back field by field, one pixel's
// radiance against the sensor model worked by hand, and reflectance recovered
// through the panel path and the DLS path from counts written with known
// reflectance, irradiance, exposure, gain and vignetting.
#include "io/rig/rig_radiometry.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "core/error.h"
#include "support/error_text.h"
#include "support/rig_tiff.h"
#include "support/test_support.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;

using test::error_of;

constexpr double kPi = 3.14159265358979323846;

// A band image's metadata as a MicaSense RedEdge would write it.
RigBandImage band(const fs::path& file, int index, double exposure_s, double iso) {
  static const char* names[] = {"Blue", "Green", "Red"};
  static const double centres[] = {475, 560, 668};
  RigBandImage b;
  b.file = file;
  b.capture_id = file.stem().string().substr(0, 8);
  b.rig_index = index;
  b.band_name = names[index - 1];
  b.centre_nm = centres[index - 1];
  b.fwhm_nm = 20;
  b.focal_length_mm = 5.4;
  b.principal_point_mm = {2.4, 1.8};
  b.rig_relatives_deg = {0.1 * index, -0.2, 0.05};
  b.width = 40;
  b.height = 30;
  b.bits = 16;
  RigRadiometry& r = b.radiometry;
  r.black_level = 4800;
  r.has_black_level = true;
  r.exposure_s = exposure_s;
  r.iso_speed = iso;
  r.calibration = {2.9e-4 + 1e-5 * index, 1.2e-6, 1.5e-5};
  r.vignetting_centre_px = {19.0 + index, 14.5};
  r.vignetting_polynomial = {-2e-3, 4e-5, -1e-7};
  return b;
}

TEST(RigRadiometry, MetadataReadsBackAsWritten) {
  const fs::path dir = test::temp_dir("rig_radiometry_meta");
  RigBandImage b = band(dir / "IMG_0001_2.tif", 2, 0.0013, 200);
  b.distortion = {-0.1, 0.2, -0.05, 0.001, -0.002};
  b.radiometry.irradiance = 1.125;
  write_rig_band_image(b, torch::full({b.height, b.width}, 9000.0));
  const RigBandImage r = read_rig_band_image(b.file);
  EXPECT_EQ(r.capture_id, b.capture_id);
  EXPECT_EQ(r.rig_index, 2);
  EXPECT_EQ(r.band_name, "Green");
  EXPECT_EQ(r.centre_nm, 560);
  EXPECT_EQ(r.principal_point_mm, b.principal_point_mm);
  EXPECT_EQ(r.distortion, b.distortion);
  EXPECT_EQ(r.rig_relatives_deg, b.rig_relatives_deg);
  EXPECT_EQ(r.width, 40);
  EXPECT_EQ(r.height, 30);
  EXPECT_TRUE(r.radiometry.has_black_level);
  EXPECT_EQ(r.radiometry.black_level, 4800);
  EXPECT_NEAR(r.radiometry.exposure_s, 0.0013, 1e-9);  // an EXIF rational
  EXPECT_EQ(r.radiometry.iso_speed, 200);
  EXPECT_EQ(r.radiometry.gain(), 2);
  EXPECT_EQ(r.radiometry.calibration, b.radiometry.calibration);
  EXPECT_EQ(r.radiometry.vignetting_centre_px, b.radiometry.vignetting_centre_px);
  EXPECT_EQ(r.radiometry.vignetting_polynomial, b.radiometry.vignetting_polynomial);
  EXPECT_EQ(r.radiometry.irradiance, 1.125);
  EXPECT_EQ(r.radiometry.irradiance_tag, "SpectralIrradiance");
  EXPECT_EQ(read_band_counts(r)[7][3].item<float>(), 9000);
}

// A DLS 2 reports HorizontalIrradiance in 1/100 W/m^2/nm unless it states
// its scale; MicaSense's metadata documentation.
TEST(RigRadiometry, IrradianceScale) {
  const fs::path dir = test::temp_dir("rig_radiometry_dls");
  std::string xmp = test::rig_xmp({"c1", 1, "Blue", 475, 32, "0,0,0"});
  const std::string with_dls =
      "Camera:HorizontalIrradiance=\"123\" Camera:SpectralIrradiance=\"2\" ";
  std::string dls2 = xmp;
  dls2.insert(dls2.find("Camera:BandName"), with_dls);
  test::write_band_tiff(dir / "a_1.tif", dls2);
  EXPECT_DOUBLE_EQ(read_rig_band_image(dir / "a_1.tif").radiometry.irradiance, 1.23);
  EXPECT_EQ(read_rig_band_image(dir / "a_1.tif").radiometry.irradiance_tag, "HorizontalIrradiance");
  std::string scaled = xmp;
  scaled.insert(scaled.find("Camera:BandName"),
                with_dls + "Camera:IrradianceScaleToSIUnits=\"0.001\" ");
  test::write_band_tiff(dir / "b_1.tif", scaled);
  EXPECT_DOUBLE_EQ(read_rig_band_image(dir / "b_1.tif").radiometry.irradiance, 0.123);
  std::string dls1 = xmp;
  dls1.insert(dls1.find("Camera:BandName"), "Camera:Irradiance=\"0.9\" ");
  test::write_band_tiff(dir / "c_1.tif", dls1);
  EXPECT_DOUBLE_EQ(read_rig_band_image(dir / "c_1.tif").radiometry.irradiance, 0.9);
  // No DLS, no radiometry: both named.
  test::write_band_tiff(dir / "d_1.tif", xmp);
  const RigBandImage none = read_rig_band_image(dir / "d_1.tif");
  EXPECT_EQ(none.radiometry.irradiance, 0);
  const std::string missing = error_of([&] { require_radiometry(none); });
  EXPECT_NE(missing.find("d_1.tif"), std::string::npos) << missing;
  EXPECT_NE(missing.find("ExposureTime"), std::string::npos) << missing;
  const std::string no_dls = error_of([&] { reflectance_calibration(none, {}); });
  EXPECT_NE(no_dls.find("d_1.tif"), std::string::npos) << no_dls;
  EXPECT_NE(no_dls.find("no panel"), std::string::npos) << no_dls;
}

// One pixel through the published model, each factor worked out here.
TEST(RigRadiometry, RadianceOfOnePixelByHand) {
  RigBandImage b = band("hand.tif", 1, 0.002, 200);
  const int x = 31, y = 22;
  const double count = 23456;
  torch::Tensor counts = torch::full({b.height, b.width}, 5000.0f);
  counts[y][x] = float(count);
  counts[0][0] = 1000;  // below the black level: radiance 0
  const torch::Tensor radiance = counts_to_radiance(b, counts);
  const double r = std::hypot(x - 20.0, y - 14.5);
  const double v = 1 / (1 - 2e-3 * r + 4e-5 * r * r - 1e-7 * r * r * r);
  const double a1 = 3.0e-4, a2 = 1.2e-6, a3 = 1.5e-5;
  const double row = 1 / (1 + a2 * y / 0.002 - a3 * y);
  const double expected = v * row * (count - 4800) / (2.0 * 0.002) * a1 / 65536;
  EXPECT_NEAR(radiance[y][x].item<double>(), expected, 1e-6 * expected);
  EXPECT_EQ(radiance[0][0].item<float>(), 0);
  // The vignetting centre reads 1; the inverse returns the counts.
  EXPECT_NEAR(vignetting_correction(b)[14][20].item<double>(),
              1 / (1 - 2e-3 * 0.5 + 4e-5 * 0.25 - 1e-7 * 0.125), 1e-6);
  EXPECT_NEAR(radiance_to_counts(b, radiance)[y][x].item<double>(), count, 1e-2);
}

// Known reflectance, irradiance per band; the panel and the flight capture
// at different exposures and gains; counts rounded to 16 bits as a camera
// stores them. Reflectance comes back within 0.5 % through the panel and
// through the DLS.
TEST(RigRadiometry, ReflectanceThroughThePanelAndTheDls) {
  const fs::path dir = test::temp_dir("rig_radiometry_panel");
  const double irradiance[] = {0.9, 1.1, 1.25};  // W/m^2/nm
  const std::vector<double> albedo = {0.52, 0.53, 0.55};
  RigCapture panel{"panel", {}}, flight{"flight", {}};
  const torch::Tensor yy = torch::arange(30, torch::kFloat).unsqueeze(1);
  const torch::Tensor xx = torch::arange(40, torch::kFloat).unsqueeze(0);
  const torch::Tensor truth = 0.08 + 0.5 * (0.5 + 0.5 * torch::sin(0.3 * xx + 0.2 * yy));
  for (int i = 1; i <= 3; ++i) {
    RigBandImage p = band(dir / ("PANL_000_" + std::to_string(i) + ".tif"), i, 0.0008, 100);
    const torch::Tensor panel_radiance =
        torch::full({30, 40}, float(albedo[i - 1] * irradiance[i - 1] / kPi));
    write_rig_band_image(p, radiance_to_counts(p, panel_radiance));
    panel.bands.push_back(read_rig_band_image(p.file));
    RigBandImage f = band(dir / ("IMG_0001_" + std::to_string(i) + ".tif"), i, 0.00045, 200);
    f.radiometry.irradiance = irradiance[i - 1];
    write_rig_band_image(f, radiance_to_counts(f, truth * float(irradiance[i - 1] / kPi)));
    flight.bands.push_back(read_rig_band_image(f.file));
  }
  const std::vector<ReflectanceCalibration> calibration =
      panel_calibration(panel, flight.bands, albedo);
  ASSERT_EQ(calibration.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(calibration[i].source, "panel");
    EXPECT_NEAR(calibration[i].panel_radiance, albedo[i] * irradiance[i] / kPi,
                2e-3 * calibration[i].panel_radiance);
    // The panel reads back at its albedo.
    const torch::Tensor panel_reflectance = read_band_reflectance(panel.bands[i], calibration[i]);
    EXPECT_NEAR(panel_reflectance.mean().item<double>(), albedo[i], 1e-3);
    // The flight's reflectance through the panel, then through the DLS.
    const ReflectanceCalibration by_panel = reflectance_calibration(flight.bands[i], calibration);
    EXPECT_EQ(by_panel.source, "panel");
    const torch::Tensor from_panel = read_band_reflectance(flight.bands[i], by_panel);
    EXPECT_LT(((from_panel - truth).abs() / truth).max().item<double>(), 5e-3) << "band " << i;
    const ReflectanceCalibration by_dls = reflectance_calibration(flight.bands[i], {});
    EXPECT_EQ(by_dls.source, "DLS");
    EXPECT_NEAR(by_dls.factor, kPi / irradiance[i], 1e-12);
    const torch::Tensor from_dls = read_band_reflectance(flight.bands[i], by_dls);
    EXPECT_LT(((from_dls - truth).abs() / truth).max().item<double>(), 5e-3) << "band " << i;
  }
}

TEST(RigRadiometry, PanelErrorsNameTheFile) {
  const fs::path dir = test::temp_dir("rig_radiometry_bad_panel");
  RigBandImage p = band(dir / "PANL_000_1.tif", 1, 0.0008, 100);
  write_rig_band_image(p, torch::full({30, 40}, 65535.0));
  const RigCapture panel{"panel", {read_rig_band_image(p.file)}};
  const std::string count = error_of([&] { panel_calibration(panel, panel.bands, {0.5, 0.5}); });
  EXPECT_NE(count.find("PANL_000_1.tif"), std::string::npos) << count;
  EXPECT_NE(count.find("1 band cameras but 2 panel albedo"), std::string::npos) << count;
  const std::string range = error_of([&] { panel_calibration(panel, panel.bands, {1.5}); });
  EXPECT_NE(range.find("not in (0, 1]"), std::string::npos) << range;
  const std::string saturated = error_of([&] { panel_calibration(panel, panel.bands, {0.5}); });
  EXPECT_NE(saturated.find("PANL_000_1.tif"), std::string::npos) << saturated;
  EXPECT_NE(saturated.find("saturated"), std::string::npos) << saturated;
  write_rig_band_image(p, torch::full({30, 40}, 100.0));  // under the black level
  const RigCapture dark{"panel", {read_rig_band_image(p.file)}};
  EXPECT_NE(error_of([&] { panel_calibration(dark, dark.bands, {0.5}); }).find("no signal"),
            std::string::npos);
  // A flight camera the panel capture lacks.
  RigBandImage other = band(dir / "IMG_0001_2.tif", 2, 0.001, 100);
  ReflectanceCalibration blue;
  blue.rig_index = 1;
  blue.band = "Blue";
  blue.centre_nm = 475;
  blue.factor = 1;
  blue.source = "panel";
  const std::vector<ReflectanceCalibration> calibration = {blue};
  EXPECT_NE(error_of([&] {
              reflectance_calibration(other, calibration);
            }).find("not in the panel capture"),
            std::string::npos);
}

// Panel files are matched to the flight's cameras by band, not by index: a
// panel capture whose Blue and Green files carry each other's camera numbers
// still calibrates Blue with the Blue panel.
TEST(RigRadiometry, PanelBandsMatchByNameNotIndex) {
  const fs::path dir = test::temp_dir("rig_radiometry_swapped");
  const double irradiance[] = {0.9, 1.3};
  RigCapture panel{"panel", {}};
  std::vector<RigBandImage> cameras;
  for (int i = 1; i <= 2; ++i) {
    RigBandImage p = band(dir / ("PANL_000_" + std::to_string(i) + ".tif"), i, 0.0008, 100);
    p.rig_index = 3 - i;  // swapped
    write_rig_band_image(
        p, radiance_to_counts(p, torch::full({30, 40}, float(0.5 * irradiance[i - 1] / kPi))));
    panel.bands.push_back(read_rig_band_image(p.file));
    cameras.push_back(band(dir / ("IMG_0001_" + std::to_string(i) + ".tif"), i, 0.001, 100));
  }
  const std::vector<ReflectanceCalibration> calibration =
      panel_calibration(panel, cameras, {0.5, 0.5});
  ASSERT_EQ(calibration.size(), 2u);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(calibration[size_t(i)].band, cameras[size_t(i)].band_name);
    EXPECT_NEAR(calibration[size_t(i)].irradiance, irradiance[i], 2e-3 * irradiance[i]);
    EXPECT_EQ(reflectance_calibration(cameras[size_t(i)], calibration).panel_file,
              panel.bands[size_t(i)].file);
  }
  // A band the panel capture lacks is named with what it holds.
  RigBandImage red = band(dir / "IMG_0001_3.tif", 3, 0.001, 100);
  const std::string missing = error_of([&] { panel_calibration(panel, {red}, {0.5}); });
  EXPECT_NE(missing.find("band Red (668 nm) has no image in the panel capture"), std::string::npos)
      << missing;
}

// Every value the radiometry uses is range-checked as the file is read: one
// error naming the file, the tag and the value.
TEST(RigRadiometry, ImplausibleMetadataIsNamed) {
  const fs::path dir = test::temp_dir("rig_radiometry_implausible");
  struct Case {
    const char* name;
    std::function<void(RigBandImage&)> edit;
    std::vector<std::string> said;
  };
  const std::vector<Case> cases = {
      {"negative_wavelength",
       [](RigBandImage& b) { b.centre_nm = -5; },
       {"CentralWavelength", "-5"}},
      {"zero_wavelength", [](RigBandImage& b) { b.centre_nm = 0; }, {"CentralWavelength", "0"}},
      {"zero_a1",
       [](RigBandImage& b) { b.radiometry.calibration[0] = 0; },
       {"RadiometricCalibration a1", "is 0"}},
      {"negative_a1",
       [](RigBandImage& b) { b.radiometry.calibration[0] = -3e-4; },
       {"RadiometricCalibration a1", "-0.0003"}},
      {"vignetting_negative",
       [](RigBandImage& b) { b.radiometry.vignetting_polynomial = {-0.1}; },
       {"VignettingPolynomial", "negative"}},
      {"black_level_at_range",
       [](RigBandImage& b) { b.radiometry.black_level = 65535; },
       {"BlackLevel", "65535", "16-bit"}},
      {"tiny_irradiance",
       [](RigBandImage& b) { b.radiometry.irradiance = 1e-300; },
       {"SpectralIrradiance", "1e-300"}},
      {"huge_exposure",
       [](RigBandImage& b) { b.radiometry.exposure_s = 1e9; },
       {"ExposureTime", "1e+09"}},
  };
  for (const Case& c : cases) {
    RigBandImage b = band(dir / (std::string(c.name) + "_1.tif"), 1, 0.001, 100);
    c.edit(b);
    write_rig_band_image(b, torch::full({b.height, b.width}, 9000.0));
    const std::string message = error_of([&] { read_rig_band_image(b.file); });
    EXPECT_NE(message.find(b.file.string()), std::string::npos) << c.name << ": " << message;
    for (const std::string& word : c.said)
      EXPECT_NE(message.find(word), std::string::npos) << c.name << ": " << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
}

}  // namespace
}  // namespace ddhgs::io
