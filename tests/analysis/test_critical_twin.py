"""The critical-state test, Python (sandcell_analysis.critical, version 3) against its C++ twin
(apps/triaxial/protocol/critical.cpp, what the app applies while shearing with shear.stop_at_critical):
on the same series they must give the same verdict, the same rows in the window, the same changes,
standard errors and effective row counts over it, and the same first row at which the test holds
when it is applied after every row (the app's stop).

The C++ side is tests/analysis/critical_twin.cpp, found through $SANDCELL_CRITICAL_TWIN (set by
ctest, analysis.critical_twin). Series: synthetic ones (stationary with fluctuations, drifts of
each quantity beyond the tolerance, a drift the noise leaves unproven, a small drift in serially
correlated noise that version 3's short-window errors refuse and version 2 accepts, short tests,
sparse and gapped windows, tests that settle midway) and, with $SANDCELL_TWIN_RESULTS naming run folders
(separated by ':'; ctest: the small campaign of analysis.campaign_run and the stop_at_critical one of
analysis.campaign_stop_run), the shear tests of those runs with each run's own tolerances; where a
run's index.csv says a test stopped at the critical state, both must put that stop at the file's last
row.
"""
import math
import os
import subprocess
import tomllib

import numpy as np
import pytest

from helpers import ar1
from sandcell_analysis import critical, results

TWIN = os.environ.get("SANDCELL_CRITICAL_TWIN")
RUNS = [d for d in os.environ.get("SANDCELL_TWIN_RESULTS", "").split(os.pathsep) if d]
W, PRE = critical.APP_CRITERION["window"], critical.APP_CRITERION["pre_strain"]
KEYS = (("eta", "eta"), ("p", "p"), ("e", "e"), ("Z_mech", "z"), ("F_a", "fabric"))


def make(d_eta=0.0, d_p=0.0, d_e=0.0, d_z=0.0, d_fa=0.0, noise=(0.0, 0.0, 0.0), end=0.6, step=0.0005):
    """As tests/apps/test_critical.cpp: eta = M (1 + d_eta u + n_q sin 1.7k), p = p0 (1 + d_p u +
    n_p sin(2.3k + 1)), e = e0 + d_e u + n_e sin(3.1k + 2), Z = Z0 (1 + d_z u), F_a = F0 (1 + d_fa u),
    u = (eps_q - end) / W: d_* is the drift over the last window."""
    k = np.arange(int(round(end / step)) + 1)
    x = step * k
    u = (x - end) / W
    eta = 0.93 * (1.0 + d_eta * u + noise[0] * np.sin(1.7 * k))
    p = 0.5e6 * (1.0 + d_p * u + noise[1] * np.sin(2.3 * k + 1.0))
    e = 0.74 + d_e * u + noise[2] * np.sin(3.1 * k + 2.0)
    return x, p, eta * p, e, 4.1 * (1.0 + d_z * u), 0.45 * (1.0 + d_fa * u)


def settling(rng):
    """A dense test: a peak of eta, then softening, dilation, contacts and fabric that settle
    exponentially, with DEM-like noise; it becomes critical part-way."""
    x = np.linspace(0.0, 0.6, 1201)
    eta = 0.95 * (1.0 + 0.4 * np.exp(-x / 0.06) * (1.0 - np.exp(-x / 0.004)))
    eta = eta * (1.0 + rng.normal(0.0, 0.02, x.size))
    p = 0.5e6 * (1.0 + rng.normal(0.0, 0.005, x.size))
    e = 0.74 - 0.12 * np.exp(-x / 0.07) + rng.normal(0.0, 5e-4, x.size)
    z = 4.1 * (1.0 + 0.5 * np.exp(-x / 0.05)) * (1.0 + rng.normal(0.0, 0.003, x.size))
    fa = 0.45 * (1.0 - 0.6 * np.exp(-x / 0.06)) * (1.0 + rng.normal(0.0, 0.01, x.size))
    return x, p, eta * p, e, z, fa


