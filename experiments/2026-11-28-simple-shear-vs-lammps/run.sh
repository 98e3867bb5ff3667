#!/bin/bash
# Simple shear at constant volume of a dense packing, sandcell beside LAMMPS (README.md).
#
#   experiments/2026-11-28-simple-shear-vs-lammps/run.sh [TRIAXIAL] [SCRATCH]
#
# TRIAXIAL: sandcell's triaxial app (default build/release/apps/triaxial/triaxial);
# SCRATCH: a directory for the runs (default /tmp/lmpcmp/run; about 300 MB, emptied first).
# Needs Debian's lammps (`lmp`, GRANULAR) and /usr/bin/python3 with h5py, numpy, matplotlib.
# Writes comparison.csv, divergence.csv and comparison.png beside this script, prints the tables
# of README.md, and early.csv, early.png. About 25 min on 2 cores (sandcell and LAMMPS side by side).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
tri=$(realpath "${1:-$root/build/release/apps/triaxial/triaxial}")
work=${2:-/tmp/lmpcmp/run}
py=/usr/bin/python3
rm -rf "$work"
mkdir -p "$work"
cd "$work"

# 1. The sample: 2000 equal spheres compressed isotropically to 100 kPa with friction 0.15.
"$tri" "$here/prepare.toml" --out prep --threads 1 --prepare-only
$py - <<'EOF'
import h5py
f = h5py.File("prep/sample-p0_100kPa.h5", "r")
L, x, r = f["cell"].attrs["length"], f["particles/position"][:], f["particles/radius"][:]
with open("packing.txt", "w") as o:
    o.write("%.17g %.17g %.17g %d\n" % (L[0], L[1], L[2], len(r)))
    for p, rr in zip(x, r):
        o.write("%.17g %.17g %.17g %.17g\n" % (p[0], p[1], p[2], rr))
EOF

# 2. sandcell's one-step frictionless "preparation" from packing.txt: the sample both codes start
# from (the frictional packing's positions, the tangential springs at zero).
cp "$here/shear.toml" .
sed 's/^series_interval = 1000/series_interval = 1/' shear.toml > shear-fine.toml
"$tri" shear.toml --out sand --threads 1 --prepare-only

# 3. LAMMPS from the same sample, in the background: newton on (the comparison), then newton off
# (the same physics, other round-off: how fast two runs of one code part). The direction of the
# shear (the sign of L_xz) is read from sandcell's checkpoint two steps in.
rc=0; "$tri" shear.toml --out sand --threads 1 --resume --stop-after 2 || rc=$?
[ "$rc" -eq 3 ] || { echo "expected the stop (exit 3), got $rc"; exit 1; }
$py "$here/to_lammps.py" sand/sample-p0_100kPa.h5 shear.toml sand/sscv-p0_100kPa.checkpoint.h5 .
nsteps=$($py - <<'EOF'
import math, tomllib
c = tomllib.load(open("shear.toml", "rb"))
dt = float([l.split()[2] for l in open("vars.txt") if l.split()[1] == "dt"][0])
# sandcell stops at the first step whose gamma = gamma_dot dt (n - 1) reaches max_shear_strain
print(int(math.ceil(c["shear"]["max_shear_strain"] / (c["shear"]["strain_rate"] * dt))) + 2)
EOF
)
(lmp -in "$here/shear.in" -log lammps.log -screen none $(cat vars.txt) -var nsteps "$nsteps" \
     -var every 1000 -var dump 2000 -var xzfile 1 -var out lammps -var newton on &&
 lmp -in "$here/shear.in" -log lammps-off.log -screen none $(cat vars.txt) -var nsteps "$nsteps" \
     -var every 1000 -var dump 2000 -var out lammps-off -var newton off) &
lammps=$!

