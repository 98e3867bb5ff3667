#!/usr/bin/env python3
"""Speed versus accuracy of a sandcell triaxial test (`triaxial study`).

    study.py [CONFIG] [--preset quick|inertia|full|size] [--out DIR] [--threads T] [--tolerance ...]

A thin entry point: the study is sandcell_analysis.study (apps/analysis, installed beside this
script in <prefix>/share/sandcell); presets and outputs: `study.py --help`.
"""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
# The package: installed beside this script, else in the source tree (apps/analysis).
for _where in (HERE, os.path.join(HERE, "..", "analysis")):
    if os.path.isdir(os.path.join(_where, "sandcell_analysis")):
        sys.path.insert(0, os.path.abspath(_where))
        break

from sandcell_analysis.study import main, slope_max_dilation  # noqa: E402,F401 (re-exported)

if __name__ == "__main__":
    sys.exit(main())
