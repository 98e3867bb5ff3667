#!/bin/bash
# Re-run of docs/calibration's `triaxial calibrate` runs with the stress-path watchdog (commit in ../commit).
set -u
cd /work/campaigns/recal
T=/work/campaigns/recal/prefix/bin/triaxial
I=in
run() { name=$1; shift; echo "== $name $(date +%T)"; /usr/bin/time -f "$name wall %e s" $T calibrate "$@" --out out/$name --threads 2 --resume > log-$name.txt 2>&1; echo "rc $? $name $(date +%T)"; }
run reduced $I/calibrate-reduced.toml --targets $I/targets-study.toml --param material.friction=0.2:0.8 --param material.rolling_friction=0.02:0.4 --budget 12
run dilatancy $I/calibrate-reduced.toml --targets $I/targets-study-dilatancy.toml --param material.friction=0.2:0.8 --param material.rolling_friction=0.02:0.4 --budget 12
run young $I/calibrate-reduced.toml --targets $I/targets-study.toml --param material.young=2e10:1e12 --param material.rolling_friction=0.02:0.2 --param material.friction=0.2:0.8 --budget 20
run full $I/calibrate-full.toml --targets $I/targets-study-full.toml --param material.friction=0.2:0.6 --param material.rolling_friction=0.02:0.2 --param material.young=2e10:3e11 --param material.restitution=0.45:0.9 --budget 24
run prep $I/calibrate-prep.toml --targets $I/targets-study-full.toml --param prepare.friction=0:0.3 --budget 8
run poisson $I/calibrate-prep.toml --targets $I/targets-study-full.toml --param material.poisson=0.15:0.35 --budget 6
run rolling $I/calibrate-reduced.toml --targets $I/targets-study.toml --param material.friction=0.2:0.8 --param material.rolling_friction=0.02:0.2 --choice contact.rolling=epsd2,epsd,cdt --budget 12
echo ALLDONE
