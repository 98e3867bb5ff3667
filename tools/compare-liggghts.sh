#!/usr/bin/env bash
# Runs LIGGGHTS (Debian package `liggghts`) and dem-bench one after the other on the same scene,
# with the same settings and core count, and prints both throughputs, their ratio, and the mean
# stress and contacts per particle of each code. Not a test: a side-by-side measurement.
#   tools/compare-liggghts.sh [STEPS=20000, the scenes' length] [CORES=2] [ERATE=0 (scene A) | 0.9391 (scene B)] [ROUNDS=1]
# With ROUNDS > 1 the two codes run alternately that many times (LIGGGHTS first in each round), and
# the median of the per-round ratios is printed last: on a shared machine whose speed drifts by
# 10-15 % over minutes, a pair of runs a minute apart is the fairest comparison, and the median of
# several pairs the figure to quote.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/.." && pwd)
steps=${1:-20000}
cores=${2:-2}
erate=${3:-0}
rounds=${4:-1}
[[ "$rounds" =~ ^[1-9][0-9]*$ ]] || { echo "ROUNDS = $rounds: must be an integer >= 1" >&2; exit 2; }
source "$here/liggghts/setup.sh"
deform=(); [ "$erate" != "0" ] && deform=(--deform "$erate")
for round in $(seq "$rounds"); do
  [ "$rounds" -gt 1 ] && echo "round $round of $rounds"
  OMP_NUM_THREADS=1 mpirun --allow-run-as-root -np "$cores" liggghts -in "$here/liggghts/bench.in" \
    -var data dense-20k.data -var nsteps "$steps" -var erate "$erate" -log none > liggghts.out
  loop=$(awk '/Loop time/ {n++; if (n == 2) print $4}' liggghts.out)  # the timed run, between the two `run 0`
  mapfile -t thermo < <(awk '/^ *Step/ {getline; print}' liggghts.out)
  lmp_start=${thermo[0]}; lmp_end=${thermo[${#thermo[@]}-1]}
  "$bench" --steps "$steps" --threads "$cores" --compat "${deform[@]}" --json > sandcell.json
  python3 - "$loop" "$steps" "$lmp_start" "$lmp_end" sandcell.json <<'PY'
import json, sys
loop, steps = float(sys.argv[1]), int(sys.argv[2])
start, end = sys.argv[3].split(), sys.argv[4].split()
s = json.load(open(sys.argv[5]))
n = s["particles"]
lig = n * steps / loop
print(f"LIGGGHTS : loop {loop:.2f} s, {lig/1e6:.3f} M particle-steps/s, contacts/particle {float(start[1]):.4f} -> {float(end[1]):.4f}, "
      f"mean stress {float(start[2])/1e6:.4f} -> {float(end[2])/1e6:.4f} MPa")
print(f"sandcell : loop {s['wall_s']:.2f} s, {s['particle_steps_per_s']/1e6:.3f} M particle-steps/s, contacts/particle "
      f"{s['contacts_per_particle_start']:.4f} -> {s['contacts_per_particle']:.4f}, mean stress "
      f"{s['mean_stress_start_pa']/1e6:.4f} -> {s['mean_stress_pa']/1e6:.4f} MPa")
print(f"ratio    : sandcell / LIGGGHTS throughput = {s['particle_steps_per_s']/lig:.2f}; "
      f"mean stress differs by {100*(s['mean_stress_pa']/float(end[2])-1):+.2f} %, "
      f"contacts by {100*(s['contacts_per_particle']/float(end[1])-1):+.2f} %")
with open("ratios.txt", "a") as f:
    f.write(f"{s['particle_steps_per_s']/lig:.4f}\n")
PY
done
if [ "$rounds" -gt 1 ]; then
  python3 - <<'PY'
import statistics
r = [float(x) for x in open("ratios.txt")]
print(f"median ratio over {len(r)} rounds: {statistics.median(r):.2f} (rounds: {', '.join(f'{x:.2f}' for x in r)})")
PY
fi
