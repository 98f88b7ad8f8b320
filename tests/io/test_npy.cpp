// .npy reader and writer: round trips, files written by NumPy, malformed files.
#include <gtest/gtest.h>

#include <fstream>
#include <limits>

#include "core/error.h"
#include "cube_test_util.h"
#include "io/cube/cube.h"
#include "support/test_support.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;
using test::expect_error_naming;

TEST(Npy, RoundTripKeepsTypeAndValues) {
  fs::path dir = test::temp_dir("npy_round_trip");
  torch::manual_seed(1);
  torch::Tensor f32 = torch::rand({4, 5, 3});
  torch::Tensor u8 = torch::randint(0, 256, {4, 5, 3}).to(torch::kUInt8);
  torch::Tensor f16 = torch::rand({4, 5, 3}).to(torch::kHalf);
  torch::Tensor u16 = torch::randint(0, 65536, {4, 5, 3}).to(torch::kInt32).to(torch::kInt16);
  for (auto [name, data, type] :
       {std::tuple{"f32", f32, SampleType::F32}, std::tuple{"u8", u8, SampleType::U8},
        std::tuple{"f16", f16, SampleType::F16}, std::tuple{"u16", u16, SampleType::U16}}) {
    fs::path path = dir / (std::string(name) + ".npy");
    write_npy(path, data, type);
    Cube cube = read_cube(path, {BandLayout::BandsLast});
    EXPECT_EQ(cube.type, type) << name;
    EXPECT_TRUE(torch::equal(cube.data, data)) << name;
    CubeInfo info = probe_cube(path, {BandLayout::BandsLast});
    EXPECT_EQ(info.height, 4);
    EXPECT_EQ(info.width, 5);
    EXPECT_EQ(info.bands, 3);
    EXPECT_EQ(info.type, type);
  }
}

TEST(Npy, HeaderIsSixtyFourByteAligned) {
  fs::path path = test::temp_dir("npy_align") / "a.npy";
  write_npy(path, torch::zeros({2, 3, 4}));
  std::string bytes = test::read_bytes(path);
  size_t header_len = uint8_t(bytes[8]) | size_t(uint8_t(bytes[9])) << 8;
  EXPECT_EQ((10 + header_len) % 64, 0u);
  EXPECT_EQ(bytes.size(), 10 + header_len + 2 * 3 * 4 * 4);
  EXPECT_EQ(bytes[10 + header_len - 1], '\n');
}

// NumPy reads what we write, and we read what NumPy writes (every dtype, a
// big-endian array, a Fortran-order array and format version 2.0).
TEST(Npy, MatchesNumpy) {
  if (!test::python_has("numpy")) GTEST_SKIP() << "python3 without numpy";
  fs::path dir = test::temp_dir("npy_numpy");
  torch::Tensor ours = torch::arange(24, torch::kFloat).view({2, 3, 4}) / 8;
  write_npy(dir / "ours.npy", ours);
  std::string out;
  ASSERT_EQ(test::run_command(test::python() + " -c \"import numpy as np; a = np.load('" +
                                  (dir / "ours.npy").string() +
                                  "'); print(a.shape, a.dtype, a[1, 2, 3])\"",
                              &out),
            0)
      << out;
  EXPECT_EQ(out, "(2, 3, 4) float32 2.875\n");

  std::string script =
      "import numpy as np\n"
      "d = '" +
      dir.string() +
      "/'\n"
      "a = np.arange(24).reshape(2, 3, 4)\n"
      "for t in ['u1', 'u2', 'i2', 'i4', 'f2', 'f4', 'f8']:\n"
      "    np.save(d + t + '.npy', a.astype(t))\n"
      "np.save(d + 'big.npy', a.astype('>u2') * 1000)\n"
      "np.save(d + 'fortran.npy', np.asfortranarray(a.astype('f4')))\n"
      "np.lib.format.write_array(open(d + 'v2.npy', 'wb'), a.astype('f4'), version=(2, 0))\n"
      "np.save(d + 'flat.npy', a[0].astype('u1'))\n";
  test::write_bytes(dir / "make.py", script);
  ASSERT_EQ(test::run_command(test::python() + " " + (dir / "make.py").string(), &out), 0) << out;

  torch::Tensor expected = torch::arange(24, torch::kLong).view({2, 3, 4});
  std::vector<std::pair<std::string, SampleType>> files = {
      {"u1", SampleType::U8},  {"u2", SampleType::U16},      {"i2", SampleType::I16},
      {"i4", SampleType::I32}, {"f2", SampleType::F16},      {"f4", SampleType::F32},
      {"f8", SampleType::F64}, {"fortran", SampleType::F32}, {"v2", SampleType::F32}};
  for (const auto& [name, type] : files) {
    Cube cube = read_cube(dir / (name + ".npy"), {BandLayout::BandsLast});
    EXPECT_EQ(cube.type, type) << name;
    EXPECT_TRUE(torch::equal(cube.data.to(torch::kLong), expected)) << name;
  }
  Cube big = read_cube(dir / "big.npy", {BandLayout::BandsLast});
  EXPECT_EQ(big.type, SampleType::U16);
  EXPECT_TRUE(torch::equal(big.data.to(torch::kInt32).bitwise_and(0xFFFF), expected * 1000));
  Cube flat = read_cube(dir / "flat.npy");
  EXPECT_EQ(flat.data.sizes(), (std::vector<int64_t>{3, 4, 1}));
  EXPECT_EQ(flat.data[2][3][0].item<int>(), 11);

  // A row range of any of NumPy's files equals the rows of the whole read:
  // the offset and byte order of each version, and Fortran order's fallback.
  for (const std::string name :
       {"u1", "u2", "i2", "i4", "f2", "f4", "f8", "big", "fortran", "v2"}) {
    const fs::path path = dir / (name + ".npy");
    const Cube whole = read_cube(path, {BandLayout::BandsLast});
    const Cube row = read_cube_rows(path, 1, 2, {BandLayout::BandsLast});
    EXPECT_EQ(row.type, whole.type) << name;
    EXPECT_TRUE(torch::equal(row.data, whole.data.slice(0, 1, 2))) << name;
  }
  const Cube flat_rows = read_cube_rows(dir / "flat.npy", 1, 3);
  EXPECT_TRUE(torch::equal(flat_rows.data, flat.data.slice(0, 1, 3)));
}

