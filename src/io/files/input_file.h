// Input files: what a reader checks before it opens a path.
#pragma once
#include <filesystem>

namespace ddhgs::io {

// Throws core::Error naming path unless it is a regular file (or a symbolic
// link to one): "file not found", "is a folder, expected a file", or, for a
// FIFO, a socket or a device, what it is. Opening a FIFO for reading blocks
// until something writes to it, so every reader asks before it opens.
void require_regular_file(const std::filesystem::path& path);

}  // namespace ddhgs::io
