// A synthetic survey's truths: every capture's EXIF GPS, read back and put
// in UTM, is its camera 1's true centre in the projected CRS of synth.json;
// the orthographic truth holds, on the ground, what a nadir camera sees
// there; the ground control points lie on the ground inside the ortho, and
// with --gcp-targets their printed targets show in the ortho at their
// projected coordinates and change nothing else.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>

#include "core/camera.h"
#include "core/error.h"
#include "core/utm.h"
#include "io/cube/cube.h"
#include "io/files/atomic_file.h"
#include "io/rig/rig_capture.h"
#include "io/transforms/transforms.h"
#include "support/checker_target.h"
#include "support/test_support.h"
#include "synth/generate.h"
#include "synth/rig_scene.h"

namespace ddhgs::synth {
namespace {

namespace fs = std::filesystem;

class GeoTruth : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    SynthConfig config = preset_config("rig-nadir");
    config.width = 64;
    config.height = 48;
    config.views = 4;
    config.supersample = 2;
    config.points = 50;
    config.gps_latitude_deg = -34.9285;  // south and east: both signs other than the default's
    config.gps_longitude_deg = 138.6007;
    dir_ = new fs::path(test::temp_dir("geo_truth") / "survey");
    write_synthetic_scene(config, *dir_, false);
  }
  static void TearDownTestSuite() { delete dir_; }
  static fs::path* dir_;
  static nlohmann::json meta() {
    return nlohmann::json::parse(io::read_file(*dir_ / "synth.json"));
  }
};
fs::path* GeoTruth::dir_ = nullptr;

TEST_F(GeoTruth, GpsIsTheTrueCentreInTheProjectedCrs) {
  const nlohmann::json j = meta();
  const auto& g = j["georeference"];
  EXPECT_EQ(g["epsg"].get<int>(), 32754);  // Adelaide: UTM 54 south
  const core::UtmZone zone{54, false};
  const io::TransformsFile truth = io::read_transforms(*dir_ / "truth" / "transforms.json");
  int checked = 0;
  for (const io::TransformsFrame& f : truth.frames) {
    if (f.rig_camera != 1) continue;
    const std::string stem = fs::path(f.hyperspectral_file_path).stem().string();
    const io::RigBandImage b = io::read_rig_band_image(*dir_ / "captures" / (stem + ".tif"));
    ASSERT_TRUE(b.has_position) << stem;
    const core::UtmPoint p = core::to_utm(b.latitude_deg, b.longitude_deg, zone);
    const core::Mat4 c2w = core::opengl_c2w_to_opencv_w2c(f.camera_to_world_gl).rigid_inverse();
    const core::Vec3 centre = c2w.translation();
    EXPECT_NEAR(p.easting_m, g["world_origin_crs_m"][0].get<double>() + centre.x, 1e-3);
    EXPECT_NEAR(p.northing_m, g["world_origin_crs_m"][1].get<double>() + centre.y, 1e-3);
    EXPECT_NEAR(b.altitude_m, g["world_origin_crs_m"][2].get<double>() + centre.z, 1e-3);
    ++checked;
  }
  EXPECT_EQ(checked, 4);
}

TEST_F(GeoTruth, OrthoHoldsWhatANadirCameraSeesOnTheGround) {
  const nlohmann::json j = meta();
  const auto& o = j["ortho"];
  const io::Cube ortho = io::read_cube(*dir_ / "truth" / "ortho.npy");
  ASSERT_EQ(ortho.data.size(0), o["height"].get<int64_t>());
  ASSERT_EQ(ortho.data.size(1), o["width"].get<int64_t>());
  ASSERT_EQ(ortho.data.size(2), 5);
  const std::vector<double> gt = o["geotransform"].get<std::vector<double>>();
  const std::vector<double> origin = j["georeference"]["world_origin_crs_m"];
  // The clean cube of the first capture (registered, from camera 1's pose).
  const io::TransformsFile cubes = io::read_transforms(*dir_ / "cubes" / "transforms.json");
  const io::TransformsFrame& f = cubes.frames.front();
  const core::Mat4 w2c = core::opengl_c2w_to_opencv_w2c(f.camera_to_world_gl);
  const io::Cube view =
      io::read_cube(*dir_ / "cubes" / "clean" / fs::path(f.hyperspectral_file_path).filename());
  // Ground points (z = 0) on the disc, away from the plant: the view's
  // pixel there and the ortho's pixel there hold the same surface, so their
  // means over a 3x3 patch agree up to the two grids' different sampling.
  double worst = 0, worst_shifted = 0;
  int compared = 0;
  for (double x = -1.2; x <= 1.2; x += 0.3)
    for (double y : {-0.5, 0.5}) {
      if (std::abs(x) < 0.6) continue;  // the plant and its pot
      const core::Vec3 c = w2c.transform_point({x, y, 0});
      const double u = f.intrinsics.fx * c.x / c.z + f.intrinsics.cx;
      const double v = f.intrinsics.fy * c.y / c.z + f.intrinsics.cy;
      if (u < 2 || v < 2 || u > f.intrinsics.width - 2 || v > f.intrinsics.height - 2) continue;
      const torch::Tensor a = view.data.slice(0, int64_t(v) - 1, int64_t(v) + 2)
                                  .slice(1, int64_t(u) - 1, int64_t(u) + 2)
                                  .mean(std::vector<int64_t>{0, 1});
      // The ortho's patch there, and (to show the comparison can fail) 8 cm east.
      for (double shift : {0.0, 0.08}) {
        const double col = (origin[0] + x + shift - gt[0]) / gt[1];
        const double row = (origin[1] + y - gt[3]) / gt[5];
        const torch::Tensor b = ortho.data.slice(0, int64_t(row) - 1, int64_t(row) + 2)
                                    .slice(1, int64_t(col) - 1, int64_t(col) + 2)
                                    .mean(std::vector<int64_t>{0, 1});
        const double diff = (a - b).abs().max().template item<double>();
        double& w = shift == 0 ? worst : worst_shifted;
        w = std::max(w, diff);
      }
      ++compared;
    }
  EXPECT_GE(compared, 4);
  EXPECT_LT(worst, 0.05);
  EXPECT_GT(worst_shifted, 2 * worst) << worst;
}

