// load_scene and Scene: layouts, missing frames, downscaling, band selection,
// binning, the view cache and clean ground truth, on small scenes written here.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "core/error.h"
#include "io/colmap/colmap.h"
#include "io/files/atomic_file.h"
#include "io/image/image.h"
#include "io/scene/scene.h"
#include "io/transforms/transforms.h"
#include "support/error_text.h"
#include "support/test_support.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;

// Deterministic uint8 content that differs per view, pixel and band.
torch::Tensor pattern(int view, int64_t h, int64_t w, int64_t bands) {
  torch::Tensor y = torch::arange(h).view({h, 1, 1});
  torch::Tensor x = torch::arange(w).view({1, w, 1});
  torch::Tensor b = torch::arange(bands).view({1, 1, bands});
  return ((y * 37 + x * 11 + b * 53 + view * 17) % 256).to(torch::kUInt8);
}

core::Mat4 w2c_of(int i) {
  core::Vec3 eye{3 * std::cos(0.5 * i), 3 * std::sin(0.5 * i), 1.0};
  return core::look_at(eye, {0, 0, 0}, {0, 0, 1});
}

struct SceneSpec {
  int views = 10;
  int64_t height = 6, width = 8, bands = 4;
  std::vector<double> wavelengths_nm = {400, 500, 600, 700};
};

// transforms.json + hyperspectral/r_<i>.npy + images/r_<i>.png
void write_scene(const fs::path& root, const SceneSpec& spec) {
  fs::create_directories(root / "hyperspectral");
  fs::create_directories(root / "images");
  TransformsFile file;
  file.wavelengths_nm = spec.wavelengths_nm;
  for (int i = 0; i < spec.views; ++i) {
    TransformsFrame f;
    std::string stem = "r_" + std::string(i < 10 ? "0" : "") + std::to_string(i);
    f.file_path = "images/" + stem + ".png";
    f.hyperspectral_file_path = "hyperspectral/" + stem + ".npy";
    f.intrinsics.fx = f.intrinsics.fy = 10;
    f.intrinsics.cx = spec.width / 2.0;
    f.intrinsics.cy = spec.height / 2.0;
    f.intrinsics.width = int(spec.width);
    f.intrinsics.height = int(spec.height);
    f.camera_to_world_gl = core::opencv_w2c_to_opengl_c2w(w2c_of(i));
    write_npy(root / f.hyperspectral_file_path, pattern(i, spec.height, spec.width, spec.bands));
    write_png(root / f.file_path, pattern(i, spec.height, spec.width, 3));
    file.frames.push_back(f);
  }
  write_transforms(root / "transforms.json", file);
}

using test::contains;
using test::error_of;

bool any_warning(const Scene& scene, const std::string& part) {
  for (const auto& w : scene.warnings)
    if (contains(w, part)) return true;
  return false;
}

void expect_mat_near(const core::Mat4& a, const core::Mat4& b, double tol) {
  for (int i = 0; i < 16; ++i) EXPECT_NEAR(a.m[size_t(i)], b.m[size_t(i)], tol) << "entry " << i;
}

TEST(Dataset, LoadsTransformsScene) {
  fs::path root = test::temp_dir("ds_basic");
  write_scene(root, {});
  auto scene = load_scene(root);
  EXPECT_EQ(scene->layout, "transforms.json");
  ASSERT_EQ(scene->views.size(), 10u);
  EXPECT_EQ(scene->views[3].name, "r_03");
  EXPECT_EQ(scene->bands(), 4);
  EXPECT_EQ(scene->wavelengths_nm, (std::vector<double>{400, 500, 600, 700}));
  EXPECT_EQ(scene->stored_type, SampleType::U8);
  EXPECT_EQ(scene->scale, 255);
  EXPECT_EQ(scene->view_bytes(), size_t(6 * 8 * 4));
  EXPECT_EQ(scene->test, std::vector<int>{8});
  EXPECT_EQ(scene->train.size(), 9u);
  EXPECT_FALSE(scene->has_clean());
  EXPECT_TRUE(scene->warnings.empty());
  EXPECT_FALSE(scene->points.xyz.defined());
  for (int i = 0; i < 10; ++i)
    expect_mat_near(scene->views[size_t(i)].camera.world_to_camera, w2c_of(i), 1e-9);

  torch::Tensor image = scene->image(7);
  EXPECT_EQ(image.sizes(), (std::vector<int64_t>{6, 8, 4}));
  EXPECT_EQ(image.scalar_type(), torch::kFloat);
  EXPECT_TRUE(torch::allclose(image, pattern(7, 6, 8, 4).to(torch::kFloat) / 255, 0, 1e-7));
  EXPECT_THROW(scene->image(10), core::Error);
}

