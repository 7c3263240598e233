#!/usr/bin/env bash
# Shards on a real Slurm cluster of one node on localhost: installs slurm-wlm and munge when
# missing (Debian, as root), writes a one-node slurm.conf in a temporary directory, starts
# munged, slurmctld and slurmd by hand, submits a 4-shard render of a small fog box with
# scripts/slurm/render.sh, preempts one shard (scontrol requeue: SIGTERM, the checkpoint is
# written, the task runs again and resumes), waits for the merge job, and checks the merge
# against the single run (at most one f32 step, `diff`'s max f32 steps) and that the requeued
# shard resumed. Every daemon it started is stopped on exit, whatever happens.
#
#   scripts/test-slurm.sh        # about 40 s after the release build
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
BIN=${PATHSPACE:-$root/target/release/pathspace}
[ -x "$BIN" ] || cargo build --release
say() { echo "test-slurm: $*"; }
fail() { echo "test-slurm: FAILED: $*" >&2; exit 1; }

if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
    [ "$(id -u)" = 0 ] || fail "slurm-wlm and munge are missing (apt-get install -y slurm-wlm munge, as root)"
    apt-get install -y slurm-wlm munge >/dev/null || (apt-get update >/dev/null && apt-get install -y slurm-wlm munge >/dev/null)
fi

tmp=$(mktemp -d /tmp/pathspace-slurm.XXXXXX)
chmod 755 "$tmp"
pids=()
cleanup() {
    local status=$?
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    for p in "${pids[@]}"; do
        for _ in $(seq 50); do kill -0 "$p" 2>/dev/null || break; sleep 0.1; done
        kill -9 "$p" 2>/dev/null || true
    done
    if [ $status -ne 0 ]; then
        for log in "$tmp"/*.log "$tmp"/out/*.log; do
            [ -f "$log" ] && { echo "--- $log"; tail -n 20 "$log"; } >&2
        done
    fi
    rm -rf "$tmp"
}
trap cleanup EXIT

# free TCP ports for the two daemons (another developer may run a cluster of their own)
read -r ctld_port slurmd_port < <(python3 -c '
import socket
s = [socket.socket() for _ in range(2)]
for x in s: x.bind(("127.0.0.1", 0))
print(*[x.getsockname()[1] for x in s])')
node=$(hostname -s)
mkdir -p "$tmp/state" "$tmp/spool" "$tmp/out"

dd if=/dev/urandom of="$tmp/munge.key" bs=1024 count=1 status=none
chmod 400 "$tmp/munge.key"
munged -F --force --key-file="$tmp/munge.key" --socket="$tmp/munge.socket" \
    --pid-file="$tmp/munged.pid" --log-file="$tmp/munged.log" --seed-file="$tmp/munged.seed" \
    >"$tmp/munged.out" 2>&1 &
pids+=($!)

cat > "$tmp/slurm.conf" <<CONF
ClusterName=pathspace-test
SlurmctldHost=$node(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$tmp/munge.socket
CredType=cred/munge
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool
SlurmctldPidFile=$tmp/slurmctld.pid
SlurmdPidFile=$tmp/slurmd.pid
SlurmctldLogFile=$tmp/slurmctld.log
SlurmdLogFile=$tmp/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
MpiDefault=none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
ReturnToService=2
KillWait=30
MinJobAge=300
NodeName=$node NodeAddr=127.0.0.1 CPUs=2 State=UNKNOWN
PartitionName=test Nodes=$node Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF=$tmp/slurm.conf
for _ in $(seq 50); do [ -S "$tmp/munge.socket" ] && break; sleep 0.1; done
slurmctld -D -i -f "$SLURM_CONF" >"$tmp/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D -N "$node" -f "$SLURM_CONF" >"$tmp/slurmd.out" 2>&1 &
pids+=($!)
for _ in $(seq 100); do
    sinfo -h -o %t 2>/dev/null | grep -qE '^(idle|mix|alloc)' && break
    sleep 0.2
done
sinfo -h -o %t | grep -qE '^(idle|mix|alloc)' || fail "the node did not come up: $(sinfo 2>&1)"
say "cluster up: $(sinfo -h -o '%P %D %t %c')"

# the single run, then the same render as 4 shards through Slurm; shard 1 is long enough to
# be preempted mid-way (checkpoints after every pass)
args=(--resolution 64x48 --spp 384 --seed 7 --reproducible --threads 1)
"$BIN" render scenes/fog-box.toml "${args[@]}" -o "$tmp/single.exr" >/dev/null 2>&1
export PATHSPACE=$BIN PATHSPACE_CHECKPOINT=0
read -r array merge < <(scripts/slurm/render.sh scenes/fog-box.toml --shards 4 --out "$tmp/out" \
    "${args[@]}")
say "submitted shard array $array and merge job $merge"

# preempt shard 1 once its first checkpoint exists
for _ in $(seq 300); do [ -f "$tmp/out/shard-1.checkpoint" ] && break; sleep 0.05; done
[ -f "$tmp/out/shard-1.checkpoint" ] || fail "shard 1 wrote no checkpoint"
scontrol requeue "${array}_1" && say "requeued shard 1 (${array}_1) while it ran"
# Slurm holds a requeued job for about two minutes (its EligibleTime); the test does not wait
for _ in $(seq 100); do
    scontrol show job "${array}_1" | grep -q 'JobState=PENDING' && break
    sleep 0.1
done
scontrol update JobId="${array}_1" StartTime=now

for _ in $(seq 600); do
    state=$(scontrol show job "$merge" 2>/dev/null | grep -o 'JobState=[A-Z_]*' || true)
    case $state in
        JobState=COMPLETED) break ;;
        JobState=FAILED|JobState=CANCELLED|JobState=TIMEOUT) fail "the merge job ended $state" ;;
    esac
    sleep 0.2
done
[ "$state" = JobState=COMPLETED ] || fail "the merge job did not finish ($state)"
# pathspace says where it stopped and where a resumed render continues
grep -qE '^stopped by SIGTERM after [0-9]+ of 96 spp' "$tmp/out/shard-1.log" ||
    fail "shard 1 was not stopped mid-way by the requeue"
resumed=$(grep -E '^resuming .*shard-1.checkpoint: [0-9]+ of 96 spp done' "$tmp/out/shard-1.log" || true)
[ -n "$resumed" ] || fail "shard 1 did not resume from its checkpoint"
say "shard 1 was stopped by SIGTERM and resumed with ${resumed#*: }"

steps=$("$BIN" diff "$tmp/out/merged.exr" "$tmp/single.exr" --json |
    python3 -c 'import json, sys; print(json.load(sys.stdin)["max_f32_steps"])')
[ "$steps" -le 1 ] || fail "the merge of the shards is $steps f32 steps from the single run"
say "ok: 4 shards through Slurm (one preempted and resumed), merged: at most $steps f32 step from the single run"
