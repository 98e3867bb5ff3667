#!/usr/bin/python3
"""How well the data determine the Li-Dafalias constants d0 and m: for each finished campaign given,
the b = 0 dilatancy points of `triaxial analyze` (its own CSL for psi, its own M_c), and for each m
on a grid the best d0 and the RMS misfit of d = d0/M (M exp(m psi) - eta). A flat profile means
that m is not determined, and every (d0, m) along it fits the points about as well. Also the RMS at
the study's own constants (d0 = 0.619, m = 4.570) and with m fixed at 4.570 (d0 refitted). Writes
profile.csv, constants.csv and dilatancy-profile.png.

    $X/dilatancy_profile.py NAME=CAMPAIGN_DIR [NAME=DIR ...] [--docs $X/dilatancy-profile]
        [--plastic]

(From the repository root, with X=experiments/2026-11-25-calibration and PYTHONPATH=apps/analysis: the script
imports sandcell_analysis. DOCS defaults to the folder named above, beside this script.)

--plastic: d from plastic increments, d eps_v^p / d eps_q^p. On a constant-p path the elastic
volumetric increment is zero, and the elastic deviatoric strain is (q - q0) / 3G, with 3G the
initial slope of q against eps_q (a straight line through the rows up to eps_1 = 1e-4) of each
test. The points are then made exactly as `triaxial analyze` makes them from total increments.
"""
import argparse
import csv
import os

import numpy as np

from sandcell_analysis.analyze import analyze_tests, parse_args
from sandcell_analysis.csl import csl_e
from sandcell_analysis.dilatancy import dilatancy_series
from sandcell_analysis.results import b_key, collect_files, read_test

HERE = os.path.dirname(os.path.abspath(__file__))  # the experiment's folder: the tables and figures

STUDY_D0, STUDY_M = 0.619, 4.570


def plastic_points(t, opt, cpar):
    """The test's dilatancy points from plastic increments (see --plastic)."""
    early = t["eps1"] <= 1e-4
    if early.sum() < 4:
        early = np.arange(t["eps1"].size) < 6
    three_g = np.polyfit(t["eps_q"][early], t["q"][early], 1)[0]
    eps_q_p = t["eps_q"] - (t["q"] - t["q"][0]) / three_g
    dil = dilatancy_series(t["eps1"], t["eps_v"], eps_q_p, smooth=opt.smooth, min_strain=opt.min_strain,
                           min_deq=opt.min_deq, others={k: t[k] for k in ("eta", "p", "e", "theta")},
                           stress=t.get("stress"))
    dil["psi"] = dil["e"] - csl_e(dil["p"], cpar["e_gamma"], cpar["lambda"], cpar["xi"])
    return dil, three_g / 3.0


def points(folder, plastic=False):
    """The pooled b = 0 constant-p dilatancy points (eta, psi, d), the tests' p0 per point, and M_c."""
    opt = parse_args([folder, "--out", os.devnull])
    tests = []
    for f, _ in collect_files([folder]):
        t, _ = read_test(f)
        if t is not None and t["rows"] >= 5:
            tests.append(t)
    res = analyze_tests(tests, opt)
    zero = [t for t in tests if t["path"] == "constant_p" and b_key(t) == 0]
    if plastic:
        cpar = res["csl"]["params"]
        for t in zero:
            t["dil"], t["G"] = plastic_points(t, opt, cpar)
            print(f"  {t['name']}: G = {t['G'] / 1e6:.0f} MPa from the initial slope", flush=True)
    pooled = {k: np.concatenate([t["dil"][k][t["dil"]["mask"]] for t in zero]) for k in ("eta", "psi", "d")}
    p0 = np.concatenate([np.full(int(t["dil"]["mask"].sum()), t["p0"]) for t in zero])
    return pooled, p0, res["m_theta"]["params"]["M_c"]


def misfit(pts, M, m, d0=None):
    f = np.exp(m * pts["psi"]) - pts["eta"] / M
    if d0 is None:
        d0 = float(f @ pts["d"]) / float(f @ f)
    r = pts["d"] - d0 * f
    return float(np.sqrt(np.mean(r * r))), d0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("campaigns", nargs="+", help="NAME=DIR")
    ap.add_argument("--docs", default=os.path.join(HERE, "dilatancy-profile"))
    ap.add_argument("--plastic", action="store_true", help="d from plastic strain increments")
    args = ap.parse_args()
    grid = np.linspace(-2.0, 30.0, 161)
    profile, constants = [], []
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for spec in args.campaigns:
        name, folder = spec.split("=", 1)
        pts, p0, M = points(folder, args.plastic)
        for scope, sel in (("0.5-16 MPa", np.ones_like(p0, bool)), ("0.5 MPa", p0 == 0.5e6)):
            sub = {k: v[sel] for k, v in pts.items()}
            if sub["d"].size < 3:
                continue
            rms = [misfit(sub, M, m) for m in grid]
            best = int(np.argmin([r[0] for r in rms]))
            at_study = misfit(sub, M, STUDY_M, STUDY_D0)[0]
            m_fixed, d0_fixed = misfit(sub, M, STUDY_M)
            for m, (r, d0) in zip(grid, rms):
                profile.append(dict(campaign=name, scope=scope, m=m, d0=d0, rms=r))
            constants.append(dict(campaign=name, scope=scope, points=int(sub["d"].size), M_c=M,
                                  best_m=grid[best], best_d0=rms[best][1], best_rms=rms[best][0],
                                  rms_m_4_57_d0_refit=m_fixed, d0_at_m_4_57=d0_fixed, rms_study=at_study))
            c = constants[-1]
            print(f"{name} ({scope}, {c['points']} points, M_c {M:.3f}): best m {c['best_m']:.1f}, d0 "
                  f"{c['best_d0']:.3f}, RMS {c['best_rms']:.4f}; m = 4.57: d0 {d0_fixed:.3f}, RMS {m_fixed:.4f}; "
                  f"the study's (0.619, 4.57): RMS {at_study:.4f}", flush=True)
            ax.plot(grid, [r[0] for r in rms], "-" if scope == "0.5-16 MPa" else "--", label=f"{name}, {scope}")
    ax.axvline(STUDY_M, color="k", lw=0.8, ls=":")
    ax.set_xlabel("m (d0 refitted at each m)")
    ax.set_ylabel("RMS misfit of d")
    ax.set_title("Li-Dafalias fit at b = 0, constant p: the misfit along m"
                 + (" (plastic increments)" if args.plastic else ""), fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    os.makedirs(args.docs, exist_ok=True)
    fig.tight_layout()
    fig.savefig(os.path.join(args.docs, "dilatancy-profile.png"), dpi=110)
    for fname, rows in (("profile.csv", profile), ("constants.csv", constants)):
        with open(os.path.join(args.docs, fname), "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
            w.writeheader()
            w.writerows(rows)
    print(f"wrote {args.docs}/profile.csv, constants.csv, dilatancy-profile.png")


if __name__ == "__main__":
    main()
