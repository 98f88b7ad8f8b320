// Atomic writes: write a temporary sibling, then rename over the target, so
// an interrupted or failed write never leaves a half-written file.
#pragma once
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <string>
#include <string_view>

namespace ddhgs::io {

// Calls write(tmp_path), then renames tmp_path to path. On any exception the
// temporary file is removed and the exception propagates (as core::Error
// naming path for I/O failures such as a full disk). Missing parent folders
// are created. Temporaries that dead processes left in the folder are
// removed first (io/files/stale_files.h).
void write_atomically(const std::filesystem::path& path,
                      const std::function<void(const std::filesystem::path& tmp)>& write);

// Convenience: atomically write a whole text or binary buffer.
void write_file_atomically(const std::filesystem::path& path, const std::string& bytes);

// Atomically writes the concatenation of parts (e.g. a header and a view of
// tensor memory) without first joining them in memory.
void write_parts_atomically(const std::filesystem::path& path,
                            std::initializer_list<std::string_view> parts);

// Reads a whole file; core::Error naming it if missing or unreadable.
std::string read_file(const std::filesystem::path& path);

}  // namespace ddhgs::io
