// The guards in front of stb_image's decoders (private to io/image).
#pragma once
#include <filesystem>
#include <string>

namespace ddhgs::io::detail {

// stb_image (v2.27) trusts two things a file declares (both found by the
// fuzzer, tests/fuzz): a JPEG Huffman table listing more than 256 codes
// makes it write past a fixed array, and a PNG IDAT chunk's length is
// allocated before the chunk is read (2 GB from a 100-byte file). Walks the
// file the way stb does and throws core::Error naming `path` on either.
// Where stb would stop on malformed input the walk may go on: it checks
// more than stb reads, never less. Other files pass untouched.
// bytes: the whole file.
void check_before_stb(const std::filesystem::path& path, const std::string& bytes);

}  // namespace ddhgs::io::detail
