#!/usr/bin/env bash
# Builds the Debian package sandcell_<version>_amd64.deb: a Release build for the portable
# instruction set, installed under /usr with the Python module in Debian's dist-packages, no tests.
# Usage: tools/build_deb.sh [--target TARGET] [BUILD_DIR] (default build/deb); prints the .deb's
# path on its last line. With --target, builds only TARGET of that tree and packs nothing (the test
# suite's portable dem-bench, tests/CMakeLists.txt; the package is then built from the same tree).
# Idempotent: an existing build directory is reused.
set -euo pipefail
src=$(cd "$(dirname "$0")/.." && pwd)
target=
if [ "${1:-}" = "--target" ]; then
  [ -n "${2:-}" ] || { echo "build_deb.sh: --target needs a target name" >&2; exit 2; }
  target=$2
  shift 2
fi
build=${1:-$src/build/deb}
mkdir -p "$(dirname "$build")"
cmake -S "$src" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DSANDCELL_ARCH=portable \
  -DCMAKE_INSTALL_PREFIX=/usr -DSANDCELL_PYTHON_INSTALL_DIR=lib/python3/dist-packages \
  -DSANDCELL_BUILD_TESTS=OFF > "$build.configure.log" 2>&1 || { cat "$build.configure.log"; exit 1; }
if [ -n "$target" ]; then
  cmake --build "$build" --target "$target"
  exit 0
fi
cmake --build "$build"
(cd "$build" && cpack -G DEB > cpack.log 2>&1) || { cat "$build/cpack.log"; exit 1; }
ls "$build"/sandcell_*_*.deb | tail -1
