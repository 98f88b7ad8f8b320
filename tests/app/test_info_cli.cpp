// `ddhgs info` run as a user would: text, JSON, problems and exit codes.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <limits>

#include "io/cube/cube.h"
#include "io/files/atomic_file.h"
#include "io/image/image.h"
#include "io/rig/rig_capture.h"
#include "io/transforms/transforms.h"
#include "support/rig_tiff.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;

// 6 views of 8 x 6 pixels, 5 bands (450-650 nm), uint8, plus clean/ copies.
fs::path make_scene(const std::string& name) {
  fs::path root = test::temp_dir(name);
  fs::create_directories(root / "cubes");
  fs::create_directories(root / "clean");
  io::TransformsFile file;
  file.wavelengths_nm = {450, 500, 550, 600, 650};
  for (int i = 0; i < 6; ++i) {
    io::TransformsFrame f;
    f.hyperspectral_file_path = "cubes/v" + std::to_string(i) + ".npy";
    f.intrinsics.fx = f.intrinsics.fy = 12;
    f.intrinsics.cx = 4;
    f.intrinsics.cy = 3;
    f.intrinsics.width = 8;
    f.intrinsics.height = 6;
    f.camera_to_world_gl =
        core::opencv_w2c_to_opengl_c2w(core::look_at({2.0 + i, 1, 1}, {0, 0, 0}, {0, 0, 1}));
    torch::Tensor cube = torch::full({6, 8, 5}, 10 * i, torch::kUInt8);
    io::write_npy(root / f.hyperspectral_file_path, cube);
    io::write_npy(root / "clean" / ("v" + std::to_string(i) + ".npy"), cube);
    file.frames.push_back(f);
  }
  io::write_transforms(root / "transforms.json", file);
  return root;
}

