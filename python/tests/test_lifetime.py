"""The World's lifetime rules (docs/python.md): no call into a World while it steps (reentrancy), views
that never read freed memory, a World left at the start of the step an exception interrupted, a custom
path that enables the servo, settings that would have no effect refused, and bad input a ValueError."""
import gc
import math
import os
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np
import pytest

import sandcell as sc
from conftest import P0, base_model

HERE = os.path.dirname(os.path.abspath(__file__))
PARTICLE_FIELDS = ("id", "position", "velocity", "angular_velocity", "force", "torque", "radius", "mass",
                   "inv_inertia", "material", "reference_position")


def servo(model, interval=1):
    s = model.servo
    s.enabled = True
    s.gain = sc.derived_gain(0.1, P0, model.materials[0], model.dt)
    s.integral_time = 1000 * model.dt
    s.max_rate = 20.0
    s.interval = interval
    return s


def drained(inp):
    """Axis 1 at 5 1/s, the lateral axes at P0: the PI servo and its integral at work."""
    return (["strain", "stress", "stress"], [5.0, P0, P0])


def sample(loose_sample, path=drained, interval=1, sort_interval=0):
    """A copy of the session's loose sample with a fresh model running `path`."""
    model, state = loose_sample
    model = sc.Model(model.dt, model.materials, model.contact)
    model.contact.sort_interval = sort_interval
    servo(model, interval).custom = path
    return model, state


def assert_same_world(a, b):
    """Bitwise: every particle array, every contact array, the cell, the clock."""
    assert a.step_count == b.step_count and a.time == b.time
    for name in PARTICLE_FIELDS:
        assert np.array_equal(a.particles[name], b.particles[name]), name
    ca, cb = a.contacts, b.contacts
    assert sorted(ca) == sorted(cb)
    for name in ca:
        assert np.array_equal(ca[name], cb[name]), name
    for name in ("length", "length0", "rate", "servo_integral"):
        assert np.array_equal(a.cell[name], b.cell[name]), name


# ---- 1. reentrancy ---------------------------------------------------------------------------------

