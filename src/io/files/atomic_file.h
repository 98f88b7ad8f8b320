// Atomic writes: write a temporary sibling, then rename over the target, so
// an interrupted or failed write never leaves a half-written file.
#pragma once
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

namespace ddhgs::io {

// The folders create_folders made, innermost first, so that a failed write
// can take them away again (only while they are empty).
struct CreatedFolders {
  std::vector<std::filesystem::path> folders;
  void remove_if_empty() const;
};
// create_directories(folder), remembering which folders did not exist.
CreatedFolders create_folders(const std::filesystem::path& folder, std::error_code& ec);

// Calls write(tmp_path), then renames tmp_path to path. On any exception the
// temporary file is removed and the exception propagates (as core::Error
// naming path for I/O failures such as a full disk). Missing parent folders
// are created, and removed again when the write fails. Temporaries that dead processes left in the
// folder are removed first (io/files/stale_files.h).
void write_atomically(const std::filesystem::path& path,
                      const std::function<void(const std::filesystem::path& tmp)>& write);

// A temporary file written with plain POSIX calls, so that a full disk
// (ENOSPC at write or at fsync) is reported instead of being lost in a
// buffered stream's destructor. write() never throws: it can sit below a C
// callback (LibTorch's zip writer, which throws from its own destructor when
// a write comes up short and so ends the process). The first failure is kept
// and finish() throws it as core::Error naming the target.
class FileSink {
 public:
  FileSink(const std::filesystem::path& tmp, const std::filesystem::path& target);
  ~FileSink();
  FileSink(const FileSink&) = delete;
  FileSink& operator=(const FileSink&) = delete;

  // Always returns size; after a failure further bytes are dropped.
  size_t write(const void* data, size_t size) noexcept;
  // fsync and close; core::Error naming the target on any failure so far.
  void finish();

 private:
  [[noreturn]] void fail(const std::string& what, int error);
  std::filesystem::path target_;
  int fd_ = -1;
  int error_ = 0;  // errno of the first failed write
};

// write_atomically for writers that produce a byte stream.
void write_stream_atomically(const std::filesystem::path& path,
                             const std::function<void(FileSink& sink)>& write);

// Convenience: atomically write a whole text or binary buffer.
void write_file_atomically(const std::filesystem::path& path, const std::string& bytes);

// Atomically replaces `to` with a copy of the file `from`.
void copy_file_atomically(const std::filesystem::path& from, const std::filesystem::path& to);

// Atomically writes the concatenation of parts (e.g. a header and a view of
// tensor memory) without first joining them in memory.
void write_parts_atomically(const std::filesystem::path& path,
                            std::initializer_list<std::string_view> parts);

// strerror(error) as the middle of a sentence: "no space left on device".
std::string system_error_text(int error);

// Reads a whole file; core::Error naming it if missing or unreadable.
std::string read_file(const std::filesystem::path& path);

}  // namespace ddhgs::io
