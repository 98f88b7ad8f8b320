// Sample types, band-axis detection and conversion of stored cubes to float.
#include <gtest/gtest.h>

#include "cube_test_util.h"
#include "io/cube/cube.h"
#include "io/cube/cube_formats.h"

namespace ddhgs::io {
namespace {

Cube make_cube(torch::Tensor data, SampleType type) {
  Cube cube;
  cube.data = std::move(data);
  cube.type = type;
  return cube;
}

TEST(Cube, SampleTypeFacts) {
  EXPECT_EQ(to_string(SampleType::U16), "uint16");
  EXPECT_EQ(bytes_per_sample(SampleType::U8), 1u);
  EXPECT_EQ(bytes_per_sample(SampleType::F16), 2u);
  EXPECT_EQ(bytes_per_sample(SampleType::F64), 8u);
  EXPECT_EQ(default_scale(SampleType::U8), 255.0);
  EXPECT_EQ(default_scale(SampleType::U16), 65535.0);
  EXPECT_EQ(default_scale(SampleType::F32), 1.0);
  Cube cube = make_cube(torch::zeros({4, 5, 6}, torch::kInt16), SampleType::U16);
  EXPECT_EQ(cube.bytes(), 4u * 5 * 6 * 2);
}

TEST(Cube, AutoLayoutPicksTheBandAxisOnlyWhenClear) {
  using detail::bands_first;
  EXPECT_TRUE(bands_first(141, 512, 640, BandLayout::Auto));   // BaySpec saved B x H x W
  EXPECT_FALSE(bands_first(512, 640, 141, BandLayout::Auto));  // H x W x B
  EXPECT_FALSE(bands_first(520, 696, 128, BandLayout::Auto));
  EXPECT_FALSE(bands_first(3, 4, 5, BandLayout::Auto));   // no clearly small axis
  EXPECT_FALSE(bands_first(3, 64, 3, BandLayout::Auto));  // both ends small: H x W x B
  EXPECT_TRUE(bands_first(3, 4, 5, BandLayout::BandsFirst));
  EXPECT_FALSE(bands_first(141, 512, 640, BandLayout::BandsLast));
}

// The blocked transpose against LibTorch's strided copy, on shapes that are
// not multiples of its 32-element blocks, for every sample width.
TEST(Cube, BlockedTransposeMatchesLibTorch) {
  torch::manual_seed(11);
  for (auto dtype : {torch::kUInt8, torch::kInt16, torch::kFloat, torch::kDouble})
    for (std::vector<int64_t> shape :
         {std::vector<int64_t>{1, 141, 70}, {3, 33, 65}, {2, 1, 5}, {1, 64, 32}}) {
      torch::Tensor in = torch::randint(0, 120, shape).to(dtype);
      torch::Tensor fast = detail::transpose_last_two(in);
      EXPECT_TRUE(fast.is_contiguous());
      EXPECT_TRUE(torch::equal(fast, in.transpose(1, 2))) << dtype << " " << shape[1];
    }
}

TEST(Cube, IntegerCubesScaleByTheirTypeMaximum) {
  torch::Tensor u8 = torch::tensor({0, 51, 255}, torch::kUInt8).view({1, 3, 1});
  torch::Tensor f = cube_to_float(make_cube(u8, SampleType::U8));
  EXPECT_EQ(f.scalar_type(), torch::kFloat);
  EXPECT_TRUE(torch::allclose(f.flatten(), torch::tensor({0.0f, 0.2f, 1.0f})));
  // uint16 bits in int16: 65535 is stored as -1 and must come back as 1.0.
  torch::Tensor u16 =
      torch::tensor({0, 32768, 65535}, torch::kInt32).to(torch::kInt16).view({1, 3, 1});
  f = cube_to_float(make_cube(u16, SampleType::U16));
  EXPECT_TRUE(torch::allclose(f.flatten(), torch::tensor({0.0f, 32768.0f / 65535.0f, 1.0f})));
  // A dataset's own scale (12-bit sensor in uint16) overrides the type maximum.
  f = cube_to_float(make_cube(u16, SampleType::U16), 4095.0);
  EXPECT_FLOAT_EQ(f[0][1][0].item<float>(), 32768.0f / 4095.0f);
}

// The one-pass conversion of the common types (no ignore value) against the
// general LibTorch path it replaces: the same float bits, large enough for
// the pooled buffer, and the stored cube untouched.
TEST(Cube, FastConversionHasTheBitsOfTheGeneralPath) {
  torch::manual_seed(5);
  const std::vector<int64_t> shape = {71, 33, 141};  // 1.3 MB as float: pooled
  struct Kind {
    SampleType type;
    torch::Tensor data;
  };
  const std::vector<Kind> kinds = {
      {SampleType::U8, torch::randint(0, 256, shape).to(torch::kUInt8)},
      {SampleType::U16, torch::randint(0, 65536, shape).to(torch::kInt32).to(torch::kInt16)},
      {SampleType::I16, torch::randint(-32768, 32768, shape).to(torch::kInt16)},
      {SampleType::F32, torch::rand(shape) * 3}};
  for (const Kind& k : kinds)
    for (double scale : {0.0, 4095.0, 1.0, 0.7}) {
      const torch::Tensor before = k.data.clone();
      const torch::Tensor fast = cube_to_float(make_cube(k.data, k.type), scale);
      // The general path: widen (uint16 through int32), then divide by the scalar.
      torch::Tensor values = k.type == SampleType::U16
                                 ? k.data.to(torch::kInt32).bitwise_and(0xFFFF).to(torch::kFloat)
                                 : k.data.to(torch::kFloat);
      const torch::Tensor general = values / (scale <= 0 ? default_scale(k.type) : scale);
      EXPECT_EQ(fast.scalar_type(), torch::kFloat);
      EXPECT_TRUE(fast.is_contiguous());
      EXPECT_TRUE(torch::equal(fast, general)) << to_string(k.type) << " scale " << scale;
      EXPECT_TRUE(torch::equal(k.data, before));
    }
}

TEST(Cube, FloatCubesAreCopiedNotModified) {
  torch::Tensor data = torch::tensor({0.5f, -1.0f, 0.25f}).view({1, 3, 1});
  Cube cube = make_cube(data, SampleType::F32);
  cube.ignore_value = -1.0;
  torch::Tensor f = cube_to_float(cube);
  EXPECT_TRUE(torch::equal(f.flatten(), torch::tensor({0.5f, 0.0f, 0.25f})));
  EXPECT_EQ(data[0][1][0].item<float>(), -1.0f);  // the stored cube is untouched
  f = cube_to_float(cube, 0.5);
  EXPECT_EQ(f[0][0][0].item<float>(), 1.0f);
  EXPECT_EQ(data[0][0][0].item<float>(), 0.5f);
}

TEST(Cube, WideTypesCompareIgnoreValueExactly) {
  // 16777217 is not a float32: the comparison must happen before narrowing.
  torch::Tensor i32 = torch::tensor({16777217, 16777216}, torch::kInt32).view({1, 2, 1});
  Cube cube = make_cube(i32, SampleType::I32);
  cube.ignore_value = 16777217.0;
  torch::Tensor f = cube_to_float(cube, 1.0);
  EXPECT_EQ(f[0][0][0].item<float>(), 0.0f);
  EXPECT_EQ(f[0][1][0].item<float>(), 16777216.0f);
}

TEST(Cube, UnknownFormatsNameTheFile) {
  auto dir = test::temp_dir("cube_unknown");
  test::write_bytes(dir / "cube.xyz", "data");
  test::expect_error_naming([&] { read_cube(dir / "cube.xyz"); }, "cube.xyz",
                            "unknown cube format");
  test::expect_error_naming([&] { probe_cube(dir / "cube.xyz"); }, "cube.xyz",
                            "unknown cube format");
  test::expect_error_naming([&] { probe_cube(dir / "gone.npy"); }, "gone.npy", "not found");
}

}  // namespace
}  // namespace ddhgs::io
