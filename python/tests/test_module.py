"""The module from the build tree: views without copies, measures, bad input, checkpoints."""
import os

import h5py
import numpy as np
import pytest

import sandcell as sc
from conftest import base_model


def test_imports_from_the_build_tree():
    # ctest sets PYTHONPATH to <build>/python: the package found must be the one built there.
    build = os.environ.get("PYTHONPATH", "").split(os.pathsep)[0]
    assert build and os.path.realpath(sc.__file__).startswith(os.path.realpath(build))
    assert sc.__version__.count(".") == 2


def test_views_see_the_state_after_steps_without_copies():
    model = base_model()
    state = sc.State.generate(model, 200, d_min=5e-3, d_max=7.5e-3, seed=5)
    world = sc.World(model, state, threads=2)
    x = world.particles["position"]
    f = world.contacts["force"]
    # The view's data is the C++ array itself, (n, 3) with the stride of a Vec3, and read-only.
    assert x.ctypes.data == world._address("position")
    assert x.shape == (200, 3) and x.strides == (24, 8) and not x.flags.writeable
    # The contact arrays move at each neighbour-list build: World.contacts are copies.
    assert f.size > 0 and f.ctypes.data != world._address("contact_force") and not f.flags.writeable
    assert np.array_equal(f, world.state().contacts["force"])
    with pytest.raises(ValueError):
        x[0, 0] = 1.0
    before = x.copy()
    world.step(50)  # no sort, no resize of the particle arrays: the pointer stays
    assert x.ctypes.data == world._address("position")
    assert world.particles["position"].ctypes.data == x.ctypes.data
    # The view shows what the engine holds now (a copy of the state taken after the steps).
    assert np.array_equal(x, world.state().particles["position"])
    assert before.shape == x.shape


def test_views_follow_moving_spheres():
    model = base_model()
    state = sc.State.from_arrays(model, [0.02, 0.02, 0.02], [[0.005, 0.01, 0.01], [0.0099, 0.01, 0.01]],
                                 [2.6e-3, 2.6e-3])  # 4.9 mm apart, overlapping by 0.3 mm: they push apart
    world = sc.World(model, state, threads=1)
    x = world.particles["position"]
    x0 = x[:, 0].copy()
    world.step(200)
    assert x[0, 0] < x0[0] and x[1, 0] > x0[1]  # the view saw the repulsion, no re-fetch
    assert x.ctypes.data == world._address("position")
    # Newton's third law on the view of the forces: equal and opposite (exact: one pair).
    f = world.particles["force"]
    assert np.array_equal(f[0], -f[1])


def test_measures_of_a_loose_sample(loose_sample):
    model, state = loose_sample
    world = sc.World(model, state, threads=2, initial_forces=False)
    m = world.measure()
    # Prepared to p0 within 1 % on each axis (the fixture's criterion), so p and the trace agree.
    assert abs(m.p - 1e5) / 1e5 < 0.01
    assert m.p == pytest.approx(np.trace(m.stress) / 3, rel=1e-12)  # identity, rounding only
    assert m.fabric.trace() == pytest.approx(1.0, rel=1e-12)  # <n (x) n> has trace 1
    assert m.z == pytest.approx(2 * m.contacts / len(state), rel=1e-15)
    assert 0.5 < m.e < 1.2


@pytest.mark.parametrize("call, key", [
    (lambda: sc.Model(dt=0.0, materials=[sc.Material()]), "dt"),
    (lambda: sc.Model(dt=-1e-6, materials=[sc.Material()]), "dt"),
    (lambda: sc.Model(dt=1e-6, materials=[]), "materials"),
    (lambda: sc.Material(young=-1.0), "young"),
    (lambda: sc.State.from_arrays(base_model(), [1, 1, 1], np.zeros((3, 2)), np.ones(3)), "position"),
    (lambda: sc.State.from_arrays(base_model(), [1, 1, 1], np.zeros((3, 3)), np.ones(4)), "radius"),
    (lambda: sc.State.from_arrays(base_model(), [1, 1, 1], np.zeros((2, 3)), [1e-3, -1e-3]), "radius[1]"),
    (lambda: sc.State.from_arrays(base_model(), [1, 1], np.zeros((2, 3)), [1e-3, 1e-3]), "box"),
    (lambda: setattr(sc.ServoSettings(), "path", "liquefy"), "servo.path"),
    (lambda: setattr(sc.ServoSettings(), "control", ["strain", "stres", "stress"]), "servo.control[1]"),
    (lambda: setattr(sc.ServoSettings(), "strain_rate", [1.0, 2.0]), "servo.strain_rate"),
    (lambda: setattr(sc.ServoSettings(), "custom", 3), "servo.custom"),
    (lambda: setattr(sc.ContactSettings(), "rolling", "sticky"), "contact.rolling"),
    (lambda: sc.PathTargets(["strain", "volume"], [0, 0, 0]), "control"),
    (lambda: sc.undrained_path(float("nan")), "undrained.axial_rate"),
    (lambda: sc.CyclicPath(sc.CyclicSettings()), "cyclic.upper"),
])
def test_bad_input_is_a_value_error_naming_the_argument(call, key):
    with pytest.raises(ValueError) as e:
        call()
    assert str(e.value).startswith(key), str(e.value)


