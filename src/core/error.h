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

}  // namespace ddhgs::core