// read_cube_rows reads only the rows of a C-order, bands-last array and
// falls back to a whole read for any other layout; either way its samples
// are the whole read's rows, bit for bit, and bad ranges name the file.
TEST(Npy, RowRangesEqualTheWholeReadsRows) {
  fs::path dir = test::temp_dir("npy_rows");
  torch::manual_seed(3);
  const torch::Tensor u16 = torch::randint(0, 65536, {9, 7, 5}).to(torch::kInt32).to(torch::kInt16);
  write_npy(dir / "u16.npy", u16, SampleType::U16);
  write_npy(dir / "f16.npy", torch::rand({9, 7, 5}).to(torch::kHalf));
  write_npy(dir / "f32.npy", torch::rand({9, 7, 5}));
  write_npy(dir / "bhw.npy", torch::rand({3, 9, 11}));  // bands first: read whole
  for (const std::string name : {"u16", "f16", "f32", "bhw"}) {
    const fs::path path = dir / (name + ".npy");
    const Cube whole = read_cube(path);
    for (auto [y0, y1] : {std::pair{0, 9}, std::pair{0, 1}, std::pair{4, 9}, std::pair{3, 6}}) {
      const Cube rows = read_cube_rows(path, y0, y1);
      EXPECT_EQ(rows.type, whole.type) << name;
      EXPECT_TRUE(rows.data.is_contiguous()) << name;
      EXPECT_TRUE(torch::equal(rows.data, whole.data.slice(0, y0, y1))) << name << " " << y0;
    }
    for (auto [y0, y1] : {std::pair{-1, 2}, std::pair{3, 3}, std::pair{5, 10}})
      expect_error_naming([&, y0 = y0, y1 = y1] { read_cube_rows(path, y0, y1); }, name + ".npy",
                          "lie outside the cube's 9 rows");
  }
  // Other formats: a whole read, sliced.
  const torch::Tensor envi = torch::rand({6, 4, 3});
  write_envi(dir / "c.hdr", envi, {500, 600, 700});
  EXPECT_TRUE(torch::equal(read_cube_rows(dir / "c.hdr", 2, 5).data, envi.slice(0, 2, 5)));
  // A non-finite sample in the rows read is an error as in a whole read.
  torch::Tensor bad = torch::rand({9, 7, 5});
  bad[6][2][1] = std::numeric_limits<float>::quiet_NaN();
  write_npy(dir / "nan.npy", bad);
  expect_error_naming([&] { read_cube_rows(dir / "nan.npy", 5, 8); }, "nan.npy", "NaN");
}

