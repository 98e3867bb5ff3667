#!/usr/bin/env python3
"""Figures and table of experiments/2026-11-28-stress-paths: every test's stresses against their
targets, b, p and the principal axes' turn, against eps_1.

    plot_paths.py RESULTS_DIR EXPERIMENT_DIR

RESULTS_DIR holds fast/ and paper/ (the two protocols' runs, run.sh); writes EXPERIMENT_DIR/figures/
<protocol>-<path>-p0_<kPa>.png (one column per b) and EXPERIMENT_DIR/results/paths.csv (per test: the
app's verdict, the largest errors of path_check.py's window means, the end).
"""
import csv
import glob
import os
import sys

import h5py
import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "apps", "analysis"))
from sandcell_analysis import path_check  # noqa: E402

WINDOW = path_check.DEFAULTS["window"]
START = 0.002  # shear.ramp_strain of both configs


def text(v):
    return v.decode() if isinstance(v, bytes) else str(v)


def load(fn):
    with h5py.File(fn, "r") as f:
        s = f["series"]
        d = {k: np.asarray(s[k][...], float) for k in ("strain", "stress", "p", "max_overlap_ratio",
                                                       "unbalanced_force_ratio")}
        d.update(path=text(f.attrs["path"]), b=float(text(f.attrs["b"])), p0=float(text(f.attrs["p0"])),
                 status=text(f.attrs.get("status", "")), reason=text(f.attrs.get("status_reason", "")),
                 name=text(f.attrs["job"]))
    d["eps1"] = d["strain"][:, 0]
    return d


def window_means(d):
    """Trailing 1 % window means of the stress tensor from the ramp's end (NaN before the window fills)."""
    eps = d["eps1"]
    t = path_check.tensor(d["stress"])
    travel = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(eps)))])
    out = np.full((len(eps), 3, 3), np.nan)
    begin = first = None
    for i in range(1, len(eps)):
        if begin is None:
            if travel[i] < START:
                continue
            begin = first = i
        while travel[i] - travel[first] > WINDOW:
            first += 1
        if travel[i] - travel[begin] >= WINDOW:
            out[i] = t[first:i + 1].mean(axis=0)
    return out


def targets(d, s1):
    """sigma2*, sigma3* of the path from the measured sigma1 (docs/physics.md section 6)."""
    b, p0 = d["b"], d["p0"]
    if d["path"] == "constant_p":
        return (3 * p0 * (1 - b) + (2 * b - 1) * s1) / (2 - b), (3 * p0 - (1 + b) * s1) / (2 - b)
    return b * s1 + (1 - b) * p0, np.full_like(s1, p0)


