// Undistortion of views: the remap against a plain double-precision bilinear
// reference for every stored sample type, and scenes whose cameras have lens
// distortion loading as pinhole views.
#include <gtest/gtest.h>

#include <cmath>

#include "core/distortion.h"
#include "io/cube/cube.h"
#include "io/scene/scene.h"
#include "io/transforms/transforms.h"
#include "io/undistort/undistort.h"
#include "support/error_text.h"
#include "support/test_support.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;

core::Intrinsics lens_24x18() {
  core::Intrinsics k;
  k.width = 24;
  k.height = 18;
  k.fx = 20;
  k.fy = 21;
  k.cx = 12.3;
  k.cy = 8.8;
  k.k1 = -0.18;
  k.k2 = 0.03;
  k.p1 = 0.004;
  k.p2 = -0.003;
  return k;
}

// The reference: each output pixel's source position from the lens model in
// double, then the bilinear blend of the four neighbours, all in double.
torch::Tensor reference_remap(const torch::Tensor& values,  // double [H, W, N]
                              const core::Intrinsics& lens, const core::Intrinsics& pinhole) {
  const int64_t h = values.size(0), w = values.size(1), n = values.size(2);
  torch::Tensor out = torch::empty_like(values);
  auto in = values.accessor<double, 3>();
  auto o = out.accessor<double, 3>();
  for (int64_t j = 0; j < h; ++j)
    for (int64_t i = 0; i < w; ++i) {
      core::Point2 d = core::distort(
          lens, {(i + 0.5 - pinhole.cx) / pinhole.fx, (j + 0.5 - pinhole.cy) / pinhole.fy});
      double sx = lens.fx * d.x + lens.cx - 0.5, sy = lens.fy * d.y + lens.cy - 0.5;
      EXPECT_TRUE(sx >= -1e-9 && sx <= w - 1 + 1e-9 && sy >= -1e-9 && sy <= h - 1 + 1e-9);
      sx = std::clamp(sx, 0.0, double(w - 1));
      sy = std::clamp(sy, 0.0, double(h - 1));
      int64_t x0 = std::min<int64_t>(int64_t(sx), w - 2),
              y0 = std::min<int64_t>(int64_t(sy), h - 2);
      double ax = sx - x0, ay = sy - y0;
      for (int64_t b = 0; b < n; ++b)
        o[j][i][b] = (1 - ay) * ((1 - ax) * in[y0][x0][b] + ax * in[y0][x0 + 1][b]) +
                     ay * ((1 - ax) * in[y0 + 1][x0][b] + ax * in[y0 + 1][x0 + 1][b]);
    }
  return out;
}

struct TypeCase {
  SampleType type;
  torch::ScalarType dtype;
  double max;  // sample range [0, max)
};

TEST(Undistort, RemapMatchesTheReferenceForEverySampleType) {
  const core::Intrinsics lens = lens_24x18();
  Undistortion u(lens);
  EXPECT_FALSE(u.pinhole().has_distortion());
  torch::manual_seed(5);
  for (const TypeCase& c :
       {TypeCase{SampleType::U8, torch::kUInt8, 255},
        TypeCase{SampleType::U16, torch::kInt16, 65535},
        TypeCase{SampleType::I16, torch::kInt16, 32767},
        TypeCase{SampleType::I32, torch::kInt32, 2e9}, TypeCase{SampleType::F16, torch::kHalf, 1},
        TypeCase{SampleType::F32, torch::kFloat, 1},
        TypeCase{SampleType::F64, torch::kDouble, 1}}) {
    torch::Tensor values = torch::rand({18, 24, 5}, torch::kDouble) * c.max;  // [H, W, N]
    const bool integral =
        c.dtype != torch::kHalf && c.dtype != torch::kFloat && c.dtype != torch::kDouble;
    if (integral) values = values.floor();
    torch::Tensor stored = values.to(c.dtype);
    if (c.type == SampleType::U16) {  // 16 bits in an int16, as the readers store them
      torch::Tensor v = values.to(torch::kInt32);
      stored = torch::where(v > 32767, v - 65536, v).to(torch::kInt16);
    }
    if (!integral) values = stored.to(torch::kDouble);  // what the stored type can hold
    torch::Tensor got = u.apply(stored, c.type, "test");
    ASSERT_EQ(got.scalar_type(), stored.scalar_type());
    ASSERT_EQ(got.sizes(), stored.sizes());
    torch::Tensor got_values = c.type == SampleType::U16
                                   ? got.to(torch::kInt32).bitwise_and(0xFFFF).to(torch::kDouble)
                                   : got.to(torch::kDouble);
    torch::Tensor expected = reference_remap(values, lens, u.pinhole());
    if (integral) expected = expected.round();
    // Integers: float accumulation may round a .5 the other way; float16 keeps 11 bits.
    double tolerance = c.type == SampleType::F16 ? 1e-3 : integral ? 1.0 : 1e-5 * c.max;
    EXPECT_LE((got_values - expected).abs().max().item<double>(), tolerance) << to_string(c.type);
    if (integral) {  // nearly all samples are exact
      EXPECT_LT((got_values != expected).sum().item<int64_t>(), values.numel() / 100)
          << to_string(c.type);
    }
  }
  std::string what = test::error_of([&] {
    u.apply(torch::zeros({18, 25, 2}, torch::kUInt8), SampleType::U8, "x");
  });
  EXPECT_TRUE(test::contains(what, "expects a 24x18 view")) << what;
}

