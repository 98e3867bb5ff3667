#!/usr/bin/python3
"""How much the critical void ratio falls from 0.5 to 8 MPa, against Young's modulus, averaged over
sample seeds: the campaigns of apps/triaxial/configs/calibrate-reduced.toml (1,000 spheres, fast
protocol, constant p, b = 0, p0 = 0.5, 2, 8 MPa) at each E and seed, with the frictions given.
Writes csl-vs-young.csv (one row per test) and prints, per E, the mean and standard error over
seeds of e_c at each p0 and of the drop e_c(0.5 MPa) - e_c(8 MPa).

    $X/csl_vs_young.py [--young 70e9,280e9] [--seeds 1,2,3,4] [--friction 0.35]
        [--rolling-friction 0.064] [--out results/csl-vs-young] [--docs $X/csl-vs-young]

(From the repository root, with X=experiments/2026-11-25-calibration and PYTHONPATH=apps/analysis: the script
imports sandcell_analysis. DOCS defaults to the folder named above, beside this script.)

Resumable: a campaign whose tests are all done is not run again; each runs in
OUT/runs/E<GPa>GPa-seed<S>, as `triaxial calibrate` runs its points.
"""
import argparse
import csv
import json
import os
import tomllib

import numpy as np

from sandcell_analysis.calibrate import run_point

HERE = os.path.dirname(os.path.abspath(__file__))  # the experiment's folder: the tables and figures
ROOT = os.path.dirname(os.path.dirname(HERE))  # the repository


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--young", default="70e9,280e9")
    ap.add_argument("--seeds", default="1,2,3,4")
    ap.add_argument("--friction", type=float, default=0.35)
    ap.add_argument("--rolling-friction", type=float, default=0.064)
    ap.add_argument("--out", default="results/csl-vs-young")
    ap.add_argument("--docs", default=os.path.join(HERE, "csl-vs-young"))
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--triaxial", default=os.path.join(ROOT, "build", "release", "apps", "triaxial", "triaxial"))
    args = ap.parse_args()
    base = tomllib.load(open(os.path.join(ROOT, "apps", "triaxial", "configs", "calibrate-reduced.toml"), "rb"))
    rows = []
    for young in [float(v) for v in args.young.split(",")]:
        for seed in [int(v) for v in args.seeds.split(",")]:
            cfg = json.loads(json.dumps(base))
            cfg["material"].update(young=young, friction=args.friction, rolling_friction=args.rolling_friction)
            cfg["sample"]["seed"] = seed
            folder = run_point(f"E{young / 1e9:g}GPa-seed{seed}", cfg, args)
            index = os.path.join(folder, "index.csv")
            for r in csv.DictReader(open(index)):
                rows.append(dict(young=young, seed=seed, p0=float(r["p0_Pa"]), e0=float(r["e0"]),
                                 final_e=float(r["final_e"]), final_eta=float(r["final_eta"]),
                                 critical=r["status"] == "done (critical state)", steps=int(r["steps"])))
    os.makedirs(args.docs, exist_ok=True)
    with open(os.path.join(args.docs, "csl-vs-young.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    print("E (GPa) | e_c 0.5 MPa | e_c 2 MPa | e_c 8 MPa | drop 0.5-8 MPa | final q/p 0.5 / 8 MPa  (mean +- s.e.)")
    for young in sorted({r["young"] for r in rows}):
        def at(p0, key="final_e"):
            return np.array([r[key] for r in rows if r["young"] == young and r["p0"] == p0])
        se = lambda a: a.std(ddof=1) / np.sqrt(len(a)) if len(a) > 1 else float("nan")  # noqa: E731
        drop = at(0.5e6) - at(8e6)
        cols = [f"{at(p).mean():.4f} +- {se(at(p)):.4f}" for p in (0.5e6, 2e6, 8e6)]
        print(f"{young / 1e9:g} | " + " | ".join(cols) + f" | {drop.mean():+.4f} +- {se(drop):.4f} | "
              f"{at(0.5e6, 'final_eta').mean():.3f} / {at(8e6, 'final_eta').mean():.3f}")


if __name__ == "__main__":
    main()
