#!/usr/bin/env python3
"""Critical-state and dilatancy analysis of sandcell true-triaxial results.

    analyze.py RESULTS... [--out DIR] [options]

RESULTS are results files written by `triaxial` (<test>.h5) or directories holding them. From a
directory every *.h5 is read except sample-*.h5 and *.checkpoint.h5; files whose root attribute
`stage` is not "shear" (the preparation series) are skipped. Files of a running job can be read
(HDF5 file locking is switched off; the common length of the series is used).

Writes into --out: report.md (tables and verdicts against the study), summary.json (every fitted
number, machine-readable) and the figures, each as PNG and SVG:
  stress_strain-<path>-p0_<p0>kPa   q and eps_v against eps_1 for every b of one (path, p0)
  csl                                e against (p/p_a)^xi with the fitted critical state line
  pi_plane                           critical stress ratios and M(theta) in the deviatoric plane
  dilatancy-<path>                   d against eta for each b, data and model curves
Exit status: 0 done; 2 bad input (no files, a named file unreadable, no shear tests, bad option),
with one line on stderr; 1 numpy, scipy, matplotlib or h5py missing. A file found in a directory
that stays unreadable over three tries (a job may be creating it) is skipped with a warning.

Options (defaults)
  --out DIR          output folder (default: <DIR>/analysis for a single directory argument,
                     else ./analysis)
  --title TEXT       report and figure title ("sandcell critical-state analysis")
  --window W         critical-state window, axial strain at the end of each test (0.05)
  --pre-strain S     axial strain the test must have run before that window (0.05): a test ending
                     below W + S is never called critical (the peak and the softening come first)
  --min-points N     rows the window must hold (10)
  --tol-eta T        largest relative change of eta over the window (0.02)
  --tol-p T          largest relative change of p over the window (0.02)
  --tol-e T          largest absolute change of the void ratio over the window (0.005)
  --tol-epsv T       largest absolute change of eps_v over the window (0.005)
  --all              fit the CSL and M(theta) with the end-window points of every test, also those
                     that did not reach the critical state (marked in tables and figures)
  --fix-xi X         fit the CSL with xi fixed at X
  --smooth W         smoothing width for the dilatancy, axial strain (0.02)
  --min-strain S     dilatancy data start at eps_1 >= S (0.01: the elastic start is left out)
  --min-deq R        dilatancy data need d eps_q / d eps_1 >= R (0.1)
  --dilatancy-path P path whose b = 0 tests give d0, m and whose b > 0 tests give alpha, beta
                     (default: constant_p if it has b = 0 tests, else constant_sigma3)

Critical state (per test)
  Over the last W of eps_1, straight lines are fitted to eta, p, e and eps_v against eps_1; the
  change over the window predicted by each line (slope x W) must be below the tolerance: eta and p
  2 % of their window mean, e and eps_v 0.005. Why these: the stress ratio of a few-thousand-sphere
  DEM sample fluctuates by several per cent, and a line through ~100 rows averages that out, so a
  2 % trend is a real drift; 2 % of M is about 0.5 degree of friction angle, well inside the
  study's scatter. e and eps_v: the study's CSL spans about 0.03 in e over 0.5-16 MPa, so e_c must
  be stationary to a fraction of that (0.005 ~ 1/6); eps_v is tested too because it is measured
  directly (e also carries the solid-volume bookkeeping) and de = -(1+e) d eps_v. Besides, the
  window must be covered: at least --min-points rows spanning 90 % of W, and the test must have
  reached W + --pre-strain. The critical point is the window mean of p, q, eta, e and eps_v;
  M = mean q / mean p; b and theta are those of the window-mean stress tensor (the mean of the
  rows' b, from sorted principal stresses, is biased away from 0 and 1 by the fluctuations).

CSL: e_c = e_Gamma - lambda (p_c/p_a)^xi (Li & Wang 1998), p_a = 101.325 kPa, fitted by nonlinear
  least squares (the exact optimum over xi by variable projection, then scipy curve_fit from it for
  the covariance). Needs >= 3 distinct p (10 % apart) and >= 4 points; with 2 distinct p (or 3
  points) xi is fixed at 1 (fallback, marked); with 1 it is not fitted. Standard errors from the
  residual variance. R = sqrt(R^2). Residuals are also reported per b (uniqueness of the CSL).
M(theta) = M_c g(theta), g = 2K/((1+K) - (1-K) cos 3theta) (K = M_e/M_c, bounds 0.5..1; a convex
  surface needs K >= 7/9), fitted to q_c/p_c and theta_c. sin phi_c = 3M_c/(6+M_c),
  sin phi_e = 3M_e/(6-M_e).
Dilatancy d = d eps_v / d eps_q (compression positive: d < 0 is dilation). Total strain increments
  are used: on constant-p paths the elastic volumetric increment vanishes (p constant), so the
  total increment is a fair proxy of the plastic one; on other paths it is an approximation.
  Derivatives: Savitzky-Golay (2nd-order polynomial, first derivative) of eps_v, eps_q and eps_1
  against the row index over a window of --smooth axial strain (rows are written at a constant
  axial strain rate), d = (d eps_v/dk)/(d eps_q/dk); eta, p, e and theta are smoothed with the
  same filter; psi = e - e_c(p) with the fitted CSL (the study's CSL if none could be fitted,
  marked). Points with eps_1 < --min-strain or d eps_q/d eps_1 < --min-deq are dropped.
  Li & Dafalias (2000): d = d0/M (M exp(m psi) - eta), fitted on the b = 0 tests (M = M_c).
  3D, Li's form: d = d0/M_c (M_c g(theta) exp(m psi) - eta), d0 and m from b = 0.
  3D, g-dependent: d0(theta) = d0 g^-alpha, m(theta) = m g^beta (the study's exact expression is
  not available), alpha and beta fitted on the b > 0 tests of the same path.
"""
import os

os.environ["HDF5_USE_FILE_LOCKING"] = "FALSE"  # read files a running job is still writing

import argparse
import datetime
import json
import math
import sys
import time
import warnings

try:
    import numpy as np
    from scipy import optimize, signal, stats
except ImportError as _exc:  # run by an interpreter without the scientific stack
    if __name__ != "__main__":
        raise
    print(f"analyze.py: error: {_exc} (needs numpy, scipy, matplotlib and h5py; on Debian: "
          "apt install python3-numpy python3-scipy python3-matplotlib python3-h5py)",
          file=sys.stderr)
    sys.exit(1)

PA = 101325.0  # reference pressure p_a, Pa

# The study's numbers (docs/physics.md section 7), compared against in the report.
STUDY = {
    "e_gamma": 0.699, "lambda": 0.0002, "xi": 0.971, "R": 0.96,
    "phi_deg": 22.0, "d0": 0.619, "m": 4.570,
}

# Verdict criteria (also written into the report).
CRIT = {
    "csl_rel": 0.10,       # CSL parameter: within 2 SE or 10 % of the study's value
    "csl_curve": 0.01,     # CSL curve: |e_c - e_c,study| <= 0.01 over the tested p range
    "R_min": 0.92,         # fit quality: R >= 0.96 - 0.04
    "phi_tol_deg": 2.0,    # friction angle within 2 degrees of 22
    "dil_rel": 0.15,       # d0, m: within 2 SE or 15 %
    "rho": 0.8,            # trend: Spearman rho beyond +-0.8 in every (path, p0) group
    "csl_unique": 0.005,   # |mean CSL residual| of every b <= 0.005 (the e tolerance)
}

XI_BOUNDS = (0.05, 3.0)  # range of the CSL exponent xi in the fit

PATHS = ("constant_p", "constant_sigma3", "strain")
PATH_LABEL = {"constant_p": "constant p", "constant_sigma3": "constant sigma3", "strain": "strain"}
PATH_MARKER = {"constant_p": "o", "constant_sigma3": "s", "strain": "^"}
NAN = float("nan")


class InputError(Exception):
    """Bad input: reported as one line, exit status 2."""


# ---------------------------------------------------------------------------------------------
# Models (pure functions of numpy arrays)


def csl_e(p, e_gamma, lam, xi, pa=PA):
    """Critical void ratio e_c(p) = e_Gamma - lambda (p/p_a)^xi (p in Pa)."""
    return e_gamma - lam * np.power(np.asarray(p, float) / pa, xi)


def g_theta(theta, K):
    """g(theta) = 2K / ((1+K) - (1-K) cos 3theta): 1 in compression (0), K in extension (pi/3)."""
    c = np.cos(3.0 * np.asarray(theta, float))
    return 2.0 * K / ((1.0 + K) - (1.0 - K) * c)


def m_theta(theta, Mc, K):
    """Critical stress ratio M(theta) = M_c g(theta)."""
    return Mc * g_theta(theta, K)


def friction_angles(Mc, Me):
    """(phi_c, phi_e) in degrees from sin phi_c = 3M_c/(6+M_c), sin phi_e = 3M_e/(6-M_e)."""
    def angle(s):
        return math.degrees(math.asin(s)) if np.isfinite(s) and -1.0 <= s <= 1.0 else NAN
    sc = 3.0 * Mc / (6.0 + Mc) if np.isfinite(Mc) else NAN
    se = 3.0 * Me / (6.0 - Me) if np.isfinite(Me) and Me < 6.0 else NAN
    return angle(sc), angle(se)


def mohr_coulomb_M(theta, phi):
    """q/p on the Mohr-Coulomb surface of friction angle phi (rad) at Lode angle theta."""
    theta = np.asarray(theta, float)
    c1 = np.cos(theta)
    c3 = np.cos(theta - 4.0 * np.pi / 3.0)
    s = math.sin(phi)
    return 3.0 * s / (c1 - c3 - (c1 + c3) * s)


def lode_from_b(b):
    """Lode angle (0 compression, pi/3 extension) of a stress state with b = (s2-s3)/(s1-s3)."""
    b = np.asarray(b, float)
    return np.arctan2(np.sqrt(3.0) * b, 2.0 - b)


