"""The shearing cell from Python: simple shear past gamma = 1 (flips), a Python path driving the
shear components, the tensor measures, bad shear settings naming their key."""
import math

import numpy as np
import pytest

import sandcell as sc
from conftest import P0, base_model


def servo(model):
    s = model.servo
    s.enabled = True
    s.gain = sc.derived_gain(0.1, P0, model.materials[0], model.dt)
    s.integral_time = 1000 * model.dt
    s.max_rate = 20.0
    return s


def test_simple_shear_at_constant_volume_runs_past_gamma_1_through_flips(dense_sample):
    model, state = dense_sample
    g = 100.0  # 1/s, engineering gamma_dot_xz (compression positive): L_xz = -g; inertial number ~0.1
    s = model.servo
    s.enabled, s.path, s.shear_strain_rate = True, "simple_shear_cv", [0.0, g, 0.0]
    assert s.path == "simple_shear_cv" and s.shear_control == ["strain"] * 3  # the registry's name; the default
    world = sc.World(model, state, threads=2, initial_forces=False)
    # The servo's rate from the first drift on (its first update comes after the first step's drift).
    world.set_cell_shear_rate([0.0, -g, 0.0])
    cell = world.cell  # live views: fetched once, read after the steps
    flip, tilt, rate = cell["flip"], cell["tilt"], cell["shear_rate"]
    assert not flip.flags.writeable and list(flip) == [0.0, 0.0, 0.0]
    n = math.ceil(1.2 / (g * model.dt))  # to gamma = 1.2
    world.step(n)
    m = world.measure()
    # Every step drifted at L_xz = -g (set, then the servo's 0 - g each update): F_xz = sum L_xz L3 dt / L3
    # over n forward-Euler updates of the tilt, continued through the flips (N); n ~ 7,000 roundings.
    assert list(rate) == [0.0, -g, 0.0]
    assert m.deformation[0, 2] == pytest.approx(-g * n * model.dt, rel=1e-9)
    assert m.gamma[1] == -m.deformation[0, 2] and m.gamma[1] > 1.0
    # The tilt is reduced at list builds (|xz| <= L1/2 there): past gamma = 0.5 it flipped, counted in N.
    assert flip[1] != 0.0 and flip[0] == 0.0 and flip[2] == 0.0, flip
    assert abs(tilt[1]) < 0.6 * cell["length"][0]
    assert np.array_equal(world.state().cell_flip, flip)
    # Constant volume: xx, yy, zz fixed (0 * L: the lengths keep their bits), eps_v = 0.
    assert np.array_equal(cell["length"], state.cell_length) and m.eps_v == 0.0
    # F is a simple shear by F_xz: principal log strains +-asinh(gamma/2), 0 (kinematics test's closed form),
    # eps_q = sqrt(2)/3 sqrt(a^2 + a^2 + 4 a^2) = 2a / sqrt(3), the strain tensor log_strain(F) itself.
    a = math.asinh(m.gamma[1] / 2)
    assert m.principal_strain == pytest.approx([a, 0.0, -a], abs=1e-12)
    assert m.eps_q == pytest.approx(2 * a / math.sqrt(3), rel=1e-12)
    assert np.array_equal(m.strain_tensor, sc.log_strain(m.deformation))
    # The rate tensor of simple shear: -D_xz = g/2; the inertial number from its principal rates +-g/2.
    assert m.strain_rate_tensor[0, 2] == g / 2 and m.strain_rate_tensor[2, 0] == g / 2
    # The sample carries the shear: S_xz > 0 (compression positive, sheared at gamma_dot_xz > 0), finite.
    assert np.isfinite(m.stress).all() and m.stress[0, 2] > 0.05 * m.p > 0, (m.stress, m.p)
    values, directions = sc.principal(m.stress)
    # The values: the invariants' (an eigenvalues-only solve) against principal()'s full one, to round-off.
    assert values == pytest.approx(m.principal_stress, rel=1e-12) and np.array_equal(directions, m.stress_directions)
    assert 0.0 <= m.noncoaxiality <= 90.0 and -90.0 < m.alpha <= 90.0


