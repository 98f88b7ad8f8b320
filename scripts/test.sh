#!/usr/bin/env bash
# Sets up (packages + build of everything, warnings as errors), checks the
# formatting of the tree and runs the whole test suite. Exit status is
# non-zero on any failure, and on any skipped test that tests/expected_skips.txt
# does not list.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh --with-tests
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

# A skipped test is a check that did not run: only the declared ones may skip.
mapfile -t skipped < <(sed -n 's/^ *[0-9]*\/[0-9]* Test *#[0-9]*: \([^ ]*\) .*Skipped.*/\1/p' "$log")
unexpected=()
for name in "${skipped[@]}"; do
  grep -qxF "$name" tests/expected_skips.txt 2>/dev/null || unexpected+=("$name")
done
if [ "${#unexpected[@]}" -gt 0 ]; then
  echo "test: ${#unexpected[@]} test(s) skipped that tests/expected_skips.txt does not list: ${unexpected[*]}" >&2
  exit 1
fi
