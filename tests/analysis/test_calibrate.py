"""`triaxial calibrate` (sandcell_analysis.calibrate): the calibrate-smoke run and its bad input.

The smoke run: the truth is the smoke config at material.friction = 0.5, prepare.friction = 0.2; its
own e0 and peak q/p are the targets. Calibrating the two frictions over [0.2, 0.8] x [0, 0.4] from
12 runs must give posteriors that contain the truth: each posterior mean within 3 posterior
standard deviations of the truth (for a Gaussian posterior that fails with probability 0.3 %; the
runs are deterministic, so the test cannot be flaky), and prepare.friction, which sets e0 through
the packing's density, identified (posterior std below half the prior's). Needs the triaxial binary
(SANDCELL_TRIAXIAL, set by ctest).
"""
import json
import os
import shutil
import subprocess
import sys
import tempfile

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
CALIBRATE = [sys.executable, "-m", "sandcell_analysis", "calibrate"]  # what `triaxial calibrate` runs
CONFIG = os.path.join(HERE, "calibrate-smoke.toml")
TRIAXIAL = os.environ.get("SANDCELL_TRIAXIAL", "")
TRUTH = {"material.friction": 0.5, "prepare.friction": 0.2}
PARAMS = ["--param", "material.friction=0.2:0.8", "--param", "prepare.friction=0.0:0.4"]

needs_binary = pytest.mark.skipif(not os.access(TRIAXIAL, os.X_OK), reason="SANDCELL_TRIAXIAL not set (ctest sets it)")


def calibrate(*args, cwd=None):
    env = dict(os.environ, SANDCELL_TRIAXIAL=TRIAXIAL)
    return subprocess.run([*CALIBRATE, *args], capture_output=True, text=True, env=env, cwd=cwd)


@pytest.fixture(scope="module")
def work():
    d = tempfile.mkdtemp(prefix="calibrate-")
    yield d
    shutil.rmtree(d, ignore_errors=True)


def truth_row(config, out):
    """The first index.csv row of CONFIG run by the app itself (the config holds the true values)."""
    import csv
    subprocess.run([TRIAXIAL, config, "--out", out, "--overwrite", "--threads", "1"], check=True, capture_output=True)
    return next(csv.DictReader(open(os.path.join(out, "index.csv"))))


def write_targets(path, text):
    with open(path, "w") as f:
        f.write(text)
    return path


@needs_binary
def test_smoke_recovers_the_truth_within_its_uncertainty(work):
    row = truth_row(CONFIG, os.path.join(work, "truth"))
    targets = write_targets(os.path.join(work, "targets.toml"),
                            f"[targets]\ne0 = {{ value = {row['e0']}, sigma = 0.005 }}\n"
                            f"peak_eta = {{ value = {row['peak_eta']}, sigma = 0.02 }}\n")
    out = os.path.join(work, "cal")
    r = calibrate(CONFIG, "--targets", targets, *PARAMS, "--budget", "12", "--out", out, "--threads", "1")
    assert r.returncode == 0, r.stderr
    result = json.load(open(os.path.join(out, "calibration.json")))
    for key, true in TRUTH.items():
        q = result["params"][key]
        assert abs(q["mean"] - true) <= 3.0 * q["std"], (key, q)
    assert result["params"]["prepare.friction"]["identified"]
    # The check run at the posterior mean lands within 3 sigma (target sigma and surrogate error) of
    # every target.
    for name, t in result["targets"].items():
        tol = 3.0 * (t["sigma"] ** 2 + result["surrogate_error"][name] ** 2) ** 0.5
        assert abs(result["check"][name] - t["value"]) <= tol, (name, result["check"][name], t)
    for f in ("runs.csv", "calibration.md", "calibration.png"):
        assert os.path.getsize(os.path.join(out, f)) > 0
    # Resumable: a second call with --resume runs nothing again (every run folder is finished).
    r2 = calibrate(CONFIG, "--targets", targets, *PARAMS, "--budget", "12", "--out", out, "--threads", "1",
                   "--resume")
    assert r2.returncode == 0, r2.stderr
    assert "run-000" not in r2.stdout and "check:" not in r2.stdout, r2.stdout
    # A changed range is other points: --resume runs them again (over the old folders), never
    # mixing the old points' measures into the new surrogate.
    r3 = calibrate(CONFIG, "--targets", targets, "--param", "material.friction=0.3:0.7", "--param",
                   "prepare.friction=0.0:0.4", "--budget", "12", "--out", out, "--threads", "1", "--resume")
    assert r3.returncode == 0, r3.stderr
    assert "run-000" in r3.stdout and "--overwrite" in r3.stdout
    rows = open(os.path.join(out, "runs.csv")).read().splitlines()[1:]
    assert all(0.3 <= float(row.split(",")[1]) <= 0.7 for row in rows)


