"""Lode-angle dependence of the critical stress ratio: M(theta) = M_c g(theta), the Lode angle and b
of a stress state, friction angles, and the fit of M_c and K = M_e/M_c."""
import math

import numpy as np

from .fitting import NAN, curve_fit, propagate, standard_errors


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
        popt, pcov = curve_fit(m_theta, theta, M, p0=[mc0, k0],
                               bounds=([1e-6, k_bounds[0]], [20.0, k_bounds[1]]))
    except (RuntimeError, ValueError) as exc:
        out["note"] = f"not fitted: {exc}"
        return out
    se = standard_errors(pcov, 2)
    if n <= 2:
        se[:] = NAN
        pcov = np.full((2, 2), NAN)
    Mc, K = map(float, popt)
    out["fitted"] = True
    out["params"] = {"M_c": Mc, "K": K, "M_e": Mc * K}
    out["stderr"] = {"M_c": float(se[0]), "K": float(se[1]),
                     "M_e": propagate(lambda v: v[0] * v[1], popt, pcov)}
    out["phi_c_deg"], out["phi_e_deg"] = friction_angles(Mc, Mc * K)
    out["se_phi_c_deg"] = propagate(lambda v: friction_angles(v[0], NAN)[0], popt, pcov)
    out["se_phi_e_deg"] = propagate(lambda v: friction_angles(NAN, v[0] * v[1])[1], popt, pcov)
    tol = 1e-3 * (k_bounds[1] - k_bounds[0])
    out["K_at_bound"] = bool(K <= k_bounds[0] + tol or K >= k_bounds[1] - tol)
    out["convex"] = bool(K >= 7.0 / 9.0)
    sphi = 3 * Mc / (6 + Mc)
    out["K_mohr_coulomb"] = (3 - sphi) / (3 + sphi)
    out["rms"] = float(np.sqrt(np.mean((M - m_theta(theta, Mc, K)) ** 2)))
    if out["K_at_bound"]:
        out["note"] = f"K at its bound ({K:.3f}); its standard error is not meaningful"
    return out


def principal_from(p, q, theta):
    """Principal stresses (s1, s2, s3) of the state (p, q, Lode angle theta: 0 compression, pi/3
    extension): s_k = p + 2q/3 cos(theta - 2 pi k / 3), k = 0, 1, -1."""
    theta = np.asarray(theta, float)
    return (p + 2.0 * q / 3.0 * np.cos(theta), p + 2.0 * q / 3.0 * np.cos(theta - 2.0 * np.pi / 3.0),
            p + 2.0 * q / 3.0 * np.cos(theta + 2.0 * np.pi / 3.0))


def _invariant_ratio(kind, eta, theta):
    s1, s2, s3 = principal_from(1.0, eta, theta)
    i1, i2, i3 = s1 + s2 + s3, s1 * s2 + s2 * s3 + s3 * s1, s1 * s2 * s3
    with np.errstate(divide="ignore", invalid="ignore"):
        return i1 * i2 / i3 if kind == "matsuoka_nakai" else i1 ** 3 / i3


def surface_M(kind, theta, Mc):
    """q/p at Lode angle theta on the Matsuoka-Nakai (I1 I2 / I3 constant) or Lade-Duncan (I1^3 / I3
    constant) surface through M_c in compression (the cone's constant from (p, q) = (1, M_c) at
    theta = 0). Solved for eta by bisection between 0 and the tensile limit s3 = 0."""
    theta = np.atleast_1d(np.asarray(theta, float))
    target = _invariant_ratio(kind, Mc, 0.0)
    out = np.full(theta.shape, NAN)
    for i, th in enumerate(theta):
        c3 = math.cos(th + 2.0 * math.pi / 3.0)  # s3 = 1 + 2 eta/3 c3 > 0 needs eta < -3/(2 c3)
        hi = -1.5 / c3 * (1 - 1e-12) if c3 < 0 else 50.0
        lo = 0.0
        f = lambda e: _invariant_ratio(kind, e, th) - target  # noqa: E731  rises with eta
        if not (np.isfinite(target) and f(hi) > 0):
            continue
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if f(mid) > 0:
                hi = mid
            else:
                lo = mid
        out[i] = 0.5 * (lo + hi)
    return out


