"""Version 2 and version 3 of the critical-state rule on the paper-faster study's end windows, from its
committed SE tables (no results file needed; the study's files are gone with their machine).

    PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-29-rule-check/study_windows.py \
        [--out experiments/2026-11-29-rule-check/study_windows.csv]

Reads experiments/2026-11-29-paper-faster/se_methods.csv (window eps_q 0.4-0.5) and se_methods-08.csv
(0.7-0.8): per test and quantity the change and 2 SE as shares of the tolerance, and r1; and the
study's index.csv for the steps. The rows in a window are not in those tables: they are estimated as
steps / 50 (the series interval) x 0.1 / 0.5 (a window's share of a run to eps_q 0.5), i.e. steps
spread evenly over eps_q: an estimate, so n_eff here is one too (the stiffness step makes steps per
strain vary by a few per cent along a test).
"""
import argparse
import csv
import os
from collections import defaultdict

from rule_check import write_rows  # this folder's (the script's directory is on sys.path)
from sandcell_analysis import critical

HERE = os.path.dirname(os.path.abspath(__file__))
STUDY = os.path.join(HERE, "..", "2026-11-29-paper-faster")
WINDOWS = (("0.4-0.5", "se_methods.csv"), ("0.7-0.8", "se_methods-08.csv"))
NEFF_MIN = critical.V3_DEFAULTS["neff_min"]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=os.path.join(HERE, "study_windows.csv"))
    a = ap.parse_args(argv)
    with open(os.path.join(STUDY, "index.csv"), newline="") as fh:
        steps = {r["test"]: int(r["steps"]) for r in csv.DictReader(fh)}
    rows = []
    for window, name in WINDOWS:
        by = defaultdict(dict)
        with open(os.path.join(STUDY, name), newline="") as fh:
            for r in csv.DictReader(fh):
                by[r["test"]][r["quantity"]] = r
        for test, q in sorted(by.items()):
            n = steps[test] / 50 * 0.1 / 0.5
            row = dict(window=window, test=test, rows_est=round(n))
            v2 = v3 = True
            for k, r in q.items():
                change, two_se, r1 = float(r["change"]), float(r["ar1"]), float(r["r1"])
                neff = critical.effective_rows(n, r1)
                v2 &= change + two_se <= 1.0
                v3 &= change + critical.errors_to_spare(neff) / 2 * two_se <= 1.0
                row[f"n_eff_{k}"] = round(neff, 1)
            row.update(v2=v2, v3=v3)
            rows.append(row)
        mine = [r for r in rows if r["window"] == window]
        eta = sorted(r["n_eff_eta"] for r in mine)
        print(f"eps_q {window}: v2 passes {sum(r['v2'] for r in mine)} of {len(mine)}, v3 {sum(r['v3'] for r in mine)};"
              f" eta's n_eff (estimated) min {eta[0]}, median {eta[len(eta) // 2]}, max {eta[-1]}; "
              f"windows with eta's n_eff >= {NEFF_MIN:g}: {sum(v >= NEFF_MIN for v in eta)}")
        for r in mine:
            if r["v2"]:
                print(f"  v2 passes {r['test']}: v3 {r['v3']}, n_eff " +
                      ", ".join(f"{k[6:]} {v}" for k, v in r.items() if k.startswith("n_eff_")))
    write_rows(a.out, rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
