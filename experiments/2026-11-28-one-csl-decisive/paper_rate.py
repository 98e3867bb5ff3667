"""The fast protocol against the paper's rate on a banded test (issue 45 item 7): b = 0.5, 0.5 MPa, free cell, seed
2017, one sample, sheared at paper-fast's inertial number (free-s2017) and at the paper's fixed axial rate of 1/s
(paper-rate-s2017).

    PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-28-one-csl-decisive/paper_rate.py RUN_ROOT \
        [--out experiments/2026-11-28-one-csl-decisive]

Writes paper_rate.csv: for each protocol, the state at eps_q = 0.05, 0.1, 0.2, ..., 0.6 (the series row nearest below
each: e, q/p, Z_mech, F_a) and the band (sandcell_analysis.localization: verdict, onset, e inside and outside over the
last 0.1 of eps_q), then the end window by analyze.py's measures. The criterion (written after the paper-rate run's
last log line, e = 0.7180, had been seen, before any other number of it was read): the fast
protocol is validated on this banded test if its end-window e and q/p differ from the paper rate's by less than the
seed scatter of the same measure (the two seeds of the same cell, b and p0: |e_2017 - e_2018| and |eta_2017 -
eta_2018| from tests.csv), and its band is found with an onset within 0.05 of eps_q.
"""
import argparse
import contextlib
import csv
import io
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "..", "apps", "analysis"))

import analyze  # noqa: E402
from sandcell_analysis import localization as loc  # noqa: E402
from sandcell_analysis import results  # noqa: E402

NAME = "p-b0.50-p0_500kPa"
RUNS = (("paper-fast (I = 3e-3)", "free-s2017"), ("paper rate (1/s, I = 4.5e-4)", "paper-rate-s2017"))
MARKS = (0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6)


def figure(curves, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.6))
    for label, (x, e, eta) in curves.items():
        ax[0].plot(x, eta, lw=0.8, label=label)
        ax[1].plot(x, e, lw=0.8, label=label)
    ax[0].set_ylabel("q/p")
    ax[1].set_ylabel("e (whole cell)")
    for a in ax:
        a.set_xlabel("eps_q")
    ax[1].legend(fontsize=8)
    fig.suptitle("b = 0.5, 0.5 MPa, free cell, seed 2017: fast protocol vs the paper's rate\n"
                 "(experiments/2026-11-28-one-csl-decisive/paper_rate.py)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"wrote {path}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root")
    ap.add_argument("--out", default=HERE)
    a = ap.parse_args(argv)
    rows = []
    ends = {}
    curves = {}
    for label, folder in RUNS:
        path = os.path.join(a.root, folder, NAME + ".h5")
        status = analyze.index_status(os.path.join(a.root, folder)).get(NAME, "")
        cols = results.read_columns(path, ["eps_q", "e", "eta", "Z_mech", "fabric", "stress", "step"])
        fa, _ = analyze.fabric_measures(cols["fabric"], cols["stress"])
        x = cols["eps_q"]
        curves[label] = (x, cols["e"], cols["eta"])
        for m in MARKS:
            k = int(np.searchsorted(x, m, side="right")) - 1
            if k < 0 or x[-1] < m - 0.01:
                continue
            rows.append(dict(protocol=label, folder=folder, eps_q=f"{x[k]:.3f}", step=int(cols["step"][k]),
                             e=f"{cols['e'][k]:.4f}", eta=f"{cols['eta'][k]:.4f}", Z_mech=f"{cols['Z_mech'][k]:.3f}",
                             F_a=f"{fa[k]:.3f}"))
        end = analyze.one_test(path, status)
        with contextlib.redirect_stdout(io.StringIO()):
            band = loc.band_void_ratios(path)
        end.update(steps=int(cols["step"][-1]), banded=bool(band["banded"]), onset=band["onset_eps_q"],
                   e_in=band["e_in"], e_out=band["e_out"])
        ends[label] = end
    seeds = {}
    tests_csv = os.path.join(HERE, "tests.csv")
    for r in results.read_csv_rows(tests_csv):
        if r.get("cell") == "free" and float(r.get("b", "nan")) == 0.5 and float(r.get("p0_MPa", "nan")) == 0.5:
            seeds[r["seed"]] = r
    out = os.path.join(a.out, "paper_rate.csv")
    with open(out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["protocol", "folder", "eps_q", "step", "e", "eta", "Z_mech", "F_a"])
        w.writeheader()
        w.writerows(rows)
    fast, paper = (ends[label] for label, _ in RUNS)
    print(f"wrote {out}")
    figure(curves, os.path.join(a.out, "paper_rate.png"))
    for label, _ in RUNS:
        e = ends[label]
        print(f"{label}: {e['steps']} steps, status {e['status']}, end window e {e['e']:.4f} (sd {e['e_sd']:.4f}), "
              f"q/p {e['eta']:.4f}, Z_mech {e['Z_mech']:.3f}, F_a {e['F_a']:.3f}, A {e['A']:.4f}, "
              f"steady (e, p, Z, F_a): {e['critical']} ({e['why_not'] or 'all'}); banded {e['banded']} from eps_q "
              f"{e['onset']:.3f}, e in {e['e_in']:.4f} out {e['e_out']:.4f}")
    de, deta = fast["e"] - paper["e"], fast["eta"] - paper["eta"]
    print(f"fast - paper: e {de:+.4f}, q/p {deta:+.4f}, onset {fast['onset'] - paper['onset']:+.3f}")
    if len(seeds) >= 2:
        s = list(seeds.values())[:2]
        se = abs(float(s[0]["e"]) - float(s[1]["e"]))
        seta = abs(float(s[0]["eta"]) - float(s[1]["eta"]))
        ok = abs(de) < se and abs(deta) < seta and abs(fast["onset"] - paper["onset"]) < 0.05
        print(f"seed scatter (free, b = 0.5, 0.5 MPa, seeds {s[0]['seed']}/{s[1]['seed']}): e {se:.4f}, q/p {seta:.4f}"
              f" -> fast protocol {'validated' if ok else 'NOT validated'} on this banded test")
    else:
        print("seed scatter: fewer than two seeds in tests.csv: no verdict")
    return 0


if __name__ == "__main__":
    sys.exit(main())
