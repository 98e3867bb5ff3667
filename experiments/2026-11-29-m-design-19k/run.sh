#!/usr/bin/env bash
# The m design at the study's size (README): per seed (2017, 2018, 2019) six samples of 19,436 spheres
# prepared at target void ratios at 0.5 MPa and each sheared at constant p, b = 0, to eps_q = 0.6 as
# paper-faster.toml shears (config.toml). Two tests at a time on one thread each; after each pair,
# export.py keeps the ended tests in git's files (series/, searches/, tests.csv) and a test already
# there for this build is not run again, so the campaign spans machines that do not keep WORKDIR.
# Every run resumes (--resume): rerun the same command after an interruption.
#   bash experiments/2026-11-29-m-design-19k/run.sh [TRIAXIAL] [WORKDIR] [SEEDS...]
# (defaults: build/release's triaxial, results/m-design-19k, 2017 2018 2019; OUT=DIR in the environment:
# where tests.csv, series/ and searches/ are kept, default this folder, e.g. a checkout's when the
# campaign runs a copy of these scripts).
set -euo pipefail
experiment="$(cd "$(dirname "$0")" && pwd)"
here="$(cd "$experiment/../.." && pwd)"
triaxial="${1:-$here/build/release/apps/triaxial/triaxial}"
work="${2:-$here/results/m-design-19k}"
shift $(($# < 2 ? $# : 2))
seeds=("$@")
[ ${#seeds[@]} -gt 0 ] || seeds=(2017 2018 2019)
mkdir -p "$work"
# The build, for tests.csv: the commit of the checkout the binary was built in; a binary copied out of
# its checkout (a campaign's own copy) keeps WORKDIR/BUILD.txt as it is.
if commit="$(git -C "$(dirname "$triaxial")" rev-parse HEAD 2>/dev/null)"; then
  echo "$commit" > "$work/BUILD.txt"
elif [ ! -s "$work/BUILD.txt" ]; then
  echo unknown > "$work/BUILD.txt"
fi
build="$(head -n1 "$work/BUILD.txt")"
out="${OUT:-$experiment}"
export PYTHONPATH="$here/apps/analysis${PYTHONPATH:+:$PYTHONPATH}"
# exported SEED TARGET: tests.csv holds that test, ended, from this build.
exported() { [ -e "$out/tests.csv" ] && grep -q "^$1,$2,.*,$build\$" "$out/tests.csv"; }
one() {  # one SEED TARGET: prepare and shear one sample (resumable), its log beside its folder
  local dir="$work/s$1-e$2"
  if exported "$1" "$2"; then echo "$(date +%T) s$1-e$2: in tests.csv, not run"; return 0; fi
  sed "s/^seed = .*/seed = $1/; s/^target_e0 = .*/target_e0 = $2/" "$experiment/config.toml" > "$dir.toml"
  case $2 in 0.75|0.79) sed -i 's/^\(trial_count = .*\)/\1\nrolling_friction = 0.3/' "$dir.toml" ;; esac
  "$triaxial" "$dir.toml" --out "$dir" --threads 1 --resume >> "$dir.log" 2>&1 ||
    echo "$(date +%T) s$1-e$2 exited non-zero (see $dir.log; a failed test is exported with its reason)"
}
for seed in "${seeds[@]}"; do
  for pair in "0.55 0.60" "0.65 0.70" "0.75 0.79"; do
    set -- $pair
    echo "$(date +%T) seed $seed: e0 $1 and $2"
    one "$seed" "$1" & a=$!
    one "$seed" "$2" & b=$!
    wait $a; wait $b
    /usr/bin/python3 "$experiment/export.py" "$work" --out "$out"
  done
done
echo "$(date +%T) done: $work"