TEST_F(GeoTruth, ControlPointsLieOnTheGroundInsideTheOrtho) {
  const nlohmann::json j = meta();
  const std::vector<double> gt = j["ortho"]["geotransform"].get<std::vector<double>>();
  const double width = j["ortho"]["width"].get<double>(),
               height = j["ortho"]["height"].get<double>();
  ASSERT_EQ(j["ground_control_points"].size(), 4u);
  for (const auto& p : j["ground_control_points"]) {
    const double col = (p["easting_m"].get<double>() - gt[0]) / gt[1];
    const double row = (p["northing_m"].get<double>() - gt[3]) / gt[5];
    EXPECT_GT(col, 0);
    EXPECT_LT(col, width);
    EXPECT_GT(row, 0);
    EXPECT_LT(row, height);
    EXPECT_EQ(p["world_xyz"][2].get<double>(), 0);
    EXPECT_NEAR(p["height_m"].get<double>(),
                j["georeference"]["world_origin_crs_m"][2].get<double>(), 1e-9);
  }
}

// The printed targets: each found in the orthographic truth where its
// projected coordinates put it, and nothing but the targets changed.
TEST(GeoTruthTargets, TargetsShowAtTheControlPointsAndChangeNothingElse) {
  SynthConfig config = preset_config("rig-nadir");
  config.width = 64;
  config.height = 48;
  config.views = 4;
  config.supersample = 2;
  config.points = 50;
  const fs::path root = test::temp_dir("geo_targets");
  write_synthetic_scene(config, root / "plain", false);
  config.gcp_targets = true;
  write_synthetic_scene(config, root / "targets", false);
  const nlohmann::json j = nlohmann::json::parse(io::read_file(root / "targets" / "synth.json"));
  EXPECT_EQ(
      j["ground_control_points"],
      nlohmann::json::parse(io::read_file(root / "plain" / "synth.json"))["ground_control_points"]);
  const std::vector<double> gt = j["ortho"]["geotransform"].get<std::vector<double>>();
  const double side_px = j["gcp_targets"]["side_m"].get<double>() / gt[1];
  EXPECT_NEAR(side_px, 10, 1e-9);
  const torch::Tensor plain = io::read_cube(root / "plain" / "truth" / "ortho.npy").data;
  const torch::Tensor ortho = io::read_cube(root / "targets" / "truth" / "ortho.npy").data;
  ASSERT_TRUE(plain.sizes() == ortho.sizes());
  const torch::Tensor total = ortho.sum(2).contiguous();  // every band
  const auto at = total.accessor<float, 2>();
  auto value = [&](int64_t row, int64_t col) { return double(at[row][col]); };
  torch::Tensor inside = torch::zeros({ortho.size(0), ortho.size(1)}, torch::kBool);
  for (const auto& p : j["ground_control_points"]) {
    const double col = (p["easting_m"].get<double>() - gt[0]) / gt[1];
    const double row = (p["northing_m"].get<double>() - gt[3]) / gt[5];
    // Sought from 1.5 px away: found where the coordinates say, to the
    // quarter pixel its edges are resolved to (2 x 2 rays a pixel).
    const test::TargetFix fix = test::find_checker_target(value, total.size(1), total.size(0),
                                                          col + 1.5, row - 1.5, 0.5 * side_px, 3);
    ASSERT_TRUE(fix.found) << p["name"];
    EXPECT_NEAR(fix.col, col, 0.26) << p["name"];
    EXPECT_NEAR(fix.row, row, 0.26) << p["name"];
    EXPECT_GT(fix.contrast, 2.0) << p["name"];  // five bands of 0.6 against 0.04
    // The same search over the plain ground finds no such pattern.
    const auto plain_total = plain.sum(2).contiguous();
    const auto pa = plain_total.accessor<float, 2>();
    const test::TargetFix none =
        test::find_checker_target([&](int64_t r, int64_t c) { return double(pa[r][c]); },
                                  total.size(1), total.size(0), col, row, 0.5 * side_px, 3);
    EXPECT_LT(none.contrast, 0.5) << p["name"];
    const int64_t r0 = int64_t(std::floor(row - 0.5 * side_px)) - 1;
    const int64_t c0 = int64_t(std::floor(col - 0.5 * side_px)) - 1;
    inside.slice(0, r0, r0 + int64_t(side_px) + 3)
        .slice(1, c0, c0 + int64_t(side_px) + 3)
        .fill_(true);
  }
  // Outside the targets (and the pixels they share an edge with), the same
  // pixels to the bit.
  EXPECT_TRUE(torch::equal(ortho.index({~inside}), plain.index({~inside})));
  EXPECT_FALSE(torch::equal(ortho, plain));
}

