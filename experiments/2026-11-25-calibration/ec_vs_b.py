#!/usr/bin/python3
"""Does b = 1 end looser than b = 0 at the critical state, and does the gap close with strain, with
sample size or with the rolling resistance? The study's sample (apps/triaxial/configs/
paper-calibrated-reduced.toml: the calibrated frictions, the fast protocol) sheared at constant p
for b = 0 and b = 1 from the same prepared sample (the same seed prepares it bitwise the same),
without the critical-state stop, to the same deviatoric strain: b = 0 to eps_1 = 0.6 and b = 1 to
eps_1 = 0.3 both reach eps_q ~ 0.6 with the cell at the same aspect ratio (~2.5).

For each test, the void ratio and q/p averaged over windows of +-0.02 of eps_q around eps_q = 0.1,
0.15, ..., 0.6; for each (size, mu_r, p0), the paired gap e(b = 1) - e(b = 0) of each seed and
its mean and standard error over the seeds.

    $X/ec_vs_b.py [--count 1000] [--seeds 1,2,3,4,5,6,7,8] [--mu-r 0.064] [--p0 2e6]
        [--friction MU] [--rolling MODEL] [--b1-inertial I]
        [--out results/ec-vs-b] [--docs $X/ec-vs-b] [--threads 2]
    $X/ec_vs_b.py --calibration results/calibrate-full/runs.csv --docs $X/full

(From the repository root, with X=experiments/2026-11-25-calibration and PYTHONPATH=apps/analysis: the script
imports sandcell_analysis. DOCS defaults to the folder named above, beside this script.)

--b1-inertial shears only the b = 1 test at another inertial number (its b = 0 partner is reused):
at b = 1 the deviatoric strain grows about twice as fast as eps_1, so I / 2 gives both tests the
same deviatoric rate.

Writes DOCS/tests.csv (one row per test and eps_q), DOCS/gap.csv (per group and eps_q) and
DOCS/ec-vs-b.png; with several calls (other --count, --mu-r), the rows of every group whose runs
are in OUT are kept. Resumable: a finished campaign is not run again, a killed one resumes; each
runs in OUT/runs/n<count>-mur<mu_r>-p<p0 kPa>-b<b>-seed<S>, as `triaxial calibrate` runs its points.
"""
import argparse
import csv
import glob
import json
import os
import re
import sys
import tomllib

import numpy as np

from sandcell_analysis.calibrate import run_point
from sandcell_analysis.results import read_columns

HERE = os.path.dirname(os.path.abspath(__file__))  # the experiment's folder: the tables and figures
ROOT = os.path.dirname(os.path.dirname(HERE))  # the repository

EPS_Q = np.round(np.arange(0.1, 0.6001, 0.05), 3)
HALF_WINDOW = 0.02  # eps_q; at 1,000 spheres e fluctuates by ~0.005 over 0.01 of eps_q at the critical state
MAX_EPS1 = {0.0: 0.6, 1.0: 0.3}  # the same eps_q (~0.6) and cell aspect ratio (~2.5) at the end


def name_of(count, mu_r, p0, b, seed, both="", b1=""):
    """both: the tag of overrides of both tests (e.g. -mu0.7, -rollnone); b1: of the b = 1 test only."""
    return f"n{count}-mur{mu_r:g}-p{p0 / 1e3:g}kPa-b{b:g}-seed{seed}{both}{b1 if b == 1.0 else ''}"


def fabric_q(f):
    """sqrt(3/2 F':F') of the fabric <n (x) n> (xx, yy, zz, xy, xz, yz): 0 isotropic."""
    dev = f[:, :3] - f[:, :3].mean(axis=1, keepdims=True)
    return np.sqrt(1.5 * ((dev ** 2).sum(axis=1) + 2.0 * (f[:, 3:] ** 2).sum(axis=1)))


