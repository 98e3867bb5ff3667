#!/usr/bin/env bash
# Validates the fast protocol (apps/triaxial/configs/paper-fast.toml) against the paper's
# (paper.toml) at the study's scale, from the same prepared samples:
#   1. prepares seed 2017's samples with paper-fast.toml (0.5 MPa from the cloud, then each higher
#      p0 from the next lower one);
#   2. shears constant p, b = 0 at 0.5 MPa and constant p, b = 1 at 16 MPa from those samples with
#      paper.toml (the paper's rate, 1 /s, dt = 0.2 t_R) and with paper-fast.toml;
#   3. prepares seeds 2018 and 2019 the same way and shears the same two tests fast (the
#      seed-to-seed scatter the errors stand against);
#   4. tabulates (validate_fast.py, beside this script): peak q/p, critical q/p and e (means over the last 5 % of
#      axial strain), the largest dilation rate and the strain at the peak.
# Two jobs at a time with one thread each. Every stage resumes (--resume): rerun the same command
# after an interruption. About 1.5 h on 2 cores.
#   experiments/2026-11-25-validate-fast/run.sh [TRIAXIAL] [WORKDIR]
set -euo pipefail
experiment="$(cd "$(dirname "$0")" && pwd)"
here="$(cd "$experiment/../.." && pwd)"  # the repository
triaxial="${1:-$here/build/release/apps/triaxial/triaxial}"
work="${2:-$here/results/validate-fast}"
configs="$here/apps/triaxial/configs"
mkdir -p "$work"

# narrow CONFIG P0 PATH B: the config with one test.
narrow() { sed "s/^p0 = .*/p0 = [$2]/; s/^path = .*/path = [\"$3\"]/; s/^b = .*/b = [$4]/; s/^parallel = .*/parallel = 1/" "$1"; }
seeded() { sed "s/^seed = .*/seed = $1/" "$configs/paper-fast.toml"; }
run() {  # run DIR CONFIG_TEXT THREADS [ARGS...]: one job, resumable, its log in DIR.log
  local dir="$1" text="$2" threads="$3"
  shift 3
  mkdir -p "$dir"
  printf '%s\n' "$text" > "$dir.toml"
  "$triaxial" "$dir.toml" --out "$dir" --threads "$threads" --resume "$@" > "$dir.log" 2>&1 ||
    { echo "failed: $dir (see $dir.log)"; return 1; }
}
# shear NAME SEED PROTOCOL P0 B: a constant-p test on seed SEED's prepared sample.
shear() {
  local dir="$work/$1" tag="p0_$(awk "BEGIN{print $4/1e3}")kPa"
  mkdir -p "$dir"
  [ -e "$dir/sample-$tag.h5" ] || cp "$work/prepare-s$2/sample-$tag.h5" "$dir/"
  local base="$configs/$3.toml"
  [ "$3" = "paper-fast" ] && { seeded "$2" > "$work/$1.base.toml"; base="$work/$1.base.toml"; }
  # The paper protocol shears the fast protocol's sample as it is (prepared chained, at 0.5 t_R).
  local allow=()
  [ "$3" = "paper" ] && allow=(--allow-change prepare.chain prepare.dt_fraction)
  run "$dir" "$(narrow "$base" "$4" constant_p "$5")" 1 ${allow[@]+"${allow[@]}"}
}

echo "$(date +%T) preparing seed 2017"
run "$work/prepare-s2017" "$(seeded 2017)" 2 --prepare-only
echo "$(date +%T) paper protocol, 0.5 MPa b = 0 and 16 MPa b = 1"
shear paper-p0_500kPa-b0 2017 paper 0.5e6 0.0 & a=$!
shear paper-p0_16000kPa-b1 2017 paper 16.0e6 1.0 & b=$!
wait $a; wait $b
echo "$(date +%T) fast protocol, seed 2017"
shear fast-s2017-p0_500kPa-b0 2017 paper-fast 0.5e6 0.0 & a=$!
shear fast-s2017-p0_16000kPa-b1 2017 paper-fast 16.0e6 1.0 & b=$!
wait $a; wait $b
for seed in 2018 2019; do
  echo "$(date +%T) seed $seed: preparation and the fast tests"
  run "$work/prepare-s$seed" "$(seeded $seed)" 2 --prepare-only
  shear fast-s$seed-p0_500kPa-b0 $seed paper-fast 0.5e6 0.0 & a=$!
  shear fast-s$seed-p0_16000kPa-b1 $seed paper-fast 16.0e6 1.0 & b=$!
  wait $a; wait $b
done
echo "$(date +%T) table"
PYTHONPATH="$here/apps/analysis" /usr/bin/python3 "$experiment/validate_fast.py" "$work"
