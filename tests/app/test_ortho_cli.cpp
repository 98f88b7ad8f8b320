// Georeferenced orthomosaics end to end: `synth --preset rig-nadir` writes
// rig captures with EXIF GPS and the orthographic truth; `process --rig`
// (with the true poses) fits the georeference (georef.json, residuals); `info` prints it;
// training keeps it; `render --ortho` writes Cloud-Optimised GeoTIFFs that
// GDAL (gdalinfo, gdal_translate) reads back: the CRS, the geotransform,
// each band's wavelength and the nodata value. The orthomosaic is measured
// against the truth's orthographic reflectance over the area it covers
// (PSNR); flown with the ground control points printed as targets, each
// target is found in it within one ground sample distance of its true
// projected coordinates. DDHGS_ORTHO_ITERATIONS lengthens the training for
// docs/benchmarks.md.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdlib>
#include <fstream>

#include "io/cube/cube.h"
#include "io/files/atomic_file.h"
#include "io/image/image.h"
#include "reliability/cli_support.h"
#include "support/checker_target.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;
using json = nlohmann::json;

using test::ddhgs;

using test::read_json;

// The strip's training length: DDHGS_ORTHO_ITERATIONS (800 unless set).
std::string strip_iterations() {
  const char* env = std::getenv("DDHGS_ORTHO_ITERATIONS");
  return env && *env ? env : "800";
}

int train_strip(const fs::path& scene, const fs::path& run, std::string* out) {
  return ddhgs("train " + scene.string() + " --out " + run.string() +
                   " --preset demo --iterations " + strip_iterations() +
                   " --set output.test_every=0",
               out);
}

// A GeoTIFF as GDAL reads it: gdalinfo's description and the pixels through
// gdal_translate to a raw band-sequential float32 file.
struct Raster {
  json info;
  std::vector<double> gt;
  int64_t width = 0, height = 0, bands = 0;
  std::vector<float> data;  // [B][H][W]
  float at(int64_t b, int64_t row, int64_t col) const {
    return data[size_t((b * height + row) * width + col)];
  }
};

Raster read_with_gdal(const fs::path& tif) {
  Raster r;
  std::string out;
  EXPECT_EQ(test::run_command("gdalinfo -json -mdd all " + tif.string(), &out), 0) << out;
  r.info = json::parse(out.substr(out.find('{')));
  r.gt = r.info["geoTransform"].get<std::vector<double>>();
  r.width = r.info["size"][0];
  r.height = r.info["size"][1];
  r.bands = int64_t(r.info["bands"].size());
  const fs::path raw = tif.parent_path() / (tif.stem().string() + ".raw");
  EXPECT_EQ(test::run_command("gdal_translate -q -of ENVI -co INTERLEAVE=BSQ -ot Float32 " +
                                  tif.string() + " " + raw.string(),
                              &out),
            0)
      << out;
  r.data.resize(size_t(r.bands * r.height * r.width));
  std::ifstream in(raw, std::ios::binary);
  in.read(reinterpret_cast<char*>(r.data.data()), std::streamsize(r.data.size() * sizeof(float)));
  EXPECT_TRUE(bool(in)) << raw;
  return r;
}

// Bilinear sample of band b at CRS (east, north); NaN where any of the four
// pixels is nodata or outside.
double sample(const Raster& r, int64_t b, double east, double north) {
  const double x = (east - r.gt[0]) / r.gt[1] - 0.5, y = (north - r.gt[3]) / r.gt[5] - 0.5;
  const int64_t x0 = int64_t(std::floor(x)), y0 = int64_t(std::floor(y));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= r.width || y0 + 1 >= r.height) return NAN;
  const double fx = x - double(x0), fy = y - double(y0);
  double v = 0;
  for (int dy = 0; dy < 2; ++dy)
    for (int dx = 0; dx < 2; ++dx) {
      const float p = r.at(b, y0 + dy, x0 + dx);
      if (p == -9999.0f) return NAN;
      v += p * (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy);
    }
  return v;
}

