"""Stress paths from Python: undrained (constant volume), cyclic, a Python callable path."""
import math
import os

import h5py
import numpy as np
import pytest

import sandcell as sc
from conftest import P0


def servo(model, gain_alpha=0.1):
    s = model.servo
    s.enabled = True
    s.gain = sc.derived_gain(gain_alpha, P0, model.materials[0], model.dt)
    s.integral_time = 1000 * model.dt
    s.max_rate = 20.0
    return s


def test_undrained_keeps_the_volume_while_p_falls(loose_sample):
    model, state = loose_sample
    servo(model).custom = sc.undrained_path(5.0)  # also sets path = "custom"
    assert model.servo.path == "custom"
    world = sc.World(model, state, threads=2, initial_forces=False)
    rows = []
    while world.measure().strain[0] < 0.05:
        world.step(200)
        m = world.measure()
        rows.append((m.strain[0], m.eps_v, m.p, m.q))
    eps1, eps_v, p, q = np.array(rows).T
    # The volume axes hold V = V0 exactly up to rounding (tests/systems/test_servo_paths.cpp);
    # 1e-6 is the bound, 1e-12 what rounding allows.
    assert np.abs(eps_v).max() < 1e-12
    # A loose sample contracts when sheared drained; held at constant volume, the contraction is
    # carried by the effective stress instead: p' falls (the excess pore pressure u = p0 - p' rises).
    assert p[-1] < 0.8 * P0, (p[-1], P0)
    assert q.max() > 0.2 * P0  # it was loaded, not merely relaxed


def test_cyclic_strain_reverses_at_its_bounds(loose_sample):
    model, state = loose_sample
    c = sc.CyclicSettings()
    c.axial, c.lower, c.upper, c.rate, c.sigma3, c.cycles = "strain", -2e-3, 4e-3, 5.0, P0, 2
    path = sc.CyclicPath(c)
    servo(model).custom = path
    world = sc.World(model, state, threads=2, initial_forces=False)
    eps1 = []
    while not path.finished:
        world.step_until(10**6, every=10, path=path)
        eps1.append(world.measure().strain[0])
    assert path.cycles == 2 and path.reversals == 4
    # Reversal at the first servo update past the bound (every step here): an overshoot of at most
    # two steps' strain, rate dt, before the new rate acts.
    slack = 2 * c.rate * model.dt
    rev = np.array(path.reversal_strains)
    assert np.all(np.abs(rev - [c.upper, c.lower] * 2) <= slack), rev
    assert max(eps1) <= c.upper + slack and min(eps1) >= c.lower - slack
    steps = np.diff([0] + list(path.reversal_steps))
    # Each half cycle spans the bounds' distance at the rate: (upper - lower)/(rate dt) steps (the
    # first from 0 to upper), within the two-step overshoot.
    expected = [c.upper / (c.rate * model.dt)] + [(c.upper - c.lower) / (c.rate * model.dt)] * 3
    assert np.all(np.abs(steps - expected) <= 3), (steps, expected)


def test_cyclic_undrained_stress_loading_liquefies_a_loose_sample(loose_sample):
    model, state = loose_sample
    c = sc.CyclicSettings()
    c.axial, c.lower, c.upper, c.undrained, c.cycles, c.max_strain = "stress", -0.15 * P0, 0.15 * P0, True, 5, 0.02
    path = sc.CyclicPath(c)
    servo(model).custom = path
    model.servo.max_rate = 1.0
    world = sc.World(model, state, threads=2, initial_forces=False)
    q_first = None
    while not path.finished and world.step_count < 100000:
        world.step_until(100000, every=50, path=path)
        m = world.measure()
        assert abs(m.eps_v) < 1e-12  # constant volume throughout (rounding only, as above)
        if path.reversals == 1 and q_first is None:
            q_first = m.stress[0, 0] - 0.5 * (m.stress[1, 1] + m.stress[2, 2])
    # The first half cycle loads q up to the upper bound: reversed within the band (2 % of the
    # range) below it; sampled every 50 steps after, so q may have started down (5 % of p0 allowed).
    band = c.tolerance * (c.upper - c.lower)
    assert path.reversals >= 1 and q_first is not None
    assert q_first >= c.upper - band - 0.05 * P0
    # This loose sample liquefies in the first extension half cycle: p' collapses and the strain
    # runs away to max_strain, which finishes the path.
    m = world.measure()
    assert path.finished and abs(m.strain[0]) >= c.max_strain
    assert m.p < 0.2 * P0


def constant_p_model(model, python):
    s = servo(model)
    s.path, s.control, s.strain_rate, s.p, s.b = "constant_p", ["strain", "stress", "stress"], [5.0, 0, 0], P0, 0.5
    s.custom = None  # the shared model may hold an earlier test's path (a World refuses a path it would not call)
    if python:
        ref = sc.ServoSettings()
        ref.path, ref.p, ref.b = "constant_p", P0, 0.5

        def constant_p(inp):
            # The built-in formulas, restated (docs/physics.md section 6); axis 1 at 5 1/s.
            s1 = inp.stress[0, 0]
            return (["strain", "stress", "stress"],
                    [5.0, (3 * P0 * 0.5 + (2 * 0.5 - 1) * s1) / 1.5, (3 * P0 - 1.5 * s1) / 1.5])
        s.custom = constant_p
    return model


def test_a_python_path_runs_bitwise_as_the_built_in_one(loose_sample):
    model, state = loose_sample
    state.cell_rate = [-5.0, 0, 0]
    a = sc.World(constant_p_model(model, False), state, threads=2, initial_forces=False)
    b = sc.World(constant_p_model(sc.Model(model.dt, model.materials, model.contact), True), state, threads=2,
                 initial_forces=False)
    a.step(2000)
    b.step(2000)
    assert np.array_equal(a.particles["position"], b.particles["position"])
    assert np.array_equal(a.cell["length"], b.cell["length"])
    assert np.array_equal(a.cell["servo_integral"], b.cell["servo_integral"])


def test_a_python_path_that_raises_stops_the_run_keeping_what_was_written(loose_sample, work_dir):
    model, state = loose_sample

    def failing(inp):
        if inp.step >= 1234:
            raise ZeroDivisionError(f"my path gave up at step {inp.step}")
        return sc.PathTargets(["strain", "volume", "volume"], [5.0, 0, 0])
    servo(model).custom = failing
    world = sc.World(model, state, threads=2, initial_forces=False)
    path = os.path.join(work_dir, "raises.h5")
    results = sc.ResultsFile.create(path, "python test")
    with pytest.raises(ZeroDivisionError, match="my path gave up at step 1234"):
        while True:
            world.step_until(10**6, every=100)
            sc.append_row(results, world, world.measure())
            results.flush()
    # The run stopped in the step the path failed in, whose clock did not advance (World::step_until:
    # the state is that of the interrupted step); the world is still usable, the file readable.
    assert world.step_count == 1234
    assert np.isfinite(world.measure().p)
    results.close()
    with h5py.File(path) as f:
        assert list(f["series/step"][()]) == [100.0 * k for k in range(1, 13)]


def test_a_python_path_returning_garbage_is_a_value_error(loose_sample):
    model, state = loose_sample
    servo(model).custom = lambda inp: ("strain", "stress")
    world = sc.World(model, state, threads=1, initial_forces=False)
    with pytest.raises(ValueError, match="path result control"):
        world.step(5)
    model.servo.custom = lambda inp: sc.PathTargets(["strain"] * 3, [math.nan, 0, 0])
    world = sc.World(model, state, threads=1, initial_forces=False)
    with pytest.raises(ValueError, match=r"value\[0\]"):
        world.step(5)
