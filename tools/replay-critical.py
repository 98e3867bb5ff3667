#!/usr/bin/env python3
"""Replays the app's critical-state test (apps/triaxial/protocol/critical.hpp) on a shearing test's series.

usage: tools/replay-critical.py RESULTS.h5 [--window 0.05] [--tolerance 0.02] [--tolerance-e 0.005]

Applies the test after every series row, as the app does with `shear.stop_at_critical`, and prints
the first row where it holds (axial strain, step, wall time, the three changes, the window means)
and the changes over the test's last window. For a run made without the stop, or before the test
changed: where the app would stop it now. Needs numpy and h5py (python3-numpy, python3-h5py).
"""
import argparse
import sys

import h5py
import numpy as np


def changes(eps1, p, q, e, n, window, pre_strain=0.05, min_rows=10):
    """The test on rows [0, n): None when the window is not covered, else the three changes."""
    x = eps1[:n]
    end = x[-1]
    sel = x >= end - window
    if end < window + pre_strain or sel.sum() < max(min_rows, 3) or np.ptp(x[sel]) < 0.9 * window:
        return None
    out = []
    for y, relative in ((q[:n] / p[:n], True), (p[:n], True), (e[:n], False)):
        slope = np.polyfit(x[sel], y[sel], 1)[0]
        change = abs(slope * window)
        mean = float(np.mean(y[sel]))
        out.append(change / abs(mean) if relative and mean != 0 else change)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results")
    ap.add_argument("--window", type=float, default=0.05)
    ap.add_argument("--tolerance", type=float, default=0.02)
    ap.add_argument("--tolerance-e", type=float, default=0.005)
    a = ap.parse_args()
    with h5py.File(a.results, "r") as f:
        s = f["series"]
        eps1 = s["strain"][:, 0]
        p, q, e = s["p"][:], s["q"][:], s["e"][:]
        step, wall = s["step"][:], s["wall_time"][:]
    n_rows = len(eps1)
    print(f"{a.results}: {n_rows} rows to eps1 = {100 * eps1[-1]:.2f} %")
    for n in range(1, n_rows + 1):
        c = changes(eps1, p, q, e, n, a.window)
        if c and c[0] <= a.tolerance and c[1] <= a.tolerance and c[2] <= a.tolerance_e:
            sel = eps1[:n] >= eps1[n - 1] - a.window
            print(f"critical at row {n}: eps1 = {100 * eps1[n - 1]:.2f} %, step {int(step[n - 1])}, "
                  f"wall {wall[n - 1]:.0f} s; changes over the window: eta {100 * c[0]:.2f} %, "
                  f"p {100 * c[1]:.2f} %, e {c[2]:.4f}; window means: p {np.mean(p[:n][sel]) / 1e6:.4f} MPa, "
                  f"M {np.mean(q[:n][sel]) / np.mean(p[:n][sel]):.4f}, e {np.mean(e[:n][sel]):.4f}")
            break
    else:
        print("not critical at any row")
    c = changes(eps1, p, q, e, n_rows, a.window)
    if c:
        print(f"last window: eta {100 * c[0]:.2f} %, p {100 * c[1]:.2f} %, e {c[2]:.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