def b_of_stress(stress):
    """b = (s2 - s3)/(s1 - s3) of stress tensors given as [..., 6] (xx yy zz xy xz yz); NaN where
    s1 = s3."""
    m = np.asarray(stress, float)
    tensor = np.stack([np.stack([m[..., 0], m[..., 3], m[..., 4]], -1),
                       np.stack([m[..., 3], m[..., 1], m[..., 5]], -1),
                       np.stack([m[..., 4], m[..., 5], m[..., 2]], -1)], -2)
    s = np.linalg.eigvalsh(tensor)[..., ::-1]  # s1 >= s2 >= s3
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(s[..., 0] > s[..., 2], (s[..., 1] - s[..., 2]) / (s[..., 0] - s[..., 2]), NAN)


def dilatancy_li(eta, psi, M, d0, m):
    """Li & Dafalias (2000): d = d0/M (M exp(m psi) - eta)."""
    return d0 / M * (M * np.exp(m * np.asarray(psi, float)) - np.asarray(eta, float))


def dilatancy_li3d(eta, psi, theta, Mc, K, d0, m):
    """Li's 3D form: d = d0/M_c (M_c g(theta) exp(m psi) - eta)."""
    g = g_theta(theta, K)
    return d0 / Mc * (Mc * g * np.exp(m * np.asarray(psi, float)) - np.asarray(eta, float))


def dilatancy_g(eta, psi, theta, Mc, K, d0, m, alpha, beta):
    """g-dependent 3D form: d0 g^-alpha and m g^beta in Li's form."""
    g = g_theta(theta, K)
    return (d0 * g ** (-alpha) / Mc
            * (Mc * g * np.exp(m * g ** beta * np.asarray(psi, float)) - np.asarray(eta, float)))


# ---------------------------------------------------------------------------------------------
# Fits


def _stderr(pcov, k):
    if pcov is None:
        return np.full(k, NAN)
    pcov = np.asarray(pcov, float)
    if pcov.shape != (k, k) or not np.all(np.isfinite(pcov)):
        return np.full(k, NAN)
    d = np.diag(pcov)
    return np.where(d >= 0, np.sqrt(np.abs(d)), NAN)


