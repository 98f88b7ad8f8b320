#!/bin/bash
# Blocks against one model (docs/benchmarks.md, "Blocks"): a synthetic grid
# flight (rig-nadir, 5 bands) cut into 2x2 blocks with 20 % margins, each
# block trained as part of the flight (data.block_as_flight: the single
# run's iterations over the flight's training views, its own views rendered
# and the others' steps on momentum alone, so every Gaussian gets the
# optimiser steps it would get in the single run), merged, and
# compared with one model trained on the whole flight: held-out PSNR
# (eval), PSNR in the blocks' overlap zones and elsewhere, in the held-out
# captures and in the orthomosaic against the truth's orthographic
# reflectance, and on each cell's own ground away from the zones
# (scripts/lib/block_zones.py), peak memory and CPU time of
# every run; the held-out figures over the flight's own held-out captures
# and, apart, over novel views between its captures and lines (synth
# --novel-views: 33 on the default 4 x 12 grid), which see every overlap
# zone. The blocks are merged twice: cross-faded across the seams (the
# default, merged/) and cut at the cell borders (--seam-blend 0, merged-cut/).
#
#   scripts/blocks_benchmark.sh [OUT]
#
# Environment: DDHGS (default build/ddhgs), VIEWS (48), LINES (4), WIDTH
# (96), HEIGHT (72), ITERATIONS (of the single run; 3000), PRESET (demo),
# BLOCKS (2x2), OVERLAP (the partition's margin; 0.2), NOVEL (1: the novel views; 0: the flight's own held-out
# captures only), SEED (of the flight; 0), TRAIN_SEED (of every training; 0),
# BLOCK_SET (more words for each block's train only, e.g. "--set
# densify.grad_threshold=0.0004", to try a setting on the blocks against the
# same single model), BUDGET (flight: the budget above; view: each block a
# scene of its own, data.block_as_flight=false, with iterations in
# proportion to its training views, each view seen as often as in the
# single run, the default until 2026-12-07; gaussian: as view but every
# block the single run's iterations and at most its Gaussians over the
# number of blocks, densify.max_gaussians; tried 2026-12-07, not better on
# every flight), SINGLE_FROM (the single/ folder of an earlier run of this
# script with the same flight and seeds, reused instead of trained), PYTHON
# (a python3 with numpy; default /usr/bin/python3; gdal_translate reads the
# orthomosaics).
set -euo pipefail
cd "$(dirname "$0")/.."
ddhgs="$(realpath "${DDHGS:-build/ddhgs}")"
out="${1:-/tmp/ddhgs-blocks-benchmark}"
views="${VIEWS:-48}" lines="${LINES:-4}" width="${WIDTH:-96}" height="${HEIGHT:-72}"
iterations="${ITERATIONS:-3000}" preset="${PRESET:-demo}" grid="${BLOCKS:-2x2}" seed="${SEED:-0}"
train_seed="${TRAIN_SEED:-0}"
novel=()
[[ "${NOVEL:-1}" == 0 ]] || novel=(--novel-views)
overlap="${OVERLAP:-0.2}"
budget="${BUDGET:-flight}"
[[ "$budget" == flight || "$budget" == view || "$budget" == gaussian ]] ||
  { echo "blocks_benchmark: BUDGET=$budget: expected flight, view or gaussian" >&2; exit 1; }
read -r -a block_set <<<"${BLOCK_SET:-}"
python="${PYTHON:-/usr/bin/python3}"
rm -rf "$out"
mkdir -p "$out"
echo "date $(date -u '+%Y-%m-%d %H:%M UTC'), $(uptime | sed 's/.*load/load/')"

# CPU seconds (user + system) and peak RSS (MiB) of one command, via GNU time.
timed() {
  local label="$1"
  shift
  /usr/bin/time -f "$label %U %S %M" -o "$out/$label.time" "$@"
  awk '{printf "%s: %.1f CPU s, peak %.0f MiB\n", $1, $2 + $3, $4 / 1024}' "$out/$label.time"
}

