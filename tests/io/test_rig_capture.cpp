// Rig captures: XMP properties in both of XMP's forms, band images read
// back from TIFFs written with known metadata, and the checks on a folder of
// captures (a band missing, two captures mixed, an unknown rig).
#include "io/rig/rig_capture.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "core/error.h"
#include "io/files/atomic_file.h"
#include "support/error_text.h"
#include "support/rig_tiff.h"
#include "support/test_support.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;

using test::error_of;

TEST(Xmp, AttributesElementsAndLists) {
  const std::string xmp =
      "<rdf:Description Camera:BandName=\"Red edge\" Camera:BandNameX=\"no\"\n"
      "  MicaSense:CaptureId='a&amp;b' Camera:PrincipalPoint=\"2.27, 1.80\">\n"
      "<Camera:CentralWavelength>717</Camera:CentralWavelength>\n"
      "<Camera:VignettingPolynomial><rdf:Seq><rdf:li>-1e-4</rdf:li>\n"
      "<rdf:li>2.5e-7</rdf:li></rdf:Seq></Camera:VignettingPolynomial>\n"
      "<drone-dji:GpsLatitude>22.5</drone-dji:GpsLatitude></rdf:Description>";
  EXPECT_EQ(xmp_property(xmp, "BandName"), "Red edge");
  EXPECT_EQ(xmp_property(xmp, "CaptureId"), "a&b");
  EXPECT_EQ(xmp_property(xmp, "CentralWavelength"), "717");
  EXPECT_EQ(xmp_property(xmp, "GpsLatitude"), "22.5");
  EXPECT_EQ(xmp_property(xmp, "Band"), std::nullopt);                  // no partial names
  EXPECT_EQ(xmp_property(xmp, "VignettingPolynomial"), std::nullopt);  // a list
  EXPECT_EQ(xmp_list(xmp, "VignettingPolynomial"), (std::vector<std::string>{"-1e-4", "2.5e-7"}));
  EXPECT_EQ(xmp_list(xmp, "PrincipalPoint"), (std::vector<std::string>{"2.27", "1.80"}));
  EXPECT_TRUE(xmp_list(xmp, "RigRelatives").empty());
  // A list of one item is a value (Parrot's Sequoia writes BandName so).
  const std::string parrot =
      "<Camera:BandName>\n<rdf:Seq>\n<rdf:li>Green</rdf:li>\n</rdf:Seq>\n</Camera:BandName>";
  EXPECT_EQ(xmp_property(parrot, "BandName"), "Green");
  EXPECT_EQ(xmp_list(parrot, "BandName"), (std::vector<std::string>{"Green"}));
  const std::string nested = "<Camera:Lens><Camera:Model>x</Camera:Model></Camera:Lens>";
  EXPECT_EQ(xmp_property(nested, "Lens"), std::nullopt);
  EXPECT_TRUE(xmp_list(nested, "Lens").empty());
}

TEST(RigCapture, ReadsABandImagesMetadata) {
  const fs::path dir = test::temp_dir("rig_band");
  test::RigBandSpec spec{"cap7", 4, "Red edge", 717, 12, "0.25,-0.5,1.0"};
  test::write_band_tiff(dir / "IMG_0007_4.tif", test::rig_xmp(spec));
  const RigBandImage b = read_rig_band_image(dir / "IMG_0007_4.tif");
  EXPECT_EQ(b.capture_id, "cap7");
  EXPECT_EQ(b.rig_index, 4);
  EXPECT_EQ(b.band_name, "Red edge");
  EXPECT_EQ(b.centre_nm, 717);
  EXPECT_EQ(b.fwhm_nm, 12);
  EXPECT_EQ(b.focal_length_mm, 5.4);
  EXPECT_EQ(b.principal_point_mm, (std::vector<double>{2.4, 1.8}));
  EXPECT_EQ(b.distortion, (std::vector<double>{-0.1, 0.2, -0.05, 0.001, -0.002}));
  EXPECT_EQ(b.rig_relatives_deg, (std::vector<double>{0.25, -0.5, 1.0}));
  EXPECT_EQ(b.width, 16);
  EXPECT_EQ(b.height, 12);
  EXPECT_EQ(b.bits, 16);
}

TEST(RigCapture, UnknownRigsAndFilesWithoutXmpAreNamed) {
  const fs::path dir = test::temp_dir("rig_unknown");
  test::write_band_tiff(dir / "plain.tif", "");
  EXPECT_EQ(error_of([&] { read_rig_band_image(dir / "plain.tif"); }),
            (dir / "plain.tif").string() +
                ": has no XMP metadata: not a band image of a multispectral rig");
  test::write_band_tiff(dir / "other.tif", "<rdf:Description drone-dji:GpsLatitude=\"1\"/>");
  EXPECT_NE(error_of([&] {
              read_rig_band_image(dir / "other.tif");
            }).find("a rig this reader does not know"),
            std::string::npos);
  // A Parrot Sequoia's band image: a fisheye lens, named with its rig.
  std::string fisheye = test::rig_xmp({"c", 1});
  fisheye.replace(fisheye.find("Camera:BandName"), 0,
                  "Camera:RigName=\"Sequoia\" Camera:ModelType=\"fisheye\" ");
  test::write_band_tiff(dir / "fisheye.tif", fisheye);
  EXPECT_EQ(error_of([&] { read_rig_band_image(dir / "fisheye.tif"); }),
            (dir / "fisheye.tif").string() +
                ": XMP Camera:ModelType is 'fisheye' (a Sequoia rig): this reader knows the "
                "perspective lens of the MicaSense RedEdge / Altum layout, not a fisheye lens");
  std::string bad = test::rig_xmp({"c", 1});
  bad.replace(bad.find("CentralWavelength=\"475\""), 23, "CentralWavelength=\"blue\"");
  test::write_band_tiff(dir / "bad.tif", bad);
  EXPECT_NE(error_of([&] {
              read_rig_band_image(dir / "bad.tif");
            }).find("XMP CentralWavelength is 'blue', not a number"),
            std::string::npos);
}

