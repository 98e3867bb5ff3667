#!/usr/bin/env python3
"""The triaxial app's test in Python: isotropic preparation to p0, then the shear of its first test.

    PYTHONPATH=build/release/python python3 python/examples/triaxial_default.py \
        apps/triaxial/configs/default.toml out-py

sandcell.Protocol reads the app's config and derives what the app derives (time steps, servo
gains, the models of both stages, the start of a test, its path watchdog) with the app's own code;
this script is the two stage loops. It writes what `triaxial <config> --out <dir>` writes for the
first test: sample-<p0>.h5 (the prepared sample, a checkpoint) and <test>.h5 (the shear series and
snapshots), the same numbers bit for bit (docs/python.md says exactly what is compared).
"""
import sys

import sandcell as sc

proto = sc.Protocol.load(sys.argv[1])
out = sys.argv[2] if len(sys.argv) > 2 else "."
test = proto.tests[0]
p0, prep_cfg, series = test.p0, proto.prepare, proto.output["series_interval"]

# Preparation: isotropic compression of the cloud to p0 until every axis is within the tolerance.
prep = proto.prepare_model(p0)
world = sc.World(prep, proto.cloud(prep), threads=2)
d50 = sc.median_diameter(world.particles["radius"])
density = prep.materials[0].density
while True:
    world.step_until(10**12, every=prep_cfg["check_interval"])  # where a call stops changes no bit
    m = world.measure(d50=d50, density=density)
    worst = max(abs(m.stress[k, k] - p0) / p0 for k in range(3))
    if worst < prep_cfg["tolerance"] and m.unbalanced < prep_cfg["unbalanced"]:
        break
sample = sc.finish_preparation(world.state())
sc.write_checkpoint(f"{out}/sample-{sc.p0_tag(p0)}.h5", sample,
                    {"doubles": {"p0": [p0], "e0": [m.void_ratio], "Z": [m.z]}})  # what the app's test reads

# Shear: the test's path from the prepared sample to max_axial_strain, watched.
model = proto.shear_model(test.name)
world = sc.World(model, proto.start_test(test.name, sample), threads=2, initial_forces=False)
cyclic = proto.cyclic_path(model)  # a cyclic test ends with its path; None for the others
watch = proto.path_watch(test.name)
eps_max = proto.shear["max_axial_strain"]
attributes = {"job": test.name, "stage": "shear", "path": test.path, "b": "%.6g" % test.b, "p0": "%.6g" % p0,
              # the run record (`triaxial verify`): the sample, its state digest, the derived settings
              "sample_file": f"sample-{sc.p0_tag(p0)}.h5", "sample_digest": "%016x" % sc.particle_digest(sample),
              "settings": proto.resolved_settings(test.name)}


def row(results):
    m = world.measure(d50=d50, density=density)
    sc.append_row(results, world, m)
    return m, watch.add(m.strain[0], m.stress, world.step_count, m.max_overlap_ratio, m.unbalanced)


with sc.ResultsFile.create(f"{out}/{test.name}.h5", proto.text, attributes) as results:
    m, failure = row(results)
    results.write_snapshot(world)
    while True:
        world.step_until(10**12, every=series, max_strain=eps_max, path=cyclic)
        m, failure = row(results)
        if m.strain[0] >= eps_max or (cyclic and cyclic.finished) or (failure and proto.watch_stop):
            break  # (a test that leaves its path stops, failed)
    results.write_snapshot(world)
    results.set_attribute("/", "status", "failed" if watch.failed else "done")  # the verdict, as the app writes it
    results.set_attribute("/", "status_reason", watch.message)
    results.set_attribute("/", "path_error", watch.worst("path"))
    results.set_attribute("/", "b_error", watch.worst("b"))
    results.set_attribute("/", "rotation_deg", watch.worst("rotation"))
verdict = f"failed: {watch.message}" if watch.failed else "on its path"
print(f"{test.name}: {world.step_count} steps, eps1 = {m.strain[0]:.4f}, q/p = {m.eta:.4f}, p = {m.p:.0f} Pa, "
      + verdict)
