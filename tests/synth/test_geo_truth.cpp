// A synthetic survey's truths: every capture's EXIF GPS, read back and put
// in UTM, is its camera 1's true centre in the projected CRS of synth.json;
// the orthographic truth holds, on the ground, what a nadir camera sees
// there; the ground control points lie on the ground inside the ortho.
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

}  // namespace
}  // namespace ddhgs::synth
