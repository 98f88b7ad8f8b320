// georef.json round-trips and refuses malformed files by name; write_cog's
// GeoTIFFs read back with gdalinfo -json (GDAL's reader, not ours): the CRS,
// the geotransform, each band's description, wavelength and nodata value,
// the COG layout, and the pixel values (gdallocationinfo).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "io/files/atomic_file.h"
#include "io/geo/georef.h"
#include "io/geo/geotiff.h"
#include "support/error_text.h"
#include "support/test_support.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;

Georeference example() {
  Georeference g;
  g.epsg = 32756;
  g.scene_to_crs.scale = 0.731;
  g.scene_to_crs.rotation = core::quat_to_rotation(0.6, 0.3, -0.5, 0.2);
  g.scene_to_crs.translation = {334368.25, 6250948.5, 42.0};
  g.captures = 12;
  g.rms_m = 0.012;
  g.worst_m = 0.031;
  g.worst_capture = "IMG_0007";
  return g;
}

TEST(Georef, RoundTripsAndIsFoundBesideAScene) {
  const fs::path dir = test::temp_dir("georef");
  EXPECT_FALSE(find_georeference(dir).has_value());
  const Georeference g = example();
  write_georeference(dir / kGeorefFile, g);
  const std::optional<Georeference> r = find_georeference(dir);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->epsg, 32756);
  EXPECT_DOUBLE_EQ(r->scene_to_crs.scale, g.scene_to_crs.scale);
  for (int i = 0; i < 9; ++i)
    EXPECT_DOUBLE_EQ(r->scene_to_crs.rotation.m[size_t(i)], g.scene_to_crs.rotation.m[size_t(i)]);
  EXPECT_DOUBLE_EQ(r->scene_to_crs.translation.y, 6250948.5);
  EXPECT_EQ(r->worst_capture, "IMG_0007");
  EXPECT_DOUBLE_EQ(r->rms_m, 0.012);
  // The CRS's up in the scene is the rotation's third row.
  const core::Vec3 up = r->scene_up();
  const core::Vec3 crs_up = r->scene_to_crs.rotation * up;
  EXPECT_NEAR(crs_up.z, 1, 1e-12);
}

TEST(Georef, MalformedFilesAreNamed) {
  const fs::path dir = test::temp_dir("georef_bad");
  const fs::path file = dir / kGeorefFile;
  write_georeference(file, example());
  const std::string good = read_file(file);
  auto refused = [&](const std::string& text, const std::string& expected) {
    write_file_atomically(file, text);
    const std::string message = test::error_of([&] { read_georeference(file); });
    EXPECT_NE(message.find(file.string()), std::string::npos) << message;
    EXPECT_NE(message.find(expected), std::string::npos) << message;
  };
  refused("{", "not valid JSON");
  refused("{}", "expected epsg");
  nlohmann::json j = nlohmann::json::parse(good);
  j["epsg"] = "32756";
  refused(j.dump(), "epsg: expected a positive integer");
  j = nlohmann::json::parse(good);
  j["scene_to_crs"]["scale"] = -1;
  refused(j.dump(), "scale: expected a positive number");
  j = nlohmann::json::parse(good);
  j["scene_to_crs"]["rotation"][0][0] = 2;
  refused(j.dump(), "is not a rotation");
  j = nlohmann::json::parse(good);
  j["scene_to_crs"]["translation"] = {1, 2};
  refused(j.dump(), "translation of 3");
  EXPECT_NE(test::error_of([&] { read_georeference(dir / "none.json"); }).find("not found"),
            std::string::npos);
}

TEST(GeoTiff, GdalReadsTheCrsGeotransformBandsAndNodata) {
  const fs::path dir = test::temp_dir("geotiff");
  GeoRaster r;
  r.bands = torch::arange(30 * 40 * 3, torch::kFloat32).reshape({30, 40, 3}) / 3600.0f;
  r.bands[2][5][1] = -9999.0f;
  r.descriptions = {"475 nm", "668 nm", "842 nm"};
  r.wavelengths_nm = {475, 668, 842};
  r.nodata = -9999;
  r.epsg = 32630;
  r.geotransform = {681111.5, 0.05, 0, 5743072.25, 0, -0.05};
  write_cog(dir / "ortho.tif", r);
  std::string out;
  ASSERT_EQ(test::run_command("gdalinfo -json -mdd all " + (dir / "ortho.tif").string(), &out), 0)
      << out;
  const nlohmann::json info = nlohmann::json::parse(out.substr(out.find('{')));
  EXPECT_EQ(info["size"], (std::vector<int>{40, 30}));
  EXPECT_EQ(info["geoTransform"], (std::vector<double>{681111.5, 0.05, 0, 5743072.25, 0, -0.05}));
  const std::string wkt = info["coordinateSystem"]["wkt"];
  EXPECT_NE(wkt.find("UTM zone 30N"), std::string::npos) << wkt;
  EXPECT_NE(wkt.find("ID[\"EPSG\",32630]"), std::string::npos) << wkt;
  EXPECT_EQ(info["metadata"]["IMAGE_STRUCTURE"]["LAYOUT"], "COG");
  ASSERT_EQ(info["bands"].size(), 3u);
  for (size_t b = 0; b < 3; ++b) {
    const nlohmann::json& band = info["bands"][b];
    EXPECT_EQ(band["type"], "Float32");
    EXPECT_EQ(band["description"], r.descriptions[b]);
    EXPECT_EQ(band["noDataValue"], -9999);
    EXPECT_EQ(band["metadata"][""]["wavelength"], std::to_string(int(r.wavelengths_nm[b])));
    EXPECT_EQ(band["metadata"][""]["wavelength_units"], "nm");
  }
  // Pixel (col 7, row 2) of band 3 (1-based) holds (2 * 40 + 7) * 3 + 2 over 3600.
  ASSERT_EQ(test::run_command(
                "gdallocationinfo -valonly -b 3 " + (dir / "ortho.tif").string() + " 7 2", &out),
            0);
  EXPECT_NEAR(std::stod(out), ((2 * 40 + 7) * 3 + 2) / 3600.0, 1e-6);
  // Nothing of the temporary name is left.
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir)) files += e.is_regular_file();
  EXPECT_EQ(files, 1);
}

TEST(GeoTiff, AnUnknownEpsgCodeIsNamedAndNothingIsWritten) {
  const fs::path dir = test::temp_dir("geotiff_bad");
  GeoRaster r;
  r.bands = torch::zeros({4, 4, 1});
  r.descriptions = {"ndvi"};
  r.epsg = 999999;
  r.geotransform = {0, 1, 0, 0, 0, -1};
  const std::string message = test::error_of([&] { write_cog(dir / "x.tif", r); });
  EXPECT_NE(message.find("EPSG:999999"), std::string::npos) << message;
  EXPECT_FALSE(fs::exists(dir / "x.tif"));
}

}  // namespace
}  // namespace ddhgs::io
