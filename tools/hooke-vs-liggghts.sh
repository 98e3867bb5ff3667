#!/usr/bin/env bash
# The linear spring-dashpot ("hooke") law on two-sphere collisions: LIGGGHTS 3.8 (Debian package
# `liggghts`) against the analytic solution and a Python replica of LIGGGHTS' algorithm, and against
# sandcell once its two-sphere program exists. Not a test: a side-by-side measurement; writes
# docs/hooke-vs-liggghts.csv and docs/hooke-vs-liggghts.png and prints the tables quoted in
# docs/hooke-vs-liggghts.md.
#   tools/hooke-vs-liggghts.sh [--sandcell BIN] [--steps-per-contact 50] [--fine 500,5000] [--csv F] [--png F]
# The contract BIN must meet (command line, CSV columns) is the docstring of tools/hooke_vs_liggghts.py.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
command -v liggghts >/dev/null || { echo "liggghts not installed: apt-get install liggghts" >&2; exit 2; }
/usr/bin/python3 -c 'import numpy, matplotlib' 2>/dev/null ||
  { echo "needs numpy and matplotlib: apt-get install python3-numpy python3-matplotlib" >&2; exit 2; }
exec /usr/bin/python3 "$here/hooke_vs_liggghts.py" "$@"
