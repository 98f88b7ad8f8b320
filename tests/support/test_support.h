// Helpers shared by the test executables.
#pragma once
#include <filesystem>
#include <string>

namespace ddhgs::test {

// A fresh empty directory under the build tree's temp area, removed at exit.
std::filesystem::path temp_dir(const std::string& name);

// Runs a shell command, returns its exit code; output captured into *output.
int run_command(const std::string& command, std::string* output = nullptr);

// Path of the built ddhgs executable and of the source tree.
std::string ddhgs_binary();
std::filesystem::path source_dir();

// /usr/bin/python3 with numpy (Debian's), used for independent cross-checks.
std::string python();

}  // namespace ddhgs::test
