#include "io/files/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <ios>

#include "core/error.h"
#include "io/files/input_file.h"
#include "io/files/stale_files.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

// Unique per process and call, so concurrent writers of one target (two
// threads saving previews) never share a temporary file.
fs::path temporary_sibling(const fs::path& path) {
  static std::atomic<unsigned> counter{0};
  std::string name = "." + path.filename().string() + ".tmp-" + std::to_string(::getpid()) + "-" +
                     std::to_string(counter++);
  return path.parent_path() / name;
}

}  // namespace

std::string system_error_text(int error) {
  std::string text = std::strerror(error);
  if (!text.empty()) text[0] = char(std::tolower(static_cast<unsigned char>(text[0])));
  return text;
}

CreatedFolders create_folders(const fs::path& folder, std::error_code& ec) {
  CreatedFolders created;
  for (fs::path p = folder; !p.empty() && !fs::exists(fs::symlink_status(p, ec));
       p = p.parent_path()) {
    created.folders.push_back(p);  // innermost first
    if (p == p.parent_path()) break;
  }
  ec.clear();
  fs::create_directories(folder, ec);
  if (ec) created.folders.clear();
  return created;
}

void CreatedFolders::remove_if_empty() const {
  std::error_code ignored;
  for (const fs::path& p : folders) fs::remove(p, ignored);  // remove() refuses a non-empty folder
}

void write_atomically(const fs::path& path, const std::function<void(const fs::path& tmp)>& write) {
  if (path.empty() || path.filename().empty()) throw core::Error(path, "not a file name to write");
  std::error_code status_ec;
  fs::file_status status = fs::status(path, status_ec);
  // Renaming over a folder or a device (/dev/null) would destroy it.
  if (fs::exists(status) && !fs::is_regular_file(status))
    throw core::Error(path, "exists and is not a regular file; not replacing it");
  fs::path parent = path.parent_path();
  CreatedFolders created;
  if (!parent.empty()) {
    std::error_code ec;
    created = create_folders(parent, ec);
    if (ec || !fs::is_directory(parent))
      throw core::Error(path, "cannot create its folder " + parent.string() + ": " + ec.message());
  }
  remove_stale_temporaries_once(parent.empty() ? fs::path(".") : parent);
  fs::path tmp = temporary_sibling(path);
  // A failed write leaves nothing: no temporary, and no folder made for it
  // (an empty RUN/export/ after a full disk).
  auto remove_tmp = [&] {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    created.remove_if_empty();
  };
  try {
    write(tmp);
  } catch (const core::Error&) {
    remove_tmp();
    throw;
  } catch (const std::ios_base::failure&) {
    const int error = errno;  // the stream's own text is "basic_ios::clear: iostream error"
    remove_tmp();
    throw core::Error(path, "write failed: " + system_error_text(error));
  } catch (const fs::filesystem_error& e) {
    remove_tmp();
    throw core::Error(path, "write failed: " + system_error_text(e.code().value()));
  } catch (...) {
    remove_tmp();
    throw;
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    remove_tmp();
    throw core::Error(path, "cannot replace the file: " + ec.message());
  }
}

FileSink::FileSink(const fs::path& tmp, const fs::path& target) : target_(target) {
  fd_ = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) fail("cannot create a file in its folder", errno);
}

FileSink::~FileSink() {
  if (fd_ >= 0) ::close(fd_);
}

size_t FileSink::write(const void* data, size_t size) noexcept {
  const char* p = static_cast<const char*>(data);
  size_t left = size;
  while (left > 0 && error_ == 0) {
    ssize_t n = ::write(fd_, p, left);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) error_ = errno;
    if (n == 0) error_ = ENOSPC;  // no progress: what a full disk does to regular files
    if (n > 0) p += n, left -= size_t(n);
  }
  return size;
}

void FileSink::finish() {
  if (error_ != 0) fail("write failed", error_);
  // Durable before the rename makes it visible: a crash must leave either the
  // old file or the complete new one.
  if (::fsync(fd_) != 0) fail("write failed", errno);
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) fail("write failed", errno);
}

void FileSink::fail(const std::string& what, int error) {
  throw core::Error(target_, what + ": " + system_error_text(error));
}

void write_stream_atomically(const fs::path& path, const std::function<void(FileSink&)>& write) {
  write_atomically(path, [&](const fs::path& tmp) {
    FileSink sink(tmp, path);
    write(sink);
    sink.finish();
  });
}

void write_parts_atomically(const fs::path& path, std::initializer_list<std::string_view> parts) {
  write_stream_atomically(path, [&](FileSink& sink) {
    for (std::string_view part : parts) sink.write(part.data(), part.size());
  });
}

void write_file_atomically(const fs::path& path, const std::string& bytes) {
  write_parts_atomically(path, {std::string_view(bytes)});
}

void copy_file_atomically(const fs::path& from, const fs::path& to) {
  write_atomically(to, [&](const fs::path& tmp) {
    fs::copy_file(from, tmp, fs::copy_options::overwrite_existing);
  });
}

std::string read_file(const fs::path& path) {
  require_regular_file(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw core::Error(path, "cannot open the file for reading");
  std::string bytes;
  in.seekg(0, std::ios::end);
  std::streamoff size = in.tellg();
  if (size < 0) throw core::Error(path, "cannot read the file size");
  bytes.resize(size_t(size));
  in.seekg(0);
  if (!in.read(bytes.data(), size)) throw core::Error(path, "read failed");
  return bytes;
}

}  // namespace ddhgs::io
