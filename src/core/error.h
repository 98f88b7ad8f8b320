// User-facing errors: one line naming the file (or option) and what was expected.
#pragma once
#include <filesystem>
#include <stdexcept>
#include <string>

namespace ddhgs::core {

// Thrown for bad input. The CLI prints what() on one line and exits non-zero.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
  Error(const std::filesystem::path& file, const std::string& problem)
      : std::runtime_error(file.string() + ": " + problem) {}
};

inline void require(bool ok, const std::filesystem::path& file, const std::string& problem) {
  if (!ok) throw Error(file, problem);
}

inline void require(bool ok, const std::string& message) {
  if (!ok) throw Error(message);
}

// A library's message without its internal tag: nlohmann-json's
// "[json.exception.parse_error.101] parse error at line 1, column 13: ..."
// becomes "parse error at line 1, column 13: ...", and a filesystem error
// (the standard library's "filesystem error: cannot create directories: ...
// [path]") the path and the system's reason ("Permission denied").
inline std::string message_of(const std::exception& e) {
  if (const auto* fs_error = dynamic_cast<const std::filesystem::filesystem_error*>(&e)) {
    const std::string reason = fs_error->code().message();
    return fs_error->path1().empty() ? reason : fs_error->path1().string() + ": " + reason;
  }
  std::string text = e.what();
  if (text.rfind("[json.exception.", 0) == 0) {
    const size_t end = text.find("] ");
    if (end != std::string::npos) text = text.substr(end + 2);
  }
  return text;
}

}  // namespace ddhgs::core
