"""The critical-state rule's eta test on synthetic series of known truth (issue 45: the decision on the
proposal of stop 54 against v2): how often each rule accepts a series whose mean drifts beyond the
tolerance over the window (a false positive) and how often it accepts one whose mean is steady (power).

    PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-29-rule-check/rule_check.py \
        [--out experiments/2026-11-29-rule-check/rule_check.csv] [--reps 4000] [--seed 45]

Each series: n rows evenly spaced over a window of width 1 (eps_q units do not matter: the rules see
only the change over the window and its SE), y = D x + AR(1) noise with lag-1 coefficient phi, scaled so
that the true standard deviation of the least-squares change over the window is tau (measured on
drift-free replicates of the same phi and n). D and tau are in units of the tolerance, as the
committed se_methods CSVs are. The estimator is critical.trend itself (the OLS slope with its
AR(1)-inflated SE, r1 clipped at 0.99: the rule's own).
- v2: accept iff |change| + 2 SE <= 1;
- the proposal: accept iff |change| <= 2 SE (eta refused only for a significant trend);
- v2 guarded: v2, and the window's effective row count n (1 - r1) / (1 + r1) >= 10 (NEFF_MIN): a window
  holding too few independent rows for its SE to be trusted is refused;
- v2 widened (version 3, critical.errors_to_spare): |change| + k SE <= 1 with k = 2 where
  n_eff >= NEFF_MIN and k = 6 below it (the AR(1) SE is down to ~1/3 of the truth there:
  se_over_tau), so a short window can still pass a small change.
The grid spans what the paper-faster study measured for eta over its last 0.1 of eps_q (0.8 run:
r1 0.86-0.99, 2 SE 0.41-5.5 tolerances, ~100-400 rows in a window).
"""
import argparse
import csv
import os

import numpy as np

from sandcell_analysis import critical

HERE = os.path.dirname(os.path.abspath(__file__))
ROWS = (100, 300)
PHI = (0.9, 0.97, 0.99, 0.998)
TAU = (0.25, 0.5, 1.0, 2.0)
DRIFT = (0.0, 0.5, 1.5, 2.0)
NEFF_MIN = critical.V3_DEFAULTS["neff_min"]  # 10, fixed before the 4,000-series runs


def ar1(rng, phi, n, reps):
    """reps AR(1) series of n rows, stationary from the first row, unit marginal variance."""
    e = rng.standard_normal((reps, n))
    y = np.empty_like(e)
    y[:, 0] = e[:, 0]
    s = np.sqrt(1.0 - phi * phi)
    for k in range(1, n):
        y[:, k] = phi * y[:, k - 1] + s * e[:, k]
    return y


def ols_change(x, y):
    """Least-squares change over the window (slope x width) of each row of y."""
    xc = x - x.mean()
    return (y - y.mean(axis=1, keepdims=True)) @ xc / float(xc @ xc) * float(np.ptp(x))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=os.path.join(HERE, "rule_check.csv"))
    ap.add_argument("--reps", type=int, default=4000)
    ap.add_argument("--seed", type=int, default=45)
    a = ap.parse_args(argv)
    rng = np.random.default_rng(a.seed)
    rows = []
    for n in ROWS:
        x = np.linspace(0.0, 1.0, n)
        for phi in PHI:
            unit = np.std(ols_change(x, ar1(rng, phi, n, a.reps)))  # the change's SD at unit noise
            for tau in TAU:
                for drift in DRIFT:
                    noise = ar1(rng, phi, n, a.reps) * (tau / unit)
                    y = drift * x + noise
                    fits = [critical.trend(x, yi, 1.0) for yi in y]
                    change = np.array([f[0] for f in fits])
                    se = np.array([f[1] for f in fits])
                    r1 = np.array([f[2] for f in fits])
                    v2 = np.abs(change) + 2 * se <= 1.0
                    proposal = np.abs(change) <= 2 * se
                    neff = critical.effective_rows(n, r1)
                    guarded = v2 & (neff >= NEFF_MIN)
                    widened = np.abs(change) + critical.errors_to_spare(neff) * se <= 1.0
                    rows.append(dict(rows=n, phi=phi, tau=tau, drift=drift, reps=a.reps,
                                     se_median=round(float(np.median(se)), 4),
                                     se_over_tau=round(float(np.median(se)) / tau, 4),
                                     r1_median=round(float(np.median(r1)), 4),
                                     v2_accepts=round(float(v2.mean()), 4),
                                     proposal_accepts=round(float(proposal.mean()), 4),
                                     neff_median=round(float(np.median(neff)), 2),
                                     guarded_accepts=round(float(guarded.mean()), 4),
                                     widened_accepts=round(float(widened.mean()), 4)))
                    r = rows[-1]
                    print(f"n {n} phi {phi} tau {tau} D {drift}: 2SE {2 * r['se_median']:.2f} "
                          f"(SE/tau {r['se_over_tau']:.2f}, r1 {r['r1_median']:.3f}) "
                          f"v2 {r['v2_accepts']:.3f} proposal {r['proposal_accepts']:.3f} "
                          f"n_eff {r['neff_median']:.1f} guarded {r['guarded_accepts']:.3f} "
                          f"widened {r['widened_accepts']:.3f}")
    write_rows(a.out, rows)
    return 0


def write_rows(path, rows):
    """rows (dicts with the same keys) as a CSV with a header (study_windows.py's too)."""
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]), lineterminator="\n")
        w.writeheader()
        w.writerows(rows)


if __name__ == "__main__":
    raise SystemExit(main())