TEST(OrthoCli, AGeoreferencedStripRendersAnOrthomosaicThatMatchesTheTruth) {
  const fs::path root = test::temp_dir("ortho_cli");
  const fs::path strip = root / "strip", scene = root / "scene", run = root / "run";
  std::string out;
  ASSERT_EQ(ddhgs("synth --preset rig-nadir --out " + strip.string(), &out), 0) << out;
  // The reference camera's true poses (COLMAP does not pose this small
  // strip): the fit then finds the truth's world, placed by the GPS alone.
  ASSERT_EQ(test::process_with_true_poses(strip, scene, "", &out), 0) << out;
  // The georeference from the GPS: exact GPS and poses, so no residual.
  const json georef = read_json(scene / "georef.json");
  const json synth = read_json(strip / "synth.json");
  EXPECT_EQ(georef["epsg"], synth["georeference"]["epsg"]);
  EXPECT_EQ(georef["fit"]["captures"], 8);
  EXPECT_LT(georef["fit"]["gps_rms_m"].get<double>(), 1e-3);
  // The world's origin lands at the truth's projected coordinates.
  for (size_t i = 0; i < 3; ++i)
    EXPECT_NEAR(georef["scene_to_crs"]["translation"][i].get<double>(),
                synth["georeference"]["world_origin_crs_m"][i].get<double>(), 1e-3);
  EXPECT_NE(georef["fit"]["orientation_from"].get<std::string>().find("nadir"),
            std::string::npos);  // one straight strip
  EXPECT_EQ(read_json(scene / "process.json")["georeference"], "georef.json");
  EXPECT_NE(out.find("georeferenced to EPSG:32630"), std::string::npos) << out;
  ASSERT_EQ(ddhgs("info " + scene.string(), &out), 0) << out;
  EXPECT_NE(out.find("georef      EPSG:32630"), std::string::npos) << out;

  ASSERT_EQ(train_strip(scene, run, &out), 0) << out;
  EXPECT_EQ(read_json(run / "georef.json"), georef);

  // The orthomosaic on the truth's grid spacing.
  const std::vector<double> truth_gt = synth["ortho"]["geotransform"].get<std::vector<double>>();
  char gsd[32];
  std::snprintf(gsd, sizeof gsd, "%.9g", truth_gt[1]);
  ASSERT_EQ(ddhgs("render " + run.string() + " --ortho --gsd " + gsd, &out), 0) << out;
  const fs::path ortho = run / "renders" / "ortho";
  const Raster r = read_with_gdal(ortho / "reflectance.tif");
  const std::string wkt = r.info["coordinateSystem"]["wkt"];
  EXPECT_NE(wkt.find("ID[\"EPSG\",32630]"), std::string::npos) << wkt;
  EXPECT_NEAR(r.gt[1], truth_gt[1], 1e-9);
  EXPECT_NEAR(r.gt[5], -truth_gt[1], 1e-9);
  EXPECT_EQ(r.info["metadata"]["IMAGE_STRUCTURE"]["LAYOUT"], "COG");
  const std::vector<std::string> names = {"475 nm", "560 nm", "668 nm", "717 nm", "842 nm"};
  ASSERT_EQ(r.bands, 5);
  for (size_t b = 0; b < 5; ++b) {
    EXPECT_EQ(r.info["bands"][b]["description"], names[b]);
    EXPECT_EQ(r.info["bands"][b]["noDataValue"], -9999);
  }
  // The footprint covers the truth's (the cameras see at least that).
  EXPECT_LE(r.gt[0], truth_gt[0] + truth_gt[1]);
  EXPECT_GE(r.gt[3], truth_gt[3] - truth_gt[1]);

  // PSNR against the truth's orthographic reflectance over the covered area
  // (peak 1), the mosaic sampled at the truth's pixel centres.
  const io::Cube truth = io::read_cube(strip / "truth" / "ortho.npy");
  const int64_t th = truth.data.size(0), tw = truth.data.size(1);
  const torch::Tensor t = truth.data.contiguous();
  const float* tv = t.data_ptr<float>();
  double sq = 0;
  int64_t n = 0, pixels = 0;
  for (int64_t row = 0; row < th; ++row)
    for (int64_t col = 0; col < tw; ++col) {
      const double e = truth_gt[0] + (col + 0.5) * truth_gt[1];
      const double nn = truth_gt[3] + (row + 0.5) * truth_gt[5];
      bool covered = true;
      for (int64_t b = 0; b < 5 && covered; ++b) {
        const double v = sample(r, b, e, nn);
        if (std::isnan(v)) {
          covered = false;
          break;
        }
        const double d = v - tv[(row * tw + col) * 5 + b];
        sq += d * d;
        ++n;
      }
      pixels += covered;
    }
  ASSERT_GT(n, 0);
  const double psnr = 10 * std::log10(double(n) / sq);
  const double covered = double(pixels) / double(th * tw);
  std::printf(
      "orthomosaic vs truth: PSNR %.2f dB over %.1f %% of the truth's footprint (%s "
      "iterations)\n",
      psnr, 100 * covered, strip_iterations().c_str());
  // The ground disc and the plant: the backdrop around them is the learned
  // background, which no Gaussian covers.
  EXPECT_GT(covered, 0.2);
  // The survey issue's bar: 30 dB (31.7 measured at 800 iterations, 31.2
  // at 3000, docs/benchmarks.md; 28.3 when the mosaic showed the Gaussians'
  // colour without the background they leave showing).
  EXPECT_GE(psnr, 30.0);

  // An index map, and GDAL's view of it.
  ASSERT_EQ(ddhgs("render " + run.string() + " --ortho --index ndvi", &out), 0) << out;
  const Raster ndvi = read_with_gdal(ortho / "ndvi.tif");
  EXPECT_EQ(ndvi.bands, 1);
  EXPECT_NE(ndvi.info["bands"][0]["description"].get<std::string>().find("ndvi"),
            std::string::npos);
  EXPECT_TRUE(fs::exists(ortho / "ndvi.png"));
  EXPECT_TRUE(fs::exists(ortho / "reflectance.png"));
  EXPECT_TRUE(fs::exists(ortho / "reflectance.tif"));  // the earlier product stays
}

