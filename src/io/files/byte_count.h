// Sizes declared by a file's header, checked against the bytes the file
// actually holds before anything is allocated or read: a corrupt or hostile
// header can neither overflow the arithmetic nor make a reader run past its
// buffer or allocate terabytes.
#pragma once
#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <optional>
#include <string>

namespace ddhgs::io {

// The product of factors, or nullopt when it does not fit in 64 bits.
std::optional<uint64_t> checked_product(std::initializer_list<uint64_t> factors);

// Bytes of an array of dims x sample_bytes, required to be at most
// available bytes. Throws core::Error naming path and what ("the header",
// "page 3") when the product overflows or exceeds what the file holds.
uint64_t require_present(const std::filesystem::path& path, const std::string& what,
                         std::initializer_list<uint64_t> dims, uint64_t sample_bytes,
                         uint64_t available);

// Largest plausible expansion of compressed image data (deflate tops out near
// 1032:1, LZW near 2700:1, JPEG near 1400:1); a header that claims more
// samples than this times its file size describes data the file cannot hold.
constexpr uint64_t kMaxCompressionRatio = 4096;
// Slack for tiny files: headers and tables of a few kB may decode to this.
constexpr uint64_t kCompressedSlackBytes = 1 << 20;

// core::Error naming path unless decoded_bytes (nullopt: overflowed) could
// come from file_bytes of compressed data.
void require_decodable(const std::filesystem::path& path, std::optional<uint64_t> decoded_bytes,
                       uint64_t file_bytes);

}  // namespace ddhgs::io