// A transforms.json scene of float cubes whose camera has lens distortion.
fs::path write_distorted_scene(const std::string& name, const core::Intrinsics& lens, int views) {
  fs::path root = test::temp_dir(name);
  TransformsFile file;
  file.wavelengths_nm = {500, 600};
  for (int i = 0; i < views; ++i) {
    TransformsFrame f;
    f.hyperspectral_file_path = "cubes/v" + std::to_string(i) + ".npy";
    f.intrinsics = lens;
    f.camera_to_world_gl = core::opencv_w2c_to_opengl_c2w(
        core::look_at({3 * std::cos(0.6 * i), 3 * std::sin(0.6 * i), 1}, {0, 0, 0}, {0, 0, 1}));
    torch::manual_seed(i);
    write_npy(root / f.hyperspectral_file_path, torch::rand({lens.height, lens.width, 2}));
    file.frames.push_back(f);
  }
  write_transforms(root / "transforms.json", file);
  return root;
}

TEST(Undistort, ScenesWithLensDistortionLoadAsPinholeViews) {
  const core::Intrinsics lens = lens_24x18();
  fs::path root = write_distorted_scene("undistort_scene", lens, 4);
  auto scene = load_scene(root);
  const Undistortion expected(lens);
  ASSERT_EQ(scene->views.size(), 4u);
  for (const View& v : scene->views) {
    EXPECT_FALSE(v.camera.intrinsics.has_distortion());
    EXPECT_TRUE(v.camera.intrinsics == expected.pinhole());
    ASSERT_TRUE(v.undistortion);
    EXPECT_EQ(v.undistortion.get(), scene->views.front().undistortion.get()) << "one per camera";
  }
  ASSERT_EQ(scene->notes.size(), 1u);
  EXPECT_TRUE(test::contains(scene->notes[0], "undistorting 4 views")) << scene->notes[0];
  Cube raw = read_cube(root / "cubes" / "v2.npy");
  EXPECT_TRUE(torch::equal(scene->image(2), expected.apply(raw.data, raw.type, "v2")));

  // At --downscale 2 the lens is undistorted at the reduced size.
  LoadOptions options;
  options.downscale = 2;
  scene = load_scene(root, options);
  const Undistortion half(lens.downscaled(2));
  EXPECT_TRUE(scene->views[1].camera.intrinsics == half.pinhole());
  EXPECT_EQ(scene->image(1).sizes(), (std::vector<int64_t>{9, 12, 2}));
}

TEST(Undistort, AFoldingLensIsOneErrorNamingTheDataset) {
  core::Intrinsics lens = lens_24x18();
  lens.k1 = -500;
  fs::path root = write_distorted_scene("undistort_folding", lens, 2);
  std::string what = test::error_of([&] { load_scene(root); });
  EXPECT_TRUE(test::contains(what, "transforms.json") && test::contains(what, "folds")) << what;
}

}  // namespace
}  // namespace ddhgs::io
