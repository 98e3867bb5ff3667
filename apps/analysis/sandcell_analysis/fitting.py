"""Least-squares helpers shared by the fits (CSL, M(theta), dilatancy): quiet curve_fit, standard
errors from a covariance, R^2, and error propagation by central differences."""
import math
import warnings

import numpy as np
from scipy import optimize

NAN = float("nan")


def standard_errors(pcov, k):
    if pcov is None:
        return np.full(k, NAN)
    pcov = np.asarray(pcov, float)
    if pcov.shape != (k, k) or not np.all(np.isfinite(pcov)):
        return np.full(k, NAN)
    d = np.diag(pcov)
    return np.where(d >= 0, np.sqrt(np.abs(d)), NAN)


def curve_fit(f, x, y, p0, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return optimize.curve_fit(f, x, y, p0=p0, **kw)


def r_squared(y, resid):
    sst = float(np.sum((y - y.mean()) ** 2))
    ssr = float(np.sum(resid ** 2))
    if sst <= 0:
        return NAN
    return 1.0 - ssr / sst


def propagate(f, x, cov):
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