TEST(Dataset, MissingFramesAreSkippedWithAWarning) {
  fs::path root = test::temp_dir("ds_missing");
  write_scene(root, {});
  fs::remove(root / "hyperspectral" / "r_04.npy");
  auto scene = load_scene(root);
  ASSERT_EQ(scene->views.size(), 9u);
  EXPECT_EQ(scene->views[4].name, "r_05");
  EXPECT_TRUE(any_warning(*scene, "r_04.npy")) << scene->warnings.front();
  EXPECT_TRUE(scene->test.empty());  // ceil(0.9 * 9) = 9: the 9 remaining views all train

  for (int i = 0; i < 10; ++i)
    fs::remove(root / "hyperspectral" / ("r_0" + std::to_string(i) + ".npy"));
  std::string what = error_of([&] { load_scene(root); });
  EXPECT_TRUE(contains(what, "transforms.json") && contains(what, "none of the 10")) << what;
}

TEST(Dataset, ScaledRotationsAreRepaired) {
  fs::path root = test::temp_dir("ds_scaled");
  write_scene(root, {});
  TransformsFile file = read_transforms(root / "transforms.json");
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) file.frames[2].camera_to_world_gl(r, c) *= 0.37;
  write_transforms(root / "transforms.json", file);
  auto scene = load_scene(root);
  expect_mat_near(scene->views[2].camera.world_to_camera, w2c_of(2), 1e-9);
  EXPECT_TRUE(any_warning(*scene, "1 frame(s) have scaled or non-orthonormal rotations"));
}

TEST(Dataset, BandCountMismatchNamesFileAndCounts) {
  fs::path root = test::temp_dir("ds_bands");
  write_scene(root, {});
  write_npy(root / "hyperspectral" / "r_06.npy", pattern(6, 6, 8, 5));
  auto scene = load_scene(root);
  std::string what = error_of([&] { scene->image(6); });
  EXPECT_TRUE(contains(what, "r_06.npy") && contains(what, "has 5 bands, expected 4")) << what;

  SceneSpec spec;
  spec.wavelengths_nm = {400, 500, 600};
  write_scene(root, spec);
  what = error_of([&] { load_scene(root); });
  EXPECT_TRUE(contains(what, "lists 3 wavelengths") && contains(what, "4 bands")) << what;
}

// Independent area average: loops over blocks, in double, then rounded.
torch::Tensor block_average(const torch::Tensor& data, int d) {
  int64_t h = data.size(0) / d, w = data.size(1) / d, b = data.size(2);
  torch::Tensor out = torch::empty({h, w, b}, torch::kUInt8);
  auto in = data.accessor<uint8_t, 3>();
  auto o = out.accessor<uint8_t, 3>();
  for (int64_t y = 0; y < h; ++y)
    for (int64_t x = 0; x < w; ++x)
      for (int64_t c = 0; c < b; ++c) {
        double sum = 0;
        for (int dy = 0; dy < d; ++dy)
          for (int dx = 0; dx < d; ++dx) sum += in[y * d + dy][x * d + dx][c];
        o[y][x][c] = uint8_t(std::nearbyint(sum / (d * d)));
      }
  return out;
}

