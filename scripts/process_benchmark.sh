#!/usr/bin/env bash
# Full-size check of `ddhgs process`: synthesises a scene, hides its
# poses, recovers them with COLMAP, reports rotation and position errors after
# a similarity alignment, and the held-out PSNR of training on the true and on
# the recovered poses. It runs the CI test ProcessCli.RecoversSyntheticPoses...
# with a larger scene and longer training (environment variables below), and
# prints its "process-benchmark:" line (copied into docs/benchmarks.md).
#   scripts/process_benchmark.sh [BUILD_DIR]     (default build; needs test_app)
# Overrides: DDHGS_PROCESS_SYNTH (ddhgs synth flags), DDHGS_PROCESS_ARGS
# (ddhgs process flags), DDHGS_PROCESS_TRAIN (ddhgs train flags),
# DDHGS_PROCESS_MAX_ROTATION_DEG, DDHGS_PROCESS_MAX_POSITION_PCT and
# DDHGS_PROCESS_MAX_PSNR_GAP (bars).
# About 15-25 minutes on 2 busy cores.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir="${1:-build}"
test -x "$build_dir/tests/test_app" || { echo "process_benchmark: build $build_dir/tests/test_app first" >&2; exit 1; }
command -v "${DDHGS_COLMAP:-colmap}" >/dev/null || { echo "process_benchmark: colmap is missing (scripts/setup.sh installs it)" >&2; exit 1; }

export DDHGS_PROCESS_SYNTH="${DDHGS_PROCESS_SYNTH:---width 512 --height 384 --bands 16 --views 60 --rings 2 --elevation-min 20 --elevation-max 40 --points 1000}"
# As the CI test (1 px reprojection filter for exact pinhole cameras), with
# SIFT capped at 1024 features a view: the 0.002 peak threshold finds about
# 1,800 per 512x384 view, and exhaustive matching time grows with their square.
export DDHGS_PROCESS_ARGS="${DDHGS_PROCESS_ARGS:---matcher exhaustive --colmap-set Mapper.filter_max_reproj_error=1 --colmap-set Mapper.tri_min_angle=3 --colmap-set SiftExtraction.max_num_features=1024}"
export DDHGS_PROCESS_TRAIN="${DDHGS_PROCESS_TRAIN:---preset demo --downscale 8 --set iterations=300}"
# The bars: median rotation error under 1 degree, position under 2 %.
export DDHGS_PROCESS_MAX_ROTATION_DEG="${DDHGS_PROCESS_MAX_ROTATION_DEG:-1}"
export DDHGS_PROCESS_MAX_POSITION_PCT="${DDHGS_PROCESS_MAX_POSITION_PCT:-2}"
# Processed-scene PSNR within 1.5 dB of the true-pose run.
export DDHGS_PROCESS_MAX_PSNR_GAP="${DDHGS_PROCESS_MAX_PSNR_GAP:-1.5}"
echo "process_benchmark: synth $DDHGS_PROCESS_SYNTH | process $DDHGS_PROCESS_ARGS | train $DDHGS_PROCESS_TRAIN" >&2
echo "process_benchmark: $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)" >&2
"$build_dir/tests/test_app" --gtest_filter='ProcessCli.RecoversSyntheticPosesAndTrainsLikeTheTruePoses' |
  grep -E 'process-benchmark:|OK \]|FAILED|Failure|Expected|Which is|actual'