def figure(tests, title, path):
    tests = sorted(tests, key=lambda d: d["b"])
    fig, ax = plt.subplots(4, len(tests), figsize=(3.2 * len(tests), 10), sharex="col", squeeze=False)
    for j, d in enumerate(tests):
        e = 100 * d["eps1"]
        s = d["stress"] / d["p0"]
        m = window_means(d)
        s2t, s3t = targets(d, d["stress"][:, 0])
        a = ax[0, j]
        for k, (c, lab) in enumerate((("C0", "S_xx (sigma1)"), ("C1", "S_yy (sigma2)"), ("C2", "S_zz (sigma3)"))):
            a.plot(e, s[:, k], color=c, lw=0.8, label=lab)
        a.plot(e, s2t / d["p0"], "k--", lw=0.8, label="targets")
        a.plot(e, s3t / d["p0"], "k--", lw=0.8)
        fl = d["check"]["failure"]
        verdict = f"failed: {fl['quantity']}" if fl else "on its path"
        a.set_title(f"b = {d['b']:g}: {verdict}", fontsize=9, color="C3" if fl else "k")
        if j == 0:
            a.set_ylabel("stress / p0")
            a.legend(fontsize=6)
        a = ax[1, j]
        with np.errstate(divide="ignore", invalid="ignore"):
            brow = (d["stress"][:, 1] - d["stress"][:, 2]) / (d["stress"][:, 0] - d["stress"][:, 2])
            bwin = (m[:, 1, 1] - m[:, 2, 2]) / (m[:, 0, 0] - m[:, 2, 2])
        a.plot(e, brow, color="0.7", lw=0.5, label="rows")
        a.plot(e, bwin, color="C0", lw=1.2, label="1 % window")
        a.axhline(d["b"], color="k", ls="--", lw=0.8)
        a.axhspan(d["b"] - path_check.DEFAULTS["b"], d["b"] + path_check.DEFAULTS["b"], color="C2", alpha=0.15)
        a.set_ylim(d["b"] - 0.15, d["b"] + 0.15)
        if j == 0:
            a.set_ylabel("b (cell axes)")
            a.legend(fontsize=6)
        a = ax[2, j]
        q = "p" if d["path"] == "constant_p" else "sigma3"
        row = d["p"] if q == "p" else d["stress"][:, 2]
        win = np.trace(m, axis1=1, axis2=2) / 3 if q == "p" else m[:, 2, 2]
        a.plot(e, row / d["p0"], color="0.7", lw=0.5)
        a.plot(e, win / d["p0"], color="C0", lw=1.2)
        a.axhline(1.0, color="k", ls="--", lw=0.8)
        tol = path_check.DEFAULTS["stress"]
        a.axhspan(1 - tol, 1 + tol, color="C2", alpha=0.15)
        a.set_ylim(0.9, 1.1)
        if j == 0:
            a.set_ylabel(f"{q} / target")
        a = ax[3, j]
        rot = np.array([path_check.rotation_deg(x) if np.all(np.isfinite(x)) else np.nan for x in m])
        a.plot(e, rot, color="C0", lw=1.2)
        a.axhline(path_check.DEFAULTS["rotation"], color="C3", ls=":", lw=0.8)
        a.set_ylim(0, 20)
        a.set_xlabel("eps_1 (%)")
        if j == 0:
            a.set_ylabel("turn of the principal axes (deg)")
        chk = d["check"]["failure"]
        if chk is not None:
            for r in range(4):
                ax[r, j].axvline(100 * chk["eps1"], color="C3", lw=0.8)
    fig.suptitle(title + "  (grey: rows; blue: 1 % window means; green: tolerance; red: the watchdog's verdict)",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main():
    results, exp = sys.argv[1], sys.argv[2]
    os.makedirs(os.path.join(exp, "figures"), exist_ok=True)
    os.makedirs(os.path.join(exp, "results"), exist_ok=True)
    rows = []
    for protocol in ("fast", "paper"):
        files = [f for f in sorted(glob.glob(os.path.join(results, protocol, "*.h5")))
                 if os.path.basename(f).startswith(("p-", "s3-")) and "checkpoint" not in f]
        tests = []
        for fn in files:
            d = load(fn)
            d["check"] = path_check.check(d["eps1"], d["stress"], d["path"], d["b"], d["p0"], start=START,
                                          overlap=d["max_overlap_ratio"], unbalanced=d["unbalanced_force_ratio"])
            tests.append(d)
            w, fl = d["check"]["worst"], d["check"]["failure"]
            rows.append({"protocol": protocol, "test": d["name"], "path": d["path"], "b": d["b"],
                         "p0_MPa": d["p0"] / 1e6, "status": d["status"],
                         "failed_on": fl["quantity"] if fl else "",
                         "failed_at_eps1_pct": f"{100 * fl['eps1']:.2f}" if fl else "",
                         "max_path_error_pct": f"{100 * max(w['p'], w['sigma3']):.3f}",
                         "max_b_error": f"{w['b']:.4f}", "max_rotation_deg": f"{w['rotation']:.2f}",
                         "max_shear_over_p": f"{w['shear']:.3f}", "max_overlap": f"{w['overlap']:.4f}",
                         "end_eps1_pct": f"{100 * d['eps1'][-1]:.2f}",
                         "max_p_over_p0": f"{np.max(d['p']) / d['p0']:.3f}"})
        for path in ("constant_p", "constant_sigma3"):
            for p0 in sorted({d["p0"] for d in tests}):
                group = [d for d in tests if d["path"] == path and d["p0"] == p0]
                if group:
                    name = f"{protocol}-{path}-p0_{p0 / 1e3:g}kPa"
                    figure(group, f"{protocol} protocol, {path}, p0 = {p0 / 1e6:g} MPa",
                           os.path.join(exp, "figures", name + ".png"))
    with open(os.path.join(exp, "results", "paths.csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"plot_paths.py: {len(rows)} tests; figures in {exp}/figures, table {exp}/results/paths.csv")


if __name__ == "__main__":
    main()