TEST(Dataset, DownscaleAveragesOrUsesReducedFolders) {
  fs::path root = test::temp_dir("ds_downscale");
  SceneSpec spec;
  spec.height = 7;  // odd: the last row is dropped, as Intrinsics::downscaled does
  write_scene(root, spec);
  LoadOptions options;
  options.downscale = 2;
  auto scene = load_scene(root, options);
  const auto& k = scene->views[1].camera.intrinsics;
  EXPECT_EQ(k.width, 4);
  EXPECT_EQ(k.height, 3);
  EXPECT_EQ(k.fx, 5);
  EXPECT_EQ(scene->view_bytes(), size_t(4 * 3 * 4));
  torch::Tensor expected = block_average(pattern(1, 7, 8, 4), 2);
  EXPECT_TRUE(torch::equal((scene->image(1) * 255).round().to(torch::kUInt8), expected));

  // A hyperspectral_2/ copy wins over averaging.
  fs::create_directories(root / "hyperspectral_2");
  write_npy(root / "hyperspectral_2" / "r_01.npy", torch::full({3, 4, 4}, 7, torch::kUInt8));
  scene = load_scene(root, options);
  EXPECT_EQ(scene->views[1].data_path, root / "hyperspectral_2" / "r_01.npy");
  EXPECT_EQ(scene->views[2].data_path, root / "hyperspectral" / "r_02.npy");
  EXPECT_TRUE(torch::allclose(scene->image(1), torch::full({3, 4, 4}, 7.0f / 255)));

  // A reduced copy of the wrong size is an error naming it.
  write_npy(root / "hyperspectral_2" / "r_01.npy", torch::full({5, 4, 4}, 7, torch::kUInt8));
  scene = load_scene(root, options);
  std::string what = error_of([&] { scene->image(1); });
  EXPECT_TRUE(contains(what, "hyperspectral_2/r_01.npy") && contains(what, "4x5 pixels")) << what;

  // RGB views: images_2/ likewise.
  options.rgb = true;
  fs::create_directories(root / "images_2");
  write_png(root / "images_2" / "r_03.png", torch::full({3, 4, 3}, 9, torch::kUInt8));
  scene = load_scene(root, options);
  EXPECT_EQ(scene->views[3].data_path, root / "images_2" / "r_03.png");
}

TEST(Dataset, BandRangeAndBinning) {
  fs::path root = test::temp_dir("ds_binning");
  SceneSpec spec;
  spec.bands = 6;
  spec.wavelengths_nm = {400, 450, 500, 550, 600, 650};
  write_scene(root, spec);
  LoadOptions options;
  options.band_min_nm = 440;
  options.band_max_nm = 660;  // keeps bands 1..5
  options.bin = 2;            // (1, 2), (3, 4); band 5 is dropped
  auto scene = load_scene(root, options);
  EXPECT_EQ(scene->wavelengths_nm, (std::vector<double>{475, 575}));
  EXPECT_EQ(scene->band_index, (std::vector<int>{1, 2, 3, 4}));
  EXPECT_TRUE(any_warning(*scene, "drops the last 1 band"));
  torch::Tensor raw = pattern(0, 6, 8, 6).to(torch::kDouble);
  torch::Tensor expected =
      torch::stack(
          {(raw.select(2, 1) + raw.select(2, 2)) / 2, (raw.select(2, 3) + raw.select(2, 4)) / 2}, 2)
          .round()
          .to(torch::kFloat) /
      255;
  EXPECT_TRUE(torch::allclose(scene->image(0), expected, 0, 1e-7));

  options.band_min_nm = 900;
  options.band_max_nm = 1000;
  EXPECT_TRUE(contains(error_of([&] { load_scene(root, options); }), "no band lies"));
}

TEST(Dataset, FloatCubesStayExact) {
  fs::path root = test::temp_dir("ds_float");
  write_scene(root, {});
  torch::Tensor values = torch::rand({6, 8, 4}, torch::TensorOptions().dtype(torch::kFloat));
  write_npy(root / "hyperspectral" / "r_00.npy", values);
  for (int i = 1; i < 10; ++i)
    write_npy(root / "hyperspectral" / ("r_0" + std::to_string(i) + ".npy"), values);
  LoadOptions options;
  options.bin = 2;
  auto scene = load_scene(root, options);
  EXPECT_EQ(scene->stored_type, SampleType::F32);
  EXPECT_EQ(scene->scale, 1);
  torch::Tensor expected = values.view({6, 8, 2, 2}).mean(3);
  EXPECT_TRUE(torch::allclose(scene->image(0), expected, 1e-6, 1e-7));
}

