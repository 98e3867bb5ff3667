#!/usr/bin/python3
"""The largest dilation rate against b, over the plausible range of the rolling resistance:
one constant-p campaign (apps/triaxial/configs/dilation-vs-b.toml: 1,000 spheres, p0 = 2 MPa,
b = 0, 0.25, 0.5, 0.75, 1) per rolling model and rolling friction, each analysed by
`triaxial analyze`; writes results.csv (one row per test), trend.csv (Spearman rho(b, -min d) per
campaign, the study's criterion being rho >= +0.8), dilation-vs-b.png and README-ready tables.

    $X/dilation_vs_b.py [--out results/dilation-vs-b] [--docs $X/dilation-vs-b]
        [--mu-r 0.05,0.1,0.2,0.4] [--rolling epsd2,epsd,cdt] [--threads 2]
    $X/dilation_vs_b.py --campaign results/paper-fast [--campaign ...] [--docs ...]

(From the repository root, with X=experiments/2026-11-25-calibration and PYTHONPATH=apps/analysis: the script
imports sandcell_analysis. DOCS defaults to the folder named above, beside this script.)

Both measures of the largest dilation rate are reported: -d eps_v / d eps_q (the dilatancy of the
Li-Dafalias law, what `triaxial analyze` tests) and -d eps_v / d eps_1 (against the axial strain).
With --campaign, no runs: the two measures' Spearman rho over b in every (path, p0) group of
finished campaigns (campaign-trend.csv).

Resumable: a campaign whose tests are all done is not run again (`triaxial --resume` finishes a
killed one); each runs in OUT/runs/<rolling>-mur<mu_r>, as `triaxial calibrate` runs its points.
"""
import argparse
import csv
import json
import os
import subprocess
import tomllib

import numpy as np

from sandcell_analysis.analyze import spearman
from sandcell_analysis.calibrate import run_point
from sandcell_analysis.dilatancy import slope_max_dilation
from sandcell_analysis.results import read_columns

HERE = os.path.dirname(os.path.abspath(__file__))  # the experiment's folder: the tables and figures
ROOT = os.path.dirname(os.path.dirname(HERE))  # the repository


def largest_rates(path):
    s = read_columns(path, ("strain", "eps_v", "eps_q"))
    eps1 = s["strain"][:, 0]
    return slope_max_dilation(eps1, s["eps_v"], s["eps_q"]), slope_max_dilation(eps1, s["eps_v"], eps1)


