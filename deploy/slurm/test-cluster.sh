#!/bin/bash
# Starts a one-node Slurm cluster on this machine (munged, slurmctld and slurmd as root, no
# systemd), renders each case with deploy/slurm/render.sbatch as a job array of parts plus a
# dependent merge job, checks that every merged image is byte for byte the local render, and
# stops the daemons and removes everything it made, whatever happens.
#
#   deploy/slurm/test-cluster.sh RAYSCOPE 'SCENE|PARTS|FLAGS' ...
#
# Exit status: 0 all cases identical, 1 a case differs or a job failed, 3 the cluster did not
# start (its logs are printed). Needs root and Debian's slurmctld, slurmd, slurm-client and munge.
set -euo pipefail

[ $# -ge 2 ] || { echo "usage: $0 RAYSCOPE 'SCENE|PARTS|FLAGS' ..." >&2; exit 2; }
rayscope=$(readlink -f "$1")
shift
here=$(cd "$(dirname "$0")" && pwd)
timeout_s=${SLURM_TEST_TIMEOUT:-240}

work=$(mktemp -d /tmp/rayscope-slurm.XXXXXX)
chmod 755 "$work"
pids=()
cleanup() {
  local status=$?
  # scancel first, so no job outlives the daemons.
  [ -f "$work/slurm.conf" ] && SLURM_CONF="$work/slurm.conf" scancel --quiet --user=root 2>/dev/null || true
  for ((i = ${#pids[@]} - 1; i >= 0; i--)); do kill "${pids[$i]}" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do
    for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -9 "$pid" 2>/dev/null || true
  done
  rm -rf "$work"
  exit "$status"
}
trap cleanup EXIT INT TERM

logs() {
  for f in "$work"/*.log; do
    [ -f "$f" ] && { echo "---- $(basename "$f")"; tail -n 40 "$f"; }
  done >&2
}

host=$(hostname -s)
# Ports of their own, away from a real Slurm's 6817/6818.
port=$((20000 + RANDOM % 20000))

# MUNGE: a fresh key, a socket in the work folder.
dd if=/dev/urandom of="$work/munge.key" bs=1024 count=1 status=none
chmod 400 "$work/munge.key"
munged --force --key-file="$work/munge.key" --socket="$work/munge.sock" \
  --pid-file="$work/munged.pid" --log-file="$work/munged.log" --seed-file="$work/munged.seed" \
  --foreground 2>"$work/munged.err" &
pids+=($!)

mkdir -p "$work/state" "$work/spool"
cpus=$(nproc)
cat >"$work/slurm.conf" <<EOF
ClusterName=rayscope-test
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$port
SlurmdPort=$((port + 1))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$work/munge.sock
CredType=cred/munge
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/slurmctld.log
SlurmdLogFile=$work/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SwitchType=switch/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
MinJobAge=600
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF="$work/slurm.conf"

for _ in $(seq 50); do [ -S "$work/munge.sock" ] && break; sleep 0.1; done
# In the foreground, so that their process ids are ours to stop; they log to their log files.
slurmctld -D -i -f "$SLURM_CONF" 2>"$work/slurmctld.err" &
pids+=($!)
slurmd -D -f "$SLURM_CONF" 2>"$work/slurmd.err" &
pids+=($!)

up=''
for _ in $(seq 60); do
  state=$(sinfo -h -n "$host" -o %T 2>/dev/null || true)
  case "$state" in idle*) up=1; break ;; esac
  sleep 0.5
done
if [ -z "$up" ]; then
  echo "error: the Slurm node did not come up in 30 s (state: '${state:-none}')" >&2
  logs
  exit 3
fi
echo "slurm: one-node cluster '$host' up ($cpus CPUs, port $port)"

# Submit every case: an array of parts, and a merge job that waits for all of them.
declare -a names outs locals flagss scenes jobs
n=0
for case in "$@"; do
  IFS='|' read -r scene parts flags <<<"$case"
  scene=$(readlink -f "$scene")
  dir="$work/case$n"
  mkdir -p "$dir"
  export RAYSCOPE="$rayscope" SCENE="$scene" OUTPUT="$dir/final.png" PARTS="$parts" FLAGS="$flags" \
    PART_DIR="$dir/parts" FRAMES=''
  array=$(sbatch --parsable --chdir="$dir" --cpus-per-task=1 --array="0-$((parts - 1))" "$here/render.sbatch")
  merge=$(sbatch --parsable --chdir="$dir" --cpus-per-task=1 --dependency="afterok:$array" "$here/render.sbatch")
  echo "slurm: case $n: $(basename "$scene") $flags, $parts parts: array job $array, merge job $merge"
  names[n]=$(basename "$scene")
  outs[n]="$dir/final.png"
  scenes[n]=$scene
  flagss[n]=$flags
  jobs[n]="$array $merge"
  n=$((n + 1))
done

# Wait, bounded, for the queue to empty.
deadline=$((SECONDS + timeout_s))
while [ -n "$(squeue -h -o %i 2>/dev/null)" ]; do
  if [ $SECONDS -ge $deadline ]; then
    echo "error: jobs still queued or running after ${timeout_s} s:" >&2
    squeue >&2 || true
    logs
    exit 1
  fi
  sleep 1
done

status=0
for ((i = 0; i < n; i++)); do
  for j in ${jobs[$i]}; do
    # Every task of the array and the merge must have completed with exit code 0.
    bad=$(scontrol -o show job "$j" | grep -v 'JobState=COMPLETED.*ExitCode=0:0' || true)
    if [ -n "$bad" ]; then
      echo "error: case $i: job $j did not complete: $bad" >&2
      cat "$work/case$i"/rayscope-*.log >&2 2>/dev/null || true
      status=1
    fi
  done
  # shellcheck disable=SC2086 # the flags are words
  "$rayscope" -f "${scenes[$i]}" -o "$work/case$i/local.png" --quiet ${flagss[$i]}
  if [ -f "${outs[$i]}" ] && cmp -s "${outs[$i]}" "$work/case$i/local.png"; then
    echo "slurm: case $i: ${names[$i]}: merged image identical to the local render ($(stat -c %s "${outs[$i]}") bytes)"
  else
    echo "error: case $i: ${names[$i]}: the merged image is missing or differs from the local render" >&2
    cat "$work/case$i"/rayscope-*.log >&2 2>/dev/null || true
    status=1
  fi
done
[ $status -eq 0 ] || logs
exit $status
