// Small helpers shared by the cube and image reader tests.
#pragma once
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <string>

#include "core/error.h"
#include "support/test_support.h"

namespace ddhgs::test {

inline std::string read_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

inline void write_bytes(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

// Expects fn to throw core::Error whose one-line message names the file and
// contains the given problem text.
inline void expect_error_naming(const std::function<void()>& fn, const std::string& file,
                                const std::string& problem) {
  try {
    fn();
    ADD_FAILURE() << "no core::Error for " << file << " (" << problem << ")";
  } catch (const core::Error& e) {
    std::string message = e.what();
    EXPECT_NE(message.find(file), std::string::npos) << message;
    EXPECT_NE(message.find(problem), std::string::npos) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
}

// Whether /usr/bin/python3 can import the module (numpy, torch).
// Cached: importing torch takes seconds.
inline bool python_has(const std::string& module) {
  static std::map<std::string, bool> known;
  auto it = known.find(module);
  if (it == known.end())
    it = known.emplace(module, run_command(python() + " -c 'import " + module + "'") == 0).first;
  return it->second;
}

}  // namespace ddhgs::test
