#!/usr/bin/env python3
"""The cost of a stress path written in Python: the same undrained shear with the built-in C++
path (sandcell.undrained_path) and with a Python function giving the same answer, the servo
updating every step; prints the time per servo update of each and the difference.

    PYTHONPATH=build/release/python python3 python/examples/path_cost.py [spheres] [steps] [threads]
"""
import sys
import time

import numpy as np

import sandcell as sc

n = int(sys.argv[1]) if len(sys.argv) > 1 else 500
steps = int(sys.argv[2]) if len(sys.argv) > 2 else 5000
threads = int(sys.argv[3]) if len(sys.argv) > 3 else 2
mat = sc.Material(young=7e9)
contact = sc.ContactSettings()
contact.skin, contact.sort_interval = 0.5e-3, 1000
model = sc.Model(0.2 * sc.rayleigh_time(2.5e-3, mat), [mat], contact)
s = model.servo
s.enabled, s.path, s.control, s.p, s.max_rate = True, "isotropic", ["stress"] * 3, 1e5, 5.0
s.gain = sc.derived_servo("prepare", 1e5, mat, model.dt)[0]
world = sc.World(model, sc.State.generate(model, n, 5e-3, 7.5e-3, seed=2), threads=threads)
while max(abs(world.measure().stress[k, k] - 1e5) for k in range(3)) > 1e3:
    world.step(1000)
sample = world.state()
sample.cell_length0 = sample.cell_length
sample.reset_clock()


def python_undrained(inp):
    return sc.PathTargets(["strain", "volume", "volume"], [1.0, 0.0, 0.0])


timings, positions = {}, {}
for name, path in [("C++", sc.undrained_path(1.0)), ("Python", python_undrained)] * 3:
    model.servo.custom = path
    w = sc.World(model, sample, threads=threads, initial_forces=False)
    t0 = time.perf_counter()
    w.step(steps)
    timings[name] = min(timings.get(name, 1e9), (time.perf_counter() - t0) / steps)
    positions[name] = w.particles["position"].copy()
same = np.array_equal(positions["C++"], positions["Python"])
print(f"{n} spheres, {threads} threads, {steps} steps, a servo update every step; bitwise equal: {same}")
for name, t in timings.items():
    print(f"  {name:7s} path: {1e6 * t:8.2f} us per step")
print(f"  Python callback: {1e6 * (timings['Python'] - timings['C++']):+.2f} us per servo update "
      f"({100 * (timings['Python'] / timings['C++'] - 1):+.1f} % of the step)")
