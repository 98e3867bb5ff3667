#!/usr/bin/env bash
# Two dem-bench binaries at the same time, one thread each, each pinned to its own CPU (swapped from
# round to round): both see the same state of a shared host (its other tenants, its clock), which
# sequential rounds do not. One JSON per run in OUT, named ROUND-NAME@cpuC.json (pair_ratios.py).
#   bash pairs.sh OUT ROUNDS A_NAME=A_BINARY B_NAME=B_BINARY [dem-bench options...]
# Default options: --steps 1600 (dense-20k). The CPUs: CPUS (environment, default "0 1").
set -euo pipefail
out=$1 rounds=$2 a=$3 b=$4
shift 4
opts=("$@")
[ ${#opts[@]} -eq 0 ] && opts=(--steps 1600)
read -r c0 c1 <<< "${CPUS:-0 1}"
mkdir -p "$out"
for r in $(seq 1 "$rounds"); do
  if [ $((r % 2)) -eq 1 ]; then ca=$c0 cb=$c1; else ca=$c1 cb=$c0; fi
  taskset -c "$ca" "${a#*=}" "${opts[@]}" --threads 1 --json > "$out/$r-${a%%=*}@cpu$ca.json" &
  taskset -c "$cb" "${b#*=}" "${opts[@]}" --threads 1 --json > "$out/$r-${b%%=*}@cpu$cb.json" &
  wait
done
