#!/usr/bin/env bash
# Per-core throughput of the 160k scene against the 20k scene with the same step count (400), in
# alternating rounds on 1 thread. Writes dem-bench's JSON per run into OUT (percore.py reads them).
# Two binaries side by side: experiments/2026-11-29-gather-order/rounds.sh and ratios.py.
# Usage: percore.sh OUT ROUNDS BENCH
set -euo pipefail
out=$1 rounds=$2 bench=$3
mkdir -p "$out"
for r in $(seq 1 "$rounds"); do
  runs=("20k:1" "160k:2")
  [ $((r % 2)) -eq 0 ] && runs=("${runs[1]}" "${runs[0]}")  # the order alternates from round to round
  for run in "${runs[@]}"; do
    IFS=: read -r tag tile <<< "$run"
    "$bench" --tile "$tile" --steps 400 --threads 1 --json > "$out/r$r.$tag.json"
  done
done
