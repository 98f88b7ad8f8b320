// ENVI cubes: hand-made files written byte by byte, round trips, bad headers.
#include <gtest/gtest.h>

#include "cube_test_util.h"
#include "io/cube/cube.h"
#include "io/scene/scene.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;
using test::expect_error_naming;

// Appends value as `bytes` bytes, most significant first when big_endian.
void put(std::string* out, uint64_t value, int bytes, bool big_endian) {
  for (int i = 0; i < bytes; ++i) {
    int shift = 8 * (big_endian ? bytes - 1 - i : i);
    out->push_back(char((value >> shift) & 0xff));
  }
}

// The sample at (line, sample, band) of the hand-made cubes below.
int64_t known_value(int64_t line, int64_t sample, int64_t band) {
  return 100 * band + 10 * line + sample;
}

// Data bytes for lines x samples x bands in the given interleave.
std::string make_data(const std::string& interleave, int64_t lines, int64_t samples, int64_t bands,
                      int bytes, bool big_endian, int64_t offset_add = 0) {
  std::string out;
  auto emit = [&](int64_t l, int64_t s, int64_t b) {
    put(&out, uint64_t(known_value(l, s, b) + offset_add), bytes, big_endian);
  };
  if (interleave == "bsq") {
    for (int64_t b = 0; b < bands; ++b)
      for (int64_t l = 0; l < lines; ++l)
        for (int64_t s = 0; s < samples; ++s) emit(l, s, b);
  } else if (interleave == "bil") {
    for (int64_t l = 0; l < lines; ++l)
      for (int64_t b = 0; b < bands; ++b)
        for (int64_t s = 0; s < samples; ++s) emit(l, s, b);
  } else {
    for (int64_t l = 0; l < lines; ++l)
      for (int64_t s = 0; s < samples; ++s)
        for (int64_t b = 0; b < bands; ++b) emit(l, s, b);
  }
  return out;
}

void expect_known_cube(const Cube& cube, int64_t lines, int64_t samples, int64_t bands,
                       int64_t offset_add = 0) {
  ASSERT_EQ(cube.data.sizes(), (std::vector<int64_t>{lines, samples, bands}));
  torch::Tensor values = cube.data.to(torch::kInt64);
  if (cube.type == SampleType::U16) values = values.bitwise_and(0xFFFF);
  for (int64_t l = 0; l < lines; ++l)
    for (int64_t s = 0; s < samples; ++s)
      for (int64_t b = 0; b < bands; ++b)
        ASSERT_EQ(values[l][s][b].item<int64_t>(), known_value(l, s, b) + offset_add)
            << l << " " << s << " " << b;
}

TEST(Envi, HandMadeBsqUint8WithOffsetListsAndUnits) {
  fs::path dir = test::temp_dir("envi_bsq_u8");
  test::write_bytes(dir / "scene.hdr",
                    "ENVI\r\n"
                    "description = {hand made,\r\n  two lines}\r\n"
                    "samples = 3\r\nlines = 2\r\nbands = 2\r\n"
                    "header offset = 5\r\nfile type = ENVI Standard\r\n"
                    "data type = 1\r\nInterleave = BSQ\r\nbyte order = 0\r\n"
                    "wavelength units = Micrometers\r\n"
                    "wavelength = {\r\n 0.45,\r\n 0.7 }\r\n"
                    "data ignore value = 0\r\n");
  test::write_bytes(dir / "scene", "junk!" + make_data("bsq", 2, 3, 2, 1, false));
  for (const char* name : {"scene.hdr", "scene"}) {
    Cube cube = read_cube(dir / name);
    EXPECT_EQ(cube.type, SampleType::U8);
    expect_known_cube(cube, 2, 3, 2);
    ASSERT_EQ(cube.wavelengths_nm.size(), 2u);
    EXPECT_DOUBLE_EQ(cube.wavelengths_nm[0], 450.0);
    EXPECT_DOUBLE_EQ(cube.wavelengths_nm[1], 700.0);
    ASSERT_TRUE(cube.ignore_value.has_value());
    EXPECT_EQ(*cube.ignore_value, 0.0);
  }
  CubeInfo info = probe_cube(dir / "scene.hdr");
  EXPECT_EQ(info.height, 2);
  EXPECT_EQ(info.width, 3);
  EXPECT_EQ(info.bands, 2);
  EXPECT_EQ(info.wavelengths_nm.size(), 2u);
}

