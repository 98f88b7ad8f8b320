#!/bin/bash
# End to end on a real scheduler: brings up a single-node Slurm (munged,
# slurmctld and slurmd with a generated slurm.conf, all in a temporary
# folder, on ports of their own), cuts a small synthetic survey into blocks
# (ddhgs partition), trains them as a job array and merges them in a
# dependent job (scripts/slurm/submit.sh), checks that the merged run
# evaluates every held-out view of the flight, and tears everything down.
#
#   tests/slurm/single_node_slurm.sh build/ddhgs
#
# Needs root (the daemons run as root here) and Debian's slurm-wlm and
# munge (scripts/setup.sh --with-tests installs them). Not root, it prints a
# GoogleTest-style SKIPPED line (tests/expected_skips.txt lists it) and
# exits 77, which ctest counts as skipped; root without the packages fails.
set -euo pipefail
name="SlurmBlocks.PartitionArrayMerge"
ddhgs="$(realpath "${1:?usage: single_node_slurm.sh DDHGS}")"
repo="$(cd "$(dirname "$0")/../.." && pwd)"
skip() {
  echo "[  SKIPPED ] $name ($1)"
  exit 77
}
[ "$(id -u)" = 0 ] || skip "needs root to run munged, slurmctld and slurmd"
# As root a missing package is a failure: scripts/setup.sh --with-tests installs them.
for tool in munged slurmctld slurmd sbatch squeue sinfo scancel; do
  command -v "$tool" >/dev/null || {
    echo "$name: $tool is not installed (scripts/setup.sh --with-tests installs slurm-wlm and munge)" >&2
    exit 1
  }
done

tmp="$(mktemp -d /tmp/ddhgs-slurm.XXXXXX)"
chmod 755 "$tmp"
teardown() {
  local status=$?
  if [ -f "$tmp/slurm.conf" ]; then
    SLURM_CONF="$tmp/slurm.conf" scancel --quiet --user=root 2>/dev/null || true
  fi
  for pid_file in "$tmp/slurmd.pid" "$tmp/slurmctld.pid" "$tmp/munged.pid"; do
    if [ -f "$pid_file" ]; then
      local pid
      pid="$(cat "$pid_file")"
      kill "$pid" 2>/dev/null || true
      for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
      kill -9 "$pid" 2>/dev/null || true
    fi
  done
  if [ "$status" != 0 ] && [ "$status" != 77 ]; then
    for log in "$tmp"/*.log "$tmp"/work/*.out; do
      [ -f "$log" ] && { echo "--- $log"; tail -n 30 "$log"; }
    done
  fi
  rm -rf "$tmp"
  exit "$status"
}
trap teardown EXIT

# munge: a key of our own and a socket in the temporary folder.
mkdir -p "$tmp/munge"
chmod 700 "$tmp/munge"
dd if=/dev/urandom of="$tmp/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$tmp/munge/munge.key"
munged --force --key-file="$tmp/munge/munge.key" --socket="$tmp/munge/munge.socket" \
  --pid-file="$tmp/munged.pid" --log-file="$tmp/munged.log" --seed-file="$tmp/munge/seed"

# Ports no other Slurm here uses: from the process id.
port=$((20000 + ($$ % 2000) * 2))
host="$(hostname -s)"
cpus="$(nproc)"
memory_mib=$(($(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 / 2))
mkdir -p "$tmp/state" "$tmp/spool" "$tmp/work"
cat >"$tmp/slurm.conf" <<CONF
ClusterName=ddhgs-test
SlurmctldHost=$host
SlurmctldPort=$port
SlurmdPort=$((port + 1))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$tmp/munge/munge.socket
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool
SlurmctldPidFile=$tmp/slurmctld.pid
SlurmdPidFile=$tmp/slurmd.pid
SlurmctldLogFile=$tmp/slurmctld.log
SlurmdLogFile=$tmp/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
MpiDefault=none
ReturnToService=2
SlurmdTimeout=60
NodeName=$host CPUs=$cpus RealMemory=$memory_mib State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF="$tmp/slurm.conf"
slurmctld -f "$SLURM_CONF"
slurmd -f "$SLURM_CONF"
for _ in $(seq 120); do
  state="$(sinfo -h -o %T 2>/dev/null | head -n 1 || true)"
  [ "$state" = idle ] && break
  sleep 0.5
done
[ "$state" = idle ] || { echo "$name: the node never became idle (state '$state')" >&2; exit 1; }

# A small survey, cut into two blocks, trained as a job array and merged.
cd "$tmp/work"
"$ddhgs" -q synth --preset rig-nadir --views 12 --lines 2 --field-spacing 1.5 --width 32 \
  --height 24 --supersample 1 --out flight
"$ddhgs" -q partition flight/cubes --blocks 2 --out blocks
DDHGS="$ddhgs" "$repo/scripts/slurm/submit.sh" blocks merged --cpus-per-task=1 \
  --chdir="$tmp/work" -- --preset demo --iterations 20 --checkpoint-every 0
for _ in $(seq 600); do
  [ -z "$(squeue -h 2>/dev/null)" ] && break
  sleep 1
done
[ -z "$(squeue -h)" ] || { echo "$name: jobs still queued after 10 minutes" >&2; squeue; exit 1; }
for block in blocks/block_*; do
  [ -f "$block/run/gaussians.ply" ] || { echo "$name: $block was not trained" >&2; exit 1; }
done
[ -f merged/gaussians.ply ] || { echo "$name: the merge job wrote no run" >&2; exit 1; }
"$ddhgs" -q eval merged
held_out=$("$ddhgs" info flight/cubes 2>&1 | sed -n 's/^views .*test \([0-9]\+\)).*/\1/p')
views=$(grep -c ',views,' merged/eval/per_view.csv)
if [ -z "$held_out" ] || [ "$views" != "$held_out" ]; then
  echo "$name: eval measured $views views, the flight holds $held_out held out" >&2
  exit 1
fi
echo "[       OK ] $name (a 2-block job array and its merge on a single-node Slurm; $views held-out views evaluated)"
