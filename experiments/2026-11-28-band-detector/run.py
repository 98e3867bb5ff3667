#!/usr/bin/env python3
"""The band detector (issue 45, item 1): its false-positive rate and power on synthetic samples at 1,000, 4,000 and
19,436 spheres, and its verdicts on the committed campaigns, old criterion against new.

    PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-28-band-detector/run.py \
        [--results /work/campaigns] [--only synthetic|campaigns] [--seeds 20]

Writes next to this script: synthetic.csv (one row per synthetic sample), campaigns.csv (one row per campaign test),
increments.csv (one row per snapshot increment of every campaign test), synthetic.png, campaigns.png and
verdicts.md (the tables of the README, from the CSVs; --only summary rewrites it alone).
"""
import argparse
import csv
import glob
import math
import os
import sys
import time

import numpy as np

from sandcell_analysis import band_detector as bd
from sandcell_analysis import band_synthetic as syn
from sandcell_analysis import localization as loc
from sandcell_analysis.results import InputError, open_results, read_series

HERE = os.path.dirname(os.path.abspath(__file__))
SIZES = (1000, 4000, 19436)
KINDS = ("noise", "gaussian", "band")
CAMPAIGNS = (("paper-fast", "paper-fast"), ("paper-calibrated", "paper-calibrated"),
             ("paper-reduced", "paper-reduced"), ("paper-calibrated-reduced", "paper-calibrated-reduced"),
             ("free-cell", "free-cell/out"))
CMD = "PYTHONPATH=apps/analysis python3 experiments/2026-11-28-band-detector/run.py"


def band_width(n):
    """The synthetic band's width (d50): 5, but 3 in the 1,000-sphere cell (9.4 d50 across: a (1,0,1) period of
    6.7 d50, which a 5 d50 band would fill three quarters of)."""
    return 3.0 if n < 2000 else 5.0


def write_csv(path, rows):
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]), lineterminator="\n")
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})


def synthetic(seeds):
    rows = []
    for n in SIZES:
        G = loc.default_grid(n)
        for kind in KINDS:
            t = time.time()
            for seed in range(seeds):
                snaps, series = syn.sample(kind, n, 1000 * SIZES.index(n) + 100 * KINDS.index(kind) + seed,
                                           width=band_width(n))
                res = loc.judge_test(snaps, series, G)
                b, whole = res["band"], res["rows"]
                k0, frac, persistent = res["onset"]
                rows.append(dict(n=n, grid=G, kind=kind, seed=seed, share=b["share"], shuffled=b["shuffled"],
                                 old_banded=int(b["share"] > loc.BAND_CONTRAST * b["shuffled"]),
                                 threshold_noise=b["judged"]["threshold_noise"],
                                 threshold_gauss=b["judged"]["threshold_gauss"], ell_d50=b["judged"]["ell"] / syn.D50,
                                 significant=int(b["judged"]["significant"]), ratio=b["ratio"],
                                 growth=b["growth"], noise=b["noise"], banded=int(b["banded"]),
                                 increments_significant=sum(r["significant"] for r in whole),
                                 increments_detected=sum(r["band_detected"] for r in whole),
                                 onset=-1 if k0 is None else k0, persistence=frac))
            done = [r for r in rows if r["n"] == n and r["kind"] == kind]
            print(f"synthetic N = {n} (G = {G}) {kind}: banded {sum(r['banded'] for r in done)}/{len(done)}, "
                  f"statistic alone {sum(r['significant'] for r in done)}/{len(done)}, old criterion "
                  f"{sum(r['old_banded'] for r in done)}/{len(done)} ({time.time() - t:.0f} s)", flush=True)
    write_csv(os.path.join(HERE, "synthetic.csv"), rows)
    return rows


def name_fields(test):
    """(b, p0 in kPa, path) from a test name like p-b0.50-p0_500kPa."""
    parts = test.split("-")
    paths = {"p": "constant_p", "s3": "constant_sigma3"}
    return float(parts[1][1:]), float(parts[2].split("_")[1].rstrip("kPa")), paths[parts[0]]


