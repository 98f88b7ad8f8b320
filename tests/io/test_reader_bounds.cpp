// Every size a file declares is checked against the bytes it
// holds before anything is allocated or read. Each case here was first seen
// failing: read past its buffer (.pt), overflowed its size arithmetic
// (ENVI), allocated what a corrupt header asked for (TIFF, PNG), trusted a
// float list count (PLY) or passed NaN poses and points on (COLMAP).
#include <gtest/gtest.h>
#include <torch/serialize.h>

#include <torch/csrc/jit/serialization/pickle.h>

#include <cstring>

#include "cube_test_util.h"
#include "io/colmap/colmap.h"
#include "io/cube/cube.h"
#include "io/files/atomic_file.h"
#include "io/files/byte_count.h"
#include "io/image/image.h"
#include "io/ply/ply.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;

// A torch.save file of `tensor` (LibTorch writes the same zip layout) whose
// data record is cut to `keep` bytes: Python's zipfile rewrites the archive
// around the shortened record, as a damaged copy or a hostile file would be.
void save_short_pt(const fs::path& path, const torch::Tensor& tensor, int keep) {
  const std::vector<char> whole = torch::pickle_save(tensor);
  const fs::path source = path.string() + ".whole";
  test::write_bytes(source, std::string(whole.begin(), whole.end()));
  const fs::path script = path.string() + ".py";
  test::write_bytes(script,
                    "import zipfile\n"
                    "src = zipfile.ZipFile('" +
                        source.string() +
                        "')\n"
                        "dst = zipfile.ZipFile('" +
                        path.string() +
                        "', 'w')\n"
                        "for n in src.namelist():\n"
                        "    d = src.read(n)\n"
                        "    if n.endswith('data/0'): d = d[:" +
                        std::to_string(keep) +
                        "]\n"
                        "    dst.writestr(n, d)\n"
                        "dst.close()\n");
  std::string out;
  ASSERT_EQ(test::run_command(test::python() + " " + script.string(), &out), 0) << out;
}

TEST(ReaderBounds, PtDataShorterThanItsShapeIsRefused) {
  if (!test::python_has("zipfile")) GTEST_SKIP() << "no python3";
  const fs::path dir = test::temp_dir("bounds_pt");
  // A small int16 cube used to load and train on whatever memory followed.
  save_short_pt(dir / "small.pt", torch::ones({4, 5, 3}, torch::kInt16), 10);
  test::expect_error_naming(
      [&] { read_cube(dir / "small.pt"); }, "small.pt",
      "truncated: the tensor [4 x 5 x 3] needs 120 bytes, the file stores 10");
  test::expect_error_naming([&] { probe_cube(dir / "small.pt"); }, "small.pt", "truncated");
  // A large one read far out of bounds (a segfault).
  save_short_pt(dir / "large.pt", torch::zeros({300, 300, 30}), 100);
  test::expect_error_naming([&] { read_cube(dir / "large.pt"); }, "large.pt", "truncated");
  // The same files whole still read.
  save_short_pt(dir / "whole.pt", torch::arange(60, torch::kInt16).reshape({4, 5, 3}), 1000);
  EXPECT_EQ(read_cube(dir / "whole.pt").data[3][4][2].item<int>(), 59);
}

TEST(ReaderBounds, EnviSizesThatOverflowAreRefused) {
  const fs::path dir = test::temp_dir("bounds_envi");
  // 2^22 cubed overflows 64 bits: the product once wrapped to a small number.
  test::write_bytes(dir / "c.hdr",
                    "ENVI\nsamples = 4194304\nlines = 4194304\nbands = 4194304\n"
                    "data type = 2\ninterleave = bsq\n");
  test::write_bytes(dir / "c.img", std::string(64, '\0'));
  test::expect_error_naming([&] { read_cube(dir / "c.hdr"); }, "c.img",
                            "more than any file can hold");
  test::write_bytes(dir / "d.hdr",
                    "ENVI\nsamples = 4\nlines = 4\nbands = 4\ndata type = 2\nheader offset = 99\n");
  test::write_bytes(dir / "d.img", std::string(64, '\0'));
  test::expect_error_naming([&] { read_cube(dir / "d.hdr"); }, "d.img", "truncated");
}

TEST(ReaderBounds, EnviWavelengthsMustBePositive) {
  const fs::path dir = test::temp_dir("bounds_envi_nm");
  write_envi(dir / "c.hdr", torch::zeros({2, 2, 2}), {-5.0, 500.0});
  // Negative bands were dropped by the default band range without a word.
  test::expect_error_naming([&] { read_cube(dir / "c.hdr"); }, "c.hdr", "expected values > 0");
}

