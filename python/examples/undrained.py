#!/usr/bin/env python3
"""Undrained (constant-volume) triaxial compression of a loose sample: p' falls as the excess pore
pressure u = p0 - p' builds up (static liquefaction). Writes the figure given (docs/python-undrained.png).

    PYTHONPATH=build/release/python python3 python/examples/undrained.py [figure.png]
"""
import sys

import matplotlib
import numpy as np

import sandcell as sc
from sample import prepare

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

p0 = 1e5
rows = {}
for label, friction in [("prepared with mu = 0.5", 0.5), ("prepared with mu = 0.3", 0.3)]:
    model, state, m0 = prepare(p0=p0, friction=friction)
    s = model.servo
    s.enabled, s.max_rate = True, 10.0
    s.gain, s.integral_time = sc.derived_servo("shear", p0, model.materials[0], model.dt)  # the app's
    s.custom = sc.undrained_path(2.0)  # axial 2/s; lateral: eps_v = 0 at every servo update
    world = sc.World(model, state, threads=2, initial_forces=False)
    r = []
    while True:
        m = world.measure()
        r.append((m.strain[0], m.p, m.q, m.eps_v))
        if m.strain[0] >= 0.05:
            break
        world.step(250)
    rows[f"{label}, e0 = {m0.e:.3f}"] = np.array(r)
    eps1, p, q, eps_v = rows[f"{label}, e0 = {m0.e:.3f}"].T
    print(f"{label}: e0 = {m0.e:.3f}, max |eps_v| = {abs(eps_v).max():.1e}, p' from {p[0]:.0f} to {p[-1]:.0f} Pa,"
          f" min p' {p.min():.0f} Pa, max q {q.max():.0f} Pa")

fig, ax = plt.subplots(1, 3, figsize=(13, 3.8))
for label, r in rows.items():
    eps1, p, q, eps_v = r.T
    ax[0].plot(100 * eps1, q / 1e3, label=label)
    ax[1].plot(p / 1e3, q / 1e3, label=label)
    ax[2].plot(100 * eps1, (p0 - p) / 1e3, label=label)
ax[0].set(xlabel="axial strain eps1 (%)", ylabel="q (kPa)", title="deviator", xlim=(0, 5))
ax[1].set(xlabel="p' (kPa)", ylabel="q (kPa)", title="effective stress path")
ax[2].set(xlabel="axial strain eps1 (%)", ylabel="u = p0 - p' (kPa)", title="excess pore pressure")
ax[0].legend(fontsize=8)
fig.suptitle("sandcell from Python: undrained triaxial compression of loose samples"
             " (500 spheres, p0 = 100 kPa, eps_v = 0)")
fig.tight_layout()
fig.savefig(sys.argv[1] if len(sys.argv) > 1 else "python-undrained.png", dpi=110)
