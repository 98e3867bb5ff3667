#!/usr/bin/env bash
# The decisive experiment's six 0.5 MPa b = 1 tests re-run with today's servo cap (20x), from the
# decisive experiment's samples (DECISIVE, default results/decisive, made by
# experiments/2026-11-28-one-csl-decisive/run.sh), to eps_q = EPS_Q (default 0.6), two at once on one
# thread each; then a folder MERGED with links to every other decisive results file and these six in
# place of the old ones, with merged index.csv files, for the decisive experiment's analyze.py:
#   bash experiments/2026-11-28-servo-cap/rerun.sh [RUN_ROOT] [EPS_Q]    (default results/servo-cap-rerun, 0.6)
#   PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-28-one-csl-decisive/analyze.py RUN_ROOT/merged \
#       --out experiments/2026-11-28-servo-cap/decisive-rerun
set -u
here=$(cd "$(dirname "$0")" && pwd)
T=${TRIAXIAL:-$PWD/build/release/apps/triaxial/triaxial}
decisive=$(cd "${DECISIVE:-results/decisive}" && pwd) || exit 2
root=${1:-results/servo-cap-rerun}
eps_q=${2:-0.6}
mkdir -p "$root" && cd "$root" || exit 2
chain() {  # the three seeds of one cell, in turn
  local cell=$1
  for s in 2017 2018 2019; do
    d=$cell-s$s
    sed -e "s/^seed = 2018/seed = $s/" -e 's/^b = \[0.0, 0.5, 1.0\]/b = [1.0]/' -e 's/^p0 = \[0.5e6, 8.0e6\]/p0 = [0.5e6]/' \
        -e "s/^max_deviatoric_strain = 0.6/max_deviatoric_strain = $eps_q/" \
        "$here/../2026-11-28-one-csl-decisive/$cell-s2018.toml" > $d.toml
    mkdir -p $d
    [ -e $d/sample-p0_500kPa.h5 ] || ln "$decisive/seed$s/sample-p0_500kPa.h5" $d/
    allow=(); [ $s = 2017 ] && allow=(--allow-change prepare.chain)  # the campaign's seed 2017 sample is paper-fast's
    "$T" $d.toml --out $d --threads 1 --resume "${allow[@]}" >> $cell.log 2>&1
  done
}
chain free & chain fixed & wait
for s in 2017 2018 2019; do for cell in free fixed; do
  d=$cell-s$s; m=merged/$d; mkdir -p $m
  for f in "$decisive"/$d/p-*.h5; do
    case $f in *checkpoint*) continue ;; esac
    b=$(basename "$f"); [ "$b" = p-b1.00-p0_500kPa.h5 ] && f=$PWD/$d/$b
    ln -sf "$f" $m/$b
  done
  { head -1 "$decisive/$d/index.csv"; grep -v "^test\|^p-b1.00-p0_500kPa," "$decisive/$d/index.csv"
    grep "^p-b1.00-p0_500kPa," $d/index.csv; } > $m/index.csv
done; done
