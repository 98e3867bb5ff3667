#!/usr/bin/env python3
"""Summarises the re-run of the 1,000-sphere calibrations under the stress-path watchdog (run.sh):
per calibration, how many of its tests held their path, why the others failed, how many runs measured
each target, and whether the calibration could fit. Writes results/summary.csv, results/tests.csv and
each calibration's runs.csv (results/<name>-runs.csv); prints the table of the README.

    /usr/bin/python3 experiments/2026-11-28-calibration-watchdog/summarize.py results/calibration-watchdog/out
"""
import csv
import math
import os
import re
import shutil
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
NAMES = ("reduced", "dilatancy", "young", "full", "prep", "poisson", "rolling")


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def main(out):
    res = os.path.join(HERE, "results")
    os.makedirs(res, exist_ok=True)
    summary, tests = [], []
    for name in NAMES:
        folder = os.path.join(out, name)
        if not os.path.isdir(os.path.join(folder, "runs")):
            continue
        log = os.path.join(os.path.dirname(os.path.abspath(out)), f"log-{name}.txt")
        text = open(log).read() if os.path.exists(log) else ""
        n_tests = n_failed = n_rotation = 0
        rotations = []
        for run in sorted(os.listdir(os.path.join(folder, "runs"))):
            index = os.path.join(folder, "runs", run, "index.csv")
            if not os.path.exists(index):
                continue
            for r in rows(index):
                n_tests += 1
                failed = r["status"] == "failed"
                n_failed += failed
                quantity = re.match(r"left its stress path: (\S+)", r.get("reason", "") or "")
                n_rotation += bool(quantity and quantity.group(1) == "rotation")
                rot = float(r["rotation_deg"]) if r.get("rotation_deg") not in (None, "", "nan") else math.nan
                rotations.append(rot)
                tests.append(dict(calibration=name, run=run, test=r["test"], status=r["status"],
                                  rotation_deg=r.get("rotation_deg", ""), path_error=r.get("path_error", ""),
                                  b_error=r.get("b_error", ""), reason=r.get("reason", "")))
        runs_csv = os.path.join(folder, "runs.csv")
        measured = ""
        if os.path.exists(runs_csv):
            shutil.copy(runs_csv, os.path.join(res, f"{name}-runs.csv"))
            rr = rows(runs_csv)
            targets = [k for k in rr[0] if ":" in k or k.startswith(("final_", "e_", "phi", "d0", "m_"))]
            counts = [sum(1 for r in rr if r[t] not in ("nan", "")) for t in targets]
            measured = f"{min(counts)}-{max(counts)} of {len(rr)}" if counts else ""
        fitted = os.path.exists(os.path.join(folder, "calibration.json"))
        why = re.findall(r"calibrate: (targets\.[^\n]*)", text)
        finite = [x for x in rotations if not math.isnan(x)]
        summary.append(dict(calibration=name, tests=n_tests, failed=n_failed, failed_on_rotation=n_rotation,
                            rotation_median=f"{sorted(finite)[len(finite) // 2]:.2f}" if finite else "",
                            rotation_max=f"{max(finite):.2f}" if finite else "",
                            runs_measuring_a_target=measured, fitted="yes" if fitted else "no",
                            stopped_on=why[-1] if why else ""))
    for fname, data in (("summary.csv", summary), ("tests.csv", tests)):
        if data:
            with open(os.path.join(res, fname), "w", newline="") as f:
                w = csv.DictWriter(f, fieldnames=list(data[0]))
                w.writeheader()
                w.writerows(data)
    print("| calibration | tests | failed (on rotation) | rotation median / max, deg | runs measuring a target "
          "| fitted |")
    print("|---|---|---|---|---|---|")
    for s in summary:
        print(f"| {s['calibration']} | {s['tests']} | {s['failed']} ({s['failed_on_rotation']}) | "
              f"{s['rotation_median']} / {s['rotation_max']} | {s['runs_measuring_a_target']} | {s['fitted']} |")
    aggregates(tests)


def aggregates(tests):
    """The figures the README quotes: failures by cause, the turn of the tests that held, failures by b."""
    failed = [t for t in tests if t["status"] == "failed"]
    other = [t for t in failed if "rotation" not in t["reason"]]
    held = sorted(float(t["rotation_deg"]) for t in tests if t["status"].startswith("done"))
    print(f"\nfailed {len(failed)} of {len(tests)}; not on rotation {len(other)}: "
          + "; ".join(f"{t['calibration']} {t['run']} {t['test']}: {t['reason']}" for t in other))
    if held:
        q = lambda f: held[min(len(held) - 1, int(f * len(held)))]  # noqa: E731
        print(f"held their path: {len(held)}, worst-window turn median {q(0.5):.2f}, p10 {q(0.1):.2f}, "
              f"p90 {q(0.9):.2f} deg")
    for b in ("b0.00", "b1.00"):
        for name in NAMES:
            sel = [t for t in tests if t["calibration"] == name and f"-{b}-" in t["test"]]
            if sel:
                print(f"{name} {b}: {sum(t['status'] == 'failed' for t in sel)} of {len(sel)} failed")


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "results/calibration-watchdog/out"))
