// Scene loading for the layouts real datasets have: wavelengths out of
// order, repeated or missing; transforms.json files whose cubes are missing;
// a COLMAP model beside a transforms.json in another world frame.
#include <gtest/gtest.h>

#include <cmath>

#include "core/similarity.h"
#include "io/colmap/colmap.h"
#include "io/cube/cube.h"
#include "io/image/image.h"
#include "io/scene/scene.h"
#include "io/transforms/transforms.h"
#include "support/error_text.h"
#include "support/test_support.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;
using test::contains;
using test::error_of;

constexpr int kViews = 6;

core::Mat4 w2c_of(int i) {
  core::Vec3 eye{3 * std::cos(1.1 * i), 3 * std::sin(1.1 * i), 1.0 + 0.2 * i};
  return core::look_at(eye, {0, 0, 0}, {0, 0, 1});
}

// Band b of every pixel holds 10 * (b + 1): the file's band order is visible.
torch::Tensor banded(int64_t bands) {
  return (torch::arange(1, bands + 1) * 10).to(torch::kUInt8).view({1, 1, bands}).repeat({4, 5, 1});
}

// transforms.json with cubes/v<i>.npy (bands banded) and images/v<i>.png.
TransformsFile write_scene(const fs::path& root, const std::vector<double>& wavelengths_nm) {
  fs::create_directories(root / "cubes");
  fs::create_directories(root / "images");
  TransformsFile file;
  file.wavelengths_nm = wavelengths_nm;
  for (int i = 0; i < kViews; ++i) {
    TransformsFrame f;
    f.file_path = "images/v" + std::to_string(i) + ".png";
    f.hyperspectral_file_path = "cubes/v" + std::to_string(i) + ".npy";
    f.intrinsics.fx = f.intrinsics.fy = 6;
    f.intrinsics.cx = 2.5;
    f.intrinsics.cy = 2;
    f.intrinsics.width = 5;
    f.intrinsics.height = 4;
    f.camera_to_world_gl = core::opencv_w2c_to_opengl_c2w(w2c_of(i));
    write_npy(root / f.hyperspectral_file_path, banded(int64_t(wavelengths_nm.size())));
    write_png(root / f.file_path, banded(3));
    file.frames.push_back(f);
  }
  write_transforms(root / "transforms.json", file);
  return file;
}

std::vector<float> first_pixel(const Scene& scene) {
  torch::Tensor p = scene.image(0)[0][0] * 255;
  return std::vector<float>(p.data_ptr<float>(), p.data_ptr<float>() + p.numel());
}

TEST(SceneBands, WavelengthsInAnotherOrderAreSortedWithTheirBands) {
  fs::path root = test::temp_dir("layout_descending");
  write_scene(root, {900, 700, 500, 400});
  auto scene = load_scene(root);
  EXPECT_EQ(scene->wavelengths_nm, (std::vector<double>{400, 500, 700, 900}));
  EXPECT_EQ(first_pixel(*scene), (std::vector<float>{40, 30, 20, 10}));
  ASSERT_EQ(scene->warnings.size(), 1u);
  EXPECT_TRUE(contains(scene->warnings[0], "not in increasing order")) << scene->warnings[0];

  // Unordered, with a band range and binning on the sorted grid.
  write_scene(root, {600, 400, 700, 500});
  LoadOptions options;
  options.band_min_nm = 450;
  options.bin = 3;
  scene = load_scene(root, options);
  EXPECT_EQ(scene->wavelengths_nm, std::vector<double>{600});  // mean of 500, 600, 700
  // Bins of uint8 cubes are rounded back to uint8.
  EXPECT_EQ(first_pixel(*scene)[0], std::round((40 + 10 + 30) / 3.0));
}

