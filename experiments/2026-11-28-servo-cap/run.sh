#!/usr/bin/env bash
# The servo's cap at b = 1 (issue 45 item 7, the 0.5 MPa b = 1 tests that left their path): each
# seed's 0.5 MPa sample of the decisive experiment (experiments/2026-11-28-one-csl-decisive/run.sh
# makes them under DECISIVE, default results/decisive), sheared at b = 1 to eps_q = 0.04 in the free
# and the fixed cell, with the cap on the sigma3 axis's rate at 10 x (the default of old) and 20 x
# (today's) the axial rate. 12 runs of ~20 s on 2 cores. From the repository root:
#   bash experiments/2026-11-28-servo-cap/run.sh [RUN_ROOT]    (default results/servo-cap)
#   /usr/bin/python3 experiments/2026-11-28-servo-cap/summary.py RUN_ROOT
set -u
here=$(cd "$(dirname "$0")" && pwd)
T=${TRIAXIAL:-$PWD/build/release/apps/triaxial/triaxial}
decisive=$(cd "${DECISIVE:-results/decisive}" && pwd) || exit 2
root=${1:-results/servo-cap}
mkdir -p "$root" && cd "$root" || exit 2
for s in 2017 2018 2019; do
  for cell in free fixed; do
    for r in 10 20; do
      d=$cell-s$s-r$r
      mkdir -p $d
      sed -e "s/^seed = 2018/seed = $s/" -e 's/^b = \[0.0, 0.5, 1.0\]/b = [1.0]/' -e 's/^p0 = \[0.5e6, 8.0e6\]/p0 = [0.5e6]/' \
          -e 's/^max_deviatoric_strain = 0.6/max_deviatoric_strain = 0.04/' \
          -e 's/^snapshot_interval = 3000/snapshot_interval = 100000/' \
          -e "s/^ramp_strain = 0.002/ramp_strain = 0.002\nmax_rate_ratio = $r.0/" \
          "$here/../2026-11-28-one-csl-decisive/$cell-s2018.toml" > $d.toml
      [ -e $d/sample-p0_500kPa.h5 ] || ln -s "$decisive/seed$s/sample-p0_500kPa.h5" $d/sample-p0_500kPa.h5
      allow=(); [ $s = 2017 ] && allow=(--allow-change prepare.chain)  # seed 2017's sample is paper-fast's own
      $T $d.toml --out $d --threads 2 --resume "${allow[@]}" 2>&1 | grep -E "done at|failed" | sed "s|^|$d: |"
    done
  done
done