// A little-endian TIFF header whose one page claims width x height 32-bit
// samples stored in a single strip of `strip_bytes` at offset 8.
std::string tiff_claiming(uint32_t width, uint32_t height, uint32_t strip_bytes,
                          uint16_t compression) {
  std::string out("II*\0\x08\0\0\0", 8);
  auto u16 = [&](uint16_t v) { out.append(reinterpret_cast<const char*>(&v), 2); };
  auto u32 = [&](uint32_t v) { out.append(reinterpret_cast<const char*>(&v), 4); };
  auto entry = [&](uint16_t tag, uint16_t type, uint32_t value) {
    u16(tag), u16(type), u32(1), u32(value);
  };
  const uint16_t kShort = 3, kLong = 4;
  u16(9);
  entry(256, kLong, width);
  entry(257, kLong, height);
  entry(258, kShort, 32);
  entry(259, kShort, compression);
  entry(262, kShort, 1);
  entry(273, kLong, 8 + 2 + 9 * 12 + 4);
  entry(278, kLong, height);
  entry(279, kLong, strip_bytes);
  entry(339, kShort, 3);
  u32(0);
  out += std::string(strip_bytes, '\0');
  return out;
}

TEST(ReaderBounds, TiffDeclaringMoreThanItHoldsIsRefusedBeforeAllocating) {
  const fs::path dir = test::temp_dir("bounds_tiff");
  test::write_bytes(dir / "ok.tif", tiff_claiming(4, 3, 48, 1));
  EXPECT_EQ(read_cube(dir / "ok.tif").data.sizes(), (std::vector<int64_t>{3, 4, 1}));
  // 60000 x 60000 float32 = 14 GB announced by a 200-byte file.
  test::write_bytes(dir / "huge.tif", tiff_claiming(60000, 60000, 48, 1));
  test::expect_error_naming([&] { read_cube(dir / "huge.tif"); }, "huge.tif", "truncated");
  test::expect_error_naming([&] { probe_cube(dir / "huge.tif"); }, "huge.tif", "truncated");
  // Compressed (deflate): no ratio reaches 14 GB from 48 bytes.
  test::write_bytes(dir / "bomb.tif", tiff_claiming(60000, 60000, 48, 8));
  test::expect_error_naming([&] { read_cube(dir / "bomb.tif"); }, "bomb.tif", "can hold");
}

TEST(ReaderBounds, ImageHeaderLargerThanItsDataIsRefused) {
  const fs::path dir = test::temp_dir("bounds_png");
  write_png(dir / "ok.png", torch::zeros({6, 4, 3}, torch::kUInt8));
  std::string png = test::read_bytes(dir / "ok.png");
  // IHDR's width and height (big-endian, bytes 16-23) set to 16000 x 16000:
  // 768 MB of pixels, within what stb_image itself accepts.
  const char big[4] = {0, 0, 0x3E, char(0x80)};
  std::memcpy(png.data() + 16, big, 4);
  std::memcpy(png.data() + 20, big, 4);
  test::write_bytes(dir / "huge.png", png);
  test::expect_error_naming([&] { read_image(dir / "huge.png"); }, "huge.png", "can hold");
}

TEST(ReaderBounds, PlyListCountMustBeAnInteger) {
  const fs::path dir = test::temp_dir("bounds_ply");
  test::write_bytes(dir / "list.ply",
                    "ply\nformat binary_little_endian 1.0\nelement face 1\n"
                    "property list double int index\nelement vertex 1\nproperty float x\n"
                    "property float y\nproperty float z\nend_header\n" +
                        std::string(64, '\xff'));
  test::expect_error_naming([&] { read_point_ply(dir / "list.ply"); }, "list.ply",
                            "not an integer type");
}

TEST(ReaderBounds, ColmapBinaryValuesAreChecked) {
  const fs::path dir = test::temp_dir("bounds_colmap");
  ColmapModel model;
  model.cameras[1] = {1, "PINHOLE", 8, 6, {5, 5, 4, 3}};
  ColmapImage image;
  image.image_id = 1;
  image.camera_id = 1;
  image.name = "a.png";
  model.images.push_back(image);
  ColmapPoint point;
  point.xyz = {1, std::nan(""), 0};
  model.points.push_back(point);
  write_colmap_binary(dir, model);
  // NaN points once reached training as "index out of range in self".
  test::expect_error_naming([&] { read_colmap_binary(dir); }, "points3D.bin",
                            "point y is not a finite number");
  model.points.clear();
  model.images[0].qvec = {std::nan(""), 0, 0, 0};
  write_colmap_binary(dir, model);
  test::expect_error_naming([&] { read_colmap_binary(dir); }, "images.bin", "quaternion");
  model.images[0].qvec = {1, 0, 0, 0};
  model.cameras[1].width = 0;
  write_colmap_binary(dir, model);
  test::expect_error_naming([&] { read_colmap_binary(dir); }, "cameras.bin", "camera width 0");
}

TEST(ReaderBounds, SizeArithmeticIsOverflowSafe) {
  EXPECT_EQ(checked_product({3, 4, 5}), 60u);
  EXPECT_FALSE(checked_product({uint64_t(1) << 32, uint64_t(1) << 32}).has_value());
  EXPECT_EQ(require_present("f", "the header", {2, 3}, 4, 24), 24u);
  test::expect_error_naming(
      [] {
        require_present("f", "the header", {2, 3}, 4, 23);
      },
      "f", "truncated: the header declares 2 x 3 samples (24 bytes)");
}

}  // namespace
}  // namespace ddhgs::io
