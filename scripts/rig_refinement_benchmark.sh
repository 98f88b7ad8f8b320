#!/usr/bin/env bash
# The rig-refinement bar: the synthetic rig with every band camera but
# camera 1 turned by 1 degree and moved by 10 cm from its factory placement
# (`synth --rig-perturb-deg 1 --rig-offset-cm 10`), processed with the
# reference camera's true poses (`process --rig --reference-camera 1 --poses
# truth`), trained with and without `camera_refinement.rig`, and the
# unperturbed rig trained alike (same seed, iterations and preset). Prints
# each run's test PSNR against clean truth and each camera's refined
# rotation error against synth.json's truth (degrees) and offset error (cm).
#   scripts/rig_refinement_benchmark.sh [BUILD_DIR] [ITERATIONS] [WORK_DIR]
# Overrides: DDHGS_RIG_SIZE (synth flags, default: the rig preset's 160x120,
# 24 captures), DDHGS_RIG_TRAIN (extra train flags), DDHGS_RIG_RUNS (which
# of clean_run drifted_refined drifted_plain drifted_second known_refined
# known_second to train; default the first three). drifted_second trains the drifted rig again with
# drifted_refined's corrections held (camera_refinement.rig_start, rates 0,
# no warm-up; without DDHGS_RIG_TRAIN): the two-pass procedure.
# known_refined trains the drifted rig with its lever arms known (synth's
# lever_arms.json: the true offsets in cm, as the rig's drawing would give
# them, through camera_refinement.rig_start, held with rig_offset_lr=0;
# rotation rate 1e-3 and an alignment phase of 0.4), and known_second
# holds its corrections in a second pass; neither takes DDHGS_RIG_TRAIN.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir="${1:-build}"
iterations="${2:-3000}"
work="${3:-$(mktemp -d /tmp/rig_refinement.XXXXXX)}"
ddhgs="$build_dir/ddhgs"
test -x "$ddhgs" || { echo "rig_refinement_benchmark: build $ddhgs first" >&2; exit 1; }
size="${DDHGS_RIG_SIZE:-}"
export DDHGS_THREADS="${DDHGS_THREADS:-$(nproc)}"
mkdir -p "$work"
scene() {  # NAME SYNTH_FLAGS...
  local name=$1
  shift
  "$ddhgs" synth --preset rig $size "$@" --out "$work/$name.synth" --force >/dev/null
  # The clean truth copied in by an earlier run is not process's to replace.
  rm -rf "$work/$name/clean"
  "$ddhgs" process "$work/$name.synth/captures" --rig --reference-camera 1 --skip-colmap \
    --poses "$work/$name.synth/truth/transforms.json" --out "$work/$name" --force >/dev/null
  cp -r "$work/$name.synth/truth/clean" "$work/$name/clean"
}
train() {  # SCENE RUN FLAGS...
  local scene=$1 run=$2
  shift 2
  local start
  start=$(date +%s)
  "$ddhgs" train "$work/$scene" --preset demo --iterations "$iterations" --seed 0 \
    --out "$work/$run" --force ${DDHGS_RIG_TRAIN:-} "$@" >"$work/$run.log" 2>&1
  python3 - "$work/$run/train_summary.json" "$work/$scene.synth/synth.json" "$run" \
    "$(( $(date +%s) - start ))" <<'PY'
import json, math, sys
summary = json.load(open(sys.argv[1]))
synth = json.load(open(sys.argv[2]))
line = f"{sys.argv[3]}: test PSNR vs clean {summary['test_psnr_clean']:.3f} dB ({sys.argv[4]} s)"
truth = {c["rig_index"]: c for c in synth["cameras"]}
for c in summary.get("rig_corrections", {}).get("cameras", []):
    t = truth[c["rig_camera"]]
    rot = [r * 180 / math.pi for r in c["rotation_rad"]]
    err = math.dist(rot, t["true_rotation_error_deg"])
    off = math.dist(c["offset_cm"], t["true_offset_cm"])
    line += f"; camera {c['rig_camera']}: rotation error {err:.3f} deg, offset error {off:.2f} cm"
print(line)
PY
}
scene clean
scene drifted --rig-perturb-deg 1 --rig-offset-cm 10
runs="${DDHGS_RIG_RUNS:-clean_run drifted_refined drifted_plain}"
[[ " $runs " == *" clean_run "* ]] && train clean clean_run
[[ " $runs " == *" drifted_refined "* ]] && train drifted drifted_refined --set camera_refinement.rig=true
[[ " $runs " == *" drifted_plain "* ]] && train drifted drifted_plain
second_pass() {  # FIRST RUN: the drifted rig trained with FIRST's corrections held
  local first=$1 run=$2
  test -f "$work/$first/rig_corrections.json" ||
    { echo "rig_refinement_benchmark: $run needs $first first" >&2; exit 1; }
  DDHGS_RIG_TRAIN="" train drifted "$run" --set camera_refinement.rig=true \
    --set camera_refinement.rig_start="$work/$first/rig_corrections.json" \
    --set camera_refinement.rig_rotation_lr=0 --set camera_refinement.rig_offset_lr=0 \
    --set camera_refinement.rig_warmup_fraction=0
}
[[ " $runs " == *" drifted_second "* ]] && second_pass drifted_refined drifted_second
if [[ " $runs " == *" known_refined "* ]]; then
  DDHGS_RIG_TRAIN="" train drifted known_refined --set camera_refinement.rig=true \
    --set camera_refinement.rig_start="$work/drifted.synth/lever_arms.json" \
    --set camera_refinement.rig_offset_lr=0 --set camera_refinement.rig_rotation_lr=1e-3 \
    --set camera_refinement.rig_align_fraction=0.4
fi
[[ " $runs " == *" known_second "* ]] && second_pass known_refined known_second
echo "rig-refinement-benchmark: $iterations iterations, work folder $work"