int info(const std::string& args, std::string* out) {
  return test::run_command(test::ddhgs_binary() + " info " + args, out);
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(InfoCli, DescribesAHealthyScene) {
  fs::path root = make_scene("info_ok");
  std::string out;
  ASSERT_EQ(info(root.string(), &out), 0) << out;
  EXPECT_TRUE(contains(out, "views       6 (train 6, test 0)")) << out;
  EXPECT_TRUE(contains(out, "8 x 6 px")) << out;
  EXPECT_TRUE(contains(out, "bands       5, 450-650 nm")) << out;
  EXPECT_TRUE(contains(out, "stored as   uint8")) << out;
  // 8 x 6 x 5 bytes per view, 6 views; 4x that as float32.
  EXPECT_TRUE(contains(out, "240 B per view, 1.4 KiB for the scene as stored; 960 B / 5.6 KiB"))
      << out;
  EXPECT_TRUE(contains(out, "6 views with clean ground truth")) << out;
  // View i is uniform at 10 i / 255: the median border value is 20 / 255, and
  // views 1-3 (within 10 / 255 = 0.039 of it) are half the border, but a
  // masked capture's backdrop lies on most views, not on half of them.
  EXPECT_TRUE(contains(out,
                       "backdrop    none (the borders of 50 % of the views lie within 0.04 of "
                       "their median)"))
      << out;
  // Every pixel's spectrum is 10 i / 255 in all 5 bands: one direction, (1,
  // 1, 1, 1, 1), holds all the variance of the 6 x 48 pixels.
  EXPECT_TRUE(contains(out,
                       "spectra     signal in 1 of 5 components above the noise floor, 1 with "
                       "each band's noise whitened (99 % of the variance in 1, 99.9 % in 1; 6 "
                       "training views, 288 pixels)"))
      << out;
  EXPECT_TRUE(contains(out, "problems    none")) << out;
}

TEST(InfoCli, ABorderThatVariesIsNoBackdrop) {
  fs::path root = make_scene("info_natural");
  // Views 40 levels (0.157) apart: only the median's own view is within 0.04.
  for (int i = 0; i < 6; ++i)
    io::write_npy(root / "cubes" / ("v" + std::to_string(i) + ".npy"),
                  torch::full({6, 8, 5}, 40 * i, torch::kUInt8));
  std::string out;
  ASSERT_EQ(info(root.string(), &out), 0) << out;
  EXPECT_TRUE(contains(out,
                       "backdrop    none (17 % of the view borders within 0.04 of their "
                       "median)"))
      << out;
}

TEST(InfoCli, JsonAtDownscale) {
  fs::path root = make_scene("info_json");
  std::string out;
  ASSERT_EQ(info(root.string() + " --downscale 2 --json 2>/dev/null", &out), 0) << out;
  nlohmann::json j = nlohmann::json::parse(out);
  EXPECT_EQ(j["views"], 6);
  EXPECT_EQ(j["width"], 4);
  EXPECT_EQ(j["height"], 3);
  EXPECT_EQ(j["bands"], 5);
  EXPECT_EQ(j["stored_type"], "uint8");
  EXPECT_EQ(j["bytes_per_view"], 4 * 3 * 5);
  EXPECT_EQ(j["bytes_scene_float32"], 6 * 4 * 3 * 5 * 4);
  EXPECT_EQ(j["points"], 0);
  EXPECT_EQ(j["clean_views"], 6);
  EXPECT_EQ(j["border"]["share"].get<double>(), 0.5);
  EXPECT_EQ(j["border"]["view_share"].get<double>(), 0.5);
  EXPECT_FALSE(j["border"]["masked"].get<bool>());
  EXPECT_TRUE(contains(j["border"]["why_not"].get<std::string>(), "50 % of the views"));
  EXPECT_NEAR(j["border"]["colour"][0].get<double>(), 20.0 / 255, 1e-6);
  EXPECT_TRUE(j["errors"].empty());
  const auto& pca = j["spectral_pca"];
  EXPECT_NEAR(pca["energy"][0].get<double>(), 1.0, 1e-9);
  EXPECT_EQ(pca["rank_99_9"], 1);
  EXPECT_EQ(pca["signal_rank"], 1);
  EXPECT_EQ(pca["whitened_signal_rank"], 1);  // no noise: the 99.9 % rank
  EXPECT_EQ(pca["pixels"], 6 * 4 * 3);
}

TEST(InfoCli, ListsEveryProblem) {
  fs::path root = make_scene("info_bad");
  fs::remove(root / "cubes" / "v1.npy");
  io::write_npy(root / "cubes" / "v4.npy", torch::zeros({6, 8, 7}, torch::kUInt8));
  torch::Tensor nan_cube = torch::zeros({6, 8, 5});
  nan_cube[2][3][1] = std::numeric_limits<float>::quiet_NaN();
  io::write_npy(root / "clean" / "v5.npy", nan_cube);
  io::write_npy(root / "cubes" / "v5.npy", nan_cube.to(torch::kFloat16));
  std::string out;
  EXPECT_EQ(info(root.string(), &out), 1) << out;
  EXPECT_TRUE(contains(out, "views       5")) << out;
  EXPECT_TRUE(contains(out, "warning: frames[1]: missing file")) << out;
  EXPECT_TRUE(contains(out, "v4.npy: has 7 bands, expected 5")) << out;
  EXPECT_TRUE(contains(out, "v5.npy")) << out;
  EXPECT_TRUE(contains(out, "NaN")) << out;
  EXPECT_TRUE(contains(out, "backdrop    not checked (views fail to load)")) << out;
}

size_t count(const std::string& text, const std::string& part) {
  size_t n = 0;
  for (size_t at = text.find(part); at != std::string::npos; at = text.find(part, at + 1)) ++n;
  return n;
}

// basil's transforms.json: scaled rotation blocks, RGB images beside cubes
// that were never published, a lens model.
TEST(InfoCli, WarningsOnceAndTheRgbFlagForMissingCubes) {
  fs::path root = make_scene("info_basil_like");
  io::TransformsFile file = io::read_transforms(root / "transforms.json");
  fs::create_directories(root / "images");
  for (size_t i = 0; i < file.frames.size(); ++i) {
    auto& f = file.frames[i];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) f.camera_to_world_gl(r, c) *= 0.25;
    f.file_path = "images/v" + std::to_string(i) + ".png";
    io::write_png(root / f.file_path, torch::full({6, 8, 3}, 200, torch::kUInt8));
    f.intrinsics.k1 = -0.05;
  }
  io::write_transforms(root / "transforms.json", file);
  std::string out;
  ASSERT_EQ(info(root.string() + " 2>&1", &out), 0) << out;
  EXPECT_EQ(count(out, "non-orthonormal rotations"), 1u) << out;
  EXPECT_TRUE(contains(out, "  warning: " + (root / "transforms.json").string() +
                                ": 6 frame(s) have scaled or non-orthonormal rotations "
                                "(re-orthonormalised)\n"))
      << out;
  EXPECT_TRUE(contains(out, "cameras     6 views with lens distortion, undistorted to pinhole"))
      << out;
  EXPECT_EQ(count(out, "note: undistorting 6 views"), 1u) << out;

  fs::remove_all(root / "cubes");
  EXPECT_EQ(info(root.string() + " 2>&1", &out), 1);
  EXPECT_TRUE(contains(out, "none of the 6 hyperspectral cubes") && contains(out, "--rgb")) << out;
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
  ASSERT_EQ(info(root.string() + " --rgb 2>&1", &out), 0) << out;
  EXPECT_TRUE(contains(out, "bands       3 (the RGB images, at 610, 550, 465 nm)\n")) << out;
  EXPECT_EQ(count(out, "non-orthonormal rotations"), 1u) << out;
}

TEST(InfoCli, BadInputExitsWithOneLine) {
  fs::path root = test::temp_dir("info_none");
  std::string out;
  EXPECT_EQ(info(root.string(), &out), 1);
  EXPECT_TRUE(contains(out, "error: " + root.string() + ": expected transforms.json")) << out;
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;

  io::write_file_atomically(root / "transforms.json", "{\"frames\": 3}");
  EXPECT_EQ(info(root.string(), &out), 1);
  EXPECT_TRUE(contains(out, "transforms.json: frames: expected an array")) << out;
}

