#!/usr/bin/env bash
# The decisive experiment on one CSL for every b (issue 45 item 7), re-run from the repository root:
#   bash experiments/2026-11-28-one-csl-decisive/run.sh [RUN_ROOT]     (default results/decisive)
# Each seed's two samples (0.5 and 8 MPa, each from its own cloud: prepare.toml), then its tests in a
# fixed cell and in a free one (fixed-s2018.toml / free-s2018.toml with the seed replaced), two at once
# on one thread each. Rerun to resume: every step resumes from its checkpoint. ~6 h on 2 cores (2026-11-28's build).
# Environment: JOBS=1 runs one test at a time on one thread (default 2: two at once); EXPORT=DIR keeps each
# cell's series in DIR/<cell>-s<seed> (export_series.py) as soon as its tests end; PAPER_RATE=0 skips the
# paper-rate check at the end; SEEDS="2018 2019" runs those seeds only (a second RUN_ROOT can run another seed
# beside, on the other core).
set -u
here=$(cd "$(dirname "$0")" && pwd)
T=${TRIAXIAL:-$PWD/build/release/apps/triaxial/triaxial}
jobs=${JOBS:-2}
root=${1:-results/decisive}
mkdir -p "$root" && cd "$root" || exit 2
for s in ${SEEDS:-2017 2018 2019}; do
  sed "s/^seed = 2017.*/seed = $s/" "$here/prepare.toml" > seed$s.toml
  for cell in fixed free; do
    sed "s/^seed = 2018/seed = $s/; s/^parallel = .*/parallel = $jobs/" "$here/$cell-s2018.toml" > $cell-s$s.toml
  done
  $T seed$s.toml --out seed$s --threads $jobs --task 0-1 --resume >> prep.log 2>&1 ||
    $T seed$s.toml --out seed$s --threads $jobs --task 0-1 >> prep.log 2>&1
  for cell in fixed free; do
    mkdir -p $cell-s$s
    for p in 500kPa 8000kPa; do [ -f $cell-s$s/sample-p0_$p.h5 ] || ln seed$s/sample-p0_$p.h5 $cell-s$s/; done
    $T $cell-s$s.toml --out $cell-s$s --threads $jobs --task 2-7 --resume >> tests.log 2>&1 ||
      $T $cell-s$s.toml --out $cell-s$s --threads $jobs --task 2-7 >> tests.log 2>&1
    if [ -n "${EXPORT:-}" ] && [ ! -e "$EXPORT/$cell-s$s/index.csv" ]; then  # a resumed cell keeps its first export
      /usr/bin/python3 "$here/export_series.py" $cell-s$s "$EXPORT/$cell-s$s" >> export.log 2>&1
    fi
  done
done
[ "${PAPER_RATE:-1}" = 0 ] && exit 0
# The paper's rate on the banded b = 0.5 test (free cell, seed 2017): ~2e6 steps.
mkdir -p paper-rate-s2017 && { [ -f paper-rate-s2017/sample-p0_500kPa.h5 ] || ln seed2017/sample-p0_500kPa.h5 paper-rate-s2017/; }
$T "$here/paper-rate-s2017.toml" --out paper-rate-s2017 --threads 1 --resume >> paper-rate.log 2>&1
