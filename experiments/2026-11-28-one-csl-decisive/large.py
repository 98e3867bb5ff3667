"""The decisive experiment's larger cell (issue 45 item 7 (c)): 155,488 spheres, one seed, 0.5 MPa, b = 0, 0.5, 1,
free cell, against the 19,436-sphere free cells.

    PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-28-one-csl-decisive/large.py LARGE_OUT REF_ROOT \
        [--out experiments/2026-11-28-one-csl-decisive/large.csv]
    PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-28-one-csl-decisive/large.py LARGE8_OUT \
        experiments/2026-11-28-one-csl-decisive/tests.csv --p0 8000     (writes large-8mpa.csv)

LARGE_OUT is the large run's --out folder (large-s2020.toml), or the folder its series were exported to
(export_series.py: series/large-8mpa); REF_ROOT holds free-s{2017,2018,2019} with the
19,436-sphere tests as analyze.py reads them (at 0.5 MPa b = 1, the servo-cap re-runs: the merged folder of
experiments/2026-11-28-servo-cap/rerun.sh, to the same eps_q = 0.6 as the large cell). Writes large.csv (one row per
large test, analyze.one_test's columns, and the offset lines) and prints the verdicts. At 8 MPa (large-8mpa-s2020.toml)
the reference is the small cells' rows in tests.csv (their files are gone; the same measures, analyze.one_test's).

Criteria, fixed on 2026-11-28 before any of the large cell's shear results was read:
- entry as in analyze.py: the watchdog's done (it held its path) and e, p, Z_mech, F_a steady over the last 0.1 of
  eps_q (analyze.one_test's column critical); every test that held its path to 0.6 again as a sensitivity line;
- the large cell has one realization per b: its offset D_L = e_c(b) - e_c(0) gets the standard error
  SE_L = sqrt(2) s sqrt(19,436 / N_L), where s is the pooled sample SD of e_c over the 19,436-sphere free-cell
  seeds at 0.5 MPa (b = 0 and 1, the tests that held their path: the realization scatter) and the scatter of a
  sample mean is assumed to fall as 1 / sqrt(N). The assumption is stated with the verdict;
- D_L is judged by analyze.py's thresholds: offset if |D| - 2 SE > 0.005, one CSL if |D| + 2 SE < 0.010, otherwise
  not identifiable;
- size effect: the large cell's D_L against the 19,436-sphere D (analyze.py's held-path offset, mean over seeds):
  "differs" when |D_L - D| > 2 sqrt(SE_L^2 + SE^2), else "agrees".
"""
import argparse
import csv
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import analyze  # noqa: E402

N_REF, N_LARGE = 19436, 155488


def test_names(p0_kpa):
    return tuple(f"p-b{b:.2f}-p0_{p0_kpa}kPa" for b in (0.0, 0.5, 1.0))


def reference(root, p0_kpa=500):
    """The 19,436-sphere free-cell tests at p0 that held their path to eps_q = 0.6: {b: [e_c, ...]}, from the
    seeds' results files or exported series under ROOT (free-s<seed>/), or from a CSV of their rows (tests.csv:
    cell, test, status, eps_q_end, e), for when the files are gone."""
    out = {0.0: [], 0.5: [], 1.0: []}
    if os.path.isfile(root):
        with open(root, newline="") as fh:
            for r in csv.DictReader(fh):
                if (r["cell"] == "free" and r["test"] in test_names(p0_kpa) and r["status"].startswith("done")
                        and float(r["eps_q_end"]) >= 0.599):
                    out[float(r["test"][3:7])].append(float(r["e"]))
        return out
    for seed in analyze.SEEDS:
        folder = os.path.join(root, f"free-s{seed}")
        status = analyze.index_status(folder)
        for name in test_names(p0_kpa):
            path = os.path.join(folder, name + ".h5")
            if not os.path.exists(path):  # the series kept in git (export_series.py)
                path = os.path.join(folder, name + ".csv.gz")
            if not os.path.exists(path):
                continue
            r = analyze.one_test(path, status.get(name, "running"))
            if r["status"].startswith("done") and r["eps_q_end"] >= 0.599:
                out[float(name[3:7])].append(r["e"])
    return out


