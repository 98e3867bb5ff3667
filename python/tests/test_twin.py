"""The app's test written in Python (examples/triaxial_default.py, two stage loops over
sandcell.Protocol) against the app itself (`triaxial`), on small configs of the app's form: the
default path (small.toml, constant p) and the undrained and cyclic paths chosen from TOML
(small-undrained.toml, small-cyclic.toml):
the prepared sample (a checkpoint: every particle and contact array, the cell, the clock) and the
shear results file (every /series dataset but wall_time, every snapshot array and attribute) are
compared bit for bit."""
import os
import subprocess
import sys

import h5py
import numpy as np
import pytest

import sandcell as sc

HERE = os.path.dirname(os.path.abspath(__file__))
EXAMPLE = os.path.join(HERE, "..", "examples", "triaxial_default.py")
CASES = {"small.toml": "p-b0.50-p0_500kPa", "small-undrained.toml": "u-p0_500kPa", "small-cyclic.toml": "cyc-p0_500kPa"}


def datasets(group, prefix=""):
    out = {}
    for key, item in group.items():
        if isinstance(item, h5py.Dataset):
            out[prefix + key] = item[()]
        else:
            out.update(datasets(item, prefix + key + "/"))
    return out


def attributes(group, prefix=""):
    out = {prefix: dict(group.attrs)}
    for key, item in group.items():
        if isinstance(item, h5py.Group):
            out.update(attributes(item, prefix + key + "/"))
    return out


# Under the sanitizers the engine runs ~30x slower; there small.toml stands for the three (the paths'
# own code runs under them in test_paths.py).
@pytest.fixture(scope="module", params=[c if c == "small.toml" else pytest.param(c, marks=pytest.mark.whole_app)
                                        for c in sorted(CASES)])
def runs(work_dir, request):
    app = os.environ.get("SANDCELL_TRIAXIAL")
    if not app:
        pytest.skip("SANDCELL_TRIAXIAL not set: the triaxial app was not built (SANDCELL_BUILD_APPS)")
    config = os.path.join(HERE, request.param)
    app_dir, py_dir = (os.path.join(work_dir, request.param, d) for d in ("app", "py"))
    os.makedirs(py_dir, exist_ok=True)
    subprocess.run([app, config, "--out", app_dir, "--overwrite", "--threads", "2"], check=True,
                   stdout=subprocess.DEVNULL)
    subprocess.run([sys.executable, EXAMPLE, config, py_dir], check=True)
    return app_dir, py_dir, CASES[request.param]


def test_prepared_sample_is_bitwise_the_apps(runs):
    app, py = (h5py.File(os.path.join(d, "sample-p0_500kPa.h5")) for d in runs[:2])
    a, b = datasets(app), datasets(py)
    arrays = [k for k in a if k.startswith(("particles/", "contacts/"))]
    assert len(arrays) >= 20  # every particle and contact field of the registry
    for k in arrays:
        assert a[k].dtype == b[k].dtype and np.array_equal(a[k], b[k]), k
    for group in ("cell", "clock"):
        for key, value in app[group].attrs.items():
            assert np.array_equal(value, py[group].attrs[key]), (group, key)
    assert a["extra/doubles/e0"][0] == b["extra/doubles/e0"][0]


def test_shear_results_are_bitwise_the_apps(runs):
    app, py = (h5py.File(os.path.join(d, runs[2] + ".h5")) for d in runs[:2])
    a, b = datasets(app), datasets(py)
    assert sorted(a) == sorted(b)
    series = [k for k in a if k.startswith("series/")]
    assert len(series) == 41 and a["series/step"].size > 10
    for k in a:
        if k == "series/wall_time":
            continue  # the one value that is the clock on the wall, not the simulation
        assert a[k].dtype == b[k].dtype and np.array_equal(a[k], b[k]), k
    # Units, the snapshots' attributes, the root attributes (config text, job, stage, path, b, p0).
    aa, ab = attributes(app), attributes(py)
    assert sorted(aa) == sorted(ab)
    for group in aa:
        for key, value in aa[group].items():
            assert np.array_equal(value, ab[group][key]), (group, key)
    for k in series:
        assert app[k].attrs["units"] == py[k].attrs["units"], k


def test_the_apps_results_verify(runs):
    # sandcell.verify re-runs the app's test from its run record: bitwise, on another thread count.
    verified, message = sc.verify(os.path.join(runs[0], runs[2] + ".h5"), threads=1,
                                  triaxial=os.environ["SANDCELL_TRIAXIAL"])
    assert verified, message
    assert message.startswith("verified: rows 0..")
    # The Python twin's file holds the same run record: it verifies too (its sample beside it).
    verified, message = sc.verify(os.path.join(runs[1], runs[2] + ".h5"), rows=(0, 3),
                                  triaxial=os.environ["SANDCELL_TRIAXIAL"])
    assert verified, message
