// An advisory lock on a folder that a command writes into (a run folder), so
// that two ddhgs processes never write one folder at once. The lock is an
// flock() on FOLDER/.ddhgs-lock: the kernel releases it when its process
// ends, however it ends, so a crash never leaves a stale lock. The file
// records the owner's pid and command, for the message a second writer gets.
#pragma once
#include <filesystem>
#include <string>

namespace ddhgs::io {

constexpr const char* kLockFile = ".ddhgs-lock";

class FolderLock {
 public:
  FolderLock() = default;
  // Locks folder (which must exist) for `command` ("train", "eval", ...).
  // Throws core::Error naming the folder and the owner's pid and command
  // when another process holds the lock.
  FolderLock(const std::filesystem::path& folder, const std::string& command);
  ~FolderLock();
  FolderLock(FolderLock&& other) noexcept;
  FolderLock& operator=(FolderLock&& other) noexcept;
  FolderLock(const FolderLock&) = delete;
  FolderLock& operator=(const FolderLock&) = delete;

  bool held() const { return fd_ >= 0; }
  void release();

 private:
  int fd_ = -1;
};

}  // namespace ddhgs::io
