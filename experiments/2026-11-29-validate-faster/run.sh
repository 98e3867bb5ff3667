#!/usr/bin/env bash
# Validates paper-faster.toml (I = 3e-3, the stiffness step, the free cell) against the paper's
# protocol (paper.toml: 1 /s, dt = 0.2 t_R) in the same free cell, from the same prepared samples
# (issue 46 item 1): constant p, b = 0 and b = 0.5 (banded), at 0.5 and 16 MPa, seeds 2017-2019,
# every test to eps_q = 0.5. 24 tests; the paper's 12 take ~750,000 steps each (~4-5 h on 2 cores).
#   1. prepares each seed's six chained samples with paper-faster.toml (--prepare-only; SAMPLES17,
#      if given, holds seed 2017's, e.g. the paper-faster campaign's out/: the same [sample] and
#      [prepare], so they are linked, not redone);
#   2. shears the four tests of each seed with both protocols, two jobs at a time on one thread each;
#   3. then the slower shear's validation (README, fixed before its data): b = 0.5 at 0.5 and 16 MPa
#      at I = 1e-3 (protocol paper-faster-i1.0e-3) and at the paper's rate, seeds 2019-2021.
# Every stage resumes (--resume): rerun the same command after an interruption. The campaign spans
# sessions on machines that may not keep WORKDIR, so a test whose measures are already in TESTS
# (compare.py's tests.csv, kept in git) is not run again, and a seed none of whose tests is left is
# not prepared.
# The comparison, fixed before any of these tests ran (as in experiments/2026-11-28-stiffness-step):
# per measure, the mean paired difference D (faster - paper) over the three seeds with its SE;
# "within the seed scatter" iff |D| + 2 SE <= s, s the paper protocol's seed SD of that measure;
# "beyond" iff |D| - 2 SE > s; else "not shown". Measures: e and q/p over the last 0.1 of eps_q,
# q/p at eps_q = 0.02, the peak q/p, and the steps.
#   experiments/2026-11-29-validate-faster/run.sh [TRIAXIAL] [WORKDIR] [SAMPLES17] [TESTS]
# (PAIRED_ONLY=1 in the environment: stages 1 and 2 only.)
set -euo pipefail
experiment="$(cd "$(dirname "$0")" && pwd)"
here="$(cd "$experiment/../.." && pwd)"
triaxial="${1:-$here/build/release/apps/triaxial/triaxial}"
work="${2:-$here/results/validate-faster}"
samples17="${3:-}"
tests="${4:-$experiment/tests.csv}"
configs="$here/apps/triaxial/configs"
mkdir -p "$work"
# The build, for compare.py's tests.csv: the commit of the checkout the binary is built in (uncommitted
# engine changes are not seen: run from a clean checkout). A binary copied out of its checkout (a
# campaign's own copy, kept so that every pair is one build's) keeps the WORKDIR's BUILD.txt as it is.
if commit="$(git -C "$(dirname "$triaxial")" rev-parse HEAD 2>/dev/null)"; then
  echo "$commit" > "$work/BUILD.txt"
elif [ ! -s "$work/BUILD.txt" ]; then
  echo unknown > "$work/BUILD.txt"
fi