// The ground control points as a survey checks them: the strip flown with
// its control points printed on the ground as targets, trained, and each
// target's centre found in the GeoTIFF (as GDAL reads it) against its true
// projected coordinates, within one ground sample distance.
TEST(OrthoCli, GroundControlTargetsLandWithinOneGroundSampleDistance) {
  const fs::path root = test::temp_dir("ortho_gcp");
  const fs::path strip = root / "strip", scene = root / "scene", run = root / "run";
  std::string out;
  ASSERT_EQ(ddhgs("synth --preset rig-nadir --gcp-targets --out " + strip.string(), &out), 0)
      << out;
  ASSERT_EQ(test::process_with_true_poses(strip, scene, "", &out), 0) << out;
  ASSERT_EQ(train_strip(scene, run, &out), 0) << out;
  ASSERT_EQ(ddhgs("render " + run.string() + " --ortho", &out), 0) << out;  // the flight's GSD
  const Raster r = read_with_gdal(run / "renders" / "ortho" / "reflectance.tif");
  const json synth = read_json(strip / "synth.json");
  const double truth_gsd = synth["ortho"]["geotransform"][1].get<double>();
  EXPECT_NEAR(r.gt[1], truth_gsd, 0.02 * truth_gsd);  // the flight's own, about the truth's
  const double side_m = synth["gcp_targets"]["side_m"].get<double>();
  ASSERT_EQ(synth["ground_control_points"].size(), 4u);
  for (const json& p : synth["ground_control_points"]) {
    const double east = p["easting_m"].get<double>(), north = p["northing_m"].get<double>();
    const double col = (east - r.gt[0]) / r.gt[1], row = (north - r.gt[3]) / r.gt[5];
    auto value = [&r](int64_t y, int64_t x) {
      double v = 0;
      for (int64_t b = 0; b < r.bands; ++b) {
        const float p = r.at(b, y, x);
        if (p == -9999.0f) return double(NAN);
        v += p;
      }
      return v;
    };
    const test::TargetFix fix =
        test::find_checker_target(value, r.width, r.height, col, row, 0.5 * side_m / r.gt[1], 3);
    ASSERT_TRUE(fix.found) << p["name"];
    const double de = (fix.col - col) * r.gt[1], dn = (fix.row - row) * r.gt[5];
    std::printf(
        "%s: target found %.3f m east, %.3f m north of its coordinates (GSD %.4f m), "
        "contrast %.2f\n",
        p["name"].get<std::string>().c_str(), de, dn, r.gt[1], fix.contrast);
    EXPECT_LT(std::hypot(de, dn), r.gt[1]) << p["name"];
    EXPECT_GT(fix.contrast, 1.0) << p["name"];  // the checker, not the ground's weave
  }

  // The report shows the orthomosaic and the NDVI map, north up on the
  // same grid, with the GSD and the CRS stated.
  ASSERT_EQ(ddhgs("report " + run.string(), &out), 0) << out;
  const fs::path assets = run / "report" / "assets";
  const std::string data = io::read_file(assets / "data.js");
  char gsd_text[32];
  std::snprintf(gsd_text, sizeof gsd_text, "%.6g m", r.gt[1]);
  EXPECT_NE(data.find(std::string("ground sample distance of ") + gsd_text), std::string::npos);
  EXPECT_NE(data.find("CRS EPSG:32630, WGS 84 / UTM zone 30N"), std::string::npos);
  const torch::Tensor mosaic = io::read_image(assets / "ortho" / "reflectance.png").to(torch::kInt);
  const torch::Tensor ndvi = io::read_image(assets / "ortho" / "ndvi.png").to(torch::kInt);
  ASSERT_EQ(mosaic.size(0), r.height);
  ASSERT_EQ(mosaic.size(1), r.width);
  ASSERT_TRUE(ndvi.sizes() == mosaic.sizes());
  auto grey = [&mosaic](double row, double col) {
    return mosaic[int64_t(row)][int64_t(col)].sum().item<int>() / 3;
  };
  for (const json& p : synth["ground_control_points"]) {
    const double col = (p["easting_m"].get<double>() - r.gt[0]) / r.gt[1];
    const double row = (p["northing_m"].get<double>() - r.gt[3]) / r.gt[5];
    // The target where its coordinates put it: north-west quarter white,
    // north-east dark.
    EXPECT_GT(grey(row - 2.5, col - 2.5), grey(row - 2.5, col + 2.5) + 60) << p["name"];
  }
  EXPECT_EQ(grey(0, 0), 128);  // nothing covers the corner: mid grey
  // NDVI: the plant (at the world's origin) green, the ground around the
  // targets not.
  const json& origin = synth["georeference"]["world_origin_crs_m"];
  const int64_t pc = int64_t((origin[0].get<double>() - r.gt[0]) / r.gt[1]);
  const int64_t pr = int64_t((origin[1].get<double>() - r.gt[3]) / r.gt[5]);
  const json& g1 = synth["ground_control_points"][0];
  const int64_t gc = int64_t((g1["easting_m"].get<double>() - r.gt[0]) / r.gt[1]) + 10;
  const int64_t gr = int64_t((g1["northing_m"].get<double>() - r.gt[3]) / r.gt[5]);
  const int plant_green = (ndvi[pr][pc][1] - ndvi[pr][pc][0]).item<int>();
  const int ground_green = (ndvi[gr][gc][1] - ndvi[gr][gc][0]).item<int>();
  EXPECT_GT(plant_green, 60);
  EXPECT_LT(ground_green, plant_green - 60);
}