// Scene::image(view, window) converts only a window's samples; it must equal
// narrowing the whole converted view, for every stored sample type (the band
// gather copies raw bits) and across the gather's 4096-pixel blocks.
TEST(Dataset, ImageWindowsEqualTheNarrowedImage) {
  const int64_t h = 60, w = 80, bands = 7;  // 4800 pixels: two blocks
  torch::manual_seed(4);
  const torch::Tensor u16 =
      torch::randint(0, 65536, {h, w, bands}).to(torch::kInt32).to(torch::kInt16);
  for (auto [name, data, type] :
       {std::tuple{"u8", pattern(0, h, w, bands), SampleType::U8},
        std::tuple{"u16", u16, SampleType::U16},
        std::tuple{"f16", torch::rand({h, w, bands}).to(torch::kHalf), SampleType::F16},
        std::tuple{"f32", torch::rand({h, w, bands}), SampleType::F32}}) {
    const fs::path root = test::temp_dir(std::string("ds_window_") + name);
    SceneSpec spec;
    spec.height = h;
    spec.width = w;
    spec.bands = bands;
    spec.wavelengths_nm = {400, 450, 500, 550, 600, 650, 700};
    write_scene(root, spec);
    write_npy(root / "hyperspectral" / "r_03.npy", data, type);
    auto scene = load_scene(root);
    const torch::Tensor whole = scene->image(3);
    const torch::Tensor drawn = torch::tensor({0, 2, 3, 6}, torch::kInt64);
    ImageWindow window{5, 9, 71, 50, drawn};
    EXPECT_TRUE(
        scene->image(3, window).equal(whole.slice(0, 9, 50).slice(1, 5, 71).index_select(2, drawn)))
        << name;
    EXPECT_TRUE(scene->image(3, {}).equal(whole)) << name;
    EXPECT_TRUE(scene->image(3, {0, 0, 0, 0, drawn}).equal(whole.index_select(2, drawn))) << name;
    EXPECT_TRUE(scene->image(3, {2, 1, 30, 0, {}}).equal(whole.slice(0, 1).slice(1, 2, 30)))
        << name;
    EXPECT_TRUE(contains(error_of([&] {
                           scene->image(3, {0, 0, w + 1, 0, {}});
                         }),
                         "image window lies outside the view"));
    EXPECT_TRUE(contains(error_of([&] {
                           scene->image(3, {0, 0, 0, 0, torch::tensor({0, 7}, torch::kInt64)});
                         }),
                         "bands out of range"));
  }
}

TEST(Dataset, RgbScenes) {
  fs::path root = test::temp_dir("ds_rgb");
  write_scene(root, {});
  LoadOptions options;
  options.rgb = true;
  auto scene = load_scene(root, options);
  EXPECT_EQ(scene->wavelengths_nm, rgb_wavelengths_nm());
  EXPECT_EQ(scene->views[2].data_path, root / "images" / "r_02.png");
  EXPECT_TRUE(torch::allclose(scene->image(2), pattern(2, 6, 8, 3).to(torch::kFloat) / 255));
  EXPECT_FALSE(scene->has_clean());

  // A dataset with only file_path images is an RGB scene by itself.
  TransformsFile file = read_transforms(root / "transforms.json");
  for (auto& f : file.frames) f.hyperspectral_file_path.clear();
  write_transforms(root / "transforms.json", file);
  scene = load_scene(root);
  EXPECT_EQ(scene->bands(), 3);
}

TEST(Dataset, ExplicitSplitLists) {
  fs::path root = test::temp_dir("ds_split");
  write_scene(root, {});
  TransformsFile file = read_transforms(root / "transforms.json");
  file.train_files = {"images/r_00.png", "./images/r_01.png", "images/r_05.png"};
  file.test_files = {"hyperspectral/r_09.npy"};
  write_transforms(root / "transforms.json", file);
  auto scene = load_scene(root);
  EXPECT_EQ(scene->train, (std::vector<int>{0, 1, 5}));
  EXPECT_EQ(scene->test, std::vector<int>{9});
}

TEST(Dataset, CacheEvictsLeastRecentlyUsed) {
  fs::path root = test::temp_dir("ds_cache");
  SceneSpec spec;
  spec.views = 3;
  spec.height = 512;
  spec.width = 512;
  write_scene(root, spec);
  LoadOptions options;
  options.cache_mb = 2;
  // Without the 400 nm band a view is not its file as it is (a .npy that is
  // is never cached: NpyViewsAreReadAtEachUse): 512 x 512 x 3 uint8 per
  // view, so 2 MB hold two views.
  options.band_min_nm = 450;
  auto scene = load_scene(root, options);
  ASSERT_EQ(scene->view_bytes(), size_t(3) << 18);
  scene->image(0);
  scene->image(1);
  scene->image(0);  // 1 is now the least recently used
  scene->image(2);  // evicts 1
  for (int i = 0; i < 3; ++i)
    fs::remove(root / "hyperspectral" / ("r_0" + std::to_string(i) + ".npy"));
  EXPECT_NO_THROW(scene->image(0));
  EXPECT_NO_THROW(scene->image(2));
  EXPECT_THROW(scene->image(1), core::Error);
}

