"""Steps and neighbour-list builds of each test from run.sh's logs (the triaxial done line's "neighbour list built K
times (the first as this process began) in its S steps"; the runs here wrote "in this process's S steps", the same
count), with the list's cost model: Ir a step = P(skin) + B(skin) x builds / steps, P and
B the callgrind counts of dense-20k (callgrind.csv), interpolated linearly in the skin.

    /usr/bin/python3 experiments/2026-11-30-skin/builds.py OUT [--variant max] > builds.csv
"""
import argparse
import csv
import glob
import os
import re
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
LINE = re.compile(r"^(p-b[0-9.]+-p0_[0-9]+kPa): done at step (\d+).*neighbour list built (\d+) times.*? in "
                  r"(?:this process's|its) (\d+) steps")


def cost_model():
    with open(os.path.join(HERE, "callgrind.csv"), newline="") as fh:
        rows = sorted(csv.DictReader(fh), key=lambda r: float(r["skin_mm"]))
    skin = np.array([float(r["skin_mm"]) for r in rows])
    step = np.array([float(r["ir_per_step_M"]) for r in rows])
    build = np.array([float(r["ir_per_build_M"]) for r in rows])
    return lambda s: (float(np.interp(s, skin, step)), float(np.interp(s, skin, build)))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out", help="run.sh's OUT folder (s<skin>.log)")
    ap.add_argument("--variant", default="max", help="the rebuild test's label in the table (default max)")
    a = ap.parse_args()
    model = cost_model()
    w = csv.writer(sys.stdout, lineterminator="\n")
    w.writerow(["variant", "skin_mm", "test", "steps", "builds", "steps_per_build", "ir_step_M", "ir_builds_M",
                "ir_total_M"])
    for log in sorted(glob.glob(os.path.join(a.out, "s*.log"))):
        skin = float(os.path.basename(log)[1:-4])
        p, b = model(skin)
        with open(log) as fh:
            for line in fh:
                m = LINE.match(line)
                if not m:
                    continue
                steps, builds = int(m.group(4)), int(m.group(3))
                per = b * builds / steps
                w.writerow([a.variant, skin, m.group(1), steps, builds, f"{steps / builds:.1f}", f"{p:.2f}",
                            f"{per:.3f}", f"{p + per:.2f}"])


if __name__ == "__main__":
    main()