// A folder of rig captures: its band cameras and their angles to the
// reference camera, as text and JSON; a band missing is one error line.
TEST(InfoCli, DescribesRigCaptures) {
  fs::path root = test::temp_dir("info_rig");
  test::write_rig_capture(root / "0000SET" / "000", 0);
  test::write_rig_capture(root / "0000SET" / "000", 1);
  std::string out;
  ASSERT_EQ(info(root.string(), &out), 0) << out;
  EXPECT_TRUE(contains(out, "captures    2 (capture0 ... capture1)")) << out;
  EXPECT_TRUE(contains(out, "rig         3 band cameras")) << out;
  EXPECT_TRUE(contains(out,
                       "camera 3  Red         668.0 nm (FWHM 14.0), 16 x 12 px, 16 bits, "
                       "focal 5.40 mm, 1.500 deg from the reference"))
      << out;
  ASSERT_EQ(info(root.string() + " --json", &out), 0) << out;
  const auto j = nlohmann::json::parse(out);
  EXPECT_EQ(j["layout"], "rig captures");
  ASSERT_EQ(j["cameras"].size(), 3u);
  EXPECT_EQ(j["cameras"][1]["band"], "Green");
  EXPECT_EQ(j["cameras"][1]["centre_nm"], 560);
  EXPECT_EQ(j["radiance"], false);
  // These files carry no EXIF: radiance is refused, naming a file and the tag.
  ASSERT_EQ(info(root.string(), &out), 0) << out;
  EXPECT_TRUE(contains(out, "radiance    no: ")) << out;
  EXPECT_TRUE(contains(out, "its EXIF has no ExposureTime")) << out;

  // With exposure, gain, calibration and a DLS reading, both are available.
  const fs::path full = test::temp_dir("info_rig_radiometry");
  for (int camera = 1; camera <= 2; ++camera) {
    io::RigBandImage b;
    b.file = full / ("IMG_0000_" + std::to_string(camera) + ".tif");
    b.capture_id = "c0";
    b.rig_index = camera;
    b.band_name = camera == 1 ? "Red" : "NIR";
    b.centre_nm = camera == 1 ? 668 : 842;
    b.fwhm_nm = 14;
    b.radiometry.black_level = 4800;
    b.radiometry.has_black_level = true;
    b.radiometry.exposure_s = 0.0015;
    b.radiometry.iso_speed = 100;
    b.radiometry.calibration = {3e-4, 1e-6, 1e-5};
    b.radiometry.irradiance = 1.5;
    io::write_rig_band_image(b, torch::full({6, 8}, 20000.0));
  }
  ASSERT_EQ(info(full.string(), &out), 0) << out;
  EXPECT_TRUE(contains(out,
                       "black level 4800, exposure 1.500 ms, gain 1x, calibration yes, "
                       "vignetting none, DLS 1.500000 W/m2/nm"))
      << out;
  EXPECT_TRUE(contains(out, "radiance    every band image")) << out;
  EXPECT_TRUE(contains(out, "reflectance from the DLS in every capture")) << out;
  // One capture: maybe a panel capture; a flat grey frame holds no panel.
  EXPECT_TRUE(contains(out, "panel       IMG_0000_*: no panel in any band")) << out;

  fs::remove(root / "0000SET" / "000" / "IMG_0001_3.tif");
  EXPECT_EQ(info(root.string(), &out), 1);
  EXPECT_TRUE(contains(out, "capture capture1 has no image from band camera 3 (Red")) << out;
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
}

// MicaSense's sample panel capture (tests/data/micasense-sample, MIT):
// `info` says where the panel lies in each band, as `process --panel` would
// find it.
TEST(InfoCli, FindsThePanelOfAPanelCapture) {
  const fs::path sample = fs::path(DDHGS_SOURCE_DIR) / "tests/data/micasense-sample/0000SET/000";
  std::string out;
  ASSERT_EQ(info(sample.string(), &out), 0) << out;
  EXPECT_TRUE(
      contains(out, "panel       IMG_0000_*: placed by label RP02-1603036-SC in 5 of 5 bands"))
      << out;
  ASSERT_EQ(info(sample.string() + " --json", &out), 0) << out;
  const auto j = nlohmann::json::parse(out);
  ASSERT_EQ(j["panels"].size(), 1u);
  EXPECT_EQ(j["panels"][0]["files"], "IMG_0000_*");
  ASSERT_EQ(j["panels"][0]["bands"].size(), 5u);
  for (const auto& band : j["panels"][0]["bands"]) {
    EXPECT_EQ(band["region"], "placed from its QR label") << band;
    EXPECT_EQ(band["label"], "RP02-1603036-SC") << band;
    EXPECT_GT(band["pixels"].get<int64_t>(), 26000) << band;
  }
}

}  // namespace
}  // namespace ddhgs
