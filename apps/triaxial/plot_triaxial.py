#!/usr/bin/env python3
"""Plot a triaxial results file: deviatoric stress q and volumetric strain eps_v against the axial
strain eps_1 (soil convention, compression positive).

    plot_triaxial.py RESULTS.h5 OUT.png

A thin entry point to sandcell_analysis.plots.plot_run (apps/analysis, installed beside this script
in <prefix>/share/sandcell).
"""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
# The package: installed beside this script, else in the source tree (apps/analysis).
for _where in (HERE, os.path.join(HERE, "..", "analysis")):
    if os.path.isdir(os.path.join(_where, "sandcell_analysis")):
        sys.path.insert(0, os.path.abspath(_where))
        break


def main(argv):
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    from sandcell_analysis.plots import plot_run
    plot_run(argv[1], argv[2])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
