#!/bin/bash
# The same flow on one workstation: trains a partition's blocks with
# `xargs -P` (JOBS at a time, each with THREADS threads), then merges them.
#
#   scripts/slurm/local.sh BLOCKS RUN [train options]
#   JOBS=2 THREADS=8 scripts/slurm/local.sh /data/blocks /data/run --iterations 30000
#
# Environment: JOBS (blocks trained at once; default 2), THREADS (threads
# per block; default the CPUs divided by JOBS), DDHGS (default ddhgs on
# PATH), LOGS (each block's log; default RUN.logs/). A block whose run already finished (RUN/gaussians.ply) is not
# trained again; one with a checkpoint is resumed.
set -euo pipefail
if [ $# -lt 2 ]; then
  echo "usage: local.sh BLOCKS RUN [train options]" >&2
  exit 2
fi
blocks="$1"
run="$2"
shift 2
ddhgs="${DDHGS:-ddhgs}"
jobs="${JOBS:-2}"
threads="${THREADS:-$(( $(nproc) / jobs > 0 ? $(nproc) / jobs : 1 ))}"
if [ ! -f "$blocks/blocks.json" ]; then
  echo "local.sh: $blocks/blocks.json: missing (write it with ddhgs partition)" >&2
  exit 2
fi
logs="${LOGS:-$run.logs}"
mkdir -p "$logs"
export DDHGS_BIN="$ddhgs" DDHGS_BLOCK_THREADS="$threads" DDHGS_LOGS="$logs"
# xargs puts the block after the train options: it is the last argument.
# shellcheck disable=SC2016  # expanded by the inner bash
find "$blocks" -mindepth 1 -maxdepth 1 -type d -name 'block_*' -print0 | sort -z |
  xargs -0 -n 1 -P "$jobs" bash -c '
    set -euo pipefail
    block="${*: -1}"
    set -- "${@:1:$#-1}"
    log="$DDHGS_LOGS/$(basename "$block").log"
    if [ -f "$block/run/gaussians.ply" ]; then exit 0; fi
    if [ -f "$block/run/checkpoint.pt" ]; then
      exec "$DDHGS_BIN" --threads "$DDHGS_BLOCK_THREADS" train --resume "$block/run" >>"$log" 2>&1
    fi
    exec "$DDHGS_BIN" --threads "$DDHGS_BLOCK_THREADS" train "$block" --out "$block/run" "$@" \
      >>"$log" 2>&1
  ' train-block "$@" || { echo "local.sh: a block failed; see $logs/" >&2; exit 1; }
"$ddhgs" merge "$blocks" --out "$run"
