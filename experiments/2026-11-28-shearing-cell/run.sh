#!/usr/bin/env bash
# The shearing cell's demonstrations (README.md): simple shear to gamma = 2.2 at constant normal stress,
# on 1 thread, and on 2 threads killed with SIGKILL mid-test and resumed (compared bit for bit); the
# rotation of the principal stresses through 180 deg; their figures. Run from the repository root.
set -euo pipefail
here=experiments/2026-11-28-shearing-cell
triaxial=${TRIAXIAL:-build/release/apps/triaxial/triaxial}
work=${WORK:-/tmp/sandcell-shearing-cell}
rm -rf "$work" && mkdir -p "$work"

"$triaxial" "$here/simple-shear.toml" --out "$work/ss1" --threads 1 | tee "$work/ss1.log"
# The same on 2 threads, killed (SIGKILL: no checkpoint at the kill) once the test has written its
# first checkpoint, then resumed from it.
"$triaxial" "$here/simple-shear.toml" --out "$work/ss2" --threads 2 > "$work/ss2.log" 2>&1 &
pid=$!
for _ in $(seq 3000); do [ -e "$work/ss2/ss-p0_500kPa.checkpoint.h5" ] && break; sleep 0.1; done
sleep 2
kill -9 "$pid"; wait "$pid" || true
echo "killed at: $(tail -1 "$work/ss2.log")"
"$triaxial" "$here/simple-shear.toml" --out "$work/ss2" --threads 2 --resume | tee "$work/ss2-resumed.log"
/usr/bin/python3 tests/cluster/compare_results.py "$work/ss1" "$work/ss2"

"$triaxial" "$here/rotation.toml" --out "$work/rot" --threads 2 | tee "$work/rot.log"

PYTHONPATH=apps/analysis /usr/bin/python3 -m sandcell_analysis analyze "$work/ss1" "$work/rot" --out "$work/figures" \
    --title "sandcell shearing cell"
cp "$work"/figures/shearing-*.png "$here/"
PYTHONPATH=apps/analysis /usr/bin/python3 "$here/summarize.py" "$work/ss1/ss-p0_500kPa.h5" "$work/rot/rot-b0.50-p0_500kPa.h5" > "$here/summary.csv"
cat "$here/summary.csv"
