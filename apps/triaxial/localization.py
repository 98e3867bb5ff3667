#!/usr/bin/env python3
"""Strain localization in a sandcell triaxial test (`triaxial localization`).

    localization.py RESULTS.h5... [--out DIR] [--grid G] [--whole] [--slabs K]

A thin entry point: the method is sandcell_analysis.localization (apps/analysis, installed beside
this script in <prefix>/share/sandcell); details: `localization.py --help`.
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
    # BAND_CONTRAST re-exported for scripts that import it from this entry point.
    from sandcell_analysis.localization import BAND_CONTRAST, main  # noqa: F401
except ImportError as _exc:  # an interpreter without numpy, or no package
    print(f"localization.py: error: {_exc} (needs numpy, matplotlib and h5py)", file=sys.stderr)
    sys.exit(1)

if __name__ == "__main__":
    sys.exit(main())
