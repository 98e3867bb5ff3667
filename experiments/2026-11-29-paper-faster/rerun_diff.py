"""A re-run of this study against the committed index.csv: per (path, b) group the end e's and q/p's
differences (re-run - committed), the samples' e0, and the statuses (the "Timed in one run" figures).

    /usr/bin/python3 experiments/2026-11-29-paper-faster/rerun_diff.py OUT/index.csv
"""
import argparse
import collections
import csv
import os

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def read(path):
    with open(path, newline="") as fh:
        return {r["test"]: r for r in csv.DictReader(fh)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rerun", help="the re-run's index.csv")
    a = ap.parse_args(argv)
    new, old = read(a.rerun), read(os.path.join(HERE, "index.csv"))
    tests = sorted(set(new) & set(old))
    print(f"{len(tests)} tests in both; statuses {sorted({new[t]['status'].split()[0] for t in tests})}; "
          f"steps {sum(int(new[t]['steps']) for t in tests)} (committed {sum(int(old[t]['steps']) for t in tests)})")
    for p0 in sorted({float(old[t]["p0_Pa"]) for t in tests}):
        t = next(t for t in tests if float(old[t]["p0_Pa"]) == p0)
        print(f"p0 {p0 / 1e6:g} MPa: e0 {float(new[t]['e0']):.4f} (committed {float(old[t]['e0']):.4f})")
    de = {t: float(new[t]["final_e"]) - float(old[t]["final_e"]) for t in tests}
    deta = np.array([float(new[t]["final_eta"]) - float(old[t]["final_eta"]) for t in tests])
    groups = collections.defaultdict(list)
    for t in tests:
        groups[(new[t]["path"], new[t]["b"])].append(t)
    for (path, b), ts in sorted(groups.items()):
        d = [de[t] for t in ts]
        worst = max(ts, key=lambda t: abs(de[t]))
        print(f"{path} b {b}: end e diff mean {np.mean(d):+.4f}, largest {de[worst]:+.4f} ({worst})")
    d = np.array(list(de.values()))
    print(f"all: end e diff mean {d.mean():+.4f} SD {d.std():.4f} max |d| {abs(d).max():.4f}; "
          f"end q/p diff mean {deta.mean():+.4f} SD {deta.std():.4f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
