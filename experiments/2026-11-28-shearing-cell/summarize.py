"""One table of the shearing-cell demonstrations: summarize.py SIMPLE_SHEAR.h5 ROTATION.h5 > summary.csv.

Simple shear: gamma at the end, flips (from the cell's deformation: the tilt over the side passes
half its value once per flip), S_zz's largest 5 %-of-gamma window mean error, tau/sigma_n at its
peak and its mean over the last half of gamma, eps_v at the end. Rotation: the angle turned, the
largest row errors of p, q (both / p0) and b, alpha's largest difference from its target, and
the non-coaxiality's mean and spread once q is up (sandcell_analysis.shearing)."""
import sys

import h5py
import numpy as np

from sandcell_analysis import shearing


def simple_shear(path):
    d = shearing.read_shearing(path)
    m = shearing.simple_shear_measures(d)
    with h5py.File(path, "r") as f:
        tilt = f["series/cell_tilt"][:, 1]
    flips = int(np.sum(np.abs(np.diff(tilt)) > 0.5 * np.max(np.abs(tilt))))
    g, zz = m["gamma"], m["sigma_n"]
    worst = 0.0
    for k in range(len(g)):
        w = (g >= g[k]) & (g < g[k] + 0.05)
        if g[k] > 0.05 and g[k] + 0.05 <= g[-1]:
            worst = max(worst, abs(zz[w].mean() - 5e5) / 5e5)
    late = g > 0.5 * g[-1]
    return [("simple shear: gamma at the end", f"{g[-1]:.4f}"), ("simple shear: flips", flips),
            ("simple shear: S_zz worst window error", f"{worst:.4f}"),
            ("simple shear: peak tau/sigma_n", f"{np.nanmax(m['ratio']):.4f}"),
            ("simple shear: mean tau/sigma_n, last half of gamma", f"{np.nanmean(m['ratio'][late]):.4f}"),
            ("simple shear: eps_v at the end", f"{m['eps_v'][-1]:.4f}")]


def rotation(path, p0=5e5, b=0.5, eta=0.5, ramp=0.02, rate=900.0):
    d = shearing.read_shearing(path)
    s, t = d["stress"], d["time"]
    up = t >= ramp
    out = []
    S = np.array([[[r[0], r[3], r[4]], [r[3], r[1], r[5]], [r[4], r[5], r[2]]] for r in s[up]])
    lam = np.linalg.eigvalsh(S)[:, ::-1]
    p = lam.mean(axis=1)
    q = np.sqrt(0.5 * ((lam[:, 0] - lam[:, 1]) ** 2 + (lam[:, 1] - lam[:, 2]) ** 2 + (lam[:, 2] - lam[:, 0]) ** 2))
    bb = (lam[:, 1] - lam[:, 2]) / (lam[:, 0] - lam[:, 2])
    a = shearing.major_angle_xz(s[up, 0], s[up, 2], s[up, 4])
    target = (t[up] - ramp) * rate
    m = shearing.rotation_measures(d)
    non = m["noncoaxiality"][m["time"] > ramp + 0.005]
    out += [("rotation: angle turned, deg", f"{target[-1]:.1f}"),
            ("rotation: worst p error / p0", f"{np.max(np.abs(p - p0)) / p0:.2e}"),
            ("rotation: worst q error / p0", f"{np.max(np.abs(q - eta * p0)) / p0:.2e}"),
            ("rotation: worst b error", f"{np.max(np.abs(bb - b)):.2e}"),
            ("rotation: worst alpha error, deg", f"{np.max(np.abs(shearing.fold(a - target))):.3f}"),
            ("rotation: non-coaxiality mean, deg", f"{np.nanmean(non):.2f}"),
            ("rotation: non-coaxiality p10 / p90, deg",
             f"{np.nanpercentile(non, 10):.2f} / {np.nanpercentile(non, 90):.2f}")]
    return out


if __name__ == "__main__":
    print("quantity,value")
    for k, v in simple_shear(sys.argv[1]) + rotation(sys.argv[2]):
        print(f"{k},{v}")