def window_means(path, count):
    """Per eps_q of EPS_Q: e, q/p, the cell's aspect ratio, Z_mech, the rattlers' share, the fabric's
    deviatoric invariant, as means over the window (NaN where the test did not reach it)."""
    s = read_columns(path, ("strain", "e", "eps_q", "eta", "Z_mech", "rattlers", "fabric"))
    out = []
    for x in EPS_Q:
        sel = np.abs(s["eps_q"] - x) <= HALF_WINDOW
        if sel.sum() < 5:  # not reached
            out.append(dict(eps_q=x, e=np.nan, eta=np.nan, aspect=np.nan, z_mech=np.nan, rattlers=np.nan,
                            fabric_q=np.nan))
            continue
        eps = s["strain"][sel].mean(axis=0)
        out.append(dict(eps_q=x, e=s["e"][sel].mean(), eta=s["eta"][sel].mean(),
                        aspect=float(np.exp(eps.max() - eps.min())), z_mech=s["Z_mech"][sel].mean(),
                        rattlers=s["rattlers"][sel].mean() / count, fabric_q=fabric_q(s["fabric"][sel]).mean()))
    return out


def run_all(args, base):
    both = (f"-mu{args.friction:g}" if args.friction is not None else "") + \
        (f"-roll{args.rolling}" if args.rolling else "")
    b1 = f"-b1I{args.b1_inertial:g}" if args.b1_inertial is not None else ""
    for count in [int(v) for v in args.count.split(",")]:
        for mu_r in [float(v) for v in args.mu_r.split(",")]:
            for p0 in [float(v) for v in args.p0.split(",")]:
                for seed in [int(v) for v in args.seeds.split(",")]:
                    for b in (0.0, 1.0):
                        cfg = json.loads(json.dumps(base))
                        cfg["sample"].update(count=count, seed=seed)
                        cfg["material"]["rolling_friction"] = mu_r
                        if args.friction is not None:
                            cfg["material"]["friction"] = args.friction
                        if args.rolling:
                            cfg["contact"]["rolling"] = args.rolling
                        cfg["shear"].update(stop_at_critical=False, max_axial_strain=MAX_EPS1[b])
                        if b == 1.0 and args.b1_inertial is not None:
                            cfg["shear"]["inertial_number"] = args.b1_inertial
                        cfg["tests"].update(p0=[p0], path="constant_p", b=[b], parallel=1)
                        cfg["output"] = {"series_interval": 50, "plot": False}
                        run_point(name_of(count, mu_r, p0, b, seed, both, b1), cfg, args)


def collect(out):
    rows = []
    pattern = re.compile(r"n(\d+)-mur([0-9.e+-]+?)-p([0-9.e+-]+)kPa-b([01])-seed(\d+)(.*)$")
    for folder in sorted(glob.glob(os.path.join(out, "runs", "*"))):
        m = pattern.match(os.path.basename(folder))
        index = os.path.join(folder, "index.csv")
        if not m or not os.path.exists(index):
            continue
        done = [r for r in csv.DictReader(open(index)) if r["status"].startswith("done")]
        if not done:
            continue
        count, mu_r, p0, b, seed = int(m[1]), float(m[2]), float(m[3]) * 1e3, float(m[4]), int(m[5])
        tags = m[6]
        b1 = tags[tags.index("-b1I"):] if "-b1I" in tags else ""
        both = tags[:len(tags) - len(b1)]
        for w in window_means(os.path.join(folder, done[0]["file"]), count):
            rows.append(dict(count=count, mu_r=mu_r, p0=p0, variant=both.lstrip("-") or "-",
                             b1_only=b1.lstrip("-") or "-", b=b, seed=seed, **w, e0=float(done[0]["e0"])))
    return rows


def group_label(g):
    count, mu_r, p0, variant, b1 = g
    extra = "" if variant == "-" else f", {variant}"
    extra += "" if b1 == "-" else f", b = 1 at {b1.replace('b1I', 'I = ')}"
    return f"{count} spheres, mu_r {mu_r:g}, p {p0 / 1e6:g} MPa{extra}"


