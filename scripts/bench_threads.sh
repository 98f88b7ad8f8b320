#!/usr/bin/env bash
# Training on a shared machine: prints the five ratios of its bars.
#   1. Basil --downscale 4, 300 iterations, beside one CPU-bound process in
#      another session, over the same run alone            (bar: <= 1.8)
#   2. two demo-preset trainings started together, the slower over one alone
#                                                             (bar: <= 2.2)
#   3. `taskset -c 0 ddhgs train` over `--threads 1`          (bar: <= 1.1)
#   4. Basil with the denoiser (loss.diffusion=0.3, 2000 iterations, 400
#      fine-tuning steps): slowest over fastest 100-iteration block, joint
#      phase and fine-tuning, from metrics.jsonl           (bars: <= 1.3)
# Bar 5 (the count follows an affinity mask and a cgroup quota) is tested by
# tests/core/test_cpu_budget.cpp and tests/app/test_threads_cli.cpp.
#   scripts/bench_threads.sh [BUILD_DIR] [PARTS]   PARTS: any of 1234 (default all)
# Basil is the repository's copy (tests/data/basil). Environment: BASIL_ITERATIONS_4
# (default 2000), DEMO_ITERATIONS (default: the preset's). Needs a quiet machine:
# the load average is printed before and after.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
parts=${2:-1234}
ddhgs=$(realpath "$build/ddhgs")
basil=$(realpath tests/data/basil)
work=$(mktemp -d /tmp/ddhgs-bench-threads.XXXXXX)
busy_pid=
cleanup() {
  [ -n "$busy_pid" ] && kill "$busy_pid" 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT

# One CPU-bound single-thread process in a session of its own (as another
# user's login would be: its own scheduler group, so its nice value does not
# make it yield to us).
start_busy() {
  setsid nice -n 19 sh -c 'while :; do :; done' &
  busy_pid=$!
}
stop_busy() {
  kill "$busy_pid" 2>/dev/null || true
  wait "$busy_pid" 2>/dev/null || true
  busy_pid=
}
# Wall seconds of a command.
timed() {
  local start end
  start=$(date +%s.%N)
  "$@" >"$work/last.log" 2>&1 || { cat "$work/last.log" >&2; return 1; }
  end=$(date +%s.%N)
  echo "$end - $start" | bc -l
}
ratio() { printf '%.2f' "$(echo "$1 / $2" | bc -l)"; }

echo "load before: $(cut -d' ' -f1-3 /proc/loadavg); $(nproc) cores; $ddhgs"

if [[ $parts == *1* ]]; then
  alone=() busy=()
  for round in 1 2; do
    a=$(timed "$ddhgs" -q train "$basil" --rgb --out "$work/b1" --force --downscale 4 --iterations 300 \
      --checkpoint-every 0)
    start_busy
    b=$(timed "$ddhgs" -q train "$basil" --rgb --out "$work/b1" --force --downscale 4 --iterations 300 \
      --checkpoint-every 0)
    stop_busy
    alone+=("$a") busy+=("$b")
    printf 'bar 1 round %d: alone %.1f s, beside a busy process %.1f s\n' "$round" "$a" "$b"
  done
  sum_a=$(echo "${alone[0]} + ${alone[1]}" | bc -l)
  sum_b=$(echo "${busy[0]} + ${busy[1]}" | bc -l)
  echo "bar 1: Basil -d 4, 300 iterations, busy / alone = $(ratio "$sum_b" "$sum_a") (bar 1.8)"
fi

if [[ $parts == *2* || $parts == *3* ]]; then
  "$ddhgs" -q synth --preset demo --out "$work/demo" --force
  demo_args=(--preset demo --checkpoint-every 0)
  [ -n "${DEMO_ITERATIONS:-}" ] && demo_args+=(--iterations "$DEMO_ITERATIONS")
fi

if [[ $parts == *2* ]]; then
  one=$(timed "$ddhgs" -q train "$work/demo" --out "$work/d0" --force "${demo_args[@]}")
  start=$(date +%s.%N)
  "$ddhgs" -q train "$work/demo" --out "$work/d1" --force "${demo_args[@]}" &
  p1=$!
  "$ddhgs" -q train "$work/demo" --out "$work/d2" --force "${demo_args[@]}" &
  p2=$!
  wait "$p1"
  t1=$(echo "$(date +%s.%N) - $start" | bc -l)
  wait "$p2"
  t2=$(echo "$(date +%s.%N) - $start" | bc -l)
  slower=$(echo "if ($t1 > $t2) $t1 else $t2" | bc -l)
  printf 'bar 2: one demo run %.1f s; two together %.1f and %.1f s\n' "$one" "$t1" "$t2"
  echo "bar 2: slower of two / one alone = $(ratio "$slower" "$one") (bar 2.2)"
fi

if [[ $parts == *3* ]]; then
  one=0 masked=0
  for round in 1 2; do
    o=$(timed "$ddhgs" -q --threads 1 train "$work/demo" --out "$work/t1" --force "${demo_args[@]}")
    m=$(timed taskset -c 0 "$ddhgs" -q train "$work/demo" --out "$work/t2" --force "${demo_args[@]}")
    printf 'bar 3 round %d: --threads 1 %.1f s, taskset -c 0 %.1f s\n' "$round" "$o" "$m"
    one=$(echo "$one + $o" | bc -l) masked=$(echo "$masked + $m" | bc -l)
  done
  echo "bar 3: taskset -c 0 / --threads 1 = $(ratio "$masked" "$one") (bar 1.1)"
fi

if [[ $parts == *4* ]]; then
  iterations=${BASIL_ITERATIONS_4:-2000}
  timed "$ddhgs" -q train "$basil" --rgb --out "$work/b4" --force --downscale 4 \
    --iterations "$iterations" --checkpoint-every 0 --set loss.diffusion=0.3 \
    diffusion.finetune_steps=400 >/dev/null
  python3 - "$work/b4/metrics.jsonl" "$iterations" <<'EOF'
import json, sys
records = [json.loads(line) for line in open(sys.argv[1])]
iterations = int(sys.argv[2])
seconds = {r["iter"]: r["seconds"] for r in records if "seconds" in r}
gaussians = {r["iter"]: r.get("num_gaussians") for r in records}
warmup = 500  # diffusion.warmup: the joint phase starts after it
def blocks(first, last):
    times = []
    for start in range(first, last, 100):
        if start in seconds and start + 100 in seconds:
            times.append(seconds[start + 100] - seconds[start])
    return times
for name, first, last in (("joint phase", warmup, iterations),
                          ("fine-tuning", iterations, max(seconds))):
    t = blocks(first, last)
    if not t:
        print(f"bar 4: {name}: no 100-iteration blocks logged"); continue
    print(f"bar 4: {name}: {len(t)} blocks of 100, {min(t):.1f}-{max(t):.1f} s, "
          f"slowest / fastest = {max(t) / min(t):.2f} (bar 1.3)")
    print("  blocks (end iteration: s, Gaussians): " + ", ".join(
        f"{first + 100 * (i + 1)}: {v:.1f} s, {gaussians.get(first + 100 * (i + 1))}"
        for i, v in enumerate(t)))
EOF
fi
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
