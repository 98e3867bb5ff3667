#!/usr/bin/env bash
# Re-runs the experiment: both protocols (about 3 and 20 minutes on 2 cores), then the figures and
# the table. Usage: experiments/2026-11-28-stress-paths/run.sh [BUILD_DIR] [OUT_DIR]
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
build="${1:-$here/../../build/release}"
out="${2:-$here/../../results/stress-paths}"
for protocol in fast paper; do
  # exit 1 is a test that left its path: expected here, and drawn
  "$build/apps/triaxial/triaxial" "$here/$protocol.toml" --threads 2 --out "$out/$protocol" --resume || [ $? -eq 1 ]
done
/usr/bin/python3 "$here/plot_paths.py" "$out" "$here"