def test_a_python_path_drives_the_shear_rates(loose_sample):
    model, state = loose_sample
    seen = []
    value = np.array([5.0, -20.0, 10.0])  # engineering rates gamma_dot (xy, xz, yz), 1/s

    def path(inp):
        seen.append((inp.step, inp.shear_strain_rate.copy(), inp.deformation.copy(), inp.stress[0, 2]))
        if inp.step < 100:  # the tuple form with shear components
            return (["strain"] * 3, [0.0, 0.0, 0.0], ["strain"] * 3, value)
        return sc.PathTargets(["strain"] * 3, [0.0, 0.0, 0.0], ["strain", "stress", "strain"], [0.0, 0.0, 0.0])
    servo(model).custom = path
    world = sc.World(model, state, threads=2, initial_forces=False)
    rate = world.cell["shear_rate"]
    world.step(100)
    # Strain answers: L_ab = -value, exactly.
    assert list(rate) == list(-value)
    # The path saw the rates applied since the first update (step 0), and F: the update at step k
    # follows k drifts at L, F = (I + L dt)^k = I + k L dt + k (k - 1)/2 L^2 dt^2 (L nilpotent:
    # strictly upper triangular), L^2 having only (xz) = L_xy L_yz.
    assert seen[0][0] == 0 and list(seen[0][1]) == [0.0, 0.0, 0.0]
    step, gdot, f, _ = seen[-1]
    assert step == 99 and list(gdot) == list(value)
    lxy, lxz, lyz = -value
    dt = model.dt
    assert f[0, 1] == pytest.approx(step * lxy * dt, rel=1e-12)
    assert f[1, 2] == pytest.approx(step * lyz * dt, rel=1e-12)
    assert f[0, 2] == pytest.approx(step * lxz * dt + step * (step - 1) / 2 * lxy * lyz * dt ** 2, rel=1e-12)
    # Then xz stress controlled toward 0 (the PathTargets form): the PI law's rate, inside the cap,
    # its integral advancing; xy and yz strain controlled at 0.
    world.step(20)
    assert rate[0] == 0.0 and rate[2] == 0.0
    assert rate[1] != -value[1] and abs(rate[1]) <= model.servo.max_rate
    integral = world.cell["shear_integral"]
    assert integral[1] != 0.0 and integral[0] == 0.0 and integral[2] == 0.0


def test_tensor_functions_from_python():
    g = 1.0
    f = np.eye(3)
    f[0, 2] = g
    e = sc.log_strain(f)
    a = math.asinh(g / 2)
    values, directions = sc.principal(e)
    assert values == pytest.approx([a, 0.0, -a], abs=1e-14)  # closed form: tests/systems/test_kinematics.cpp
    assert np.allclose(directions.T @ directions, np.eye(3), atol=1e-14)
    # A diagonal F exactly: -ln F_kk (math.log is the C library's log, as the engine's; NumPy's own may
    # differ in the last bit).
    assert np.array_equal(sc.log_strain(np.diag([0.9, 1.0, 1.1])), np.diag([-math.log(x) for x in (0.9, 1.0, 1.1)]))
    # alpha of a stress turned 30 degrees in xz, and the angle between it and an axis-aligned strain.
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    r = np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])
    stress = r @ np.diag([3e5, 2e5, 1e5]) @ r.T
    assert sc.alpha_deg(stress) == pytest.approx(30.0, abs=1e-9)
    assert sc.axes_rotation_deg(stress) == pytest.approx(30.0, abs=1e-9)
    assert sc.axes_rotation_deg(stress) == pytest.approx(sc.principal_rotation_deg(stress), abs=1e-9)
    assert sc.noncoaxiality_deg(stress, np.diag([1e-3, 0, -1e-3])) == pytest.approx(30.0, abs=1e-9)
    lg = np.zeros((3, 3))
    lg[0, 2] = -4.0
    assert sc.strain_rate_tensor(lg)[0, 2] == 2.0


