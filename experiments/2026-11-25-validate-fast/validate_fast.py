#!/usr/bin/env python3
"""Tabulates the fast-protocol validation of run.sh (beside this script).

    PYTHONPATH=apps/analysis validate_fast.py WORKDIR [--out DIR]

For each test folder in WORKDIR (paper-*, fast-s<seed>-*): peak q/p and the axial strain at it,
critical q/p and e (means over the last 5 % of axial strain), the largest dilation rate -d eps_v /
d eps_q (least-squares slopes over 1 % of axial strain, as `triaxial study`), steps and wall time.
Then per test condition: the fast run on the paper run's sample (seed 2017) against the paper run,
next to the standard deviation over the three seeds of the fast protocol. Writes validation.md and
validation.csv into --out (default: WORKDIR).
"""
import argparse
import csv
import glob
import os

import h5py
import numpy as np

from sandcell_analysis.dilatancy import slope_max_dilation

WINDOW = 0.05
METRICS = [("peak_eta", "peak q/p", "%.4f"), ("peak_strain", "eps1 at peak", "%.4f"), ("crit_eta", "critical q/p", "%.4f"),
           ("crit_e", "critical e", "%.4f"), ("max_dilation", "max -d", "%.3f")]


def measure(folder):
    files = [f for f in glob.glob(os.path.join(folder, "*.h5"))
             if not os.path.basename(f).startswith(("sample-", "prepare-")) and not f.endswith(".checkpoint.h5")]
    if len(files) != 1:
        return None
    with h5py.File(files[0], "r") as f:
        s = f["series"]
        eps1 = np.asarray(s["strain"][:, 0])
        eta, e = np.asarray(s["eta"][:]), np.asarray(s["e"][:])
        eps_v, eps_q = np.asarray(s["eps_v"][:]), np.asarray(s["eps_q"][:])
        step, wall = np.asarray(s["step"][:]), np.asarray(s["wall_time"][:])
        inertial = np.asarray(s["inertial_number_axial"][:]) if "inertial_number_axial" in s else np.full_like(eps1, np.nan)
    tail = eps1 >= eps1[-1] - WINDOW
    return dict(peak_eta=float(eta.max()), peak_strain=float(eps1[eta.argmax()]), crit_eta=float(eta[tail].mean()),
                crit_e=float(e[tail].mean()), max_dilation=slope_max_dilation(eps1, eps_v, eps_q),
                final_strain=float(eps1[-1]), steps=int(step[-1]), wall=float(wall[-1]),
                mean_I=float(np.nanmean(inertial[eps1 >= 0.01])) if np.any(eps1 >= 0.01) else float("nan"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("work")
    ap.add_argument("--out")
    a = ap.parse_args()
    out = a.out or a.work
    os.makedirs(out, exist_ok=True)
    runs = {}
    for folder in sorted(glob.glob(os.path.join(a.work, "*"))):
        name = os.path.basename(folder)
        if os.path.isdir(folder) and name.startswith(("paper-", "fast-")):
            m = measure(folder)
            if m:
                runs[name] = m
    with open(os.path.join(out, "validation.csv"), "w", newline="") as fh:
        w = csv.writer(fh)
        keys = ["peak_eta", "peak_strain", "crit_eta", "crit_e", "max_dilation", "final_strain", "steps", "wall", "mean_I"]
        w.writerow(["run"] + keys)
        for name, m in runs.items():
            w.writerow([name] + [m[k] for k in keys])
    lines = ["# Fast protocol against the paper's, 19,436 spheres", "",
             "Every run: `experiments/2026-11-25-validate-fast/run.sh` (the commands it runs are in its header); "
             "this table: `validate_fast.py WORKDIR --out experiments/2026-11-25-validate-fast`.", "",
             "| run | peak q/p | eps1 at peak | critical q/p | critical e | max -d | final eps1 | steps | wall s | mean I (axial) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for name, m in runs.items():
        lines.append(f"| {name} | {m['peak_eta']:.4f} | {m['peak_strain']:.4f} | {m['crit_eta']:.4f} | {m['crit_e']:.4f} | "
                     f"{m['max_dilation']:.3f} | {m['final_strain']:.3f} | {m['steps']} | {m['wall']:.0f} | {m['mean_I']:.2e} |")
    lines += ["", "Errors of the fast protocol (seed 2017, the paper run's own sample) against the paper run, next to "
              "the scatter of the fast protocol over seeds 2017-2019 (standard deviation):", "",
              "| test | " + " | ".join(f"err {label} (scatter)" for _, label, _ in METRICS) + " | cost: paper steps / fast steps | paper wall / fast wall |",
              "|---|" + "---|" * (len(METRICS) + 2)]
    for cond in sorted({n.split("-", 1)[1] for n in runs if n.startswith("paper-")}):
        paper = runs.get(f"paper-{cond}")
        fast = runs.get(f"fast-s2017-{cond}")
        if not (paper and fast):
            continue
        seeds = [runs[n] for n in runs if n.startswith("fast-s") and n.endswith(cond)]
        cells = []
        for key, _, fmt in METRICS:
            err = abs(fast[key] - paper[key])
            sd = float(np.std([s[key] for s in seeds], ddof=1)) if len(seeds) >= 2 else float("nan")
            cells.append(f"{fmt % err} ({fmt % sd}, {len(seeds)} seeds)")
        lines.append(f"| {cond} | " + " | ".join(cells) + f" | {paper['steps'] / fast['steps']:.1f} | {paper['wall'] / fast['wall']:.1f} |")
    # The table of the README (and docs/reproducing-the-study.md): per condition and measure, the paper run, the fast run on its sample,
    # the error, and the fast protocol's seed-to-seed standard deviation.
    lines += ["", "| test | measure | paper protocol | fast, same sample | error | seed scatter (std, fast) |",
              "|---|---|---|---|---|---|"]
    for cond in sorted({n.split("-", 1)[1] for n in runs if n.startswith("paper-")}):
        paper, fast = runs.get(f"paper-{cond}"), runs.get(f"fast-s2017-{cond}")
        if not (paper and fast):
            continue
        seeds = [runs[n] for n in runs if n.startswith("fast-s") and n.endswith(cond)]
        for key, label, fmt in METRICS:
            sd = float(np.std([x[key] for x in seeds], ddof=1)) if len(seeds) >= 2 else float("nan")
            lines.append(f"| {cond} | {label} | {fmt % paper[key]} | {fmt % fast[key]} | {fmt % abs(fast[key] - paper[key])} | "
                         f"{fmt % sd} ({len(seeds)} seeds) |")
        lines.append(f"| {cond} | steps (wall s) | {paper['steps']} ({paper['wall']:.0f}) | {fast['steps']} ({fast['wall']:.0f}) | "
                     f"{paper['steps'] / fast['steps']:.1f}x fewer | |")
    with open(os.path.join(out, "validation.md"), "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
