"""Dilatancy d = d eps_v / d eps_q: the series from Savitzky-Golay derivatives, the Li & Dafalias
(2000) form and its 3D variants, their fits, and the speed-accuracy study's largest dilation rate."""
import numpy as np
from scipy import optimize, signal

from .fitting import NAN, curve_fit, r_squared, standard_errors
from .m_theta import b_of_stress, g_theta, lode_from_b


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
        popt, pcov = curve_fit(lambda X, d0, m: dilatancy_li(X[0], X[1], M, d0, m), X, d,
                               p0=best, maxfev=20000)
        if np.sum((d - dilatancy_li(eta, psi, M, *popt)) ** 2) <= project(m0)[0] * (1 + 1e-9):
            best = popt
    except (RuntimeError, ValueError):
        pass
    se = standard_errors(pcov, 2)
    resid = d - dilatancy_li(eta, psi, M, *best)
    out.update(fitted=True, params={"d0": float(best[0]), "m": float(best[1])},
               stderr={"d0": float(se[0]), "m": float(se[1])},
               mse=float(np.mean(resid ** 2)), r2=r_squared(d, resid))
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
                popt, pcov = curve_fit(model, X, d, p0=start, bounds=([-20, -20], [20, 20]),
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
    se = standard_errors(best_cov, 2)
    resid = d - model(X, *best)
    out.update(fitted=True, params={"alpha": float(best[0]), "beta": float(best[1])},
               stderr={"alpha": float(se[0]), "beta": float(se[1])},
               mse=float(np.mean(resid ** 2)), r2=r_squared(d, resid))
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


def slope_max_dilation(eps1, eps_v, eps_q, width=0.01, start=0.005):
    """Largest -d eps_v / d eps_q, slopes by least squares over windows of `width` in eps1."""
    import numpy as np
    best = -np.inf
    grid = np.arange(start + width / 2, eps1[-1] - width / 2, width / 4)
    for c in grid:
        sel = (eps1 >= c - width / 2) & (eps1 <= c + width / 2)
        if sel.sum() < 4:
            continue
        dq = np.polyfit(eps1[sel], eps_q[sel], 1)[0]
        dv = np.polyfit(eps1[sel], eps_v[sel], 1)[0]
        if dq > 0.1:
            best = max(best, -dv / dq)
    return float(best) if np.isfinite(best) else float("nan")
