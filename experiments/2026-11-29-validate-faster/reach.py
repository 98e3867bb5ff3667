"""What the validation's criterion can decide: how often it says "within the seed scatter" for a protocol
with no bias at all, by the number of seeds and the correlation of a pair's two runs, and the
correlations the validation's own pairs show.

    /usr/bin/python3 experiments/2026-11-29-validate-faster/reach.py \
        [--out experiments/2026-11-29-validate-faster/reach.csv]

The criterion (compare.py, fixed before the data): "within" iff |D| + 2 SE_D <= s, D the mean paired
difference over n seeds, SE_D its standard error, s the sample SD of the paper protocol's n values.
Simulated: each seed's two runs are standard normal with correlation rho and the same mean (no bias;
the criterion is scale-free, so unit variance loses nothing); 200,000 campaigns a cell, seed 46.
A pair of chaotic runs from one sample decorrelates as it shears: rho ~ 0 at the end state.
Beside it, the form proposed instead (README): "within a margin" iff |D| + 2 SE_D <= delta, delta an
absolute margin fixed before the data; its chance for a protocol with no bias depends on n and
delta / SD_d only (SD_d the SD of the paired differences).
Observed: rho = 1 - SD_d^2 / (2 s_p s_f) from tests.csv (s_p, s_f the two protocols' seed SDs, SD_d
that of the paired differences), per case and measure: three seeds estimate it only roughly.
"""
import argparse
import csv
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SEEDS = (3, 5, 8, 10, 15, 20, 30)
RHOS = (0.0, 0.5, 0.8, 0.9, 0.95)
MARGINS = (0.5, 1.0, 1.5, 2.0, 3.0)  # delta / SD_d


def p_margin(n, ratio, rng, campaigns=200_000):
    d = rng.standard_normal((campaigns, n))
    se = d.std(axis=1, ddof=1) / np.sqrt(n)
    return float(np.mean(np.abs(d.mean(axis=1)) + 2.0 * se <= ratio))


def p_within(n, rho, rng, campaigns=200_000):
    a = rng.standard_normal((campaigns, n))
    b = rho * a + np.sqrt(1.0 - rho * rho) * rng.standard_normal((campaigns, n))
    d = b - a
    se = d.std(axis=1, ddof=1) / np.sqrt(n)
    s = a.std(axis=1, ddof=1)
    return float(np.mean(np.abs(d.mean(axis=1)) + 2.0 * se <= s))


def observed(tests_csv, faster="paper-faster"):
    with open(tests_csv, newline="") as fh:
        rows = list(csv.DictReader(fh))
    out = []
    for p0 in ("500kPa", "16000kPa"):
        for b in ("0", "0.5"):
            for m in ("e", "eta", "eta_2pct", "peak_eta"):
                pairs = {}
                for r in rows:
                    if r["p0"] == p0 and r["b"] == b and r["ok"] == "True" and r["protocol"] in ("paper", faster):
                        pairs.setdefault(r["seed"], {})[r["protocol"]] = float(r[m])
                both = [(v["paper"], v[faster]) for v in pairs.values() if len(v) == 2]
                if len(both) < 3:
                    continue
                p, f = np.array(both).T
                sd_d, s_p, s_f = np.std(f - p, ddof=1), np.std(p, ddof=1), np.std(f, ddof=1)
                out.append(dict(p0=p0, b=b, measure=m, pairs=len(both), sd_paper=s_p, sd_faster=s_f, sd_diff=sd_d,
                                rho=1.0 - sd_d ** 2 / (2.0 * s_p * s_f)))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tests", default=os.path.join(HERE, "tests.csv"))
    ap.add_argument("--out", default=os.path.join(HERE, "reach.csv"))
    a = ap.parse_args(argv)
    rng = np.random.default_rng(46)
    table = [dict(seeds=n, rho=rho, p_within=p_within(n, rho, rng)) for n in SEEDS for rho in RHOS]
    margin = [dict(seeds=n, ratio=x, p=p_margin(n, x, rng)) for n in SEEDS for x in MARGINS]
    with open(a.out, "w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["seeds", "rho", "p_within_no_bias"])
        for r in table:
            w.writerow([r["seeds"], r["rho"], f"{r['p_within']:.4f}"])
        w.writerow([])
        w.writerow(["seeds", "margin_over_sd_diff", "p_within_margin_no_bias"])
        for r in margin:
            w.writerow([r["seeds"], r["ratio"], f"{r['p']:.4f}"])
        obs = observed(a.tests)
        w.writerow([])
        keys = ["p0", "b", "measure", "pairs", "sd_paper", "sd_faster", "sd_diff", "rho"]
        w.writerow(keys)
        for r in obs:
            w.writerow([f"{r[k]:.4g}" if isinstance(r[k], float) else r[k] for k in keys])
    print("P(within | no bias), rows: seeds; columns: rho " + " ".join(f"{r:5g}" for r in RHOS))
    for n in SEEDS:
        print(f"{n:3d}: " + " ".join(f"{r['p_within']:5.3f}" for r in table if r["seeds"] == n))
    print("P(within a margin | no bias), rows: seeds; columns: margin / SD_d " + " ".join(f"{x:5g}" for x in MARGINS))
    for n in SEEDS:
        print(f"{n:3d}: " + " ".join(f"{r['p']:5.3f}" for r in margin if r["seeds"] == n))
    for r in obs:
        print(f"{r['p0']:8s} b {r['b']:3s} {r['measure']:8s}: n {r['pairs']}, SD paper {r['sd_paper']:.4f}, "
              f"faster {r['sd_faster']:.4f}, of the differences {r['sd_diff']:.4f}: rho {r['rho']:+.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