def _curve_fit(f, x, y, p0, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return optimize.curve_fit(f, x, y, p0=p0, **kw)


def distinct_levels(p, rel=0.1):
    """Number of distinct pressure levels (values closer than `rel` relative are one level)."""
    p = np.sort(np.asarray(p, float)[np.isfinite(p) & (np.asarray(p, float) > 0)])
    if p.size == 0:
        return 0
    return 1 + int(np.sum(np.diff(np.log(p)) > math.log1p(rel)))


def _r2(y, resid):
    sst = float(np.sum((y - y.mean()) ** 2))
    ssr = float(np.sum(resid ** 2))
    if sst <= 0:
        return NAN
    return 1.0 - ssr / sst


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
            popt, pcov = _curve_fit(lambda pp, eg, lam, s: csl_e(pp, eg, lam, s, pa), p, e,
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
        se = _stderr(pcov, 3)
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
                popt, pcov = _curve_fit(lambda pp, eg, lam: csl_e(pp, eg, lam, s, pa), p, e,
                                        p0=best)
                best = popt
            except (RuntimeError, ValueError):
                pass
        se = _stderr(pcov, 2)
        out["params"] = {"e_gamma": float(best[0]), "lambda": float(best[1]), "xi": s}
        out["stderr"] = {"e_gamma": float(se[0]), "lambda": float(se[1]), "xi": NAN}
    par = out["params"]
    resid = e - csl_e(p, par["e_gamma"], par["lambda"], par["xi"], pa)
    out["fitted"] = True
    out["residuals"] = resid.tolist()
    out["rms"] = float(np.sqrt(np.mean(resid ** 2)))
    out["r2"] = _r2(e, resid)
    out["R"] = math.sqrt(out["r2"]) if np.isfinite(out["r2"]) and out["r2"] >= 0 else NAN
    out["per_b"] = _per_group(bb, resid)
    return out


def _propagate(f, x, cov):
    """Standard error of f(x) from the covariance of x (central differences)."""
    x = np.asarray(x, float)
    cov = np.asarray(cov, float)
    if not np.all(np.isfinite(cov)):
        return NAN
    grad = np.zeros_like(x)
    for i in range(x.size):
        h = 1e-6 * max(abs(x[i]), 1e-3)
        xp, xm = x.copy(), x.copy()
        xp[i] += h
        xm[i] -= h
        grad[i] = (f(xp) - f(xm)) / (2 * h)
    v = float(grad @ cov @ grad)
    return math.sqrt(v) if v >= 0 and np.isfinite(v) else NAN


def fit_m_theta(theta, M, k_bounds=(0.5, 1.0)):
    """Fit M(theta) = M_c g(theta; K) to critical stress ratios.

    Returns a dict: fitted (both M_c and K), note, params (M_c, K, M_e), stderr, phi_c_deg,
    phi_e_deg (and their stderr), K_at_bound, convex (K >= 7/9), K_mohr_coulomb (the K a
    Mohr-Coulomb surface of friction angle phi_c would give), rms, n.
    """
    theta = np.asarray(theta, float).ravel()
    M = np.asarray(M, float).ravel()
    ok = np.isfinite(theta) & np.isfinite(M)
    theta, M = theta[ok], M[ok]
    n = int(M.size)
    out = {"fitted": False, "note": "", "n": n,
           "params": {"M_c": NAN, "K": NAN, "M_e": NAN},
           "stderr": {"M_c": NAN, "K": NAN, "M_e": NAN},
           "phi_c_deg": NAN, "phi_e_deg": NAN, "se_phi_c_deg": NAN, "se_phi_e_deg": NAN,
           "K_at_bound": False, "convex": None, "K_mohr_coulomb": NAN, "rms": NAN,
           "K_bounds": list(k_bounds)}
    if n == 0:
        out["note"] = "not fitted: no critical points"
        return out
    c = np.cos(3 * theta)
    if n < 2 or np.ptp(c) < 0.3:
        mean = float(M.mean())
        se = float(M.std(ddof=1) / math.sqrt(n)) if n > 1 else NAN
        th = math.degrees(float(theta.mean()))
        out["note"] = (f"K not fitted: {n} critical point(s), all near theta = {th:.0f} deg "
                       "(points on both sides of theta = 30 deg are needed)")
        if np.mean(c) > 0:
            out["params"]["M_c"], out["stderr"]["M_c"] = mean, se
            out["phi_c_deg"] = friction_angles(mean, NAN)[0]
        else:
            out["params"]["M_e"], out["stderr"]["M_e"] = mean, se
            out["phi_e_deg"] = friction_angles(NAN, mean)[1]
        out["rms"] = float(np.sqrt(np.mean((M - mean) ** 2)))
        return out
    k0 = 0.5 * (k_bounds[0] + k_bounds[1])
    mc0 = float(np.mean(M / g_theta(theta, k0)))
    try:
        popt, pcov = _curve_fit(m_theta, theta, M, p0=[mc0, k0],
                                bounds=([1e-6, k_bounds[0]], [20.0, k_bounds[1]]))
    except (RuntimeError, ValueError) as exc:
        out["note"] = f"not fitted: {exc}"
        return out
    se = _stderr(pcov, 2)
    if n <= 2:
        se[:] = NAN
        pcov = np.full((2, 2), NAN)
    Mc, K = map(float, popt)
    out["fitted"] = True
    out["params"] = {"M_c": Mc, "K": K, "M_e": Mc * K}
    out["stderr"] = {"M_c": float(se[0]), "K": float(se[1]),
                     "M_e": _propagate(lambda v: v[0] * v[1], popt, pcov)}
    out["phi_c_deg"], out["phi_e_deg"] = friction_angles(Mc, Mc * K)
    out["se_phi_c_deg"] = _propagate(lambda v: friction_angles(v[0], NAN)[0], popt, pcov)
    out["se_phi_e_deg"] = _propagate(lambda v: friction_angles(NAN, v[0] * v[1])[1], popt, pcov)
    tol = 1e-3 * (k_bounds[1] - k_bounds[0])
    out["K_at_bound"] = bool(K <= k_bounds[0] + tol or K >= k_bounds[1] - tol)
    out["convex"] = bool(K >= 7.0 / 9.0)
    sphi = 3 * Mc / (6 + Mc)
    out["K_mohr_coulomb"] = (3 - sphi) / (3 + sphi)
    out["rms"] = float(np.sqrt(np.mean((M - m_theta(theta, Mc, K)) ** 2)))
    if out["K_at_bound"]:
        out["note"] = f"K at its bound ({K:.3f}); its standard error is not meaningful"
    return out


def fit_li_dafalias(eta, psi, d, M):
    """Fit d0, m of d = d0/M (M exp(m psi) - eta) with M given.

    Returns a dict: fitted, note, params (d0, m), stderr, mse, r2, n.
    """
    eta, psi, d = (np.asarray(a, float).ravel() for a in (eta, psi, d))
    ok = np.isfinite(eta) & np.isfinite(psi) & np.isfinite(d)
    eta, psi, d = eta[ok], psi[ok], d[ok]
    n = int(d.size)
    out = {"fitted": False, "note": "", "n": n, "M": float(M),
           "params": {"d0": NAN, "m": NAN}, "stderr": {"d0": NAN, "m": NAN},
           "mse": NAN, "r2": NAN}
    if not np.isfinite(M) or M <= 0:
        out["note"] = "not fitted: no critical stress ratio M"
        return out
    if n < 3:
        out["note"] = f"not fitted: {n} dilatancy point(s)"
        return out

    def project(m):
        f = np.exp(m * psi) - eta / M
        ff = float(f @ f)
        d0 = float(f @ d) / ff if ff > 0 else 0.0
        r = d - d0 * f
        return float(r @ r), d0

    grid = np.linspace(-20.0, 60.0, 321)
    with np.errstate(over="ignore", invalid="ignore"):
        ssr = np.array([project(m)[0] for m in grid])
    ssr[~np.isfinite(ssr)] = np.inf
    i = int(np.argmin(ssr))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    res = optimize.minimize_scalar(lambda m: project(m)[0], bounds=(lo, hi), method="bounded",
                                   options={"xatol": 1e-10})
    m0 = float(res.x) if project(res.x)[0] <= ssr[i] else float(grid[i])
    best = np.array([project(m0)[1], m0])
    pcov = None
    X = np.vstack([eta, psi])
    try:
        popt, pcov = _curve_fit(lambda X, d0, m: dilatancy_li(X[0], X[1], M, d0, m), X, d,
                                p0=best, maxfev=20000)
        if np.sum((d - dilatancy_li(eta, psi, M, *popt)) ** 2) <= project(m0)[0] * (1 + 1e-9):
            best = popt
    except (RuntimeError, ValueError):
        pass
    se = _stderr(pcov, 2)
    resid = d - dilatancy_li(eta, psi, M, *best)
    out.update(fitted=True, params={"d0": float(best[0]), "m": float(best[1])},
               stderr={"d0": float(se[0]), "m": float(se[1])},
               mse=float(np.mean(resid ** 2)), r2=_r2(d, resid))
    return out


def fit_g_form(eta, psi, theta, d, Mc, K, d0, m):
    """Fit alpha, beta of d = d0 g^-alpha / M_c (M_c g exp(m g^beta psi) - eta), the rest given.

    Returns a dict: fitted, note, params (alpha, beta), stderr, mse, mse_li3d (alpha = beta = 0),
    r2, n.
    """
    eta, psi, theta, d = (np.asarray(a, float).ravel() for a in (eta, psi, theta, d))
    ok = np.isfinite(eta) & np.isfinite(psi) & np.isfinite(theta) & np.isfinite(d)
    eta, psi, theta, d = eta[ok], psi[ok], theta[ok], d[ok]
    n = int(d.size)
    out = {"fitted": False, "note": "", "n": n, "params": {"alpha": NAN, "beta": NAN},
           "stderr": {"alpha": NAN, "beta": NAN}, "mse": NAN, "mse_li3d": NAN, "r2": NAN}
    if not all(np.isfinite(v) for v in (Mc, K, d0, m)):
        out["note"] = "not fitted: M_c, K, d0 or m missing"
        return out
    if n < 3:
        out["note"] = f"not fitted: {n} dilatancy point(s) at b > 0"
        return out
    g = g_theta(theta, K)
    if np.max(np.abs(np.log(g))) < 0.01:
        out["note"] = "not fitted: g(theta) = 1 at every point (alpha, beta not identifiable)"
        return out
    X = np.vstack([eta, psi, theta])

    def model(X, a, b):
        return dilatancy_g(X[0], X[1], X[2], Mc, K, d0, m, a, b)

    best, best_ssr, best_cov = None, np.inf, None
    for start in [(0, 0), (1, 0), (0, 1), (-1, 0), (0, -1), (2, 2), (-2, -2), (2, -2), (-2, 2)]:
        try:
            with np.errstate(over="ignore", invalid="ignore"):
                popt, pcov = _curve_fit(model, X, d, p0=start, bounds=([-20, -20], [20, 20]),
                                        maxfev=5000)
                ssr = float(np.sum((d - model(X, *popt)) ** 2))
        except (RuntimeError, ValueError):
            continue
        if np.isfinite(ssr) and ssr < best_ssr:
            best, best_ssr, best_cov = popt, ssr, pcov
    out["mse_li3d"] = float(np.mean((d - dilatancy_li3d(eta, psi, theta, Mc, K, d0, m)) ** 2))
    if best is None:
        out["note"] = "not fitted: the least-squares solver did not converge"
        return out
    se = _stderr(best_cov, 2)
    resid = d - model(X, *best)
    out.update(fitted=True, params={"alpha": float(best[0]), "beta": float(best[1])},
               stderr={"alpha": float(se[0]), "beta": float(se[1])},
               mse=float(np.mean(resid ** 2)), r2=_r2(d, resid))
    return out


# ---------------------------------------------------------------------------------------------
# Per-test analysis


def detect_critical(eps1, series, window=0.05, tol_eta=0.02, tol_p=0.02, tol_e=0.005,
                    tol_epsv=0.005, pre_strain=0.05, min_points=10):
    """Critical-state test on the last `window` of axial strain.

    series: dict with arrays p, q, eta, e, eps_v (and optionally b, theta, and stress [n, 6]:
    xx yy zz xy xz yz), same length as eps1.
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


def _savgol_window(n, rows, polyorder=2):
    w = int(round(rows))
    w = max(w, polyorder + 3)
    if w % 2 == 0:
        w += 1
    if w > n:
        w = n if n % 2 == 1 else n - 1
    return w if w >= polyorder + 2 else 0


def dilatancy_series(eps1, eps_v, eps_q, smooth=0.02, min_strain=0.01, min_deq=0.1,
                     others=None, polyorder=2, stress=None):
    """Dilatancy d = d eps_v / d eps_q from Savitzky-Golay derivatives.

    Derivatives against the row index over a window of `smooth` axial strain (converted to rows
    with the median axial strain increment per row); `others` (dict of arrays) are smoothed with
    the same window. Returns a dict: d, deq_de1, mask (points kept: eps1 >= min_strain and
    d eps_q/d eps1 >= min_deq), window_rows, and the smoothed `others`.
    stress ([n, 6]: xx yy zz xy xz yz), when given, is smoothed with the same window too, and b
    and theta are those of the smoothed tensor (keys b, theta; the smoothed rows' theta, if
    `others` has it, moves to theta_rows): as for the critical point (detect_critical), the
    rows' b is biased by the sorting of each row's principal stresses. The smoothed tensor is
    sorted too, so the bias shrinks with its noise rather than vanishing (about 4x smaller for a
    41-row window on the synthetic record of test_analyze.py).
    """
    eps1, eps_v, eps_q = (np.asarray(a, float) for a in (eps1, eps_v, eps_q))
    n = eps1.size
    out = {"d": np.full(n, NAN), "deq_de1": np.full(n, NAN), "mask": np.zeros(n, bool),
           "window_rows": 0}
    others = others or {}
    for k, v in others.items():
        out[k] = np.asarray(v, float).copy()
    step = float(np.median(np.abs(np.diff(eps1)))) if n > 1 else 0.0
    if step <= 0:
        return out
    w = _savgol_window(n, smooth / step, polyorder)
    if w == 0:
        return out
    out["window_rows"] = w
    dv = signal.savgol_filter(eps_v, w, polyorder, deriv=1)
    dq = signal.savgol_filter(eps_q, w, polyorder, deriv=1)
    d1 = signal.savgol_filter(eps1, w, polyorder, deriv=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = dq / np.abs(d1)
        d = dv / dq
    out["d"] = d
    out["deq_de1"] = ratio
    out["mask"] = (eps1 >= min_strain) & np.isfinite(d) & np.isfinite(ratio) & (ratio >= min_deq)
    idx = np.arange(n)
    for k, v in others.items():
        v = np.asarray(v, float)
        good = np.isfinite(v)
        if good.sum() >= n // 2 + 1:  # fill isolated gaps (e.g. theta at q = 0), then smooth
            v = np.interp(idx, idx[good], v[good])
            out[k] = signal.savgol_filter(v, w, polyorder)
    if stress is not None:
        st = np.asarray(stress, float)
        if st.ndim == 2 and st.shape == (n, 6) and np.isfinite(st).all():
            b = b_of_stress(signal.savgol_filter(st, w, polyorder, axis=0))
            if "theta" in out:
                out["theta_rows"] = out["theta"]
            out["b"] = b
            out["theta"] = lode_from_b(b)
    return out


def spearman(x, y):
    """Spearman rank correlation of finite pairs; NaN with < 3 distinct x or constant y."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if np.unique(np.round(x, 6)).size < 3 or np.ptp(y) == 0:
        return NAN
    return float(stats.spearmanr(x, y)[0])


def compare(value, se, ref, rel):
    """Verdict of a fitted value against the study's: within 2 standard errors or rel x |ref|.

    "not testable" when there is no value, or when the value is undetermined: 2 SE > |ref|, i.e.
    the data could not tell the study's value from zero (a degenerate fit must not pass)."""
    if not np.isfinite(value):
        return "not testable"
    if np.isfinite(se) and 2 * se > abs(ref):
        return "not testable"
    bound = rel * abs(ref)
    if np.isfinite(se):
        bound = max(bound, 2 * se)
    return "reproduced" if abs(value - ref) <= bound else "not reproduced"


# ---------------------------------------------------------------------------------------------
# Input


def _attr(f, key):
    v = f.attrs.get(key)
    if v is None:
        return None
    if isinstance(v, np.ndarray):
        v = v.item() if v.size == 1 else v.tolist()
    if isinstance(v, bytes):
        v = v.decode("utf-8", "replace")
    return v


def _float(v, default=NAN):
    try:
        return float(v)
    except (TypeError, ValueError):
        return default


def collect_files(inputs):
    """The .h5 files named or found in the input directories (sample and checkpoint files out).

    Returns a list of (path, named): named is False for a file found in a directory."""
    files, seen = [], set()
    for item in inputs:
        if os.path.isdir(item):
            for name in sorted(os.listdir(item)):
                if (not name.endswith(".h5") or name.startswith("sample-")
                        or name.endswith(".checkpoint.h5")):
                    continue
                path = os.path.join(item, name)
                if os.path.isfile(path) and os.path.realpath(path) not in seen:
                    seen.add(os.path.realpath(path))
                    files.append((path, False))
        elif os.path.isfile(item):
            if os.path.realpath(item) not in seen:
                seen.add(os.path.realpath(item))
                files.append((item, True))
        else:
            raise InputError(f"no such file or directory: {item}")
    if not files:
        raise InputError("no results files (*.h5) in " + ", ".join(inputs))
    return files


def read_test(path):
    """Read a results file. Returns (test dict, None) or (None, why it is not a shear test)."""
    import h5py
    try:
        f = h5py.File(path, "r")
    except Exception as exc:  # h5py raises OSError, sometimes others, for non-HDF5 files
        why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"cannot read {path}: {why}") from None
    try:
        with f:
            stage = _attr(f, "stage")
            if stage != "shear":
                return None, f"stage {stage!r}" if stage else "no 'stage' attribute"
            if "series" not in f:
                raise InputError(f"cannot read {path}: no /series group")
            s = f["series"]

            def get(name):
                return np.asarray(s[name][...], float) if name in s else None

            strain = get("strain")
            cols = {"p": get("p"), "q": get("q"), "e": get("e"), "eps_v": get("eps_v")}
            missing = [k for k, v in (("strain", strain), *cols.items()) if v is None]
            if missing:
                raise InputError(f"cannot read {path}: /series lacks {', '.join(missing)}")
            if strain.ndim != 2 or strain.shape[1] < 3:
                raise InputError(f"cannot read {path}: /series/strain is not [n, 3]")
            for name in ("eta", "theta", "b", "eps_q", "time", "stress"):
                cols[name] = get(name)
            ps = get("principal_stress")
            attrs = {k: _attr(f, k) for k in ("job", "path", "b", "p0")}
    except InputError:
        raise
    except Exception as exc:
        why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"cannot read {path}: {why}") from None
    if cols["stress"] is not None and (cols["stress"].ndim != 2 or cols["stress"].shape[1] != 6):
        cols["stress"] = None
    lengths = [strain.shape[0]] + [v.shape[0] for v in cols.values() if v is not None]
    if ps is not None and ps.ndim == 2 and ps.shape[1] == 3:
        lengths.append(ps.shape[0])
    else:
        ps = None
    n = min(lengths)
    strain = strain[:n, :3]
    cols = {k: (v[:n] if v is not None else None) for k, v in cols.items()}
    if cols["eta"] is None:
        with np.errstate(divide="ignore", invalid="ignore"):
            cols["eta"] = cols["q"] / cols["p"]
    if cols["eps_q"] is None:
        a, b_, c = strain[:, 0], strain[:, 1], strain[:, 2]
        cols["eps_q"] = math.sqrt(2) / 3 * np.sqrt((a - b_) ** 2 + (b_ - c) ** 2 + (c - a) ** 2)
    if ps is not None:
        ps = np.sort(ps[:n], axis=1)[:, ::-1]
        with np.errstate(divide="ignore", invalid="ignore"):
            if cols["b"] is None:
                cols["b"] = (ps[:, 1] - ps[:, 2]) / (ps[:, 0] - ps[:, 2])
            if cols["theta"] is None:
                cols["theta"] = lode_from_b(cols["b"])
    for k in ("b", "theta"):
        if cols[k] is None:
            cols[k] = np.full(n, NAN)
    eps1 = strain[:, 0]
    good = np.isfinite(eps1)
    for k in ("p", "q", "e", "eps_v", "eps_q"):
        good &= np.isfinite(cols[k])
    test = {k: v[good] for k, v in cols.items() if v is not None}
    test["eps1"] = eps1[good]
    test["strain"] = strain[good]
    name = attrs["job"] or os.path.splitext(os.path.basename(path))[0]
    path_kind = attrs["path"] or "unknown"
    test.update(file=path, name=str(name), path=str(path_kind), rows=int(np.sum(good)),
                b_nominal=_float(attrs["b"]), p0=_float(attrs["p0"]))
    if path_kind == "strain":
        test["b_nominal"] = NAN  # b is not controlled on a strain path
    if not np.isfinite(test["p0"]) and test["rows"]:
        test["p0"] = float(test["p"][0])
    return test, None