def synthetic():
    rng = np.random.default_rng(2026)
    noise = (0.04, 0.005, 0.001)
    out = {
        "straight drifts inside the tolerances": make(0.015, -0.01, 0.003, 0.01, 0.03),
        "stationary, q fluctuating 8 %": make(noise=noise),
        "eta drifting 3 %": make(d_eta=0.03, noise=noise),
        "p drifting 3 %": make(d_p=0.03, noise=noise),
        "e drifting 0.008": make(d_e=0.008, noise=noise),
        "Z_mech drifting 3 %": make(d_z=0.03, noise=noise),
        "F_a drifting 8 %": make(d_fa=0.08, noise=noise),
        "eta drifting 1.5 % in noise of 16 %": make(d_eta=0.015, noise=(0.08, 0.005, 0.001)),
        "ended at eps_q 25 %": make(end=0.25),
        "sparse: 5 rows in the window": make(step=0.02),
    }
    full = make()
    keep = (full[0] < 0.4999) | (full[0] > 0.53)  # the window's first 30 % missing: covered < 90 %
    out["gap in the window"] = tuple(a[keep] for a in full)
    keep = (full[0] < 0.52) | (full[0] > 0.54)  # a gap, but the window still covered: accepted
    out["gap, window still covered"] = tuple(a[keep] for a in full)
    for k in range(4):
        out[f"settling test {k}"] = settling(rng)
    out["eta drifting 0.4 % in correlated noise"] = correlated(np.random.default_rng(42))
    return out


def correlated(rng):
    """Stationary but for eta: a drift of 0.4 % over the window in AR(1) noise of 0.4 % (lag-1
    coefficient 0.98 row to row): a window of 200 rows holding ~5 effective ones. With this seed
    version 2's bound is 0.99 % and version 3's 2.7 % (tolerance 2 %): far from either edge."""
    x, p, q, e, z, fa = make()
    return x, p, q * (1.0 + 0.004 * (x - x[-1]) / W + ar1(rng, x.size, 0.98, 0.004)), e, z, fa


