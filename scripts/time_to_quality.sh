#!/bin/bash
# Time to quality at 101 training views (docs/benchmarks.md): a 640x512,
# 141-band synthetic scene with 112 views (101 training, 11 held out) trained
# for several iteration counts, one run after the other. Prints, per run, the
# wall clock, the training time and the held-out views' PSNR against clean
# truth, its gap to the longest finished run with the default settings, and
# the test-PSNR curve against training minutes and against wall minutes (the
# clock the bar is set in).
#
#   scripts/time_to_quality.sh [DIR] [RUNS (default "6000 12000 30000")]
#
# A run is an iteration count, optionally followed by settings for `--set`,
# each after a colon: "11000:loss.bands_per_step_until_fraction=0.9" trains
# 11,000 iterations with that setting, in run_11000_loss.bands_per_...=0.9.
# Writes into DIR (default a new folder under /tmp; the scene takes 20 GB).
# Finished runs are reused and an interrupted one continues from its last
# checkpoint (every 1000 iterations here; checkpoints do not change
# training; its wall clock is then not reported), but only by the same
# version: each run records a digest of the ddhgs binary and configs/*.json
# in run_N.version, and the script stops if they differ (after a default
# changes, use a new DIR with a link to the old DIR's scene).
# About 42 min for 6000 iterations, 80 min for 12000 on 2 cores (whole views,
# before crops per step became the default; faster now).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
B="$here/build/ddhgs"
dir=${1:-$(mktemp -d /tmp/ddhgs_time_to_quality_XXXXXX)}
runs=${2:-"6000 12000 30000"}
mkdir -p "$dir"
cd "$dir"
version=$(cat "$B" "$here"/configs/*.json | sha256sum | cut -c1-16)
# Reusing or resuming a run made by another binary or other configs would mix
# two versions' figures in one table.
same_version() {
  local made
  made=$(cat "$1.version" 2> /dev/null || echo "unrecorded")
  [ "$made" = "$version" ] && return 0
  echo "time_to_quality: $dir/$1 was made by version $made, this is $version" \
    "(binary and configs/*.json); use a new DIR" >&2
  exit 2
}
[ -f scene/transforms.json ] || "$B" synth --preset bayspec --out scene --views 112 --force \
  > synth.log 2>&1
for spec in $runs; do
  IFS=: read -r n settings <<< "$spec"
  run=run_$n${settings:+_${settings//:/_}}
  if [ -f "$run/train_summary.json" ]; then
    same_version "$run"
    continue
  fi
  echo "$run: start $(date -u +%FT%TZ), load $(cut -d' ' -f1-3 /proc/loadavg)" >&2
  if [ -f "$run/checkpoint.pt" ]; then
    same_version "$run"
    rm -f "$run.wall"
    "$B" train --resume "$run" >> "$run.log" 2>&1
  else
    args=(--set output.checkpoint_every=1000)
    IFS=: read -ra pairs <<< "$settings"
    for pair in "${pairs[@]}"; do args+=(--set "$pair"); done
    echo "$version" > "$run.version"
    start=$(date +%s)
    # Every 5 s: wall seconds and the test records written so far, so each
    # record's wall clock (loading, initialising and earlier records
    # included) is known to 5 s.
    # It stops with this script, however that ends.
    (while sleep 5 && kill -0 $$ 2> /dev/null; do
      echo "$(($(date +%s) - start)) $(grep -c test_psnr_clean "$run/metrics.jsonl" 2> /dev/null)"
    done) > "$run.records" &
    sampler=$!
    status=0
    "$B" train scene --out "$run" --iterations "$n" "${args[@]}" --force > "$run.log" 2>&1 ||
      status=$?
    kill $sampler
    [ $status = 0 ] || exit $status
    echo $(($(date +%s) - start)) > "$run.wall"
  fi
done
/usr/bin/python3 - "$dir" $runs <<'PY'
import json, os, sys

root, specs = sys.argv[1], sys.argv[2:]
runs = []
for spec in specs:
    n, *settings = spec.split(":")
    name = f"run_{n}" + "".join("_" + s for s in settings)
    path = os.path.join(root, name)
    if not os.path.exists(os.path.join(path, "train_summary.json")):
        continue
    summary = json.load(open(os.path.join(path, "train_summary.json")))
    curve = [(r["seconds"] / 60, r["test_psnr_clean"])
             for r in map(json.loads, open(os.path.join(path, "metrics.jsonl")))
             if "test_psnr_clean" in r]
    wall = os.path.join(root, f"{name}.wall")
    wall_minutes = int(open(wall).read()) / 60 if os.path.exists(wall) else None
    # Wall minutes at which the k-th test record had been written (5 s samples).
    records = os.path.join(root, f"{name}.records")
    wall_curve = []
    if os.path.exists(records) and wall_minutes is not None:
        samples = [tuple(map(int, fields)) for fields in map(str.split, open(records))
                   if len(fields) == 2]
        for k, (_, psnr) in enumerate(curve, 1):
            at = next((s / 60 for s, count in samples if count >= k), wall_minutes)
            wall_curve.append((at, psnr))
    runs.append((int(n), settings, name, summary, curve, wall_minutes, wall_curve))
defaults = [r for r in runs if not r[1]]
if not defaults:
    sys.exit("no finished run with the default settings")
reference = max(defaults, key=lambda r: r[0])
best = reference[3]["test_psnr_clean"]
print(f"longest finished default run: {reference[0]} iterations, {best:.3f} dB clean test PSNR")
for n, settings, name, summary, curve, wall, wall_curve in runs:
    psnr = summary["test_psnr_clean"]
    wall_text = f"{wall:5.1f} min wall" if wall is not None else "wall not recorded"
    print(f"{name}  {wall_text}  {summary['seconds'] / 60:5.1f} min training"
          f"  {psnr:.3f} dB ({psnr - best:+.3f})  {summary['num_gaussians']} Gaussians"
          f"  peak RSS {summary['peak_rss_mib'] / 1024:.1f} GiB")
    print("        curve (training minutes: dB): "
          + ", ".join(f"{m:.1f}: {p:.2f}" for m, p in curve))
    if wall_curve:
        print("        curve (wall minutes: dB):     "
              + ", ".join(f"{m:.1f}: {p:.2f}" for m, p in wall_curve))
PY