# ---------------------------------------------------------------------------------------------
# Analysis


def _b_key(t):
    return round(t["b_nominal"], 3) if np.isfinite(t["b_nominal"]) else NAN


def analyze_tests(tests, opt):
    """Run every step on the loaded tests; returns the summary dict (tests gain their series)."""
    warn = []
    for t in tests:
        eps1 = t["eps1"]
        t["critical"] = detect_critical(
            eps1, t, window=opt.window, tol_eta=opt.tol_eta, tol_p=opt.tol_p, tol_e=opt.tol_e,
            tol_epsv=opt.tol_epsv, pre_strain=opt.pre_strain, min_points=opt.min_points)
        if not np.isfinite(t["b_nominal"]):
            t["b_nominal"] = round(t["critical"]["point"].get("b", NAN), 2)
        i = int(np.nanargmax(t["eta"])) if np.any(np.isfinite(t["eta"])) else 0
        j = int(np.nanargmax(t["q"]))
        t["peak"] = {"eta": float(t["eta"][i]), "eps1_eta": float(eps1[i]),
                     "q": float(t["q"][j]), "eps1_q": float(eps1[j])}
        t["end"] = {"eps1": float(eps1[-1]), "eps_v": float(t["eps_v"][-1]),
                    "e": float(t["e"][-1])}
        t["used"] = bool(t["critical"]["reached"] or opt.all)

    used = [t for t in tests if t["used"]]
    cp = lambda k: np.array([t["critical"]["point"][k] for t in used], float)  # noqa: E731
    csl = fit_csl(cp("p"), cp("e"), b=np.array([_b_key(t) for t in used]), xi=opt.fix_xi)
    csl["points"] = "end windows of every test (--all)" if opt.all else \
        "tests that reached the critical state"
    if not used:
        csl["note"] = "not fitted: no test reached the critical state (see --all)"
    mth = fit_m_theta(cp("theta"), cp("M"))

    # State parameter: own CSL, else the study's.
    if csl["fitted"]:
        cpar = csl["params"]
        psi_source = "fitted CSL"
    else:
        cpar = {"e_gamma": STUDY["e_gamma"], "lambda": STUDY["lambda"], "xi": STUDY["xi"]}
        psi_source = "study's CSL (own CSL not fitted)"
        warn.append("psi computed with the study's CSL because the CSL could not be fitted")
    for t in tests:
        dil = dilatancy_series(t["eps1"], t["eps_v"], t["eps_q"], smooth=opt.smooth,
                               min_strain=opt.min_strain, min_deq=opt.min_deq,
                               others={k: t[k] for k in ("eta", "p", "e", "theta")},
                               stress=t.get("stress"))
        dil["psi"] = dil["e"] - csl_e(dil["p"], cpar["e_gamma"], cpar["lambda"], cpar["xi"])
        t["dil"] = dil
        m = dil["mask"]
        t["min_d"] = float(np.min(dil["d"][m])) if np.any(m) else NAN
        t["eps1_min_d"] = float(t["eps1"][m][np.argmin(dil["d"][m])]) if np.any(m) else NAN
        t["psi0"] = float(t["e"][0] - csl_e(t["p"][0], cpar["e_gamma"], cpar["lambda"],
                                            cpar["xi"]))

    # Dilatancy fits.
    if opt.dilatancy_path:
        dpath = opt.dilatancy_path
    else:
        dpath = next((pk for pk in ("constant_p", "constant_sigma3")
                      if any(t["path"] == pk and _b_key(t) == 0 for t in tests)), None)
    zero = [t for t in tests if t["path"] == dpath and _b_key(t) == 0]
    pos = [t for t in tests if t["path"] == dpath and np.isfinite(_b_key(t)) and _b_key(t) > 0]

    def pooled(ts, *keys):
        return [np.concatenate([t["dil"][k][t["dil"]["mask"]] for t in ts]) if ts
                else np.array([]) for k in keys]

    Mc, Mc_source = mth["params"]["M_c"], "M(theta) fit"
    if not np.isfinite(Mc) and zero:
        Mc = float(np.nanmean([t["critical"]["point"]["M"] for t in zero]))
        Mc_source = "mean q/p of the b = 0 end windows"
    K = mth["params"]["K"]
    eta0, psi0, d0_ = pooled(zero, "eta", "psi", "d")
    ld = fit_li_dafalias(eta0, psi0, d0_, Mc if np.isfinite(Mc) else NAN)
    ld["path"] = dpath
    ld["tests"] = [t["name"] for t in zero]
    ld["M_source"] = Mc_source
    if dpath is None:
        ld["note"] = "not fitted: no b = 0 test on a constant-p or constant-sigma3 path"
    d0, mm = ld["params"]["d0"], ld["params"]["m"]
    etap, psip, thp, dp = pooled(pos, "eta", "psi", "theta", "d")
    gf = fit_g_form(etap, psip, thp, dp, Mc, K, d0, mm)
    gf["path"] = dpath
    gf["tests"] = [t["name"] for t in pos]

    # Table 3: MSE per (path, b) of both 3D forms.
    mse = []
    alpha, beta = gf["params"]["alpha"], gf["params"]["beta"]
    for pk in sorted({t["path"] for t in tests}):
        for bk in sorted({_b_key(t) for t in tests if t["path"] == pk and np.isfinite(_b_key(t))}):
            ts = [t for t in tests if t["path"] == pk and _b_key(t) == bk]
            eta_, psi_, th_, d_ = pooled(ts, "eta", "psi", "theta", "d")
            row = {"path": pk, "b": bk, "n": int(d_.size), "tests": len(ts),
                   "mse_li3d": NAN, "mse_g": NAN}
            if d_.size and all(np.isfinite(v) for v in (Mc, K, d0, mm)):
                row["mse_li3d"] = float(np.mean(
                    (d_ - dilatancy_li3d(eta_, psi_, th_, Mc, K, d0, mm)) ** 2))
                if np.isfinite(alpha):
                    row["mse_g"] = float(np.mean(
                        (d_ - dilatancy_g(eta_, psi_, th_, Mc, K, d0, mm, alpha, beta)) ** 2))
            mse.append(row)

    trends = evaluate_trends(tests, csl, mse, dpath, opt)
    verdicts = study_verdicts(csl, mth, ld)
    return {"csl": csl, "m_theta": mth, "psi_source": psi_source, "li_dafalias": ld,
            "g_form": gf, "mse": mse, "trends": trends, "verdicts": verdicts, "warnings": warn,
            "dilatancy_path": dpath, "M_c_dilatancy": Mc}


