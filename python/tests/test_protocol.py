"""sandcell.Protocol: the app's protocol from Python is the app's own code (apps/triaxial/protocol),
checked against the app's documented rules and the app itself."""
import math
import os
import subprocess

import pytest

import sandcell as sc

HERE = os.path.dirname(os.path.abspath(__file__))
SMALL = os.path.join(HERE, "small.toml")


def test_derived_values_follow_the_documented_rules():
    """dt = dt_fraction t_R of the smallest sphere; t_s = max(dt, 0.2 t_R); the shear gain
    0.1 (p0/E*)^(2/3) / t_s and the integral time 1000 t_s (docs/physics.md section 6). Exact: the
    same formulas in the same order give the same double."""
    p = sc.Protocol.load(SMALL)
    mat = sc.Material(density=2650.0, young=7e9, poisson=0.3, restitution=0.5, friction=0.5, rolling_friction=0.1)
    t_r = sc.rayleigh_time(0.5 * min(p.diameters), mat)
    assert p.r_min == 0.5 * min(p.diameters)
    assert p.dt == 0.2 * t_r
    assert p.servo_time == max(p.dt, 0.2 * t_r)
    s = p.shear_model(0).servo
    assert s.gain == sc.derived_gain(0.1, 0.5e6, mat, p.servo_time)
    assert s.integral_time == 1000 * p.servo_time
    assert (s.gain, s.integral_time) == sc.derived_servo("shear", 0.5e6, mat, p.servo_time)
    assert p.prepare_model(0.5e6).servo.gain == sc.derived_servo("prepare", 0.5e6, mat, p.prepare_servo_time)[0]
    assert p.servo_time == sc.servo_time_unit(p.dt, p.r_min, mat)
    # The cap follows the axial rate (10 /s here), 20 x by default (shear.max_rate_ratio;
    # experiments/2026-11-28-servo-cap), the rate at p0 its floor.
    assert s.max_rate == 20 * 10.0 and s.max_rate_ratio == 20.0
    # An explicit fixed cap is used alone, unless a ratio is given beside it; a ratio alone scales the floor.
    text = open(SMALL).read()
    assert "max_rate" not in text.split("[shear]")[1].split("[")[0]
    for extra, cap, ratio in (("max_rate = 50.0", 50.0, 0.0), ("max_rate = 50.0\nmax_rate_ratio = 15.0", 50.0, 15.0),
                              ("max_rate_ratio = 15.0", 150.0, 15.0)):
        q = sc.Protocol.parse(text.replace("[shear]", "[shear]\n" + extra, 1)).shear_model(0).servo
        assert (q.max_rate, q.max_rate_ratio) == (cap, ratio), extra
    e_star = 7e9 / (2 * (1 - 0.3 ** 2))
    assert math.isclose(sc.derived_gain(0.05, 1e5, mat, 1e-6), 0.05 * (1e5 / e_star) ** (2 / 3) / 1e-6, rel_tol=1e-15)
    prep = p.prepare_model(0.5e6)
    assert prep.servo.path == "isotropic" and prep.servo.p == 0.5e6
    assert prep.materials[0].friction == 0.0  # [prepare] friction, restored for the shear
    assert p.shear_model(p.tests[0].name).materials[0].friction == 0.5


def test_tests_and_tags_are_the_apps():
    p = sc.Protocol.load(SMALL)
    assert [t.name for t in p.tests] == ["p-b0.50-p0_500kPa"]
    assert p.tests[0].path == "constant_p" and p.tests[0].b == 0.5 and p.p0 == [0.5e6]
    assert sc.p0_tag(0.5e6) == "p0_500kPa"
    with pytest.raises(KeyError):
        p.shear_model("no-such-test")
    with pytest.raises(IndexError):
        p.shear_model(1)


def test_dt_is_the_one_the_app_reports():
    """`triaxial --check` prints the dt it derives (%.6g): the same value."""
    app = os.environ.get("SANDCELL_TRIAXIAL")
    if not app:
        pytest.skip("SANDCELL_TRIAXIAL not set")
    out = subprocess.run([app, SMALL, "--check"], capture_output=True, text=True, check=True).stdout
    reported = float(out.split("dt = ")[1].split(" s")[0])
    assert "%.6g" % sc.Protocol.load(SMALL).dt == "%.6g" % reported


