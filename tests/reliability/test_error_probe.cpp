// Every error a user can cause names the file or flag and the problem:
// tests/reliability/probe_errors.py feeds ddhgs about 150
// malformed inputs and lists each error line that names neither, or that
// carries a library's raw text. It found about 40 such lines at first.
#include <gtest/gtest.h>

#include "cli_support.h"

namespace ddhgs {
namespace {

TEST(ErrorProbe, EveryErrorNamesTheFileOrFlag) {
  if (test::run_command(test::python() + " -c 'import json'") != 0) GTEST_SKIP() << "no python3";
  const auto work = test::temp_dir("error_probe");
  std::string out;
  const int rc = test::run_command(
      test::python() + " " + (test::source_dir() / "tests/reliability/probe_errors.py").string() +
          " " + test::ddhgs_binary() + " " + work.string(),
      &out);
  EXPECT_EQ(rc, 0) << out;
}

}  // namespace
}  // namespace ddhgs
