#!/usr/bin/env bash
# Exploratory, chosen after the interim data (README, "A slower shear for the band"): the banded
# test (constant p, b = 0.5; 500 kPa unless P0_KPA says) of seeds 2017 and 2018 sheared as paper-faster.toml but at a
# lower inertial number, from the same prepared samples as the validation's pairs, to see whether
# the band's looser end e (paper-faster minus paper +0.009 to +0.017) is the shear rate's.
# Usage: explore_inertial.sh TRIAXIAL WORKDIR [INERTIAL_NUMBER (1.0e-3)] [P0_KPA (500)] [SEEDS ("2017 2018")] [B (0.5)]
# WORKDIR: the validation's (run.sh), holding prepare-sSEED with its samples.
set -euo pipefail
experiment="$(cd "$(dirname "$0")" && pwd)"
here="$(cd "$experiment/../.." && pwd)"
configs="$here/apps/triaxial/configs"
source "$experiment/configs.sh"  # narrow, seeded
triaxial=$1 work=$2 inertial=${3:-1.0e-3} kpa=${4:-500} seeds=${5:-"2017 2018"} b=${6:-0.5}
tag="i${inertial}"
for seed in $seeds; do
  dir="$work/paper-faster-$tag-s$seed-p0_${kpa}kPa-b$b"
  mkdir -p "$dir"
  [ -e "$dir/sample-p0_${kpa}kPa.h5" ] || ln "$work/prepare-s$seed/sample-p0_${kpa}kPa.h5" "$dir/"
  narrow <(seeded paper-faster "$seed") "${kpa}.0e3" "$b" |
    sed "s/^inertial_number = .*/inertial_number = $inertial/" > "$dir.toml"
  "$triaxial" "$dir.toml" --out "$dir" --threads 1 --resume \
    >> "$dir.log" 2>&1 &
done
wait
