#include "io/files/stale_files.h"

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <mutex>
#include <set>
#include <vector>

#include "core/log.h"
#include "io/files/output_folder.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

// Digits only, at least one; the value, or nullopt.
std::optional<long> parse_pid(const std::string& text) {
  if (text.empty() || text.size() > 9) return std::nullopt;
  for (char c : text)
    if (c < '0' || c > '9') return std::nullopt;
  return std::stol(text);
}

bool running(long pid) {
  return ::kill(pid_t(pid), 0) == 0 || errno == EPERM;
}

}  // namespace

std::optional<TemporaryName> parse_temporary_name(const std::string& name) {
  if (name.size() < 3 || name[0] != '.') return std::nullopt;
  for (const std::string tag : {".tmp-", ".old-"}) {
    const size_t at = name.rfind(tag);
    if (at == std::string::npos || at == 0) continue;
    std::string rest = name.substr(at + tag.size());
    // ".NAME.tmp-PID-N" (files) or ".NAME.tmp-PID" / ".NAME.old-PID" (folders).
    TemporaryName parsed;
    const size_t dash = rest.find('-');
    if (dash != std::string::npos) {
      if (tag != ".tmp-" || !parse_pid(rest.substr(dash + 1))) continue;
      rest = rest.substr(0, dash);
      parsed.is_file = true;
    }
    if (auto pid = parse_pid(rest)) {
      parsed.owner = *pid;
      return parsed;
    }
  }
  return std::nullopt;
}

void remove_stale_temporaries_once(const fs::path& folder) {
  static std::mutex mutex;
  static std::set<std::string> scanned;
  {
    std::lock_guard<std::mutex> lock(mutex);
    if (!scanned.insert(fs::absolute(folder).lexically_normal().string()).second) return;
  }
  remove_stale_temporaries(folder);
}

namespace {

// True when the folder holds nothing but an output marker (a temporary
// output whose build had not written anything yet).
bool empty_but_marker(const fs::path& folder) {
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(folder, ec))
    if (entry.path().filename() != kOutputMarker) return false;
  return !ec;
}

}  // namespace

void remove_stale_temporaries(const fs::path& folder) {
  std::error_code ec;
  // A folder that is itself a ddhgs output is ddhgs's to tidy; anywhere else
  // (beside an output, in the user's folders) a name alone proves nothing.
  const bool ours = output_kind(folder).has_value();
  std::vector<std::string> left;
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    const auto name = parse_temporary_name(entry.path().filename().string());
    if (!name || name->owner == long(::getpid()) || running(name->owner)) continue;
    std::error_code ignored;
    if (entry.is_symlink(ignored)) continue;
    if (!name->is_file && entry.is_directory(ignored)) {
      if (fs::is_empty(entry.path(), ignored) || empty_but_marker(entry.path()))
        fs::remove_all(entry.path(), ignored);
      else
        left.push_back(entry.path().filename().string());
    } else if (name->is_file && entry.is_regular_file(ignored)) {
      if (ours)
        fs::remove(entry.path(), ignored);
      else
        left.push_back(entry.path().filename().string());
    }
  }
  if (left.empty()) return;
  std::sort(left.begin(), left.end());
  core::log_warn(folder.string() + ": left alone, named like temporaries of a ddhgs process " +
                 "that is gone: " + core::format_names(left) +
                 " (delete them if they are not yours)");
}

}  // namespace ddhgs::io