def _world_with(**servo):
    model = base_model()
    s = model.servo
    s.enabled, s.gain, s.max_rate = True, 1.0, 1.0
    for k, v in servo.items():
        setattr(s, k, v)
    state = sc.State.generate(model, 50, d_min=5e-3, d_max=7.5e-3)
    return sc.World(model, state)


def _state():
    return sc.State.generate(base_model(), 20, d_min=5e-3, d_max=7.5e-3)


def _set(obj, key, value):
    setattr(obj, key, value)


@pytest.mark.parametrize("call, key", [
    (lambda: _set(sc.ServoSettings(), "shear_control", ["strain", "volume", "strain"]), "servo.shear_control[xz]"),
    (lambda: _set(sc.ServoSettings(), "shear_control", ["strain", "strain", "stres"]), "servo.shear_control[yz]"),
    (lambda: _set(sc.ServoSettings(), "shear_control", ["strain"]), "servo.shear_control"),
    (lambda: _set(sc.ServoSettings(), "shear_strain_rate", [0.0, math.nan, 0.0]), "servo.shear_strain_rate[xz]"),
    (lambda: _set(sc.ServoSettings(), "shear_strain_rate", [0.0, 1.0]), "servo.shear_strain_rate"),
    (lambda: _set(sc.ServoSettings(), "shear_target", [math.inf, 0.0, 0.0]), "servo.shear_target[xy]"),
    (lambda: _set(sc.ServoSettings(), "normal_stress", -1e5), "servo.normal_stress"),
    (lambda: _set(sc.ServoSettings(), "q", math.nan), "servo.q"),
    (lambda: _set(sc.ServoSettings(), "rotation_rate", math.inf), "servo.rotation_rate"),
    (lambda: _set(sc.ServoSettings(), "rotation_start", math.nan), "servo.rotation_start"),
    (lambda: sc.PathTargets(["strain"] * 3, [0, 0, 0], ["volume", "strain", "strain"]), "shear_control[xy]"),
    (lambda: sc.PathTargets(["strain"] * 3, [0, 0, 0], ["strain"] * 3, [0, 0]), "shear_value"),
    (lambda: _set(_state(), "cell_flip", [0.0, 0.5, 0.0]), "cell_flip[xz]"),
    (lambda: _set(_state(), "cell_shear_rate", [math.nan, 0.0, 0.0]), "cell_shear_rate[xy]"),
    (lambda: _set(_state(), "cell_tilt", [0.0, 0.0, math.inf]), "cell_tilt[yz]"),
    (lambda: _set(_state(), "cell_tilt0", [0.0, math.nan, 0.0]), "cell_tilt0[xz]"),
    (lambda: _set(_state(), "shear_integral", [0.0, 0.0, math.nan]), "shear_integral[yz]"),
    (lambda: _world_with().set_cell_shear_rate([0.0, math.nan, 0.0]), "shear_rate[xz]"),
    # The engine's checks when the World is built (systems/servo.cpp validate).
    (lambda: _world_with(path="simple_shear"), "servo.normal_stress"),
    (lambda: _world_with(path="rotation", p=P0, b=0.0, q=4 * P0), "servo.q"),
    (lambda: sc.log_strain(np.diag([1.0, -1.0, 1.0])), "F"),
])
def test_bad_shear_settings_are_value_errors_naming_the_key(call, key):
    with pytest.raises(ValueError) as e:
        call()
    assert str(e.value).startswith(key), str(e.value)


def test_a_python_path_answering_a_volume_shear_is_a_value_error(loose_sample):
    model, state = loose_sample
    servo(model).custom = lambda inp: (["strain"] * 3, [0, 0, 0], ["strain", "volume", "strain"], [0, 0, 0])
    world = sc.World(model, state, threads=1, initial_forces=False)
    with pytest.raises(ValueError, match=r"path result shear_control\[xz\] = 'volume'"):
        world.step(5)
    model.servo.custom = lambda inp: (["strain"] * 3, [0, 0, 0], ["strain"] * 3)  # three items: neither form
    world = sc.World(model, state, threads=1, initial_forces=False)
    with pytest.raises(ValueError, match="of 3 items"):
        world.step(5)
