// Mirrors the chunk loop of stb_image v2.27's stbi__parse_png_file: every
// chunk stb accepts spans exactly the length it declares, so a walk by
// lengths meets every one stb meets.
#include "io/image/stb_guards.h"

#include <cstdint>

#include "core/error.h"

namespace ddhgs::io::detail {
namespace fs = std::filesystem;

namespace {

// Each chunk: 4-byte big-endian length, 4-byte type, data, 4-byte CRC.
void check_png_chunks(const fs::path& path, const std::string& bytes) {
  static const std::string kSignature = "\x89PNG\r\n\x1a\n";
  if (bytes.compare(0, kSignature.size(), kSignature) != 0) return;  // not a PNG
  const auto byte = [&](size_t i) { return uint32_t(uint8_t(bytes[i])); };
  for (size_t at = kSignature.size(); at + 8 <= bytes.size();) {
    const uint32_t length = byte(at) << 24 | byte(at + 1) << 16 | byte(at + 2) << 8 | byte(at + 3);
    const std::string type = bytes.substr(at + 4, 4);
    const size_t left = bytes.size() - (at + 8);
    if (length > left)
      throw core::Error(path, "not a readable PNG image: its " + type + " chunk at byte " +
                                  std::to_string(at) + " declares " + std::to_string(length) +
                                  " bytes, " + std::to_string(left) +
                                  " follow (truncated or corrupt file)");
    if (type == "IEND") return;
    at += 12 + size_t(length);
  }
}

}  // namespace

void check_before_stb(const fs::path& path, const std::string& bytes) {
  check_png_chunks(path, bytes);
}

}  // namespace ddhgs::io::detail
