"""The critical-state test, Python (sandcell_analysis.critical) against its C++ twin
(apps/triaxial/protocol/critical.cpp, what the app applies while shearing with shear.stop_at_critical): on
the same series they must give the same verdict, the same rows in the window, the same changes over
it, and the same first row at which the test holds when it is applied after every row (the app's
stop).

The C++ side is tests/analysis/critical_twin.cpp, found through $SANDCELL_CRITICAL_TWIN (set by
ctest, analysis.critical_twin). Series: synthetic ones (stationary with fluctuations, drifts of
each quantity beyond the tolerance, short tests, sparse and gapped windows, a test that settles
midway) and, with $SANDCELL_TWIN_RESULTS naming run folders (separated by ':'; ctest: the small
campaign of analysis.campaign_run and the stop_at_critical one of analysis.campaign_stop_run), the
shear tests of those runs; where a run's index.csv says a test stopped at the critical state, both
must put that stop at the file's last row.
"""
import math
import os
import subprocess

import numpy as np
import pytest

from sandcell_analysis import critical, results

TWIN = os.environ.get("SANDCELL_CRITICAL_TWIN")
RUNS = [d for d in os.environ.get("SANDCELL_TWIN_RESULTS", "").split(os.pathsep) if d]
W, PRE = critical.APP_CRITERION["window"], critical.APP_CRITERION["pre_strain"]


def make(d_eta=0.0, d_p=0.0, d_e=0.0, noise=(0.0, 0.0, 0.0), end=0.3, step=0.0005):
    """As tests/apps/test_critical.cpp: eta = M (1 + d_eta u + n_q sin 1.7k), p = p0 (1 + d_p u +
    n_p sin(2.3k + 1)), e = e0 + d_e u + n_e sin(3.1k + 2), u = (eps1 - end) / W: d_* is the drift
    over the last window."""
    k = np.arange(int(round(end / step)) + 1)
    eps1 = step * k
    u = (eps1 - end) / W
    eta = 0.93 * (1.0 + d_eta * u + noise[0] * np.sin(1.7 * k))
    p = 0.5e6 * (1.0 + d_p * u + noise[1] * np.sin(2.3 * k + 1.0))
    e = 0.74 + d_e * u + noise[2] * np.sin(3.1 * k + 2.0)
    return eps1, p, eta * p, e


def settling(rng):
    """A dense test: a peak of eta, then softening and dilation that settle exponentially, with
    DEM-like noise; it becomes critical part-way."""
    eps1 = np.linspace(0.0, 0.3, 601)
    eta = 0.95 * (1.0 + 0.4 * np.exp(-eps1 / 0.04) * (1.0 - np.exp(-eps1 / 0.004)))
    eta = eta * (1.0 + rng.normal(0.0, 0.02, eps1.size))
    p = 0.5e6 * (1.0 + rng.normal(0.0, 0.005, eps1.size))
    e = 0.74 - 0.12 * np.exp(-eps1 / 0.05) + rng.normal(0.0, 5e-4, eps1.size)
    return eps1, p, eta * p, e


def synthetic():
    rng = np.random.default_rng(2026)
    out = {
        "straight drifts inside the tolerances": make(0.015, -0.01, 0.003),
        "stationary, q fluctuating 8 %": make(noise=(0.04, 0.01, 0.002)),
        "eta drifting 3 %": make(d_eta=0.03, noise=(0.04, 0.01, 0.002)),
        "p drifting 3 %": make(d_p=0.03, noise=(0.01, 0.01, 0.0)),
        "e drifting 0.008": make(d_e=0.008, noise=(0.01, 0.0, 0.002)),
        "ended at 8 %": make(end=0.08),
        "sparse: 6 rows in the window": make(step=0.01),
    }
    eps1, p, q, e = make()
    keep = (eps1 < 0.2499) | (eps1 > 0.265)  # the window's first 30 % missing: covered < 90 %
    out["gap in the window"] = tuple(a[keep] for a in (eps1, p, q, e))
    eps1, p, q, e = make()
    keep = (eps1 < 0.26) | (eps1 > 0.27)  # a gap, but the window still covered: accepted
    out["gap, window still covered"] = tuple(a[keep] for a in (eps1, p, q, e))
    for k in range(6):
        out[f"settling test {k}"] = settling(rng)
    return out


