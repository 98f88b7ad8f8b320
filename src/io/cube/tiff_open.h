// Opening a TIFF with libtiff without its messages on stderr: errors are
// kept for the one-line core::Error that names the file, warnings dropped.
#pragma once
#include <tiffio.h>

#include <filesystem>
#include <string>

namespace ddhgs::io {

// TIFFOpenExt(path, mode) whose error messages go to *error (the last one
// wins; *error must outlive the handle). Null when libtiff cannot open it.
TIFF* open_tiff_quietly(const std::filesystem::path& path, const char* mode, std::string* error);

}  // namespace ddhgs::io
