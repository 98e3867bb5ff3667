"""The stiffness step against the fixed 0.2 t_R step at 19,436 spheres, three seeds (issue 46 item 1).

    PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-28-stiffness-step/seeds.py REF_ROOT STIFF_ROOT \
        [--out experiments/2026-11-28-stiffness-step/seeds.csv]

REF_ROOT holds free-s{2017,2018,2019} with the decisive experiment's fixed-step tests (paper-fast's 0.2 t_R; at
0.5 MPa b = 1 the servo-cap re-runs, as in experiments/2026-11-28-servo-cap/rerun.sh's merged folder); STIFF_ROOT
is run-seeds.sh's OUT: the same samples sheared with time.step = "stiffness" (safety 0.8). Each test pairs with the
fixed-step test of its own sample. Writes seeds.csv: one row per (p0, b, measure).

Measures: over the last 0.1 of eps_q (analyze.one_test of the decisive experiment) the mean e and q/p, and q/p at
eps_1 = 2 % (before any band; the peak of b = 1 at 0.5 MPa is the servo's start-up). The steps taken, per test.

Criterion, fixed on 2026-11-28 before the seeds 2018 and 2019 were sheared with the stiffness step:
- only pairs where both tests held their path (the watchdog's done) to eps_q = 0.6 enter;
- D = the mean over seeds of (stiffness - fixed) with SE_D = SD of the paired differences / sqrt(n);
- s = the sample SD over seeds of the fixed-step tests (the protocol's realization scatter);
- "within the seed scatter" when |D| + 2 SE_D <= s: the step's effect is shown to be smaller than what one more
  seed would change; "beyond" when |D| - 2 SE_D > s; otherwise "not shown" (the pairs too few or too scattered).
"""
import argparse
import csv
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "2026-11-28-one-csl-decisive"))
sys.path.insert(0, os.path.join(HERE, "..", "..", "apps", "analysis"))

import analyze  # noqa: E402
from sandcell_analysis import results  # noqa: E402

SEEDS = (2017, 2018, 2019)
TESTS = [f"p-b{b}-p0_{p}" for p in ("500kPa", "8000kPa") for b in ("0.00", "0.50", "1.00")]


def measures(folder, test):
    path = os.path.join(folder, test + ".h5")
    if not os.path.exists(path):
        return None
    status = analyze.index_status(folder).get(test, "running")
    end = analyze.one_test(path, status)
    cols = results.read_columns(path, ["strain", "eta", "step"])
    k = min(int(np.searchsorted(cols["strain"][:, 0], 0.02)), len(cols["eta"]) - 1)
    return dict(ok=status.startswith("done") and end["eps_q_end"] >= 0.599, e=end["e"], eta=end["eta"],
                eta_2pct=float(cols["eta"][k]), steps=int(cols["step"][-1]))


def paired(pairs, m):
    """Over pairs (seed, reference, new): the reference mean of measure m, D = the mean of (new - reference),
    SE_D = the SD of those differences / sqrt(n), s = the reference's sample SD (NaN where undefined)."""
    diff = np.array([g[m] - f[m] for _, f, g in pairs])
    ref = np.array([f[m] for _, f, _ in pairs])
    n = len(pairs)
    return (float(ref.mean()) if n else math.nan, float(diff.mean()) if n else math.nan,
            float(diff.std(ddof=1) / math.sqrt(n)) if n > 1 else math.nan,
            float(ref.std(ddof=1)) if n > 1 else math.nan)


def judge(d, se, s):
    if not all(math.isfinite(v) for v in (d, se, s)):
        return "not shown (fewer than two pairs)"
    if abs(d) + 2 * se <= s:
        return "within the seed scatter"
    if abs(d) - 2 * se > s:
        return "beyond the seed scatter"
    return "not shown"


def write_rows(path, rows):
    """The rows as CSV, floats to 6 significant digits."""
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]), lineterminator="\n")
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("ref")
    ap.add_argument("stiff")
    ap.add_argument("--out", default=os.path.join(HERE, "seeds.csv"))
    a = ap.parse_args(argv)
    rows = []
    for test in TESTS:
        pairs = []
        for seed in SEEDS:
            f = measures(os.path.join(a.ref, f"free-s{seed}"), test)
            g = measures(os.path.join(a.stiff, f"free-s{seed}"), test)
            if f and g and f["ok"] and g["ok"]:
                pairs.append((seed, f, g))
        for m in ("e", "eta", "eta_2pct"):
            n = len(pairs)
            mean, d, se, s = paired(pairs, m)
            rows.append(dict(test=test, measure=m, pairs=n, seeds=" ".join(str(p[0]) for p in pairs),
                             fixed_mean=mean, D=d, SE_D=se, seed_sd=s, verdict=judge(d, se, s),
                             steps_fixed=int(sum(f["steps"] for _, f, _ in pairs)),
                             steps_stiffness=int(sum(g["steps"] for _, _, g in pairs))))
            r = rows[-1]
            print(f"{test} {m:8s}: n {n}, fixed {r['fixed_mean']:.4f}, D {d:+.4f} +- {se:.4f}, seed SD {s:.4f}: "
                  f"{r['verdict']}; steps {r['steps_fixed']} -> {r['steps_stiffness']}")
    write_rows(a.out, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
