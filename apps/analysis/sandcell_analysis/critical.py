"""The critical-state test: ONE implementation, used by `triaxial analyze` and checked against the
app's C++ twin (apps/triaxial/protocol/critical.cpp, applied while shearing with shear.stop_at_critical) by
tests/analysis/test_critical_twin.py.

Version 2 (issue 45; the default until 2026-11-29), fixed before looking at any data:
  window variable x = eps_q (the series column "eps_q"), window W = 0.1, pre-strain P = 0.2: the
  test must reach x_end >= W + P (x_end = the largest x); the window is the rows with
  x >= x_end - W; it must hold >= 10 rows spanning >= 0.9 W.
  Quantities and tolerances: eta = q/p relative 0.02; p relative 0.02; e absolute 0.005; Z_mech
  relative 0.02; the fabric anisotropy F_a relative 0.05, F_a = sqrt(F':F'),
  F' = 15/2 (phi - tr(phi)/3 I), phi the series "fabric" (xx yy zz xy xz yz, the off-diagonal
  terms counted twice in F':F'). eps_v is not tested (de = -(1 + e) d eps_v: e's stationarity
  bounds it).
  For each quantity, over the window's rows (in series order, finite values only): the least-squares
  line y = a + s x; change = s W; r1 = the lag-1 autocorrelation of the residuals,
  sum(r_i r_{i-1}) / sum(r_i^2), clipped to [0, 0.99]; SE(s) = the OLS standard error
  sqrt(SSR / (n - 2) / Sxx) times sqrt((1 + r1) / (1 - r1)) (the rows of a DEM test are serially
  correlated: the effective sample size of an AR(1) series); measure = |change| / scale and
  se = SE(s) W / scale, scale = |window mean| (relative) or 1 (absolute); a quantity is steady iff
  measure + 2 se <= tol. Critical iff every quantity is steady and the length, rows and span
  conditions hold. A quantity the series does not record fails ("not recorded").
Version 3 (issue 45, the default since 2026-11-29; `detect_critical`): version 2 with one amendment for
  windows that hold few independent rows. n_eff = n (1 - r1) / (1 + r1), the window's effective row
  count; where n_eff < neff_min = 10 the bound is measure + k_short se, k_short = 6, instead of
  measure + 2 se. Why: on synthetic AR(1) series of known drift (experiments/2026-11-29-rule-check),
  the AR(1) SE above is 0.33-0.90 of the change's true standard deviation, the low end where the
  window holds ~6 effective rows (eta's windows in the 19,436-sphere study hold 1-7), and version 2
  then accepted 8.4 % of series drifting by 1.5 tolerances; with 6 SE below n_eff 10, at most 2.4 %
  (the criterion: at most 5 %, the band detector's false-positive bound; the amendment was chosen
  after a pilot run of the same grid had shown the SE short, and 6 = 2 / 0.33). Version 2 is
  `detect_critical(..., k_short=2.0)` (V2_DEFAULTS), kept to compare.
Why change + 2 SE and not the change alone: version 1 stopped each test at the first row whose
window passed; a line through noisy rows passes by chance at its first passage (48 of 50 stopped
tests of the 19,436-sphere campaign passed at >= 90 % of a tolerance). Requiring the change to be
below the tolerance by two standard errors makes a pass evidence of stationarity, not of noise.

Version 1 (`detect_critical_v1`, `first_critical_row(..., criterion="v1")`): the window in eps_1
(0.05, pre-strain 0.05), eta, p, e (and eps_v) by their change alone: the test the 2026-11-28
campaigns stopped on, kept to measure that stop's bias.
"""
import math

import numpy as np

from .fitting import NAN
from .m_theta import b_of_stress, lode_from_b

# The quantities of versions 2 and 3: (series key, tolerance keyword, relative?).
QUANTITIES = (("eta", "tol_eta", True), ("p", "tol_p", True), ("e", "tol_e", False),
              ("Z_mech", "tol_z", True), ("F_a", "tol_fabric", True))

V3_DEFAULTS = dict(window=0.1, pre_strain=0.2, min_points=10, tol_eta=0.02, tol_p=0.02, tol_e=0.005,
                   tol_z=0.02, tol_fabric=0.05, tol_epsv=None, neff_min=10.0, k_short=6.0)
# Version 2: two standard errors whatever the window's effective row count.
V2_DEFAULTS = dict(V3_DEFAULTS, k_short=2.0)
# detect_critical's keywords by version name (analyze's and replay-critical's --criterion).
CRITERIA = {"v3": V3_DEFAULTS, "v2": V2_DEFAULTS}


def effective_rows(n, r1):
    """The AR(1) effective row count of n serially correlated rows, r1 their lag-1 autocorrelation
    (scalars or arrays)."""
    return n * (1.0 - r1) / (1.0 + r1)