def campaigns(root):
    rows, incs = [], []
    for label, sub in CAMPAIGNS:
        files = sorted(f for f in glob.glob(os.path.join(root, sub, "*.h5"))
                       if os.path.basename(f).startswith(("p-", "s3-")) and "checkpoint" not in f)
        t = time.time()
        for path in files:
            test = os.path.basename(path)[:-3]
            b_val, p0, stress_path = name_fields(test)
            base = dict(campaign=label, test=test, path=stress_path, b=b_val, p0_kPa=p0)
            try:
                with open_results(path) as f:
                    series = read_series(f, path)
                    snaps = loc.read_snapshots(f, path)
            except InputError as e:
                rows.append(dict(base, n=math.nan, verdict_old="not judged", verdict_new="not judged",
                                 note=str(e).split(": ", 2)[-1]))
                continue
            G = loc.default_grid(len(snaps[0][1]))
            res = loc.judge_test(snaps, series, G)
            b = res["band"]
            k0, frac, persistent = res["onset"]
            old = b["share"] > loc.BAND_CONTRAST * b["shuffled"]
            j = b["judged"]
            rows.append(dict(base, n=len(snaps[0][1]), grid=G, snapshots=len(snaps), mode=loc.mode_str(b["hkl"]),
                             share=b["share"], shuffled=b["shuffled"],
                             threshold=max(j["threshold_noise"], j["threshold_gauss"]),
                             threshold_noise=j["threshold_noise"], threshold_gauss=j["threshold_gauss"],
                             ell_mm=j["ell"] * 1e3, significant=int(j["significant"]), ratio=b["ratio"],
                             ratio_whole=b.get("ratio_whole", math.nan), growth=b["growth"], noise=b["noise"],
                             verdict_old="banded" if old else "no band",
                             verdict_new="banded" if b["banded"] else "no band",
                             onset_eps1=res["rows"][k0]["eps1_mid"] if k0 is not None else math.nan,
                             persistence=frac, persistent=int(persistent),
                             note="; ".join(b.get("why", []))))
            for r in res["rows"]:
                incs.append(dict(campaign=label, test=test, step_a=r["step_a"], step_b=r["step_b"],
                                 eps1_mid=r["eps1_mid"], mode=f"({r['mode_h']},{r['mode_k']},{r['mode_l']})",
                                 share=r["mode_share"],
                                 threshold=max(r["threshold_noise"], r["threshold_gauss"]),
                                 ell_mm=r["corr_length"] * 1e3, significant=r["significant"],
                                 strain_ratio=r["strain_ratio"], band_detected=r["band_detected"]))
            print(f"{label} {test}: N {len(snaps[0][1])}, old {rows[-1]['verdict_old']}, new "
                  f"{rows[-1]['verdict_new']} (share {b['share']:.3f} / {rows[-1]['threshold']:.3f}, ratio "
                  f"{b['ratio']:.2f}, growth {b['growth']:+.4f} noise {b['noise']:.4f})", flush=True)
        print(f"{label}: {len(files)} files, {time.time() - t:.0f} s", flush=True)
    keys = list(dict.fromkeys(k for r in rows for k in r))
    write_csv(os.path.join(HERE, "campaigns.csv"), [{k: r.get(k, "") for k in keys} for r in rows])
    write_csv(os.path.join(HERE, "increments.csv"), incs)
    return rows