// A .npy view that is the view as it is (its size, every band, no
// undistortion) is read from its file at each use, only the rows a window
// asks for, and never cached; its images equal the file's samples converted.
TEST(Dataset, NpyViewsAreReadAtEachUse) {
  fs::path root = test::temp_dir("ds_direct");
  SceneSpec spec;
  spec.views = 3;
  spec.height = 40;
  spec.width = 30;
  write_scene(root, spec);
  const fs::path file = root / "hyperspectral" / "r_01.npy";
  torch::manual_seed(6);
  const torch::Tensor first = torch::rand({40, 30, 4}).to(torch::kHalf);
  write_npy(file, first);
  auto scene = load_scene(root);
  const torch::Tensor drawn = torch::tensor({1, 3}, torch::kInt64);
  EXPECT_TRUE(scene->image(1).equal(first.to(torch::kFloat)));
  EXPECT_TRUE(
      scene->image(1, {4, 7, 25, 31, drawn})
          .equal(first.slice(0, 7, 31).slice(1, 4, 25).index_select(2, drawn).to(torch::kFloat)));
  EXPECT_TRUE(scene->image(1, {0, 39, 0, 0, {}}).equal(first.slice(0, 39).to(torch::kFloat)));
  // Read again at each use: a changed file is seen, a removed one is an error.
  const torch::Tensor second = torch::rand({40, 30, 4}).to(torch::kHalf);
  write_npy(file, second);
  EXPECT_TRUE(scene->image(1, {0, 10, 0, 20, {}}).equal(second.slice(0, 10, 20).to(torch::kFloat)));
  fs::remove(file);
  EXPECT_THROW(scene->image(1), core::Error);
  // Rows outside the view are the same error as for a cached view.
  EXPECT_TRUE(contains(error_of([&] {
                         scene->image(0, {0, 30, 0, 41, {}});
                       }),
                       "image window lies outside the view"));
  EXPECT_TRUE(contains(error_of([&] {
                         scene->image(0, {0, 5, 0, 5, {}});
                       }),
                       "image window lies outside the view"));
}

// Downscaled views decode through the cache; whole ones are read directly.
class ConcurrentReads : public ::testing::TestWithParam<int> {};

TEST_P(ConcurrentReads, Agree) {
  fs::path root = test::temp_dir("ds_threads_" + std::to_string(GetParam()));
  write_scene(root, {});
  LoadOptions options;
  options.downscale = GetParam();
  auto scene = load_scene(root, options);
  std::vector<torch::Tensor> expected;
  for (int i = 0; i < 10; ++i) expected.push_back(scene->image(i));
  options.cache_mb = 0;  // every read decodes: the path most exposed to races
  auto fresh = load_scene(root, options);
  std::vector<std::thread> threads;
  std::atomic<int> mismatches{0};
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      for (int k = 0; k < 20; ++k) {
        int i = (k * 3 + t) % 10;
        if (!torch::equal(fresh->image(i), expected[size_t(i)])) ++mismatches;
      }
    });
  for (auto& th : threads) th.join();
  EXPECT_EQ(mismatches.load(), 0);
}
INSTANTIATE_TEST_SUITE_P(Dataset, ConcurrentReads, ::testing::Values(1, 2));

TEST(Dataset, CleanGroundTruth) {
  fs::path root = test::temp_dir("ds_clean");
  write_scene(root, {});
  fs::create_directories(root / "clean");
  torch::Tensor clean = torch::rand({6, 8, 4});
  write_npy(root / "clean" / "r_03.npy", clean);
  auto scene = load_scene(root);
  EXPECT_TRUE(scene->has_clean());
  EXPECT_TRUE(scene->views[2].clean_path.empty());
  EXPECT_FALSE(scene->clean_image(2).defined());
  // float clean beside uint8 noisy cubes: scaled by its own type (1), not 255.
  EXPECT_TRUE(torch::allclose(scene->clean_image(3), clean));
}

