// PNG/JPEG reading and PNG writing.
#include <gtest/gtest.h>

#include "cube_test_util.h"
#include "io/cube/cube.h"
#include "io/image/image.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;

TEST(Image, PngRoundTripUint8AndFloat) {
  fs::path dir = test::temp_dir("png_round_trip");
  torch::manual_seed(3);
  torch::Tensor rgb = torch::randint(0, 256, {7, 9, 3}).to(torch::kUInt8);
  write_png(dir / "rgb.png", rgb);
  EXPECT_TRUE(torch::equal(read_image(dir / "rgb.png"), rgb));

  torch::Tensor grey = torch::randint(0, 256, {5, 4}).to(torch::kUInt8);
  write_png(dir / "grey.png", grey);
  EXPECT_TRUE(torch::equal(read_image(dir / "grey.png"), grey.unsqueeze(2)));

  // Floats are clamped to [0, 1] and rounded to the nearest of 256 levels.
  torch::Tensor f = torch::tensor({-0.5f, 0.0f, 0.5f, 1.0f, 2.0f, 0.1f}).view({2, 3, 1});
  write_png(dir / "float.png", f);
  torch::Tensor expected = torch::tensor({0, 0, 128, 255, 255, 26}, torch::kUInt8).view({2, 3, 1});
  EXPECT_TRUE(torch::equal(read_image(dir / "float.png"), expected));
}

TEST(Image, PngMatchesAnIndependentDecoder) {
  if (!test::python_has("PIL")) GTEST_SKIP() << "python3 without PIL";
  fs::path dir = test::temp_dir("png_pil");
  torch::Tensor rgb =
      torch::arange(2 * 3 * 3, torch::kInt).view({2, 3, 3}).mul(10).to(torch::kUInt8);
  write_png(dir / "a.png", rgb);
  std::string out;
  ASSERT_EQ(test::run_command(test::python() + " -c \"from PIL import Image; im = Image.open('" +
                                  (dir / "a.png").string() +
                                  "'); print(im.size, im.mode, im.getpixel((2, 1)))\"",
                              &out),
            0)
      << out;
  EXPECT_EQ(out, "(3, 2) RGB (150, 160, 170)\n");
}

TEST(Image, PngAndJpegAreThreeBandCubes) {
  fs::path dir = test::temp_dir("image_cube");
  torch::Tensor grey = torch::full({6, 8, 1}, 77, torch::kUInt8);
  write_png(dir / "grey.png", grey);
  Cube cube = read_cube(dir / "grey.png");
  EXPECT_EQ(cube.type, SampleType::U8);
  EXPECT_EQ(cube.data.sizes(), (std::vector<int64_t>{6, 8, 3}));
  EXPECT_EQ(cube.data.min().item<int>(), 77);
  EXPECT_EQ(cube.data.max().item<int>(), 77);
  torch::Tensor rgba = torch::full({6, 8, 4}, 200, torch::kUInt8);
  write_png(dir / "rgba.png", rgba);
  EXPECT_EQ(read_cube(dir / "rgba.png").data.size(2), 3);
  CubeInfo info = probe_cube(dir / "rgba.png");
  EXPECT_EQ(info.height, 6);
  EXPECT_EQ(info.width, 8);
  EXPECT_EQ(info.bands, 3);

  if (!test::python_has("PIL")) GTEST_SKIP() << "python3 without PIL for the JPEG";
  std::string out;
  ASSERT_EQ(test::run_command(test::python() +
                                  " -c \"from PIL import Image; Image.new('RGB', (8, 6), (40, "
                                  "120, 200)).save('" +
                                  (dir / "flat.jpg").string() + "', quality=95)\"",
                              &out),
            0)
      << out;
  Cube jpeg = read_cube(dir / "flat.jpg");
  ASSERT_EQ(jpeg.data.sizes(), (std::vector<int64_t>{6, 8, 3}));
  torch::Tensor mean = jpeg.data.to(torch::kFloat).mean(std::vector<int64_t>{0, 1});
  EXPECT_NEAR(mean[0].item<float>(), 40, 3);
  EXPECT_NEAR(mean[1].item<float>(), 120, 3);
  EXPECT_NEAR(mean[2].item<float>(), 200, 3);
  EXPECT_EQ(probe_cube(dir / "flat.jpg").width, 8);
}

TEST(Image, MalformedImagesNameTheFile) {
  fs::path dir = test::temp_dir("image_bad");
  test::expect_error_naming([&] { read_image(dir / "none.png"); }, "none.png", "not found");
  test::write_bytes(dir / "empty.png", "");
  test::expect_error_naming([&] { read_image(dir / "empty.png"); }, "empty.png", "empty");
  test::expect_error_naming([&] { probe_cube(dir / "empty.png"); }, "empty.png", "empty");
  test::write_bytes(dir / "text.png", "definitely not a png file");
  test::expect_error_naming([&] { read_image(dir / "text.png"); }, "text.png", "not a readable");
  test::expect_error_naming([&] { probe_cube(dir / "text.png"); }, "text.png", "not a readable");
  write_png(dir / "good.png", torch::zeros({16, 16, 3}, torch::kUInt8));
  std::string good = test::read_bytes(dir / "good.png");
  test::write_bytes(dir / "cut.png", good.substr(0, good.size() / 2));
  test::expect_error_naming([&] { read_image(dir / "cut.png"); }, "cut.png", "not a readable");
  test::expect_error_naming(
      [&] {
        write_png(dir / "bad_shape.png", torch::zeros({2, 2, 5}));
      },
      "bad_shape.png", "[H, W, C]");
  EXPECT_FALSE(fs::exists(dir / "bad_shape.png"));
  test::expect_error_naming([&] { read_cube(dir / "cube.bmp"); }, "cube.bmp", "not found");
  test::write_bytes(dir / "cube.bmp", "BM");
  test::expect_error_naming([&] { read_cube(dir / "cube.bmp"); }, "cube.bmp",
                            "unknown cube format");
}

// A Huffman table listing more than 256 codes made stb_image write past an
// array (the fuzzer's first find); libjpeg-turbo refuses it, naming the
// file, by read and by probe.
TEST(Image, JpegHuffmanTableWithTooManyCodesIsRefused) {
  fs::path dir = test::temp_dir("image_huffman");
  std::string jpeg = "\xFF\xD8";                   // start of image
  std::string table = std::string(1, '\x10');      // AC table 0
  for (int i = 0; i < 16; ++i) table += char(20);  // 16 x 20 = 320 codes
  table += std::string(320, '\x01');
  const size_t length = table.size() + 2;
  jpeg += "\xFF\xC4";
  jpeg += char(length >> 8);
  jpeg += char(length & 0xFF);
  jpeg += table + "\xFF\xD9";
  test::write_bytes(dir / "huffman.jpg", jpeg);
  test::expect_error_naming([&] { read_image(dir / "huffman.jpg"); }, "huffman.jpg",
                            "not a readable JPEG image (Bogus Huffman table definition)");
  test::expect_error_naming([&] { probe_cube(dir / "huffman.jpg"); }, "huffman.jpg",
                            "not a readable JPEG image (Bogus Huffman table definition)");
}

}  // namespace
}  // namespace ddhgs::io