// --gps-noise: each capture's EXIF GPS is its true centre plus the error
// synth.json records, errors of about the asked spread, seeded; the images
// and the truths stay as they are.
TEST(GeoTruthNoise, EachCapturesGpsIsOffByItsRecordedError) {
  SynthConfig config = preset_config("rig-nadir");
  config.width = 32;
  config.height = 24;
  config.views = 12;
  config.lines = 3;
  config.supersample = 1;
  config.points = 50;
  const fs::path root = test::temp_dir("geo_noise");
  write_synthetic_scene(config, root / "exact", false);
  config.gps_noise_m = 2;
  write_synthetic_scene(config, root / "noisy", false);
  const fs::path dir = root / "noisy";
  const nlohmann::json j = nlohmann::json::parse(io::read_file(dir / "synth.json"));
  EXPECT_FALSE(
      nlohmann::json::parse(io::read_file(root / "exact" / "synth.json")).contains("gps_noise"));
  EXPECT_EQ(j["gps_noise"]["sigma_m"].get<double>(), 2);
  const auto& errors = j["gps_noise"]["capture_error_m"];
  ASSERT_EQ(errors.size(), 12u);
  const auto& origin = j["georeference"]["world_origin_crs_m"];
  const core::UtmZone zone = core::utm_zone(51.8091, -0.3727);
  const io::TransformsFile truth = io::read_transforms(dir / "truth" / "transforms.json");
  double sum_sq = 0;
  int checked = 0;
  for (const io::TransformsFrame& f : truth.frames) {
    if (f.rig_camera != 1) continue;
    const std::string stem = fs::path(f.hyperspectral_file_path).stem().string();
    const int capture = std::stoi(stem.substr(4, 4));
    const io::RigBandImage b = io::read_rig_band_image(dir / "captures" / (stem + ".tif"));
    const core::UtmPoint p = core::to_utm(b.latitude_deg, b.longitude_deg, zone);
    const core::Vec3 centre =
        core::opengl_c2w_to_opencv_w2c(f.camera_to_world_gl).rigid_inverse().translation();
    const auto& e = errors[size_t(capture)];
    EXPECT_NEAR(p.easting_m, origin[0].get<double>() + centre.x + e[0].get<double>(), 1e-3);
    EXPECT_NEAR(p.northing_m, origin[1].get<double>() + centre.y + e[1].get<double>(), 1e-3);
    EXPECT_NEAR(b.altitude_m, origin[2].get<double>() + centre.z + e[2].get<double>(), 1e-3);
    for (int i = 0; i < 3; ++i) sum_sq += e[size_t(i)].get<double>() * e[size_t(i)].get<double>();
    ++checked;
  }
  ASSERT_EQ(checked, 12);
  const double rms = std::sqrt(sum_sq / (3 * checked));  // per axis
  EXPECT_GT(rms, 1.2);
  EXPECT_LT(rms, 3.0);
  // Only the GPS moves: the truths are the exact run's.
  EXPECT_TRUE(torch::equal(io::read_cube(dir / "truth" / "ortho.npy").data,
                           io::read_cube(root / "exact" / "truth" / "ortho.npy").data));
}

}  // namespace
}  // namespace ddhgs::synth