def evaluate_trends(tests, csl, mse, dpath, opt):
    groups = {}
    for t in tests:
        groups.setdefault((t["path"], t["p0"]), []).append(t)

    def trend(name, statement, value, sign, label, only_used=False):
        rows = []
        for (pk, p0), ts in sorted(groups.items()):
            if only_used:
                ts = [t for t in ts if t["used"]]
            b = [_b_key(t) for t in ts]
            y = [value(t) for t in ts]
            rho = spearman(b, y)
            if np.isfinite(rho):
                rows.append({"path": pk, "p0": p0, "rho": rho, "b": b, "values": y,
                             "ok": bool(sign * rho >= CRIT["rho"])})
        if not rows:
            verdict = "not testable"
        else:
            verdict = "reproduced" if all(r["ok"] for r in rows) else "not reproduced"
        return {"name": name, "statement": statement, "quantity": label, "verdict": verdict,
                "criterion": (f"Spearman rho(b, {label}) {'<= -' if sign < 0 else '>= +'}"
                              f"{CRIT['rho']} in every (path, p0) group with >= 3 b values"),
                "groups": rows}

    out = [
        trend("peak_eta_falls", "peak strength (peak stress ratio) falls as b rises",
              lambda t: t["peak"]["eta"], -1, "peak eta = (q/p)max"),
        trend("peak_q_falls", "peak q falls as b rises (supplementary: at constant sigma3, p "
              "rises with b)", lambda t: t["peak"]["q"] / 1e6, -1, "peak q (MPa)"),
        trend("critical_M_falls", "critical stress ratio M = q_c/p_c falls as b rises",
              lambda t: t["critical"]["point"]["M"], -1, "M = q_c/p_c", only_used=True),
        trend("critical_q_falls", "critical q falls as b rises (supplementary)",
              lambda t: t["critical"]["point"]["q"] / 1e6, -1, "q_c (MPa)", only_used=True),
        trend("dilation_grows", "dilation grows with b", lambda t: -t["min_d"], +1,
              "max dilation rate -min(d)"),
        trend("final_dilation_grows", "final dilation grows with b (supplementary)",
              lambda t: -t["end"]["eps_v"], +1, "-eps_v at the end"),
    ]
    # CSL unique across b.
    rows = csl.get("per_b", [])
    if csl["fitted"] and len(rows) >= 2:
        ok = all(abs(r["mean"]) <= CRIT["csl_unique"] for r in rows)
        verdict = "reproduced" if ok else "not reproduced"
    else:
        verdict = "not testable"
    out.append({"name": "csl_unique", "statement": "one CSL for every b",
                "quantity": "mean CSL residual per b", "verdict": verdict,
                "criterion": f"abs(mean residual) <= {CRIT['csl_unique']} for every b",
                "groups": rows})
    # g-dependent form at least as good as Li's at each b > 0.
    rows = [r for r in mse if r["path"] == dpath and r["b"] > 0
            and np.isfinite(r["mse_g"]) and np.isfinite(r["mse_li3d"])]
    if rows:
        verdict = "reproduced" if all(r["mse_g"] <= r["mse_li3d"] for r in rows) \
            else "not reproduced"
    else:
        verdict = "not testable"
    out.append({"name": "g_form_better",
                "statement": "the g-dependent 3D form fits d better than Li's 3D form at b > 0",
                "quantity": "MSE of d", "verdict": verdict,
                "criterion": "MSE(g-dependent) <= MSE(Li 3D) at every b > 0 of the fitting path",
                "groups": rows})
    return out


def study_verdicts(csl, mth, ld):
    v = []
    for k, label in (("e_gamma", "e_Gamma"), ("lambda", "lambda"), ("xi", "xi")):
        value, se = csl["params"][k], csl["stderr"][k]
        if not csl["fitted"] or csl["xi_at_bound"] or (k == "xi" and csl["mode"] != "full"):
            verdict = "not testable"
        else:
            verdict = compare(value, se, STUDY[k], CRIT["csl_rel"])
        v.append({"quantity": f"CSL {label}", "value": value, "se": se, "study": STUDY[k],
                  "verdict": verdict,
                  "criterion": f"within 2 SE or {100 * CRIT['csl_rel']:g} % of the study's "
                               "(not testable if 2 SE > the study's value)"})
    if csl["fitted"]:
        pp = np.geomspace(*csl["p_range"], 50)
        par = csl["params"]
        dev = float(np.max(np.abs(csl_e(pp, par["e_gamma"], par["lambda"], par["xi"])
                                  - csl_e(pp, STUDY["e_gamma"], STUDY["lambda"], STUDY["xi"]))))
        verdict = "reproduced" if dev <= CRIT["csl_curve"] else "not reproduced"
    else:
        dev, verdict = NAN, "not testable"
    v.append({"quantity": "CSL curve: max abs(e_c - e_c,study) over the tested p", "value": dev,
              "se": NAN, "study": 0.0, "verdict": verdict,
              "criterion": f"<= {CRIT['csl_curve']}"})
    R = csl["R"]
    v.append({"quantity": "CSL R", "value": R, "se": NAN, "study": STUDY["R"],
              "verdict": "not testable" if not np.isfinite(R) else
              ("reproduced" if R >= CRIT["R_min"] else "not reproduced"),
              "criterion": f"R >= {CRIT['R_min']}"})
    for k, label in (("phi_c_deg", "phi_c (deg)"), ("phi_e_deg", "phi_e (deg)")):
        value = mth[k]
        verdict = "not testable" if not np.isfinite(value) else (
            "reproduced" if abs(value - STUDY["phi_deg"]) <= CRIT["phi_tol_deg"]
            else "not reproduced")
        v.append({"quantity": label, "value": value, "se": mth["se_" + k],
                  "study": STUDY["phi_deg"], "verdict": verdict,
                  "criterion": f"within {CRIT['phi_tol_deg']:g} deg of 22"})
    for k in ("d0", "m"):
        value, se = ld["params"][k], ld["stderr"][k]
        v.append({"quantity": f"Li-Dafalias {k} (b = 0)", "value": value, "se": se,
                  "study": STUDY[k], "verdict": compare(value, se, STUDY[k], CRIT["dil_rel"]),
                  "criterion": f"within 2 SE or {100 * CRIT['dil_rel']:g} % of the study's "
                               "(not testable if 2 SE > the study's value)"})
    return v


# ---------------------------------------------------------------------------------------------
# Figures


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _b_cmap(plt):
    """viridis without its last tenth (pale yellow is hard to read on white), for b in [0, 1]."""
    from matplotlib.colors import ListedColormap
    return ListedColormap(plt.get_cmap("viridis")(np.linspace(0.0, 0.9, 256)))


def _b_color(plt, b):
    return _b_cmap(plt)(min(max(b, 0.0), 1.0)) if np.isfinite(b) else "0.4"


def _save(fig, out, stem, files):
    for ext in ("png", "svg"):
        name = f"{stem}.{ext}"
        fig.savefig(os.path.join(out, name), dpi=120)
        files.append(name)


def _note(ax, text):
    ax.text(0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center", fontsize=10,
            color="C3", wrap=True, bbox={"facecolor": "white", "edgecolor": "C3", "alpha": 0.9})


def _p0_tag(p0):
    return f"p0_{p0 / 1e3:g}kPa" if np.isfinite(p0) else "p0_unknown"


def figure_stress_strain(plt, tests, out, title, files):
    groups = {}
    for t in tests:
        groups.setdefault((t["path"], t["p0"]), []).append(t)
    for (pk, p0), ts in sorted(groups.items()):
        fig, ax = plt.subplots(1, 2, figsize=(11, 4.4))
        for t in sorted(ts, key=_b_key):
            c = _b_color(plt, _b_key(t))
            lab = f"b = {_b_key(t):g}" + ("" if t["critical"]["reached"] else " (not critical)")
            ax[0].plot(100 * t["eps1"], t["q"] / 1e6, color=c, label=lab)
            ax[1].plot(100 * t["eps1"], 100 * t["eps_v"], color=c, label=lab)
        ax[0].set_ylabel("deviatoric stress q (MPa)")
        ax[1].set_ylabel("volumetric strain eps_v (%)  [compression +]")
        for a in ax:
            a.set_xlabel("axial strain eps_1 (%)")
            a.grid(True, alpha=0.3)
        ax[0].legend(fontsize=8)
        fig.suptitle(f"{title}: {PATH_LABEL.get(pk, pk)}, p0 = {p0 / 1e6:g} MPa")
        fig.tight_layout()
        _save(fig, out, f"stress_strain-{pk}-{_p0_tag(p0)}", files)
        plt.close(fig)


