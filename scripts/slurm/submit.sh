#!/bin/bash
# Submits a partition's training to Slurm: one job array (a task per block)
# and a merge that waits for all of them (--dependency=afterok).
#
#   scripts/slurm/submit.sh BLOCKS RUN [sbatch options --] [train options]
#   scripts/slurm/submit.sh /data/blocks /data/run --cpus-per-task=8 --mem=16G -- --iterations 30000
#
# Prints the two job ids. Environment: DDHGS (the program the jobs run;
# default ddhgs on PATH of the compute nodes).
set -euo pipefail
if [ $# -lt 2 ]; then
  echo "usage: submit.sh BLOCKS RUN [sbatch options --] [train options]" >&2
  exit 2
fi
blocks="$(cd "$1" && pwd)"
run="$(realpath -m "$2")"
shift 2
here="$(cd "$(dirname "$0")" && pwd)"
sbatch_options=()
if [[ " $* " == *" -- "* ]]; then
  while [ $# -gt 0 ] && [ "$1" != "--" ]; do sbatch_options+=("$1"); shift; done
  shift
fi
if [ ! -f "$blocks/blocks.json" ]; then
  echo "submit.sh: $blocks/blocks.json: missing (write it with ddhgs partition)" >&2
  exit 2
fi
count=$(find "$blocks" -mindepth 1 -maxdepth 1 -type d -name 'block_*' | wc -l)
if [ "$count" -lt 1 ]; then
  echo "submit.sh: $blocks holds no block_* folders" >&2
  exit 2
fi
export BLOCKS="$blocks" RUN="$run"
train=$(sbatch --parsable --export=ALL --array="0-$((count - 1))" "${sbatch_options[@]}" \
  "$here/train_block.sbatch" "$@")
train="${train%%;*}"
merge=$(sbatch --parsable --export=ALL --dependency="afterok:$train" "${sbatch_options[@]}" \
  "$here/merge_blocks.sbatch")
echo "training array $train ($count blocks), merge $merge -> $run"