TEST(Dataset, ColmapLayoutWithCubeFolder) {
  fs::path root = test::temp_dir("ds_colmap");
  ColmapModel model;
  model.cameras[1] = {1, "PINHOLE", 8, 6, {10, 10, 4, 3}};
  fs::create_directories(root / "spectra");
  for (int i = 0; i < 4; ++i) {
    core::Mat4 w2c = w2c_of(i);
    ColmapImage image;
    image.image_id = i + 1;
    image.qvec = core::rotation_to_quat(w2c.rotation());
    image.tvec = w2c.translation();
    image.camera_id = 1;
    image.name = "view" + std::to_string(i) + ".jpg";
    model.images.push_back(image);
    if (i != 2)
      write_npy(root / "spectra" / ("view" + std::to_string(i) + ".npy"), pattern(i, 6, 8, 5));
  }
  model.points.push_back({1, {0.5, -1, 2}, {10, 20, 30}, 0.1, {{1, 0}}});
  model.points.push_back({2, {1, 1, 1}, {40, 50, 60}, 0.1, {{2, 0}}});
  write_colmap_binary(root / "sparse" / "0", model);

  auto scene = load_scene(root);
  EXPECT_EQ(scene->layout, "colmap");
  ASSERT_EQ(scene->views.size(), 3u);
  EXPECT_EQ(scene->views[2].name, "view3");
  EXPECT_TRUE(any_warning(*scene, "view2.jpg"));
  EXPECT_EQ(scene->bands(), 5);
  expect_mat_near(scene->views[2].camera.world_to_camera, w2c_of(3), 1e-9);
  EXPECT_TRUE(torch::allclose(scene->image(2), pattern(3, 6, 8, 5).to(torch::kFloat) / 255));
  ASSERT_TRUE(scene->points.xyz.defined());
  EXPECT_TRUE(torch::equal(scene->points.xyz,
                           torch::tensor({0.5f, -1.f, 2.f, 1.f, 1.f, 1.f}).view({2, 3})));
  EXPECT_EQ(scene->points.rgb[1][2].item<int>(), 60);
  EXPECT_TRUE(any_warning(*scene, "no wavelengths"));
}

TEST(Dataset, PointsFromPlyFilePath) {
  fs::path root = test::temp_dir("ds_ply");
  write_scene(root, {});
  TransformsFile file = read_transforms(root / "transforms.json");
  file.ply_file_path = "points.ply";
  write_transforms(root / "transforms.json", file);
  auto scene = load_scene(root);
  EXPECT_FALSE(scene->points.xyz.defined());
  EXPECT_TRUE(any_warning(*scene, "points.ply does not exist"));

  PointCloud points;
  points.xyz = torch::tensor({0.f, 1.f, 2.f, -1.f, 0.5f, 0.25f}).view({2, 3});
  points.spectra = torch::tensor({0.1f, 0.2f, 0.3f, 0.4f, 0.5f, 0.6f, 0.7f, 0.8f}).view({2, 4});
  write_point_ply(root / "points.ply", points);
  scene = load_scene(root);
  ASSERT_TRUE(scene->points.xyz.defined());
  EXPECT_TRUE(torch::equal(scene->points.xyz, points.xyz));
  ASSERT_TRUE(scene->points.spectra.defined());
  EXPECT_TRUE(torch::equal(scene->points.spectra, points.spectra));
}

TEST(Dataset, NoLayoutIsAnError) {
  fs::path root = test::temp_dir("ds_none");
  std::string what = error_of([&] { load_scene(root); });
  EXPECT_TRUE(contains(what, root.string()) && contains(what, "expected transforms.json")) << what;
  EXPECT_TRUE(contains(error_of([&] { load_scene(root / "nope"); }), "does not exist"));
}

}  // namespace
}  // namespace ddhgs::io

