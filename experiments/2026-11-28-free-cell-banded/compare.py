"""The banded true triaxial tests in a fixed and a free cell: compare.py FIXED_DIR FREE_DIR > comparison.csv.

For each of p-b0.25/0.50/0.75-p0_500kPa in both runs: the status (index.csv), the axial strain at
the end, and over the last 5 % of axial strain (the critical state the app stopped at, or the
strains before a failure): p, q/p and e; b from the principal stresses (what the test really
followed) against its target; sigma3 (the smallest principal stress) over its target on the path,
s3* = (3p - (1 + b) s1)/(2 - b) with the measured s1 and p = p0; the principal axes' turn off the
cell axes (degrees, as the watchdog measures it) and the largest |shear stress| / p; the cell's shear
F_xz at the end (0 in a file from before the cell could shear: its cell was orthorhombic)."""
import csv
import math
import os
import sys

import h5py
import numpy as np

TESTS = ("p-b0.25-p0_500kPa", "p-b0.50-p0_500kPa", "p-b0.75-p0_500kPa")
P0 = 5e5


def status(folder, test):
    with open(os.path.join(folder, "index.csv"), newline="") as fh:
        for row in csv.DictReader(fh):
            if row["test"] == test:
                return row["status"]
    return "missing"


def measures(path, b_target):
    with h5py.File(path, "r") as f:
        s = f["series"]
        eps1 = s["strain"][:, 0]
        stress = s["stress"][:]
        e = s["e"][:]
        f_xz = float(s["deformation"][-1][2]) if "deformation" in s else 0.0
    last = eps1 >= eps1[-1] - 0.05
    S = np.array([[[r[0], r[3], r[4]], [r[3], r[1], r[5]], [r[4], r[5], r[2]]] for r in stress[last]])
    lam = np.linalg.eigvalsh(S)[:, ::-1]
    p = lam.mean(axis=1)
    q = np.sqrt(0.5 * ((lam[:, 0] - lam[:, 1]) ** 2 + (lam[:, 1] - lam[:, 2]) ** 2 + (lam[:, 2] - lam[:, 0]) ** 2))
    b = (lam[:, 1] - lam[:, 2]) / (lam[:, 0] - lam[:, 2])
    s3_target = (3 * P0 - (1 + b_target) * lam[:, 0]) / (2 - b_target)
    tau = np.sqrt(stress[last, 3] ** 2 + stress[last, 4] ** 2 + stress[last, 5] ** 2)
    span = lam[:, 0] - lam[:, 2]
    turn = 0.5 * np.degrees(np.arcsin(np.minimum(1.0, 2 * tau / span)))
    shear = np.max(np.abs(stress[last, 3:6]), axis=1) / p
    return {"eps1_end": eps1[-1], "p_MPa": p.mean() / 1e6, "q/p": (q / p).mean(), "e": e[last].mean(),
            "b_principal": b.mean(), "s3/s3*": (lam[:, 2] / s3_target).mean(), "turn_deg": turn.mean(),
            "max_turn_deg": turn.max(), "shear/p": shear.mean(), "F_xz_end": f_xz}


def main(fixed, free):
    out = csv.writer(sys.stdout)
    keys = ("eps1_end", "p_MPa", "q/p", "e", "b_principal", "s3/s3*", "turn_deg", "max_turn_deg", "shear/p", "F_xz_end")
    out.writerow(("test", "cell", "status") + keys)
    for test in TESTS:
        b_target = float(test.split("-b")[1][:4])
        for cell, folder in (("fixed", fixed), ("free", free)):
            path = os.path.join(folder, test + ".h5")
            if not os.path.exists(path):
                out.writerow((test, cell, "missing") + ("",) * len(keys))
                continue
            m = measures(path, b_target)
            out.writerow((test, cell, status(folder, test)) +
                         tuple(f"{m[k]:.4f}" if math.isfinite(m[k]) else "nan" for k in keys))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
