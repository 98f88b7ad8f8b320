// JPEG decoding through libjpeg-turbo (private to io/image). stb_image's
// JPEG decoder read out of bounds on corrupt Huffman data in ways a check in
// front of it could not foresee without decoding the scan itself (the
// fuzzer's finds, tests/fuzz/regressions/*jpeg*); libjpeg-turbo checks
// every code it decodes.
#pragma once
#include "core/tensor.h"

#include <filesystem>
#include <string>

namespace ddhgs::io::detail {

// True when bytes start with a JPEG start-of-image marker.
bool is_jpeg(const std::string& bytes);

struct JpegSize {
  int width = 0, height = 0, channels = 0;  // channels: 1 (grey) or 3 (RGB)
};

// The header's size; core::Error naming path when the header is unreadable,
// the colour space is CMYK/YCCK, or the size is more than the file's bytes
// could decode to (io/files/byte_count.h).
JpegSize read_jpeg_size(const std::filesystem::path& path, const std::string& bytes);

// uint8 [H, W, C], C = 1 or 3. Corrupt data is an error, also where libjpeg
// would only warn and fill the rest of the image with grey.
torch::Tensor decode_jpeg(const std::filesystem::path& path, const std::string& bytes);

}  // namespace ddhgs::io::detail
