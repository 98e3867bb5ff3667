"""The stiffness time step's first scan (run.sh): per run and pressure, the steps to 10 % axial strain, the median
step, the peak q/p, q/p and e at 5 % and 10 %, the largest kinetic / elastic energy and unbalanced force ratio after
the first rows (the instability shows there), and the watchdog's status. Writes results.csv beside this file.

    /usr/bin/python3 experiments/2026-11-28-stiffness-step/analyze.py OUT
"""
import csv
import os
import sys

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
RUNS = ["r0.1", "r0.2", "s0.6", "s0.8", "s0.9", "s1.0", "s1.1", "s1.2"]
FIELDS = ["run", "p0_MPa", "status", "steps", "dt_median_s", "peak_eta", "eta_5", "e_5", "eta_10", "e_10",
          "max_kinetic_over_elastic", "max_unbalanced"]


def row(path, run, p0):
    with h5py.File(path, "r") as h:
        s = h["series"]
        eps1, eta, e = s["strain"][:, 0], s["eta"][:], s["e"][:]
        dt = s["dt"][:] if "dt" in s else np.full(len(eta), np.nan)
        ek = s["kinetic_energy"][:] / np.maximum(s["elastic_energy"][:], 1e-300)
        unb = s["unbalanced_force_ratio"][:]
        status = h.attrs.get("status", b"")
        status = status.decode() if isinstance(status, bytes) else str(status)

        def at(x):  # q/p averaged over 5 rows around, e at the row
            k = min(int(np.searchsorted(eps1, x)), len(eta) - 1)
            return float(eta[max(k - 2, 0):k + 3].mean()), float(e[k])
        eta5, e5 = at(0.05)
        eta10, e10 = at(0.0999)
        return dict(run=run, p0_MPa=p0, status=status, steps=int(s["step"][-1]), dt_median_s=f"{np.median(dt):.4e}",
                    peak_eta=f"{eta.max():.4f}", eta_5=f"{eta5:.4f}", e_5=f"{e5:.4f}", eta_10=f"{eta10:.4f}",
                    e_10=f"{e10:.4f}", max_kinetic_over_elastic=f"{ek[5:].max():.3f}",
                    max_unbalanced=f"{unb[5:].max():.3f}")


def main(out):
    rows = []
    for p0, name in ((0.5, "500kPa"), (16, "16000kPa")):
        for run in RUNS:
            path = os.path.join(out, run, f"p-b0.50-p0_{name}.h5")
            if os.path.exists(path):
                rows.append(row(path, run, p0))
                print(" ".join(f"{k}={v}" for k, v in rows[-1].items()))
    with open(os.path.join(HERE, "results.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS)
        w.writeheader()
        w.writerows(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]) if len(sys.argv) == 2 else "usage: analyze.py OUT")