def compare_surfaces(theta, M):
    """M(theta) of the critical points under four surfaces, by least squares and AIC:
    g(theta) (M_c, K: 2 parameters; fit_m_theta), Matsuoka-Nakai, Lade-Duncan and Mohr-Coulomb (M_c
    or phi: 1 parameter each). AIC = n ln(SSR/n) + 2k, AICc = AIC + 2k(k+1)/(n-k-1) (small n);
    delta = AICc - the smallest AICc. Returns a dict: n, forms (name -> params, k, ssr, rms, aic,
    aicc, delta, phi_e_deg), best; the verdict on the g form is left to the caller."""
    from scipy import optimize
    theta, M = np.asarray(theta, float).ravel(), np.asarray(M, float).ravel()
    ok = np.isfinite(theta) & np.isfinite(M)
    theta, M = theta[ok], M[ok]
    n = int(M.size)
    out = {"n": n, "forms": {}, "best": None}
    if n < 3:
        return out

    def score(name, pred, k, params, me):
        r = M - pred
        ssr = float(r @ r)
        aic = n * math.log(ssr / n) + 2 * k if ssr > 0 else -np.inf
        aicc = aic + (2 * k * (k + 1) / (n - k - 1) if n - k - 1 > 0 else np.inf)
        out["forms"][name] = {"params": params, "k": k, "ssr": ssr, "rms": math.sqrt(ssr / n), "aic": aic,
                              "aicc": aicc, "phi_e_deg": friction_angles(NAN, me)[1]}

    g = fit_m_theta(theta, M)
    if g["fitted"]:
        score("g(theta)", m_theta(theta, g["params"]["M_c"], g["params"]["K"]), 2,
              {"M_c": g["params"]["M_c"], "K": g["params"]["K"]}, g["params"]["M_e"])
    mc0 = float(np.mean(M[np.cos(3 * theta) > 0.5])) if np.any(np.cos(3 * theta) > 0.5) else float(M.mean())
    for name in ("matsuoka_nakai", "lade_duncan"):
        res = optimize.minimize_scalar(lambda mc: float(np.sum((M - surface_M(name, theta, mc)) ** 2)),
                                       bounds=(0.5 * mc0, 1.5 * mc0), method="bounded", options={"xatol": 1e-9})
        mc = float(res.x)
        score(name, surface_M(name, theta, mc), 1, {"M_c": mc}, float(surface_M(name, [math.pi / 3], mc)[0]))
    phi0 = math.asin(3 * mc0 / (6 + mc0))
    res = optimize.minimize_scalar(lambda ph: float(np.sum((M - mohr_coulomb_M(theta, ph)) ** 2)),
                                   bounds=(0.5 * phi0, min(1.5 * phi0, 1.5)), method="bounded",
                                   options={"xatol": 1e-10})
    ph = float(res.x)
    score("mohr_coulomb", mohr_coulomb_M(theta, ph), 1, {"phi_deg": math.degrees(ph)},
          float(mohr_coulomb_M(np.array([math.pi / 3]), ph)[0]))
    best = min(out["forms"], key=lambda k: out["forms"][k]["aicc"])
    for f in out["forms"].values():
        f["delta"] = f["aicc"] - out["forms"][best]["aicc"]
    out["best"] = best
    return out


def direct_friction_angles(theta, M, tol_deg=5.0):
    """phi_c and phi_e from the compression (theta within tol_deg of 0, b ~ 0) and extension (theta
    within tol_deg of 60 deg, b ~ 1) critical points directly: the mean M of each set, its standard
    error (sd / sqrt(n)) and the friction angle, no g(theta) assumed. Returns a dict: M_c, se_M_c,
    n_c, phi_c_deg, se_phi_c_deg, and the same for e."""
    theta, M = np.asarray(theta, float).ravel(), np.asarray(M, float).ravel()
    ok = np.isfinite(theta) & np.isfinite(M)
    theta, M = theta[ok], M[ok]
    out = {}
    for key, centre in (("c", 0.0), ("e", math.pi / 3)):
        sel = np.abs(theta - centre) <= math.radians(tol_deg)
        v = M[sel]
        n = int(v.size)
        mean = float(v.mean()) if n else NAN
        se = float(v.std(ddof=1) / math.sqrt(n)) if n > 1 else NAN
        if key == "c":
            phi = friction_angles(mean, NAN)[0]
            dphi = (friction_angles(mean + se, NAN)[0] - friction_angles(mean - se, NAN)[0]) / 2 if n > 1 else NAN
        else:
            phi = friction_angles(NAN, mean)[1]
            dphi = (friction_angles(NAN, mean + se)[1] - friction_angles(NAN, mean - se)[1]) / 2 if n > 1 else NAN
        out.update({f"M_{key}": mean, f"se_M_{key}": se, f"n_{key}": n, f"phi_{key}_deg": phi,
                    f"se_phi_{key}_deg": dphi})
    return out
