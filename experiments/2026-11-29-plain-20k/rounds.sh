#!/usr/bin/env bash
# Alternating rounds of dem-bench binaries on the plain dense-20k scene (no servo: dem-bench's
# default), issue 46's "1-thread throughput +15 % over today's main" and "2 threads over 1 thread
# of its round": each round runs every binary, in an order rotated from round to round, on 1 and on
# 2 threads, 1,600 steps each. One JSON per run in OUT, named as ../2026-11-29-gather-order's
# ratios.py reads them (S<threads>-<round>-<name>.json).
#   bash rounds.sh OUT ROUNDS NAME=BINARY NAME=BINARY ...
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
    for t in 1 2; do
      "${bins[$k]}" --steps 1600 --threads "$t" --json > "$out/S$t-$r-${names[$k]}.json"
    done
  done
done
