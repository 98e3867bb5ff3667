#!/usr/bin/env python3
"""Critical-state and dilatancy analysis of sandcell true-triaxial results (`triaxial analyze`).

    analyze.py RESULTS... [--out DIR] [options]

A thin entry point: the analysis is the package sandcell_analysis (apps/analysis, installed beside
this script in <prefix>/share/sandcell); methods, criteria and options are in the docstring of
sandcell_analysis/analyze.py and in `analyze.py --help`.
"""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
# The package: installed beside this script, else in the source tree (apps/analysis).
for _where in (HERE, os.path.join(HERE, "..", "analysis")):
    if os.path.isdir(os.path.join(_where, "sandcell_analysis")):
        sys.path.insert(0, os.path.abspath(_where))
        break

try:
    from sandcell_analysis.analyze import main
except ImportError as _exc:  # an interpreter without the scientific stack, or no package
    print(f"analyze.py: error: {_exc} (needs numpy, scipy, matplotlib and h5py; on Debian: "
          "apt install python3-numpy python3-scipy python3-matplotlib python3-h5py)", file=sys.stderr)
    sys.exit(1)

if __name__ == "__main__":
    sys.exit(main())
