#!/bin/bash
# A corpus of varied synthetic scenes, each trained with the defaults on a
# short schedule, for a denoiser prior trained across many scenes: its
# held-out renders against their clean truth (docs/commands.md, "A corpus
# of trained synthetic scenes").
#
#   scripts/prior_corpus.sh OUT COUNT
#   ITERS=1000 nice -n 10 scripts/prior_corpus.sh /data/corpus 60
#
# Entry i (0 .. COUNT-1) is drawn from i alone: the preset (demo, bayspec,
# surface-optics, noisy-edges in turn) as a `synth --vary` variant of seed
# 1000 + i (the seeds 0-2 of the benchmarks stay out), 3 to 141 bands, 8 to
# 48 training views plus 2 + training/12 held-out views (listed in the
# scene's transforms.json as test_filenames, evenly spread over the views),
# 96x72 to 192x144 pixels, noise scale 0.5-2, one scene in four without the
# ground disc. Each is trained by `ddhgs train SCENE --preset demo
# --iterations ITERS --seed i`.
#
# Layout: OUT/scenes/NNN (the scene, clean truth in clean/), OUT/runs/NNN
# (the run), OUT/logs/NNN.log, OUT/entries/NNN.json (the entry's record) and
# OUT/manifest.json ({"entries": [...]}, paths relative to OUT), rewritten
# whole (to a temporary name, then renamed) after every entry. Resumable: an
# entry whose run finished (train_summary.json) is skipped; one left half
# made is made again from its scene on.
#
# Environment: DDHGS (default build/ddhgs), ITERS (1000), PYTHON (python3,
# for the split), DDHGS_THREADS (threads per run; default all cores),
# DOWNSIZE (divides every drawn width and height; default 1; tests use 6).
set -euo pipefail
if [ $# -ne 2 ] || ! [[ "$2" =~ ^[1-9][0-9]*$ ]]; then
  echo "usage: prior_corpus.sh OUT COUNT (COUNT a positive whole number)" >&2
  exit 2
fi
out="$1"
count="$2"
ddhgs="${DDHGS:-build/ddhgs}"
iters="${ITERS:-1000}"
downsize="${DOWNSIZE:-1}"
python="${PYTHON:-python3}"
if [ ! -x "$ddhgs" ]; then
  echo "prior_corpus.sh: $ddhgs: no ddhgs executable there (set DDHGS)" >&2
  exit 2
fi
for setting in "ITERS=$iters" "DOWNSIZE=$downsize"; do
  if ! [[ "${setting#*=}" =~ ^[1-9][0-9]*$ ]]; then
    echo "prior_corpus.sh: $setting: expected a positive whole number (DOWNSIZE at most 8)" >&2
    exit 2
  fi
done
if [ "$downsize" -gt 8 ]; then
  echo "prior_corpus.sh: DOWNSIZE=$downsize: expected a positive whole number (DOWNSIZE at most 8)" >&2
  exit 2
fi
mkdir -p "$out/scenes" "$out/runs" "$out/logs" "$out/entries"

presets=(demo bayspec surface-optics noisy-edges)
band_counts=(3 8 16 24 40 64 96 128 141)
noise_scales=(0.5 0.75 1 1.25 1.5 2)

# A number in [0, n) drawn from entry i and a salt, the same every time.
# Every product stays below 2^62: bash's integers are 64-bit.
draw() {
  local i=$1 salt=$2 n=$3
  local x=$(((i * 7919 + salt * 104729 + 1) % 2147483648)) round
  for round in 1 2 3; do
    x=$(((x ^ (x >> 16)) * 73244475 % 2147483648))
  done
  echo $(((x ^ (x >> 16)) % n))
}

# The manifest: every recorded entry below COUNT, in order.
write_manifest() {
  local tmp="$out/manifest.json.tmp" first=1 k record
  {
    printf '{"entries": ['
    for ((k = 0; k < count; k++)); do
      record="$out/entries/$(printf '%03d' "$k").json"
      [ -f "$record" ] || continue
      [ "$first" = 1 ] || printf ','
      printf '\n  %s' "$(cat "$record")"
      first=0
    done
    printf '\n]}\n'
  } >"$tmp"
  mv "$tmp" "$out/manifest.json"
}

# Lists views (evenly spread) of the scene's transforms.json as held out.
write_split() {
  "$python" - "$1/transforms.json" "$2" <<'PY'
import json, os, sys
path, held_out = sys.argv[1], int(sys.argv[2])
with open(path) as f:
    t = json.load(f)
names = [frame["file_path"] for frame in t["frames"]]
n = len(names)
test = {(2 * j + 1) * n // (2 * held_out) for j in range(held_out)}
t["train_filenames"] = [name for k, name in enumerate(names) if k not in test]
t["test_filenames"] = [name for k, name in enumerate(names) if k in test]
with open(path + ".tmp", "w") as f:
    json.dump(t, f, indent=2)
os.replace(path + ".tmp", path)
PY
}

made=0
made_seconds=0
for ((i = 0; i < count; i++)); do
  name=$(printf '%03d' "$i")
  scene="$out/scenes/$name" run="$out/runs/$name" record="$out/entries/$name.json"
  log="$out/logs/$name.log"
  preset=${presets[$((i % ${#presets[@]}))]}
  bands=${band_counts[$(draw "$i" 1 ${#band_counts[@]})]}
  train_views=$((8 + $(draw "$i" 2 41)))
  test_views=$((2 + train_views / 12))
  views=$((train_views + test_views))
  width=$(((96 + 8 * $(draw "$i" 3 13)) / downsize))
  height=$((width * 3 / 4))
  noise=${noise_scales[$(draw "$i" 4 ${#noise_scales[@]})]}
  ground=true
  ground_flag=()
  if [ "$(draw "$i" 5 4)" = 0 ]; then
    ground=false
    ground_flag=(--no-ground)
  fi
  seed=$((1000 + i))
  describe="$preset, $bands bands, $train_views+$test_views views, ${width}x$height"
  if [ -f "$run/train_summary.json" ] && [ -f "$record" ]; then
    echo "corpus: $((i + 1))/$count entry $name ($describe): done before, skipped"
    continue
  fi

  start=$(date +%s%N)
  force=()
  [ -e "$scene" ] && force=(--force)
  "$ddhgs" synth --preset "$preset" --vary --seed "$seed" --bands "$bands" --views "$views" \
    --width "$width" --height "$height" --noise-scale "$noise" "${ground_flag[@]}" \
    "${force[@]}" --out "$scene" >"$log" 2>&1 ||
    { echo "prior_corpus.sh: entry $name: synth failed; see $log" >&2; exit 1; }
  write_split "$scene" "$test_views"
  force=()
  [ -e "$run" ] && force=(--force)
  "$ddhgs" train "$scene" --preset demo --iterations "$iters" --seed "$i" "${force[@]}" \
    --out "$run" >>"$log" 2>&1 ||
    { echo "prior_corpus.sh: entry $name: train failed; see $log" >&2; exit 1; }
  seconds=$(awk -v a="$start" -v b="$(date +%s%N)" 'BEGIN { printf "%.1f", (b - a) / 1e9 }')

  printf '{"scene": "scenes/%s", "run": "runs/%s", "preset": "%s", "seed": %d, "bands": %d, "views": %d, "train_views": %d, "test_views": %d, "width": %d, "height": %d, "noise_scale": %s, "ground": %s, "iterations": %d, "seconds": %s}\n' \
    "$name" "$name" "$preset" "$seed" "$bands" "$views" "$train_views" "$test_views" \
    "$width" "$height" "$noise" "$ground" "$iters" "$seconds" >"$record.tmp"
  mv "$record.tmp" "$record"
  write_manifest

  made=$((made + 1))
  made_seconds=$(awk -v a="$made_seconds" -v b="$seconds" 'BEGIN { print a + b }')
  left=0
  for ((k = i + 1; k < count; k++)); do
    [ -f "$out/runs/$(printf '%03d' "$k")/train_summary.json" ] || left=$((left + 1))
  done
  eta=$(awk -v s="$made_seconds" -v m="$made" -v l="$left" \
    'BEGIN { e = s / m * l; printf "%dh%02dm", e / 3600, (e % 3600) / 60 }')
  echo "corpus: $((i + 1))/$count entry $name ($describe): ${seconds} s (mean $(awk -v s="$made_seconds" -v m="$made" 'BEGIN { printf "%.0f", s / m }') s), ETA $eta"
done
write_manifest
echo "corpus: $count entries in $out/manifest.json"
