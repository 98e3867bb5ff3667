#!/usr/bin/env bash
# Thread scaling of sandcell beside LIGGGHTS's MPI scaling on the same machine at the same time: each
# round runs LIGGGHTS on 1 and on 2 ranks, then dem-bench on 1 and on 2 threads (the benchmark scene,
# `--compat` as in compare-liggghts.sh), and prints the four throughputs and the two codes' 1 -> 2
# ratios; the medians of the rounds' ratios come last. Not a test: a side-by-side measurement, to
# tell the machine's share of a scaling figure (a host whose shared caches are busy slows both codes'
# second core) from the engine's.
#   tools/scaling-liggghts.sh [STEPS=4000] [ROUNDS=5] [ERATE=0 (scene A) | 0.9391 (scene B)]
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/.." && pwd)
steps=${1:-4000}
rounds=${2:-5}
erate=${3:-0}
[[ "$steps" =~ ^[1-9][0-9]*$ ]] || { echo "STEPS = $steps: must be an integer >= 1" >&2; exit 2; }
[[ "$rounds" =~ ^[1-9][0-9]*$ ]] || { echo "ROUNDS = $rounds: must be an integer >= 1" >&2; exit 2; }
source "$here/liggghts/setup.sh"
deform=(); [ "$erate" != "0" ] && deform=(--deform "$erate")
liggghts_rate() {  # ranks -> M particle-steps/s of the timed run (the second "Loop time")
  OMP_NUM_THREADS=1 mpirun --allow-run-as-root -np "$1" liggghts -in "$here/liggghts/bench.in" \
    -var data dense-20k.data -var nsteps "$steps" -var erate "$erate" -log none > liggghts.out
  awk -v n="$steps" '/Loop time/ {k++; if (k == 2) printf "%.4f\n", 20000 * n / $4 / 1e6}' liggghts.out
}
sandcell_rate() {  # threads -> M particle-steps/s of the step loop
  "$bench" --steps "$steps" --threads "$1" --compat "${deform[@]}" --json |
    python3 -c 'import json, sys; print("%.4f" % (json.load(sys.stdin)["particle_steps_per_s"] / 1e6))'
}
for round in $(seq "$rounds"); do
  l1=$(liggghts_rate 1); l2=$(liggghts_rate 2)
  s1=$(sandcell_rate 1); s2=$(sandcell_rate 2)
  python3 - "$round" "$l1" "$l2" "$s1" "$s2" <<'PY'
import sys
r, l1, l2, s1, s2 = sys.argv[1], *map(float, sys.argv[2:])
print(f"round {r}: LIGGGHTS {l1:.3f} -> {l2:.3f} M ({l2 / l1:.3f}x), sandcell {s1:.3f} -> {s2:.3f} M ({s2 / s1:.3f}x), "
      f"sandcell / LIGGGHTS on 2 cores {s2 / l2:.2f}")
with open("ratios.txt", "a") as f:
    f.write(f"{l2 / l1} {s2 / s1}\n")
PY
done
python3 - <<'PY'
import statistics
rows = [tuple(map(float, line.split())) for line in open("ratios.txt")]
print(f"median 1 -> 2 scaling over {len(rows)} rounds: LIGGGHTS {statistics.median(r[0] for r in rows):.3f}x, "
      f"sandcell {statistics.median(r[1] for r in rows):.3f}x")
PY
