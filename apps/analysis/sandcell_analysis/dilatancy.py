"""Dilatancy d = d eps_v / d eps_q: the series from Savitzky-Golay derivatives (total strains) and,
for `triaxial analyze`, the plastic dilatancy from strain-adaptive local fits with both elastic parts
removed; the Li & Dafalias (2000) form and its 3D variants, their fits, the phase transformation and
m's identifiability, and the speed-accuracy study's largest dilation rate."""
import math

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


# --- Issue 45: plastic increments, strain-adaptive smoothing, phase transformation, m's identifiability ---

ELASTIC_FRACTION = 0.2   # the moduli from the rows before q - q0 reaches this fraction of q_peak - q0
ELASTIC_MIN_ROWS = 4     # ... and at least this many rows
K_MIN_DP = 0.05          # K is measured only where p moves by >= 5 % of p0 over those rows


def elastic_moduli(eps_v, eps_q, p, q, fraction=ELASTIC_FRACTION, min_rows=ELASTIC_MIN_ROWS):
    """Bulk and shear moduli K, G from the test's own initial response.

    Method: over the first rows of the test, from the start to the row where q - q0 first exceeds
    `fraction` (0.2) of q_peak - q0 (at least `min_rows` rows), least-squares slopes
    dq / d eps_q = 3G and dp / d eps_v = K. This is the initial tangent of the shear, where the
    response is nearly linear (19,436 spheres at 0.5 MPa: the secant 3G is 1.28 and 1.33 GPa at 5
    and 10 rows); it includes whatever plastic strain those rows hold, so the moduli are lower
    bounds and the elastic parts removed upper bounds. K needs p to move: where p changes by less
    than K_MIN_DP (5 %) of p0 over those rows (constant-p paths), K is not measured (NaN) and the
    elastic volumetric part dp/K, the servo's noise over an unmeasurable K, is taken as zero.

    Returns a dict: K, G (Pa; NaN where not measured), rows (used), note."""
    eps_v, eps_q, p, q = (np.asarray(a, float) for a in (eps_v, eps_q, p, q))
    out = {"K": NAN, "G": NAN, "rows": 0, "note": ""}
    n = q.size
    if n < min_rows:
        out["note"] = f"{n} rows: too few for the initial moduli"
        return out
    dq = q - q[0]
    peak = float(np.nanmax(dq))
    over = np.nonzero(dq > fraction * peak)[0]
    j = int(over[0]) + 1 if over.size else n
    j = min(max(j, min_rows), n)
    out["rows"] = j
    sl = slice(0, j)
    if np.ptp(eps_q[sl]) > 0:
        g3 = float(np.polyfit(eps_q[sl], q[sl], 1)[0])
        out["G"] = g3 / 3.0 if g3 > 0 else NAN
    if np.ptp(p[sl]) >= K_MIN_DP * abs(p[0]) and np.ptp(eps_v[sl]) > 0:
        k = float(np.polyfit(eps_v[sl], p[sl], 1)[0])
        out["K"] = k if k > 0 else NAN
    else:
        out["note"] = "p held constant: K not measured, dp/K taken as 0"
    return out


def plastic_strains(eps_v, eps_q, p, q, K, G):
    """eps_v^p = eps_v - (p - p0)/K and eps_q^p = eps_q - (q - q0)/(3G) (K or G NaN: that elastic
    part taken as zero)."""
    eps_v, eps_q, p, q = (np.asarray(a, float) for a in (eps_v, eps_q, p, q))
    ev = eps_v - ((p - p[0]) / K if np.isfinite(K) and K > 0 else 0.0)
    eq = eps_q - ((q - q[0]) / (3.0 * G) if np.isfinite(G) and G > 0 else 0.0)
    return ev, eq


