// Multi-band TIFF: every layout and sample type, tiled and compressed files,
// files written by PIL, malformed files.
#include <gtest/gtest.h>
#include <tiffio.h>

#include "cube_test_util.h"
#include "io/cube/cube.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;
using test::expect_error_naming;

TEST(Tiff, RoundTripEveryLayoutAndType) {
  fs::path dir = test::temp_dir("tiff_round_trip");
  torch::manual_seed(7);
  torch::Tensor f32 = torch::rand({9, 11, 5});
  torch::Tensor u8 = torch::randint(0, 256, {9, 11, 5}).to(torch::kUInt8);
  torch::Tensor u16 = torch::randint(0, 65536, {9, 11, 5}).to(torch::kInt32).to(torch::kInt16);
  torch::Tensor i16 = torch::randint(-30000, 30000, {9, 11, 5}).to(torch::kInt16);
  for (TiffLayout layout : {TiffLayout::Contiguous, TiffLayout::Separate, TiffLayout::Pages})
    for (auto [data, type] : {std::pair{f32, SampleType::F32}, std::pair{u8, SampleType::U8},
                              std::pair{u16, SampleType::U16}, std::pair{i16, SampleType::I16}}) {
      fs::path path = dir / ("c" + std::to_string(int(layout)) + to_string(type) + ".tif");
      write_tiff(path, data, layout, type);
      Cube cube = read_cube(path);
      EXPECT_EQ(cube.type, type) << path;
      EXPECT_TRUE(torch::equal(cube.data, data)) << path;
      CubeInfo info = probe_cube(path);
      EXPECT_EQ(info.height, 9);
      EXPECT_EQ(info.width, 11);
      EXPECT_EQ(info.bands, 5);
      EXPECT_EQ(info.type, type);
    }
}

// Writes data [H, W, B] uint16 as a tiled, LZW-compressed TIFF through libtiff.
void write_tiled(const fs::path& path, const torch::Tensor& data, bool separate) {
  TIFF* tif = TIFFOpen(path.c_str(), "w");
  ASSERT_NE(tif, nullptr);
  int64_t h = data.size(0), w = data.size(1), b = data.size(2);
  const uint32_t tile = 16;
  TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, uint32_t(w));
  TIFFSetField(tif, TIFFTAG_IMAGELENGTH, uint32_t(h));
  TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, uint16_t(b));
  TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, uint16_t(16));
  TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, SAMPLEFORMAT_UINT);
  TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
  TIFFSetField(tif, TIFFTAG_PLANARCONFIG, separate ? PLANARCONFIG_SEPARATE : PLANARCONFIG_CONTIG);
  TIFFSetField(tif, TIFFTAG_COMPRESSION, COMPRESSION_LZW);
  TIFFSetField(tif, TIFFTAG_TILEWIDTH, tile);
  TIFFSetField(tif, TIFFTAG_TILELENGTH, tile);
  std::vector<uint16_t> buf(tile * tile * (separate ? 1 : b), 0);
  auto acc = data.accessor<int16_t, 3>();
  for (int64_t plane = 0; plane < (separate ? b : 1); ++plane)
    for (uint32_t y = 0; y < h; y += tile)
      for (uint32_t x = 0; x < w; x += tile) {
        std::fill(buf.begin(), buf.end(), 0);
        for (uint32_t ty = 0; ty < tile && y + ty < h; ++ty)
          for (uint32_t tx = 0; tx < tile && x + tx < w; ++tx)
            for (int64_t s = 0; s < (separate ? 1 : b); ++s)
              buf[(ty * tile + tx) * (separate ? 1 : b) + s] =
                  uint16_t(acc[y + ty][x + tx][separate ? plane : s]);
        ASSERT_GE(TIFFWriteTile(tif, buf.data(), x, y, 0, uint16_t(plane)), 0);
      }
  TIFFClose(tif);
}

TEST(Tiff, TiledAndCompressed) {
  fs::path dir = test::temp_dir("tiff_tiled");
  // 20 x 37 is not a multiple of the 16-pixel tile: edge tiles are partial.
  torch::Tensor data = torch::randint(0, 65536, {20, 37, 3}).to(torch::kInt32).to(torch::kInt16);
  for (bool separate : {false, true}) {
    fs::path path = dir / (separate ? "separate.tif" : "contig.tif");
    write_tiled(path, data, separate);
    Cube cube = read_cube(path);
    EXPECT_EQ(cube.type, SampleType::U16);
    EXPECT_TRUE(torch::equal(cube.data, data)) << path;
  }
}

