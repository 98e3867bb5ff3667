#!/usr/bin/env bash
# The 2-core host's two vCPUs, one against the other (issue 46: the 2-thread / 1-thread ratio).
# Each round: dense-20k (1,600 steps) on one thread pinned to CPU 0 alone, to CPU 1 alone, then on
# both at once (one copy pinned to each), then on 2 threads unpinned. One JSON per run in OUT.
#   bash run.sh OUT ROUNDS DEM_BENCH
set -euo pipefail
out=$1 rounds=$2 bench=$3
mkdir -p "$out"
for r in $(seq 1 "$rounds"); do
  taskset -c 0 "$bench" --steps 1600 --threads 1 --json > "$out/$r-alone0.json"
  taskset -c 1 "$bench" --steps 1600 --threads 1 --json > "$out/$r-alone1.json"
  taskset -c 0 "$bench" --steps 1600 --threads 1 --json > "$out/$r-both0.json" &
  taskset -c 1 "$bench" --steps 1600 --threads 1 --json > "$out/$r-both1.json" &
  wait
  "$bench" --steps 1600 --threads 2 --json > "$out/$r-two.json"
done
