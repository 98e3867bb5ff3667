"""The critical state line e_c = e_Gamma - lambda (p_c/p_a)^xi (Li & Wang 1998) and its fit."""
import math

import numpy as np
from scipy import optimize

from .fitting import NAN, curve_fit, r_squared, standard_errors

PA = 101325.0  # reference pressure p_a, Pa

XI_BOUNDS = (0.05, 3.0)  # range of the CSL exponent xi in the fit


def csl_e(p, e_gamma, lam, xi, pa=PA):
    """Critical void ratio e_c(p) = e_Gamma - lambda (p/p_a)^xi (p in Pa)."""
    return e_gamma - lam * np.power(np.asarray(p, float) / pa, xi)


def distinct_levels(p, rel=0.1):
    """Number of distinct pressure levels (values closer than `rel` relative are one level)."""
    p = np.sort(np.asarray(p, float)[np.isfinite(p) & (np.asarray(p, float) > 0)])
    if p.size == 0:
        return 0
    return 1 + int(np.sum(np.diff(np.log(p)) > math.log1p(rel)))


def _per_group(keys, resid):
    out = []
    keys = np.round(np.asarray(keys, float), 3)
    for k in np.unique(keys[np.isfinite(keys)]):
        r = resid[keys == k]
        out.append({"b": float(k), "n": int(r.size), "mean": float(r.mean()),
                    "rms": float(np.sqrt(np.mean(r ** 2)))})
    return out


def fit_csl(p, e, b=None, xi=None, pa=PA):
    """Fit e_c = e_Gamma - lambda (p/p_a)^xi to critical points (p in Pa).

    Returns a dict: fitted, mode ("full", "xi fixed", "xi = 1 fallback"), note, params and stderr
    (e_gamma, lambda, xi), r2, R, rms, n, distinct_p, per_b residuals (when b is given).
    """
    p = np.asarray(p, float).ravel()
    e = np.asarray(e, float).ravel()
    bb = np.full(p.shape, NAN) if b is None else np.asarray(b, float).ravel()
    ok = np.isfinite(p) & np.isfinite(e) & (p > 0)
    p, e, bb = p[ok], e[ok], bb[ok]
    n = int(p.size)
    levels = distinct_levels(p)
    out = {"fitted": False, "mode": None, "note": "", "n": n, "distinct_p": levels,
           "params": {"e_gamma": NAN, "lambda": NAN, "xi": NAN},
           "stderr": {"e_gamma": NAN, "lambda": NAN, "xi": NAN},
           "r2": NAN, "R": NAN, "rms": NAN, "per_b": [], "p_range": [NAN, NAN],
           "xi_at_bound": False}
    if levels < 2:
        out["note"] = (f"not fitted: {n} critical point(s) at {levels} distinct p "
                       "(at least 2 distinct p are needed)")
        return out
    out["p_range"] = [float(p.min()), float(p.max())]
    x = p / pa

    def project(s):
        X = x ** s
        A = np.column_stack([np.ones(n), -X])
        coef = np.linalg.lstsq(A, e, rcond=None)[0]
        r = e - A @ coef
        return float(r @ r), coef

    if xi is None and levels >= 3 and n >= 4:
        grid = np.linspace(XI_BOUNDS[0], XI_BOUNDS[1], 60)
        ssr = [project(s)[0] for s in grid]
        i = int(np.argmin(ssr))
        lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
        res = optimize.minimize_scalar(lambda s: project(s)[0], bounds=(lo, hi),
                                       method="bounded", options={"xatol": 1e-12})
        xi0 = float(res.x) if project(res.x)[0] <= ssr[i] else float(grid[i])
        eg0, lam0 = project(xi0)[1]
        best = np.array([eg0, lam0, xi0])
        pcov = None
        try:
            popt, pcov = curve_fit(lambda pp, eg, lam, s: csl_e(pp, eg, lam, s, pa), p, e,
                                   p0=best, bounds=([-np.inf, -np.inf, XI_BOUNDS[0]],
                                                    [np.inf, np.inf, XI_BOUNDS[1]]),
                                   max_nfev=20000)
            if np.sum((e - csl_e(p, *popt, pa)) ** 2) <= project(xi0)[0] * (1 + 1e-9) + 1e-300:
                best = popt
        except (RuntimeError, ValueError):
            pass
        out["mode"] = "full"
        if not XI_BOUNDS[0] * 1.01 < best[2] < XI_BOUNDS[1] * 0.99:
            out["xi_at_bound"] = True
            out["note"] = (f"xi at its bound ({best[2]:.3g}): the points do not determine the "
                           "curvature of the CSL (try --fix-xi); the standard errors are not "
                           "meaningful")
        se = standard_errors(pcov, 3)
        if n <= 3:
            se[:] = NAN
        out["params"] = dict(zip(("e_gamma", "lambda", "xi"), map(float, best)))
        out["stderr"] = dict(zip(("e_gamma", "lambda", "xi"), map(float, se)))
    else:
        s = 1.0 if xi is None else float(xi)
        if xi is None:
            out["mode"] = "xi = 1 fallback"
            out["note"] = (f"xi fixed at 1 (fallback): {n} point(s) at {levels} distinct p; "
                           "fitting xi needs >= 3 distinct p and >= 4 points")
        else:
            out["mode"] = "xi fixed"
            out["note"] = f"xi fixed at {s:g} (--fix-xi)"
        eg0, lam0 = project(s)[1]
        best = np.array([eg0, lam0])
        pcov = None
        if n > 2:
            try:
                popt, pcov = curve_fit(lambda pp, eg, lam: csl_e(pp, eg, lam, s, pa), p, e,
                                       p0=best)
                best = popt
            except (RuntimeError, ValueError):
                pass
        se = standard_errors(pcov, 2)
        out["params"] = {"e_gamma": float(best[0]), "lambda": float(best[1]), "xi": s}
        out["stderr"] = {"e_gamma": float(se[0]), "lambda": float(se[1]), "xi": NAN}
    par = out["params"]
    resid = e - csl_e(p, par["e_gamma"], par["lambda"], par["xi"], pa)
    out["fitted"] = True
    out["residuals"] = resid.tolist()
    out["rms"] = float(np.sqrt(np.mean(resid ** 2)))
    out["r2"] = r_squared(e, resid)
    out["R"] = math.sqrt(out["r2"]) if np.isfinite(out["r2"]) and out["r2"] >= 0 else NAN
    out["per_b"] = _per_group(bb, resid)
    return out
