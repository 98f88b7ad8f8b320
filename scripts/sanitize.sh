#!/usr/bin/env bash
# The readers' memory-safety check, a step of scripts/test.sh (CI) after
# ctest: builds the core and io layers, test_io and the reader fuzzer with
# clang, AddressSanitizer and UndefinedBehaviorSanitizer (CMake option
# DDHGS_SANITIZE) in a build folder of their own, runs test_io (which replays
# tests/fuzz/regressions/), replays those inputs again under the fuzzer's
# memory limits, then fuzzes every reader for a bounded time. Exit
# status is non-zero on any sanitizer report or test failure in test_io, and
# on a fuzzer crash (FUZZ_STRICT=0: reported only); a crashing input is left in
# $SANITIZE_BUILD_DIR/fuzz-artifacts/ and printed in base64 (add it to
# tests/fuzz/regressions/). Run time: docs/reliability.md.
# Installs clang and its sanitizer runtimes when missing (as root, or through
# sudo); everything else it builds against is what scripts/setup.sh installs.
# Environment: SANITIZE_BUILD_DIR (default build-sanitize), FUZZ_SECONDS
# (cap, default 300), FUZZ_RUNS (inputs, default 300000), FUZZ_SEED (default
# 1; 0: random), FUZZ_STRICT (default 1: a fuzzer find fails the step; 0:
# reported with its input), SANITIZE_JOBS (parallel compiles, default: all
# cores). Sanitizer reports in test_io always fail it.
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=lib/packages.sh
source scripts/lib/packages.sh

# clang only recommends its sanitizer and libFuzzer runtimes
# (libclang-rt-14-dev), which apt-get --no-install-recommends leaves out;
# libomp-14-dev is OpenMP for clang; llvm-14 symbolizes the stack traces.
packages=(clang libclang-rt-14-dev libomp-14-dev llvm-14)
ensure_packages sanitize "${packages[@]}"
export PATH="/usr/lib/llvm-14/bin:$PATH"

build_dir="${SANITIZE_BUILD_DIR:-build-sanitize}"
fuzz_seconds="${FUZZ_SECONDS:-300}"
# A fixed number of inputs from a fixed seed bounds the run's work on any
# machine speed (FUZZ_SECONDS only caps a slow one). It does not make runs
# identical across machines (see below); FUZZ_SEED=0 lets libFuzzer pick.
fuzz_runs="${FUZZ_RUNS:-300000}"
fuzz_seed="${FUZZ_SEED:-1}"
start=$SECONDS
if [ ! -f "$build_dir/build.ninja" ]; then
  mkdir -p "$build_dir"
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
# test_io replays the found inputs without a memory limit, where a reader
# that allocates what a corrupt header declares still passes (4 GB are only
# reserved); the fuzzer replays them once more under the limits it fuzzes with.
replay_log="$build_dir/replay.log"
if ! DDHGS_THREADS=1 "$build_dir/tests/fuzz_readers" -rss_limit_mb=2048 -malloc_limit_mb=1024 \
  tests/fuzz/regressions/* >"$replay_log" 2>&1; then
  grep -m1 '^Running: ' <(tac "$replay_log") >&2 || true
  tail -40 "$replay_log" >&2
  echo "sanitize: a found input (tests/fuzz/regressions) exhausts or breaks a reader" >&2
  exit 1
fi
rm -f "$replay_log"
tested=$SECONDS

corpus="$build_dir/fuzz-corpus"
artifacts="$build_dir/fuzz-artifacts"
rm -rf "$corpus/seeds"
mkdir -p "$corpus/found" "$artifacts"
touch "$build_dir/fuzz.start"
"$build_dir/tests/fuzz_seeds" "$corpus/seeds"
# rss/malloc limits: a reader that trusts a corrupt size and allocates
# gigabytes is a defect too. One reader thread: with two, which code runs
# (the coverage that steers the mutations) varied between runs, so the same
# seed took different paths on different machines. From a fresh clone (empty
# corpus/found) the run is then the same one here and in CI.
DDHGS_THREADS=1 "$build_dir/tests/fuzz_readers" -seed="$fuzz_seed" -runs="$fuzz_runs" -max_total_time="$fuzz_seconds" -timeout=20 -rss_limit_mb=2048 \
  -malloc_limit_mb=1024 -max_len=16384 -print_final_stats=1 -artifact_prefix="$artifacts/" \
  "$corpus/found" "$corpus/seeds" 2>"$build_dir/fuzz.log" || {
  grep -m1 '^INFO: Seed:' "$build_dir/fuzz.log" >&2 || true
  tail -60 "$build_dir/fuzz.log" >&2
  # The CI machine is gone after the run: its log alone must carry the input.
  find "$artifacts" -type f -newer "$build_dir/fuzz.start" | while read -r input; do
    echo "sanitize: $(basename "$input") (base64):" >&2
    base64 "$input" >&2
  done
  echo "sanitize: the reader fuzzer found a defect (inputs in $artifacts)" >&2
  [ "${FUZZ_STRICT:-1}" = 1 ] && exit 1
  echo "sanitize: WARNING: fuzzer find reported above, not failing (FUZZ_STRICT=0)" >&2
  exit 0
}
executed=$(sed -n 's/^stat::number_of_executed_units: *//p' "$build_dir/fuzz.log")
peak_rss=$(sed -n 's/^stat::peak_rss_mb: *//p' "$build_dir/fuzz.log")
echo "sanitize: test_io passed under ASan+UBSan; the fuzzer ran ${executed:-?} inputs in" \
  "$((SECONDS - tested)) s (peak ${peak_rss:-?} MB) with no crash"
echo "sanitize: build $((built - start)) s, test_io $((tested - built)) s, fuzzing $((SECONDS - tested)) s"
