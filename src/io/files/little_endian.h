// Little-endian integers inside file bytes, for the readers' header checks.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string_view>

namespace ddhgs::io {

// The unsigned integer of `width` bytes (at most 8) stored little-endian at
// `at`; bytes past the end read as zero (callers check lengths themselves).
inline uint64_t little_endian(std::string_view bytes, size_t at, size_t width) {
  uint64_t value = 0;
  for (size_t i = 0; i < width && at + i < bytes.size(); ++i)
    value |= uint64_t(uint8_t(bytes[at + i])) << (8 * i);
  return value;
}

}  // namespace ddhgs::io
