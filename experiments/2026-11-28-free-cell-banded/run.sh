#!/usr/bin/env bash
# The banded true triaxial tests (0.5 MPa, constant p, b = 0.25, 0.5, 0.75; paper-fast.toml at 19,436
# spheres) in a cell whose shear stresses are held at zero, beside the fixed cell's published run
# (experiments/2026-11-28-campaign-full: its results directory). Run from the repository root; about
# 20 min on 2 cores. FIXED: the paper-fast results directory holding the fixed cell's tests and the
# prepared sample-p0_500kPa.h5 (the campaign's command is in that experiment's README).
set -euo pipefail
here=experiments/2026-11-28-free-cell-banded
fixed=${FIXED:-results/paper-fast}
out=${OUT:-results/free-cell}
mkdir -p "$out"
cp -n "$fixed/sample-p0_500kPa.h5" "$out/"  # the same prepared sample (the free cell changes no sample key)
build/release/apps/triaxial/triaxial "$here/free.toml" --out "$out" --threads 2 --resume
/usr/bin/python3 "$here/compare.py" "$fixed" "$out" > "$here/comparison.csv"
cp "$out/index.csv" "$here/index.csv"
column -s, -t "$here/comparison.csv"
