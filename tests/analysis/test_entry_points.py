"""The analysis commands run as `python -m sandcell_analysis COMMAND` (what `triaxial COMMAND` runs):
no script patches sys.path; the app finds the package beside its installed binary
(<prefix>/share/sandcell) or in its source tree (apps/analysis) and passes it in PYTHONPATH. With
$SANDCELL_BUILD_DIR (set by ctest, analysis.entry_points), the real install: `cmake --install` into a
temporary prefix, then `<prefix>/bin/triaxial analyze` on synthetic results."""
import os
import subprocess
import sys

import numpy as np
import pytest

from helpers import ANALYSIS, caricature, write_results

PACKAGE = os.path.join(ANALYSIS, "sandcell_analysis")
# No PYTHONPATH: the app must hand the package to Python by itself.
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}


def shear_file(folder, name="p-b0.00-p0_500kPa", b=0.0):
    path = os.path.join(folder, name + ".h5")
    write_results(path, caricature(0.5e6, b, rng=np.random.default_rng(1)),
                  {"job": name.encode(), "stage": b"shear", "path": b"constant_p", "b": str(b).encode(),
                   "p0": "500000"})
    return path


def test_no_entry_point_patches_sys_path():
    """The package's modules and the app's directory hold no sys.path shim (the issue of the shims:
    five copies of the same search); the tests' conftest is the one place that sets the path."""
    apps = os.path.join(ANALYSIS, "..", "triaxial")
    assert not [f for f in os.listdir(apps) if f.endswith(".py")]
    for f in os.listdir(PACKAGE):
        if f.endswith(".py"):
            assert "sys.path.insert" not in open(os.path.join(PACKAGE, f)).read(), f


@pytest.mark.skipif(not os.environ.get("SANDCELL_BUILD_DIR"), reason="needs $SANDCELL_BUILD_DIR (ctest)")
def test_cmake_install_then_triaxial_analyze(tmp_path):
    prefix = tmp_path / "prefix"
    r = subprocess.run(["cmake", "--install", os.environ["SANDCELL_BUILD_DIR"], "--prefix", str(prefix)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    share = prefix / "share" / "sandcell"
    assert (share / "sandcell_analysis" / "__main__.py").is_file()
    assert (share / "sandcell_analysis" / "analyze.py").is_file()
    assert not (share / "sandcell_analysis" / "__pycache__").exists()
    assert not list(share.glob("*.py"))  # no scripts beside the package
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    for b in (0.0, 0.5, 1.0):
        shear_file(str(run_dir), f"p-b{b:.2f}-p0_500kPa", b)
    r = subprocess.run([str(prefix / "bin" / "triaxial"), "analyze", str(run_dir), "--out", str(tmp_path / "out")],
                       capture_output=True, text=True, timeout=300, env=ENV)
    assert r.returncode == 0, r.stderr
    assert os.path.getsize(tmp_path / "out" / "report.md") > 1000
    r = subprocess.run([str(prefix / "bin" / "triaxial"), "analyze", str(tmp_path / "out" / "report.md")],
                       capture_output=True, text=True, timeout=60, env=ENV)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "cannot read" in r.stderr, r.stderr
    r = subprocess.run([str(prefix / "bin" / "triaxial"), "analyze", "--help"], capture_output=True, text=True,
                       timeout=60, env=ENV)
    assert r.returncode == 0 and "usage: triaxial analyze" in r.stdout, r.stdout


# python -m sandcell_analysis: every command of the package, with PYTHONPATH=apps/analysis (or installed).
MODULE_ENV = dict(ENV, PYTHONPATH=os.path.abspath(os.path.join(PACKAGE, "..")))
COMMANDS = ("analyze", "study", "calibrate", "localization", "plot", "replay-critical", "campaign-table")


def run_module(*args, cwd):
    return subprocess.run([sys.executable, "-m", "sandcell_analysis", *args], capture_output=True, text=True,
                          timeout=300, env=MODULE_ENV, cwd=cwd)


def test_module_help_lists_every_command(tmp_path):
    r = run_module("--help", cwd=str(tmp_path))
    assert r.returncode == 0 and r.stdout.startswith("usage: python -m sandcell_analysis COMMAND"), r.stderr
    for command in COMMANDS:
        assert f"\n  {command} " in r.stdout, command
        h = run_module(command, "--help", cwd=str(tmp_path))
        assert h.returncode == 0 and f"sandcell_analysis {command}" in h.stdout, (command, h.stderr)
    r = run_module(cwd=str(tmp_path))  # no command: the usage on stderr, exit 2
    assert r.returncode == 2 and "COMMAND" in r.stderr
    r = run_module("nope", cwd=str(tmp_path))
    assert r.returncode == 2 and "unknown command 'nope'" in r.stderr


def test_module_dispatch_replay_critical_and_analyze(tmp_path):
    from sandcell_analysis import critical, results
    h5 = shear_file(str(tmp_path))
    r = run_module("replay-critical", h5, cwd=str(tmp_path))
    assert r.returncode == 0, r.stderr
    # the command's first critical row is critical.first_critical_row's, on results.read_columns' series
    s = results.read_columns(h5, ("strain", "p", "q", "e", "eps_q", "Z_mech", "fabric"))
    n = critical.first_critical_row(s["eps_q"], {"p": s["p"], "q": s["q"], "eta": s["q"] / s["p"], "e": s["e"],
                                                 "Z_mech": s["Z_mech"], "fabric": s["fabric"]})
    assert n is not None and f"critical (v3) at row {n}: " in r.stdout, r.stdout
    r = run_module("replay-critical", str(tmp_path / "missing.h5"), cwd=str(tmp_path))
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "cannot read" in r.stderr, r.stderr
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    for b in (0.0, 0.5, 1.0):
        shear_file(str(run_dir), f"p-b{b:.2f}-p0_500kPa", b)
    r = run_module("analyze", str(run_dir), "--out", str(tmp_path / "out"), cwd=str(tmp_path))
    assert r.returncode == 0, r.stderr
    assert os.path.getsize(tmp_path / "out" / "report.md") > 1000