def test_a_bad_config_is_a_value_error_naming_the_key():
    with pytest.raises(sc.ConfigError, match="material.young"):
        sc.Protocol.parse(open(SMALL).read().replace("young = 7.0e9", "young = -1.0"))
    with pytest.raises(ValueError):  # ConfigError is a ValueError
        sc.Protocol.parse("[nonsense]\n")


def test_the_series_schema_is_one_table():
    """The 41 columns of the results files (the twin test compares them bitwise with the app's)."""
    cols = sc.series_columns()
    names = [c[0] for c in cols]
    assert len(cols) == 41 and len(set(names)) == 41
    assert names[:2] == ["time", "step"] and names[-1] == "wall_time"
    assert dict((c[0], c[2]) for c in cols)["stress"] == 6


def test_the_accuracy_watch_warns_once_per_indicator():
    """The cloud at rest trips nothing (no false positive); 1,000 steps into the compression the
    kinetic energy is ~80 x the elastic one and the inertial number ~1 (a loose cloud shrinking at
    the servo's cap), the unbalanced force and overlap within their limits: one line for each of the
    two indicators beyond its limit (named, with its value and limit), none for the others, none
    repeated at the next check, the worst values kept."""
    p = sc.Protocol.load(SMALL)
    prep = p.prepare_model(0.5e6)
    world = sc.World(prep, p.cloud(prep), threads=1)
    lines = []
    w = sc.AccuracyWatch("job", lines.append)
    w.check(world.measure(d50=p.d50, density=2650.0), 0)
    assert lines == []
    world.step(1000)
    m = world.measure(d50=p.d50, density=2650.0)
    ratio = m.kinetic_energy / m.elastic_energy
    assert ratio > 0.05 and m.inertial_number_axial > 3.15e-3
    assert m.unbalanced < 0.1 and m.max_overlap_ratio < 0.05
    w.check(m, 1000)
    w.check(m, 1001)
    assert len(lines) == 2, lines
    assert lines[0].startswith("job: warning: step 1000: inertial number ") and "> 0.00315" in lines[0]
    assert lines[1].startswith("job: warning: step 1000: kinetic / elastic energy = ") and "> 0.05" in lines[1]
    assert f"max I {m.inertial_number_axial:.2g}" in w.worst() and f"Ek/Ee {ratio:.2g}" in w.worst()


def test_the_path_registry_is_one_list_for_the_app_and_the_analysis():
    """tests.path names (apps/triaxial/protocol/paths.cpp) are the analysis's PATHS, in order (ctest puts
    apps/analysis on PYTHONPATH beside the module)."""
    from sandcell_analysis.results import PATHS
    names = [p["name"] for p in sc.test_paths()]
    assert tuple(names) == PATHS
    assert {p["name"]: p["prefix"] for p in sc.test_paths()}["undrained"] == "u"


def test_the_undrained_path_holds_the_volume_and_refuses_what_it_cannot_do():
    """From TOML: constant volume (eps_v = 0 to round-off over 2 % of axial strain: the servo sets the
    lateral rates so the volume after each update is the reference's, |eps_v| < 1e-9); a set inertial
    number, a ramp or a b are refused naming the key."""
    text = open(os.path.join(HERE, "small-undrained.toml")).read()
    p = sc.Protocol.parse(text)
    assert p.tests[0].name == "u-p0_500kPa" and p.tests[0].path == "undrained"
    model = p.shear_model(0)
    assert model.servo.path == "custom" and model.servo.enabled
    with pytest.raises(sc.ConfigError, match="shear.inertial_number"):
        sc.Protocol.parse(text.replace("strain_rate = 10.0", "inertial_number = 1e-3"))
    with pytest.raises(sc.ConfigError, match="shear.ramp_strain"):
        sc.Protocol.parse(text.replace("strain_rate = 10.0", "strain_rate = 10.0\nramp_strain = 0.001"))
    with pytest.raises(sc.ConfigError, match="tests.b"):
        sc.Protocol.parse(text.replace('path = "undrained"', 'path = "undrained"\nb = 0.5'))
    prep = p.prepare_model(0.5e6)
    world = sc.World(prep, p.cloud(prep), threads=1)
    while True:
        world.step_until(10**12, every=1000)
        m = world.measure()
        if max(abs(m.stress[k, k] - 0.5e6) / 0.5e6 for k in range(3)) < 0.01 and m.unbalanced < 0.01:
            break
    world = sc.World(model, p.start_test(0, sc.finish_preparation(world.state())), threads=1, initial_forces=False)
    worst = 0.0
    while world.measure().strain[0] < 0.02:
        world.step_until(10**12, every=100, max_strain=0.02)
        worst = max(worst, abs(world.measure().eps_v))
    assert worst < 1e-9


