// Spectral response functions as CSV: a header row "wavelength_nm,NAME,..."
// then one row per sample wavelength (increasing), a response (>= 0) per
// channel. Lines starting with '#' are comments. Examples in
// examples/responses/.
#pragma once
#include <filesystem>

#include "core/band_map.h"

namespace ddhgs::io {

// Throws core::Error naming the file and the line on anything else.
core::ResponseFunctions read_response_csv(const std::filesystem::path& path);

}  // namespace ddhgs::io
