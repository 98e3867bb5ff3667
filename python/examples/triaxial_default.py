#!/usr/bin/env python3
"""The triaxial app's test in Python: isotropic preparation to p0, then constant p and b shear.

    PYTHONPATH=build/release/python python3 python/examples/triaxial_default.py \
        apps/triaxial/configs/default.toml out-py

reads the app's config (the keys of a single constant-p test; the app's defaults for the others)
and writes what `triaxial <config> --out <dir>` writes for it: sample-<p0>.h5 (the prepared
sample, a checkpoint) and <test>.h5 (the shear series and snapshots), the same numbers bit for
bit (docs/python.md says exactly what is compared).
"""
import math
import sys
import tomllib

import sandcell as sc

cfg = tomllib.load(open(sys.argv[1], "rb"))
out = sys.argv[2] if len(sys.argv) > 2 else "."
S, M, P, H, T = (cfg.get(k, {}) for k in ("sample", "material", "prepare", "shear", "tests"))
series = cfg.get("output", {}).get("series_interval", 1000)
p0, b, rate = T["p0"], T["b"], H["strain_rate"]
mat = sc.Material(**M)
d = sc.sample_diameters(S["d_min"], S["d_max"], S["count"], S.get("seed", 1))
t_r = sc.rayleigh_time(0.5 * min(d), mat)
dt = cfg.get("time", {}).get("dt_fraction", 0.2) * t_r
t_s = max(dt, 0.2 * t_r)  # the servo's time unit (docs/physics.md section 6)
contact = sc.ContactSettings()
contact.skin, contact.sort_interval = 0.2 * 0.5 * min(d), 1000  # the app's defaults

# Preparation: frictionless isotropic compression of the cloud to p0 (the app's prepare stage).
prep = sc.Model(dt, [sc.Material(**{**M, "friction": P.get("friction", 0.0),
                                    "rolling_friction": P.get("rolling_friction", 0.0)})], contact)
s = prep.servo
s.enabled, s.path, s.control, s.p = True, "isotropic", ["stress"] * 3, p0
s.max_rate, s.gain = P.get("max_rate", 5.0), sc.derived_gain(0.05, p0, mat, t_s)
state = sc.State.generate(prep, S["count"], S["d_min"], S["d_max"], S.get("solid_fraction", 0.3), S.get("seed", 1))
world = sc.World(prep, state, threads=2)
d50 = sc.median_diameter(world.particles["radius"])
check = P.get("check_interval", 1000)
while True:
    world.step_until(10**12, every=check)  # where a call stops changes no bit (World.step_until)
    m = world.measure(d50=d50, density=mat.density)
    worst = max(abs(m.stress[k, k] - p0) / p0 for k in range(3))
    if worst < P.get("tolerance", 0.01) and m.unbalanced < P.get("unbalanced", 0.01):
        break
sample = world.state()
sample.cell_length0 = sample.cell_length
tag = "p0_%gkPa" % (p0 / 1e3)
sc.write_checkpoint(f"{out}/sample-{tag}.h5", sample, {"doubles": {"p0": [p0], "e0": [m.void_ratio]}})

# Shear: constant p and b, axis 1 at the strain rate, to max_axial_strain (the app's test).
model = sc.Model(dt, [mat], contact)
s = model.servo
s.enabled, s.path, s.control, s.strain_rate = True, "constant_p_b", ["strain", "stress", "stress"], [rate, 0, 0]
s.p = s.sigma3 = p0
s.b, s.max_rate, s.interval = b, H.get("max_rate", 0.0) or 10 * rate, H.get("servo_interval", 1)
s.max_rate_ratio = 0.0 if H.get("max_rate", 0.0) else 10.0  # the cap follows the axial rate, as the app's
s.gain, s.integral_time = sc.derived_gain(0.1, p0, mat, t_s), 1000 * t_s
sample.reset_clock()
sample.servo_integral, sample.cell_rate = [0, 0, 0], [-rate, 0, 0]
world = sc.World(model, sample, threads=2, initial_forces=False)
name, eps_max = "p-b%.2f-%s" % (b, tag), H.get("max_axial_strain", 0.2)
attributes = {"job": name, "stage": "shear", "path": "constant_p", "b": "%.6g" % b, "p0": "%.6g" % p0}
tolerance = sc.PathTolerance()  # the app's [watch] defaults; the checks begin after the ramp
tolerance.start = H.get("ramp_strain", 0.0)
watch = sc.PathWatch(s, tolerance)


def watched(m):
    return watch.add(m.strain[0], m.stress, world.step_count, m.max_overlap_ratio, m.unbalanced)


with sc.ResultsFile.create(f"{out}/{name}.h5", open(sys.argv[1]).read(), attributes) as results:
    sc.append_row(results, world, m := world.measure(d50=d50, density=mat.density))
    watched(m)
    results.write_snapshot(world)
    done = False
    while not done:
        world.step_until(10**12, every=series, max_strain=eps_max)
        done = -math.log(world.cell["length"][0] / world.cell["length0"][0]) >= eps_max
        sc.append_row(results, world, m := world.measure(d50=d50, density=mat.density))
        done = bool(watched(m)) or done  # a test that leaves its path stops, failed
    results.write_snapshot(world)
    # the verdict in the file, as the app writes it
    results.set_attribute("/", "status", "failed" if watch.failed else "done")
    results.set_attribute("/", "status_reason", watch.message)
    results.set_attribute("/", "path_error", watch.worst("path"))
    results.set_attribute("/", "b_error", watch.worst("b"))
    results.set_attribute("/", "rotation_deg", watch.worst("rotation"))
verdict = f"failed: {watch.message}" if watch.failed else "on its path"
print(f"{name}: {world.step_count} steps, eps1 = {m.strain[0]:.4f}, q/p = {m.eta:.4f}, p = {m.p:.0f} Pa, {verdict}")
