#!/usr/bin/env bash
# The decisive experiment's six 0.5 MPa b = 0 tests continued from eps_q = 0.6 to EPS_Q (default 0.9)
# from their final checkpoints: copies of their results files and checkpoints in RUN_ROOT, resumed
# with shear.max_deviatoric_strain raised (a finished test goes on as if it had never stopped), two at
# once on one thread each. Then RUN_ROOT/merged: links to every decisive results file, with these six
# and the b = 1 re-runs to the same strain (B1_ROOT, made by `rerun.sh B1_ROOT EPS_Q`) in place of the
# old ones, and merged index.csv files, for the decisive experiment's analyze.py:
#   bash experiments/2026-11-28-servo-cap/extend-b0.sh RUN_ROOT B1_ROOT [EPS_Q]
#   PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-28-one-csl-decisive/analyze.py RUN_ROOT/merged \
#       --out experiments/2026-11-28-servo-cap/decisive-large-strain
set -u
here=$(cd "$(dirname "$0")" && pwd)
T=${TRIAXIAL:-$PWD/build/release/apps/triaxial/triaxial}
decisive=$(cd "${DECISIVE:-results/decisive}" && pwd) || exit 2
root=${1:?RUN_ROOT}
b1=$(cd "${2:?B1_ROOT}" && pwd) || exit 2
eps_q=${3:-0.9}
mkdir -p "$root" && cd "$root" || exit 2
test=p-b0.00-p0_500kPa
chain() {  # the three seeds of one cell, in turn
  local cell=$1
  for s in 2017 2018 2019; do
    d=$cell-s$s
    sed -e "s/^seed = 2018/seed = $s/" -e 's/^b = \[0.0, 0.5, 1.0\]/b = [0.0]/' -e 's/^p0 = \[0.5e6, 8.0e6\]/p0 = [0.5e6]/' \
        -e "s/^max_deviatoric_strain = 0.6/max_deviatoric_strain = $eps_q/" \
        "$here/../2026-11-28-one-csl-decisive/$cell-s2018.toml" > $d.toml
    if [ ! -e $d/.config.toml ]; then  # the finished test as the decisive run left it (copied: it will change)
      mkdir -p $d
      cp "$decisive/$d/.config.toml" "$decisive/$d/$test.h5" "$decisive/$d/$test.checkpoint.h5" $d/
      ln "$decisive/$d/sample-p0_500kPa.h5" $d/
    fi
    allow=(); [ $s = 2017 ] && allow=(--allow-change prepare.chain)  # the campaign's seed 2017 sample is paper-fast's
    "$T" $d.toml --out $d --threads 1 --resume "${allow[@]}" >> $cell.log 2>&1
  done
}
chain free & chain fixed & wait
for s in 2017 2018 2019; do for cell in free fixed; do
  d=$cell-s$s; m=merged/$d; mkdir -p $m
  for f in "$decisive"/$d/p-*.h5; do
    case $f in *checkpoint*) continue ;; esac
    b=$(basename "$f")
    case $b in $test.h5) f=$PWD/$d/$b ;; p-b1.00-p0_500kPa.h5) f=$b1/$d/$b ;; esac
    ln -sf "$f" $m/$b
  done
  { head -1 "$decisive/$d/index.csv"; grep -v "^test\|^$test,\|^p-b1.00-p0_500kPa," "$decisive/$d/index.csv"
    grep "^$test," $d/index.csv; grep "^p-b1.00-p0_500kPa," "$b1/$d/index.csv"; } > $m/index.csv
done; done