// Georeferencing from noisy GPS: a survey of 200 captures (10 flight lines
// at 40 m, about 240 x 120 m) whose every EXIF GPS is off by a normal error
// of 2 m along each axis. The fitted similarity, applied to the ground
// control points' scene coordinates (the truth's poses: the scene is the
// truth's world), places them within 0.5 m of their true projected
// coordinates, while the GPS residuals show the noise (about 2 m x sqrt 3).
TEST(OrthoCli, NoisyGpsPlacesTheControlPointsWithinHalfAMetre) {
  const fs::path root = test::temp_dir("ortho_gps_noise");
  const fs::path survey = root / "survey", scene = root / "scene";
  std::string out;
  ASSERT_EQ(ddhgs("synth --preset rig-nadir --views 200 --lines 10 --altitude 40 --width 32 "
                  "--height 24 --supersample 1 --points 200 --gps-noise 2 --out " +
                      survey.string(),
                  &out),
            0)
      << out;
  ASSERT_EQ(test::process_with_true_poses(survey, scene, "", &out), 0) << out;
  const json georef = read_json(scene / "georef.json");
  const json synth = read_json(survey / "synth.json");
  EXPECT_EQ(georef["fit"]["captures"], 200);
  const double rms = georef["fit"]["gps_rms_m"].get<double>();
  std::printf("GPS residuals: RMS %.2f m, worst %.2f m (noise 2 m per axis)\n", rms,
              georef["fit"]["gps_worst_m"].get<double>());
  EXPECT_GT(rms, 0.8 * 2 * std::sqrt(3.0));
  EXPECT_LT(rms, 1.2 * 2 * std::sqrt(3.0));
  const json& s = georef["scene_to_crs"];
  ASSERT_EQ(synth["ground_control_points"].size(), 4u);
  for (const json& p : synth["ground_control_points"]) {
    double crs[3];
    for (size_t i = 0; i < 3; ++i) {
      crs[i] = s["translation"][i].get<double>();
      for (size_t k = 0; k < 3; ++k)
        crs[i] += s["scale"].get<double>() * s["rotation"][i][k].get<double>() *
                  p["world_xyz"][k].get<double>();
    }
    const double horizontal =
        std::hypot(crs[0] - p["easting_m"].get<double>(), crs[1] - p["northing_m"].get<double>());
    const double vertical = crs[2] - p["height_m"].get<double>();
    std::printf("%s: placed %.3f m from its coordinates horizontally, %.3f m vertically\n",
                p["name"].get<std::string>().c_str(), horizontal, vertical);
    EXPECT_LT(std::hypot(horizontal, vertical), 0.5) << p["name"];
  }
}

