// Error-message helpers shared by the tests that check core::Error messages.
#pragma once
#include <string>

#include "core/error.h"

namespace ddhgs::test {

// The message of the core::Error that f throws, or "(no error)".
template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const core::Error& e) {
    return e.what();
  }
  return "(no error)";
}

inline bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

}  // namespace ddhgs::test
