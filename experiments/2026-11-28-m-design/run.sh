#!/usr/bin/env bash
# The m design (issue 45 item 3), re-run from the repository root:
#   bash experiments/2026-11-28-m-design/run.sh [RUN_ROOT]     (default results/m-design)
# One sample per target void ratio at 0.5 MPa (prepare.target_e0: 0.75 and 0.79 also with
# prepare.rolling_friction = 0.3, as friction alone reaches 0.736 at most), each sheared at constant p,
# b = 0, to eps_q = 0.6 in a fixed cell (e<e0>) and in a free one (e<e0>-free, the same sample).
# Rerun to resume. ~1.5 h on 2 cores.
set -u
here=$(cd "$(dirname "$0")" && pwd)
T=${TRIAXIAL:-$PWD/build/release/apps/triaxial/triaxial}
root=${1:-results/m-design}
mkdir -p "$root" && cd "$root" || exit 2
for e in 0.55 0.60 0.65 0.70 0.75 0.79; do
  sed "s/^target_e0 = .*/target_e0 = $e/" "$here/config.toml" > e$e.toml
  case $e in 0.75|0.79) sed -i 's/^trial_count = 2000/trial_count = 2000\nrolling_friction = 0.3/' e$e.toml ;; esac
  sed 's/^\[output\]/[cell]\nshear = "free"\n\n[output]/' e$e.toml > e$e-free.toml
  $T e$e.toml --out e$e --threads 1 --resume >> run.log 2>&1 || $T e$e.toml --out e$e --threads 1 >> run.log 2>&1
  mkdir -p e$e-free && { [ -f e$e-free/sample-p0_500kPa.h5 ] || cp e$e/sample-p0_500kPa.h5 e$e-free/; }
  $T e$e-free.toml --out e$e-free --threads 1 --resume >> run.log 2>&1
done