def gaps(rows):
    out = []
    groups = sorted({(r["count"], r["mu_r"], r["p0"], r["variant"], r["b1_only"]) for r in rows if r["b"] == 1.0})
    for g in groups:
        for x in EPS_Q:
            base = [r for r in rows if (r["count"], r["mu_r"], r["p0"], r["variant"]) == g[:4] and r["eps_q"] == x]
            b0 = {r["seed"]: r for r in base if r["b"] == 0.0}
            b1 = {r["seed"]: r for r in base if r["b"] == 1.0 and r["b1_only"] == g[4]}
            seeds = sorted(set(b0) & set(b1))
            d = np.array([b1[s]["e"] - b0[s]["e"] for s in seeds])
            ok = np.isfinite(d)
            if not ok.any():
                continue
            seeds = [s for s, k in zip(seeds, ok) if k]
            d = d[ok]
            se = d.std(ddof=1) / np.sqrt(len(d)) if len(d) > 1 else np.nan
            out.append(dict(count=g[0], mu_r=g[1], p0=g[2], variant=g[3], b1_only=g[4], eps_q=x, seeds=len(d),
                            e_b0=np.mean([b0[s]["e"] for s in seeds]), e_b1=np.mean([b1[s]["e"] for s in seeds]),
                            gap=d.mean(), gap_se=se, eta_b0=np.mean([b0[s]["eta"] for s in seeds]),
                            eta_b1=np.mean([b1[s]["eta"] for s in seeds]),
                            z_b0=np.mean([b0[s]["z_mech"] for s in seeds]),
                            z_b1=np.mean([b1[s]["z_mech"] for s in seeds]),
                            fq_b0=np.mean([b0[s]["fabric_q"] for s in seeds]),
                            fq_b1=np.mean([b1[s]["fabric_q"] for s in seeds])))
    return out


