"""Which critical-state windows the stationarity rule can certify, by sample size, pressure and b (issue 45 item 2:
the data behind the note that "change + 2 SE within tolerance" cannot be met at 19,436 spheres for some quantities).

    PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-28-one-csl-decisive/stationarity.py \
        [--set NAME=ROOT ...] [--large LARGE_OUT] [--out experiments/2026-11-28-one-csl-decisive/stationarity.csv]

Each --set is a run root with {fixed,free}-s{2017,2018,2019}/p-b*kPa.h5 (the decisive layout; only tests that held
their path and reached eps_q >= 0.599 are read); --large adds the 155,488-sphere cell's files. For every test and
quantity (eta, p, e, Z_mech, F_a) and window (the last 0.1, 0.2, 0.3 of eps_q), the package's critical-state check
(version 2, its tolerances): the fitted change over the window, its serially corrected standard error, and whether
change + 2 SE is within tolerance. Writes one row per (set, cell, p0, b, quantity, window): tests, how many pass,
the median |change| and the median 2 SE as a share of the tolerance. Nothing here is a verdict: it measures what
the rule can show at these sizes.
"""
import argparse
import csv
import glob
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import analyze  # noqa: E402
from sandcell_analysis import critical, results  # noqa: E402

WINDOWS = (0.1, 0.2, 0.3)
QUANTITIES = ("eta", "p", "e", "Z_mech", "F_a")


def checks(path):
    cols = results.read_columns(path, ["eps_q", "p", "q", "eta", "e", "eps_v", "b", "Z_mech", "fabric", "stress"])
    fa, _ = analyze.fabric_measures(cols["fabric"], cols["stress"])
    series = {k: cols[k] for k in ("p", "q", "eta", "e", "eps_v", "b")}
    series["Z_mech"] = cols["Z_mech"]
    series["F_a"] = fa
    out = {}
    for w in WINDOWS:
        c = critical.detect_critical(cols["eps_q"], series, window=w)["checks"]
        for name in QUANTITIES:
            k = c.get(name)
            if k is not None:  # measure: |change| (relative to the mean where the tolerance is)
                out[(name, w)] = (k["measure"] / k["tol"], 2 * k["se_measure"] / k["tol"], bool(k["ok"]))
    return out


def files(sets, large):
    for name, root in sets:
        for cell in analyze.CELLS:
            for seed in analyze.SEEDS:
                folder = os.path.join(root, f"{cell}-s{seed}")
                status = analyze.index_status(folder)
                for path in sorted(glob.glob(os.path.join(folder, "p-b*kPa.h5"))):
                    test = os.path.basename(path)[:-3]
                    yield name, cell, test, path, status.get(test, "")
    if large:
        status = analyze.index_status(large)
        for path in sorted(glob.glob(os.path.join(large, "p-b*kPa.h5"))):
            test = os.path.basename(path)[:-3]
            yield "155k", "free", test, path, status.get(test, "")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--set", action="append", default=[], help="NAME=ROOT")
    ap.add_argument("--large")
    ap.add_argument("--out", default=os.path.join(HERE, "stationarity.csv"))
    a = ap.parse_args(argv)
    sets = [tuple(s.split("=", 1)) for s in a.set]
    groups = {}
    for name, cell, test, path, status in files(sets, a.large):
        if not status.startswith("done"):
            continue
        x = results.read_columns(path, ["eps_q"])["eps_q"]
        if x[-1] < 0.599:
            continue
        b, p0 = test[3:7], test.split("p0_")[1]
        for (q, w), v in checks(path).items():
            groups.setdefault((name, cell, p0, b, q, w), []).append(v)
    rows = []
    for key in sorted(groups):
        v = np.array(groups[key], float)
        rows.append(dict(zip(("set", "cell", "p0", "b", "quantity", "window"), key),
                         tests=len(v), pass_=int(v[:, 2].sum()), median_change_over_tol=float(np.median(v[:, 0])),
                         median_2se_over_tol=float(np.median(v[:, 1]))))
    with open(a.out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]) if rows else ["set"], lineterminator="\n")
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.3g}" if isinstance(v, float) else v) for k, v in r.items()})
    for r in rows:
        print(f"{r['set']:6s} {r['cell']:5s} {r['p0']:8s} b {r['b']} {r['quantity']:6s} w {r['window']}: "
              f"{r['pass_']}/{r['tests']} pass; |change| {r['median_change_over_tol']:.2f} tol, "
              f"2 SE {r['median_2se_over_tol']:.2f} tol")
    return 0


if __name__ == "__main__":
    sys.exit(main())
