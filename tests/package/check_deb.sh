#!/usr/bin/env bash
# The Debian package end to end (issue 47): builds sandcell_<version>_amd64.deb (tools/build_deb.sh:
# Release, portable instruction set, /usr), installs it with apt into this machine, and checks what a
# user gets: the installed triaxial (--check on the embedded default, a short run, `triaxial verify`
# of it, `triaxial analyze --help` finding its Python package), `import sandcell` with
# /usr/bin/python3 from Debian's dist-packages and a short World.step, the consumer project
# (tests/consumer) built against the installed headers with find_package(sandcell); then removes the
# package and checks that none of its files is left. Needs root (apt); prints SKIP otherwise.
# Usage: check_deb.sh SOURCE_DIR WORK_DIR
set -euo pipefail
src=$1
work=$2
if [ "$(id -u)" -ne 0 ]; then
  echo "SKIP: installing a .deb needs root"
  exit 0
fi
mkdir -p "$work"
deb=$("$src/tools/build_deb.sh" "$work/build" | tail -1)
echo "package: $deb ($(du -h "$deb" | cut -f1))"
dpkg-deb --info "$deb" | grep -E "Package|Version|Architecture|Depends"
# Every file the package holds, to check the removal against.
dpkg-deb --contents "$deb" | awk '{print $NF}' | sed 's|^\./|/|' | grep -v '/$' > "$work/files.txt"
grep -q '^/usr/bin/triaxial$' "$work/files.txt"
grep -q '^/usr/lib/python3/dist-packages/sandcell/__init__.py$' "$work/files.txt"
grep -q '^/usr/lib/x86_64-linux-gnu/cmake/sandcell/sandcellConfig.cmake$\|^/usr/lib/cmake/sandcell/sandcellConfig.cmake$' \
  "$work/files.txt"
DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$deb" > "$work/apt-install.log" 2>&1 ||
  { cat "$work/apt-install.log"; exit 1; }
trap 'DEBIAN_FRONTEND=noninteractive apt-get remove -y -qq sandcell > /dev/null 2>&1 || true' EXIT

# The app: the default config checks, a short test runs and verifies, the analysis is found.
cd "$work"
/usr/bin/triaxial --check | tee check.log
grep -q "valid" check.log
rm -rf run
cat > tiny.toml <<'TOML'
[sample]
count = 200
distribution = "uniform"
d_min = 5.0e-3
d_max = 7.5e-3
seed = 1
[material]
young = 7.0e9
[prepare]
dt_fraction = 0.5
[shear]
inertial_number = 1.0e-2
max_axial_strain = 0.005
[tests]
path = "constant_p"
b = 0.5
p0 = 0.5e6
[output]
series_interval = 20
plot = false
TOML
/usr/bin/triaxial tiny.toml --out run --threads 2 > run.log
/usr/bin/triaxial verify run/p-b0.50-p0_500kPa.h5 --threads 1 | tee verify.log
grep -q "^verified: rows 0\.\." verify.log
/usr/bin/triaxial analyze --help > analyze.log
grep -q "usage" analyze.log

# Python: Debian's interpreter finds the module in dist-packages (not the build tree).
env -u PYTHONPATH /usr/bin/python3 - <<'PY'
import sandcell as sc
assert sc.__file__.startswith("/usr/lib/python3/dist-packages/sandcell/"), sc.__file__
mat = sc.Material(density=2650.0, young=7e9, poisson=0.3, restitution=0.5, friction=0.5, rolling_friction=0.1)
model = sc.Model(0.2 * sc.rayleigh_time(2.5e-3, mat), [mat], sc.ContactSettings())
state = sc.State.generate(model, 100, d_min=5e-3, d_max=7.5e-3, solid_fraction=0.3, seed=1)
world = sc.World(model, state, threads=2)
world.step(50)
assert world.step_count == 50
print("python: sandcell", sc.__version__, "from", sc.__file__, "stepped 50")
PY

# C++: the consumer project against the installed package (no prefix given: /usr is searched).
rm -rf consumer
cmake -S "$src/tests/consumer" -B consumer -G Ninja -DCMAKE_BUILD_TYPE=Release > consumer.log 2>&1 ||
  { cat consumer.log; exit 1; }
cmake --build consumer >> consumer.log 2>&1 || { cat consumer.log; exit 1; }
grep -q "/usr/" consumer/CMakeCache.txt
./consumer/consumer

# Removal: the package and every file it brought are gone.
DEBIAN_FRONTEND=noninteractive apt-get remove -y -qq sandcell > "$work/apt-remove.log" 2>&1
trap - EXIT
if dpkg-query -W -f='${Status}' sandcell 2>/dev/null | grep -q 'install ok installed'; then
  echo "sandcell is still installed"
  exit 1
fi
left=0
while read -r f; do
  if [ -e "$f" ]; then echo "left after removal: $f"; left=1; fi
done < "$work/files.txt"
[ "$left" -eq 0 ]
echo "deb: built, installed, used (app, verify, analysis, Python, find_package) and removed cleanly"
