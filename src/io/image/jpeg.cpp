#include "io/image/jpeg.h"

#include <csetjmp>
#include <cstdio>
// jpeglib.h needs size_t and FILE declared first.
#include <jpeglib.h>

#include "core/error.h"
#include "io/files/byte_count.h"

namespace ddhgs::io::detail {
namespace fs = std::filesystem;

namespace {

// A progressive file may hold many scans, each a pass over the image; real
// encoders write about ten. Thousands of tiny scans only cost time.
constexpr int kMaxScans = 1000;

struct ErrorManager {
  jpeg_error_mgr base;  // first: libjpeg hands out a pointer to it
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX];
};

extern "C" void jump_on_error(j_common_ptr cinfo) {
  auto* e = reinterpret_cast<ErrorManager*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, e->message);
  std::longjmp(e->jump, 1);
}

// Corrupt-data warnings (a truncated scan filled with grey, a bad code
// skipped) end the decode too: a view with made-up pixels must not be
// trained on. Trace messages (level >= 0) are ignored.
extern "C" void jump_on_warning(j_common_ptr cinfo, int level) {
  if (level < 0) jump_on_error(cinfo);
}

extern "C" void limit_scans(j_common_ptr cinfo) {
  auto* d = reinterpret_cast<j_decompress_ptr>(cinfo);
  if (d->input_scan_number > kMaxScans) {
    auto* e = reinterpret_cast<ErrorManager*>(cinfo->err);
    std::snprintf(e->message, sizeof e->message, "more than %d progressive scans", kMaxScans);
    std::longjmp(e->jump, 1);
  }
}

// What the decode does once the header is read: checks its size and
// returns where the rows go (nullptr: stop after the header, or the size
// was refused with `refused` set).
struct Target {
  const fs::path* path;
  uint64_t file_bytes;
  bool header_only;
  JpegSize size;
  torch::Tensor pixels;
  std::string refused;

  unsigned char* accept(int width, int height, int channels) {
    size = {width, height, channels};
    if (width == 0 || height == 0) {
      refused = path->string() + ": not a readable JPEG image (it holds tables but no picture)";
      return nullptr;
    }
    try {
      require_decodable(*path,
                        checked_product({uint64_t(width), uint64_t(height), uint64_t(channels)}),
                        file_bytes);
    } catch (const core::Error& e) {
      refused = e.what();
      return nullptr;
    }
    if (header_only) return nullptr;
    pixels = torch::empty({height, width, channels}, torch::kUInt8);
    return pixels.data_ptr<uint8_t>();
  }
};

// The libjpeg calls, with no object that has a destructor in this frame
// (longjmp comes back here). False with `error` set when libjpeg failed.
bool run_libjpeg(const std::string& bytes, Target& target, ErrorManager& error) {
  jpeg_decompress_struct cinfo;
  jpeg_progress_mgr progress;
  error.message[0] = 0;
  cinfo.err = jpeg_std_error(&error.base);
  error.base.error_exit = jump_on_error;
  error.base.emit_message = jump_on_warning;
  if (setjmp(error.jump)) {
    jpeg_destroy_decompress(&cinfo);
    return false;
  }
  jpeg_create_decompress(&cinfo);
  progress.progress_monitor = limit_scans;
  cinfo.progress = &progress;
  jpeg_mem_src(&cinfo, reinterpret_cast<const unsigned char*>(bytes.data()),
               static_cast<unsigned long>(bytes.size()));
  jpeg_read_header(&cinfo, TRUE);
  if (cinfo.jpeg_color_space == JCS_CMYK || cinfo.jpeg_color_space == JCS_YCCK) {
    std::snprintf(error.message, sizeof error.message,
                  "CMYK JPEG (save the image as RGB or greyscale)");
    jpeg_destroy_decompress(&cinfo);
    return false;
  }
  const bool grey = cinfo.num_components == 1;
  cinfo.out_color_space = grey ? JCS_GRAYSCALE : JCS_RGB;
  const int channels = grey ? 1 : 3;
  unsigned char* rows = target.accept(int(cinfo.image_width), int(cinfo.image_height), channels);
  if (!rows) {
    jpeg_destroy_decompress(&cinfo);
    return true;  // header only, or refused (target.refused)
  }
  jpeg_start_decompress(&cinfo);
  const size_t stride = size_t(cinfo.output_width) * size_t(channels);
  while (cinfo.output_scanline < cinfo.output_height) {
    JSAMPROW row = rows + size_t(cinfo.output_scanline) * stride;
    jpeg_read_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_decompress(&cinfo);
  jpeg_destroy_decompress(&cinfo);
  return true;
}

Target run(const fs::path& path, const std::string& bytes, bool header_only) {
  Target target{&path, uint64_t(bytes.size()), header_only, {}, {}, {}};
  ErrorManager error;
  if (!run_libjpeg(bytes, target, error))
    throw core::Error(path, std::string("not a readable JPEG image (") + error.message + ")");
  if (!target.refused.empty()) throw core::Error(target.refused);
  return target;
}

}  // namespace

bool is_jpeg(const std::string& bytes) {
  return bytes.size() >= 2 && uint8_t(bytes[0]) == 0xFF && uint8_t(bytes[1]) == 0xD8;
}

JpegSize read_jpeg_size(const fs::path& path, const std::string& bytes) {
  return run(path, bytes, true).size;
}

torch::Tensor decode_jpeg(const fs::path& path, const std::string& bytes) {
  return run(path, bytes, false).pixels;
}

}  // namespace ddhgs::io::detail
