#!/usr/bin/env python3
"""The b = 1 constant-sigma3 run-away and its fix: one test (paper-reduced.toml --task 15) run by
three builds, its p, sigma3 and the lateral rates against eps_1.

    before_after.py BEFORE.h5 CAP.h5 AFTER.h5 EXPERIMENT_DIR

BEFORE: the build before the fix (commit 62658dd); CAP: with the cap that follows the axial rate
alone (commit 05f0047); AFTER: with the integral time bounded too (this experiment's build). Writes
EXPERIMENT_DIR/figures/runaway.png and EXPERIMENT_DIR/results/runaway.csv (every 10th row of each).
"""
import csv
import os
import sys

import h5py
import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def series(fn):
    with h5py.File(fn, "r") as f:
        s = f["series"]
        return {k: np.asarray(s[k][...], float) for k in ("strain", "stress", "p", "strain_rate", "e")}


def main():
    before, cap, after, exp = sys.argv[1:5]
    runs = [("before (62658dd)", series(before)), ("cap follows the axial rate", series(cap)),
            ("and the integral time (this build)", series(after))]
    p0 = 0.5e6
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.2))
    for (label, s), c in zip(runs, ("C3", "C1", "C0")):
        e1 = 100 * s["strain"][:, 0]
        ax[0].semilogy(e1, s["p"] / p0, color=c, label=label)
        ax[1].plot(e1, s["stress"][:, 2] / p0, color=c, lw=0.8, label=label)
        ax[2].plot(e1, -s["strain_rate"][:, 2] / s["strain_rate"][:, 0].clip(1e-12), color=c, lw=0.8, label=label)
    ax[0].set_ylabel("p / p0")
    ax[1].set_ylabel("sigma3 (S_zz) / target")
    ax[1].set_ylim(0.5, 3.0)
    ax[1].axhspan(0.98, 1.02, color="C2", alpha=0.2)
    ax[2].set_ylabel("extension rate of axis 3 / axial rate")
    ax[2].set_ylim(0, 8)
    for a in ax:
        a.set_xlabel("eps_1 (%)")
        a.legend(fontsize=7)
    fig.suptitle("paper-reduced.toml --task 15: constant sigma3, b = 1, p0 = 0.5 MPa, 1,000 spheres, I = 3e-3")
    fig.tight_layout()
    os.makedirs(os.path.join(exp, "figures"), exist_ok=True)
    os.makedirs(os.path.join(exp, "results"), exist_ok=True)
    fig.savefig(os.path.join(exp, "figures", "runaway.png"), dpi=90)
    with open(os.path.join(exp, "results", "runaway.csv"), "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["build", "eps1", "p_over_p0", "sigma3_over_target", "axis3_rate_over_axial", "e"])
        for label, s in runs:
            for i in range(0, len(s["p"]), 10):
                w.writerow([label, f"{s['strain'][i, 0]:.5f}", f"{s['p'][i] / p0:.5g}",
                            f"{s['stress'][i, 2] / p0:.5g}",
                            f"{-s['strain_rate'][i, 2] / max(s['strain_rate'][i, 0], 1e-12):.4g}", f"{s['e'][i]:.4f}"])
    print(f"before_after.py: {exp}/figures/runaway.png, {exp}/results/runaway.csv")


if __name__ == "__main__":
    main()