TEST(SceneBands, RepeatedWavelengthsFallBackToTheBandIndex) {
  fs::path root = test::temp_dir("layout_repeated");
  write_scene(root, {500, 500, 600});
  auto scene = load_scene(root);
  ASSERT_EQ(scene->bands(), 3);
  EXPECT_LT(scene->wavelengths_nm[0], scene->wavelengths_nm[1]);
  EXPECT_LT(scene->wavelengths_nm[1], scene->wavelengths_nm[2]);
  EXPECT_EQ(first_pixel(*scene), (std::vector<float>{10, 20, 30}));  // file order
  ASSERT_EQ(scene->warnings.size(), 1u);
  EXPECT_TRUE(contains(scene->warnings[0], "using the band index")) << scene->warnings[0];
}

TEST(SceneBands, RgbKeepsItsChannelOrder) {
  fs::path root = test::temp_dir("layout_rgb");
  write_scene(root, {400, 500, 600, 700});
  LoadOptions options;
  options.rgb = true;
  auto scene = load_scene(root, options);
  EXPECT_EQ(scene->wavelengths_nm, rgb_wavelengths_nm());
  EXPECT_EQ(first_pixel(*scene), (std::vector<float>{10, 20, 30}));
  EXPECT_TRUE(scene->warnings.empty());
}

TEST(SceneBands, MissingCubesNameTheRgbFlag) {
  fs::path root = test::temp_dir("layout_no_cubes");
  write_scene(root, {400, 500});
  fs::remove_all(root / "cubes");
  std::string what = error_of([&] { load_scene(root); });
  EXPECT_TRUE(contains(what, "none of the 6 hyperspectral cubes")) << what;
  EXPECT_TRUE(contains(what, "train on those as a 3-band scene with --rgb")) << what;
  fs::remove_all(root / "images");
  what = error_of([&] { load_scene(root); });
  EXPECT_TRUE(contains(what, "none of the 6") && !contains(what, "--rgb")) << what;
}

// A COLMAP model of the same cameras in another frame: the scene's points
// are the model's, mapped by `map` (COLMAP frame -> transforms.json frame).
ColmapModel model_in_frame(const core::Similarity& to_file) {
  ColmapModel model;
  model.cameras[1] = {1, "PINHOLE", 5, 4, {6, 6, 2.5, 2}};
  core::Similarity to_colmap;  // the inverse map
  to_colmap.scale = 1 / to_file.scale;
  to_colmap.rotation = to_file.rotation.transposed();
  to_colmap.translation = (to_colmap.rotation * to_file.translation) * -to_colmap.scale;
  for (int i = 0; i < kViews; ++i) {
    // Camera-to-world in the COLMAP frame: the file's pose moved by to_colmap.
    core::Mat4 c2w = w2c_of(i).rigid_inverse();
    core::Mat3 r = to_colmap.rotation * c2w.rotation();
    core::Vec3 centre = to_colmap.apply(c2w.translation());
    core::Mat4 w2c = core::Mat4::from(r, centre).rigid_inverse();
    ColmapImage image;
    image.image_id = i + 1;
    image.camera_id = 1;
    image.name = "v" + std::to_string(i) + ".jpg";
    image.qvec = core::rotation_to_quat(w2c.rotation());
    image.tvec = w2c.translation();
    model.images.push_back(image);
  }
  model.points.push_back({1, to_colmap.apply({0.1, 0.2, 0.3}), {10, 20, 30}, 0.5, {}});
  model.points.push_back({2, to_colmap.apply({-0.4, 0.0, 0.25}), {40, 50, 60}, 0.5, {}});
  return model;
}

core::Similarity basil_like_map() {
  core::Similarity s;
  s.scale = 0.25;
  s.rotation = core::quat_to_rotation(0.6, 0.2, -0.7, 0.3);
  s.translation = {14, -0.5, 1.4};
  return s;
}

