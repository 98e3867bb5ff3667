#!/usr/bin/env python3
"""Calibration of a triaxial configuration's micro-parameters against macroscopic targets
(`triaxial calibrate`).

    calibrate.py CONFIG --targets FILE --param KEY=LO:HI [...] [--budget N] [--out DIR] [--resume]

A thin entry point: the method is sandcell_analysis.calibrate (apps/analysis, installed beside this
script in <prefix>/share/sandcell); options: `calibrate.py --help`.
"""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
# The package: installed beside this script, else in the source tree (apps/analysis).
for _where in (HERE, os.path.join(HERE, "..", "analysis")):
    if os.path.isdir(os.path.join(_where, "sandcell_analysis")):
        sys.path.insert(0, os.path.abspath(_where))
        break

from sandcell_analysis.calibrate import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