# 4. sandcell's shear in three more pieces: to 200 steps before the tilt reaches +-L1/2, 5000 steps
# with a series row every step (to see the step of the flip), then on to gamma = 0.6. A resumed run
# is bitwise the uninterrupted one (apps/triaxial/README.md); only output.series_interval changes.
first=$($py - <<'EOF'
import h5py, tomllib
c = tomllib.load(open("shear.toml", "rb"))
dt = float([l.split()[2] for l in open("vars.txt") if l.split()[1] == "dt"][0])
L = h5py.File("sand/sample-p0_100kPa.h5", "r")["cell"].attrs["length"]
# |tilt(n)| = gamma_dot L3 dt (n - 1) (step 1 runs unsheared) reaches L1/2; 2 steps are done
print(int(0.5 * L[0] / (c["shear"]["strain_rate"] * L[2] * dt)) + 1 - 200 - 2)
EOF
)
rc=0; "$tri" shear.toml --out sand --threads 1 --resume --stop-after "$first" || rc=$?
[ "$rc" -eq 3 ] || { echo "expected the stop (exit 3), got $rc"; exit 1; }
rc=0; "$tri" shear-fine.toml --out sand --threads 1 --resume --stop-after 5000 || rc=$?
[ "$rc" -eq 3 ] || { echo "expected the stop (exit 3), got $rc"; exit 1; }
"$tri" shear.toml --out sand --threads 1 --resume
wait "$lammps"

# 5. More runs of the same scene and physics with other round-off, for the statistics after the
# trajectories part: sandcell with other Verlet skins (list builds, flips, pair order), LAMMPS with
# other neighbour skins; stress only.
for skin in 3e-4 4e-4; do
    mkdir -p "sand-skin$skin"
    cp sand/sample-p0_100kPa.h5 "sand-skin$skin/"
    sed -e "s/^rolling = \"none\"/rolling = \"none\"\nskin = $skin/" -e 's/^snapshot_interval = 2000/snapshot_interval = 0/' \
        shear.toml > "shear-skin$skin.toml"
done
("$tri" shear-skin3e-4.toml --out sand-skin3e-4 --threads 1 --resume --allow-change contact.skin > sand-skin3e-4.log 2>&1 &&
 "$tri" shear-skin4e-4.toml --out sand-skin4e-4 --threads 1 --resume --allow-change contact.skin > sand-skin4e-4.log 2>&1) &
more=$!
for skin in 3e-4 5e-4; do
    sed "s/^-var skin .*/-var skin $skin/" vars.txt > "vars-skin$skin.txt"
    lmp -in "$here/shear.in" -log "lammps-skin$skin.log" -screen none $(cat "vars-skin$skin.txt") -var nsteps "$nsteps" \
        -var every 1000 -var dump 1000000000 -var out "lammps-skin$skin" -var newton on
done

# 6. The first 0.05 of strain, output every 200 steps, at restitution 0.5 and 1 (no damping), and
# LAMMPS with its box deformed every 2 steps (a probe of the lag of its box behind the positions).
sed -e 's/^-var gn .*/-var gn 0/' -e 's/^-var gt .*/-var gt 0/' vars.txt > vars-e1.0.txt
for e in 0.5 1.0; do
    mkdir -p "early/e$e/sand"
    cp sand/sample-p0_100kPa.h5 "early/e$e/sand/"
    sed -e "s/^restitution = 0.5/restitution = $e/" -e 's/^max_shear_strain = 0.6/max_shear_strain = 0.05/' \
        -e 's/^series_interval = 1000/series_interval = 200/' -e 's/^snapshot_interval = 2000/snapshot_interval = 200/' \
        shear.toml > "early-e$e.toml"
    "$tri" "early-e$e.toml" --out "early/e$e/sand" --threads 1 --resume --allow-change material.restitution
done
early() {  # NAME VARS NEWTON DEFORM
    lmp -in "$here/shear.in" -log "early/$1.log" -screen none $(cat "$2") -var nsteps 39130 -var every 200 -var dump 200 \
        -var out "early/$1" -var newton "$3" -var deform "$4"
}
early e05-on vars.txt on 1
early e05-off vars.txt off 1
early e05-deform2 vars.txt on 2
early e1-on vars-e1.0.txt on 1
early e1-off vars-e1.0.txt off 1
wait "$more"

# 7. The comparison.
$py "$here/compare.py" --sandcell sand/sscv-p0_100kPa.h5 --lammps lammps --control lammps-off \
    --sandcell-more sand-skin3e-4/sscv-p0_100kPa.h5 sand-skin4e-4/sscv-p0_100kPa.h5 \
    --lammps-more lammps-skin3e-4 lammps-skin5e-4 --out "$here"
$py "$here/early.py" --dir early --out "$here"