TEST(Envi, HandMadeBigEndianInt16BilAndUint16Bip) {
  fs::path dir = test::temp_dir("envi_big_endian");
  // int16 BIL, values shifted negative, big-endian; data in a .raw file.
  test::write_bytes(dir / "i16.hdr",
                    "ENVI\nsamples = 4\nlines = 3\nbands = 5\ndata type = 2\n"
                    "interleave = bil\nbyte order = 1\nwavelength = {400, 450, 500, 550, 600}\n");
  test::write_bytes(dir / "i16.raw", make_data("bil", 3, 4, 5, 2, true, -1000));
  Cube i16 = read_cube(dir / "i16.raw");
  EXPECT_EQ(i16.type, SampleType::I16);
  expect_known_cube(i16, 3, 4, 5, -1000);
  EXPECT_DOUBLE_EQ(i16.wavelengths_nm[4], 600.0);  // no units, values in nm

  // uint16 BIP above the int16 range, big-endian, data in .img with a
  // GDAL-style header name (data file name + .hdr).
  test::write_bytes(dir / "u16.img.hdr",
                    "ENVI\nsamples = 2\nlines = 2\nbands = 3\ndata type = 12\n"
                    "interleave = bip\nbyte order = 1\n");
  test::write_bytes(dir / "u16.img", make_data("bip", 2, 2, 3, 2, true, 60000));
  Cube u16 = read_cube(dir / "u16.img");
  EXPECT_EQ(u16.type, SampleType::U16);
  expect_known_cube(u16, 2, 2, 3, 60000);
  EXPECT_TRUE(u16.wavelengths_nm.empty());
  EXPECT_FLOAT_EQ(cube_to_float(u16)[1][1][2].item<float>(), float(60211.0 / 65535.0));
}

TEST(Envi, HandMadeFloatsBothByteOrders) {
  fs::path dir = test::temp_dir("envi_floats");
  for (int order : {0, 1}) {
    std::string stem = "f32_" + std::to_string(order);
    test::write_bytes(dir / (stem + ".hdr"),
                      "ENVI\nsamples = 3\nlines = 2\nbands = 2\ndata type = 4\n"
                      "interleave = bsq\nbyte order = " +
                          std::to_string(order) + "\n");
    std::string data;
    for (int64_t b = 0; b < 2; ++b)
      for (int64_t l = 0; l < 2; ++l)
        for (int64_t s = 0; s < 3; ++s) {
          float v = float(known_value(l, s, b)) / 4;
          uint32_t bits;
          std::memcpy(&bits, &v, 4);
          put(&data, bits, 4, order == 1);
        }
    test::write_bytes(dir / (stem + ".dat"), data);
    Cube cube = read_cube(dir / (stem + ".hdr"));
    EXPECT_EQ(cube.type, SampleType::F32);
    EXPECT_FLOAT_EQ(cube.data[1][2][1].item<float>(), 112.0f / 4);
    EXPECT_FLOAT_EQ(cube.data[0][1][0].item<float>(), 1.0f / 4);
  }
}