def pooled_sd(groups):
    num = sum((len(g) - 1) * np.var(g, ddof=1) for g in groups if len(g) > 1)
    dof = sum(len(g) - 1 for g in groups if len(g) > 1)
    return math.sqrt(num / dof) if dof else math.nan


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("large")
    ap.add_argument("reference", help="REF_ROOT (the seeds' folders) or a CSV of their rows (tests.csv)")
    ap.add_argument("--p0", type=int, default=500, help="kPa: 500 (large-s2020.toml) or 8000 (large-8mpa-s2020.toml)")
    ap.add_argument("--out", default=None, help="default large.csv (500 kPa), large-8mpa.csv (8000 kPa)")
    a = ap.parse_args(argv)
    out = a.out or os.path.join(HERE, "large.csv" if a.p0 == 500 else f"large-{a.p0 // 1000}mpa.csv")
    status = analyze.index_status(a.large)
    rows = {}
    for name in test_names(a.p0):
        path = os.path.join(a.large, name + ".h5")
        if not os.path.exists(path):  # the series kept in git (export_series.py)
            path = os.path.join(a.large, name + ".csv.gz")
        if os.path.exists(path):
            rows[float(name[3:7])] = dict(test=name, **analyze.one_test(path, status.get(name, "running")))
    ref = reference(a.reference, a.p0)
    s = pooled_sd([ref[0.0], ref[1.0]])
    se_l = math.sqrt(2.0) * s * math.sqrt(N_REF / N_LARGE)
    lines = []
    for entry, admit in (("steady", lambda r: r["status"].startswith("done") and r["critical"]),
                         ("held_path", lambda r: r["status"].startswith("done") and r["eps_q_end"] >= 0.599)):
        for b in (0.5, 1.0):
            r0, rb = rows.get(0.0), rows.get(b)
            m0, se0, n0 = analyze.mean_se(ref[0.0])
            mb, seb, nb = analyze.mean_se(ref[b])
            d_ref = mb - m0
            se_ref = math.sqrt(se0 ** 2 + seb ** 2) if n0 > 1 and nb > 1 else math.nan
            line = dict(entry=entry, b=b, D_ref=d_ref, SE_ref=se_ref, n_ref=f"{nb}/{n0}", s_pooled=s, SE_L=se_l)
            if r0 and rb and admit(r0) and admit(rb):
                d = rb["e"] - r0["e"]
                line.update(D_L=d, verdict=analyze.verdict(d, se_l),
                            size_effect=("differs" if abs(d - d_ref) > 2 * math.sqrt(se_l ** 2 + se_ref ** 2)
                                         else "agrees") if math.isfinite(se_ref) else "no reference SE")
            else:
                why = [f"b = {bb:g} " + ("missing" if r is None else f"status {r['status']}"
                                         if not r["status"].startswith("done") else "ended before eps_q 0.6"
                                         if r["eps_q_end"] < 0.599 else "not steady: " + r["why_not"])
                       for bb, r in ((0.0, r0), (b, rb)) if r is None or not admit(r)]
                line.update(D_L=math.nan, verdict="not entered: " + "; ".join(why), size_effect="")
            lines.append(line)
    cols = ["test", "status", "eps_q_end", "critical", "critical_full", "why_not", "e", "e_sd", "p_MPa", "eta",
            "eta_sd", "Z_mech", "Z_mech_sd", "F_a", "F_a_sd", "A", "b_rows"]
    with open(out, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(cols)
        for b in sorted(rows):
            w.writerow([f"{rows[b][c]:.6g}" if isinstance(rows[b][c], float) else rows[b][c] for c in cols])
        w.writerow([])
        keys = ["entry", "b", "D_L", "SE_L", "verdict", "D_ref", "SE_ref", "n_ref", "s_pooled", "size_effect"]
        w.writerow(keys)
        for ln in lines:
            w.writerow([f"{ln[k]:.6g}" if isinstance(ln[k], float) else ln[k] for k in keys])
    for b in sorted(rows):
        r = rows[b]
        print(f"large b {b:g}: {r['status']}, eps_q {r['eps_q_end']:.3f}, steady {r['critical']}, e {r['e']:.4f}, "
              f"q/p {r['eta']:.4f}, Z_mech {r['Z_mech']:.3f}, F_a {r['F_a']:.3f}, A {r['A']:.4f}; {r['why_not']}")
    for ln in lines:
        print(f"{ln['entry']:9s} b {ln['b']:g}: D_L {ln['D_L']:+.4f} +- {ln['SE_L']:.4f}: {ln['verdict']}; "
              f"19,436 spheres D {ln['D_ref']:+.4f} +- {ln['SE_ref']:.4f} (n {ln['n_ref']}): {ln['size_effect']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