void expect_points(const Scene& scene, const std::vector<float>& xyz, float tol) {
  ASSERT_TRUE(scene.points.xyz.defined());
  ASSERT_EQ(scene.points.xyz.numel(), int64_t(xyz.size()));
  for (size_t i = 0; i < xyz.size(); ++i)
    EXPECT_NEAR(scene.points.xyz.view(-1)[int64_t(i)].item<float>(), xyz[i], tol) << i;
}

TEST(ColmapBeside, PointsAreMappedIntoTheTransformsFrame) {
  fs::path root = test::temp_dir("layout_beside");
  write_scene(root, {400, 500});
  write_colmap_binary(root / "colmap" / "sparse" / "0", model_in_frame(basil_like_map()));
  auto scene = load_scene(root);
  EXPECT_EQ(scene->layout, "transforms.json");
  expect_points(*scene, {0.1f, 0.2f, 0.3f, -0.4f, 0.0f, 0.25f}, 1e-5f);
  EXPECT_EQ(scene->points.rgb[1][0].item<int>(), 40);
  ASSERT_EQ(scene->notes.size(), 1u);
  EXPECT_TRUE(contains(scene->notes[0], "using the 2 points of the COLMAP model") &&
              contains(scene->notes[0], "similarity fitted to 6 camera centres"))
      << scene->notes[0];
  EXPECT_TRUE(scene->warnings.empty());
}

TEST(ColmapBeside, AppliedTransformIsUsedWhenItFits) {
  fs::path root = test::temp_dir("layout_applied");
  TransformsFile file = write_scene(root, {400, 500});
  core::Similarity swap;  // nerfstudio's (x, y, z) -> (x, z, -y)
  swap.rotation.m = {1, 0, 0, 0, 0, 1, 0, -1, 0};
  write_colmap_binary(root / "sparse" / "0", model_in_frame(swap));
  core::Mat4 applied = core::Mat4::from(swap.rotation, {});
  file.applied_transform = applied;
  write_transforms(root / "transforms.json", file);
  auto scene = load_scene(root);
  expect_points(*scene, {0.1f, 0.2f, 0.3f, -0.4f, 0.0f, 0.25f}, 1e-5f);
  ASSERT_EQ(scene->notes.size(), 1u);
  EXPECT_TRUE(contains(scene->notes[0], "applied_transform")) << scene->notes[0];
}

TEST(ColmapBeside, AnotherFrameOrNoMatchesIsAWarning) {
  fs::path root = test::temp_dir("layout_unrelated");
  TransformsFile file = write_scene(root, {400, 500});
  ColmapModel model = model_in_frame(basil_like_map());
  // Shuffle the poses: no similarity relates the two sets of cameras.
  std::swap(model.images[0].tvec, model.images[3].tvec);
  std::swap(model.images[1].qvec, model.images[4].qvec);
  write_colmap_binary(root / "colmap" / "sparse" / "0", model);
  auto scene = load_scene(root);
  EXPECT_FALSE(scene->points.xyz.defined());
  ASSERT_EQ(scene->warnings.size(), 1u);
  EXPECT_TRUE(contains(scene->warnings[0], "is in another frame") &&
              contains(scene->warnings[0], "its points are not used"))
      << scene->warnings[0];

  for (auto& image : model.images) image.name = "other_" + image.name;
  write_colmap_binary(root / "colmap" / "sparse" / "0", model);
  scene = load_scene(root);
  ASSERT_EQ(scene->warnings.size(), 1u);
  EXPECT_TRUE(contains(scene->warnings[0], "shares only 0 image names")) << scene->warnings[0];

  // A ply_file_path wins: the model is not consulted.
  file.ply_file_path = "points.ply";
  PointCloud own;
  own.xyz = torch::tensor({1.f, 2.f, 3.f}).view({1, 3});
  write_point_ply(root / "points.ply", own);
  write_transforms(root / "transforms.json", file);
  scene = load_scene(root);
  expect_points(*scene, {1, 2, 3}, 0);
  EXPECT_TRUE(scene->warnings.empty());
}

}  // namespace
}  // namespace ddhgs::io
