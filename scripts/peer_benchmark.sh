#!/usr/bin/env bash
# ddhgs against OpenSplat (the CPU splatting peer in ../shared/peers) on the
# real Basil capture: the same 45 training views, the same pixels, the same
# iteration count; both models measured by ONE metric code (`ddhgs eval`
# renders OpenSplat's PLY at the test cameras with ddhgs's renderer).
#
#   scripts/peer_benchmark.sh [--iterations 2000] [--downscale 4] [--seed 0]
#       [--variants white,black] [--no-ddhgs] [--work DIR] [--ddhgs-args "--set k=v ..."]
#       [--opensplat-args "--refine-every 100 ..."] [--threads N]
#
# Needs build/ddhgs, the repository's Basil (tests/data/basil: images,
# images_4 and images_8) and ../shared/peers ($DDHGS_SHARED_DIR instead of
# ../shared when set; OpenSplat is built there on first use by
# build-opensplat.sh, which apt-installs libopencv-dev). Prints one markdown table; everything else goes to
# WORK/log.txt. WORK (default /tmp/ddhgs-peer-benchmark) is created by the
# script and holds the runs. Nothing of OpenSplat enters this repository.
#
# Fairness: OpenSplat gets a COLMAP folder (under WORK) whose images/ holds
# only the training views at full resolution and runs with -d <downscale>,
# its own way of training at a lower resolution; its model is written in the
# COLMAP frame (it undoes its own centring and scaling) with the standard SH
# layout, which ddhgs reads as is. Both are scored against the same
# images_<d>/ JPEGs. OpenSplat's defaults densify every 500 steps after step
# 500 and before half the iterations: at 2,000 iterations, never; with
# --opensplat-args "--refine-every 100" it densifies 4 times.
# The test views are the ones ddhgs withholds (Hyper-NeRF split), read from
# ddhgs's own per-view metrics. ms/iteration is the whole command's wall time
# over the iterations for both tools (loading and writing included); peak RSS
# from /usr/bin/time. OMP_NUM_THREADS and ddhgs's threads are --threads (default:
# the core count; on a machine shared with other work, 1 avoids oversubscription).
set -euo pipefail

repo="$(cd "$(dirname "$0")/.." && pwd)"
iterations=2000 downscale=4 seed=0 variants=white work=/tmp/ddhgs-peer-benchmark ddhgs_args=""
opensplat_args=""
with_ddhgs=1 threads="$(nproc)"
while [ $# -gt 0 ]; do
  case "$1" in
    --iterations) iterations="$2"; shift 2 ;;
    --downscale) downscale="$2"; shift 2 ;;
    --seed) seed="$2"; shift 2 ;;
    --variants) variants="$2"; shift 2 ;;
    --work) work="$2"; shift 2 ;;
    --ddhgs-args) ddhgs_args="$2"; shift 2 ;;
    --opensplat-args) opensplat_args="$2"; shift 2 ;;
    --no-ddhgs) with_ddhgs=0; shift ;;
    --threads) threads="$2"; shift 2 ;;
    -h|--help) sed -n '2,32p' "$0"; exit 0 ;;
    *) echo "peer_benchmark.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done

shared="${DDHGS_SHARED_DIR:-$repo/../shared}"
data="$repo/tests/data/basil"
peers="$shared/peers"
ddhgs="$repo/build/ddhgs"
[ -x "$ddhgs" ] || { echo "peer_benchmark.sh: $ddhgs missing; build it first (ninja -C build ddhgs)" >&2; exit 1; }
[ -d "$data/colmap/sparse/0" ] || { echo "peer_benchmark.sh: $data/colmap/sparse/0 missing (the Basil capture)" >&2; exit 1; }
[ -x /usr/bin/time ] || { echo "peer_benchmark.sh: /usr/bin/time missing (apt-get install time)" >&2; exit 1; }
images="images"
[ "$downscale" -gt 1 ] && images="images_$downscale"
[ -d "$data/$images" ] || { echo "peer_benchmark.sh: $data/$images missing" >&2; exit 1; }