TEST(Envi, RoundTripEveryInterleave) {
  fs::path dir = test::temp_dir("envi_round_trip");
  torch::manual_seed(5);
  std::vector<double> wavelengths = {401.5, 455.25, 510.125, 987.0};
  torch::Tensor f32 = torch::rand({5, 7, 4});
  torch::Tensor u8 = torch::randint(0, 256, {5, 7, 4}).to(torch::kUInt8);
  torch::Tensor u16 = torch::randint(0, 65536, {5, 7, 4}).to(torch::kInt32).to(torch::kInt16);
  for (EnviInterleave interleave : {EnviInterleave::BSQ, EnviInterleave::BIL, EnviInterleave::BIP})
    for (auto [data, type] : {std::pair{f32, SampleType::F32}, std::pair{u8, SampleType::U8},
                              std::pair{u16, SampleType::U16}}) {
      std::string name = "c" + std::to_string(int(interleave)) + to_string(type);
      write_envi(dir / (name + ".hdr"), data, wavelengths, interleave, type);
      ASSERT_TRUE(fs::exists(dir / (name + ".img")));
      Cube cube = read_cube(dir / (name + ".img"));
      EXPECT_EQ(cube.type, type) << name;
      EXPECT_TRUE(torch::equal(cube.data, data)) << name;
      EXPECT_EQ(cube.wavelengths_nm, wavelengths) << name;
    }
  // A 2-D image is a one-band cube; float16 is stored as float32.
  write_envi(dir / "half.hdr", torch::full({3, 3}, 0.25, torch::kHalf), {});
  Cube half = read_cube(dir / "half.hdr");
  EXPECT_EQ(half.type, SampleType::F32);
  EXPECT_EQ(half.data.sizes(), (std::vector<int64_t>{3, 3, 1}));
  EXPECT_EQ(half.data.sum().item<float>(), 9 * 0.25f);
}

TEST(Envi, WrittenDataMatchesNumpyLayout) {
  if (!test::python_has("numpy")) GTEST_SKIP() << "python3 without numpy";
  fs::path dir = test::temp_dir("envi_numpy");
  torch::Tensor data = torch::arange(2 * 3 * 4, torch::kFloat).view({2, 3, 4});  // [H, W, B]
  write_envi(dir / "bil.hdr", data, {}, EnviInterleave::BIL);
  std::string out;
  // BIL on disk is [lines, bands, samples]: element (line 1, band 3, sample 2).
  ASSERT_EQ(test::run_command(test::python() + " -c \"import numpy as np; a = np.fromfile('" +
                                  (dir / "bil.img").string() +
                                  "', '<f4').reshape(2, 4, 3); print(a[1, 3, 2])\"",
                              &out),
            0)
      << out;
  EXPECT_EQ(out, std::to_string(data[1][2][3].item<float>()).substr(0, 4) + "\n");
}

TEST(Envi, IgnoreValueBecomesZeroInFloat) {
  fs::path dir = test::temp_dir("envi_ignore");
  test::write_bytes(dir / "x.hdr",
                    "ENVI\nsamples = 2\nlines = 1\nbands = 1\ndata type = 2\n"
                    "interleave = bsq\ndata ignore value = -9999\n");
  std::string data;
  put(&data, uint16_t(int16_t(-9999)), 2, false);
  put(&data, 16383, 2, false);
  test::write_bytes(dir / "x.bsq", data);
  Cube cube = read_cube(dir / "x.hdr");
  torch::Tensor f = cube_to_float(cube);
  EXPECT_EQ(f[0][0][0].item<float>(), 0.0f);
  EXPECT_FLOAT_EQ(f[0][1][0].item<float>(), 16383.0f / 32767.0f);
  EXPECT_FLOAT_EQ(cube_to_float(cube, 16383)[0][1][0].item<float>(), 1.0f);
}

// A uint16 reflectance product scaled by 10,000, as processing chains write it.
void write_scaled_cube(const fs::path& hdr, const std::string& factor_line) {
  test::write_bytes(hdr,
                    "ENVI\nsamples = 2\nlines = 1\nbands = 1\ndata type = 12\n"
                    "interleave = bsq\n" +
                        factor_line);
  std::string data;
  put(&data, 6500, 2, false);
  put(&data, 10000, 2, false);
  test::write_bytes(fs::path(hdr).replace_extension(".img"), data);
}