def errors_to_spare(n_eff, neff_min=V3_DEFAULTS["neff_min"], k_short=V3_DEFAULTS["k_short"]):
    """Standard errors a change must leave below its tolerance: 2, or k_short in a window of fewer
    than neff_min effective rows (version 3; k_short = 2 is version 2). Scalars or arrays."""
    return np.where(np.asarray(n_eff) >= neff_min, 2.0, k_short)


def fabric_anisotropy(fabric):
    """F_a = sqrt(F':F'), F' = 15/2 (phi - tr(phi)/3 I), of fabric tensors [..., 6] (xx yy zz xy
    xz yz; off-diagonals counted twice). F' is the deviatoric coefficient of the contact-normal
    density E(n) = (1 + F'_ij n_i n_j) / (4 pi), whose fabric tensor is phi = I/3 + 2/15 F' (tr
    phi = 1): 0 for an isotropic fabric; for phi = diag(a, c, c), F_a = 15/2 sqrt(2/3) (a - c)."""
    f = np.asarray(fabric, float)
    tr = f[..., 0] + f[..., 1] + f[..., 2]
    d = f[..., :3] - tr[..., None] / 3.0
    s = np.sum(d ** 2, axis=-1) + 2.0 * np.sum(f[..., 3:6] ** 2, axis=-1)
    return 7.5 * np.sqrt(s)