export OMP_NUM_THREADS="$threads"
mkdir -p "$work"
log="$work/log.txt"
: >"$log"
say() { echo "$*" >>"$log"; }

# Wall seconds and peak RSS (MiB) of a command, from GNU time's report.
timed() {
  local report="$1"; shift
  /usr/bin/time -v -o "$report" "$@" >>"$log" 2>&1
}
wall_s() { awk -F': ' '/Elapsed \(wall clock\)/ {n=split($2,t,":"); s=0; for(i=1;i<=n;i++) s=s*60+t[i]; print s}' "$1"; }
rss_mib() { awk -F': ' '/Maximum resident set size/ {printf "%.0f", $2/1024}' "$1"; }
json_value() { python3 -c "import json,sys; print(json.load(open(sys.argv[1]))$2)" "$1"; }

# ddhgs reads the COLMAP layout from a folder of links (the capture's own
# folder also holds transforms.json, which would be read first).
scene="$work/basil-colmap"
mkdir -p "$scene"
for d in images images_2 images_4 images_8 colmap; do
  [ -e "$data/$d" ] && ln -sfn "$data/$d" "$scene/$d"
done

rows=()
row() { rows+=("| $1 | $iterations | $2 | $3 | $4 | $5 | $6 |"); }

# A ddhgs run folder that OpenSplat's models are evaluated in (1 iteration
# writes the config; the model is replaced later). Its evaluation also names
# the test views, as ddhgs splits them.
holder() {  # holder DIR BACKGROUND
  "$ddhgs" --threads "$threads" -q train "$scene" --out "$1" --force --iterations 1 \
    --downscale "$downscale" --set model.learn_background=false \
    --set model.background_from_views=false --set model.background="$2" >>"$log" 2>&1
}
holder "$work/split" 1
"$ddhgs" --threads "$threads" -q eval "$work/split" --fps-repeats 0 >>"$log" 2>&1
mapfile -t test_views < <(awk -F, 'NR > 1 && $2 == "views" {print $1}' "$work/split/eval/per_view.csv")
say "test views: ${test_views[*]}"
[ "${#test_views[@]}" -gt 0 ] || { echo "peer_benchmark.sh: no test views in $work/split/eval/per_view.csv" >&2; exit 1; }

# --- ddhgs, default settings ---
if [ "$with_ddhgs" = 1 ]; then
  run="$work/ddhgs"
  say "== ddhgs train ($iterations iterations, downscale $downscale, seed $seed)"
  # shellcheck disable=SC2086
  timed "$work/ddhgs.time" "$ddhgs" --threads "$threads" -q train "$scene" --out "$run" --force \
    --iterations "$iterations" --downscale "$downscale" --seed "$seed" $ddhgs_args
  "$ddhgs" --threads "$threads" -q eval "$run" --fps-repeats 0 >>"$log" 2>&1
  wall="$(wall_s "$work/ddhgs.time")"
  row "ddhgs (default${ddhgs_args:+ $ddhgs_args})" \
    "$(awk -v w="$wall" -v n="$iterations" 'BEGIN{printf "%.0f", 1000*w/n}')" \
    "$(rss_mib "$work/ddhgs.time")" "$(json_value "$run/train_summary.json" "['num_gaussians']")" \
    "$(printf %.2f "$(json_value "$run/eval/metrics.json" "['psnr']")")" \
    "$(printf %.3f "$(json_value "$run/eval/metrics.json" "['ssim']")")"
fi

# --- OpenSplat's input: training views only, full resolution ---
peer_in="$work/opensplat-input"
rm -rf "$peer_in"
mkdir -p "$peer_in/images" "$peer_in/sparse/0"  # OpenSplat reads sparse/0, not colmap/sparse/0
cp "$data/colmap/sparse/0/cameras.bin" "$data/colmap/sparse/0/points3D.bin" "$peer_in/sparse/0/"
python3 - "$data/colmap/sparse/0/images.bin" "$peer_in/sparse/0/images.bin" \
  "$data/images" "$peer_in/images" "${test_views[@]}" <<'PY'