"$ddhgs" -q synth --preset rig-nadir --views "$views" --lines "$lines" --field-spacing 2 \
  --width "$width" --height "$height" --supersample 2 --seed "$seed" "${novel[@]}" --out "$out/flight"
scene="$out/flight/cubes"
# The cubes lie in the synthetic world's frame, which maps to the projected
# CRS by the translation synth.json records: the scene's exact georeference
# (what process --rig fits from exact GPS), so that render --ortho works.
"$python" - "$out/flight" <<'PY'
import json, sys
g = json.load(open(sys.argv[1] + "/synth.json"))["georeference"]
json.dump({"crs": "EPSG:%d" % g["epsg"], "epsg": g["epsg"],
           "scene_to_crs": {"scale": 1.0, "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
                            "translation": g["world_origin_crs_m"]}},
          open(sys.argv[1] + "/cubes/georef.json", "w"), indent=2)
PY
"$ddhgs" -q partition "$scene" --blocks "$grid" --overlap "$overlap" --out "$out/blocks"
if [[ -n "${SINGLE_FROM:-}" ]]; then
  # A single run of this flight and seeds from an earlier run of this
  # script (training is deterministic: the same figures to the digit).
  cp -r "$SINGLE_FROM" "$out/single"
  rm -rf "$out/single/renders" "$out/single/eval"
  cp "$(dirname "$SINGLE_FROM")/single.time" "$out/single.time"
  awk '{printf "single (from %s): %.1f CPU s, peak %.0f MiB\n", "'"$SINGLE_FROM"'", $2 + $3, $4 / 1024}' \
    "$out/single.time"
else
  timed single "$ddhgs" -q train "$scene" --out "$out/single" --preset "$preset" \
    --iterations "$iterations" --seed "$train_seed" --checkpoint-every 0
fi
total=$("$ddhgs" info "$scene" 2>&1 | sed -n 's/^views .*(train \([0-9]\+\),.*/\1/p')
budget_set=() cap=""
[[ "$budget" == flight ]] || budget_set=(--set data.block_as_flight=false)
if [[ "$budget" == gaussian ]]; then
  single_gaussians=$("$python" -c 'import json, sys; print(json.load(open(sys.argv[1]))["num_gaussians"])' \
    "$out/single/train_summary.json")
  blocks=$(ls -d "$out"/blocks/block_* | wc -l)
  cap=$(( (single_gaussians + blocks - 1) / blocks ))
  budget_set+=(--set "densify.max_gaussians=$cap")
fi
for block in "$out"/blocks/block_*; do
  name="$(basename "$block")"
  train_views=$("$ddhgs" info "$block" 2>&1 | sed -n 's/^views .*(train \([0-9]\+\),.*/\1/p')
  block_iterations=$iterations
  [[ "$budget" == view ]] && block_iterations=$(( (iterations * train_views + total / 2) / total ))
  echo "$name: $train_views of $total training views, $block_iterations iterations${cap:+, at most $cap Gaussians}"
  timed "$name" "$ddhgs" -q train "$block" --out "$block/run" --preset "$preset" \
    --iterations "$block_iterations" --seed "$train_seed" --checkpoint-every 0 "${budget_set[@]}" \
    "${block_set[@]}"
done
"$ddhgs" merge "$out/blocks" --out "$out/merged"
"$ddhgs" -q merge "$out/blocks" --out "$out/merged-cut" --seam-blend 0
for run in single merged merged-cut; do
  echo "--- $run"
  "$ddhgs" eval "$out/$run" --data "$scene" 2>&1 | sed -n '/PSNR dB/,/clean/p'
  "$ddhgs" -q render "$out/$run" --format npy --data "$scene"
  "$ddhgs" -q render "$out/$run" --ortho --data "$scene"
done
"$python" scripts/lib/block_zones.py "$scene" "$out/blocks" "$out/single" "$out/merged" \
  "$out/merged-cut"
awk '{cpu += $2 + $3} END {printf "blocks together: %.1f CPU s\n", cpu}' "$out"/block_*.time
echo "done $(date -u '+%H:%M UTC'), $(uptime | sed 's/.*load/load/')"