def run_twin(series, tmp_path):
    """The C++ twin's (reached, rows, change_eta, change_p, change_e, first_row) per series."""
    path = tmp_path / "series.csv"
    with open(path, "w") as f:
        f.write("series,eps1,p,q,e\n")
        for i, (eps1, p, q, e) in enumerate(series.values()):
            for row in zip(eps1, p, q, e):
                f.write(f"{i}," + ",".join(repr(float(v)) for v in row) + "\n")  # repr: exact round trip
    proc = subprocess.run([TWIN, str(path)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    out = {}
    for line in proc.stdout.split("\n"):
        if line.strip():
            i, reached, rows, ce, cp, cv, first = line.split()
            out[int(i)] = (reached == "1", int(rows), float(ce), float(cp), float(cv), int(first) or None)
    return [out[i] for i in range(len(series))]


def python_side(eps1, p, q, e):
    cols = {"p": p, "q": q, "eta": q / p, "e": e}  # the app's eta is q/p of its rows
    r = critical.detect_critical(eps1, cols, **critical.APP_CRITERION)
    return r, critical.first_critical_row(eps1, cols)


def covered(eps1):
    """The window tests of the app (length, rows, coverage): passed, the changes are computed."""
    end = eps1[-1]
    sel = eps1 >= end - W
    return end >= W + PRE and sel.sum() >= 10 and eps1[-1] - eps1[sel][0] >= 0.9 * W


def assert_agree(name, series, twin):
    eps1, p, q, e = series
    r, first = python_side(eps1, p, q, e)
    reached, rows, ce, cp, cv, first_cpp = twin
    assert r["reached"] == reached, f"{name}: Python {r['reached']} ({r['reasons']}), C++ {reached}"
    assert r["rows"] == rows, f"{name}: rows in the window, Python {r['rows']}, C++ {rows}"
    assert first == first_cpp, f"{name}: first critical row, Python {first}, C++ {first_cpp}"
    if covered(eps1):
        # Both are the least-squares slope of the same doubles (numpy's lstsq against centred sums):
        # they differ by round-off, ~1e-13 relative for windows of 10-1000 rows at eps1 ~ 0.3; 1e-9
        # relative leaves room for that and is far below what another window or formula would
        # change (one row more or less moves a change by ~1e-3 relative).
        for key, cpp in (("eta", ce), ("p", cp), ("e", cv)):
            py = r["checks"][key]["measure"]
            assert math.isclose(py, cpp, rel_tol=1e-9, abs_tol=1e-15), f"{name}: change of {key} {py} vs {cpp}"
    return r["reached"], first


needs_twin = pytest.mark.skipif(not TWIN, reason="needs $SANDCELL_CRITICAL_TWIN (ctest analysis.critical_twin)")


@needs_twin
def test_synthetic_series_agree(tmp_path):
    series = synthetic()
    verdicts = {}
    for (name, s), twin in zip(series.items(), run_twin(series, tmp_path)):
        verdicts[name] = assert_agree(name, s, twin)
    # The set exercises both verdicts and the stop part-way (else agreement would prove little).
    assert verdicts["straight drifts inside the tolerances"][0] and verdicts["stationary, q fluctuating 8 %"][0]
    for name in ("eta drifting 3 %", "p drifting 3 %", "e drifting 0.008", "ended at 8 %",
                 "sparse: 6 rows in the window", "gap in the window"):
        assert not verdicts[name][0], name
    assert verdicts["gap, window still covered"][0]
    n = len(synthetic()["settling test 0"][0])
    stops = [verdicts[f"settling test {k}"][1] for k in range(6)]
    assert all(s is not None and 0.1 / 0.3 * n < s < n for s in stops), stops


@needs_twin
@pytest.mark.skipif(not RUNS, reason="needs $SANDCELL_TWIN_RESULTS, run folders (ctest: the small campaigns)")
def test_run_series_agree_and_match_the_app_stops(tmp_path):
    series, stopped = {}, {}
    for run in RUNS:
        index = results.read_index(run)
        assert index, f"no index.csv rows in {run}"
        for row in index:
            path = os.path.join(run, row["file"])
            t, why = results.read_test(path)
            assert t is not None, f"{path}: {why}"
            series[path] = (t["eps1"], t["p"], t["q"], t["e"])
            stopped[path] = "critical" in row["status"]
    for (path, s), twin in zip(series.items(), run_twin(series, tmp_path)):
        reached, first = assert_agree(path, s, twin)
        if stopped[path]:
            # The app stopped after the row at which its test first held: the file's last row.
            assert first == len(s[0]) and reached, f"{path}: the app stopped at row {len(s[0])}, replay {first}"
    # The stop_at_critical campaign (deterministic: fixed seed, bitwise reproducible engine) has
    # tests that stop and tests that do not: both cases are compared.
    assert any(stopped.values()) and not all(stopped.values()), stopped
