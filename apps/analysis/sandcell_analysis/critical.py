"""The critical-state test: ONE implementation, used by `triaxial analyze` and checked against the
app's C++ twin (apps/triaxial/protocol/critical.cpp, applied while shearing with shear.stop_at_critical) by
tests/analysis/test_critical_twin.py."""
import math

import numpy as np

from .fitting import NAN
from .m_theta import b_of_stress, lode_from_b


def detect_critical(eps1, series, window=0.05, tol_eta=0.02, tol_p=0.02, tol_e=0.005,
                    tol_epsv=0.005, pre_strain=0.05, min_points=10):
    """Critical-state test on the last `window` of axial strain.

    series: dict with arrays p, q, eta, e, eps_v (and optionally b, theta, and stress [n, 6]:
    xx yy zz xy xz yz), same length as eps1. A tolerance of None leaves its quantity untested.
    Returns a dict: reached (bool), reasons (list of failed criteria), checks (per quantity: slope,
    change over the window, the measure compared, tolerance, ok), point (window means of p, q,
    eta, e, eps_v, M = mean q / mean p, and b, theta of the window-mean stress when stress is
    given, else the rows' means; b_rows, theta_rows: the rows' means), window [from, to], rows.
    """
    eps1 = np.asarray(eps1, float)
    end = float(np.nanmax(eps1)) if eps1.size else NAN
    sel = eps1 >= end - window
    rows = int(np.sum(sel))
    out = {"reached": False, "reasons": [], "checks": {}, "point": {}, "rows": rows,
           "window": [end - window, end]}
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
    point = {}
    for k in ("p", "q", "eta", "e", "b", "theta", "eps_v"):
        if k in series and rows:
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
    stress = np.asarray(series["stress"], float)[sel] if "stress" in series and rows else None
    if stress is not None and stress.ndim == 2 and stress.shape[1] == 6 and np.isfinite(stress).all():
        point["b_rows"], point["theta_rows"] = point["b"], point["theta"]
        point["b"] = float(b_of_stress(stress.mean(axis=0)))
        point["theta"] = float(lode_from_b(point["b"]))
    out["point"] = point
    for name, tol, relative in (("eta", tol_eta, True), ("p", tol_p, True),
                                ("e", tol_e, False), ("eps_v", tol_epsv, False)):
        if tol is None:  # not tested (the app's criterion has no eps_v: APP_CRITERION)
            continue
        y = np.asarray(series[name], float)[sel] if name in series else np.array([])
        x = eps1[sel]
        good = np.isfinite(y)
        if good.sum() < 3 or np.ptp(x[good]) <= 0:
            out["checks"][name] = {"slope": NAN, "change": NAN, "se_change": NAN,
                                   "measure": NAN, "tol": tol, "relative": relative, "ok": False}
            reasons.append(f"{name}: too few rows for a trend")
            continue
        xg, yg = x[good], y[good]
        slope, icpt = np.polyfit(xg, yg, 1)
        resid = yg - (slope * xg + icpt)
        sxx = float(np.sum((xg - xg.mean()) ** 2))
        se_slope = math.sqrt(float(resid @ resid) / (xg.size - 2) / sxx) if xg.size > 2 else NAN
        change = float(slope * window)
        mean = float(np.mean(yg))
        scale = abs(mean) if relative and mean != 0 else 1.0
        measure = abs(change) / scale
        se_measure = se_slope * window / scale
        ok = bool(measure <= tol)
        out["checks"][name] = {"slope": float(slope), "change": change,
                               "se_change": se_slope * window, "measure": measure,
                               "se_measure": se_measure, "tol": tol, "relative": relative,
                               "ok": ok}
        if not ok:
            unit = (f"{100 * measure:.1f} % (+- {100 * se_measure:.1f} %) > {100 * tol:g} %"
                    if relative else f"{measure:.4f} (+- {se_measure:.4f}) > {tol:g}")
            reasons.append(f"{name} changes over the window by {unit}")
    out["reached"] = not reasons
    return out


# The criterion the app applies while shearing (apps/triaxial/protocol/critical.hpp, CriticalTest's defaults):
# eta, p and e, not eps_v (|de| <= 0.005 bounds eps_v's change to 0.005 / (1 + e), see there).
APP_CRITERION = dict(window=0.05, tol_eta=0.02, tol_p=0.02, tol_e=0.005, tol_epsv=None, pre_strain=0.05,
                     min_points=10)


def first_critical_row(eps1, series, **criterion):
    """The app's stop: the test applied after every row, on the rows so far (as the app does with
    shear.stop_at_critical). Returns the number of rows n of the first prefix [0, n) that is
    critical, None if none is. `criterion`: detect_critical's keywords (default APP_CRITERION)."""
    kw = dict(APP_CRITERION, **criterion)
    eps1 = np.asarray(eps1, float)
    cols = {k: np.asarray(v, float) for k, v in series.items() if k in ("p", "q", "eta", "e", "eps_v")}
    for n in range(1, eps1.size + 1):
        if eps1[n - 1] < kw["window"] + kw["pre_strain"]:
            continue  # refused by the length test whatever the rest (a shortcut, same verdict)
        if detect_critical(eps1[:n], {k: v[:n] for k, v in cols.items()}, **kw)["reached"]:
            return n
    return None