@pytest.mark.whole_app  # resume under the sanitizers: test_io.cpp; the cyclic path: test_paths.py
def test_a_cyclic_test_from_toml_resumes_bitwise(tmp_path):
    """[cyclic] through the app: 2 strain cycles of +-0.2 % (4 reversals), the shear stopped after 300
    steps (one reversal made) and resumed (the path's memory, its direction and reversals, rides in the
    checkpoint) equal to the uninterrupted run, every series value but wall_time bitwise."""
    import h5py
    import numpy as np
    app = os.environ.get("SANDCELL_TRIAXIAL")
    if not app:
        pytest.skip("SANDCELL_TRIAXIAL not set")
    config = os.path.join(HERE, "small-cyclic.toml")
    whole, parts = str(tmp_path / "whole"), str(tmp_path / "parts")
    subprocess.run([app, config, "--out", whole, "--threads", "1"], check=True, capture_output=True)
    subprocess.run([app, config, "--out", parts, "--threads", "1", "--prepare-only"], check=True, capture_output=True)
    # the shear stopped at step 300: after its first reversal (step ~120), heading down
    r = subprocess.run([app, config, "--out", parts, "--threads", "1", "--resume", "--stop-after", "300"],
                       capture_output=True)
    assert r.returncode == 3, r.stderr
    subprocess.run([app, config, "--out", parts, "--threads", "2", "--resume"], check=True, capture_output=True)
    name = "cyc-p0_500kPa.h5"
    with h5py.File(os.path.join(whole, name)) as a, h5py.File(os.path.join(parts, name)) as b:
        eps1 = a["series/strain"][:, 0]
        assert eps1.max() > 0.0019 and eps1.min() < -0.0019  # both bounds reached
        for k in a["series"]:
            if k != "wall_time":
                assert np.array_equal(a["series"][k][()], b["series"][k][()]), k


def test_the_contact_law_registry_is_what_the_module_accepts():
    """Every slot's names from the law registries (systems/laws/); each is accepted by ContactSettings,
    and a name not registered is a ValueError listing them."""
    laws = sc.contact_laws()
    assert [n["name"] for n in laws["normal"]] == ["hertz", "hooke"]
    assert laws["tangential"] == ["history", "incremental", "mindlin_rescale"]
    assert laws["rolling"] == ["none", "epsd2", "epsd", "cdt"]
    hooke = laws["normal"][1]["parameters"][0]
    assert hooke["name"] == "characteristic_velocity" and hooke["units"] == "m/s"
    c = sc.ContactSettings()
    for name in laws["tangential"]:
        c.tangential = name
        assert c.tangential == name
    for name in laws["rolling"]:
        c.rolling = name
        assert c.rolling == name
    with pytest.raises(ValueError, match="mindlin_rescale"):
        c.tangential = "mindlin"


def test_cyclic_settings_that_would_do_nothing_are_refused():
    """[cyclic] without a cyclic test, a cyclic test without an end, a stress-mode tolerance in strain
    mode: each a ConfigError naming the key."""
    text = open(os.path.join(HERE, "small-cyclic.toml")).read()
    with pytest.raises(sc.ConfigError, match="cyclic.tolerance"):
        sc.Protocol.parse(text.replace("cycles = 2", "cycles = 2\ntolerance = 0.1"))
    with pytest.raises(sc.ConfigError, match="cyclic.cycles"):
        sc.Protocol.parse(text.replace("cycles = 2", "cycles = 0"))
    with pytest.raises(sc.ConfigError, match=r"\[cyclic\]"):
        sc.Protocol.parse(text.replace('path = "cyclic"', 'path = "constant_p"'))