# Copies images.bin without the test views, and links the training images.
import os, struct, sys
src, dst, image_dir, out_dir, *test = sys.argv[1:]
test = set(test)
with open(src, "rb") as f:
    data = f.read()
count, = struct.unpack_from("<Q", data, 0)
pos, kept = 8, []
for _ in range(count):
    start = pos
    pos += 4 + 32 + 24 + 4
    end = data.index(b"\0", pos)
    name = data[pos:end].decode()
    pos = end + 1
    points, = struct.unpack_from("<Q", data, pos)
    pos += 8 + 24 * points
    if os.path.splitext(name)[0] not in test:
        kept.append(data[start:pos])
        os.symlink(os.path.join(image_dir, name), os.path.join(out_dir, name))
with open(dst, "wb") as f:
    f.write(struct.pack("<Q", len(kept)) + b"".join(kept))
print(f"{len(kept)} training views of {count}")
PY
say "OpenSplat input: $(find "$peer_in/images" -mindepth 1 | wc -l) training views in $peer_in"

# --- OpenSplat, one variant per background ---
IFS=, read -r -a wanted <<<"$variants"
for variant in "${wanted[@]}"; do
  case "$variant" in
    white) env_white=1 background=1 ;;
    black) env_white=0 background=0 ;;
    *) echo "peer_benchmark.sh: --variants takes white and/or black, got '$variant'" >&2; exit 2 ;;
  esac
  [ -f "$peers/build-opensplat.sh" ] || { echo "peer_benchmark.sh: $peers/build-opensplat.sh missing" >&2; exit 1; }
  dest="$work/opensplat-$variant"
  say "== building OpenSplat ($variant background) in $dest"
  binary="$(OPENSPLAT_WHITE_BACKGROUND=$env_white bash "$peers/build-opensplat.sh" "$dest" 2>>"$log" | tail -1)"
  [ -x "$binary" ] || { echo "peer_benchmark.sh: OpenSplat build failed (see $log)" >&2; exit 1; }
  out="$work/opensplat-$variant-run"
  rm -rf "$out" && mkdir -p "$out"
  say "== OpenSplat ($variant) train"
  # shellcheck disable=SC2086  # the extra arguments are words on purpose
  (cd "$out" && timed "$work/opensplat-$variant.time" "$binary" "$peer_in" -n "$iterations" -d "$downscale" \
    $opensplat_args -o "$out/splat.ply")
  # Evaluated with OpenSplat's fixed background.
  eval_run="$work/opensplat-$variant-eval"
  holder "$eval_run" "$background"
  cp "$out/splat.ply" "$eval_run/gaussians.ply"
  "$ddhgs" --threads "$threads" -q eval "$eval_run" --fps-repeats 0 >>"$log" 2>&1
  wall="$(wall_s "$work/opensplat-$variant.time")"
  row "OpenSplat ($variant background${opensplat_args:+ $opensplat_args})" \
    "$(awk -v w="$wall" -v n="$iterations" 'BEGIN{printf "%.0f", 1000*w/n}')" \
    "$(rss_mib "$work/opensplat-$variant.time")" \
    "$(awk '/^element vertex/ {print $3; exit}' "$out/splat.ply")" \
    "$(printf %.2f "$(json_value "$eval_run/eval/metrics.json" "['psnr']")")" \
    "$(printf %.3f "$(json_value "$eval_run/eval/metrics.json" "['ssim']")")"
done

load="$(cut -d' ' -f1-3 /proc/loadavg)"
echo "Basil, COLMAP layout, downscale $downscale, ${#test_views[@]} test views (${test_views[*]}), $threads threads, load average $load"
echo
echo "| tool | iterations | ms / iteration (wall) | peak RSS MiB | Gaussians | test PSNR dB | test SSIM |"
echo "| --- | --- | --- | --- | --- | --- | --- |"
printf '%s\n' "${rows[@]}"
