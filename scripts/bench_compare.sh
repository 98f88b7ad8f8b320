#!/usr/bin/env bash
# Two builds of bench_train_step, interleaved case by case (base, then new;
# two rounds), so that the machine's load hits both alike. Prints wall and
# CPU seconds per iteration at 160x128 with 10k Gaussians (3, 40, 128 and
# 141 bands) and at 640x512 with 100k Gaussians (141 bands).
#   scripts/bench_compare.sh BASE_BUILD_DIR NEW_BUILD_DIR
# e.g. git worktree add /tmp/base REV && cmake -S /tmp/base -B /tmp/base/build -G Ninja \
#        -DCMAKE_BUILD_TYPE=Release -DDDHGS_BUILD_TESTS=OFF && ninja -C /tmp/base/build bench/bench_train_step
#      scripts/bench_compare.sh /tmp/base/build build
set -euo pipefail
if [ $# -ne 2 ]; then
  echo "usage: scripts/bench_compare.sh BASE_BUILD_DIR NEW_BUILD_DIR" >&2
  exit 2
fi
for dir in "$1" "$2"; do
  if [ ! -x "$dir/bench/bench_train_step" ]; then
    echo "bench_compare: $dir/bench/bench_train_step: not built" >&2
    exit 1
  fi
done
echo "load: $(cut -d' ' -f1-3 /proc/loadavg)"
for round in 1 2; do
  for case in "160 128 10000 3" "160 128 10000 40" "160 128 10000 128" "160 128 10000 141" \
    "640 512 100000 141"; do
    iterations=10
    [ "${case%% *}" = 640 ] && iterations=3
    for which in base new; do
      dir=$1
      [ "$which" = new ] && dir=$2
      # shellcheck disable=SC2086  # the case is four words on purpose
      line=$(DDHGS_THREADS="${DDHGS_THREADS:-2}" OMP_WAIT_POLICY=PASSIVE \
        "$dir/bench/bench_train_step" --only $case --iterations "$iterations" 2>&1 |
        grep 'per iteration' | sed 's/.*wall \([0-9.]*\) s, CPU \([0-9.]*\) s.*/wall \1 s, CPU \2 s/')
      echo "round $round | $case | $which | $line"
    done
  done
done
echo "load: $(cut -d' ' -f1-3 /proc/loadavg)"
