#!/usr/bin/env bash
# Sets up (packages + build of everything, warnings as errors), checks the
# formatting of the tree, runs the whole test suite, then the readers under
# AddressSanitizer/UBSan and their fuzzer (scripts/sanitize.sh, about 5
# minutes of the total; docs/reliability.md). Exit status is non-zero on any
# failure, on any sanitizer report in the readers' tests, and on any skipped
# test that tests/expected_skips.txt does not list, and on a fuzzer find
# (printed with its input; FUZZ_STRICT=0 only reports it). Arguments go to
# ctest.
# Environment: BUILD_DIR (default build; the sanitizer build goes to
# BUILD_DIR-sanitize), DDHGS_SKIP_SANITIZE=1 leaves out the sanitizer and
# fuzzing step (for quick local runs; CI never sets it), and the variables
# of scripts/sanitize.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
start=$SECONDS
scripts/setup.sh --with-tests
set_up=$SECONDS
build_dir="${BUILD_DIR:-build}"

# Formatting: every C++ file of the tree, as .clang-format says.
mapfile -t sources < <(git ls-files '*.cpp' '*.h' 2>/dev/null || find src tests bench -name '*.cpp' -o -name '*.h')
if ! clang-format --dry-run --Werror "${sources[@]}" 2>"$build_dir.format.log"; then
  head -40 "$build_dir.format.log" >&2
  echo "test: files are not clang-formatted (run clang-format -i on them; log: $build_dir.format.log)" >&2
  exit 1
fi
rm -f "$build_dir.format.log"

log="$build_dir.ctest.log"
status=0
ctest --test-dir "$build_dir" --output-on-failure -j "$(nproc)" "$@" 2>&1 | tee "$log" || status=$?
[ "$status" = 0 ] || exit "$status"
tested=$SECONDS

# A skipped test is a check that did not run: only the declared ones may
# skip. ctest runs a GoogleTest suite per test (tests/gtest_suites.cmake) and
# shows a suite with any skipped test as "Skipped", even when another test
# of it failed; so the tests' own lines in ctest's full log decide.
last_log="$build_dir/Testing/Temporary/LastTest.log"
if grep -q '^\[  FAILED  \] [^ ]*\.' "$last_log"; then
  grep '^\[  FAILED  \] [^ ]*\.' "$last_log" | sort -u >&2
  echo "test: a test failed inside a suite that ctest counted as skipped (log: $last_log)" >&2
  exit 1
fi
mapfile -t skipped < <(sed -n 's/^\[  SKIPPED \] \([^ ]*\.[^ ]*\).*/\1/p' "$last_log" | sort -u)
unexpected=()
for name in "${skipped[@]}"; do
  grep -qxF "$name" tests/expected_skips.txt 2>/dev/null || unexpected+=("$name")
done
if [ "${#unexpected[@]}" -gt 0 ]; then
  echo "test: ${#unexpected[@]} test(s) skipped that tests/expected_skips.txt does not list: ${unexpected[*]}" >&2
  exit 1
fi

# After ctest, so that a failing test is reported first.
if [ "${DDHGS_SKIP_SANITIZE:-0}" = 1 ]; then
  echo "test: sanitizer and fuzzing step skipped (DDHGS_SKIP_SANITIZE=1)"
else
  SANITIZE_BUILD_DIR="${SANITIZE_BUILD_DIR:-$build_dir-sanitize}" scripts/sanitize.sh
fi
# CI reads the closing lines: ctest's result again, after the sanitizer's,
# and where the time went (CI has a time limit).
grep -E '^[0-9]+% tests passed|^Total Test time' "$log" || true
echo "test: setup and build $((set_up - start)) s, format and ctest $((tested - set_up)) s," \
  "sanitizer and fuzzing $((SECONDS - tested)) s, in all $((SECONDS - start)) s"