def figure_csl(plt, tests, csl, out, title, files):
    fig, ax = plt.subplots(figsize=(7, 5))
    par = csl["params"]
    xi = par["xi"] if csl["fitted"] else 1.0
    pts = [t for t in tests if np.isfinite(t["critical"]["point"].get("p", NAN))]
    shown = [t for t in pts if t["used"]] or pts
    for t in shown:
        pt = t["critical"]["point"]
        c = _b_color(plt, _b_key(t))
        filled = t["critical"]["reached"]
        ax.scatter((pt["p"] / PA) ** xi, pt["e"], marker=PATH_MARKER.get(t["path"], "D"), s=45,
                   facecolors=c if filled else "none", edgecolors=c, zorder=3)
    if shown:
        x = np.array([(t["critical"]["point"]["p"] / PA) ** xi for t in shown])
        xx = np.linspace(0, 1.1 * x.max(), 200)
        if csl["fitted"]:
            ax.plot(xx, par["e_gamma"] - par["lambda"] * xx, "k-",
                    label=(f"fit: e_c = {par['e_gamma']:.4f} - {par['lambda']:.4g} "
                           f"(p/p_a)^{xi:.3f}, R = {csl['R']:.3f}"
                           + ("" if csl["mode"] == "full" else f"  [{csl['mode']}]")))
        # the study's CSL over the tested pressures (x maps back to p through this xi)
        pt = np.array([t["critical"]["point"]["p"] for t in shown])
        ps = np.geomspace(0.5 * pt.min(), 2.0 * pt.max(), 200)
        ax.plot((ps / PA) ** xi, csl_e(ps, STUDY["e_gamma"], STUDY["lambda"], STUDY["xi"]), "--",
                color="0.5", label="study: e_c = 0.699 - 0.0002 (p/p_a)^0.971")
    if not csl["fitted"]:
        _note(ax, "CSL " + (csl["note"] or "not fitted") + "\n(x axis drawn with xi = 1)")
    sm = plt.cm.ScalarMappable(cmap=_b_cmap(plt), norm=plt.Normalize(0, 1))
    cb = fig.colorbar(sm, ax=ax)
    cb.set_label("b (colour)")
    for pk, mk in PATH_MARKER.items():
        if any(t["path"] == pk for t in shown):
            ax.scatter([], [], marker=mk, facecolors="0.5", edgecolors="0.5",
                       label=PATH_LABEL[pk])
    if any(not t["critical"]["reached"] for t in shown):
        ax.scatter([], [], marker="o", facecolors="none", edgecolors="0.5",
                   label="end window, not critical")
    ax.set_xlabel(f"(p / p_a)^xi  (p_a = 101.325 kPa, xi = {xi:.3f})")
    ax.set_ylabel("void ratio e")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    ax.set_title(f"{title}: critical state line")
    fig.tight_layout()
    _save(fig, out, "csl", files)
    plt.close(fig)


def figure_pi_plane(plt, tests, mth, out, title, files):
    fig, ax = plt.subplots(figsize=(7.2, 8.0))
    phi = np.linspace(0, 2 * np.pi, 721)
    Mc, K = mth["params"]["M_c"], mth["params"]["K"]
    rmax = 0.0

    def draw(r, *args, **kw):
        ax.plot(r * np.sin(phi), r * np.cos(phi), *args, **kw)

    if np.isfinite(Mc) and np.isfinite(K):
        r = m_theta(phi, Mc, K)
        draw(r, "k-", lw=1.8, label=f"fit: M_c = {Mc:.3f}, K = {K:.3f} "
             f"(phi_c = {mth['phi_c_deg']:.1f}, phi_e = {mth['phi_e_deg']:.1f} deg)")
        if np.isfinite(mth["phi_c_deg"]):
            draw(mohr_coulomb_M(_fold(phi), math.radians(mth["phi_c_deg"])), "--", color="C1",
                 lw=1, label="Mohr-Coulomb, phi = phi_c")
        draw(np.full_like(phi, Mc), ":", color="C0", lw=1, label="circle M = M_c")
        rmax = max(rmax, float(np.max(r)))
    else:
        _note(ax, "M(theta) " + (mth["note"] or "not fitted"))
    s22 = math.sin(math.radians(STUDY["phi_deg"]))
    Mc22, K22 = 6 * s22 / (3 - s22), (3 - s22) / (3 + s22)
    draw(m_theta(phi, Mc22, K22), "-", color="0.6", lw=1, label="study: phi = 22 deg (M_c, M_e)")
    rmax = max(rmax, Mc22)
    shown = [t for t in tests if t["used"]] or tests  # none critical: the end windows, open
    for t in shown:
        pt = t["critical"]["point"]
        th, M = pt.get("theta", NAN), pt.get("M", NAN)
        if not (np.isfinite(th) and np.isfinite(M)):
            continue
        c = _b_color(plt, _b_key(t))
        filled = t["critical"]["reached"]
        for k in range(6):  # the point and its images in the other five sectors
            a = (th if k % 2 == 0 else -th) + 2 * np.pi / 3 * (k // 2)
            ax.scatter(M * np.sin(a), M * np.cos(a), marker=PATH_MARKER.get(t["path"], "D"),
                       s=40 if k == 0 else 14, alpha=1.0 if k == 0 else 0.3,
                       facecolors=c if filled else "none", edgecolors=c, zorder=3)
        rmax = max(rmax, M)
    rmax = 1.25 * (rmax or 1.0)
    for k, lab in enumerate(("sigma_1", "sigma_2", "sigma_3")):
        a = 2 * np.pi / 3 * k
        ax.plot([0, rmax * np.sin(a)], [0, rmax * np.cos(a)], color="0.7", lw=0.8)
        ax.text(1.04 * rmax * np.sin(a), 1.04 * rmax * np.cos(a), lab, ha="center", va="center")
    ax.set_xlim(-1.15 * rmax, 1.15 * rmax)
    ax.set_ylim(-1.15 * rmax, 1.15 * rmax)
    ax.set_aspect("equal")
    ax.set_xlabel("q/p (radius) in the deviatoric plane, sigma_2 - sigma_3 direction")
    ax.set_ylabel("q/p (radius), sigma_1 direction")
    ax.grid(True, alpha=0.2)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2)
    ax.set_title(f"{title}: critical stress ratio M(theta)\n"
                 "(large markers: measured; small: images by symmetry; colour: b)", fontsize=10)
    fig.tight_layout()
    _save(fig, out, "pi_plane", files)
    plt.close(fig)


def _fold(phi):
    """Lode angle in [0, pi/3] of a direction at angle phi from the sigma_1 axis (symmetry)."""
    return np.abs(((np.asarray(phi) + np.pi / 3) % (2 * np.pi / 3)) - np.pi / 3)


def figure_dilatancy(plt, tests, res, out, title, files):
    from matplotlib.lines import Line2D
    ld, gf = res["li_dafalias"], res["g_form"]
    Mc, K = res["M_c_dilatancy"], res["m_theta"]["params"]["K"]
    d0, m = ld["params"]["d0"], ld["params"]["m"]
    al, be = gf["params"]["alpha"], gf["params"]["beta"]
    paths = sorted({t["path"] for t in tests})
    for pk in paths:
        ts = [t for t in tests if t["path"] == pk]
        bs = sorted({_b_key(t) for t in ts if np.isfinite(_b_key(t))}) or [NAN]
        ncol = min(3, len(bs))
        nrow = int(math.ceil(len(bs) / ncol))
        fig, axes = plt.subplots(nrow, ncol, figsize=(4.6 * ncol, 3.9 * nrow), squeeze=False)
        p0s = sorted({t["p0"] for t in ts})
        for ax, bk in zip(axes.flat, bs):
            sel = [t for t in ts if _b_key(t) == bk or (not np.isfinite(bk))]
            any_data = False
            legend, legend_data = {}, {}
            for t in sel:
                dl = t["dil"]
                mk = dl["mask"]
                if not np.any(mk):
                    continue
                any_data = True
                c = f"C{p0s.index(t['p0']) % 10}"
                ax.plot(dl["eta"][mk], dl["d"][mk], ".", ms=3, color=c, alpha=0.6)
                legend_data.setdefault(f"p0 = {t['p0'] / 1e6:g} MPa",
                                  Line2D([], [], ls="", marker="o", ms=4, color=c))
                if not all(np.isfinite(v) for v in (Mc, d0, m)):
                    continue
                eta, psi, th = dl["eta"][mk], dl["psi"][mk], dl["theta"][mk]
                if bk == 0 or not np.isfinite(K):
                    lab = "Li-Dafalias (b = 0 fit)" + ("" if bk == 0 else ", g = 1: K unknown")
                    ax.plot(eta, dilatancy_li(eta, psi, Mc, d0, m), "-", color=c, lw=1.2)
                    legend.setdefault(lab, Line2D([], [], ls="-", color="k"))
                else:
                    ax.plot(eta, dilatancy_li3d(eta, psi, th, Mc, K, d0, m), "--", color=c,
                            lw=1.2)
                    legend.setdefault("Li 3D (d0, m of b = 0)", Line2D([], [], ls="--", color="k"))
                    if np.isfinite(al):
                        ax.plot(eta, dilatancy_g(eta, psi, th, Mc, K, d0, m, al, be), "-",
                                color=c, lw=1.2)
                        legend.setdefault("g-dependent 3D (alpha, beta fit)",
                                          Line2D([], [], ls="-", color="k"))
            if not any_data:
                _note(ax, "no dilatancy data")
            elif not all(np.isfinite(v) for v in (Mc, d0, m)):
                _note(ax, "model not drawn: " + (ld["note"] or "d0, m not fitted"))
            elif bk > 0 and np.isfinite(K) and not np.isfinite(al):
                ax.text(0.02, 0.02, "g-form: " + (gf["note"] or "not fitted"),
                        transform=ax.transAxes, fontsize=7, color="C3")
            ax.axhline(0, color="0.6", lw=0.8)
            ax.set_title(f"b = {bk:g}" if np.isfinite(bk) else "b not set", fontsize=10)
            ax.set_xlabel("stress ratio eta = q/p (-)")
            ax.set_ylabel("dilatancy d = d eps_v / d eps_q (-)")
            ax.grid(True, alpha=0.3)
            legend = {**legend_data, **legend}
            if legend:
                ax.legend(legend.values(), legend.keys(), fontsize=7)
        for ax in list(axes.flat)[len(bs):]:
            ax.axis("off")
        fig.suptitle(f"{title}: dilatancy, {PATH_LABEL.get(pk, pk)} "
                     f"(models along each test's own eta, psi, theta)")
        fig.tight_layout()
        _save(fig, out, f"dilatancy-{pk}", files)
        plt.close(fig)