namespace ddhgs::io {
namespace {

// A band-per-view scene: frames name the bands their files hold. Views come
// back with their bands in scene order (a file may list them in any order),
// images narrowed to those bands, and band selection applied per view.
TEST(Dataset, BandPerViewScenes) {
  const fs::path root = test::temp_dir("band_per_view");
  fs::create_directories(root / "bands");
  TransformsFile file;
  file.wavelengths_nm = {400, 500, 600, 700};
  // r_00 holds band 2; r_01 bands 3 and 0 (in that order); r_02 every band; r_03 band 1.
  const std::vector<std::vector<int>> held = {{2}, {3, 0}, {}, {1}};
  for (int i = 0; i < int(held.size()); ++i) {
    TransformsFrame f;
    f.hyperspectral_file_path = "bands/r_0" + std::to_string(i) + ".npy";
    f.intrinsics.fx = f.intrinsics.fy = 10;
    f.intrinsics.cx = 4;
    f.intrinsics.cy = 3;
    f.intrinsics.width = 8;
    f.intrinsics.height = 6;
    f.camera_to_world_gl = core::opencv_w2c_to_opengl_c2w(w2c_of(i));
    f.bands = held[size_t(i)];
    write_npy(root / f.hyperspectral_file_path,
              pattern(i, 6, 8, held[size_t(i)].empty() ? 4 : int64_t(held[size_t(i)].size())));
    file.frames.push_back(f);
  }
  file.train_files = {"bands/r_00.npy", "bands/r_01.npy", "bands/r_02.npy"};
  file.test_files = {"bands/r_03.npy"};
  write_transforms(root / "transforms.json", file);
  EXPECT_EQ(read_transforms(root / "transforms.json").frames[1].bands, (std::vector<int>{3, 0}));

  auto scene = load_scene(root);
  EXPECT_TRUE(scene->band_per_view());
  EXPECT_EQ(scene->bands(), 4);
  EXPECT_EQ(scene->views[0].bands, (std::vector<int>{2}));
  EXPECT_EQ(scene->views[1].bands, (std::vector<int>{0, 3}));
  EXPECT_TRUE(scene->views[2].bands.empty());
  const float scale = 255;
  EXPECT_TRUE(torch::equal(scene->image(0), pattern(0, 6, 8, 1).to(torch::kFloat) / scale));
  // Scene order: the file's second band (band 0) first.
  const torch::Tensor file_1 = pattern(1, 6, 8, 2).to(torch::kFloat) / scale;
  EXPECT_TRUE(torch::equal(scene->image(1), file_1.flip(2)));
  EXPECT_EQ(scene->image(2).size(2), 4);
  // view_slice narrows a render the same way.
  const torch::Tensor render = torch::arange(4, torch::kFloat).view({1, 1, 4}).expand({6, 8, 4});
  EXPECT_TRUE(torch::equal(scene->view_slice(1, render)[0][0], torch::tensor({0.0f, 3.0f})));
  EXPECT_TRUE(torch::equal(scene->view_slice(2, render), render));

  // A band range keeps each view's bands inside it; a view left with none is left out.
  LoadOptions range;
  range.band_min_nm = 550;
  auto upper = load_scene(root, range);
  ASSERT_EQ(upper->bands(), 2);        // 600, 700
  ASSERT_EQ(upper->views.size(), 3u);  // r_03 (500 nm only) is left out
  EXPECT_EQ(upper->views[0].bands, (std::vector<int>{0}));
  EXPECT_EQ(upper->views[1].bands, (std::vector<int>{1}));
  EXPECT_TRUE(torch::equal(upper->image(1), file_1.select(2, 0).unsqueeze(2)));
  EXPECT_TRUE(contains(upper->notes.front(), "1 view(s) hold no band in the selected range"));

  LoadOptions binned;
  binned.bin = 2;
  EXPECT_TRUE(contains(error_of([&] { load_scene(root, binned); }), "cannot be binned"));

  // A file that holds another number of bands than its frame names.
  write_npy(root / "bands" / "r_03.npy", pattern(3, 6, 8, 2));
  auto wrong = load_scene(root);
  const std::string count = error_of([&] { wrong->image(3); });
  EXPECT_TRUE(contains(count, "r_03.npy") && contains(count, "has 2 bands, but its frame names 1"))
      << count;
  write_npy(root / "bands" / "r_03.npy", pattern(3, 6, 8, 1));

  // Bands without a wavelength list, or past it.
  std::string text = read_file(root / "transforms.json");
  text.replace(text.find("\"wavelengths\""), 13, "\"wavelengths_\"");
  write_file_atomically(root / "transforms.json", text);
  const std::string no_list = error_of([&] { load_scene(root); });
  EXPECT_TRUE(contains(no_list, "no top-level \"wavelengths\"")) << no_list;
  file.frames[3].bands = {4};
  write_transforms(root / "transforms.json", file);
  const std::string past = error_of([&] { load_scene(root); });
  EXPECT_TRUE(contains(past, "frames[3].bands") && contains(past, "past the 4 wavelengths"))
      << past;
}

}  // namespace
}  // namespace ddhgs::io
