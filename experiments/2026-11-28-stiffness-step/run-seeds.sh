#!/usr/bin/env bash
# The stiffness step against paper-fast's fixed 0.2 t_R at 19,436 spheres, three seeds: the decisive
# experiment's free-cell samples of seeds 2017-2019 (0.5 and 8 MPa; DECISIVE, default results/decisive,
# made by experiments/2026-11-28-one-csl-decisive/run.sh) sheared again by decisive-stiffness.toml with
# the seed replaced (constant p, b = 0, 0.5, 1, I = 3e-3, to eps_q = 0.6, time.step = "stiffness",
# safety 0.8), two tests at once on one thread each; ~15 min on 2 cores. Then seeds.py compares.
#   bash experiments/2026-11-28-stiffness-step/run-seeds.sh OUT
set -u
here=$(cd "$(dirname "$0")" && pwd)
T=${TRIAXIAL:-$PWD/build/release/apps/triaxial/triaxial}
decisive=$(cd "${DECISIVE:-results/decisive}" && pwd) || exit 2
out=${1:?usage: run-seeds.sh OUT}
mkdir -p "$out" && cd "$out" || exit 2
for s in 2017 2018 2019; do
  d=free-s$s
  sed -e "s/^seed = 2017/seed = $s/" "$here/decisive-stiffness.toml" > $d.toml
  mkdir -p $d
  for p in 500 8000; do [ -e $d/sample-p0_${p}kPa.h5 ] || ln "$decisive/seed$s/sample-p0_${p}kPa.h5" $d/; done
  allow=(); [ $s = 2017 ] && allow=(--allow-change prepare.chain)  # the campaign's seed 2017 samples are paper-fast's
  "$T" $d.toml --out $d --threads 2 --resume "${allow[@]}" >> $d.log 2>&1
done
echo "done: $out"