def run_twin(series, tmp_path, settings=None):
    """The C++ twin's (reached, rows, {quantity: (change, se, n_eff)}, first_row) per series."""
    path = tmp_path / "series.csv"
    with open(path, "w") as f:
        f.write("series,eps_q,p,q,e,z_mech,fabric_anisotropy\n")
        for i, s in enumerate(series.values()):
            for row in zip(*s):
                f.write(f"{i}," + ",".join(repr(float(v)) for v in row) + "\n")  # repr: exact round trip
    args = [TWIN, str(path)] + ([repr(float(settings[k])) for k in ("window", "tol_eta", "tol_e", "tol_fabric")]
                                if settings else [])
    proc = subprocess.run(args, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    out = {}
    for line in proc.stdout.split("\n"):
        if line.strip():
            f = line.split()
            trends = {k: tuple(float(v) for v in f[3 + 3 * j:6 + 3 * j]) for j, (k, _) in enumerate(KEYS)}
            out[int(f[0])] = (f[1] == "1", int(f[2]), trends, int(f[18]) or None)
    return [out[i] for i in range(len(series))]


def criterion(settings):
    """detect_critical's keywords for the app's settings (one tolerance for eta, p and Z_mech)."""
    kw = dict(critical.APP_CRITERION)
    if settings:
        kw.update(window=settings["window"], tol_eta=settings["tol_eta"], tol_p=settings["tol_eta"],
                  tol_z=settings["tol_eta"], tol_e=settings["tol_e"], tol_fabric=settings["tol_fabric"])
    return kw


def python_side(s, settings=None):
    x, p, q, e, z, fa = s
    cols = {"p": p, "q": q, "eta": q / p, "e": e, "Z_mech": z, "F_a": fa}  # the app's eta is q/p of its rows
    kw = criterion(settings)
    return critical.detect_critical(x, cols, **kw), critical.first_critical_row(x, cols, **kw)


def covered(x, window):
    """The window tests of the app (length, rows, coverage): passed, the trends are computed."""
    end = x[-1]
    sel = x >= end - window
    return end >= window + PRE and sel.sum() >= 10 and x[-1] - x[sel][0] >= 0.9 * window


def assert_agree(name, s, twin, settings=None):
    r, first = python_side(s, settings)
    reached, rows, trends, first_cpp = twin
    assert r["reached"] == reached, f"{name}: Python {r['reached']} ({r['reasons']}), C++ {reached}"
    assert r["rows"] == rows, f"{name}: rows in the window, Python {r['rows']}, C++ {rows}"
    assert first == first_cpp, f"{name}: first critical row, Python {first}, C++ {first_cpp}"
    if covered(s[0], criterion(settings)["window"]):
        # Both are least-squares slopes, residual sums and lag products of the same doubles, summed
        # in another order: they differ by round-off, ~1e-13 relative for 10-1000 rows; 1e-9 leaves
        # room for that and is far below what another window or formula would change (one row more
        # or less moves a change by ~1e-3 relative). abs_tol 1e-12: a series without noise has a
        # standard error of pure round-off (1e-16 .. 1e-14, summed in another order), while the
        # smallest error that matters is ~1e-5 (a tolerance of 1e-3 over its 2 SE).
        for key, _ in KEYS:
            py = r["checks"][key]
            cpp_change, cpp_se, cpp_neff = trends[key]
            assert math.isclose(py["measure"], cpp_change, rel_tol=1e-9, abs_tol=1e-12), \
                f"{name}: change of {key} {py['measure']} vs {cpp_change}"
            assert math.isclose(py["se_measure"], cpp_se, rel_tol=1e-9, abs_tol=1e-12), \
                f"{name}: standard error of {key} {py['se_measure']} vs {cpp_se}"
            # n_eff: from the same r1, a ratio of residual sums, so the same round-off as above where
            # the residuals are noise; where they are round-off themselves (a noiseless series, SE
            # ~1e-16) r1 is a ratio of round-off and differs, but then k x SE is nil either way.
            if py["se_measure"] > 1e-12:
                assert math.isclose(py["n_eff"], cpp_neff, rel_tol=1e-9), \
                    f"{name}: effective rows of {key} {py['n_eff']} vs {cpp_neff}"
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
    for name in ("eta drifting 3 %", "p drifting 3 %", "e drifting 0.008", "Z_mech drifting 3 %", "F_a drifting 8 %",
                 "eta drifting 1.5 % in noise of 16 %", "ended at eps_q 25 %", "sparse: 5 rows in the window",
                 "gap in the window", "eta drifting 0.4 % in correlated noise"):
        assert not verdicts[name][0], name
    # ... the correlated one only by version 3's short-window errors: version 2 accepts it, so the
    # branch where the two versions differ is compared too.
    x, p, q, e, z, fa = series["eta drifting 0.4 % in correlated noise"]
    v2 = critical.detect_critical(x, {"p": p, "q": q, "eta": q / p, "e": e, "Z_mech": z, "F_a": fa},
                                  **critical.V2_DEFAULTS)
    assert v2["reached"] and v2["checks"]["eta"]["n_eff"] < 10, v2["checks"]["eta"]
    assert verdicts["gap, window still covered"][0]
    n = len(synthetic()["settling test 0"][0])
    stops = [verdicts[f"settling test {k}"][1] for k in range(4)]
    assert all(s is not None and (W + PRE) / 0.6 * n < s < n for s in stops), stops


def run_settings(run):
    """The run's critical-state settings, from its stored config (.config.toml)."""
    with open(os.path.join(run, ".config.toml"), "rb") as f:
        shear = tomllib.load(f).get("shear", {})
    return {"window": shear.get("critical_window", W), "tol_eta": shear.get("critical_tolerance", 0.02),
            "tol_e": shear.get("critical_tolerance_e", 0.005),
            "tol_fabric": shear.get("critical_tolerance_fabric", 0.05)}


@needs_twin
@pytest.mark.skipif(not RUNS, reason="needs $SANDCELL_TWIN_RESULTS, run folders (ctest: the small campaigns)")
def test_run_series_agree_and_match_the_app_stops(tmp_path):
    any_stop, any_run_on = False, False
    for run in RUNS:
        settings = run_settings(run)
        index = results.read_index(run)
        assert index, f"no index.csv rows in {run}"
        series, stopped = {}, {}
        for row in index:
            path = os.path.join(run, row["file"])
            cols = results.read_columns(path, ["eps_q", "p", "q", "e", "Z_mech", "fabric"])
            fa = critical.fabric_anisotropy(cols["fabric"])
            series[path] = (cols["eps_q"], cols["p"], cols["q"], cols["e"], cols["Z_mech"], fa)
            stopped[path] = "critical" in row["status"]
        for (path, s), twin in zip(series.items(), run_twin(series, tmp_path, settings)):
            reached, first = assert_agree(path, s, twin, settings)
            if stopped[path]:
                # The app stopped after the row at which its test first held: the file's last row.
                assert first == len(s[0]) and reached, f"{path}: the app stopped at row {len(s[0])}, replay {first}"
        any_stop = any_stop or any(stopped.values())
        any_run_on = any_run_on or not all(stopped.values())
    # The stop_at_critical campaign (deterministic: fixed seed, bitwise reproducible engine) has
    # tests that stop and tests that do not: both cases are compared.
    assert any_stop and any_run_on