TEST(Npy, BandsFirstByFlagAndByDetection) {
  fs::path dir = test::temp_dir("npy_layout");
  // [B=3, H=8, W=10]: the first axis is clearly the band axis.
  torch::Tensor bhw = torch::arange(240, torch::kFloat).view({3, 8, 10});
  write_npy(dir / "bhw.npy", bhw);
  for (BandLayout layout : {BandLayout::Auto, BandLayout::BandsFirst}) {
    Cube cube = read_cube(dir / "bhw.npy", {layout});
    ASSERT_EQ(cube.data.sizes(), (std::vector<int64_t>{8, 10, 3}));
    EXPECT_EQ(cube.data[2][7][1].item<float>(), bhw[1][2][7].item<float>());
    CubeInfo info = probe_cube(dir / "bhw.npy", {layout});
    EXPECT_EQ(info.height, 8);
    EXPECT_EQ(info.width, 10);
    EXPECT_EQ(info.bands, 3);
  }
  EXPECT_EQ(read_cube(dir / "bhw.npy", {BandLayout::BandsLast}).data.sizes(),
            (std::vector<int64_t>{3, 8, 10}));
  // [H=8, W=10, B=3] stays bands-last under Auto.
  write_npy(dir / "hwb.npy", torch::zeros({8, 10, 3}));
  EXPECT_EQ(read_cube(dir / "hwb.npy").data.sizes(), (std::vector<int64_t>{8, 10, 3}));
  // A cube with as many bands as rows is ambiguous: Auto keeps bands last.
  write_npy(dir / "square.npy", torch::zeros({6, 6, 6}));
  EXPECT_EQ(probe_cube(dir / "square.npy").bands, 6);
}

TEST(Npy, MalformedFilesNameTheFile) {
  fs::path dir = test::temp_dir("npy_bad");
  expect_error_naming([&] { read_cube(dir / "missing.npy"); }, "missing.npy", "not found");
  test::write_bytes(dir / "empty.npy", "");
  expect_error_naming([&] { read_cube(dir / "empty.npy"); }, "empty.npy", "empty");
  test::write_bytes(dir / "magic.npy", "PK\x03\x04 this is a zip, not an array");
  expect_error_naming([&] { read_cube(dir / "magic.npy"); }, "magic.npy", "magic");
  expect_error_naming([&] { probe_cube(dir / "magic.npy"); }, "magic.npy", "magic");

  write_npy(dir / "good.npy", torch::ones({4, 4, 2}));
  std::string good = test::read_bytes(dir / "good.npy");
  test::write_bytes(dir / "truncated.npy", good.substr(0, good.size() - 5));
  expect_error_naming([&] { read_cube(dir / "truncated.npy"); }, "truncated.npy", "truncated");
  expect_error_naming([&] { probe_cube(dir / "truncated.npy"); }, "truncated.npy", "truncated");
  test::write_bytes(dir / "short_header.npy", good.substr(0, 30));
  expect_error_naming([&] { read_cube(dir / "short_header.npy"); }, "short_header.npy",
                      "truncated");

  std::string complex = good;
  complex.replace(complex.find("<f4"), 3, "<c8");
  test::write_bytes(dir / "complex.npy", complex);
  expect_error_naming([&] { read_cube(dir / "complex.npy"); }, "complex.npy", "dtype");

  std::string four_d = good;
  four_d.replace(four_d.find("(4, 4, 2)"), 9, "(1,4,4,2)");
  test::write_bytes(dir / "four_d.npy", four_d);
  expect_error_naming([&] { read_cube(dir / "four_d.npy"); }, "four_d.npy", "dimensions");

  std::string version = good;
  version[6] = 9;
  test::write_bytes(dir / "version.npy", version);
  expect_error_naming([&] { read_cube(dir / "version.npy"); }, "version.npy", "version");
}

TEST(Npy, NonFiniteValuesAreRejected) {
  fs::path dir = test::temp_dir("npy_nan");
  torch::Tensor data = torch::rand({3, 3, 2});
  data[1][1][1] = std::numeric_limits<float>::quiet_NaN();
  write_npy(dir / "nan.npy", data);
  expect_error_naming([&] { read_cube(dir / "nan.npy"); }, "nan.npy", "NaN or Inf");
  data[1][1][1] = std::numeric_limits<float>::infinity();
  write_npy(dir / "inf.npy", data.to(torch::kHalf));
  expect_error_naming([&] { read_cube(dir / "inf.npy"); }, "inf.npy", "NaN or Inf");
}

}  // namespace
}  // namespace ddhgs::io