@needs_binary
def test_discrete_choice_picks_the_rolling_model_that_made_the_targets(work):
    # The truth rolls with epsd2 at mu_r = 0.3, which raises the peak q/p well above rolling "none"
    # (at 150 spheres by about 0.2, ten target sigmas): the option that made the targets must get
    # nearly all the posterior probability, and the friction's posterior must contain its truth.
    base = open(CONFIG).read().replace("[material]\n", "[material]\nrolling_friction = 0.3\n")
    config = os.path.join(work, "choice.toml")
    with open(config, "w") as f:
        f.write(base + '[contact]\nrolling = "none"\n')
    truth_config = os.path.join(work, "choice-truth.toml")
    with open(truth_config, "w") as f:
        f.write(base + '[contact]\nrolling = "epsd2"\n')
    row = truth_row(truth_config, os.path.join(work, "choice-truth"))
    targets = write_targets(os.path.join(work, "choice-targets.toml"),
                            f"[targets]\npeak_eta = {{ value = {row['peak_eta']}, sigma = 0.02 }}\n"
                            f"final_eta = {{ value = {row['final_eta']}, sigma = 0.02 }}\n")
    out = os.path.join(work, "choice-cal")
    r = calibrate(config, "--targets", targets, "--param", "material.friction=0.2:0.8", "--choice",
                  "contact.rolling=none,epsd2", "--budget", "6", "--out", out, "--threads", "1")
    assert r.returncode == 0, r.stderr
    result = json.load(open(os.path.join(out, "calibration.json")))
    assert result["choice"]["chosen"] == "epsd2", result["choice"]
    assert result["choice"]["options"]["epsd2"]["probability"] > 0.95, result["choice"]
    q = result["params"]["material.friction"]
    assert abs(q["mean"] - 0.5) <= 3.0 * q["std"], q
    header = open(os.path.join(out, "runs.csv")).readline().strip().split(",")
    assert header[:3] == ["run", "contact.rolling", "material.friction"]
    assert len(result["runs"]) == 12  # the budget per option


@pytest.mark.parametrize("args, expect", [
    (["--param", "material.friction=0.2:0.8", "--choice", "contact.rollin=none,epsd2"],
     "--choice contact.rollin: unknown choice"),
    (["--param", "material.friction=0.2:0.8", "--choice", "contact.rolling=none,epsd3"],
     "--choice contact.rolling: unknown option 'epsd3'"),
    (["--param", "material.friction=0.2:0.8", "--choice", "contact.rolling=epsd2"],
     "needs at least two different options"),
    (["--param", "material.friction=0.2:0.8", "--choice", "contact.rolling=epsd2,epsd2"],
     "needs at least two different options"),
    (["--param", "material.fricton=0.2:0.8"], "--param material.fricton: unknown parameter"),
    (["--param", "material.friction=0.8:0.2"], "the range must be non-empty with LO < HI"),
    (["--param", "material.friction=0.5:0.5"], "the range must be non-empty with LO < HI"),
    (["--param", "material.friction=0.2"], "expected KEY=LO:HI"),
    (["--param", "material.friction=0.2:0.8", "--param", "prepare.friction=0:0.4", "--budget", "7"],
     "--budget 7: a quadratic surrogate in 2 parameter(s) needs at least 8 runs"),
])
def test_bad_parameters_exit_2_with_one_line(work, args, expect):
    targets = write_targets(os.path.join(work, "ok.toml"), "[targets]\ne0 = { value = 0.65, sigma = 0.01 }\n")
    r = calibrate(CONFIG, "--targets", targets, *args, "--out", os.path.join(work, "bad"))
    assert r.returncode == 2
    assert expect in r.stderr
    assert r.stderr.count("\n") == 1
    assert not os.path.exists(os.path.join(work, "bad"))


