// `ddhgs process` building blocks: the cube scan, pseudo-RGB modes with a
// scene-wide stretch (hand-computed values), COLMAP <-> transforms.json round
// trips, the largest-model choice, point spectra and COLMAP option checks.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>

#include "core/error.h"
#include "io/cube/cube.h"
#include "io/image/image.h"
#include "process/poses.h"
#include "process/process.h"
#include "process/pseudo_rgb_images.h"
#include "support/error_text.h"
#include "support/test_support.h"

namespace ddhgs::process {
using namespace io;
namespace {
namespace fs = std::filesystem;
using test::contains;
using test::error_of;

// A float32 cube [H, W, B] with value(y, x, b) = 0.01 * (b + 1) + 0.001 * (y * W + x).
torch::Tensor ramp_cube(int64_t h, int64_t w, int64_t b) {
  auto pixel = torch::arange(h * w, torch::kFloat32).reshape({h, w, 1}) * 0.001f;
  auto band = torch::arange(1, b + 1, torch::kFloat32).reshape({1, 1, b}) * 0.01f;
  return (pixel + band).contiguous();
}

CubeSet scan_with_range(const fs::path& dir, double lo, double hi) {
  return scan_cubes(dir, WavelengthRange{lo, hi});
}

TEST(SfmScan, FindsCubesSortedWithAnEvenGrid) {
  auto dir = test::temp_dir("sfm_scan");
  write_npy(dir / "b.npy", ramp_cube(4, 5, 3));
  write_npy(dir / "a.npy", ramp_cube(4, 5, 3));
  std::ofstream(dir / "notes.txt") << "not a cube";
  CubeSet set = scan_with_range(dir, 400, 500);
  ASSERT_EQ(set.names, (std::vector<std::string>{"a", "b"}));
  EXPECT_EQ(set.height, 4);
  EXPECT_EQ(set.width, 5);
  EXPECT_EQ(set.bands, 3);
  EXPECT_EQ(set.wavelengths_nm, (std::vector<double>{400, 450, 500}));
}

TEST(SfmScan, WavelengthsFromTheFilesWin) {
  auto dir = test::temp_dir("sfm_scan_envi");
  write_envi(dir / "v0.hdr", ramp_cube(3, 3, 2), {500, 600});
  write_envi(dir / "v1.hdr", ramp_cube(3, 3, 2), {500, 600});
  EXPECT_EQ(scan_cubes(dir).wavelengths_nm, (std::vector<double>{500, 600}));
  write_envi(dir / "v2.hdr", ramp_cube(3, 3, 2), {510, 600});
  EXPECT_TRUE(contains(error_of([&] { scan_cubes(dir); }), "names other wavelengths than v0.hdr"));
}

TEST(SfmScan, BadFoldersGiveOneLineNamingTheFile) {
  auto empty = test::temp_dir("sfm_empty");
  std::string e = error_of([&] { scan_with_range(empty, 400, 500); });
  EXPECT_TRUE(contains(e, empty.string() + ": holds no cube files")) << e;

  auto mixed = test::temp_dir("sfm_mixed");
  write_npy(mixed / "a.npy", ramp_cube(4, 4, 3));
  write_npy(mixed / "b.npy", ramp_cube(4, 4, 5));
  e = error_of([&] { scan_with_range(mixed, 400, 500); });
  EXPECT_TRUE(contains(e, "b.npy: has 5 bands, expected 3")) << e;

  auto sizes = test::temp_dir("sfm_sizes");
  write_npy(sizes / "a.npy", ramp_cube(4, 4, 3));
  write_npy(sizes / "b.npy", ramp_cube(4, 6, 3));
  e = error_of([&] { scan_with_range(sizes, 400, 500); });
  EXPECT_TRUE(contains(e, "b.npy: is 6x4 pixels, expected 4x4 like a.npy")) << e;

  auto broken = test::temp_dir("sfm_broken");
  write_npy(broken / "a.npy", ramp_cube(4, 4, 3));
  std::ofstream(broken / "b.npy") << "garbage";
  e = error_of([&] { scan_with_range(broken, 400, 500); });
  EXPECT_TRUE(contains(e, (broken / "b.npy").string())) << e;

  auto twins = test::temp_dir("sfm_twins");
  write_npy(twins / "a.npy", ramp_cube(4, 4, 3));
  write_tiff(twins / "a.tif", ramp_cube(4, 4, 3));
  e = error_of([&] { scan_with_range(twins, 400, 500); });
  EXPECT_TRUE(contains(e, "has the same name as a.npy")) << e;

  auto unnamed = test::temp_dir("sfm_unnamed");
  write_npy(unnamed / "a.npy", ramp_cube(4, 4, 3));
  e = error_of([&] { scan_cubes(unnamed); });
  EXPECT_TRUE(contains(e, "a.npy: names no wavelengths; pass --wl-range")) << e;
}

TEST(SfmScan, WavelengthRangeSyntax) {
  WavelengthRange r = parse_wavelength_range("400.5:1000");
  EXPECT_DOUBLE_EQ(r.first_nm, 400.5);
  EXPECT_DOUBLE_EQ(r.last_nm, 1000);
  for (const char* bad : {"400", "400:", "a:b", "500:400", "400:1000x"})
    EXPECT_TRUE(contains(error_of([&] { parse_wavelength_range(bad); }), "--wl-range")) << bad;
}

TEST(SfmPseudoRgb, BandsModeIsTheNearestBandsInLinearLight) {
  torch::Tensor cube = ramp_cube(2, 3, 3);  // bands at 450, 550, 650 nm
  auto options = parse_sfm_pseudo_rgb("bands:640,560,440");
  torch::Tensor rgb = pseudo_rgb_linear(cube, {450, 550, 650}, options);
  EXPECT_TRUE(pseudo_rgb_encodes(options));
  EXPECT_TRUE(torch::allclose(rgb, cube.flip({2}), 1e-4, 1e-6));
}

TEST(SfmPseudoRgb, CieModeMapsWhiteToWhiteAndKeepsHeadroomAboveOne) {
  std::vector<double> nm;
  for (double w = 380; w <= 780; w += 10) nm.push_back(w);
  auto options = parse_sfm_pseudo_rgb("cie");
  torch::Tensor white = torch::ones({1, 1, int64_t(nm.size())});
  torch::Tensor rgb = pseudo_rgb_linear(white, nm, options);
  EXPECT_TRUE(torch::allclose(rgb, torch::ones({1, 1, 3}), 0, 0.02)) << rgb;
  // Linear in the cube up to the headroom: core::pseudo_rgb alone clamps at 1.
  torch::Tensor bright = pseudo_rgb_linear(white * 6.0, nm, options);
  EXPECT_TRUE(torch::allclose(bright, rgb * 6.0, 1e-3, 1e-5)) << bright;
}

TEST(SfmPseudoRgb, MatrixModeWeighsBandsAsWritten) {
  auto dir = test::temp_dir("sfm_matrix");
  std::ofstream(dir / "m.txt") << "# R, G, B weights per band\n1 0 0 0\n0 0.5 0.5 0\n0 0 0 2\n";
  auto options = parse_sfm_pseudo_rgb("matrix:" + (dir / "m.txt").string());
  EXPECT_FALSE(pseudo_rgb_encodes(options));
  torch::Tensor cube = ramp_cube(1, 2, 4);
  torch::Tensor rgb = pseudo_rgb_linear(cube, {400, 500, 600, 700}, options);
  // Pixel 1: bands 0.011 0.021 0.031 0.041 -> (0.011, 0.026, 0.082).
  EXPECT_NEAR(rgb[0][1][0].item<float>(), 0.011f, 1e-6);
  EXPECT_NEAR(rgb[0][1][1].item<float>(), 0.026f, 1e-6);
  EXPECT_NEAR(rgb[0][1][2].item<float>(), 0.082f, 1e-6);
  EXPECT_TRUE(contains(error_of([] { parse_sfm_pseudo_rgb("rainbow"); }), "pseudo-RGB"));
  EXPECT_TRUE(
      contains(error_of([] { parse_sfm_pseudo_rgb("matrix:/no/such/file"); }), "/no/such/file"));
}

TEST(SfmPseudoRgb, StretchPercentilesAreInterpolatedOverAllViews) {
  // 0..1000 split over two views: percentile p sits at value 10 p.
  Stretch s = scene_stretch(
      {torch::arange(0, 500, torch::kFloat32), torch::arange(500, 1001, torch::kFloat32)}, 0.5,
      99.5);
  EXPECT_NEAR(s.low, 5.0, 1e-9);
  EXPECT_NEAR(s.high, 995.0, 1e-9);
  torch::Tensor v = torch::tensor({5.0f, 500.0f, 995.0f, 2000.0f}).reshape({1, 4, 1});
  torch::Tensor out = apply_stretch(v, s, false);
  EXPECT_EQ(out[0][0][0].item<uint8_t>(), 0);
  EXPECT_EQ(out[0][1][0].item<uint8_t>(), 128);  // (495 / 990) * 255 = 127.5 -> 128
  EXPECT_EQ(out[0][2][0].item<uint8_t>(), 255);
  EXPECT_EQ(out[0][3][0].item<uint8_t>(), 255);
  // With the sRGB curve: linear 0.5 of the range -> 0.7354 -> 188.
  EXPECT_EQ(apply_stretch(v, s, true)[0][1][0].item<uint8_t>(), 188);
  Stretch flat = scene_stretch({torch::full({10}, 0.3f)});
  EXPECT_GT(flat.high, flat.low);
}

TEST(SfmPseudoRgb, OneStretchForTheSceneKeepsDarkViewsDark) {
  auto dir = test::temp_dir("sfm_images");
  auto cubes_dir = dir / "cubes";
  fs::create_directories(cubes_dir);
  write_npy(cubes_dir / "dark.npy", torch::full({6, 8, 3}, 0.1f));
  write_npy(cubes_dir / "bright.npy", torch::full({6, 8, 3}, 0.4f));
  CubeSet set = scan_with_range(cubes_dir, 450, 650);
  Stretch s =
      write_pseudo_rgb_images(set, parse_sfm_pseudo_rgb("bands:650,550,450"), dir / "images");
  EXPECT_NEAR(s.low, 0.1, 1e-4);
  EXPECT_NEAR(s.high, 0.4, 1e-4);
  torch::Tensor dark = read_image(dir / "images" / "dark.png");
  torch::Tensor bright = read_image(dir / "images" / "bright.png");
  ASSERT_EQ(dark.sizes(), (std::vector<int64_t>{6, 8, 3}));
  // A per-image stretch would make both images identical.
  EXPECT_EQ(dark.max().item<uint8_t>(), 0);
  EXPECT_EQ(bright.min().item<uint8_t>(), 255);
}

ColmapModel posed_model() {
  ColmapModel m;
  m.cameras[2] = {2, "PINHOLE", 8, 6, {9.5, 9.25, 4.1, 2.9}};
  for (int i = 0; i < 4; ++i) {
    ColmapImage image;
    image.image_id = 7 + i;
    double a = 0.4 + 0.9 * i;
    image.qvec = {std::cos(a / 2), 0.6 * std::sin(a / 2), 0.0, 0.8 * std::sin(a / 2)};
    image.tvec = {0.1 * i, -0.7, 2.5};
    image.camera_id = 2;
    image.name = "v" + std::to_string(i) + ".png";
    m.images.push_back(image);
  }
  return m;
}

CubeSet named_cubes(const std::vector<std::string>& names) {
  CubeSet set;
  set.names = names;
  for (const auto& n : names) set.files.push_back(n + ".npy");
  set.height = 6;
  set.width = 8;
  set.bands = 2;
  set.wavelengths_nm = {500, 600};
  return set;
}

TEST(SfmConvert, ColmapToTransformsAndBackRoundTrips) {
  ColmapModel model = posed_model();
  CubeSet cubes = named_cubes({"v0", "v1", "v2", "v3", "unposed"});
  std::vector<std::string> paths = {"../c/v0.npy", "../c/v1.npy", "../c/v2.npy", "../c/v3.npy",
                                    "../c/unposed.npy"};
  TransformsFile tf = transforms_from_colmap(model, cubes, paths);
  ASSERT_EQ(tf.frames.size(), 4u);
  EXPECT_EQ(tf.wavelengths_nm, cubes.wavelengths_nm);
  EXPECT_EQ(tf.frames[2].hyperspectral_file_path, "../c/v2.npy");
  EXPECT_EQ(tf.frames[2].file_path, "images/v2.png");

  // Through the file on disk, then back to COLMAP.
  auto dir = test::temp_dir("sfm_roundtrip");
  write_transforms(dir / "transforms.json", tf);
  ColmapModel back = colmap_from_transforms(read_transforms(dir / "transforms.json"));
  ASSERT_EQ(back.cameras.size(), 1u);
  const ColmapCamera& cam = back.cameras.begin()->second;
  EXPECT_EQ(cam.model, "PINHOLE");
  EXPECT_EQ(cam.width, 8);
  EXPECT_EQ(cam.height, 6);
  for (size_t p = 0; p < 4; ++p) EXPECT_NEAR(cam.params[p], model.cameras[2].params[p], 1e-9);
  ASSERT_EQ(back.images.size(), 4u);
  for (size_t i = 0; i < 4; ++i) {
    const auto& a = model.images[i];
    const auto& b = back.images[i];
    EXPECT_EQ(b.name, "images/v" + std::to_string(i) + ".png");
    double norm = 0, dot = 0;
    for (int k = 0; k < 4; ++k) {
      norm += a.qvec[size_t(k)] * a.qvec[size_t(k)];
      dot += a.qvec[size_t(k)] * b.qvec[size_t(k)];
    }
    EXPECT_NEAR(std::abs(dot) / std::sqrt(norm), 1.0, 1e-9);  // same rotation, sign free
    EXPECT_NEAR(b.tvec.x, a.tvec.x, 1e-9);
    EXPECT_NEAR(b.tvec.y, a.tvec.y, 1e-9);
    EXPECT_NEAR(b.tvec.z, a.tvec.z, 1e-9);
  }
  // And forwards again: the same frames.
  TransformsFile again = transforms_from_colmap(back, cubes, paths);
  ASSERT_EQ(again.frames.size(), 4u);
  for (size_t i = 0; i < 4; ++i)
    for (size_t k = 0; k < 16; ++k)
      EXPECT_NEAR(again.frames[i].camera_to_world_gl.m[k], tf.frames[i].camera_to_world_gl.m[k],
                  1e-9);
}

TEST(SfmConvert, DistortedCamerasKeepTheirLensMissizedOnesAreRefused) {
  ColmapModel model = posed_model();
  CubeSet cubes = named_cubes({"v0", "v1"});
  std::vector<std::string> paths = {"v0.npy", "v1.npy"};
  // The scene's views are undistorted when they load: the lens is kept.
  model.cameras[2] = {2, "SIMPLE_RADIAL", 8, 6, {9.5, 4.1, 2.9, 0.01}};
  TransformsFile file = transforms_from_colmap(model, cubes, paths);
  ASSERT_EQ(file.frames.size(), 2u);
  const core::Intrinsics& k = file.frames[1].intrinsics;
  EXPECT_EQ(k.k1, 0.01);
  EXPECT_EQ(k.fx, 9.5);
  EXPECT_EQ(k.fy, 9.5);
  ColmapModel back = colmap_from_transforms(file);
  ASSERT_EQ(back.cameras.size(), 1u);  // every image uses camera 2
  EXPECT_EQ(back.cameras.at(back.images[1].camera_id).model, "OPENCV");
  EXPECT_TRUE(colmap_intrinsics(back.cameras.at(back.images[1].camera_id)) == k);

  model.cameras[2] = {2, "PINHOLE", 16, 12, {9.5, 9.25, 4.1, 2.9}};
  EXPECT_TRUE(contains(error_of([&] { transforms_from_colmap(model, cubes, paths); }),
                       "is 16x12 pixels, but the cubes are 8x6"));
}

TEST(SfmConvert, LargestModelHasTheMostViewsThenPoints) {
  EXPECT_FALSE(largest_model({}).has_value());
  std::vector<ColmapModel> models(3);
  models[0].images.resize(5);
  models[0].points.resize(50);
  models[1].images.resize(7);
  models[1].points.resize(3);
  models[2].images.resize(7);
  models[2].points.resize(20);
  EXPECT_EQ(largest_model(models), std::optional<size_t>(2));
  models[0].images.resize(8);
  EXPECT_EQ(largest_model(models), std::optional<size_t>(0));
}

TEST(SfmConvert, PointSpectraAreMeansOverTheObservingPixels) {
  auto dir = test::temp_dir("sfm_spectra");
  write_npy(dir / "v0.npy", ramp_cube(6, 8, 2));
  write_npy(dir / "v1.npy", ramp_cube(6, 8, 2) * 2.0f);
  CubeSet cubes = scan_with_range(dir, 500, 600);
  ColmapModel model = posed_model();
  model.images.resize(3);  // v2 has no cube: its observations are ignored
  // Point 40 seen at pixel (x 3, y 1) in v0 and (x 5, y 2) in v1; point 41 at
  // (0, 0) in v2 only; point 42 at (7, 5) in v0.
  model.images[0].xys = {{3.7, 1.2}, {7.5, 5.5}};
  model.images[0].point3d_ids = {40, 42};
  model.images[1].xys = {{5.1, 2.9}, {1.0, 1.0}};
  model.images[1].point3d_ids = {40, -1};
  model.images[2].xys = {{0.5, 0.5}};
  model.images[2].point3d_ids = {41};
  model.points.resize(3);
  model.points[0].point3d_id = 40;
  model.points[1].point3d_id = 41;
  model.points[2].point3d_id = 42;
  torch::Tensor s = sample_point_spectra(model, cubes);
  ASSERT_EQ(s.sizes(), (std::vector<int64_t>{3, 2}));
  auto value = [](int64_t y, int64_t x, int64_t b) { return 0.01 * (b + 1) + 0.001 * (y * 8 + x); };
  for (int64_t b = 0; b < 2; ++b) {
    double p40 = 0.5 * (value(1, 3, b) + 2 * value(2, 5, b));
    double p42 = value(5, 7, b);
    EXPECT_NEAR(s[0][b].item<float>(), p40, 1e-4);
    EXPECT_NEAR(s[2][b].item<float>(), p42, 1e-4);
    EXPECT_NEAR(s[1][b].item<float>(), 0.5 * (p40 + p42), 1e-4);  // unobserved: the mean
  }
}

TEST(SfmColmapOptions, UnknownModelsAndBadSettingsAreRefused) {
  ColmapOptions o;
  EXPECT_NO_THROW(check_colmap_options(o));
  for (const char* lens : {"SIMPLE_RADIAL", "OPENCV", "OPENCV_FISHEYE"}) {
    o.camera_model = lens;  // undistorted when the scene loads
    EXPECT_NO_THROW(check_colmap_options(o)) << lens;
  }
  o.camera_model = "FOV";
  EXPECT_TRUE(contains(error_of([&] { check_colmap_options(o); }), "unsupported camera model"));
  o.camera_model = "FISHEYE_WHATEVER";
  EXPECT_TRUE(contains(error_of([&] { check_colmap_options(o); }), "--camera-model"));
  o.camera_model = "SIMPLE_PINHOLE";
  o.matcher = "vocab";
  EXPECT_TRUE(contains(error_of([&] { check_colmap_options(o); }), "--matcher 'vocab'"));
  o.matcher = "sequential";
  o.settings = {"Mapper.init_min_num_inliers=30"};
  EXPECT_NO_THROW(check_colmap_options(o));
  for (const char* bad : {"Mapper.x", "init=3", "Dense.x=1"}) {
    o.settings = {bad};
    EXPECT_TRUE(contains(error_of([&] { check_colmap_options(o); }), "--colmap-set")) << bad;
  }
}

TEST(SfmColmapOptions, MissingColmapSaysHowToInstallIt) {
  ColmapOptions o;
  o.binary = "/no/such/colmap";
  std::string e = error_of([&] { find_colmap(o); });
  EXPECT_TRUE(contains(e, "/no/such/colmap: is not an executable COLMAP")) << e;
  EXPECT_TRUE(contains(e, "apt-get install colmap")) << e;

  auto empty_path = test::temp_dir("sfm_empty_path");
  std::string saved = std::getenv("PATH") ? std::getenv("PATH") : "";
  setenv("PATH", empty_path.c_str(), 1);
  o.binary = "colmap";
  e = error_of([&] { find_colmap(o); });
  setenv("PATH", saved.c_str(), 1);
  EXPECT_TRUE(contains(e, "colmap: COLMAP not found on PATH")) << e;

  auto fake = empty_path / "colmap";
  std::ofstream(fake) << "#!/bin/sh\n";
  fs::permissions(fake, fs::perms::owner_all);
  o.binary = fake.string();
  EXPECT_EQ(find_colmap(o), fake.string());
}

}  // namespace
}  // namespace ddhgs::process
