#!/bin/bash
# The seven 1,000-sphere calibrations of experiments/2026-11-25-calibration, re-run as published with
# the stress-path watchdog. From the repository root:
#   experiments/2026-11-28-calibration-watchdog/run.sh [OUT]       (OUT: results/calibration-watchdog)
# TRIAXIAL picks the binary (default: triaxial on the PATH). Each calibration's log is OUT/log-NAME.txt;
# a calibration that cannot fit exits 1 and the next one runs. Resumable (--resume).
set -u
OUT=${1:-results/calibration-watchdog}
T=${TRIAXIAL:-triaxial}
C=apps/triaxial/configs
G=experiments/2026-11-25-calibration
mkdir -p "$OUT"
run() {
  name=$1; shift
  echo "== $name $(date +%T)"
  "$T" calibrate "$@" --out "$OUT/out/$name" --threads 2 --resume > "$OUT/log-$name.txt" 2>&1
  echo "rc $? $name $(date +%T)"
}
run reduced $C/calibrate-reduced.toml --targets $G/targets-study.toml --param material.friction=0.2:0.8 --param material.rolling_friction=0.02:0.4 --budget 12
run dilatancy $C/calibrate-reduced.toml --targets $G/targets-study-dilatancy.toml --param material.friction=0.2:0.8 --param material.rolling_friction=0.02:0.4 --budget 12
run young $C/calibrate-reduced.toml --targets $G/targets-study.toml --param material.young=2e10:1e12 --param material.rolling_friction=0.02:0.2 --param material.friction=0.2:0.8 --budget 20
run full $C/calibrate-full.toml --targets $G/targets-study-full.toml --param material.friction=0.2:0.6 --param material.rolling_friction=0.02:0.2 --param material.young=2e10:3e11 --param material.restitution=0.45:0.9 --budget 24
run prep $C/calibrate-prep.toml --targets $G/targets-study-full.toml --param prepare.friction=0:0.3 --budget 8
run poisson $C/calibrate-prep.toml --targets $G/targets-study-full.toml --param material.poisson=0.15:0.35 --budget 6
run rolling $C/calibrate-reduced.toml --targets $G/targets-study.toml --param material.friction=0.2:0.8 --param material.rolling_friction=0.02:0.2 --choice contact.rolling=epsd2,epsd,cdt --budget 12
