// The end of central directory record, its zip64 variant and the central
// directory entries as miniz 2.1 (LibTorch 1.13's copy) reads them:
// mz_zip_reader_read_central_dir and mz_zip_file_stat_internal.
#include "io/cube/zip_check.h"

#include <algorithm>
#include <cstdint>
#include <fstream>
#include <optional>
#include <string>

#include "core/error.h"
#include "io/files/byte_count.h"
#include "io/files/little_endian.h"

namespace ddhgs::io::detail {
namespace fs = std::filesystem;

namespace {

constexpr uint32_t kEndSignature = 0x06054b50, kZip64LocatorSignature = 0x07064b50,
                   kZip64EndSignature = 0x06064b50, kEntrySignature = 0x02014b50;
constexpr size_t kEndBytes = 22, kZip64LocatorBytes = 20, kZip64EndBytes = 56, kEntryBytes = 46;
constexpr uint32_t kZip64Marker = 0xFFFFFFFF;
constexpr uint16_t kZip64ExtraField = 1;

class CentralDirectory {
 public:
  explicit CentralDirectory(const fs::path& path)
      : path_(path), in_(path, std::ios::binary), size_(fs::file_size(path)) {}

  void check() {
    // The last end record with room for itself, within 64 kB of comment.
    const uint64_t tail = std::min<uint64_t>(size_, 0xFFFF + kEndBytes);
    const std::string end_area = read(size_ - tail, tail);
    if (end_area.size() < kEndBytes) return;
    size_t end = end_area.size() - kEndBytes + 1;
    do {
      if (end-- == 0) return;  // none: miniz refused the archive
    } while (little_endian(end_area, end, 4) != kEndSignature);
    const uint64_t end_offset = size_ - tail + end;
    const std::string record = end_area.substr(end, kEndBytes);
    uint64_t entries = little_endian(record, 10, 2);
    uint64_t directory = little_endian(record, 16, 4);
    if (end_offset >= kZip64LocatorBytes + kZip64EndBytes) {
      const std::string locator = read(end_offset - kZip64LocatorBytes, kZip64LocatorBytes);
      if (little_endian(locator, 0, 4) == kZip64LocatorSignature) {
        const std::string zip64 = read(little_endian(locator, 8, 8), kZip64EndBytes);
        if (little_endian(zip64, 0, 4) == kZip64EndSignature) {
          entries = little_endian(zip64, 32, 8);
          directory = little_endian(zip64, 48, 8);
        }
      }
    }
    for (uint64_t i = 0; i < entries && directory < size_; ++i) directory = check_entry(directory);
  }

 private:
  std::string read(uint64_t offset, uint64_t bytes) {
    std::string data(size_t(std::min(bytes, size_ - std::min(offset, size_))), '\0');
    in_.clear();
    in_.seekg(std::streamoff(offset));
    in_.read(data.data(), std::streamsize(data.size()));
    data.resize(size_t(std::max<std::streamsize>(in_.gcount(), 0)));
    return data;
  }

  // Checks the entry at `offset`; returns where the next one starts.
  uint64_t check_entry(uint64_t offset) {
    const std::string entry = read(offset, kEntryBytes);
    if (little_endian(entry, 0, 4) != kEntrySignature) return size_;  // miniz refused it
    const uint64_t method = little_endian(entry, 10, 2);
    uint64_t uncompressed = little_endian(entry, 24, 4);
    const uint64_t name_bytes = little_endian(entry, 28, 2);
    const uint64_t extra_bytes = little_endian(entry, 30, 2);
    const uint64_t comment_bytes = little_endian(entry, 32, 2);
    const std::string name = read(offset + kEntryBytes, name_bytes);
    if (uncompressed == kZip64Marker)
      uncompressed = zip64_size(read(offset + kEntryBytes + name_bytes, extra_bytes));
    // Stored (as torch.save writes): at most the file; deflated: its
    // largest plausible expansion.
    const std::optional<uint64_t> expanded = checked_product({size_, kMaxCompressionRatio});
    const uint64_t most = method == 0 ? size_
                          : expanded  ? *expanded + kCompressedSlackBytes
                                      : UINT64_MAX;
    if (uncompressed > most)
      throw core::Error(path_, "corrupt zip archive: record " + name + " declares " +
                                   std::to_string(uncompressed) + " bytes, more than the file's " +
                                   std::to_string(size_) + " can hold");
    return offset + kEntryBytes + name_bytes + extra_bytes + comment_bytes;
  }

  // The uncompressed size of a zip64 extra field: its first 64-bit value
  // (when the 32-bit one is 0xFFFFFFFF, as the caller checked).
  static uint64_t zip64_size(const std::string& extra) {
    for (size_t at = 0; at + 4 <= extra.size(); at += 4 + little_endian(extra, at + 2, 2))
      if (little_endian(extra, at, 2) == kZip64ExtraField) return little_endian(extra, at + 4, 8);
    return kZip64Marker;
  }

  const fs::path& path_;
  std::ifstream in_;
  uint64_t size_;
};

}  // namespace

void check_zip_record_sizes(const fs::path& path) {
  CentralDirectory(path).check();
}

}  // namespace ddhgs::io::detail
