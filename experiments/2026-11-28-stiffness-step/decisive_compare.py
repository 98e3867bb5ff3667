"""The stiffness step at 19,436 spheres: the decisive experiment's free-cell tests of seed 2017 (constant p, b = 0,
0.5, 1 at 0.5 and 8 MPa, to eps_q = 0.6) sheared again from the same samples with time.step = "stiffness" (safety
0.8), against paper-fast's fixed 0.2 t_R. Writes decisive.csv beside this file.

    PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-28-stiffness-step/decisive_compare.py \
        DECISIVE_ROOT STIFFNESS_OUT

DECISIVE_ROOT: the decisive experiment's run root (free-s2017, and {fixed,free}-s{2017,2018,2019} for the seed
scatter, through its tests.csv); STIFFNESS_OUT: the run folder of decisive-stiffness.toml. For each test: the steps,
the end-window (last 0.1 of eps_q) means of e, q/p, Z_mech and F_a by the decisive analysis's own measures
(analyze.one_test), q/p at eps_1 = 1, 2 and 5 % (the peak of b = 1 at 0.5 MPa is the servo's start-up, not the
material's: 1.03-1.18 from one sample), and the seed scatter of the end e and q/p (sample SD over the seeds of the same
cell, b and p0 that held their path; tests.csv).
"""
import csv
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DECISIVE = os.path.join(HERE, "..", "2026-11-28-one-csl-decisive")
sys.path.insert(0, DECISIVE)
sys.path.insert(0, os.path.join(HERE, "..", "..", "apps", "analysis"))

import analyze  # noqa: E402
from sandcell_analysis import results  # noqa: E402

TESTS = [f"p-b{b}-p0_{p}" for p in ("500kPa", "8000kPa") for b in ("0.00", "0.50", "1.00")]


def at_strain(path):
    cols = results.read_columns(path, ["strain", "eta", "step"])
    e1 = cols["strain"][:, 0]
    out = {}
    for x in (0.01, 0.02, 0.05):
        k = min(int(np.searchsorted(e1, x)), len(e1) - 1)
        out[f"eta_at_{int(x * 100)}pct"] = float(cols["eta"][k])
    out["steps"] = int(cols["step"][-1])
    return out


def scatter():
    rows = list(csv.DictReader(open(os.path.join(DECISIVE, "tests.csv"))))
    out = {}
    for r in rows:
        if r["cell"] != "free" or not r["status"].startswith("done") or not r["e"]:
            continue
        key = (float(r["b"]), float(r["p0_MPa"]))
        out.setdefault(key, []).append((float(r["e"]), float(r["eta"])))
    return {k: (float(np.std([v[0] for v in vs], ddof=1)), float(np.std([v[1] for v in vs], ddof=1)), len(vs))
            for k, vs in out.items() if len(vs) > 1}


def main(decisive, stiff):
    sd = scatter()
    rows = []
    for t in TESTS:
        b, p0 = float(t[3:7]), float(t.split("_")[1][:-3]) / 1000.0
        row = dict(test=t)
        for tag, folder in (("fixed_step", os.path.join(decisive, "free-s2017")), ("stiffness", stiff)):
            path = os.path.join(folder, t + ".h5")
            status = analyze.index_status(folder).get(t, "")
            end = analyze.one_test(path, status)
            row.update({f"{tag}_{k}": v for k, v in at_strain(path).items()})
            for k in ("e", "eta", "Z_mech", "F_a", "A"):
                row[f"{tag}_{k}"] = end[k]
            row[f"{tag}_status"] = status
        row["steps_ratio"] = row["fixed_step_steps"] / row["stiffness_steps"]
        for k in ("e", "eta", "Z_mech", "F_a"):
            row[f"diff_{k}"] = row[f"stiffness_{k}"] - row[f"fixed_step_{k}"]
        s = sd.get((b, p0), (float("nan"), float("nan"), 0))
        row.update(seed_sd_e=s[0], seed_sd_eta=s[1], seeds=s[2])
        rows.append(row)
        print(f"{t}: steps {row['fixed_step_steps']} -> {row['stiffness_steps']} ({row['steps_ratio']:.2f}x fewer); "
              f"end e {row['fixed_step_e']:.4f} -> {row['stiffness_e']:.4f} ({row['diff_e']:+.4f}, "
              f"seed SD {s[0]:.4f}); "
              f"q/p {row['fixed_step_eta']:.4f} -> {row['stiffness_eta']:.4f} ({row['diff_eta']:+.4f}, seed SD "
              f"{s[1]:.4f}); q/p at 1 % {row['fixed_step_eta_at_1pct']:.4f} -> {row['stiffness_eta_at_1pct']:.4f}")
    with open(os.path.join(HERE, "decisive.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:3]) if len(sys.argv) == 3 else __doc__)