@pytest.mark.parametrize("text, expect", [
    ("[targets]\nphi_x = { value = 1, sigma = 1 }\n", "targets.phi_x: unknown measure"),
    ("[targets]\ne0 = { value = 0.6 }\n", "targets.e0: expected { value = ..., sigma = ... }"),
    ("[targets]\ne0 = { value = 0.6, sigma = 0 }\n", "sigma > 0"),
    ("[targets]\n\"phi_c:p-b0\" = { value = 22, sigma = 1 }\n", "takes no ':TEST'"),
    ("", "expected a [targets] table"),
])
def test_bad_targets_exit_2_with_one_line(work, text, expect):
    targets = write_targets(os.path.join(work, "bad-targets.toml"), text)
    r = calibrate(CONFIG, "--targets", targets, *PARAMS, "--out", os.path.join(work, "bad"))
    assert r.returncode == 2
    assert expect in r.stderr, r.stderr
    assert r.stderr.count("\n") == 1


def _index(folder, rows):
    import csv
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, "index.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["test", "status", "final_eta", "reason"])
        w.writeheader()
        w.writerows(rows)
    return folder


def test_a_test_that_left_its_path_measures_nothing_and_leaves_only_its_targets_surrogate(work):
    """A run whose target test the watchdog failed gives NaN for that target (never its off-path value),
    its other targets stay; the surrogate is fit on the runs that measured it, exactly (a quadratic
    through noise-free quadratic data is recovered to round-off: 1e-9), and fewer runs than the
    surrogate's coefficients stop the calibration with exit 1 naming the target and the count."""
    import numpy as np
    from sandcell_analysis import calibrate as cal
    folder = _index(os.path.join(work, "measures"), [
        dict(test="a", status="done", final_eta="0.8", reason=""),
        dict(test="b", status="failed", final_eta="3.0", reason="b = 0.41 off its target 0.5")])
    m = cal.measures_of(folder, {"final_eta:a": None, "final_eta:b": None}, TRIAXIAL)
    assert m["final_eta:a"] == 0.8
    assert np.isnan(m["final_eta:b"])
    with pytest.raises(SystemExit):  # a test that is not in the run at all is a wrong target, not a failure
        cal.measures_of(folder, {"final_eta:c": None}, TRIAXIAL)

    rng = np.random.default_rng(1)
    u = rng.random((8, 2))
    truth = 0.3 + 0.2 * u[:, 0] - 0.1 * u[:, 1] + 0.05 * u[:, 0] * u[:, 1]
    ys = [{"t": float(v)} for v in truth]
    ys[3]["t"] = float("nan")
    ys[6]["t"] = float("nan")
    coef, s = cal.fit_surrogate(u[[0, 1, 2, 4, 5, 7]], truth[[0, 1, 2, 4, 5, 7]])
    got = cal.fit_targets(u, ys, {"t": (0.5, 0.1)}, need=6)["t"]
    assert np.allclose(got[0], coef, rtol=0, atol=1e-12)
    assert abs(cal.predict(got[0], u[3:4])[0] - truth[3]) < 1e-9
    with pytest.raises(SystemExit) as e:
        cal.fit_targets(u, ys, {"t": (0.5, 0.1)}, need=7)
    assert e.value.code == 1
