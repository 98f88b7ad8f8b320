#!/usr/bin/env bash
# The readers' memory-safety check, apart from scripts/test.sh (its build of
# the core and io layers again is too long for CI's time budget; see
# docs/reliability.md): builds the core and io layers, test_io and the reader
# fuzzer with clang, AddressSanitizer and UndefinedBehaviorSanitizer (CMake
# option DDHGS_SANITIZE), runs test_io, then fuzzes every reader for a
# bounded time. Exit status is non-zero on any
# sanitizer report, test failure or fuzzer crash; a crashing input is left in
# $SANITIZE_BUILD_DIR/fuzz-artifacts/ (add it to tests/fuzz/regressions/).
# Environment: SANITIZE_BUILD_DIR (default build-sanitize), FUZZ_SECONDS (90),
# SANITIZE_JOBS (parallel compiles, default: all cores).
set -euo pipefail
cd "$(dirname "$0")/.."

build_dir="${SANITIZE_BUILD_DIR:-build-sanitize}"
if ! command -v clang++ >/dev/null; then
  echo "sanitize: needs clang++ with its sanitizer runtimes:" \
    "apt-get install clang libclang-rt-14-dev libomp-14-dev" >&2
  exit 1
fi
fuzz_seconds="${FUZZ_SECONDS:-90}"
start=$SECONDS
if [ ! -f "$build_dir/build.ninja" ]; then
  CC=clang CXX=clang++ cmake -S . -B "$build_dir" -G Ninja -DDDHGS_SANITIZE=ON \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo -DDDHGS_BUILD_BENCH=OFF >"$build_dir.cmake.log" 2>&1 || {
    echo "sanitize: cmake configuration failed (log: $build_dir.cmake.log)" >&2
    tail -20 "$build_dir.cmake.log" >&2
    exit 1
  }
  rm -f "$build_dir.cmake.log"
fi
build_log="$build_dir.build.log"
if ! ninja -C "$build_dir" -j "${SANITIZE_JOBS:-$(nproc)}" --quiet test_io fuzz_readers fuzz_seeds >"$build_log" 2>&1; then
  cat "$build_log" >&2
  echo "sanitize: build failed (log: $build_log)" >&2
  exit 1
fi
rm -f "$build_log"
built=$SECONDS

# LibTorch keeps allocations until exit by design: leak reports would be its own.
export ASAN_OPTIONS="detect_leaks=0:abort_on_error=1:allocator_may_return_null=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
export DDHGS_THREADS=2
"$build_dir/tests/test_io" --gtest_brief=1
tested=$SECONDS

corpus="$build_dir/fuzz-corpus"
artifacts="$build_dir/fuzz-artifacts"
rm -rf "$corpus/seeds"
mkdir -p "$corpus/found" "$artifacts"
"$build_dir/tests/fuzz_seeds" "$corpus/seeds"
# rss/malloc limits: a reader that trusts a corrupt size and allocates
# gigabytes is a defect too.
"$build_dir/tests/fuzz_readers" -max_total_time="$fuzz_seconds" -timeout=20 -rss_limit_mb=2048 \
  -malloc_limit_mb=1024 -max_len=16384 -print_final_stats=1 -artifact_prefix="$artifacts/" \
  "$corpus/found" "$corpus/seeds" 2>"$build_dir/fuzz.log" || {
  tail -60 "$build_dir/fuzz.log" >&2
  echo "sanitize: the reader fuzzer found a defect (inputs in $artifacts)" >&2
  exit 1
}
grep -E "^stat::number_of_executed_units|^stat::peak_rss_mb" "$build_dir/fuzz.log" | tr '\n' ' '
echo
echo "sanitize: build $((built - start)) s, test_io $((tested - built)) s, fuzzing $((SECONDS - tested)) s"
