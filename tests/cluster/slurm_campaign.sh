#!/usr/bin/env bash
# A campaign on a real single-node Slurm cluster, started here (munged, slurmctld, slurmd on
# 127.0.0.1, every runtime file in one temporary directory, SLURM_CONF pointing at it):
#   1. `triaxial slurm CONFIG --submit` runs tests/cluster/campaign.toml (2 p0 x 2 b, chained
#      preparations) as a preparation job, a test array and an analysis job; every test must be
#      bitwise identical to the same campaign run locally in one process;
#   2. the same campaign again, where one running test task gets SIGTERM through
#      `scancel --signal=TERM --full`: it checkpoints, exits 3 and requeues itself; the resumed
#      result must be bitwise identical too.
# The daemons are stopped by PID at the end, whatever happens. If they cannot start, the test
# fails with the reason. Needs root (slurmd starts jobs) and the Debian packages slurm-wlm and
# munge (tools/deps.sh installs them). Usage: slurm_campaign.sh TRIAXIAL PYTHON SOURCE_DIR
set -uo pipefail
triaxial="$1" python="$2" src="$3"
config="$src/tests/cluster/campaign.toml"
fail() { echo "FAIL: $*"; exit 1; }
for tool in munged slurmctld slurmd sbatch squeue scancel sinfo scontrol; do
  command -v "$tool" > /dev/null || fail "$tool not found: install slurm-wlm and munge (bash tools/deps.sh)"
done
[ "$(id -u)" -eq 0 ] || fail "needs root to start slurmd (it runs jobs as their users)"

tmp=$(mktemp -d /tmp/sandcell-slurm.XXXXXX)
chmod 755 "$tmp"
pids=()
cleanup() {
  [ -n "${SLURM_CONF:-}" ] && scancel --quiet --user=root 2>/dev/null
  for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null; done
  for pid in "${pids[@]}"; do
    for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -9 "$pid" 2>/dev/null
  done
  [ -f "$tmp/munge/pid" ] && kill "$(cat "$tmp/munge/pid")" 2>/dev/null
  rm -rf "$tmp"
}
trap cleanup EXIT
mkdir -p "$tmp/munge" "$tmp/state" "$tmp/spool" "$tmp/log"

# munge: its own key, socket and pid file.
dd if=/dev/urandom of="$tmp/munge/key" bs=1024 count=1 2> /dev/null
chmod 400 "$tmp/munge/key"
munged --key-file="$tmp/munge/key" --socket="$tmp/munge/socket" --pid-file="$tmp/munge/pid" \
  --log-file="$tmp/log/munged.log" --seed-file="$tmp/munge/seed" --force ||
  fail "munged did not start: $(tail -3 "$tmp/log/munged.log" 2>/dev/null)"

host=$(hostname -s)
port=$((20000 + RANDOM % 20000))
cat > "$tmp/slurm.conf" <<EOC
ClusterName=sandcelltest
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$port
SlurmdPort=$((port + 1))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$tmp/munge/socket
CredType=cred/munge
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool
SlurmctldPidFile=$tmp/slurmctld.pid
SlurmdPidFile=$tmp/slurmd.pid
SlurmctldLogFile=$tmp/log/slurmctld.log
SlurmdLogFile=$tmp/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
MpiDefault=none
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
NodeName=$host NodeAddr=127.0.0.1 CPUs=$(nproc) State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOC
export SLURM_CONF="$tmp/slurm.conf"
slurmctld -D -f "$SLURM_CONF" > "$tmp/log/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D -f "$SLURM_CONF" > "$tmp/log/slurmd.out" 2>&1 &
pids+=($!)
up=0
for _ in $(seq 100); do
  if sinfo -h -o %t 2> /dev/null | grep -q idle; then up=1; break; fi
  sleep 0.2
done
[ "$up" -eq 1 ] || fail "the cluster did not come up: $(tail -3 "$tmp/log/slurmctld.log" "$tmp/log/slurmd.log" 2>/dev/null)"
echo "slurm up on $host:$port ($(sinfo --version))"

# wait_idle SECONDS: until the queue is empty.
wait_idle() {
  for _ in $(seq $(( $1 * 5 ))); do
    [ -z "$(squeue -h 2> /dev/null)" ] && return 0
    sleep 0.2
  done
  squeue; fail "the campaign did not finish within $1 s"
}

# The reference: the same campaign in one process.
"$triaxial" "$config" --out "$tmp/local" --threads 2 > "$tmp/local.log" || fail "local run: $(tail -3 "$tmp/local.log")"

# 1. Submitted as arrays.
"$triaxial" slurm "$config" --out "$tmp/cluster" --cpus-per-task 1 --max-running 2 --time 00:10:00 --submit ||
  fail "triaxial slurm --submit failed"
wait_idle 300
grep -q "analyze.py: 4 test(s)" "$tmp"/cluster/slurm/logs/analyze-*.out || fail "the analysis job did not run: $(cat "$tmp"/cluster/slurm/logs/analyze-*.out)"
"$python" "$src/tests/cluster/compare_results.py" "$tmp/local" "$tmp/cluster" || fail "cluster run differs from the local run"

# 2. One running test task stopped with SIGTERM, requeued, resumed.
"$triaxial" slurm "$config" --out "$tmp/stopped" --cpus-per-task 1 --time 00:10:00 --submit || fail "second submission failed"
target=""
for _ in $(seq 600); do  # a test task that is running and has started shearing
  for job in $(squeue -h -t R -n sandcell-tests -o %i 2> /dev/null); do
    log="$tmp/stopped/slurm/logs/tests-${job}.out"
    if [ -f "$log" ] && grep -q "to axial strain" "$log"; then target=$job; break 2; fi
  done
  sleep 0.1
done
[ -n "$target" ] || fail "no running test task to stop"
sleep 0.5
# scancel may report the job "already completing": the task checkpoints and requeues within ms.
scancel --signal=TERM --full "$target" > /dev/null 2>&1
# Slurm holds a requeued job back for about two minutes (BeginTime); let it start now.
for _ in $(seq 300); do
  if [ "$(squeue -h -j "$target" -o %r 2> /dev/null)" = "BeginTime" ]; then
    scontrol update JobId="$target" StartTime=now || fail "scontrol update JobId=$target StartTime=now"
    break
  fi
  sleep 0.1
done
wait_idle 300
log="$tmp/stopped/slurm/logs/tests-${target}.out"
grep -q "(SIG[A-Z0-9]*), checkpoint written" "$log" || fail "task $target did not checkpoint on the signal: $(cat "$log")"
grep -q "requeued" "$log" || fail "task $target did not requeue itself"
grep -q "resumed at step" "$log" || fail "task $target did not resume from its checkpoint: $(cat "$log")"
"$python" "$src/tests/cluster/compare_results.py" "$tmp/local" "$tmp/stopped" || fail "the requeued campaign differs from the local run"
echo "slurm_campaign: passed (arrays bitwise identical to one process; task $target stopped, requeued, resumed bitwise identical)"