def test_servo_settings_are_checked_when_the_world_is_built():
    model = base_model()
    model.servo.enabled = True
    model.servo.control = ["strain", "stress", "stress"]  # a path with no stress-controlled axis needs no gain
    model.servo.gain = 0.0
    state = sc.State.generate(model, 50, d_min=5e-3, d_max=7.5e-3)
    with pytest.raises(ValueError, match="servo.gain"):
        sc.World(model, state)
    model.servo.gain, model.servo.max_rate, model.servo.path = 1.0, 1.0, "custom"
    with pytest.raises(ValueError, match="servo.custom"):
        sc.World(model, state)


def test_checkpoint_round_trip_is_bitwise(loose_sample, work_dir):
    model, state = loose_sample
    world = sc.World(model, state, threads=2, initial_forces=False)
    world.step(10)
    path = os.path.join(work_dir, "round.h5")
    world.write_checkpoint(path, {"doubles": {"p0": [1e5]}, "strings": {"note": "py"}})
    back, extra = sc.read_checkpoint(path)
    assert extra["doubles"]["p0"] == [1e5] and extra["strings"]["note"] == "py"
    for name, view in world.particles.items():
        assert np.array_equal(view, back.particles[name]), name
    assert back.step == world.step_count and back.time == world.time
    # A world continued from the checkpoint runs bitwise as the one that wrote it.
    again = sc.World(model, back, threads=1, initial_forces=False)
    world.step(100)
    again.step(100)
    assert np.array_equal(world.particles["position"], again.particles["position"])
    with h5py.File(path) as f:
        assert f.attrs["format"] == b"sandcell checkpoint" or f.attrs["format"] == "sandcell checkpoint"


def test_every_partition_steps_bitwise_the_same(loose_sample):
    # How the threads share each pass (partition=) must change no bit: 1 thread against 2 and 3
    # threads under each partition, on a sample in contact at p0, after enough steps for the
    # adaptive one to run its first trial (four batches of at least 16 steps).
    model, state = loose_sample
    reference = sc.World(model, state, threads=1, initial_forces=False)
    reference.step(150)
    assert np.abs(reference.particles["force"]).max() > 0  # the sums compared below are not all zero
    for threads, partition in ((2, "owner"), (3, "owner"), (2, "dynamic"), (3, "fixed"), (2, "adaptive")):
        world = sc.World(model, state, threads=threads, initial_forces=False, partition=partition)
        world.step(150)
        for name in ("position", "velocity", "angular_velocity", "force", "torque"):
            assert np.array_equal(world.particles[name], reference.particles[name]), (threads, partition, name)
    with pytest.raises(ValueError, match="partition = 'static': allowed 'adaptive', 'owner'"):
        sc.World(model, state, threads=2, partition="static")


def test_stiffness_time_step_from_python(loose_sample):
    # time_step = stiffness: World sets dt from the contacts (safety x sc.stable_step, capped at
    # max_dt) when it is built and every `interval` steps, bitwise for any thread count.
    _, state = loose_sample
    model = base_model()  # its own: the fixture's model is shared by the session's tests
    model.time_step = sc.TimeStepSettings("stiffness", safety=0.8, interval=10, max_dt=10 * model.dt)
    assert model.time_step.rule == "stiffness"
    world = sc.World(model, state, threads=1, initial_forces=False)
    bound = sc.stable_step(model, world.state())
    assert 0 < bound["step"] < float("inf") and bound["rotational"]  # friction and rolling springs: rotation bounds
    assert world.model.dt == 0.8 * bound["step"]  # the same arithmetic as the engine's: equal to the bit
    # The update before step 31 (clock step 30, a multiple of the interval) reads the state after 30.
    world.step(30)
    expected = 0.8 * sc.stable_step(model, world.state())["step"]
    world.step(5)
    assert world.model.dt == expected != bound["step"] * 0.8
    other = sc.World(model, state, threads=2, initial_forces=False)
    other.step(35)
    assert other.model.dt == world.model.dt
    assert np.array_equal(world.particles["position"], other.particles["position"])
    with pytest.raises(ValueError, match="time_step.rule = 'adaptive'|time_step.rule"):
        sc.TimeStepSettings("adaptive")
    model.time_step = sc.TimeStepSettings("stiffness", safety=2.0, max_dt=model.dt)
    with pytest.raises(ValueError, match="time_step.safety = 2"):
        sc.World(model, state, initial_forces=False)
