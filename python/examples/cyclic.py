#!/usr/bin/env python3
"""Cyclic undrained triaxial test: q = s1 - (s2 + s3)/2 between +-q_amp (axis 1 stress controlled,
lateral axes at constant volume), until a number of cycles or a strain. p' drifts down cycle by
cycle as the excess pore pressure builds up. Writes the figure given (docs/python-cyclic.png).

    PYTHONPATH=build/release/python python3 python/examples/cyclic.py [figure.png] [q_amp/p0] [friction]
"""
import sys

import matplotlib
import numpy as np

import sandcell as sc
from sample import prepare

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

p0 = 1e5
ratio = float(sys.argv[2]) if len(sys.argv) > 2 else 0.5
model, state, m0 = prepare(p0=p0, friction=float(sys.argv[3]) if len(sys.argv) > 3 else 0.2)
c = sc.CyclicSettings()
c.axial, c.lower, c.upper = "stress", -ratio * p0, ratio * p0  # Pa, bounds on q
c.undrained, c.cycles, c.max_strain = True, 10, 0.05
path = sc.CyclicPath(c)
s = model.servo
s.enabled, s.max_rate, s.custom = True, 1.0, path
s.gain, s.integral_time = sc.derived_servo("shear", p0, model.materials[0], model.dt)  # the app's
world = sc.World(model, state, threads=2, initial_forces=False)
rows = []
while not path.finished:
    m = world.measure()
    rows.append((m.strain[0], m.p, m.stress[0, 0] - 0.5 * (m.stress[1, 1] + m.stress[2, 2]), m.eps_v))
    world.step_until(10**7, every=100, path=path)
eps1, p, q, eps_v = np.array(rows).T
print(f"e0 = {m0.e:.3f}, {path.cycles} cycles, {path.reversals} reversals,"
      f" eps1 in [{eps1.min():.4f}, {eps1.max():.4f}],"
      f" p' from {p[0]:.0f} to {p[-1]:.0f} Pa, max |eps_v| = {abs(eps_v).max():.1e}")

fig, ax = plt.subplots(1, 3, figsize=(13, 3.8))
ax[0].plot(p / 1e3, q / 1e3)
ax[0].set(xlabel="p' (kPa)", ylabel="q (kPa)", title="effective stress path")
ax[1].plot(100 * eps1, q / 1e3)
ax[1].set(xlabel="axial strain eps1 (%)", ylabel="q (kPa)", title="stress-strain loops")
ax[2].plot(np.arange(len(p)) * 100 * model.dt * 1e3, (p0 - p) / 1e3)
ax[2].set(xlabel="time (ms)", ylabel="u = p0 - p' (kPa)", title="excess pore pressure")
for k in path.reversal_steps:
    ax[2].axvline(k * model.dt * 1e3, color="0.85", lw=0.8, zorder=0)
fig.suptitle(f"sandcell from Python: cyclic undrained triaxial, q = +-{ratio:g} p0 (500 spheres, e0 = {m0.e:.3f}, "
             f"p0 = 100 kPa; grey: reversals)")
fig.tight_layout()
fig.savefig(sys.argv[1] if len(sys.argv) > 1 else "python-cyclic.png", dpi=110)