TEST(Tiff, ReadsPagesWrittenByPil) {
  if (!test::python_has("PIL") || !test::python_has("numpy")) GTEST_SKIP() << "no PIL/numpy";
  fs::path dir = test::temp_dir("tiff_pil");
  std::string script =
      "import numpy as np\nfrom PIL import Image\n"
      "d = '" +
      dir.string() +
      "/'\n"
      "pages = [Image.fromarray((np.arange(12).reshape(3, 4) + 100 * b).astype('f4'))\n"
      "         for b in range(4)]\n"
      "pages[0].save(d + 'pages.tif', save_all=True, append_images=pages[1:])\n"
      "Image.fromarray(np.arange(12).reshape(3, 4).astype('u1')).save(d + 'grey.tif')\n";
  test::write_bytes(dir / "make.py", script);
  std::string out;
  ASSERT_EQ(test::run_command(test::python() + " " + (dir / "make.py").string(), &out), 0) << out;
  Cube pages = read_cube(dir / "pages.tif");
  EXPECT_EQ(pages.type, SampleType::F32);
  ASSERT_EQ(pages.data.sizes(), (std::vector<int64_t>{3, 4, 4}));
  EXPECT_EQ(pages.data[2][1][3].item<float>(), 9 + 300);
  EXPECT_EQ(probe_cube(dir / "pages.tif").bands, 4);
  Cube grey = read_cube(dir / "grey.tif");
  EXPECT_EQ(grey.type, SampleType::U8);
  ASSERT_EQ(grey.data.sizes(), (std::vector<int64_t>{3, 4, 1}));
  EXPECT_EQ(grey.data[2][3][0].item<int>(), 11);
}

TEST(Tiff, MalformedFilesNameTheFile) {
  fs::path dir = test::temp_dir("tiff_bad");
  expect_error_naming([&] { read_cube(dir / "none.tif"); }, "none.tif", "not found");
  test::write_bytes(dir / "empty.tif", "");
  expect_error_naming([&] { read_cube(dir / "empty.tif"); }, "empty.tif", "empty");
  test::write_bytes(dir / "magic.tiff", "GIF89a not a tiff at all");
  expect_error_naming([&] { read_cube(dir / "magic.tiff"); }, "magic.tiff", "not a readable TIFF");
  expect_error_naming([&] { probe_cube(dir / "magic.tiff"); }, "magic.tiff", "not a readable TIFF");

  torch::Tensor data = torch::rand({64, 64, 4});
  write_tiff(dir / "good.tif", data);
  std::string good = test::read_bytes(dir / "good.tif");
  // libtiff writes the directory after the samples: cutting the file in half
  // loses it, and overwriting the last strip's bytes leaves a short strip.
  test::write_bytes(dir / "cut.tif", good.substr(0, good.size() / 2));
  expect_error_naming([&] { read_cube(dir / "cut.tif"); }, "cut.tif", "not a readable TIFF");
  write_tiff(dir / "page.tif", data, TiffLayout::Pages);
  std::string pages = test::read_bytes(dir / "page.tif");
  test::write_bytes(dir / "short.tif", pages.substr(0, pages.size() - 100));
  expect_error_naming([&] { read_cube(dir / "short.tif"); }, "short.tif", "corrupt TIFF");
  expect_error_naming([&] { probe_cube(dir / "short.tif"); }, "short.tif", "corrupt TIFF");

  torch::Tensor nan = data.clone();
  nan[10][20][3] = std::numeric_limits<float>::infinity();
  write_tiff(dir / "inf.tif", nan, TiffLayout::Separate);
  expect_error_naming([&] { read_cube(dir / "inf.tif"); }, "inf.tif", "NaN or Inf");

  // One-bit samples are not a cube type.
  TIFF* tif = TIFFOpen((dir / "bits.tif").c_str(), "w");
  ASSERT_NE(tif, nullptr);
  TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, uint32_t(8));
  TIFFSetField(tif, TIFFTAG_IMAGELENGTH, uint32_t(1));
  TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, uint16_t(1));
  TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, uint16_t(1));
  TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
  uint8_t row = 0xA5;
  TIFFWriteScanline(tif, &row, 0, 0);
  TIFFClose(tif);
  expect_error_naming([&] { read_cube(dir / "bits.tif"); }, "bits.tif", "unsupported TIFF samples");

  // Pages of different sizes are not bands of one cube.
  tif = TIFFOpen((dir / "mixed.tif").c_str(), "w");
  ASSERT_NE(tif, nullptr);
  for (uint32_t width : {4u, 5u}) {
    TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, width);
    TIFFSetField(tif, TIFFTAG_IMAGELENGTH, uint32_t(1));
    TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, uint16_t(1));
    TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, uint16_t(8));
    TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
    uint8_t pixels[5] = {1, 2, 3, 4, 5};
    TIFFWriteScanline(tif, pixels, 0, 0);
    TIFFWriteDirectory(tif);
  }
  TIFFClose(tif);
  expect_error_naming([&] { read_cube(dir / "mixed.tif"); }, "mixed.tif", "page 2 differs");
  expect_error_naming(
      [&] {
        write_tiff(dir / "half.tif", torch::zeros({2, 2, 2}, torch::kHalf));
      },
      "half.tif", "float16");
  EXPECT_FALSE(fs::exists(dir / "half.tif"));
}

}  // namespace
}  // namespace ddhgs::io
