#!/usr/bin/env bash
# A run stopped by SIGTERM (as Slurm stops a job at its time limit) checkpoints and exits 3 within
# seconds; --resume then ends bitwise identical to an uninterrupted run (a second signal exiting at
# once is tested in-process: tests/apps/test_triaxial.cpp). Usage: signal_resume.sh TRIAXIAL PYTHON SOURCE_DIR
set -euo pipefail
triaxial="$1" python="$2" src="$3"
config="$src/tests/cluster/campaign.toml"
work=$(mktemp -d /tmp/sandcell-signal.XXXXXX)
trap 'rm -rf "$work"' EXIT
"$triaxial" "$config" --out "$work/whole" --threads 1 > "$work/whole.log"

# wait_for FILE: until FILE exists (a test is shearing), at most 60 s.
wait_for() { for _ in $(seq 600); do [ -e "$1" ] && return 0; sleep 0.1; done; echo "FAIL: $1 never appeared"; exit 1; }

"$triaxial" "$config" --out "$work/stopped" --threads 1 > "$work/stopped.log" 2>&1 &
pid=$!
wait_for "$work/stopped/p-b0.00-p0_100kPa.h5"
sleep 1
start=$(date +%s%N)
kill -TERM "$pid"
rc=0; wait "$pid" || rc=$?
took_ms=$(( ($(date +%s%N) - start) / 1000000 ))
cat "$work/stopped.log"
[ "$rc" -eq 3 ] || { echo "FAIL: exit $rc after SIGTERM, expected 3"; exit 1; }
# Within a few seconds: one step, a checkpoint and a flush of 300 spheres (bound: 5 s).
[ "$took_ms" -lt 5000 ] || { echo "FAIL: took $took_ms ms to stop"; exit 1; }
grep -q "stopped at step [0-9]* (SIGTERM), checkpoint written" "$work/stopped.log" ||
  { echo "FAIL: no stop line naming SIGTERM"; exit 1; }
[ -e "$work/stopped/p-b0.00-p0_100kPa.checkpoint.h5" ] || { echo "FAIL: no checkpoint"; exit 1; }
"$triaxial" "$config" --out "$work/stopped" --threads 2 --resume > "$work/resumed.log"
"$python" "$src/tests/cluster/compare_results.py" "$work/whole" "$work/stopped"

echo "signal_resume: passed (stopped in $took_ms ms, exit 3, resumed bitwise identical)"
