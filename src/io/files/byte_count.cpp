#include "io/files/byte_count.h"

#include "core/error.h"

namespace ddhgs::io {

std::optional<uint64_t> checked_product(std::initializer_list<uint64_t> factors) {
  uint64_t product = 1;
  for (uint64_t factor : factors)
    if (__builtin_mul_overflow(product, factor, &product)) return std::nullopt;
  return product;
}

uint64_t require_present(const std::filesystem::path& path, const std::string& what,
                         std::initializer_list<uint64_t> dims, uint64_t sample_bytes,
                         uint64_t available) {
  std::string shape;
  for (uint64_t dim : dims) shape += (shape.empty() ? "" : " x ") + std::to_string(dim);
  std::optional<uint64_t> bytes = checked_product(dims);
  if (bytes) bytes = checked_product({*bytes, sample_bytes});
  if (!bytes)
    throw core::Error(path, what + " declares " + shape + " samples, more than any file can hold");
  if (*bytes > available)
    throw core::Error(path, "truncated: " + what + " declares " + shape + " samples (" +
                                std::to_string(*bytes) + " bytes), the file holds " +
                                std::to_string(available));
  return *bytes;
}

void require_decodable(const std::filesystem::path& path, std::optional<uint64_t> decoded_bytes,
                       uint64_t file_bytes) {
  std::optional<uint64_t> limit = checked_product({file_bytes, kMaxCompressionRatio});
  const uint64_t most = limit ? *limit + kCompressedSlackBytes : UINT64_MAX;
  if (!decoded_bytes || *decoded_bytes > most)
    throw core::Error(path, "its header declares " +
                                (decoded_bytes ? std::to_string(*decoded_bytes) : "over 2^64") +
                                " bytes of samples, more than its " + std::to_string(file_bytes) +
                                " bytes can hold (corrupt header?)");
}

}  // namespace ddhgs::io
