#!/bin/bash
# Alternates two dem-bench binaries on the bench scene, N rounds, T threads, extra dem-bench
# options after them (e.g. --tile 2 --steps 200); prints "round label particle_steps_per_s".
# Usage: rounds.sh OLD NEW N T [options...]
OLD=$1; NEW=$2; N=${3:-10}; T=${4:-1}; shift 4
SCENE=${SCENE:-apps/dem-bench/scenes/dense-20k.txt}
OPTS=("$@"); [ ${#OPTS[@]} -eq 0 ] && OPTS=(--steps 1000)
for r in $(seq 1 "$N"); do
  for v in old new; do
    b=$OLD; [ $v = new ] && b=$NEW
    "$b" --scene "$SCENE" --threads "$T" --json "${OPTS[@]}" |
      /usr/bin/python3 -c "import json,sys; print('$r $v', json.load(sys.stdin)['particle_steps_per_s'])"
  done
done
