#!/usr/bin/env bash
# Per-core throughput of the 160k scene against the 20k scene with the same step count, in
# alternating rounds (1 thread), and optionally a second binary against the first on the 160k
# scene (the gather's j-side bound). Writes dem-bench's JSON per run into OUT.
# Usage: percore.sh OUT ROUNDS BENCH [OTHER_BENCH]
set -euo pipefail
out=$1 rounds=$2 bench=$3 other=${4:-}
mkdir -p "$out"
for r in $(seq 1 "$rounds"); do
  if [ -z "$other" ]; then
    runs=("20k:$bench:1" "160k:$bench:2")
  else
    runs=("160k-a:$bench:2" "160k-b:$other:2")
  fi
  [ $((r % 2)) -eq 0 ] && runs=("${runs[1]}" "${runs[0]}")  # the order alternates from round to round
  for run in "${runs[@]}"; do
    IFS=: read -r tag bin tile <<< "$run"
    "$bin" --tile "$tile" --steps 400 --threads 1 --json > "$out/r$r.$tag.json"
  done
done
