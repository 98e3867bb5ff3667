#!/usr/bin/env bash
# Alternating rounds of dem-bench binaries (issue 46): each round runs every binary, in an order
# rotated from round to round, on the 160,000-sphere scene (--tile 2, 200 steps) and on dense-20k
# (1,600 steps: the same particle-steps), on 1 and 2 threads. One JSON per run in OUT.
#   bash rounds.sh OUT ROUNDS NAME=COMMAND NAME=COMMAND ...
# COMMAND: a dem-bench binary and any options of its own, split at spaces (no spaces in paths).
# SCENES (environment, default "L S") picks the scenes: SCENES=S runs dense-20k alone (binaries
# older than --tile; experiments/2026-11-29-plain-20k). THREADS (default "1 2") picks the thread counts.
set -euo pipefail
out=$1 rounds=$2
shift 2
mkdir -p "$out"
names=() bins=()
for a in "$@"; do names+=("${a%%=*}"); bins+=("${a#*=}"); done
n=${#names[@]}
for r in $(seq 1 "$rounds"); do
  for i in $(seq 0 $((n - 1))); do
    k=$(((i + r) % n))
    for t in ${THREADS:-1 2}; do
      read -ra cmd <<< "${bins[$k]}"
      for scene in ${SCENES:-L S}; do
        case $scene in
          L) "${cmd[@]}" --tile 2 --steps 200 --threads "$t" --json > "$out/L$t-$r-${names[$k]}.json" ;;
          S) "${cmd[@]}" --steps 1600 --threads "$t" --json > "$out/S$t-$r-${names[$k]}.json" ;;
          *) echo "SCENES: $scene is not a scene (L: 160,000 spheres, S: dense-20k)" >&2; exit 2 ;;
        esac
      done
    done
  done
done