// A scene without GPS: no georef.json, and --ortho is one error naming the
// run, with nothing written.
TEST(OrthoCli, WithoutGpsThereIsNoGeoreferenceAndNoOrthomosaic) {
  const fs::path root = test::temp_dir("ortho_none");
  std::string out;
  ASSERT_EQ(ddhgs("synth --preset demo --views 6 --width 32 --height 24 --bands 8 --out " +
                      (root / "demo").string(),
                  &out),
            0)
      << out;
  ASSERT_EQ(ddhgs("train " + (root / "demo").string() + " --out " + (root / "run").string() +
                      " --preset demo --iterations 20 --set output.test_every=0",
                  &out),
            0)
      << out;
  EXPECT_FALSE(fs::exists(root / "run" / "georef.json"));
  EXPECT_NE(ddhgs("render " + (root / "run").string() + " --ortho", &out), 0);
  EXPECT_NE(out.find("--ortho needs a georeferenced scene"), std::string::npos) << out;
  EXPECT_NE(out.find((root / "run").string()), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(root / "run" / "renders"));
  EXPECT_NE(ddhgs("render " + (root / "run").string() + " --gsd 0.1", &out), 0);  // needs --ortho
  // Its report has no orthomosaic section's pictures.
  ASSERT_EQ(ddhgs("report " + (root / "run").string(), &out), 0) << out;
  EXPECT_FALSE(fs::exists(root / "run" / "report" / "assets" / "ortho"));
  EXPECT_NE(io::read_file(root / "run" / "report" / "assets" / "data.js").find("\"ortho\":null"),
            std::string::npos);
  EXPECT_NE(ddhgs("render " + (root / "run").string() + " --ortho --orbit 4", &out), 0);
}

}  // namespace
}  // namespace ddhgs
