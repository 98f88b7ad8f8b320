// libFuzzer's entry points over every reader (tests/fuzz/fuzz_target.h). Run
// by scripts/sanitize.sh for a bounded time from the corpus fuzz_seeds writes:
//   fuzz_readers -max_total_time=60 CORPUS SEEDS
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>

#include "fuzz/fuzz_target.h"

namespace {

std::filesystem::path& scratch() {
  static std::filesystem::path dir;
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  // Readers warn on stderr about odd but readable files; at thousands of
  // inputs a second that drowns the fuzzer's own report.
  std::cerr.rdbuf(nullptr);
  // A RAM-backed folder where there is one: every input is written to a file.
  const std::filesystem::path base =
      access("/dev/shm", W_OK) == 0 ? "/dev/shm" : std::filesystem::temp_directory_path();
  // A name of fixed length: the readers' path handling (string copies and
  // their allocations) then takes the same branches in every run, so one
  // seed gives one run.
  char name[32];
  std::snprintf(name, sizeof name, "ddhgs-fuzz-%010d", int(getpid()));
  scratch() = base / name;
  std::filesystem::create_directories(scratch());
  // libFuzzer exits through exit() when its time is up; a crash keeps the
  // folder and the input in it.
  std::atexit([] {
    std::error_code ignored;
    std::filesystem::remove_all(scratch(), ignored);
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ddhgs::fuzz::run_input(data, size, scratch());
  return 0;
}