TEST(RigCapture, GroupsCapturesAndNamesAMissingOrMixedBand) {
  const fs::path dir = test::temp_dir("rig_captures");
  test::write_rig_capture(dir / "000", 1);
  test::write_rig_capture(dir / "000", 2);
  EXPECT_TRUE(looks_like_rig_captures(dir));
  std::vector<RigCapture> captures = read_rig_captures(dir);
  ASSERT_EQ(captures.size(), 2u);
  EXPECT_EQ(captures[0].id, "capture1");
  EXPECT_EQ(captures[1].id, "capture2");
  ASSERT_EQ(captures[1].bands.size(), 3u);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(captures[1].bands[size_t(i)].rig_index, i + 1);
  EXPECT_EQ(captures[1].bands[2].band_name, "Red");

  // The green band of capture 2 lost: named, with the capture.
  fs::remove(dir / "000" / "IMG_0002_2.tif");
  EXPECT_EQ(error_of([&] { read_rig_captures(dir); }),
            (dir / "000" / "IMG_0002_1.tif").string() +
                ": capture capture2 has no image from band camera 2 (Green, e.g. IMG_0001_2.tif "
                "in another capture): a band is missing");
  // A file of capture 1 under capture 2's name: two captures mixed.
  test::write_band_tiff(dir / "000" / "IMG_0002_2.tif",
                        test::rig_xmp({"capture1", 2, "Green", 560, 27}));
  EXPECT_NE(error_of([&] { read_rig_captures(dir); }).find("bands of two captures are mixed"),
            std::string::npos);

  // A scene folder is not taken for captures.
  io::write_file_atomically(dir / "transforms.json", "{}");
  EXPECT_FALSE(looks_like_rig_captures(dir));
}

TEST(RigCapture, AngleToTheReferenceCamera) {
  EXPECT_NEAR(rig_relative_angle_deg({0, 0, 0}), 0, 1e-9);
  EXPECT_NEAR(rig_relative_angle_deg({1.5, 0, 0}), 1.5, 1e-9);
  EXPECT_NEAR(rig_relative_angle_deg({0, -2, 0}), 2, 1e-9);
  EXPECT_NEAR(rig_relative_angle_deg({0, 0, 0.7}), 0.7, 1e-9);
  // Small angles about several axes: close to the length of the angle vector.
  EXPECT_NEAR(rig_relative_angle_deg({0.3, 0.4, 0}), 0.5, 1e-4);
  EXPECT_EQ(rig_relative_angle_deg({}), 0);
}

}  // namespace
}  // namespace ddhgs::io

namespace ddhgs::io {
namespace {

// EXIF GPS as the synthetic rig writes it: read back here to well under a
// millimetre (EXIF rationals of degrees, minutes, seconds), in every
// hemisphere and below sea level, and by GDAL (gdalinfo's EXIF metadata), a
// reader that is not ours.
TEST(RigCapture, GpsPositionReadsBackAsWritten) {
  const fs::path dir = test::temp_dir("rig_gps");
  const double positions[][3] = {{52.123456789, 5.987654321, 112.25}, {-33.8688, -70.6693, -12.5}};
  int i = 0;
  for (const auto& p : positions) {
    RigBandImage b;
    b.file = dir / ("IMG_000" + std::to_string(i++) + "_1.tif");
    b.capture_id = "gps";
    b.rig_index = 1;
    b.band_name = "Blue";
    b.centre_nm = 475;
    b.fwhm_nm = 32;
    b.width = 8;
    b.height = 6;
    b.has_position = true;
    b.latitude_deg = p[0];
    b.longitude_deg = p[1];
    b.altitude_m = p[2];
    write_rig_band_image(b, torch::full({b.height, b.width}, 1000.0));
    const RigBandImage r = read_rig_band_image(b.file);
    ASSERT_TRUE(r.has_position);
    // 1e-9 degrees is 0.1 mm on the ground.
    EXPECT_NEAR(r.latitude_deg, p[0], 1e-9);
    EXPECT_NEAR(r.longitude_deg, p[1], 1e-9);
    EXPECT_NEAR(r.altitude_m, p[2], 1e-6);
  }
  std::string out;
  ASSERT_EQ(test::run_command("gdalinfo -mdd EXIF " + (dir / "IMG_0000_1.tif").string(), &out), 0)
      << out;
  EXPECT_NE(out.find("EXIF_GPSLatitudeRef=N"), std::string::npos) << out;
  EXPECT_NE(out.find("EXIF_GPSLatitude=(52) (7) (24.4444"), std::string::npos) << out;
  EXPECT_NE(out.find("EXIF_GPSLongitude=(5) (59) (15.5556"), std::string::npos) << out;
  EXPECT_NE(out.find("EXIF_GPSAltitude=(112.25)"), std::string::npos) << out;
}

}  // namespace
}  // namespace ddhgs::io