def trend(x, y, window):
    """The least-squares line of y against x with an AR(1)-corrected slope error.

    Returns (slope, se_slope, r1, n) over the finite pairs (series order kept: the residuals'
    lag-1 autocorrelation is over consecutive finite rows); NaN where fewer than 3 finite pairs or
    x does not vary."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    good = np.isfinite(x) & np.isfinite(y)
    xg, yg = x[good], y[good]
    n = int(xg.size)
    if n < 3 or np.ptp(xg) <= 0:
        return NAN, NAN, NAN, n
    xc = xg - xg.mean()
    yc = yg - yg.mean()
    sxx = float(xc @ xc)
    slope = float(xc @ yc) / sxx
    resid = yc - slope * xc
    ssr = float(resid @ resid)
    r1 = float(resid[1:] @ resid[:-1]) / ssr if ssr > 0 else 0.0
    r1 = min(max(r1, 0.0), 0.99)
    se = math.sqrt(ssr / (n - 2) / sxx) * math.sqrt((1.0 + r1) / (1.0 - r1))
    return slope, se, r1, n


def _point(series, sel, rows):
    point = {}
    for k in ("p", "q", "eta", "e", "b", "theta", "eps_v", "eps_q", "Z_mech", "F_a"):
        if k in series and series[k] is not None and rows:
            v = np.asarray(series[k], float)[sel]
            point[k] = float(np.nanmean(v)) if np.any(np.isfinite(v)) else NAN
        else:
            point[k] = NAN
    point["M"] = point["q"] / point["p"] if point.get("p") else NAN
    # b and theta of the mean stress state: the principal values of the window-mean stress tensor.
    # The mean of the rows' b is biased: each row's s1 >= s2 >= s3 are sorted, so at b = 0 the
    # fluctuations of s2 - s3 about zero all count as positive, and at b = 1 those of s1 - s2
    # (1,000-sphere tests: b 0.02-0.07 above 0, theta 0.8-3.5 deg; 0.04-0.09 below 1, theta
    # 2-4.6 deg below 60). q and p are invariants, unbiased row by row.
    stress = series.get("stress")
    stress = np.asarray(stress, float)[sel] if stress is not None and rows else None
    if stress is not None and stress.ndim == 2 and stress.shape[1] == 6 and np.isfinite(stress).all():
        point["b_rows"], point["theta_rows"] = point["b"], point["theta"]
        point["b"] = float(b_of_stress(stress.mean(axis=0)))
        point["theta"] = float(lode_from_b(point["b"]))
    return point


def with_fabric_anisotropy(series):
    """series with "F_a" added from "fabric" when it has one (a shallow copy)."""
    out = dict(series)
    fab = series.get("fabric")
    if "F_a" not in out and fab is not None:
        fab = np.asarray(fab, float)
        if fab.ndim == 2 and fab.shape[1] == 6:
            out["F_a"] = fabric_anisotropy(fab)
    return out


def detect_critical(x, series, window=0.1, tol_eta=0.02, tol_p=0.02, tol_e=0.005, tol_z=0.02,
                    tol_fabric=0.05, tol_epsv=None, pre_strain=0.2, min_points=10, neff_min=10.0, k_short=6.0):
    """Critical-state test version 3 on the last `window` of x (the deviatoric strain eps_q); version 2
    with k_short=2.0.

    series: dict with arrays p, q, eta, e and Z_mech, fabric ([n, 6]) or F_a (optionally eps_v, b,
    theta, stress [n, 6]), the same length as x. A tolerance of None leaves its quantity untested
    (tol_epsv: eps_v, absolute, untested by default).
    Returns a dict: reached (bool), reasons (failed criteria), checks (per quantity: slope, change
    over the window, se_change, r1, n_eff, k (2, or k_short where n_eff < neff_min), measure,
    se_measure, bound = measure + k se_measure, tol, relative, ok), point (window means of p, q, eta,
    e, eps_v, eps_q, Z_mech, F_a; M = mean q / mean p; b, theta of the window-mean stress tensor when
    stress is given, else the rows' means),
    window [from, to] in x, rows, variable ("eps_q"), criterion ("v3", or "v2" when k_short is 2).
    """
    x = np.asarray(x, float)
    series = with_fabric_anisotropy(series)
    end = float(np.nanmax(x)) if x.size and np.any(np.isfinite(x)) else NAN
    sel = x >= end - window
    rows = int(np.sum(sel))
    out = {"reached": False, "reasons": [], "checks": {}, "point": {}, "rows": rows,
           "window": [end - window, end], "variable": "eps_q",
           "criterion": "v2" if k_short == 2.0 else "v3"}
    reasons = out["reasons"]
    if x.size == 0 or not np.isfinite(end):
        reasons.append("no data")
        return out
    span = float(np.ptp(x[sel])) if rows else 0.0
    if end < window + pre_strain:
        reasons.append(f"test ended at eps_q = {100 * end:.1f} % < window + pre-strain "
                       f"= {100 * (window + pre_strain):.1f} %")
    if rows < min_points:
        reasons.append(f"{rows} rows in the window < {min_points}")
    if span < 0.9 * window:
        reasons.append(f"window covered over {100 * span:.2f} % < 90 % of {100 * window:g} % of eps_q")
    out["point"] = _point(series, sel, rows)
    tols = dict(tol_eta=tol_eta, tol_p=tol_p, tol_e=tol_e, tol_z=tol_z, tol_fabric=tol_fabric)
    quantities = list(QUANTITIES) + [("eps_v", "tol_epsv", False)]
    tols["tol_epsv"] = tol_epsv
    for name, key, relative in quantities:
        tol = tols[key]
        if tol is None:
            continue
        if series.get(name) is None:
            out["checks"][name] = {"slope": NAN, "change": NAN, "se_change": NAN, "r1": NAN, "n_eff": NAN, "k": NAN,
                                   "measure": NAN, "se_measure": NAN, "bound": NAN, "tol": tol, "relative": relative,
                                   "ok": False}
            reasons.append(f"{name}: not recorded in the series")
            continue
        y = np.asarray(series[name], float)[sel]
        slope, se_slope, r1, n = trend(x[sel], y, window)
        if not np.isfinite(slope):
            out["checks"][name] = {"slope": NAN, "change": NAN, "se_change": NAN, "r1": NAN, "n_eff": NAN, "k": NAN,
                                   "measure": NAN, "se_measure": NAN, "bound": NAN, "tol": tol, "relative": relative,
                                   "ok": False}
            reasons.append(f"{name}: too few rows for a trend")
            continue
        mean = float(np.nanmean(y))
        scale = abs(mean) if relative and mean != 0 else 1.0
        change = slope * window
        measure = abs(change) / scale
        se_measure = se_slope * window / scale
        n_eff = effective_rows(n, r1)
        k = float(errors_to_spare(n_eff, neff_min, k_short))
        bound = measure + k * se_measure
        ok = bool(bound <= tol)
        out["checks"][name] = {"slope": slope, "change": change, "se_change": se_slope * window, "r1": r1,
                               "n_eff": n_eff, "k": k, "measure": measure, "se_measure": se_measure, "bound": bound,
                               "tol": tol, "relative": relative, "ok": ok}
        if not ok:
            short = f" ({n_eff:.1f} effective rows < {neff_min:g})" if k != 2.0 else ""
            if relative:
                text = (f"{100 * measure:.2f} % + {k:g} x {100 * se_measure:.2f} %{short} = {100 * bound:.2f} % "
                        f"> {100 * tol:g} %")
            else:
                text = f"{measure:.4f} + {k:g} x {se_measure:.4f}{short} = {bound:.4f} > {tol:g}"
            reasons.append(f"{name} changes over the window by {text}")
    out["reached"] = not reasons
    return out


def detect_critical_v1(eps1, series, window=0.05, tol_eta=0.02, tol_p=0.02, tol_e=0.005,
                       tol_epsv=0.005, pre_strain=0.05, min_points=10):
    """Version 1 (the test of the 2026-11-28 campaigns, kept for the early stop's bias): the last
    `window` of axial strain; eta, p, e, eps_v by the change of their straight line alone (no
    standard error, no coordination or fabric). Returns detect_critical's dict (criterion "v1",
    variable "eps1")."""
    eps1 = np.asarray(eps1, float)
    end = float(np.nanmax(eps1)) if eps1.size else NAN
    sel = eps1 >= end - window
    rows = int(np.sum(sel))
    out = {"reached": False, "reasons": [], "checks": {}, "point": {}, "rows": rows,
           "window": [end - window, end], "variable": "eps1", "criterion": "v1"}
    reasons = out["reasons"]
    if eps1.size == 0:
        reasons.append("no data")
        return out
    span = float(np.ptp(eps1[sel])) if rows else 0.0
    if end < window + pre_strain:
        reasons.append(f"test ended at eps1 = {100 * end:.1f} % < window + pre-strain "
                       f"= {100 * (window + pre_strain):.1f} %")
    if rows < min_points:
        reasons.append(f"{rows} rows in the window < {min_points}")
    if span < 0.9 * window:
        reasons.append(f"window covered over {100 * span:.2f} % < 90 % of {100 * window:g} %")
    out["point"] = _point(series, sel, rows)
    for name, tol, relative in (("eta", tol_eta, True), ("p", tol_p, True),
                                ("e", tol_e, False), ("eps_v", tol_epsv, False)):
        if tol is None:
            continue
        y = np.asarray(series[name], float)[sel] if series.get(name) is not None else np.array([])
        if y.size != rows:
            y = np.full(rows, NAN)
        slope, se_slope, r1, n = trend(eps1[sel], y, window)
        if not np.isfinite(slope):
            out["checks"][name] = {"slope": NAN, "change": NAN, "se_change": NAN, "measure": NAN,
                                   "tol": tol, "relative": relative, "ok": False}
            reasons.append(f"{name}: too few rows for a trend")
            continue
        # version 1's plain OLS standard error (reported only)
        se_plain = se_slope / math.sqrt((1.0 + r1) / (1.0 - r1))
        mean = float(np.nanmean(y))
        scale = abs(mean) if relative and mean != 0 else 1.0
        change = slope * window
        measure = abs(change) / scale
        se_measure = se_plain * window / scale
        ok = bool(measure <= tol)
        out["checks"][name] = {"slope": slope, "change": change, "se_change": se_plain * window,
                               "measure": measure, "se_measure": se_measure, "tol": tol,
                               "relative": relative, "ok": ok}
        if not ok:
            unit = (f"{100 * measure:.1f} % (+- {100 * se_measure:.1f} %) > {100 * tol:g} %"
                    if relative else f"{measure:.4f} (+- {se_measure:.4f}) > {tol:g}")
            reasons.append(f"{name} changes over the window by {unit}")
    out["reached"] = not reasons
    return out


# The criterion the app applies while shearing (apps/triaxial/protocol/critical.hpp, CriticalTest's
# defaults): version 3 as above (eps_v untested).
APP_CRITERION = dict(V3_DEFAULTS)

# Version 1, the criterion of the 2026-11-28 campaigns' stop (eta, p, e over 5 % of eps_1).
APP_CRITERION_V1 = dict(window=0.05, tol_eta=0.02, tol_p=0.02, tol_e=0.005, tol_epsv=None, pre_strain=0.05,
                        min_points=10)


def first_critical_row(x, series, criterion="v3", **kw):
    """The app's stop: the test applied after every row, on the rows so far (as the app does with
    shear.stop_at_critical). x: eps_q for versions 3 and 2, eps_1 for version 1. Returns the number of
    rows n of the first prefix [0, n) that is critical, None if none is. `kw`: the test's keywords
    (default APP_CRITERION, V2_DEFAULTS with criterion="v2", APP_CRITERION_V1 with criterion="v1")."""
    if criterion == "v1":
        test, kw = detect_critical_v1, dict(APP_CRITERION_V1, **kw)
        keys = ("p", "q", "eta", "e", "eps_v")
    elif criterion in CRITERIA:
        test, kw = detect_critical, dict(CRITERIA[criterion], **kw)
        series = with_fabric_anisotropy(series)
        keys = ("p", "q", "eta", "e", "eps_v", "Z_mech", "F_a")
    else:
        raise ValueError(f"criterion must be 'v1', 'v2' or 'v3', got {criterion!r}")
    x = np.asarray(x, float)
    cols = {k: np.asarray(v, float) for k, v in series.items() if k in keys and v is not None}
    running = np.fmax.accumulate(np.where(np.isfinite(x), x, -np.inf)) if x.size else x
    for n in range(1, x.size + 1):
        if running[n - 1] < kw["window"] + kw["pre_strain"]:
            continue  # refused by the length test whatever the rest (a shortcut, same verdict)
        if test(x[:n], {k: v[:n] for k, v in cols.items()}, **kw)["reached"]:
            return n
    return None
