"""paper-faster.toml against the paper's rate (paper.toml in the free cell), three seeds (issue 46 item 1).

    PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-29-validate-faster/compare.py WORKDIR \
        [--out experiments/2026-11-29-validate-faster/compare.csv]

WORKDIR is run.sh's: {paper,paper-faster}-s{2017,2018,2019}-p0_{500,16000}kPa-b{0,0.5}/, each with its one
constant-p test. Each paper-faster test pairs with the paper-protocol test of its own sample. Writes one row per
(p0, b, measure).

Measures: over the last 0.1 of eps_q (the decisive experiment's analyze.one_test) the mean e and q/p; q/p at
eps_q = 0.02; the peak q/p; the steps taken.

Criterion, fixed in README.md before any of these tests finished (as experiments/2026-11-28-stiffness-step's):
- only pairs where both tests held their path (the watchdog's done) to eps_q = 0.5 enter;
- D = the mean over seeds of (faster - paper), SE_D = SD of the paired differences / sqrt(n);
- s = the sample SD over seeds of the paper-protocol tests;
- "within the seed scatter" when |D| + 2 SE_D <= s; "beyond" when |D| - 2 SE_D > s; else "not shown".
"""
import argparse
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "2026-11-28-one-csl-decisive"))
sys.path.append(os.path.join(HERE, "..", "2026-11-28-stiffness-step"))  # after: it has an analyze.py of its own
sys.path.insert(0, os.path.join(HERE, "..", "..", "apps", "analysis"))

import analyze  # noqa: E402
from sandcell_analysis import results  # noqa: E402
from seeds import judge, paired, write_rows  # noqa: E402  (the same criterion and table as the stiffness step's)

SEEDS = (2017, 2018, 2019)
CASES = [(p, b) for p in ("500kPa", "16000kPa") for b in ("0", "0.5")]
MEASURES = ("e", "eta", "eta_2pct", "peak_eta")


def measures(work, protocol, seed, p0, b):
    folder = os.path.join(work, f"{protocol}-s{seed}-p0_{p0}-b{b}")
    test = f"p-b{float(b):.2f}-p0_{p0}"
    path = os.path.join(folder, test + ".h5")
    if not os.path.exists(path):
        return None
    status = analyze.index_status(folder).get(test, "running")
    end = analyze.one_test(path, status)
    cols = results.read_columns(path, ["eps_q", "eta", "step"])
    k = min(int(np.searchsorted(cols["eps_q"], 0.02)), len(cols["eta"]) - 1)
    return dict(ok=status.startswith("done") and end["eps_q_end"] >= 0.499, e=end["e"], eta=end["eta"],
                eta_2pct=float(cols["eta"][k]), peak_eta=float(np.nanmax(cols["eta"])), steps=int(cols["step"][-1]))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("work")
    ap.add_argument("--out", default=os.path.join(HERE, "compare.csv"))
    a = ap.parse_args(argv)
    rows = []
    for p0, b in CASES:
        pairs = []
        for seed in SEEDS:
            ref = measures(a.work, "paper", seed, p0, b)
            fast = measures(a.work, "paper-faster", seed, p0, b)
            if ref and fast and ref["ok"] and fast["ok"]:
                pairs.append((seed, ref, fast))
        for m in MEASURES:
            n = len(pairs)
            mean, d, se, s = paired(pairs, m)
            rows.append(dict(p0=p0, b=b, measure=m, pairs=n, seeds=" ".join(str(p[0]) for p in pairs),
                             paper_mean=mean, D=d, SE_D=se, seed_sd=s, verdict=judge(d, se, s),
                             steps_paper=int(sum(f["steps"] for _, f, _ in pairs)),
                             steps_faster=int(sum(g["steps"] for _, _, g in pairs))))
            r = rows[-1]
            print(f"{p0} b {b} {m:8s}: n {n}, paper {r['paper_mean']:.4f}, D {d:+.4f} +- {se:.4f}, "
                  f"seed SD {s:.4f}: {r['verdict']}; steps {r['steps_paper']} -> {r['steps_faster']}")
    write_rows(a.out, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