# ---------------------------------------------------------------------------------------------
# Report


def _f(x, fmt=".4g"):
    if x is None:
        return "n/a"
    try:
        if not np.isfinite(x):
            return "n/a"
    except TypeError:
        return str(x)
    return format(x, fmt)


def _pm(v, se, fmt=".4g"):
    return _f(v, fmt) + (f" ± {_f(se, fmt)}" if se is not None and np.isfinite(se) else "")


def write_report(path, tests, res, opt, files, skipped):
    L = []
    add = L.append
    csl, mth, ld, gf = res["csl"], res["m_theta"], res["li_dafalias"], res["g_form"]
    add(f"# {opt.title}\n")
    add(f"Generated by `analyze.py` on {datetime.datetime.now().isoformat(timespec='seconds')}.\n")
    add("## Inputs\n")
    add(f"{len(tests)} shear test(s) read" + (f", {len(skipped)} file(s) skipped" if skipped
                                               else "") + ":\n")
    for t in tests:
        add(f"- `{t['file']}` ({t['rows']} rows)")
    for f, why in skipped:
        add(f"- skipped `{f}`: {why}")
    add("")
    add(f"Options: window {opt.window:g}, pre-strain {opt.pre_strain:g}, "
        f"min rows {opt.min_points}, tolerances eta {opt.tol_eta:g} (relative), "
        f"p {opt.tol_p:g} (relative), e {opt.tol_e:g}, "
        f"eps_v {opt.tol_epsv:g} (absolute); smoothing {opt.smooth:g}, min strain "
        f"{opt.min_strain:g}, min d eps_q/d eps_1 {opt.min_deq:g}"
        + (", --all" if opt.all else "") + (f", xi fixed {opt.fix_xi:g}" if opt.fix_xi else "")
        + ".\n")
    for w in res["warnings"]:
        add(f"> Warning: {w}\n")

    add("## 1. Tests\n")
    add("Critical point = means over the last window of eps_1; M = q_c/p_c. "
        "Criticality: the straight-line change over the window of eta and p below "
        f"{100 * opt.tol_eta:g} % / {100 * opt.tol_p:g} % of their mean, of e below {opt.tol_e:g} "
        f"and of eps_v below {opt.tol_epsv:g}, the window ({100 * opt.window:g} % of eps_1) "
        f"covered by >= {opt.min_points} rows and the test run to >= "
        f"{100 * (opt.window + opt.pre_strain):g} %. eps_v is compression positive (dilation "
        "negative); psi0 = e0 - e_c(p0) with the "
        f"{res['psi_source']}.\n")
    add("| test | path | b | p0 (MPa) | eps1 end (%) | critical | p_c (MPa) | q_c (MPa) | M | e_c "
        "| b_c | theta_c (deg) | eps_v,c (%) | peak eta | at eps1 (%) | peak q (MPa) | min d "
        "| eps_v end (%) | psi0 |")
    add("|" + "---|" * 19)
    for t in tests:
        c = t["critical"]
        pt = c["point"]
        add(f"| {t['name']} | {t['path']} | {_f(_b_key(t), 'g')} | {_f(t['p0'] / 1e6, 'g')} "
            f"| {_f(100 * t['end']['eps1'], '.1f')} | {'yes' if c['reached'] else 'no'} "
            f"| {_f(pt['p'] / 1e6)} | {_f(pt['q'] / 1e6)} | {_f(pt['M'], '.4f')} "
            f"| {_f(pt['e'], '.4f')} | {_f(pt['b'], '.3f')} "
            f"| {_f(math.degrees(pt['theta']), '.1f')} | {_f(100 * pt['eps_v'], '.2f')} "
            f"| {_f(t['peak']['eta'], '.4f')} "
            f"| {_f(100 * t['peak']['eps1_eta'], '.2f')} | {_f(t['peak']['q'] / 1e6)} "
            f"| {_f(t['min_d'], '.3f')} | {_f(100 * t['end']['eps_v'], '.2f')} "
            f"| {_f(t['psi0'], '.4f')} |")
    add("")
    notc = [t for t in tests if not t["critical"]["reached"]]
    if notc:
        add("Not at the critical state:\n")
        for t in notc:
            add(f"- {t['name']}: " + "; ".join(t["critical"]["reasons"]))
        add("")

    add("## 2. Critical state line\n")
    add("e_c = e_Gamma - lambda (p_c/p_a)^xi (Li & Wang 1998), p_a = 101.325 kPa; nonlinear least "
        f"squares over the critical points ({csl['points']}): n = {csl['n']}, "
        f"{csl['distinct_p']} distinct p. Standard errors from the residual variance.\n")
    if csl["note"]:
        add(f"**{csl['note']}**\n")
    add("| parameter | this run | study | verdict | criterion |")
    add("|---|---|---|---|---|")
    for v in res["verdicts"]:
        if v["quantity"].startswith("CSL"):
            add(f"| {v['quantity']} | {_pm(v['value'], v['se'])} | {_f(v['study'], 'g')} "
                f"| {v['verdict']} | {v['criterion']} |")
    add(f"\nR^2 = {_f(csl['r2'])}, RMS residual = {_f(csl['rms'])}, mode: {csl['mode'] or 'n/a'}."
        " (A study lambda of 0.0002 with xi ~ 1 means e_c varies by only ~0.03 over 0.5-16 MPa.)\n")
    if csl["per_b"]:
        add("Residuals e - e_c per b (uniqueness of the CSL across b):\n")
        add("| b | n | mean | RMS |")
        add("|---|---|---|---|")
        for r in csl["per_b"]:
            add(f"| {r['b']:g} | {r['n']} | {_f(r['mean'], '.4f')} | {_f(r['rms'], '.4f')} |")
        add("")

    add("## 3. Critical stress ratio M(theta)\n")
    add("M(theta) = M_c g(theta), g = 2K/((1+K) - (1-K) cos 3theta), K = M_e/M_c in "
        f"[{mth['K_bounds'][0]:g}, {mth['K_bounds'][1]:g}], fitted to q_c/p_c at theta_c "
        f"(n = {mth['n']}); sin phi_c = 3M_c/(6+M_c), sin phi_e = 3M_e/(6-M_e).\n")
    if mth["note"]:
        add(f"**{mth['note']}**\n")
    P, S = mth["params"], mth["stderr"]
    add("| quantity | this run | study | verdict | criterion |")
    add("|---|---|---|---|---|")
    add(f"| M_c | {_pm(P['M_c'], S['M_c'])} | | | |")
    add(f"| K | {_pm(P['K'], S['K'])} | | | |")
    add(f"| M_e | {_pm(P['M_e'], S['M_e'])} | | | |")
    for v in res["verdicts"]:
        if v["quantity"].startswith("phi"):
            add(f"| {v['quantity']} | {_pm(v['value'], v['se'], '.2f')} | about 22 | "
                f"{v['verdict']} | {v['criterion']} |")
    conv = {True: "yes", False: "no", None: "n/a"}[mth["convex"]]
    add(f"\nConvex (K >= 7/9 = 0.778): {conv}. A Mohr-Coulomb surface with phi = phi_c would "
        f"have K = {_f(mth['K_mohr_coulomb'], '.3f')}. RMS of M about the fit: "
        f"{_f(mth['rms'], '.4f')}.\n")

    add("## 4. Dilatancy\n")
    add("d = d eps_v / d eps_q from total strain increments (on constant-p paths the elastic "
        "volumetric increment vanishes, so the total increment is an acceptable proxy of the "
        "plastic one; on other paths it is an approximation). Derivatives: Savitzky-Golay "
        "(quadratic, first derivative) of eps_v, eps_q and eps_1 against the row index over "
        f"{100 * opt.smooth:g} % of axial strain, then the ratio; eta, p, e, theta smoothed "
        f"alike; points with eps_1 < {100 * opt.min_strain:g} % or d eps_q/d eps_1 < "
        f"{opt.min_deq:g} dropped; psi from the {res['psi_source']}.\n")
    add(f"Li & Dafalias (2000) d = d0/M (M exp(m psi) - eta), fitted on the b = 0 tests of path "
        f"`{ld['path']}` ({', '.join(ld['tests']) or 'none'}; {ld['n']} points), "
        f"M = M_c = {_f(res['M_c_dilatancy'], '.4f')} from the {ld['M_source']}.\n")
    if ld["note"]:
        add(f"**{ld['note']}**\n")
    add("| parameter | this run | study (b = 0, p = 0.5 MPa) | verdict | criterion |")
    add("|---|---|---|---|---|")
    for v in res["verdicts"]:
        if v["quantity"].startswith("Li-Dafalias"):
            add(f"| {v['quantity']} | {_pm(v['value'], v['se'])} | {_f(v['study'], 'g')} "
                f"| {v['verdict']} | {v['criterion']} |")
    add(f"\nMSE of the b = 0 fit: {_f(ld['mse'])}, R^2 = {_f(ld['r2'], '.3f')}.\n")
    add("3D forms at b > 0: Li's d = d0/M_c (M_c g(theta) exp(m psi) - eta) with d0, m from b = 0; "
        "and the study's form, whose exact expression is not available here, taken as d0(theta) = "
        "d0 g^-alpha, m(theta) = m g^beta in Li's form, i.e. d = d0 g^-alpha / M_c (M_c g "
        "exp(m g^beta psi) - eta), with alpha and beta fitted on the b > 0 tests of the same path "
        f"({len(gf['tests'])} tests, {gf['n']} points).\n")
    if gf["note"]:
        add(f"**g-dependent form: {gf['note']}**\n")
    add(f"alpha = {_pm(gf['params']['alpha'], gf['stderr']['alpha'])}, beta = "
        f"{_pm(gf['params']['beta'], gf['stderr']['beta'])}; pooled b > 0 MSE: g-dependent "
        f"{_f(gf['mse'])}, Li 3D {_f(gf['mse_li3d'])}.\n")
    add("Mean squared error of d per b (the study's Table 3; the study's own values are not "
        "available here):\n")
    add("| path | b | tests | points | MSE Li 3D | MSE g-dependent |")
    add("|---|---|---|---|---|---|")
    for r in res["mse"]:
        add(f"| {r['path']} | {r['b']:g} | {r['tests']} | {r['n']} | {_f(r['mse_li3d'])} "
            f"| {_f(r['mse_g'])} |")
    add("\n(At b = 0, g = 1 and both forms reduce to Li-Dafalias.)\n")

    add("## 5. Trends stated by the study\n")
    add("| statement | quantity | verdict | criterion | groups (path, p0: rho) |")
    add("|---|---|---|---|---|")
    for tr in res["trends"]:
        if tr["name"] in ("csl_unique", "g_form_better"):
            g = "; ".join(
                (f"b = {r['b']:g}: {_f(r['mean'], '.4f')}" if "mean" in r else
                 f"b = {r['b']:g}: {_f(r['mse_g'])} vs {_f(r['mse_li3d'])}") for r in tr["groups"])
        else:
            g = "; ".join(f"{r['path']}, {r['p0'] / 1e6:g} MPa: {r['rho']:+.2f}"
                          for r in tr["groups"])
        add(f"| {tr['statement']} | {tr['quantity']} | **{tr['verdict']}** | {tr['criterion']} "
            f"| {g or 'no group with >= 3 b values'} |")
    add("")

    add("## 6. Figures\n")
    for name in files:
        if name.endswith(".png"):
            add(f"![{name}]({name})")
    add("")
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("\n".join(L) + "\n")


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (np.bool_, bool)):
        return bool(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x) if np.isfinite(x) else None
    return x