def write(docs, rows, gap_rows):
    os.makedirs(docs, exist_ok=True)
    for fname, data in (("tests.csv", rows), ("gap.csv", gap_rows)):
        with open(os.path.join(docs, fname), "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(data[0].keys()))
            w.writeheader()
            for r in data:
                w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    groups = sorted({(r["count"], r["mu_r"], r["p0"], r["variant"], r["b1_only"]) for r in gap_rows})
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for g in groups:
        sel = [r for r in gap_rows if (r["count"], r["mu_r"], r["p0"], r["variant"], r["b1_only"]) == g]
        x = np.array([r["eps_q"] for r in sel])
        label = f"{group_label(g)} ({sel[0]['seeds']} seeds)"
        line, = axes[0].plot(x, [r["e_b0"] for r in sel], "o-", ms=3, label=label + ", b = 0")
        axes[0].plot(x, [r["e_b1"] for r in sel], "s--", ms=3, color=line.get_color(), label="b = 1")
        gap = np.array([r["gap"] for r in sel])
        se = np.array([r["gap_se"] for r in sel])
        axes[1].errorbar(x, gap, yerr=se, fmt="o-", ms=3, capsize=2, color=line.get_color(), label=label)
    axes[0].set_xlabel("eps_q")
    axes[0].set_ylabel("void ratio e (mean over seeds)")
    axes[0].legend(fontsize=5, loc="lower right")
    axes[1].axhline(0.0, color="k", lw=0.6)
    axes[1].set_xlabel("eps_q")
    axes[1].set_ylabel("e(b = 1) - e(b = 0), same sample (mean +- s.e.)")
    axes[1].legend(fontsize=6)
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle("constant p: the void ratio at b = 1 against b = 0 along the deviatoric strain", fontsize=9)
    fig.tight_layout()
    fig.savefig(os.path.join(docs, "ec-vs-b.png"), dpi=110)
    for r in gap_rows:
        g = (r["count"], r["mu_r"], r["p0"], r["variant"], r["b1_only"])
        print(f"{group_label(g)}, eps_q {r['eps_q']:.2f}: "
              f"e b0 {r['e_b0']:.4f} b1 {r['e_b1']:.4f} gap {r['gap']:+.4f} +- {r['gap_se']:.4f} ({r['seeds']} seeds); "
              f"q/p {r['eta_b0']:.3f} / {r['eta_b1']:.3f}; Z_mech {r['z_b0']:.3f} / {r['z_b1']:.3f}; "
              f"fabric_q {r['fq_b0']:.3f} / {r['fq_b1']:.3f}")
    print(f"wrote {docs}/tests.csv, gap.csv, ec-vs-b.png")


def calibration_gaps(runs_csv, docs):
    """The b = 1 - b = 0 gap in final e at each p0 of every run of a calibration whose tests include
    both (calibrate-full.toml), and its Spearman rho with each free parameter."""
    from sandcell_analysis.analyze import spearman
    rows = list(csv.DictReader(open(runs_csv)))
    pat = re.compile(r"final_e:p-b0\.00-p0_(\d+)kPa$")
    p0s = [m[1] for m in (pat.match(k) for k in rows[0]) if m and f"final_e:p-b1.00-p0_{m[1]}kPa" in rows[0]]
    params = [k for k in rows[0] if "." in k and not k.startswith("final") and k != "run"]
    out = []
    for r in rows:
        gaps = [float(r[f"final_e:p-b1.00-p0_{p}kPa"]) - float(r[f"final_e:p-b0.00-p0_{p}kPa"]) for p in p0s]
        out.append(dict(run=r["run"], **{k: float(r[k]) for k in params},
                        **{f"gap_{p}kPa": g for p, g in zip(p0s, gaps)}, mean_gap=float(np.mean(gaps))))
    os.makedirs(docs, exist_ok=True)
    with open(os.path.join(docs, "gap-vs-parameters.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(out[0].keys()))
        w.writeheader()
        for r in out:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    m = np.array([r["mean_gap"] for r in out])
    print(f"{len(out)} runs: mean gap over p0 {m.mean():+.4f} (min {m.min():+.4f}, max {m.max():+.4f}); "
          f"runs with a positive mean gap: {(m > 0).sum()} of {len(m)}")
    for p in p0s:
        g = np.array([r[f"gap_{p}kPa"] for r in out])
        print(f"  p0 {p} kPa: mean {g.mean():+.4f} +- {g.std(ddof=1) / np.sqrt(len(g)):.4f} (s.e.)")
    for k in params:
        print(f"  rho({k}, mean gap) = {spearman(np.array([r[k] for r in out]), m):+.2f}")
    print(f"wrote {docs}/gap-vs-parameters.csv")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--count", default="1000")
    ap.add_argument("--seeds", default="1,2,3,4,5,6,7,8")
    ap.add_argument("--mu-r", default="0.064")
    ap.add_argument("--p0", default="2e6")
    ap.add_argument("--out", default="results/ec-vs-b")
    ap.add_argument("--docs", default=os.path.join(HERE, "ec-vs-b"))
    ap.add_argument("--friction", type=float, help="material.friction of both tests (default: the config's 0.35)")
    ap.add_argument("--rolling", help="contact.rolling of both tests (default: the config's epsd2)")
    ap.add_argument("--b1-inertial", type=float, help="shear.inertial_number of the b = 1 test only")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--no-run", action="store_true", help="only collect what OUT holds")
    ap.add_argument("--calibration", metavar="RUNS_CSV",
                    help="no runs: the gap in every run of a calibration with b = 0 and b = 1 tests (its runs.csv)")
    ap.add_argument("--triaxial", default=os.path.join(ROOT, "build", "release", "apps", "triaxial", "triaxial"))
    args = ap.parse_args()
    if args.calibration:
        return calibration_gaps(args.calibration, args.docs)
    base = tomllib.load(open(os.path.join(ROOT, "apps", "triaxial", "configs", "paper-calibrated-reduced.toml"), "rb"))
    if not args.no_run:
        run_all(args, base)
    rows = collect(args.out)
    if not rows:
        sys.exit(f"ec_vs_b.py: no finished runs in {args.out}")
    write(args.docs, rows, gaps(rows))


if __name__ == "__main__":
    main()
