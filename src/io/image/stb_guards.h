// The guards in front of stb_image's decoders (private to io/image).
#pragma once
#include <filesystem>
#include <string>

namespace ddhgs::io::detail {

// stb_image (v2.27) allocates a PNG IDAT chunk's declared length before
// reading the chunk (2 GB from a 100-byte file: found by the fuzzer,
// tests/fuzz). Walks the chunks the way stb does and throws core::Error
// naming `path` on a chunk longer than the file. Where stb would stop on
// malformed input the walk may go on: it checks more than stb reads, never
// less. Other files pass untouched. (JPEG no longer goes to stb: jpeg.h.)
// bytes: the whole file.
void check_before_stb(const std::filesystem::path& path, const std::string& bytes);

}  // namespace ddhgs::io::detail