def build_summary(tests, res, opt, files, skipped):
    per_test = []
    for t in tests:
        per_test.append({
            "name": t["name"], "file": t["file"], "path": t["path"], "b": _b_key(t),
            "p0": t["p0"], "rows": t["rows"], "eps1_end": t["end"]["eps1"],
            "critical": t["critical"]["reached"], "used_in_fits": t["used"],
            "reasons": t["critical"]["reasons"], "checks": t["critical"]["checks"],
            "critical_point": t["critical"]["point"], "peak": t["peak"],
            "min_d": t["min_d"], "eps1_min_d": t["eps1_min_d"], "eps_v_end": t["end"]["eps_v"],
            "psi0": t["psi0"], "dilatancy_points": int(np.sum(t["dil"]["mask"])),
        })
    opts = {k: getattr(opt, k) for k in ("window", "pre_strain", "min_points", "tol_eta", "tol_p",
                                         "tol_e", "tol_epsv", "all", "fix_xi", "smooth",
                                         "min_strain", "min_deq", "dilatancy_path", "title")}
    return _jsonable({
        "tool": "sandcell analyze.py", "inputs": [t["file"] for t in tests],
        "skipped": [{"file": f, "why": w} for f, w in skipped], "options": opts,
        "study": STUDY, "criteria": CRIT, "tests": per_test, "csl": res["csl"],
        "m_theta": res["m_theta"], "psi_source": res["psi_source"],
        "li_dafalias": res["li_dafalias"], "g_form": res["g_form"], "mse": res["mse"],
        "trends": res["trends"], "verdicts": res["verdicts"], "warnings": res["warnings"],
        "figures": files,
    })


# ---------------------------------------------------------------------------------------------
# Command line


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise InputError(message)


def _positive(v):
    x = _float(v)
    if not (np.isfinite(x) and x > 0):
        raise argparse.ArgumentTypeError(f"must be a positive number, got {v!r}")
    return x


def _nonneg(v):
    x = _float(v)
    if not (np.isfinite(x) and x >= 0):
        raise argparse.ArgumentTypeError(f"must be a number >= 0, got {v!r}")
    return x


def parse_args(argv):
    ap = _Parser(prog=os.environ.get("SANDCELL_ANALYZE_PROG", "analyze.py"), description="Critical-state and dilatancy analysis of "
                 "sandcell triaxial results: report.md, summary.json and figures in --out. "
                 "Methods and criteria: the docstring at the top of analyze.py.")
    ap.add_argument("results", nargs="*", metavar="RESULTS",
                    help="results files (<test>.h5) or directories holding them")
    ap.add_argument("--out", metavar="DIR", help="output folder (default: <DIR>/analysis for a "
                    "single directory argument, else ./analysis)")
    ap.add_argument("--title", default="sandcell critical-state analysis",
                    help="title of the report and the figures")
    g = ap.add_argument_group("critical state")
    g.add_argument("--window", type=_positive, default=0.05, metavar="W",
                   help="window at the end of each test, axial strain (default 0.05)")
    g.add_argument("--pre-strain", type=_nonneg, default=0.05, metavar="S",
                   help="axial strain the test must have run before the window (default 0.05)")
    g.add_argument("--min-points", type=int, default=10, metavar="N",
                   help="rows the window must hold (default 10)")
    g.add_argument("--tol-eta", type=_positive, default=0.02, metavar="T",
                   help="largest change of eta over the window, relative (default 0.02)")
    g.add_argument("--tol-p", type=_positive, default=0.02, metavar="T",
                   help="largest change of p over the window, relative (default 0.02)")
    g.add_argument("--tol-e", type=_positive, default=0.005, metavar="T",
                   help="largest change of e over the window, absolute (default 0.005)")
    g.add_argument("--tol-epsv", type=_positive, default=0.005, metavar="T",
                   help="largest change of eps_v over the window, absolute (default 0.005)")
    g.add_argument("--all", action="store_true", help="fit the CSL and M(theta) with the end "
                   "windows of every test, critical or not (marked)")
    g.add_argument("--fix-xi", type=_positive, default=None, metavar="X",
                   help="fit the CSL with xi fixed at X (default: xi fitted)")
    g = ap.add_argument_group("dilatancy")
    g.add_argument("--smooth", type=_positive, default=0.02, metavar="W",
                   help="Savitzky-Golay window, axial strain (default 0.02)")
    g.add_argument("--min-strain", type=_nonneg, default=0.01, metavar="S",
                   help="use points from this axial strain on (default 0.01)")
    g.add_argument("--min-deq", type=_nonneg, default=0.1, metavar="R",
                   help="use points with d eps_q / d eps_1 >= R (default 0.1)")
    g.add_argument("--dilatancy-path", choices=("constant_p", "constant_sigma3"), default=None,
                   help="path whose tests give d0, m (b = 0) and alpha, beta (b > 0) "
                   "(default: constant_p if it has a b = 0 test, else constant_sigma3)")
    opt = ap.parse_args(argv)
    if not opt.results:
        raise InputError("no results given (usage: analyze.py RESULTS... [--out DIR])")
    if opt.min_points < 3:
        raise InputError(f"--min-points must be >= 3, got {opt.min_points}")
    if opt.out is None:
        if len(opt.results) == 1 and os.path.isdir(opt.results[0]):
            opt.out = os.path.join(opt.results[0], "analysis")
        else:
            opt.out = "analysis"
    return opt


def run(opt):
    files = collect_files(opt.results)
    tests, skipped = [], []
    for f, named in files:
        for attempt in range(3):
            try:
                t, why = read_test(f)
                break
            except InputError as exc:
                # A running job may be writing the file right now: try again shortly. A named
                # file that stays unreadable is an error; one found in a directory is skipped
                # (with a warning) so that a running campaign can be analysed.
                if attempt < 2:
                    time.sleep(0.2)
                    continue
                if named:
                    raise
                t, why = None, f"unreadable, perhaps being written ({exc})"
                print(f"analyze.py: warning: skipping {f}: {exc}", file=sys.stderr)
        if t is None:
            skipped.append((f, why))
        elif t["rows"] < 5:
            skipped.append((f, f"only {t['rows']} rows"))
        else:
            tests.append(t)
    if not tests:
        raise InputError(f"no shear tests with data in {len(files)} file(s) read "
                         "(files need the root attribute stage = 'shear')")
    tests.sort(key=lambda t: (PATHS.index(t["path"]) if t["path"] in PATHS else 9,
                              t["p0"], t["b_nominal"], t["name"]))
    try:
        os.makedirs(opt.out, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the output folder {opt.out}: {exc.strerror}") from None
    res = analyze_tests(tests, opt)
    plt = _plt()
    figs = []
    figure_stress_strain(plt, tests, opt.out, opt.title, figs)
    figure_csl(plt, tests, res["csl"], opt.out, opt.title, figs)
    figure_pi_plane(plt, tests, res["m_theta"], opt.out, opt.title, figs)
    figure_dilatancy(plt, tests, res, opt.out, opt.title, figs)
    write_report(os.path.join(opt.out, "report.md"), tests, res, opt, figs, skipped)
    summary = build_summary(tests, res, opt, figs, skipped)
    with open(os.path.join(opt.out, "summary.json"), "w", encoding="utf-8") as fh:
        json.dump(summary, fh, indent=1, allow_nan=False)
    return res, tests


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    try:
        opt = parse_args(argv)
        res, tests = run(opt)
    except InputError as exc:
        print(f"analyze.py: error: {exc}", file=sys.stderr)
        return 2
    except ImportError as exc:
        print(f"analyze.py: error: {exc} (needs numpy, scipy, matplotlib and h5py)",
              file=sys.stderr)
        return 1
    crit = sum(t["critical"]["reached"] for t in tests)
    print(f"analyze.py: {len(tests)} test(s), {crit} at the critical state; "
          f"report: {os.path.join(opt.out, 'report.md')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
