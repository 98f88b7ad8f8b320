// Reader inputs that once crashed a reader, overflowed its size arithmetic
// or made it allocate what a corrupt header claimed (tests/fuzz/regressions,
// written by tests/fuzz/make_regressions.py, plus any input the fuzzer
// finds): each is replayed through the fuzzer's own target, which aborts on
// anything but success or a core::Error. Under the sanitizer build
// (scripts/sanitize.sh) ASan and UBSan watch the replay.
#include <gtest/gtest.h>

#include <filesystem>

#include "fuzz/fuzz_target.h"
#include "io/files/atomic_file.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;

TEST(FuzzRegressions, EveryFoundInputIsRefusedCleanly) {
  const fs::path scratch = test::temp_dir("fuzz_regressions");
  int replayed = 0;
  for (const auto& entry : fs::directory_iterator(DDHGS_FUZZ_REGRESSIONS)) {
    if (!entry.is_regular_file()) continue;
    const std::string input = io::read_file(entry.path());
    SCOPED_TRACE(entry.path().filename().string());
    // Aborts the test binary on a defect (fuzz::run_input).
    fuzz::run_input(reinterpret_cast<const uint8_t*>(input.data()), input.size(), scratch);
    ++replayed;
  }
  EXPECT_GT(replayed, 0) << "no inputs in " << DDHGS_FUZZ_REGRESSIONS;
}

}  // namespace
}  // namespace ddhgs