def plot_synthetic(rows):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axs = plt.subplots(1, 3, figsize=(14, 4.2))
    for ax, n in zip(axs, SIZES):
        for c, kind in enumerate(KINDS):
            sel = [r for r in rows if r["n"] == n and r["kind"] == kind]
            thr = [max(r["threshold_noise"], r["threshold_gauss"]) for r in sel]
            ax.scatter(thr, [r["share"] for r in sel], s=18, color=f"C{c}",
                       marker="o", label=f"{kind}: banded {sum(r['banded'] for r in sel)}/{len(sel)}, old "
                       f"{sum(r['old_banded'] for r in sel)}/{len(sel)}")
            ax.scatter([loc.BAND_CONTRAST * r["shuffled"] for r in sel], [r["share"] for r in sel], s=10,
                       color=f"C{c}", marker="x")
        lim = [0, 1.02]
        ax.plot(lim, lim, "k-", lw=0.8)
        ax.set_xlim(lim)
        ax.set_ylim(lim)
        ax.set_xlabel("threshold: surrogates' 0.99 quantile (o), old 3 x shuffled (x)")
        ax.set_ylabel("strongest mode's share (whole test)")
        ax.set_title(f"N = {n}, grid {loc.default_grid(n)}^3", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    fig.suptitle(f"synthetic samples: above the diagonal = statistic significant. Reproduce: {CMD} --only synthetic",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(os.path.join(HERE, "synthetic.png"), dpi=90)
    plt.close(fig)


def plot_campaigns(rows):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rows = [r for r in rows if r["verdict_new"] != "not judged"]
    fig, axs = plt.subplots(1, 3, figsize=(15, 4.5))
    bs = sorted({r["b"] for r in rows})
    for r in rows:
        c = f"C{bs.index(r['b'])}"
        m = "o" if r["n"] > 5000 else "s"
        fc = c if r["verdict_new"] == "banded" else "none"
        axs[0].scatter(r["threshold"], r["share"], marker=m, edgecolors=c, facecolors=fc, s=25)
        axs[1].scatter(r["share"] / r["threshold"], r["ratio"], marker=m, edgecolors=c, facecolors=fc, s=25)
        axs[2].scatter(r["ratio"], r["growth"] / max(r["noise"], 1e-9) if r["noise"] > 0 else np.nan, marker=m,
                       edgecolors=c, facecolors=fc, s=25)
    axs[0].plot([0, 1], [0, 1], "k-", lw=0.8)
    axs[0].set_xlabel("surrogates' 0.99 quantile")
    axs[0].set_ylabel("strongest mode's share (whole test)")
    axs[1].axvline(1, color="k", lw=0.8)
    axs[1].axhline(bd.STRAIN_RATIO, color="k", lw=0.8)
    axs[1].set_xscale("log")
    axs[1].set_xlabel("share / threshold")
    axs[1].set_ylabel("band/outside deps_q (largest increment)")
    axs[2].axvline(bd.STRAIN_RATIO, color="k", lw=0.8)
    axs[2].axhline(bd.NOISE_SIGMAS, color="k", lw=0.8)
    axs[2].set_xlabel("band/outside deps_q (largest increment)")
    axs[2].set_ylabel("void-ratio contrast growth / its noise")
    for ax in axs:
        ax.grid(alpha=0.3)
    for k, b in enumerate(bs):
        axs[0].scatter([], [], color=f"C{k}", label=f"b = {b:g}")
    axs[0].scatter([], [], marker="o", color="0.5", label="19,436 spheres")
    axs[0].scatter([], [], marker="s", color="0.5", label="1,000 spheres")
    axs[0].legend(fontsize=7)
    fig.suptitle(f"campaign tests (filled: banded by the new detector). Reproduce: {CMD} --only campaigns", fontsize=9)
    fig.tight_layout()
    fig.savefig(os.path.join(HERE, "campaigns.png"), dpi=90)
    plt.close(fig)


def read_csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def reasons(r):
    """The criteria a campaign test fails, as letters: s statistic, r strain ratio, v void-ratio contrast."""
    out = "" if int(r["significant"]) else "s"
    out += "" if float(r["ratio"]) >= bd.STRAIN_RATIO else "r"
    growth, noise = float(r["growth"]), float(r["noise"])
    return out + ("" if growth >= max(bd.VOID_CONTRAST, bd.NOISE_SIGMAS * noise) else "v")


def summary():
    """verdicts.md from synthetic.csv and campaigns.csv: the tables the README quotes."""
    syn_rows, camp = read_csv(os.path.join(HERE, "synthetic.csv")), read_csv(os.path.join(HERE, "campaigns.csv"))
    out = [f"# Band detector: verdicts (written by `{CMD} --only summary`)", "",
           "## Synthetic samples (20 per size and kind)", "",
           "| N | grid | kind | banded (new) | statistic alone | old criterion |", "|---|---|---|---|---|---|"]
    for n in SIZES:
        for kind in KINDS:
            sel = [r for r in syn_rows if int(r["n"]) == n and r["kind"] == kind]
            out.append(f"| {n:,} | {sel[0]['grid']}^3 | {kind} | {sum(int(r['banded']) for r in sel)}/{len(sel)} | "
                       f"{sum(int(r['significant']) for r in sel)}/{len(sel)} | "
                       f"{sum(int(r['old_banded']) for r in sel)}/{len(sel)} |")
    out += ["", "## Campaign tests: new verdict per test (old: every 19,436-sphere test banded, no 1,000-sphere one)",
            "", "Cell: `band`, or `no` with the criteria failed (s: mode share not above the surrogates' 0.99 "
            "quantile; r: band/outside deps_q below 2 in every increment; v: void-ratio contrast growth below "
            "0.01 or 3 x noise) and the largest strain ratio.", ""]
    for label in ("paper-fast", "paper-calibrated", "paper-reduced", "paper-calibrated-reduced"):
        sel = [r for r in camp if r["campaign"] == label]
        if not sel:
            continue
        bs = sorted({float(r["b"]) for r in sel})
        out += [f"### {label} ({sel[0]['n']} spheres): old {sum(r['verdict_old'] == 'banded' for r in sel)}/"
                f"{len(sel)} banded, new {sum(r['verdict_new'] == 'banded' for r in sel)}/{len(sel)}", "",
                "| path | p0 kPa | " + " | ".join(f"b = {b:g}" for b in bs) + " |", "|---|---|" + "---|" * len(bs)]
        for path in ("constant_p", "constant_sigma3"):
            for p0 in sorted({float(r["p0_kPa"]) for r in sel}):
                cells = []
                for b in bs:
                    r = next(x for x in sel if x["path"] == path and float(x["p0_kPa"]) == p0 and float(x["b"]) == b)
                    why = reasons(r)
                    cells.append("band" if r["verdict_new"] == "banded"
                                 else f"no ({','.join(why)}; {float(r['ratio']):.2f})")
                out.append(f"| {path} | {p0:g} | " + " | ".join(cells) + " |")
        out.append("")
        for b in bs:
            g = [r for r in sel if float(r["b"]) == b]
            nb = [r for r in g if r["verdict_new"] == "banded"]
            n_sig = sum(int(r['significant']) for r in g)
            ratios = [float(r["ratio"]) for r in g]
            growths = [float(r["growth"]) for r in g]
            line = (f"- b = {b:g}: {len(nb)}/{len(g)} banded; statistic significant {n_sig}/{len(g)}; largest strain "
                    f"ratio {min(ratios):.2f}-{max(ratios):.2f}; void-ratio contrast growth {min(growths):+.3f} to "
                    f"{max(growths):+.3f}")
            if nb:
                onset = [float(r["onset_eps1"]) for r in nb]
                line += f"; onset (increment midpoint) eps_1 {min(onset):.3f}-{max(onset):.3f}"
            out.append(line)
        out.append("")
    skipped = [r for r in camp if r["verdict_new"] == "not judged"]
    if skipped:
        names = ", ".join(r["campaign"] + "/" + r["test"] for r in skipped)
        out += [f"Not judged: {names} ({skipped[0]['note']}).", ""]
    with open(os.path.join(HERE, "verdicts.md"), "w") as fh:
        fh.write("\n".join(out))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--results", default="/work/campaigns", help="folder holding the campaigns' result folders")
    ap.add_argument("--only", choices=("synthetic", "campaigns", "summary"))
    ap.add_argument("--seeds", type=int, default=20, help="synthetic samples per size and kind")
    a = ap.parse_args(argv)
    if a.only in (None, "synthetic"):
        plot_synthetic(synthetic(a.seeds))
    if a.only in (None, "campaigns"):
        plot_campaigns(campaigns(a.results))
    summary()
    return 0


if __name__ == "__main__":
    sys.exit(main())
