#!/usr/bin/env bash
# The rig's pose accuracy at a sensor-like size: `ddhgs synth --preset rig` (five
# band cameras with known rig rotations), `ddhgs process --rig` (COLMAP on
# the reference camera's images, the other cameras placed by their rig
# rotations), then every band camera's rotation error against the truth
# after a similarity alignment. It runs the CI test
# RigCli.ColmapPosesEveryBandCamera (320x240 there, for time) at 640x480,
# half a RedEdge's 1280x960, once per seed, with a bar of 0.1 degrees for
# every camera, and prints each run's "COLMAP:" line (copied into
# docs/benchmarks.md).
#   scripts/rig_pose_benchmark.sh [BUILD_DIR] [SEED...]   (default: build 0 1)
# Overrides: DDHGS_RIG_SIZE (synth flags, default "--width 640 --height 480
# --views 36"), DDHGS_RIG_WORST_ROTATION_DEG (default 0.1).
# About 4 minutes a seed on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir="${1:-build}"
shift || true
seeds=("${@:-0 1}")
test -x "$build_dir/tests/test_app" || { echo "rig_pose_benchmark: build $build_dir/tests/test_app first" >&2; exit 1; }
command -v "${DDHGS_COLMAP:-colmap}" >/dev/null || { echo "rig_pose_benchmark: colmap is missing (scripts/setup.sh installs it)" >&2; exit 1; }
size="${DDHGS_RIG_SIZE:---width 640 --height 480 --views 36}"
export DDHGS_RIG_WORST_ROTATION_DEG="${DDHGS_RIG_WORST_ROTATION_DEG:-0.1}"
export DDHGS_RIG_MEDIAN_ROTATION_DEG="$DDHGS_RIG_WORST_ROTATION_DEG"
export DDHGS_THREADS="${DDHGS_THREADS:-$(nproc)}"
status=0
for seed in ${seeds[*]}; do
  export DDHGS_RIG_SYNTH="$size --seed $seed"
  start=$(date +%s)
  if out=$("$build_dir/tests/test_app" --gtest_filter='RigCli.ColmapPosesEveryBandCamera' 2>&1); then verdict=pass; else verdict=FAIL; status=1; fi
  line=$(grep -m1 '^COLMAP:' <<<"$out" || echo "COLMAP: no result (see the test's output)")
  echo "rig-pose-benchmark: seed $seed ($size): $line; bar ${DDHGS_RIG_WORST_ROTATION_DEG} deg: $verdict ($(( $(date +%s) - start )) s)"
  [ "$verdict" = pass ] || grep -E 'Failure|error|Expected|Which is' <<<"$out" | head -8 >&2
done
exit $status
