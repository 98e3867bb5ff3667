"""How far the same test moves when it is run again (issue 45 item 7; added 2026-11-30, after the v3 re-run's
first two seeds were seen, never a verdict): the first run's tests.csv (builds of 2026-11-28) against the v3
re-run's v3/tests.csv (build 9ac3c84), test by test: the same config, seed and packing recipe, another build, so
another trajectory (DEM is chaotic: a last-bit change grows to a different realization of the same flow).

    /usr/bin/python3 experiments/2026-11-28-one-csl-decisive/rerun_scatter.py [--out rerun_scatter.csv]

For each test that held its path to eps_q = 0.6 in both runs (b = 0 and 1; the 0.5 MPa b = 1 tests of the first
run ran with the servo's old 10x cap): the end-window e of both and their difference. Per group (cell, p0, b) and
overall: the SD of a single run's e implied by the differences (their root mean square / sqrt 2: two runs of one
process differ by zero on average), against the seeds' SD within
one run; and, for b = 1 against b = 0 at each cell and p0, the offset pooled over both runs (up to 6 realizations,
two per seed: the seeds' mean of the two runs, so the SE stays the seeds'), for reading beside the verdicts.
"""
import argparse
import csv
import math
import os

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def rows(path):
    with open(path, newline="") as fh:
        return {(r["cell"], r["seed"], r["test"]): r for r in csv.DictReader(fh)}


def rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def held(r):
    return r["status"].startswith("done") and float(r["eps_q_end"]) >= 0.599


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--first", default=os.path.join(HERE, "tests.csv"))
    ap.add_argument("--rerun", default=os.path.join(HERE, "v3", "tests.csv"))
    ap.add_argument("--out", default=os.path.join(HERE, "rerun_scatter.csv"))
    a = ap.parse_args()
    first, rerun = rows(a.first), rows(a.rerun)
    out = []
    for k in sorted(first):
        if k not in rerun or "b0.50" in k[2]:
            continue
        f, r = first[k], rerun[k]
        out.append(dict(cell=k[0], seed=k[1], test=k[2], p0_MPa=float(r["p0_MPa"]), b=float(r["b"]),
                        held_first=held(f), held_rerun=held(r), e_first=float(f["e"]), e_rerun=float(r["e"]),
                        diff=float(r["e"]) - float(f["e"])))
    with open(a.out, "w", newline="") as fh:
        w = csv.DictWriter(fh, list(out[0]), lineterminator="\n")
        w.writeheader()
        for o in out:
            w.writerow({c: (f"{v:.5f}" if isinstance(v, float) else v) for c, v in o.items()})
    both = [o for o in out if o["held_first"] and o["held_rerun"]]
    d = np.array([o["diff"] for o in both])
    print(f"{len(both)} tests held their path in both runs: e(rerun) - e(first) mean {d.mean():+.4f}, "
          f"RMS {rms(d):.4f}, max |diff| {np.abs(d).max():.4f}; one run's SD implied {rms(d) / math.sqrt(2):.4f}")
    for cell in ("fixed", "free"):
        for p0 in (0.5, 8.0):
            g = {b: [o for o in both if o["cell"] == cell and o["p0_MPa"] == p0 and o["b"] == b] for b in (0.0, 1.0)}
            parts = []
            for b in (0.0, 1.0):
                dd = np.array([o["diff"] for o in g[b]])
                within = np.array([o["e_rerun"] for o in g[b]])
                if len(dd) >= 2:
                    parts.append(f"b {b:g}: n {len(dd)}, run-to-run SD {rms(dd) / math.sqrt(2):.4f}, "
                                 f"seed SD (re-run) {within.std(ddof=1):.4f}")
            # Pooled offset: per seed the mean of its two runs, then the seeds' mean and SE, as analyze.py.
            seeds = {b: [0.5 * (o["e_first"] + o["e_rerun"]) for o in g[b]] for b in (0.0, 1.0)}
            if len(seeds[0.0]) >= 2 and len(seeds[1.0]) >= 2:
                e0, e1 = np.array(seeds[0.0]), np.array(seeds[1.0])
                D = e1.mean() - e0.mean()
                se = math.sqrt(e1.var(ddof=1) / len(e1) + e0.var(ddof=1) / len(e0))
                parts.append(f"b = 1 - b = 0 over both runs {D:+.4f} +- {se:.4f} (seeds {len(e1)} / {len(e0)})")
            print(f"{cell:5s} {p0:g} MPa: " + "; ".join(parts))
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
