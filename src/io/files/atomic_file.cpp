#include "io/files/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <ios>

#include "core/error.h"
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

std::string errno_text() {
  return std::strerror(errno);
}

// Plain POSIX calls: their return codes report a full disk (ENOSPC at write or
// at fsync), which buffered streams would hide until destruction.
void write_parts(const fs::path& tmp, const fs::path& target,
                 std::initializer_list<std::string_view> parts) {
  int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw core::Error(target, "cannot create a file in its folder: " + errno_text());
  auto fail = [&](const std::string& what) {
    std::string reason = errno_text();
    ::close(fd);
    throw core::Error(target, what + ": " + reason);
  };
  for (std::string_view part : parts) {
    const char* p = part.data();
    size_t left = part.size();
    while (left > 0) {
      ssize_t n = ::write(fd, p, left);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) fail("write failed");
      p += n;
      left -= size_t(n);
    }
  }
  // Durable before the rename makes it visible: a crash must leave either the
  // old file or the complete new one.
  if (::fsync(fd) != 0) fail("write failed");
  if (::close(fd) != 0) throw core::Error(target, "write failed: " + errno_text());
}

}  // namespace

void write_atomically(const fs::path& path, const std::function<void(const fs::path& tmp)>& write) {
  if (path.empty() || path.filename().empty()) throw core::Error(path, "not a file name to write");
  std::error_code status_ec;
  fs::file_status status = fs::status(path, status_ec);
  // Renaming over a folder or a device (/dev/null) would destroy it.
  if (fs::exists(status) && !fs::is_regular_file(status))
    throw core::Error(path, "exists and is not a regular file; not replacing it");
  fs::path parent = path.parent_path();
  if (!parent.empty()) {
    std::error_code ec;
    fs::create_directories(parent, ec);
    if (ec || !fs::is_directory(parent))
      throw core::Error(path, "cannot create its folder " + parent.string() + ": " + ec.message());
  }
  remove_stale_temporaries_once(parent.empty() ? fs::path(".") : parent);
  fs::path tmp = temporary_sibling(path);
  auto remove_tmp = [&] {
    std::error_code ignored;
    fs::remove(tmp, ignored);
  };
  try {
    write(tmp);
  } catch (const core::Error&) {
    remove_tmp();
    throw;
  } catch (const std::ios_base::failure& e) {
    remove_tmp();
    throw core::Error(path, std::string("write failed: ") + e.what());
  } catch (const fs::filesystem_error& e) {
    remove_tmp();
    throw core::Error(path, std::string("write failed: ") + e.code().message());
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

void write_parts_atomically(const fs::path& path, std::initializer_list<std::string_view> parts) {
  write_atomically(path, [&](const fs::path& tmp) { write_parts(tmp, path, parts); });
}

void write_file_atomically(const fs::path& path, const std::string& bytes) {
  write_parts_atomically(path, {std::string_view(bytes)});
}

std::string read_file(const fs::path& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw core::Error(path, "file not found");
  if (fs::is_directory(path, ec)) throw core::Error(path, "is a folder, expected a file");
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
