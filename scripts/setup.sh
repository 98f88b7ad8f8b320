#!/usr/bin/env bash
# Installs what ddhgs needs from Debian 12 (only what is missing) and builds it.
#   scripts/setup.sh               runtime + build dependencies, then the ddhgs program
#   scripts/setup.sh --with-tests  also the test-only packages, then everything (tests,
#                                  benchmarks) with warnings as errors
# Quiet when everything is already there. Environment: BUILD_DIR (default build).
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=lib/packages.sh
source scripts/lib/packages.sh

with_tests=0
for arg in "$@"; do
  case "$arg" in
    --with-tests) with_tests=1 ;;
    *) echo "setup.sh: unknown option '$arg'" >&2; exit 2 ;;
  esac
done

# colmap: `ddhgs process` runs it (structure from motion on pseudo-RGB views).
packages=(build-essential cmake ninja-build pkg-config libtorch-dev libopenblas0-pthread
          nlohmann-json3-dev libcli11-dev libstb-dev libtiff-dev libpng-dev libjpeg-dev
          libgtest-dev libbenchmark-dev colmap)
if [ "$with_tests" = 1 ]; then
  # Independent cross-checks in tests: numpy for metrics and .npy files,
  # PyTorch for .pt files written by torch.save; headless Chromium opens the
  # HTML report (tests/app/test_report_cli.cpp).
  # PIL decodes PNG/JPEG/TIFF independently of ours; clang-format checks the
  # tree's formatting.
  packages+=(python3 python3-numpy python3-torch python3-pil chromium clang-format)
fi

ensure_packages setup "${packages[@]}"

build_dir="${BUILD_DIR:-build}"
# The main command builds only the program; the tests and benchmarks (about
# two thirds of the compile time) only when asked for.
targets=(ddhgs)
werror=OFF
if [ "$with_tests" = 1 ]; then
  targets=(all)
  werror=ON
fi
configured=$(sed -n 's/^DDHGS_WERROR:BOOL=//p' "$build_dir/CMakeCache.txt" 2>/dev/null || true)
if [ ! -f "$build_dir/build.ninja" ] || { [ "$werror" = ON ] && [ "$configured" != ON ]; }; then
  mkdir -p "$build_dir"
  cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release -DDDHGS_WERROR="$werror" \
    >"$build_dir.cmake.log" 2>&1 || {
    echo "setup: cmake configuration failed (log: $build_dir.cmake.log)" >&2
    tail -20 "$build_dir.cmake.log" >&2
    exit 1
  }
  rm -f "$build_dir.cmake.log"
fi
# ninja's own status decides (a filter in a pipeline with `|| true` would
# hide a failed build and leave stale binaries to be tested).
build_log="$build_dir.build.log"
began=$SECONDS
if ! ninja -C "$build_dir" -j "$(nproc)" --quiet "${targets[@]}" >"$build_log" 2>&1; then
  cat "$build_log" >&2
  echo "setup: build failed (log: $build_log)" >&2
  exit 1
fi
grep -v '^ninja: no work to do' "$build_log" || true
grep -q '^ninja: no work to do' "$build_log" ||
  echo "setup: built ${targets[*]} in $((SECONDS - began)) s" >&2
rm -f "$build_log"
