# Sourced by the side-by-side scripts in tools/ (not run on its own): checks that LIGGGHTS and the
# release dem-bench are there, sets `bench`, makes a work directory removed on exit, writes the
# benchmark scene there as a LIGGGHTS data file (dense-20k.data) and changes into it.
# Expects `here` (the tools directory) and `root` (the repository) to be set.
bench="$root/build/release/apps/dem-bench/dem-bench"
scene="$root/apps/dem-bench/scenes/dense-20k.txt"
command -v liggghts >/dev/null || { echo "liggghts not installed: apt-get install liggghts" >&2; exit 2; }
[ -x "$bench" ] || { echo "build first: cmake --preset release && cmake --build --preset release" >&2; exit 2; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
python3 "$here/liggghts/packing2data.py" "$scene" "$work/dense-20k.data"
cd "$work"
