#include "io/files/folder_lock.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "core/error.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

std::string read_owner(int fd) {
  char buffer[256] = {};
  const ssize_t n = ::pread(fd, buffer, sizeof buffer - 1, 0);
  std::string owner = n > 0 ? std::string(buffer, size_t(n)) : std::string();
  while (!owner.empty() && (owner.back() == '\n' || owner.back() == ' ')) owner.pop_back();
  return owner.empty() ? "another ddhgs process" : owner;
}

}  // namespace

FolderLock::FolderLock(const fs::path& folder, const std::string& command) {
  const fs::path path = folder / kLockFile;
  // Never through a link: a lock file linked to someone else's file would
  // have that file truncated and rewritten below.
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW | O_NONBLOCK, 0644);
  if (fd_ < 0 && errno == ELOOP)
    throw core::Error(path, std::string("is a symbolic link; ddhgs never follows links for its "
                                        "lock file (remove the link)"));
  if (fd_ < 0 && errno == EISDIR) throw core::Error(path, "is not a regular file; remove it");
  if (fd_ < 0)
    throw core::Error(folder, std::string("cannot create its lock file: ") + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd_, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd_);
    fd_ = -1;
    throw core::Error(path, "is not a regular file; remove it");
  }
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    const std::string owner = read_owner(fd_);
    ::close(fd_);
    fd_ = -1;
    if (error == EWOULDBLOCK)
      throw core::Error(folder, "in use by " + owner + "; wait for it to finish or stop it");
    throw core::Error(folder, std::string("cannot lock: ") + std::strerror(error));
  }
  const std::string owner = "ddhgs " + command + " (pid " + std::to_string(::getpid()) + ")\n";
  if (::ftruncate(fd_, 0) == 0) {
    const ssize_t written = ::pwrite(fd_, owner.data(), owner.size(), 0);
    (void)written;  // the owner's name is for messages only
  }
}

FolderLock::~FolderLock() {
  release();
}

FolderLock::FolderLock(FolderLock&& other) noexcept : fd_(other.fd_) {
  other.fd_ = -1;
}

FolderLock& FolderLock::operator=(FolderLock&& other) noexcept {
  if (this != &other) {
    release();
    fd_ = other.fd_;
    other.fd_ = -1;
  }
  return *this;
}

void FolderLock::release() {
  if (fd_ < 0) return;
  ::close(fd_);  // closing the last descriptor releases the flock
  fd_ = -1;
}

}  // namespace ddhgs::io
