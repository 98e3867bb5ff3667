"""Shared scenes of the Python front end's tests: a small loose sample prepared once per session."""
import os
import tempfile

import pytest

import sandcell as sc

# Soft quartz-like spheres (E = 7 GPa keeps the time step long: the tests run in seconds).
MATERIAL = dict(density=2650.0, young=7e9, poisson=0.3, restitution=0.5, friction=0.5, rolling_friction=0.1)
P0 = 1e5  # Pa


def base_model(friction=0.5):
    mat = sc.Material(**{**MATERIAL, "friction": friction})
    dt = 0.2 * sc.rayleigh_time(2.5e-3, mat)
    contact = sc.ContactSettings()
    contact.skin = 0.5e-3
    return sc.Model(dt, [mat], contact)


def pytest_configure(config):
    config.addinivalue_line(
        "markers",
        "whole_app: runs one of the app's whole tests again (preparation and shear, ~10^5 steps) to compare "
        "files bit for bit; python.asan deselects them, all but test_twin's small.toml (python/CMakeLists.txt)")


@pytest.fixture(scope="session")
def work_dir():
    base = os.environ.get("SANDCELL_PYTHON_WORK")
    if base:
        os.makedirs(base, exist_ok=True)
    return tempfile.mkdtemp(prefix="sandcell-py-", dir=base)


def prepared_sample(friction):
    """250 spheres compressed isotropically to P0 with this friction, strains counted from there:
    a state with the cell at rest and the shear model base_model() (friction 0.5)."""
    model = base_model(friction)
    s = model.servo
    s.enabled, s.path, s.control, s.p = True, "isotropic", ["stress"] * 3, P0
    s.max_rate, s.gain = 5.0, sc.derived_servo("prepare", P0, model.materials[0], model.dt)[0]
    state = sc.State.generate(model, 250, d_min=5e-3, d_max=7.5e-3, solid_fraction=0.3, seed=3)
    world = sc.World(model, state, threads=2)
    for _ in range(200):
        world.step(1000)
        m = world.measure()
        if max(abs(m.stress[k, k] - P0) / P0 for k in range(3)) < 0.01 and m.unbalanced < 0.01:
            break
    else:
        raise AssertionError(f"the sample (friction {friction}) did not converge to p0")
    state = world.state()
    state.cell_length0 = state.cell_length
    state.reset_clock()
    state.servo_integral = [0, 0, 0]
    state.cell_rate = [0, 0, 0]
    return base_model(), state


@pytest.fixture(scope="session")
def loose_sample():
    """Compressed *with* friction: a loose packing, e ~ 0.75. Returns (model, state)."""
    return prepared_sample(0.5)


@pytest.fixture(scope="session")
def dense_sample():
    """Compressed without friction: a dense packing, e ~ 0.55. Returns (model, state)."""
    return prepared_sample(0.0)
