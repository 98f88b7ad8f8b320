#!/bin/bash
# Time to quality (issue 30, bar 4): a 640x512, 141-band synthetic scene with
# 112 views (101 training, 11 held out) trained with the default settings for
# several iteration counts, one run after the other. Prints, per run, the wall
# clock, the training time and the held-out views' PSNR against clean truth,
# its gap to the longest finished run, and the test-PSNR-against-time curve.
#
#   scripts/time_to_quality.sh [DIR] [ITERATIONS (default "6000 12000 30000")]
#
# Writes into DIR (default a new folder under /tmp; the scene takes 20 GB).
# Finished runs are reused; an interrupted one continues from its last
# checkpoint (output.checkpoint_every, 5000), and its wall clock is then not
# reported. About 42 min for 6000 iterations, 75 min for 12000 on 2 cores.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
B="$here/build/ddhgs"
dir=${1:-$(mktemp -d /tmp/ddhgs_time_to_quality_XXXXXX)}
counts=${2:-"6000 12000 30000"}
mkdir -p "$dir"
cd "$dir"
[ -f scene/transforms.json ] || "$B" synth --preset bayspec --out scene --views 112 --force \
  > synth.log 2>&1
for n in $counts; do
  run=run_$n
  [ -f $run/train_summary.json ] && continue
  echo "$run: start $(date -u +%FT%TZ), load $(cut -d' ' -f1-3 /proc/loadavg)" >&2
  if [ -f $run/checkpoint.pt ]; then
    rm -f $run.wall
    "$B" train --resume $run >> $run.log 2>&1
  else
    start=$(date +%s)
    "$B" train scene --out $run --iterations $n --force > $run.log 2>&1
    echo $(($(date +%s) - start)) > $run.wall
  fi
done
/usr/bin/python3 - "$dir" $counts <<'PY'
import json, os, sys

root, counts = sys.argv[1], [int(c) for c in sys.argv[2:]]
runs = {}
for n in counts:
    path = os.path.join(root, f"run_{n}")
    if not os.path.exists(os.path.join(path, "train_summary.json")):
        continue
    summary = json.load(open(os.path.join(path, "train_summary.json")))
    curve = [(r["seconds"] / 60, r["test_psnr_clean"])
             for r in map(json.loads, open(os.path.join(path, "metrics.jsonl")))
             if "test_psnr_clean" in r]
    wall = os.path.join(root, f"run_{n}.wall")
    runs[n] = (summary, curve, int(open(wall).read()) / 60 if os.path.exists(wall) else None)
if not runs:
    sys.exit("no finished run")
best = runs[max(runs)][0]["test_psnr_clean"]
print(f"longest finished run: {max(runs)} iterations, {best:.3f} dB clean test PSNR")
for n, (summary, curve, wall) in runs.items():
    psnr = summary["test_psnr_clean"]
    wall_text = f"{wall:5.1f} min wall" if wall is not None else "wall not recorded"
    print(f"{n:6d} iterations  {wall_text}  {summary['seconds'] / 60:5.1f} min training"
          f"  {psnr:.3f} dB ({psnr - best:+.3f})  {summary['num_gaussians']} Gaussians"
          f"  peak RSS {summary['peak_rss_mib'] / 1024:.1f} GiB")
    print("        curve (training minutes: dB): "
          + ", ".join(f"{m:.1f}: {p:.2f}" for m, p in curve))
PY