TEST(Envi, ReflectanceScaleFactorDividesTheSamples) {
  fs::path dir = test::temp_dir("envi_scale");
  write_scaled_cube(dir / "r.hdr", "reflectance scale factor = 10000\n");
  Cube cube = read_cube(dir / "r.hdr");
  ASSERT_TRUE(cube.scale_factor.has_value());
  EXPECT_EQ(*cube.scale_factor, 10000);
  EXPECT_EQ(probe_cube(dir / "r.hdr").scale_factor, std::optional<double>(10000));
  torch::Tensor f = cube_to_float(cube);
  EXPECT_FLOAT_EQ(f[0][0][0].item<float>(), 0.65f);  // not 6500 / 65535 = 0.099
  EXPECT_FLOAT_EQ(f[0][1][0].item<float>(), 1.0f);
  EXPECT_FLOAT_EQ(cube_to_float(cube, 20000)[0][0][0].item<float>(), 0.325f);  // given scale wins

  write_scaled_cube(dir / "plain.hdr", "");
  EXPECT_FALSE(read_cube(dir / "plain.hdr").scale_factor.has_value());
  EXPECT_FLOAT_EQ(cube_to_float(read_cube(dir / "plain.hdr"))[0][0][0].item<float>(),
                  6500.0f / 65535.0f);

  for (const char* bad : {"reflectance scale factor = 0\n", "reflectance scale factor = abc\n"}) {
    write_scaled_cube(dir / "bad.hdr", bad);
    expect_error_naming([&] { read_cube(dir / "bad.hdr"); }, (dir / "bad.hdr").string(),
                        "reflectance scale factor");
  }
}

// The scene's divisor: --scale, then the dataset's scale, then the header's
// reflectance scale factor, then the sample type's maximum.
TEST(Envi, SceneScaleOrder) {
  fs::path dir = test::temp_dir("envi_scene_scale");
  fs::create_directories(dir / "cubes");
  for (int i = 0; i < 3; ++i)
    write_scaled_cube(dir / "cubes" / ("v" + std::to_string(i) + ".hdr"),
                      "reflectance scale factor = 10000\n");
  auto transforms = [&](const std::string& extra) {
    std::string frames;
    for (int i = 0; i < 3; ++i)
      frames += std::string(i ? "," : "") + R"({"hyperspectral_file_path": "cubes/v)" +
                std::to_string(i) + R"(.hdr", "transform_matrix": [[1,0,0,)" + std::to_string(i) +
                "],[0,1,0,0],[0,0,1,3],[0,0,0,1]]}";
    test::write_bytes(dir / "transforms.json",
                      R"({"fl_x": 2, "w": 2, "h": 1, "wavelengths": [550], )" + extra +
                          R"("frames": [)" + frames + "]}");
  };
  transforms("");
  auto scene = load_scene(dir);
  EXPECT_EQ(scene->scale, 10000);
  EXPECT_FLOAT_EQ(scene->image(1)[0][0][0].item<float>(), 0.65f);
  transforms(R"("scale": 5000, )");
  EXPECT_EQ(load_scene(dir)->scale, 5000);
  LoadOptions options;
  options.scale = 2;
  EXPECT_EQ(load_scene(dir, options)->scale, 2);
}