def local_quadratic(x, ys, rel=0.25, h_min=2e-4, min_rows=7):
    """Strain-adaptive smoothing: at every row i, a least-squares quadratic in x over the rows with
    |x_j - x_i| <= h_i, h_i = max(h_min, rel x_i) (a window proportional to the strain: a constant
    width in log strain, narrow on the pre-peak branch, wide on the long post-peak one), widened to
    the nearest `min_rows` rows where it holds fewer. Returns, per y in ys, (value, dy/dx) at every
    row, and the half-widths h."""
    x = np.asarray(x, float)
    n = x.size
    ys = [np.asarray(y, float) for y in ys]
    vals = [np.full(n, NAN) for _ in ys]
    ders = [np.full(n, NAN) for _ in ys]
    h = np.maximum(h_min, rel * np.abs(x))
    order = np.argsort(x, kind="stable")
    xs = x[order]
    for i in range(n):
        lo = np.searchsorted(xs, x[i] - h[i], "left")
        hi = np.searchsorted(xs, x[i] + h[i], "right")
        if hi - lo < min_rows:
            k = int(np.searchsorted(xs, x[i]))
            lo = max(0, min(k - min_rows // 2, n - min_rows))
            hi = min(n, lo + min_rows)
        idx = order[lo:hi]
        u = x[idx] - x[i]
        if idx.size < 3 or np.ptp(u) <= 0:
            continue
        A = np.column_stack([np.ones(idx.size), u, u * u])
        for k, y in enumerate(ys):
            yy = y[idx]
            good = np.isfinite(yy)
            if good.sum() < 3:
                continue
            coef = np.linalg.lstsq(A[good], yy[good], rcond=None)[0]
            vals[k][i], ders[k][i] = coef[0], coef[1]
    return vals, ders, h


def plastic_dilatancy(eps_v, eps_q, p, q, others=None, rel=0.25, h_min=2e-4, min_deq=0.5,
                      moduli=None):
    """Plastic dilatancy d = d eps_v^p / d eps_q^p, the elastic parts removed with the test's own
    moduli (elastic_moduli) and derivatives from strain-adaptive local quadratics in eps_q
    (local_quadratic), no strain cut: a point is kept where the plastic shear flows
    (d eps_q^p / d eps_q >= min_deq, 0.5 by default, which leaves out the elastic start by itself:
    where the plastic part is less than half the increment, d is a ratio of two small differences
    whose error is the moduli's, and the 19,436-sphere tests show d rising there, against every
    flow rule, before it falls).

    others (dict of arrays: eta, p, e, theta, ...) are smoothed with the same windows. Returns a
    dict: d, deqp_deq, mask, moduli, h (the half-widths), and the smoothed others."""
    eps_v, eps_q, p, q = (np.asarray(a, float) for a in (eps_v, eps_q, p, q))
    mod = moduli if moduli is not None else elastic_moduli(eps_v, eps_q, p, q)
    evp, eqp = plastic_strains(eps_v, eps_q, p, q, mod["K"], mod["G"])
    others = others or {}
    names = list(others)
    vals, ders, h = local_quadratic(eps_q, [evp, eqp] + [others[k] for k in names], rel, h_min)
    with np.errstate(divide="ignore", invalid="ignore"):
        d = ders[0] / ders[1]
    out = {"d": d, "deqp_deq": ders[1], "moduli": mod, "h": h,
           "mask": np.isfinite(d) & np.isfinite(ders[1]) & (ders[1] >= min_deq)}
    for k, v in zip(names, vals[2:]):
        out[k] = v
    return out


def phase_transformation(d, mask, values, end=None):
    """The phase transformation: the first kept point where d turns from contraction (d > 0) to
    dilation (d < 0), interpolated linearly between the two points. values: dict of arrays (eta,
    psi, ...) interpolated there. Returns a dict (index, and each value) or None when d never turns
    (a loose sample that contracts to the critical state, or one dilating from its first point).
    end: only points up to this index are searched (the peak of eta: past it, d fluctuates about 0
    at the critical state, where a sign change is noise at psi ~ 0, not a phase transformation)."""
    idx = np.nonzero(mask)[0]
    if end is not None:
        idx = idx[idx <= end]
    if idx.size < 2:
        return None
    dd = np.asarray(d, float)[idx]
    for k in range(1, idx.size):
        if dd[k - 1] > 0 >= dd[k] and idx[k] - idx[k - 1] == 1:
            w = dd[k - 1] / (dd[k - 1] - dd[k])
            out = {"index": int(idx[k - 1])}
            for name, v in values.items():
                v = np.asarray(v, float)
                out[name] = float(v[idx[k - 1]] + w * (v[idx[k]] - v[idx[k - 1]]))
            return out
    return None


M_STUDY = 4.57   # the study's m
M_RANGE = (-20.0, 60.0)  # the range over which m is sought (the old fit's grid)


def fit_m_pt(psi, eta, M):
    """m of Li & Dafalias's d = d0 (M e^{m psi} - eta) from phase-transformation states (d = 0):
    ln(eta_PT / M) = c + m psi_PT, by least squares with the intercept c free.

    Why c free: at d = 0 the form says ln(eta_PT/M) = m psi, through the origin; but psi and M are
    measured (a CSL or an M off by a constant moves every point alike), and with c fixed at 0 m is
    then set by the points' level, not by how eta_PT changes with psi (the data of issue 45: psi
    ~ -0.20 for all, m from 0.2 to 17 by which CSL psi was taken from). With c free, m is the
    slope: identified only by a span of psi.
    Interval: the profile likelihood of m (Gaussian residuals, c profiled out), its 95 % region
    SSR(m) <= SSR_min (1 + F(0.95; 1, n - 2) / (n - 2)), the exact likelihood-ratio interval of a
    linear model (= m +- t SE); unbounded when psi does not vary, clipped to M_RANGE otherwise.
    Verdict (fixed before the data): "identified" iff n >= 4, the interval lies inside M_RANGE and
    is narrower than the study's m (4.57: it can tell m = 4.57 from m = 0); then "consistent with
    the study" if it contains 4.57, "not the study's" if not; otherwise "not identifiable".

    Returns a dict: n, m, se, interval [lo, hi] (NaN bounds where unbounded), c, m_origin (the
    through-origin fit, c = 0, for reference), psi_span, verdict, note."""
    from scipy import stats as st
    psi, eta = np.asarray(psi, float), np.asarray(eta, float)
    M = np.broadcast_to(np.asarray(M, float), psi.shape)
    ok = np.isfinite(psi) & np.isfinite(eta) & np.isfinite(M) & (eta > 0) & (M > 0)
    x, y = psi[ok], np.log(eta[ok] / M[ok])
    n = int(x.size)
    out = {"n": n, "m": NAN, "se": NAN, "interval": [NAN, NAN], "c": NAN, "m_origin": NAN,
           "psi_span": float(np.ptp(x)) if n else NAN, "verdict": "not identifiable", "note": ""}
    if n >= 1 and float(x @ x) > 0:
        out["m_origin"] = float(x @ y) / float(x @ x)
    if n < 3:
        out["note"] = f"{n} state(s): at least 3 needed for a slope and its error"
        return out
    xc, yc = x - x.mean(), y - y.mean()
    sxx = float(xc @ xc)
    if sxx <= 0:
        out["note"] = "psi does not vary across the points: the profile of m is flat (unbounded interval)"
        return out
    m = float(xc @ yc) / sxx
    ssr = float(np.sum((yc - m * xc) ** 2))
    out["m"], out["c"] = m, float(y.mean() - m * x.mean())
    out["se"] = math.sqrt(ssr / (n - 2) / sxx) if n > 2 else NAN
    f = float(st.f.ppf(0.95, 1, n - 2))
    half = math.sqrt(ssr * f / (n - 2) / sxx)   # SSR(m') = ssr + (m' - m)^2 sxx
    lo, hi = m - half, m + half
    inside = M_RANGE[0] <= lo and hi <= M_RANGE[1]
    out["interval"] = [lo if lo >= M_RANGE[0] else NAN, hi if hi <= M_RANGE[1] else NAN]
    width = hi - lo
    if n >= 4 and inside and width < M_STUDY:
        out["verdict"] = "consistent with the study" if lo <= M_STUDY <= hi else "not the study's"
    else:
        why = []
        if n < 4:
            why.append(f"{n} points < 4")
        if not inside:
            why.append(f"the interval leaves [{M_RANGE[0]:g}, {M_RANGE[1]:g}]")
        if width >= M_STUDY:
            why.append(f"its width {width:.3g} >= {M_STUDY}")
        out["note"] = "; ".join(why) + f" (psi spans {out['psi_span']:.3f})"
    return out


def initial_linear_part(eta, d, mask, min_points=5):
    """Slope s and intercept a of d = a + s eta over the test's initial branch: its kept points
    from the first up to the largest dilation (min d), where d falls as eta rises. Returns
    (a, s, n); NaN with fewer than min_points points."""
    idx = np.nonzero(mask)[0]
    if idx.size < min_points:
        return NAN, NAN, int(idx.size)
    dd = np.asarray(d, float)[idx]
    k = int(np.argmin(dd))
    sel = idx[:k + 1]
    if sel.size < min_points:
        return NAN, NAN, int(sel.size)
    e = np.asarray(eta, float)[sel]
    y = np.asarray(d, float)[sel]
    if np.ptp(e) <= 0:
        return NAN, NAN, int(sel.size)
    s, a = np.polyfit(e, y, 1)
    return float(a), float(s), int(sel.size)