source "$experiment/configs.sh"  # narrow, seeded
run() {  # run DIR CONFIG_TEXT THREADS [ARGS...]: one job, resumable, its log in DIR.log
  local dir="$1" text="$2" threads="$3"
  shift 3
  mkdir -p "$dir"
  printf '%s\n' "$text" > "$dir.toml"
  "$triaxial" "$dir.toml" --out "$dir" --threads "$threads" --resume "$@" >> "$dir.log" 2>&1 ||
    { echo "failed: $dir (see $dir.log)"; return 1; }
}
# measured PROTOCOL SEED P0TAG BTAG: whether TESTS holds that test, done on its path to the end, by
# this build (a pair pairs one build's tests: another build's preparation makes other bits).
build="$(head -n1 "$work/BUILD.txt")"
measured() { [ -e "$tests" ] && grep -q "^$1,$2,$3,$4,done,True,.*,$build\$" "$tests"; }
# shear NAME SEED PROTOCOL P0 B: a constant-p test on seed SEED's prepared sample. PROTOCOL: paper,
# paper-faster, or paper-faster-iI (paper-faster at inertial number I: explore_inertial.sh's settings).
shear() {
  local dir="$work/$1" tag="p0_$(awk "BEGIN{print $4/1e3}")kPa"
  if measured "$3" "$2" "${tag#p0_}" "${1##*-b}"; then echo "$(date +%T) $1: in $(basename "$tests"), not run"; return 0; fi
  mkdir -p "$dir"
  [ -e "$dir/sample-$tag.h5" ] || ln "$work/prepare-s$2/sample-$tag.h5" "$dir/"
  case $3 in
    paper-faster-i*) seeded paper-faster "$2" | sed "s/^inertial_number = .*/inertial_number = ${3#paper-faster-i}/" ;;
    *) seeded "$3" "$2" ;;
  esac > "$work/$1.base.toml"
  local allow=()
  if [ "$3" = "paper" ]; then
    # The paper's rate and step in the same free cell; it shears paper-faster's sample as it is.
    printf '[cell]\nshear = "free"\n' >> "$work/$1.base.toml"
    allow=(--allow-change prepare.chain prepare.dt_fraction)
  fi
  run "$dir" "$(narrow "$work/$1.base.toml" "$4" "$5")" 1 ${allow[@]+"${allow[@]}"}
}

for seed in 2017 2018 2019; do
  left=0
  for proto in paper-faster paper; do for p in 500kPa 16000kPa; do for b in 0 0.5; do
    measured $proto $seed $p $b || left=$((left + 1))
  done; done; done
  if [ $left = 0 ]; then echo "$(date +%T) seed $seed: all in $(basename "$tests")"; continue; fi
  if [ "$seed" = 2017 ] && [ -n "$samples17" ]; then
    mkdir -p "$work/prepare-s2017"
    for f in "$samples17"/sample-p0_*kPa.h5; do [ -e "$work/prepare-s2017/$(basename "$f")" ] || ln "$f" "$work/prepare-s2017/"; done
  else
    echo "$(date +%T) preparing seed $seed"
    run "$work/prepare-s$seed" "$(seeded paper-faster $seed)" 2 --prepare-only
  fi
  for proto in paper-faster paper; do
    echo "$(date +%T) seed $seed, $proto"
    shear "$proto-s$seed-p0_500kPa-b0" $seed $proto 0.5e6 0.0 & a=$!
    shear "$proto-s$seed-p0_500kPa-b0.5" $seed $proto 0.5e6 0.5 & b=$!
    wait $a; wait $b
    shear "$proto-s$seed-p0_16000kPa-b0" $seed $proto 16.0e6 0.0 & a=$!
    shear "$proto-s$seed-p0_16000kPa-b0.5" $seed $proto 16.0e6 0.5 & b=$!
    wait $a; wait $b
  done
done

# PAIRED_ONLY=1 stops here (a campaign that queues other work before the third stage).
if [ "${PAIRED_ONLY:-0}" = 1 ]; then echo "$(date +%T) paired stage done (PAIRED_ONLY=1): $work"; exit 0; fi

# The slower shear for the band (README, "Fixed now for the candidate", before its data): the banded
# test (b = 0.5) at 0.5 and 16 MPa, sheared at I = 1e-3 and at the paper's rate, seeds 2019-2021. Seed
# 2019's paper tests are the loop's above; seeds 2020 and 2021 are prepared as the others.
slow=paper-faster-i1.0e-3
for seed in 2019 2020 2021; do
  left=0
  for proto in $slow paper; do for p in 500kPa 16000kPa; do
    measured $proto $seed $p 0.5 || left=$((left + 1))
  done; done
  if [ $left = 0 ]; then echo "$(date +%T) seed $seed, b = 0.5 at I = 1e-3 and the paper's rate: all in $(basename "$tests")"; continue; fi
  echo "$(date +%T) preparing seed $seed (resumed where it is done)"
  run "$work/prepare-s$seed" "$(seeded paper-faster $seed)" 2 --prepare-only
  for proto in $slow paper; do
    echo "$(date +%T) seed $seed, $proto, b = 0.5"
    shear "$proto-s$seed-p0_500kPa-b0.5" $seed $proto 0.5e6 0.5 & a=$!
    shear "$proto-s$seed-p0_16000kPa-b0.5" $seed $proto 16.0e6 0.5 & b=$!
    wait $a; wait $b
  done
done
echo "$(date +%T) done: $work"
