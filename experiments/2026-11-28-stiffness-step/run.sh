#!/usr/bin/env bash
# The stiffness time step's first scan (issue 46 item 1): one 1,000-sphere sample per pressure
# (0.5 and 16 MPa, b = 0.5, constant p, I = 3e-3, to 10 % axial strain) sheared at fixed steps of
# 0.1 and 0.2 t_R and at time.step = "stiffness" with safety 0.6-1.2. Every run shears the same
# prepared samples (the first run prepares them; the others --resume on copies). ~1 min on 2 cores.
# Usage (repository root, release build): bash experiments/2026-11-28-stiffness-step/run.sh OUT
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=${1:?usage: run.sh OUT}
T=${TRIAXIAL:-build/release/apps/triaxial/triaxial}
mkdir -p "$out"
run() {  # name, [time] table
  local dir="$out/$1"
  mkdir -p "$dir"
  [ "$1" = r0.2 ] || cp -n "$out"/r0.2/sample-*.h5 "$dir"/ 2>/dev/null || true
  (cat "$here/base.toml"; printf '%b' "$2") > "$out/$1.toml"
  "$T" "$out/$1.toml" --out "$dir" --threads 2 --resume > "$out/$1.log" 2>&1 || true
}
run r0.2 '[time]\ndt_fraction = 0.2\n'
run r0.1 '[time]\ndt_fraction = 0.1\n'
for s in 0.6 0.8 0.9 1.0 1.1 1.2; do run s$s "[time]\nstep = \"stiffness\"\nsafety = $s\n"; done
echo "done: $out"