TEST(Envi, MalformedInputNamesTheFile) {
  fs::path dir = test::temp_dir("envi_bad");
  const std::string good_header =
      "ENVI\nsamples = 2\nlines = 2\nbands = 2\ndata type = 1\ninterleave = bsq\n";
  auto make = [&](const std::string& stem, const std::string& header, const std::string& data) {
    test::write_bytes(dir / (stem + ".hdr"), header);
    if (!data.empty()) test::write_bytes(dir / (stem + ".img"), data);
    return dir / (stem + ".hdr");
  };
  expect_error_naming([&] { read_cube(dir / "none.hdr"); }, "none.hdr", "not found");
  test::write_bytes(dir / "lonely.img", std::string(8, '\1'));
  expect_error_naming([&] { read_cube(dir / "lonely.img"); }, "lonely.img", "no ENVI header");
  fs::path no_data = make("no_data", good_header, "");
  expect_error_naming([&] { read_cube(no_data); }, "no_data.hdr", "no data file");
  fs::path empty = make("empty", "", std::string(8, '\1'));
  expect_error_naming([&] { read_cube(empty); }, "empty.hdr", "empty");
  fs::path magic = make("magic", "samples = 2\nlines = 2\nbands = 2\n", std::string(8, '\1'));
  expect_error_naming([&] { read_cube(magic); }, "magic.hdr", "not an ENVI header");
  fs::path no_bands =
      make("no_bands", "ENVI\nsamples = 2\nlines = 2\ndata type = 1\n", std::string(8, '\1'));
  expect_error_naming([&] { read_cube(no_bands); }, "no_bands.hdr", "missing required key 'bands'");
  expect_error_naming([&] { probe_cube(no_bands); }, "no_bands.hdr", "'bands'");
  fs::path no_type =
      make("no_type", "ENVI\nsamples = 2\nlines = 2\nbands = 2\n", std::string(8, 1));
  expect_error_naming([&] { read_cube(no_type); }, "no_type.hdr", "'data type'");
  fs::path complex = make("complex", "ENVI\nsamples = 2\nlines = 2\nbands = 2\ndata type = 6\n",
                          std::string(64, '\1'));
  expect_error_naming([&] { read_cube(complex); }, "complex.hdr", "unsupported data type 6");
  fs::path bad_number = make("bad_number",
                             "ENVI\nsamples = two\nlines = 2\nbands = 2\n"
                             "data type = 1\n",
                             std::string(8, '\1'));
  expect_error_naming([&] { read_cube(bad_number); }, "bad_number.hdr", "'samples'");
  fs::path truncated = make("truncated", good_header, std::string(7, '\1'));
  expect_error_naming([&] { read_cube(truncated); }, "truncated.img", "truncated");
  expect_error_naming([&] { probe_cube(truncated); }, "truncated.img", "truncated");
  fs::path unclosed = make("unclosed", good_header + "wavelength = {400, 500\n", std::string(8, 1));
  expect_error_naming([&] { read_cube(unclosed); }, "unclosed.hdr", "'}'");
  fs::path count = make("count", good_header + "wavelength = {400, 500, 600}\n", std::string(8, 1));
  expect_error_naming([&] { read_cube(count); }, "count.hdr", "3 values for 2 bands");
  fs::path interleave = make("interleave",
                             "ENVI\nsamples = 2\nlines = 2\nbands = 2\n"
                             "data type = 1\ninterleave = bsx\n",
                             std::string(8, 1));
  expect_error_naming([&] { read_cube(interleave); }, "interleave.hdr", "interleave");

  std::string nan_data;
  for (int i = 0; i < 8; ++i) put(&nan_data, i == 5 ? 0x7fc00000u : 0x3f000000u, 4, false);
  fs::path nan = make("nan", "ENVI\nsamples = 2\nlines = 2\nbands = 2\ndata type = 4\n", nan_data);
  expect_error_naming([&] { read_cube(nan); }, "nan.img", "NaN or Inf");

  expect_error_naming(
      [&] {
        write_envi(dir / "out.txt", torch::zeros({2, 2, 2}), {});
      },
      "out.txt", ".hdr");
  expect_error_naming(
      [&] {
        write_envi(dir / "out.hdr", torch::zeros({2, 2, 2}), {500});
      },
      "out.hdr", "1 wavelengths for 2 bands");
  EXPECT_FALSE(fs::exists(dir / "out.hdr"));
  EXPECT_FALSE(fs::exists(dir / "out.img"));
}

}  // namespace
}  // namespace ddhgs::io