def campaign_trends(folders, docs):
    out = []
    for folder in folders:
        rows = [r for r in csv.DictReader(open(os.path.join(folder, "index.csv"))) if r["status"].startswith("done")]
        groups = sorted({(r["path"], float(r["p0_Pa"])) for r in rows})
        for path, p0 in groups:
            sel = sorted((r for r in rows if r["path"] == path and float(r["p0_Pa"]) == p0),
                         key=lambda r: float(r["b"]))
            if len(sel) < 3:
                continue
            b = np.array([float(r["b"]) for r in sel])
            rates = np.array([largest_rates(os.path.join(folder, r["file"])) for r in sel])
            rho_q, rho_1 = spearman(b, rates[:, 0]), spearman(b, rates[:, 1])
            out.append(dict(campaign=os.path.basename(os.path.normpath(folder)), path=path, p0_MPa=p0 / 1e6,
                            tests=len(sel), rho_eps_q=rho_q, rho_eps_1=rho_1))
            print(f"{out[-1]['campaign']} {path} {p0 / 1e6:g} MPa: rho(b, max -dv/dq) {rho_q:+.2f}, "
                  f"rho(b, max -dv/de1) {rho_1:+.2f}", flush=True)
    os.makedirs(docs, exist_ok=True)
    with open(os.path.join(docs, "campaign-trend.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(out[0].keys()))
        w.writeheader()
        w.writerows(out)
    print(f"wrote {docs}/campaign-trend.csv")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="results/dilation-vs-b")
    ap.add_argument("--docs", default=os.path.join(HERE, "dilation-vs-b"))
    ap.add_argument("--mu-r", default="0.05,0.1,0.2,0.4")
    ap.add_argument("--rolling", default="epsd2,epsd,cdt")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--triaxial", default=os.path.join(ROOT, "build", "release", "apps", "triaxial", "triaxial"))
    ap.add_argument("--campaign", action="append", help="a finished campaign's folder (repeatable): trends only")
    args = ap.parse_args()
    if args.campaign:
        return campaign_trends(args.campaign, args.docs)
    base = tomllib.load(open(os.path.join(ROOT, "apps", "triaxial", "configs", "dilation-vs-b.toml"), "rb"))
    rows, trends = [], []
    for model in args.rolling.split(","):
        for mu_r in [float(v) for v in args.mu_r.split(",")]:
            cfg = json.loads(json.dumps(base))
            cfg["contact"]["rolling"] = model
            cfg["material"]["rolling_friction"] = mu_r
            name = f"{model}-mur{mu_r:g}"
            folder = run_point(name, cfg, args)  # a new or changed config drops the folder's analysis
            analysis = os.path.join(folder, "analysis")
            if not os.path.exists(os.path.join(analysis, "summary.json")):
                subprocess.run([args.triaxial, "analyze", folder, "--out", analysis], check=True,
                               capture_output=True)
            summary = json.load(open(os.path.join(analysis, "summary.json")))
            tests = sorted(summary["tests"], key=lambda t: t["b"])
            for t in tests:
                # max_dv_de1: the largest -d eps_v / d eps_1 (slopes over windows of 1 % of eps_1), the
                # measure a study reporting dilation against axial strain would take.
                rows.append(dict(rolling=model, mu_r=mu_r, b=t["b"], max_dilation=-t["min_d"],
                                 eps1_at_max=t["eps1_min_d"], max_dilation_eps1=t["max_dv_de1"],
                                 peak_eta=t["peak"]["eta"], critical=t["critical"], eps_v_end=t["eps_v_end"]))
            b = np.array([t["b"] for t in tests])
            mine = rows[-len(tests):]
            d = np.array([r["max_dilation"] for r in mine])
            d1 = np.array([r["max_dilation_eps1"] for r in mine])
            rho, rho1 = spearman(b, d), spearman(b, d1)
            trends.append(dict(rolling=model, mu_r=mu_r, rho=rho, reproduced=bool(rho >= 0.8),
                               d_b0=d[0], d_b1=d[-1], rho_eps1=rho1, d1_b0=d1[0], d1_b1=d1[-1]))
            print(f"{name}: max -dv/dq {' '.join(f'{v:.3f}' for v in d)} (rho {rho:+.2f}); "
                  f"max -dv/de1 {' '.join(f'{v:.3f}' for v in d1)} (rho {rho1:+.2f})", flush=True)
    os.makedirs(args.docs, exist_ok=True)
    for fname, data in (("results.csv", rows), ("trend.csv", trends)):
        with open(os.path.join(args.docs, fname), "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(data[0].keys()))
            w.writeheader()
            w.writerows(data)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    models = args.rolling.split(",")
    fig, axes = plt.subplots(2, len(models), figsize=(4.2 * len(models), 6.6), sharey="row", squeeze=False)
    for col, model in enumerate(models):
        for row, (key, label) in enumerate((("max_dilation", "max -d eps_v / d eps_q"),
                                            ("max_dilation_eps1", "max -d eps_v / d eps_1"))):
            ax = axes[row, col]
            for mu_r in sorted({r["mu_r"] for r in rows}):
                sel = [r for r in rows if r["rolling"] == model and r["mu_r"] == mu_r]
                ax.plot([r["b"] for r in sel], [r[key] for r in sel], "o-", label=f"mu_r {mu_r:g}")
            ax.set_title(f"rolling {model}", fontsize=9)
            ax.set_xlabel("b")
            ax.grid(alpha=0.3)
            if col == 0:
                ax.set_ylabel(label)
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("constant p = 2 MPa, 1,000 spheres: the study has the largest dilation rate growing with b",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(os.path.join(args.docs, "dilation-vs-b.png"), dpi=110)
    print(f"wrote {args.docs}/results.csv, trend.csv, dilation-vs-b.png")


if __name__ == "__main__":
    main()
