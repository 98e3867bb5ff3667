"""How the critical-state rule's standard error depends on its estimator (issue 45: a measurement for
the decision on the rule's form, not a verdict; the rule in critical.py is unchanged).

    PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-29-paper-faster/se_methods.py RESULTS \
        [--out experiments/2026-11-29-paper-faster/se_methods.csv]

RESULTS: the paper-faster campaign's folder (p-*.h5, s3-*.h5). For every test and each of v2's five
quantities over the last 0.1 of eps_q, the change of the least-squares line and two standard errors of
it, as shares of the tolerance:
- ar1: critical.py's (the OLS SE times sqrt((1 + r1)/(1 - r1)), r1 clipped at 0.99), with r1;
- batch-B: the window's rows cut into B consecutive blocks of equal row count, the line through the
  B block means (x mean, y mean) and its OLS SE with B - 2 degrees of freedom (B = 10 and 5): blocks
  long against the correlation time make the block means nearly independent, with no model of it.
Prints, per quantity, the median 2 SE / tolerance by estimator and how many tests each would pass
(change + 2 SE <= tolerance), all quantities together.
"""
import argparse
import csv
import glob
import math
import os

import numpy as np

from sandcell_analysis import critical, results

QUANTITIES = (("eta", 0.02, True), ("p", 0.02, True), ("e", 0.005, False), ("Z_mech", 0.02, True),
              ("F_a", 0.05, True))
WINDOW = 0.1


def batch_se(x, y, blocks):
    """Slope and its SE from the means of `blocks` consecutive blocks of the rows."""
    good = np.isfinite(x) & np.isfinite(y)
    x, y = x[good], y[good]
    if x.size < 2 * blocks:
        return math.nan, math.nan
    cuts = np.array_split(np.arange(x.size), blocks)
    xm = np.array([x[c].mean() for c in cuts])
    ym = np.array([y[c].mean() for c in cuts])
    xc = xm - xm.mean()
    sxx = float(xc @ xc)
    slope = float(xc @ (ym - ym.mean())) / sxx
    resid = (ym - ym.mean()) - slope * xc
    return slope, math.sqrt(float(resid @ resid) / (blocks - 2) / sxx)


def one_test(path):
    cols = results.read_columns(path, ["eps_q", "p", "q", "eta", "e", "Z_mech", "fabric"])
    series = {k: np.asarray(cols[k], float) for k in ("p", "eta", "e", "Z_mech")}
    series["F_a"] = critical.fabric_anisotropy(cols["fabric"])
    x = np.asarray(cols["eps_q"], float)
    sel = x >= x[-1] - WINDOW
    out = {}
    for name, tol, relative in QUANTITIES:
        y = series[name][sel]
        scale = abs(float(np.nanmean(y))) if relative else 1.0
        slope, se, r1, _ = critical.trend(x[sel], y, WINDOW)
        row = dict(change=abs(slope) * WINDOW / scale / tol, ar1=2 * se * WINDOW / scale / tol, r1=r1)
        for blocks in (10, 5):
            b_slope, b_se = batch_se(x[sel], y, blocks)
            row[f"batch{blocks}"] = 2 * b_se * WINDOW / scale / tol
            row[f"change{blocks}"] = abs(b_slope) * WINDOW / scale / tol
        out[name] = row
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "se_methods.csv"))
    a = ap.parse_args()
    files = sorted(f for f in glob.glob(os.path.join(a.results, "*.h5"))
                   if os.path.basename(f).startswith(("p-", "s3-")) and "checkpoint" not in f)
    rows = []
    for f in files:
        for name, r in one_test(f).items():
            rows.append(dict(test=os.path.basename(f)[:-3], quantity=name, **{k: round(v, 4) for k, v in r.items()}))
    with open(a.out, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]), lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    print(f"{len(files)} tests; 2 SE and the change as shares of each tolerance (median over tests)")
    for name, _, _ in QUANTITIES:
        q = [r for r in rows if r["quantity"] == name]
        med = {k: np.median([r[k] for r in q]) for k in ("change", "ar1", "batch10", "batch5", "r1")}
        print(f"  {name:7s} change {med['change']:.2f}, 2 SE: ar1 {med['ar1']:.2f} (r1 {med['r1']:.2f}), "
              f"batch-10 {med['batch10']:.2f}, batch-5 {med['batch5']:.2f}")
    for est, change in (("ar1", "change"), ("batch10", "change10"), ("batch5", "change5")):
        passed = 0
        for test in sorted({r["test"] for r in rows}):
            q = [r for r in rows if r["test"] == test]
            passed += all(r[change] + r[est] <= 1.0 for r in q)
        print(f"  all five steady with {est}: {passed} of {len(files)} tests")


if __name__ == "__main__":
    main()
