#!/usr/bin/env bash
# The linear spring-dashpot ("hooke") law on two-sphere collisions: LIGGGHTS 3.8 (Debian package
# `liggghts`) against the analytic solution and a Python replica of LIGGGHTS' algorithm, and against
# sandcell with its two-sphere program (--sandcell build/release/tests/two-sphere). Not a test: a
# side-by-side measurement; writes hooke-vs-liggghts.csv and hooke-vs-liggghts.png beside this script
# and prints the tables quoted in its README.md.
#   experiments/2026-11-25-hooke-vs-liggghts/run.sh [--sandcell BIN] [--steps-per-contact 50] [--fine 500,5000]
#       [--csv F] [--png F]
# The contract BIN must meet (command line, CSV columns) is the docstring of hooke_vs_liggghts.py.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
command -v liggghts >/dev/null || { echo "liggghts not installed: apt-get install liggghts" >&2; exit 2; }
/usr/bin/python3 -c 'import numpy, matplotlib' 2>/dev/null ||
  { echo "needs numpy and matplotlib: apt-get install python3-numpy python3-matplotlib" >&2; exit 2; }
exec /usr/bin/python3 "$here/hooke_vs_liggghts.py" "$@"
