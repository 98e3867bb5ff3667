#!/usr/bin/env bash
# The neighbour list's skin against its builds on the study's own samples (issue 46), from the repository root:
#   bash experiments/2026-11-30-skin/run.sh PREP OUT [TRIAXIAL]
# PREP holds paper-faster.toml's preparations (sample-p0_500kPa.h5, sample-p0_16000kPa.h5: `triaxial
# apps/triaxial/configs/paper-faster.toml --out PREP --task 0-5`, ~6 min on 2 cores). Each skin shears the same
# samples at constant p, b = 0 and 0.5, 0.5 and 16 MPa, to eps_q 0.1 on one thread; the log's done lines give the
# steps and the neighbour-list builds (builds.py). ~15 min of one core.
set -eu
prep=$(cd "$1" && pwd); out=$2; T=${3:-$PWD/build/release/apps/triaxial/triaxial}
cfg=$PWD/apps/triaxial/configs/paper-faster.toml
mkdir -p "$out" && cd "$out"
for sk in 0.45 0.25 0.12; do
  # 0.45 mm is the default (0 in the config: 0.1 x the smallest diameter, 4.5 mm); the samples were prepared with it.
  extra=""; allow=""
  [ $sk != 0.45 ] && extra="skin = ${sk}e-3" && allow="--allow-change contact.skin"
  sed -e "s/^max_deviatoric_strain = .*/max_deviatoric_strain = 0.1/" -e "s/^p0 = .*/p0 = [0.5e6, 16.0e6]/" \
      -e 's/^path = .*/path = ["constant_p"]/' -e "s/^b = .*/b = [0.0, 0.5]/" -e "s/^parallel = .*/parallel = 1/" \
      -e "s/^rolling = \"epsd2\"/rolling = \"epsd2\"\n$extra/" "$cfg" > skin$sk.toml
  mkdir -p s$sk
  for p in 500kPa 16000kPa; do [ -f s$sk/sample-p0_$p.h5 ] || ln -s "$prep/sample-p0_$p.h5" s$sk/; done
  "$T" skin$sk.toml --out s$sk --threads 1 --task 2-5 --resume $allow >> s$sk.log 2>&1
done
