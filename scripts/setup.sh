#!/usr/bin/env bash
# Installs what ddhgs needs from Debian 12 (only what is missing) and builds it.
#   scripts/setup.sh               runtime + build dependencies, then the ddhgs program
#   scripts/setup.sh --with-tests  also the test-only packages, then everything (tests,
#                                  benchmarks) with warnings as errors
# Quiet when everything is already there; while building, one progress line.
# Environment: BUILD_DIR (default build).
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
# libgdal-dev: `render --ortho` writes Cloud-Optimised GeoTIFFs through GDAL.
# libzbar-dev: `process --panel` reads the calibration panel's QR label.
packages=(build-essential cmake ninja-build pkg-config libtorch-dev libopenblas0-pthread
          nlohmann-json3-dev libcli11-dev libstb-dev libtiff-dev libpng-dev libjpeg-dev
          libgdal-dev libzbar-dev libgtest-dev libbenchmark-dev colmap)
if [ "$with_tests" = 1 ]; then
  # Independent cross-checks in tests: numpy for metrics and .npy files,
  # PyTorch for .pt files written by torch.save; headless Chromium opens the
  # HTML report (tests/app/test_report_cli.cpp).
  # PIL decodes PNG/JPEG/TIFF independently of ours; clang-format checks the
  # tree's formatting; git makes the scratch checkout that tests the commit
  # `--version` names; gdal-bin's gdalinfo reads the orthomosaics back.
  # slurm-wlm and munge: tests/slurm/single_node_slurm.sh starts a real
  # single-node Slurm and runs a partition's blocks as a job array.
  packages+=(python3 python3-numpy python3-torch python3-pil chromium clang-format git gdal-bin
             slurm-wlm munge)
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
# The build shows one line of progress (steps done of all, seconds so far):
# rewritten in place on a terminal, else printed once a minute (CI's log
# stays short). ninja's whole output goes to the log, shown in full when the
# build fails. ninja's own status decides (a filter's would hide a failed
# build and leave stale binaries to be tested).
build_log="$build_dir.build.log"
began=$SECONDS
show_progress() {
  local line="" partial="" progress done_=0 total=0 shown=$SECONDS tty=0
  [ -t 2 ] && tty=1
  exec 3>"$build_log"
  while :; do
    if IFS= read -r -t 1 line; then
      line=$partial$line partial=
      printf '%s\n' "$line" >&3
      if [[ $line =~ ^\[([0-9]+)/([0-9]+)\]\  ]]; then
        done_=${BASH_REMATCH[1]} total=${BASH_REMATCH[2]}
      fi
    elif [ $? -gt 128 ]; then # a second without a line: keep what came of it
      partial+=$line
    else
      [ -n "$partial$line" ] && printf '%s\n' "$partial$line" >&3
      break
    fi
    progress="setup: building, $done_ of $total steps, $((SECONDS - began)) s"
    if [ "$tty" = 1 ]; then
      printf '\r%s ' "$progress" >&2
    elif ((SECONDS - shown >= 60)); then
      echo "$progress" >&2
      shown=$SECONDS
    fi
  done
  exec 3>&-
  [ "$tty" = 1 ] && printf '\r\033[K' >&2
  return 0
}
if ! NINJA_STATUS='[%f/%t] ' ninja -C "$build_dir" -j "$(nproc)" "${targets[@]}" 2>&1 | show_progress; then
  cat "$build_log" >&2
  echo "setup: build failed after $((SECONDS - began)) s (log: $build_log)" >&2
  exit 1
fi
# What the compiler said besides the steps and a re-run of cmake (warnings,
# without -Werror).
grep -vE '^\[[0-9]+/[0-9]+\] |^ninja: (Entering directory|no work to do)|^-- |^Re-running CMake' "$build_log" || true
# Quiet when nothing was built: the glob check ([0/N]) and reading the commit
# (cmake/version.cmake) run every time.
steps=$(grep -E '^\[[1-9][0-9]*/[0-9]+\] ' "$build_log" | grep -cv 'Reading the commit' || true)
[ "$steps" = 0 ] || echo "setup: built ${targets[*]} in $((SECONDS - began)) s ($steps steps)" >&2
rm -f "$build_log"