def test_stepping_a_world_from_its_own_path_does_not_crash_the_interpreter():
    # Before: SIGSEGV (or a hang with a one-level guard). In a child interpreter, so that a crash or a
    # hang fails this test instead of the suite.
    script = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {HERE!r})
        import sandcell as sc
        from conftest import base_model, P0
        model = base_model()
        s = model.servo
        s.gain, s.max_rate = 10.0, 20.0
        holder = {{}}
        def path(inp):
            if inp.step == 3 and not holder.get("tried"):
                holder["tried"] = True
                holder["world"].step(1)
            return (["strain", "volume", "volume"], [5.0, 0, 0])
        s.custom = path
        state = sc.State.generate(model, 200, d_min=5e-3, d_max=7.5e-3, seed=5)
        world = holder["world"] = sc.World(model, state, threads=2)
        try:
            world.step(10)
        except RuntimeError as e:
            print("RuntimeError:", e)
        print("step_count", world.step_count)
        world.step(10)
        print("continued", world.step_count)
    """)
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120,
                         env=dict(os.environ))
    assert run.returncode == 0, run.stderr
    assert "RuntimeError: World.step: called from this World's own stress path (servo.custom)" in run.stdout
    assert "step_count 3\n" in run.stdout and "continued 13\n" in run.stdout


@pytest.mark.parametrize("call", [
    lambda w: w.step(1),
    lambda w: w.step_until(5, every=1),
    lambda w: w.measure(),
    lambda w: w.particles,
    lambda w: w.contacts,
    lambda w: w.cell,
    lambda w: w.state(),
    lambda w: w.step_count,
    lambda w: w.set_cell_rate([0, 0, 0]),
    lambda w: w.write_checkpoint(os.devnull),
], ids=["step", "step_until", "measure", "particles", "contacts", "cell", "state", "step_count", "set_cell_rate",
        "write_checkpoint"])
def test_a_world_used_from_its_own_path_raises_and_rolls_back(loose_sample, call):
    holder = {}

    def path(inp):
        if inp.step == 37:
            call(holder["world"])
        return drained(inp)
    model, state = sample(loose_sample, path)
    world = holder["world"] = sc.World(model, state, threads=2, initial_forces=False)
    with pytest.raises(RuntimeError, match="called from this World's own stress path .* while World.step runs it"):
        world.step(100)
    # Left at the start of the interrupted step, bitwise a clean run's state there.
    clean = sc.World(sample(loose_sample)[0], state, threads=2, initial_forces=False)
    clean.step(37)
    assert_same_world(world, clean)
    assert world.model.servo.custom is path  # World.model shows the path as given


def test_a_path_that_swallows_the_reentrancy_error_still_fails_the_step(loose_sample):
    holder, caught = {}, []

    def path(inp):
        if inp.step == 20:
            try:
                holder["world"].step(1)
            except RuntimeError as e:
                caught.append(str(e))
        return drained(inp)
    model, state = sample(loose_sample, path)
    world = holder["world"] = sc.World(model, state, threads=1, initial_forces=False)
    with pytest.raises(RuntimeError, match="World.step: called from this World's own stress path"):
        world.step(50)
    assert len(caught) == 1 and world.step_count == 20


def test_a_world_used_from_its_stop_function_raises_at_the_end_of_that_step(loose_sample):
    model, state = loose_sample
    world = sc.World(model, state, threads=2, initial_forces=False)

    def stop(step, length):
        if step == 15:
            world.measure()
        return False
    with pytest.raises(RuntimeError, match="World.measure: called from this World's own stop function"):
        world.step_until(100, stop=stop)
    assert world.step_count == 15  # a stop function runs after its step: the World holds that step's end
    clean = sc.World(model, state, threads=2, initial_forces=False)
    clean.step(15)
    assert_same_world(world, clean)


def test_a_world_stepping_in_one_thread_refuses_another(loose_sample):
    started, answered = threading.Event(), []

    def path(inp):
        if inp.step == 10:
            started.set()
            time.sleep(0.3)  # releases the GIL: the other thread runs while this World steps
        return drained(inp)
    model, state = sample(loose_sample, path)
    world = sc.World(model, state, threads=2, initial_forces=False)

    def other():
        started.wait(30)
        try:
            world.step(1)
            answered.append("stepped")
        except RuntimeError as e:
            answered.append(str(e))
    t = threading.Thread(target=other)
    t.start()
    world.step(30)  # not failed by the other thread's attempt
    t.join()
    assert world.step_count == 30
    assert answered and answered[0].startswith("World.step: this World is busy in World.step (called from another")


# ---- 2. views -------------------------------------------------------------------------------------

def test_particle_views_stay_valid_across_sorts_and_rollbacks(loose_sample):
    # The particle arrays never move: the sort permutes them in place, a rollback assigns them in place.
    fail = {"at": 250}

    def path(inp):
        if inp.step == fail["at"]:
            fail["at"] = None
            raise KeyError("once")
        return drained(inp)
    model, state = sample(loose_sample, path, sort_interval=50)
    world = sc.World(model, state, threads=2, initial_forces=False)
    views = world.particles
    addresses = {name: world._address(name) for name in ("position", "velocity", "force", "radius")}
    ids = views["id"].copy()
    with pytest.raises(KeyError):
        world.step(400)
    world.step(400 - world.step_count)
    for name, address in addresses.items():
        assert views[name].ctypes.data == address == world._address(name), name
    assert not np.array_equal(views["id"], ids)  # the sort reordered them, in place
    state_now = world.state().particles
    for name in PARTICLE_FIELDS:
        assert np.array_equal(views[name], state_now[name]), name


def test_contact_arrays_are_copies_that_outlive_the_list(loose_sample):
    # The pair list is rebuilt (and its arrays reallocated) as the cell is compressed: a copy taken
    # before keeps its own memory (under ASan: no read of freed memory).
    model, state = loose_sample
    world = sc.World(model, state, threads=2, initial_forces=False)
    before, address = world.contacts, world._address("contact_force")
    saved = {name: a.copy() for name, a in before.items()}
    world.set_cell_rate([-20.0, -20.0, -20.0])
    world.step(1500)
    after = world.contacts
    assert after["force"].shape[0] > before["force"].shape[0]  # the list grew
    assert world._address("contact_force") != address  # reallocated: a view into it would now dangle
    for name, a in before.items():
        assert np.array_equal(a, saved[name]) and np.isfinite(a.astype(float)).all(), name


def test_a_view_keeps_its_world_alive():
    model = base_model()
    state = sc.State.generate(model, 50, d_min=5e-3, d_max=7.5e-3, seed=2)
    world = sc.World(model, state)
    world.step(10)
    x, expected = world.particles["position"], world.state().particles["position"]
    del world
    gc.collect()
    assert np.array_equal(x, expected)


# ---- 3. state after an exception ------------------------------------------------------------------

@pytest.mark.parametrize("threads, interval, sort_interval, fail_at, calls", [
    (2, 1, 0, 1234, 1),     # in the second snapshot's span (renewed every 1000 steps)
    (1, 3, 100, 1233, 1),   # servo every 3 steps, spatial sort every 100
    (2, 1, 100, 1777, 25),  # in the 23rd of 25 calls: the snapshot taken by an earlier call
])
def test_a_path_that_raises_once_leaves_the_world_at_the_start_of_that_step(
        loose_sample, threads, interval, sort_interval, fail_at, calls):
    n = 2000
    failed = []

    def path(inp):
        if inp.step == fail_at and not failed:
            failed.append(inp.step)
            raise ZeroDivisionError(f"path gave up at step {inp.step}")
        return drained(inp)
    model, state = sample(loose_sample, path, interval, sort_interval)
    world = sc.World(model, state, threads=threads, initial_forces=False)
    with pytest.raises(ZeroDivisionError, match=f"path gave up at step {fail_at}"):
        while world.step_count < n:
            world.step(n // calls)
    clean = sc.World(sample(loose_sample, drained, interval, sort_interval)[0], state, threads=threads,
                     initial_forces=False)
    clean.step(fail_at)
    assert_same_world(world, clean)  # exactly the start of the interrupted step
    world.step(n - world.step_count)  # the path is asked again for that step, and the run goes on
    clean.step(n - clean.step_count)
    assert_same_world(world, clean)


def test_a_path_returning_garbage_also_rolls_back(loose_sample):
    def path(inp):
        return drained(inp) if inp.step != 321 else (["strain", "stress", "stress"], [math.inf, P0, P0])
    model, state = sample(loose_sample, path)
    world = sc.World(model, state, threads=2, initial_forces=False)
    with pytest.raises(ValueError, match=r"value\[0\] = inf"):
        world.step(1000)
    clean = sc.World(sample(loose_sample)[0], state, threads=2, initial_forces=False)
    clean.step(321)
    assert_same_world(world, clean)


def test_a_cpp_path_world_continues_bitwise_after_a_stop_function_raises(loose_sample):
    # A stop function runs between steps: the World holds the end of its step, which continues bitwise.
    model, state = sample(loose_sample, sc.undrained_path(5.0))

    def stop(step, length):
        if step == 77:
            raise LookupError("stop")
        return False
    world = sc.World(model, state, threads=2, initial_forces=False)
    with pytest.raises(LookupError):
        world.step_until(500, stop=stop)
    assert world.step_count == 77
    world.step(100)
    clean = sc.World(model, state, threads=2, initial_forces=False)
    clean.step(177)
    assert_same_world(world, clean)


# ---- 4. a custom path and settings without effect -------------------------------------------------

def test_a_custom_path_enables_the_servo():
    s = sc.ServoSettings()
    assert not s.enabled and s.path == "fixed"
    s.custom = drained
    assert s.enabled and s.path == "custom" and s.custom is drained
    calls = []
    model = base_model()
    servo(model).custom = lambda inp: calls.append(inp.step) or drained(inp)
    model.servo.enabled = False  # switched off again: the path would never be called
    state = sc.State.generate(model, 50, d_min=5e-3, d_max=7.5e-3, seed=2)
    with pytest.raises(ValueError, match="servo.custom: set, but servo.enabled = False: the path would never"):
        sc.World(model, state)
    model.servo.enabled, model.servo.path = True, "isotropic"
    with pytest.raises(ValueError, match="servo.custom: set, but servo.path is not 'custom'"):
        sc.World(model, state)
    model.servo.path = "custom"
    sc.World(model, state).step(3)
    assert calls == [0, 1, 2]


def test_settings_that_would_have_no_effect_are_errors(loose_sample):
    model, state = loose_sample
    world = sc.World(model, state, initial_forces=False)
    with pytest.raises(ValueError, match="axis = 2: has no effect without max_strain"):
        world.step_until(10, axis=2)
    with pytest.raises(ValueError, match="d50 = 0.001: has no effect without density"):
        world.measure(d50=1e-3)
    with pytest.raises(ValueError, match="density = 2650: has no effect without d50"):
        world.measure(density=2650.0)
    c = sc.CyclicSettings()
    c.lower, c.upper, c.rate, c.sigma3 = -1e-3, 1e-3, 1.0, P0
    with pytest.raises(ValueError, match="path: not this World's servo path"):
        world.step_until(10, path=sc.CyclicPath(c))
    with pytest.raises(ValueError, match="d_min = 0.001: has no effect with a gradation table"):
        sc.State.generate(model, 10, d_min=1e-3, gradation=[(1e-3, 0.0), (2e-3, 100.0)])


def test_a_path_without_a_stress_controlled_axis_needs_no_gain():
    model = base_model()
    s = model.servo
    s.enabled, s.control, s.strain_rate = True, ["strain"] * 3, [2.0, -1.0, -1.0]  # gain and max_rate left at 0
    assert s.gain == 0.0 and s.max_rate == 0.0
    state = sc.State.generate(model, 50, d_min=5e-3, d_max=7.5e-3, seed=2)
    world = sc.World(model, state)
    world.step(10)
    assert np.array_equal(world.cell["rate"], [-2.0, 1.0, 1.0])  # D_kk = -strain rate, compression positive
    s.control = ["strain", "stress", "stress"]
    with pytest.raises(ValueError, match="servo.gain = 0.000000: must be a finite value > 0"):
        sc.World(model, state)


# ---- 6. bad input ---------------------------------------------------------------------------------

def _world():
    model = base_model()
    return sc.World(model, sc.State.generate(model, 20, d_min=5e-3, d_max=7.5e-3, seed=2))


def _set(obj, name, value):
    setattr(obj, name, value)


@pytest.mark.parametrize("call, message", [
    (lambda: sc.Material(friction=math.inf), "friction = inf: must be a finite value >= 0"),
    (lambda: sc.Material(rolling_friction=math.nan), "rolling_friction = nan: must be a finite value >= 0"),
    (lambda: sc.Material(density=math.inf), "density = inf: must be a finite value > 0 kg/m^3"),
    (lambda: sc.Material(poisson=math.nan), "poisson = nan: must be in (-1, 0.5)"),
    (lambda: _set(sc.Material(), "friction", -0.1), "friction = -0.1: must be a finite value >= 0"),
    (lambda: _set(sc.Material(), "young", 0.0), "young = 0: must be a finite value > 0 Pa"),
    (lambda: _world().step_until(10, max_strain=math.nan), "max_strain = nan: must be finite"),
    (lambda: _world().step_until(10, max_strain=0.1, axis=3), "axis = 3: must be 0, 1 or 2"),
    (lambda: _world().measure(d50=-1.0, density=2650.0), "d50 = -1: must be a finite value >= 0 m"),
    (lambda: _world().measure(d50=1e-3, density=math.inf), "density = inf: must be a finite value >= 0"),
    (lambda: _world().set_cell_rate([0, math.nan, 0]), "rate[1] = nan: must be finite"),
    (lambda: sc.rayleigh_time(-1.0, sc.Material()), "r_min = -1: must be a finite value > 0 m"),
    (lambda: sc.rayleigh_time(math.inf, sc.Material()), "r_min = inf: must be a finite value > 0 m"),
    (lambda: sc.median_diameter([1e-3, -1e-3]), "radius[1] = -0.001: must be a finite value > 0 m"),
    (lambda: sc.sample_diameters(-1e-3, 2e-3, 10), "d_min = -0.001: must be a finite value > 0 m"),
    (lambda: sc.sample_diameters(1e-3, math.inf, 10), "d_max = inf: must be a finite value > 0 m"),
    (lambda: _set(sc.ServoSettings(), "gain", math.nan), "servo.gain = nan: must be a finite value >= 0 1/s"),
    (lambda: _set(sc.ServoSettings(), "b", 1.5), "servo.b = 1.5: must be in [0, 1]"),
    (lambda: _set(sc.ServoSettings(), "ramp_time", -1.0), "servo.ramp_time = -1: must be a finite value >= 0 s"),
    (lambda: _set(sc.ServoSettings(), "target", [0, math.inf, 0]), "servo.target[1] = inf: must be finite"),
    (lambda: _set(sc.ContactSettings(), "skin", math.inf), "contact.skin = inf: must be a finite value > 0 m"),
    (lambda: _set(sc.ContactSettings(), "sort_interval", -5), "contact.sort_interval = -5: must be >= 0 steps"),
    (lambda: _set(sc.State.generate(base_model(), 5, d_min=1e-3, d_max=1e-3), "time", math.nan),
     "time = nan: must be a finite value >= 0 s"),
    (lambda: _world().write_checkpoint(os.devnull, {"doubles": {"p0": 5e5}}),
     "extra['doubles']['p0'] = 500000.0: must be a sequence of numbers, e.g. [5e5]"),
    (lambda: _world().write_checkpoint(os.devnull, {"integers": {"n": ["a"]}}),
     "extra['integers']['n'] = ['a']: must be a sequence of integers"),
    (lambda: _world().write_checkpoint(os.devnull, {"strings": {3: "x"}}), "extra['strings']: key 3: must be a str"),
    (lambda: _world().write_checkpoint(os.devnull, {"doubles": [1.0]}),
     "extra['doubles']: <class 'list'>: must be a dict of name -> a sequence of numbers"),
    (lambda: sc.write_checkpoint(os.devnull, sc.State.generate(base_model(), 5, d_min=1e-3, d_max=1e-3), [1]),
     "extra: <class 'list'>: must be a dict with keys doubles, integers, strings"),
])
def test_bad_input_is_a_value_error_naming_argument_value_and_allowed(call, message):
    with pytest.raises(ValueError) as e:
        call()
    assert str(e.value).startswith(message), str(e.value)
