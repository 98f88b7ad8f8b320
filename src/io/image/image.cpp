// 8-bit PNG through stb_image (the one translation unit holding its
// implementation), JPEG through libjpeg-turbo (io/image/jpeg.h), and PNG
// writing through stb_image_write.
#include "io/image/image.h"

#include <limits>

#include "core/error.h"
#include "io/cube/cube_formats.h"
#include "io/files/atomic_file.h"
#include "io/files/byte_count.h"
#include "io/image/jpeg.h"
#include "io/image/stb_guards.h"

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wunused-function"
#define STB_IMAGE_IMPLEMENTATION
#define STBI_ONLY_PNG
#include <stb_image.h>
#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb_image_write.h>
#pragma GCC diagnostic pop

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

std::string load_bytes(const fs::path& path) {
  std::string bytes = read_file(path);
  if (bytes.empty()) throw core::Error(path, "empty file, expected a PNG or JPEG image");
  if (bytes.size() > size_t(std::numeric_limits<int>::max()))
    throw core::Error(path, "image file larger than 2 GB");
  return bytes;
}

const stbi_uc* as_stbi(const std::string& bytes) {
  return reinterpret_cast<const stbi_uc*>(bytes.data());
}

void append_bytes(void* context, void* data, int size) {
  static_cast<std::string*>(context)->append(static_cast<const char*>(data), size_t(size));
}

}  // namespace

torch::Tensor read_image(const fs::path& path) {
  std::string bytes = load_bytes(path);
  if (detail::is_jpeg(bytes)) return detail::decode_jpeg(path, bytes);
  detail::check_before_stb(path, bytes);
  int width = 0, height = 0, channels = 0;
  // The header's size decides the allocation: it must be one the data can fill.
  if (stbi_info_from_memory(as_stbi(bytes), int(bytes.size()), &width, &height, &channels))
    require_decodable(path,
                      checked_product({uint64_t(width), uint64_t(height), uint64_t(channels)}),
                      bytes.size());
  stbi_uc* pixels =
      stbi_load_from_memory(as_stbi(bytes), int(bytes.size()), &width, &height, &channels, 0);
  if (!pixels)
    throw core::Error(
        path, std::string("not a readable PNG or JPEG image (") + stbi_failure_reason() + ")");
  std::unique_ptr<stbi_uc, void (*)(void*)> owner(pixels, stbi_image_free);
  return torch::from_blob(pixels, {height, width, channels}, torch::kUInt8).clone();
}

void write_png(const fs::path& path, const torch::Tensor& image) {
  torch::Tensor pixels = image.cpu();
  if (pixels.dim() == 2) pixels = pixels.unsqueeze(2);
  if (pixels.dim() != 3 || pixels.size(2) < 1 || pixels.size(2) > 4 || pixels.size(0) == 0 ||
      pixels.size(1) == 0)
    throw core::Error(path, "write_png expects an image [H, W, C] with C = 1 to 4");
  if (pixels.is_floating_point()) {
    pixels = pixels.to(torch::kFloat).nan_to_num(0.0).clamp(0.0, 1.0).mul(255.0).round();
  } else if (pixels.scalar_type() != torch::kUInt8) {
    throw core::Error(path, "write_png expects uint8 or float pixels");
  }
  pixels = pixels.to(torch::kUInt8).contiguous();
  int height = int(pixels.size(0)), width = int(pixels.size(1)), channels = int(pixels.size(2));
  std::string png;
  int ok = stbi_write_png_to_func(append_bytes, &png, width, height, channels, pixels.data_ptr(),
                                  width * channels);
  if (!ok) throw core::Error(path, "PNG encoding failed");
  write_file_atomically(path, png);
}

namespace detail {

Cube read_image_cube(const fs::path& path) {
  torch::Tensor pixels = read_image(path);
  int64_t channels = pixels.size(2);
  // Grey images repeat their one channel; alpha is dropped.
  if (channels < 3) pixels = pixels.narrow(2, 0, 1).expand({-1, -1, 3});
  Cube cube;
  cube.type = SampleType::U8;
  cube.data = pixels.narrow(2, 0, 3).contiguous();
  return cube;
}

CubeInfo probe_image(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw core::Error(path, "file not found");
  if (fs::file_size(path, ec) == 0)
    throw core::Error(path, "empty file, expected a PNG or JPEG image");
  const std::string bytes = load_bytes(path);  // small: an 8-bit picture
  CubeInfo info;
  info.bands = 3;
  info.type = SampleType::U8;
  info.compressed = true;
  if (is_jpeg(bytes)) {
    const JpegSize size = read_jpeg_size(path, bytes);
    info.height = size.height, info.width = size.width;
    return info;
  }
  check_before_stb(path, bytes);
  int width = 0, height = 0, channels = 0;
  if (!stbi_info_from_memory(as_stbi(bytes), int(bytes.size()), &width, &height, &channels))
    throw core::Error(
        path, std::string("not a readable PNG or JPEG image (") + stbi_failure_reason() + ")");
  info.height = height, info.width = width;
  return info;
}

}  // namespace detail
}  // namespace ddhgs::io
