#!/usr/bin/env bash
# Builds the Debian package sandcell_<version>_amd64.deb: a Release build for the portable
# instruction set, installed under /usr with the Python module in Debian's dist-packages, no tests.
# Usage: tools/build_deb.sh [BUILD_DIR] (default build/deb); prints the .deb's path on its last line.
# Idempotent: an existing build directory is reused.
set -euo pipefail
src=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$src/build/deb}
cmake -S "$src" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DSANDCELL_ARCH=portable \
  -DCMAKE_INSTALL_PREFIX=/usr -DSANDCELL_PYTHON_INSTALL_DIR=lib/python3/dist-packages \
  -DSANDCELL_BUILD_TESTS=OFF > "$build.configure.log" 2>&1 || { cat "$build.configure.log"; exit 1; }
cmake --build "$build"
(cd "$build" && cpack -G DEB > cpack.log 2>&1) || { cat "$build/cpack.log"; exit 1; }
ls "$build"/sandcell_*_*.deb | tail -1
