// Mirrors stb_image v2.27: for JPEG stbi__get_marker,
// stbi__decode_jpeg_header, stbi__decode_jpeg_image and the DHT case of
// stbi__process_marker; for PNG the chunk loop of stbi__parse_png_file.
// Every JPEG segment and PNG chunk stb accepts spans exactly the length it
// declares, so a walk by lengths meets every one stb meets.
#include "io/image/stb_guards.h"

#include <cstdint>

#include "core/error.h"

namespace ddhgs::io::detail {
namespace fs = std::filesystem;

namespace {

constexpr uint8_t kNoMarker = 0xFF;  // stb's STBI__MARKER_none
constexpr uint8_t kStartOfImage = 0xD8, kEndOfImage = 0xD9, kStartOfScan = 0xDA;
constexpr uint8_t kHuffmanTables = 0xC4;
constexpr size_t kMaxCodes = 256;  // stb's stbi__huffman.values[256]

bool is_frame_header(uint8_t marker) {
  return marker >= 0xC0 && marker <= 0xC2;
}

// Segments stb reads and goes on after: DHT, DQT, DNL, DRI, APPn, COM.
bool is_table_or_note(uint8_t marker) {
  return marker == kHuffmanTables || marker == 0xDB || marker == 0xDC || marker == 0xDD ||
         (marker >= 0xE0 && marker <= 0xEF) || marker == 0xFE;
}

bool is_restart(uint8_t marker) {
  return marker >= 0xD0 && marker <= 0xD7;
}

class JpegMarkerWalk {
 public:
  JpegMarkerWalk(const fs::path& path, const std::string& bytes) : path_(path), bytes_(bytes) {}

  void run() {
    if (next_marker() != kStartOfImage) return;  // not a JPEG: stb says so
    uint8_t marker = next_marker();
    while (!is_frame_header(marker)) {
      if (!is_table_or_note(marker) || !segment(marker)) return;
      // Before the frame header stb skips junk bytes up to the next marker.
      while ((marker = next_marker()) == kNoMarker)
        if (pos_ >= bytes_.size()) return;
    }
    if (!segment(marker)) return;
    for (marker = next_marker(); marker != kEndOfImage; marker = next_marker()) {
      if (marker == kStartOfScan) {
        if (!segment(marker)) return;
        skip_entropy_coded_data();
      } else if (!is_table_or_note(marker) || !segment(marker)) {
        return;
      }
    }
  }

 private:
  // stb reads zeros past the end of the file.
  uint8_t byte(size_t i) const { return i < bytes_.size() ? uint8_t(bytes_[i]) : 0; }

  // stbi__get_marker: consumes one byte that is not 0xFF (no marker), or a
  // run of 0xFF fill bytes and the marker after it.
  uint8_t next_marker() {
    if (byte(pos_++) != 0xFF) return kNoMarker;
    while (byte(pos_) == 0xFF) ++pos_;
    return byte(pos_++);
  }

  // One segment after its marker; false where stb stops (a length below 2).
  bool segment(uint8_t marker) {
    const size_t length = size_t(byte(pos_)) << 8 | byte(pos_ + 1);
    if (length < 2) return false;
    if (marker == kHuffmanTables) check_tables(length - 2);
    pos_ += length;
    return true;
  }

  // stb reads tables while its count of the segment's bytes is positive, so
  // the last one may run past the segment.
  void check_tables(size_t length) const {
    size_t table = pos_ + 2;
    for (size_t read = 0; read < length;) {
      const uint8_t kind = byte(table);
      if ((kind >> 4) > 1 || (kind & 15) > 3) return;  // stb refuses the table
      size_t codes = 0;
      for (size_t i = 1; i <= 16; ++i) codes += byte(table + i);
      if (codes > kMaxCodes)
        throw core::Error(path_, "corrupt JPEG: a Huffman table lists " + std::to_string(codes) +
                                     " codes (at most " + std::to_string(kMaxCodes) + ")");
      table += 17 + codes;
      read += 17 + codes;
    }
  }

  // Stops at the first marker in the scan's data other than a stuffed zero
  // or a restart marker: stb's decoder reads up to it, or stops earlier and
  // then either searches forward to it or fails.
  void skip_entropy_coded_data() {
    for (; pos_ < bytes_.size(); ++pos_) {
      if (byte(pos_) != 0xFF) continue;
      size_t after = pos_ + 1;
      while (after < bytes_.size() && byte(after) == 0xFF) ++after;
      const uint8_t marker = byte(after);
      if (marker != 0 && !is_restart(marker)) return;
      pos_ = after;
    }
  }

  const fs::path& path_;
  const std::string& bytes_;
  size_t pos_ = 0;
};

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
  JpegMarkerWalk(path, bytes).run();
  check_png_chunks(path, bytes);
}

}  // namespace ddhgs::io::detail
