#!/bin/bash
# Per band against the spectral-subspace colour model, against
# clean truth: same scenes, seeds and iterations. Writes into DIR (default
# a new folder under /tmp) and prints one line per run: clean PSNR and SAM,
# the mean PSNR of the 10 % of bands with the lowest SNR, bytes per Gaussian.
#
#   scripts/subspace_quality.sh [DIR] [RANKS (default "0 -1")] [ITERATIONS (3000)]
#                               [BANDS_PER_STEP (loss.bands_per_step values, default "0")]
#
# Runs are reused when DIR already holds them. About 5 min per run on 2 cores.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
B="$here/build/ddhgs"
dir=${1:-$(mktemp -d /tmp/ddhgs_subspace_XXXXXX)}
ranks=${2:-"0 -1"}
iterations=${3:-3000}
bands_per_step=${4:-0}
mkdir -p "$dir"
cd "$dir"
for preset in bayspec surface-optics noisy-edges; do
  extra=""
  [ $preset = noisy-edges ] && extra="--bands 141"
  [ -d scene_$preset ] || "$B" synth --preset $preset --out scene_$preset --width 128 --height 96 \
    --views 40 $extra > synth_$preset.log 2>&1
  for seed in 0 1; do
    for rank in $ranks; do
      for bands in $bands_per_step; do
        run=run_${preset}_s${seed}_r${rank}
        [ "$bands" = 0 ] || run=${run}_b$bands
        [ -f $run/eval/metrics.json ] && continue
        "$B" train scene_$preset --out $run --iterations $iterations --seed $seed \
          --set model.spectral_rank=$rank --set loss.bands_per_step=$bands --force > $run.log 2>&1
        "$B" eval $run --no-denoise >> $run.log 2>&1
      done
    done
  done
done
/usr/bin/python3 - "$dir" <<'PY'
import glob, json, os, sys
import numpy as np

root = sys.argv[1]

def unit(path):
    a = np.load(path)
    scale = {np.dtype(np.uint16): 65535.0, np.dtype(np.uint8): 255.0}.get(a.dtype, 1.0)
    return a.astype(np.float64) / scale

def band_snr(scene):
    """Mean clean value over noise RMS per band, from 6 views."""
    signal = noise = 0
    for clean in sorted(glob.glob(f"{scene}/clean/*.npy"))[:6]:
        c, n = unit(clean), unit(clean.replace("/clean/", "/hyperspectral/"))
        signal = signal + c.reshape(-1, c.shape[-1]).mean(0)
        noise = noise + ((n - c) ** 2).reshape(-1, c.shape[-1]).mean(0)
    return signal / np.sqrt(noise)

for run in sorted(glob.glob(f"{root}/run_*/")):
    metrics = os.path.join(run, "eval", "metrics.json")
    if not os.path.exists(metrics):
        continue
    name = os.path.basename(run.rstrip("/"))
    m, s = json.load(open(metrics)), json.load(open(os.path.join(run, "train_summary.json")))
    snr = band_snr(f"{root}/scene_{name.split('_')[1]}")
    low = np.argsort(snr)[: max(1, len(snr) // 10)]
    per_band = np.array(m["clean"]["per_band_psnr"]["psnr"])
    print(f"{name:32s} channels {s['colour_channels']:>3}  clean PSNR {m['clean']['psnr']:.3f}"
          f"  SAM {m['clean']['sam']:.4f}  lowest-SNR {len(low)} bands {per_band[low].mean():.2f} dB"
          f"  {s['bytes_per_gaussian']} B per Gaussian  {s['seconds']:.0f} s")
PY
