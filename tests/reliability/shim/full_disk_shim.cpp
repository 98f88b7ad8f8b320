// A full disk without filling one: preloaded into a ddhgs process by the
// reliability tests (LD_PRELOAD), it makes writes to files below one folder
// fail with ENOSPC once a byte budget is spent, as a filesystem out of space
// does. Nothing outside that folder is affected, and no real disk fills.
//   DDHGS_FULL_DISK_DIR    absolute folder whose files are on the "full disk"
//   DDHGS_FULL_DISK_BYTES  bytes that still fit there (default 0)
//   DDHGS_FULL_DISK_MATCH  only files whose name contains this (default: all)
#include <dlfcn.h>
#include <fcntl.h>
#include <sys/sendfile.h>
#include <sys/uio.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

namespace {

template <typename F>
F real(const char* name) {
  return reinterpret_cast<F>(dlsym(RTLD_NEXT, name));
}

// Bytes left on the pretend disk; shared by all threads of the process.
std::atomic<long long>& budget() {
  static std::atomic<long long> left{[] {
    const char* bytes = std::getenv("DDHGS_FULL_DISK_BYTES");
    return bytes ? std::atoll(bytes) : 0LL;
  }()};
  return left;
}

bool on_full_disk(int fd) {
  const char* dir = std::getenv("DDHGS_FULL_DISK_DIR");
  if (!dir || !*dir) return false;
  char link[64], target[4096];
  std::snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
  ssize_t n = readlink(link, target, sizeof target - 1);
  if (n <= 0) return false;
  target[n] = '\0';
  const size_t dir_len = std::strlen(dir);
  if (std::strncmp(target, dir, dir_len) != 0 || target[dir_len] != '/') return false;
  const char* match = std::getenv("DDHGS_FULL_DISK_MATCH");
  const char* name = std::strrchr(target, '/') + 1;
  return !match || !*match || std::strstr(name, match) != nullptr;
}

// How many of `wanted` bytes fit; -1 with errno ENOSPC when none does.
ssize_t allowance(int fd, size_t wanted) {
  if (wanted == 0 || !on_full_disk(fd)) return ssize_t(wanted);
  long long left = budget().load();
  while (true) {
    if (left <= 0) {
      errno = ENOSPC;
      return -1;
    }
    long long take = std::min<long long>(left, (long long)wanted);
    if (budget().compare_exchange_weak(left, left - take)) return ssize_t(take);
  }
}

}  // namespace

extern "C" {

ssize_t write(int fd, const void* buf, size_t count) {
  static auto next = real<ssize_t (*)(int, const void*, size_t)>("write");
  ssize_t allowed = allowance(fd, count);
  return allowed < 0 ? -1 : next(fd, buf, size_t(allowed));
}

ssize_t pwrite(int fd, const void* buf, size_t count, off_t offset) {
  static auto next = real<ssize_t (*)(int, const void*, size_t, off_t)>("pwrite");
  ssize_t allowed = allowance(fd, count);
  return allowed < 0 ? -1 : next(fd, buf, size_t(allowed), offset);
}

ssize_t pwrite64(int fd, const void* buf, size_t count, off64_t offset) {
  static auto next = real<ssize_t (*)(int, const void*, size_t, off64_t)>("pwrite64");
  ssize_t allowed = allowance(fd, count);
  return allowed < 0 ? -1 : next(fd, buf, size_t(allowed), offset);
}

// libstdc++'s file streams write through writev; a short budget writes the
// leading buffers, as the kernel would.
ssize_t writev(int fd, const struct iovec* iov, int iovcnt) {
  static auto next = real<ssize_t (*)(int, const struct iovec*, int)>("writev");
  size_t total = 0;
  for (int i = 0; i < iovcnt; ++i) total += iov[i].iov_len;
  ssize_t allowed = allowance(fd, total);
  if (allowed < 0) return -1;
  if (size_t(allowed) == total) return next(fd, iov, iovcnt);
  static auto plain = real<ssize_t (*)(int, const void*, size_t)>("write");
  ssize_t done = 0;
  for (int i = 0; i < iovcnt && done < allowed; ++i) {
    size_t n = std::min(iov[i].iov_len, size_t(allowed - done));
    ssize_t wrote = plain(fd, iov[i].iov_base, n);
    if (wrote < 0) return done > 0 ? done : -1;
    done += wrote;
  }
  return done;
}

// std::filesystem::copy_file copies with sendfile (or copy_file_range).
ssize_t sendfile(int out_fd, int in_fd, off_t* offset, size_t count) {
  static auto next = real<ssize_t (*)(int, int, off_t*, size_t)>("sendfile");
  ssize_t allowed = allowance(out_fd, count);
  return allowed < 0 ? -1 : next(out_fd, in_fd, offset, size_t(allowed));
}

ssize_t sendfile64(int out_fd, int in_fd, off64_t* offset, size_t count) {
  static auto next = real<ssize_t (*)(int, int, off64_t*, size_t)>("sendfile64");
  ssize_t allowed = allowance(out_fd, count);
  return allowed < 0 ? -1 : next(out_fd, in_fd, offset, size_t(allowed));
}

ssize_t copy_file_range(int in_fd, off64_t* in_off, int out_fd, off64_t* out_off, size_t len,
                        unsigned int flags) {
  static auto next =
      real<ssize_t (*)(int, off64_t*, int, off64_t*, size_t, unsigned int)>("copy_file_range");
  ssize_t allowed = allowance(out_fd, len);
  return allowed < 0 ? -1 : next(in_fd, in_off, out_fd, out_off, size_t(allowed), flags);
}

}  // extern "C"
