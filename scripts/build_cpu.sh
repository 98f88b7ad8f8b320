#!/usr/bin/env bash
# Where the build's time goes: builds TARGET (default ddhgs) of this checkout
# from an empty folder and prints the CPU seconds (user + sys) of every
# compile and link step, the slowest first, and their total. CPU time, not
# wall time, so a busy machine still gives comparable figures.
#   scripts/build_cpu.sh [BUILD_DIR] [TARGET] [CMAKE OPTIONS...]
# e.g. scripts/build_cpu.sh /tmp/bt ddhgs -DDDHGS_UNITY=OFF (the files one by one).
# The build folder is emptied first. Needs the packages of scripts/setup.sh.
set -euo pipefail
if [ "${1:-}" = --step ]; then # the compiler launcher: one step, timed
  shift
  log=$1 out=-
  shift
  prev=""
  for arg in "$@"; do
    [ "$prev" = -o ] && out=$arg
    prev=$arg
  done
  exec /usr/bin/time -f "%U %S $out" -a -o "$log" "$@"
fi
cd "$(dirname "$0")/.."
build_dir=${1:-build-cpu}
target=${2:-ddhgs}
shift $(($# < 2 ? $# : 2))
[ -x /usr/bin/time ] || { echo "build_cpu.sh: needs /usr/bin/time (apt-get install time)" >&2; exit 1; }
rm -rf "$build_dir"
mkdir -p "$build_dir"
log=$(realpath "$build_dir")/cpu.log
launcher="$(realpath "$0");--step;$log"
cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  "-DCMAKE_CXX_COMPILER_LAUNCHER=$launcher" "-DCMAKE_CXX_LINKER_LAUNCHER=$launcher" "$@" >/dev/null
began=$SECONDS
ninja -C "$build_dir" -j "$(nproc)" "$target" >/dev/null
wall=$((SECONDS - began))
sort -k1,1 -g -r <(awk '{printf "%.1f %s\n", $1 + $2, $3}' "$log") | sed 's|CMakeFiles/||'
awk -v wall="$wall" -v load="$(cut -d' ' -f1-3 /proc/loadavg)" \
  '{cpu += $1 + $2; n++} END {printf "%d steps, %.0f s of CPU, %d s wall, load average %s\n", n, cpu, wall, load}' "$log"
