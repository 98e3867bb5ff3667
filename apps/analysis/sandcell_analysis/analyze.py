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
  --window W         critical-state window, deviatoric strain eps_q at the end of each test (0.1)
  --pre-strain S     eps_q the test must have run before that window (0.2): a test ending below
                     W + S is never called critical
  --min-points N     rows the window must hold (10)
  --tol-eta, --tol-p, --tol-z, --tol-fabric T   relative change + 2 SE over the window of eta, p,
                     Z_mech and the fabric anisotropy F_a (0.02, 0.02, 0.02, 0.05)
  --tol-e T          absolute change + 2 SE of the void ratio (0.005)
  --tol-epsv T       also test eps_v (absolute; default: untested, e bounds it)
  --all              fit the CSL and M(theta) with the end-window points of every test, also those
                     that did not reach the critical state (marked in tables and figures)
  --fix-xi X         fit the CSL with xi fixed at X
  --smooth R         dilatancy smoothing: local quadratics in eps_q over +-R eps_q (0.25)
  --smooth-min H     the smallest half-width of that window (2e-4)
  --min-strain S     dilatancy data start at eps_q >= S (0: no cut)
  --min-deq R        dilatancy data need d eps_q^p / d eps_q >= R (0.5): the elastic start is left out
  --moduli M         initial (each test's initial moduli remove the elastic strains) or none
  --dilatancy-path P path whose b = 0 tests give d0, m for the report's Li-Dafalias fit and Table 3
                     (default: constant_p if it has b = 0 tests, else constant_sigma3)
  --targets KEYS     verdicts that were calibration targets (e_gamma, lambda, xi, csl_curve, R, phi_c,
                     phi_e, d0, m): shown as targets, not reproductions
  --localization DIR the <test>-localization.csv of `triaxial localization --whole`: the table of
                     paths says which tests are banded (else "not judged")

Stress paths: every test is judged by the app's watchdog rules (path_check.py, with the tolerances of
  the file's [watch]); a test that failed (the file's status, or its series off its path) or has no
  verdict yet (running) enters no fit, table, trend or figure, and is listed in report.md (a table of
  paths: status, largest errors, turn of the axes, critical, banded) and summary.json (excluded,
  path_checks, warnings).

Critical state (per test; critical.py, version 3; --criterion v2 for the one before): found after the
  fact on the whole test, never by first passage. Over the last W of eps_q, least-squares lines through
  eta, p, e, Z_mech and F_a (F_a = sqrt(F':F'), F' = 15/2 dev(fabric)); each quantity's change over the
  window plus twice its standard error (OLS x sqrt((1 + r1)/(1 - r1)), r1 the residuals' lag-1
  autocorrelation: serially correlated rows), six times where the window holds fewer than 10 effective
  rows n (1 - r1)/(1 + r1) (version 2: twice whatever the window), must be within its tolerance. The
  window must hold >= --min-points rows over 90 % of W and the test must have reached W + --pre-strain.
  The critical point: the window means; e_c
  is its void ratio, M = mean q / mean p, b and theta of the window-mean stress tensor. The
  first-passage test of the 2026-11-28 campaigns (version 1: 5 % of eps_1, the change alone) is
  applied to the same rows (the tests table's v1 column) and, where a test is critical, replayed to
  measure the early stop's bias.

CSL: e_CSL(p) = e_Gamma - lambda (p/p_a)^xi (Li & Wang 1998) through the critical points (p_c, e_c),
  p_a = 101.325 kPa, fitted by nonlinear
  least squares (the exact optimum over xi by variable projection, then scipy curve_fit from it for
  the covariance). Needs >= 3 distinct p (10 % apart) and >= 4 points; with 2 distinct p (or 3
  points) xi is fixed at 1 (fallback, marked); with 1 it is not fitted. Standard errors from the
  residual variance. R = sqrt(R^2). Residuals are also reported per b (uniqueness of the CSL).
M(theta) = M_c g(theta), g = 2K/((1+K) - (1-K) cos 3theta) (K = M_e/M_c, bounds 0.5..1; a convex
  surface needs K >= 7/9), fitted to q_c/p_c and theta_c. sin phi_c = 3M_c/(6+M_c),
  sin phi_e = 3M_e/(6-M_e).
Dilatancy d = d eps_v^p / d eps_q^p (compression positive: d < 0 is dilation), the elastic parts
  removed: eps_v^p = eps_v - (p - p0)/K, eps_q^p = eps_q - (q - q0)/(3G), K and G each test's initial
  tangent moduli (dilatancy.elastic_moduli; K not measured, and dp/K taken as 0, where p is held).
  Derivatives from local quadratics in eps_q over +-max(H, R eps_q) (a constant width in log strain:
  the pre-peak branch and the phase transformation are kept). psi and M from each (path, b) group's
  own CSL (e_Gamma, lambda fitted; xi the pooled fit's) and mean q_c/p_c (the groups' end windows,
  marked, where their critical points span < 2 distinct p).
  m: from each test's phase transformation (d = 0; else its peak with eta* = eta - d/s), ln(eta*/M)
  = c + m psi with c free, 95 % profile-likelihood interval; "not identifiable" unless >= 4 states
  and the interval inside [-20, 60] and narrower than 4.57.
  Li & Dafalias (2000): d = d0/M (M exp(m psi) - eta), fitted on the b = 0 tests (as the study did).
  3D, Li's form: d = d0/M_c (M_c g(theta) exp(m psi) - eta), d0 and m from b = 0.
  3D, g-dependent: d0(theta) = d0 g^-alpha, m(theta) = m g^beta (the study's exact expression is
  not available), alpha and beta fitted on the b > 0 tests of a path; judged by cross-validation:
  fitted on constant p it predicts constant sigma3 and the reverse.
  The study's Fig 10(e): slope and intercept of d = a + s eta over each test's initial branch (to
  its largest dilation), by Spearman rho with b.
M(theta) surfaces: g(theta), Matsuoka-Nakai, Lade-Duncan and Mohr-Coulomb compared by AICc; the
  friction angles also from the b = 0 and b = 1 critical points directly.
"""
import argparse
import datetime
import json
import math
import os
import sys
import time

import numpy as np
from scipy import stats

from .critical import (APP_CRITERION_V1, CRITERIA, V3_DEFAULTS, detect_critical, detect_critical_v1,
                       first_critical_row)
from .csl import csl_e, distinct_levels, fit_csl
from .dilatancy import (M_STUDY, dilatancy_g, dilatancy_li3d, fit_g_form, fit_li_dafalias, fit_m_pt,
                        initial_linear_part, phase_transformation, plastic_dilatancy, slope_max_dilation)
from .fitting import NAN
from .m_theta import b_of_stress, compare_surfaces, direct_friction_angles, fit_m_theta, lode_from_b
from .path_check import DEFAULTS as PATH_DEFAULTS
from .path_check import check_file as check_path
from .reference import CRIT, STUDY
from .results import PATHS, InputError, attr, b_key, collect_files, open_results, read_test, to_float


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


def _group_states(tests, csl, opt):
    """Each (path, b) group's own CSL and critical stress ratio M, for its tests' psi and M.

    Points: the group's tests that reached the critical state (every test with --all); where those
    give fewer than 2 distinct p, the end windows of all the group's tests, marked "end windows (not
    proven critical)". The CSL: e_Gamma and lambda fitted with xi fixed at the pooled fit's xi (the
    study's where the pooled CSL is not fitted): a group holds at most 6 p0, too few for xi. M: the
    mean q_c/p_c of the same points. Returns {(path, b): dict(csl (params), M, source, n, note)}."""
    xi = csl["params"]["xi"] if csl["fitted"] and np.isfinite(csl["params"]["xi"]) else STUDY["xi"]
    out = {}
    # the fallback of a group with < 2 distinct p: the pooled CSL, else one through every end window
    if csl["fitted"]:
        fallback, fb_note = dict(csl["params"]), "group CSL not fitted (< 2 distinct p): the pooled CSL"
    else:
        fb = fit_csl([t["critical"]["point"]["p"] for t in tests], [t["critical"]["point"]["e"] for t in tests], xi=xi)
        if fb["fitted"]:
            fallback = dict(fb["params"])
            fb_note = "group CSL not fitted (< 2 distinct p): the CSL through every test's end window"
        else:
            fallback = {"e_gamma": STUDY["e_gamma"], "lambda": STUDY["lambda"], "xi": STUDY["xi"]}
            fb_note = "group CSL not fitted (< 2 distinct p): the study's CSL"
    keys = sorted({(t["path"], b_key(t)) for t in tests if np.isfinite(b_key(t))})
    for key in keys:
        ts = [t for t in tests if (t["path"], b_key(t)) == key]
        src = "critical points"
        pts = [t for t in ts if t["critical"]["reached"]]
        p = np.array([t["critical"]["point"]["p"] for t in pts], float)
        if distinct_levels(p) < 2:
            pts, src = ts, "end windows (not proven critical)"
        p = np.array([t["critical"]["point"]["p"] for t in pts], float)
        e = np.array([t["critical"]["point"]["e"] for t in pts], float)
        M = np.array([t["critical"]["point"]["M"] for t in pts], float)
        fit = fit_csl(p, e, xi=xi)
        if fit["fitted"]:
            par, note = dict(fit["params"]), ""
        else:
            par, note = dict(fallback), fb_note
        out[key] = {"path": key[0], "b": key[1], "csl": par, "M": float(np.nanmean(M)) if M.size else NAN,
                    "source": src, "n": len(pts), "note": note}
    return out


def characteristic_state(t, slope):
    """The test's state for m: its phase transformation (d = 0) where d turns before the peak of eta
    (past it d crosses 0 by noise at the critical state, psi ~ 0: not a phase transformation), else its peak stress
    ratio (the largest smoothed eta among the kept points) with eta* = eta - d/s (s < 0: the
    group's initial slope of d against eta; for Li & Dafalias, M e^{m psi} = eta - d/s at any
    state, eta at d = 0)."""
    dl = t["dil"]
    mk = dl["mask"]
    kept = np.nonzero(mk)[0]
    peak = int(kept[int(np.nanargmax(dl["eta"][kept]))]) if kept.size and np.any(np.isfinite(dl["eta"][kept])) else None
    pt = phase_transformation(dl["d"], mk, {"eta": dl["eta"], "psi": dl["psi"], "eps_q": t["eps_q"],
                                            "p": dl["p"]}, end=peak)
    if pt is not None:
        return {"kind": "phase transformation", "eta": pt["eta"], "psi": pt["psi"], "d": 0.0,
                "eta_star": pt["eta"], "eps_q": pt["eps_q"]}
    idx = np.nonzero(mk)[0]
    if idx.size == 0 or not (np.isfinite(slope) and slope < 0):
        return None
    k = idx[int(np.nanargmax(dl["eta"][idx]))]
    star = float(dl["eta"][k] - dl["d"][k] / slope)
    return {"kind": "peak" if star > 0 else "peak, eta* <= 0", "eta": float(dl["eta"][k]),
            "psi": float(dl["psi"][k]), "d": float(dl["d"][k]), "eta_star": star if star > 0 else NAN,
            "eps_q": float(t["eps_q"][k])}


def _mse(d, pred):
    r = d - pred
    return float(np.mean(r ** 2)) if r.size else NAN


def _aic(d, pred, k):
    r = d - pred
    n = r.size
    ssr = float(r @ r)
    return n * math.log(ssr / n) + 2 * k if n and ssr > 0 else NAN


def _path_model(tests, path, groups):
    """Li's (d0, m at b = 0, M of the group) and the g-dependent form (alpha, beta at b > 0) fitted
    on one path; M_c and K from that path's b = 0 and b = 1 groups."""
    zero = [t for t in tests if t["path"] == path and b_key(t) == 0]
    pos = [t for t in tests if t["path"] == path and np.isfinite(b_key(t)) and b_key(t) > 0]
    g0, g1 = groups.get((path, 0.0)), groups.get((path, 1.0))
    Mc = g0["M"] if g0 else NAN
    K = g1["M"] / Mc if g1 and np.isfinite(Mc) else NAN
    K = min(max(K, 0.5), 1.0) if np.isfinite(K) else NAN
    eta, psi, d = _pooled(zero, "eta", "psi", "d")
    ld = fit_li_dafalias(eta, psi, d, Mc)
    eta, psi, th, d = _pooled(pos, "eta", "psi", "theta", "d")
    gf = fit_g_form(eta, psi, th, d, Mc, K, ld["params"]["d0"], ld["params"]["m"])
    return {"path": path, "M_c": Mc, "K": K, "li": ld, "g": gf, "tests_b0": [t["name"] for t in zero],
            "tests_b": [t["name"] for t in pos]}


def _pooled(ts, *keys):
    return [np.concatenate([t["dil"][k][t["dil"]["mask"]] for t in ts]) if ts else np.array([]) for k in keys]


def _predict(model, ts):
    """MSE and AIC of Li's 3D form and the g-dependent form of `model` on tests ts (b > 0)."""
    eta, psi, th, d = _pooled(ts, "eta", "psi", "theta", "d")
    Mc, K = model["M_c"], model["K"]
    d0, m = model["li"]["params"]["d0"], model["li"]["params"]["m"]
    al, be = model["g"]["params"]["alpha"], model["g"]["params"]["beta"]
    out = {"n": int(d.size), "mse_li3d": NAN, "mse_g": NAN, "aic_li3d": NAN, "aic_g": NAN}
    if d.size and all(np.isfinite(v) for v in (Mc, K, d0, m)):
        pl = dilatancy_li3d(eta, psi, th, Mc, K, d0, m)
        out["mse_li3d"], out["aic_li3d"] = _mse(d, pl), _aic(d, pl, 2)
        if np.isfinite(al) and np.isfinite(be):
            pg = dilatancy_g(eta, psi, th, Mc, K, d0, m, al, be)
            out["mse_g"], out["aic_g"] = _mse(d, pg), _aic(d, pg, 4)
    return out


def cross_validate_3d(tests, groups):
    """The g-dependent 3D form against Li's 3D form, judged out of the fitting path: fitted on
    constant p, predicting constant sigma3's b > 0 tests, and the reverse. Verdict (fixed before the
    data): "reproduced" (the g form predicts better) iff its MSE on the other path is lower in both
    directions; "not reproduced" if it is higher in either; "not testable" unless both directions
    have data and fitted models. AIC (k = 2: d0, m; 4: + alpha, beta) on the fitting path is
    reported beside it."""
    paths = [pk for pk in ("constant_p", "constant_sigma3") if any(t["path"] == pk for t in tests)]
    models = {pk: _path_model(tests, pk, groups) for pk in paths}
    rows = []
    for a, b in (("constant_p", "constant_sigma3"), ("constant_sigma3", "constant_p")):
        if a not in models or b not in models:
            continue
        pos_a = [t for t in tests if t["path"] == a and np.isfinite(b_key(t)) and b_key(t) > 0]
        pos_b = [t for t in tests if t["path"] == b and np.isfinite(b_key(t)) and b_key(t) > 0]
        rows.append({"fitted_on": a, "predicts": b, "in_path": _predict(models[a], pos_a),
                     "out_of_path": _predict(models[a], pos_b)})
    good = [r for r in rows if np.isfinite(r["out_of_path"]["mse_g"]) and np.isfinite(r["out_of_path"]["mse_li3d"])]
    if len(good) < 2:
        verdict = "not testable"
    elif all(r["out_of_path"]["mse_g"] < r["out_of_path"]["mse_li3d"] for r in good):
        verdict = "reproduced"
    else:
        verdict = "not reproduced"
    return {"models": models, "rows": rows, "verdict": verdict,
            "criterion": "MSE(g form) < MSE(Li 3D) on the other path's b > 0 tests, in both directions "
                         "(fit on constant p, predict constant sigma3, and the reverse)"}


def _criterion(opt):
    """The version --criterion names (v3 when opt has none: callers that build opt themselves)."""
    return getattr(opt, "criterion", "v3")


def _k_short(opt):
    """Standard errors to spare in a window of few effective rows, as the version asks."""
    return CRITERIA[_criterion(opt)]["k_short"]


def analyze_tests(tests, opt):
    """Run every step on the loaded tests; returns the summary dict (tests gain their series)."""
    warn = []
    for t in tests:
        eps1 = t["eps1"]
        # Version 3 (or 2), after the fact on the whole test's last window of eps_q (never first passage).
        t["critical"] = detect_critical(
            t["eps_q"], t, window=opt.window, tol_eta=opt.tol_eta, tol_p=opt.tol_p, tol_e=opt.tol_e,
            tol_z=opt.tol_z, tol_fabric=opt.tol_fabric, tol_epsv=opt.tol_epsv, pre_strain=opt.pre_strain,
            min_points=opt.min_points, k_short=_k_short(opt))
        # Version 1 on the same series (the early stop's test), for the bias of stopping there.
        t["critical_v1"] = detect_critical_v1(eps1, t, **APP_CRITERION_V1)
        if not np.isfinite(t["b_nominal"]):
            t["b_nominal"] = round(t["critical"]["point"].get("b", NAN), 2)
        i = int(np.nanargmax(t["eta"])) if np.any(np.isfinite(t["eta"])) else 0
        j = int(np.nanargmax(t["q"]))
        t["peak"] = {"eta": float(t["eta"][i]), "eps1_eta": float(eps1[i]),
                     "q": float(t["q"][j]), "eps1_q": float(eps1[j])}
        t["end"] = {"eps1": float(eps1[-1]), "eps_q": float(t["eps_q"][-1]), "eps_v": float(t["eps_v"][-1]),
                    "e": float(t["e"][-1])}
        t["used"] = bool(t["critical"]["reached"] or opt.all)

    early = early_stop_bias(tests)
    used = [t for t in tests if t["used"]]
    cp = lambda k: np.array([t["critical"]["point"][k] for t in used], float)  # noqa: E731
    csl = fit_csl(cp("p"), cp("e"), b=np.array([b_key(t) for t in used]), xi=opt.fix_xi)
    csl["points"] = "end windows of every test (--all)" if opt.all else \
        "tests that reached the critical state"
    if not used:
        csl["note"] = "not fitted: no test reached the critical state (see --all)"
    mth = fit_m_theta(cp("theta"), cp("M"))
    surfaces = compare_surfaces(cp("theta"), cp("M"))
    direct = direct_friction_angles(cp("theta"), cp("M"))

    # For reference, without verdicts: the same fits through every test's end window.
    ends = {}
    if not opt.all:
        ep = lambda k: np.array([t["critical"]["point"][k] for t in tests], float)  # noqa: E731
        ends = {"csl": fit_csl(ep("p"), ep("e"), b=np.array([b_key(t) for t in tests]), xi=opt.fix_xi),
                "m_theta": fit_m_theta(ep("theta"), ep("M")), "surfaces": compare_surfaces(ep("theta"), ep("M")),
                "direct_friction": direct_friction_angles(ep("theta"), ep("M")), "n": len(tests)}
        if ends["csl"]["fitted"]:
            pp = np.geomspace(*ends["csl"]["p_range"], 50)
            par = ends["csl"]["params"]
            ends["csl_curve"] = float(np.max(np.abs(csl_e(pp, par["e_gamma"], par["lambda"], par["xi"])
                                                    - csl_e(pp, STUDY["e_gamma"], STUDY["lambda"], STUDY["xi"]))))
    if csl["fitted"]:
        cpar = csl["params"]
        psi_source = "fitted CSL"
    else:
        cpar = {"e_gamma": STUDY["e_gamma"], "lambda": STUDY["lambda"], "xi": STUDY["xi"]}
        psi_source = "study's CSL (own CSL not fitted)"
        warn.append("psi0 computed with the study's CSL because the pooled CSL could not be fitted")
    groups = _group_states(tests, csl, opt)
    for t in tests:
        others = {k: t[k] for k in ("eta", "p", "e", "theta")}
        st = t.get("stress")
        if st is not None and np.asarray(st).shape == (t["rows"], 6) and np.isfinite(st).all():
            others.update({f"s{k}": st[:, k] for k in range(6)})
        dil = plastic_dilatancy(t["eps_v"], t["eps_q"], t["p"], t["q"], others=others, rel=opt.smooth,
                                h_min=opt.smooth_min, min_deq=opt.min_deq,
                                moduli={"K": NAN, "G": NAN, "rows": 0, "note": "--moduli none"}
                                if opt.moduli == "none" else None)
        if "s0" in dil:
            dil["theta_rows"] = dil["theta"]
            dil["b"] = b_of_stress(np.column_stack([dil.pop(f"s{k}") for k in range(6)]))
            dil["theta"] = lode_from_b(dil["b"])
        dil["mask"] &= t["eps_q"] >= opt.min_strain
        g = groups.get((t["path"], b_key(t)))
        par = g["csl"] if g else cpar
        dil["psi"] = dil["e"] - csl_e(dil["p"], par["e_gamma"], par["lambda"], par["xi"])
        dil["M"] = g["M"] if g else NAN
        t["dil"] = dil
        m = dil["mask"]
        t["min_d"] = float(np.min(dil["d"][m])) if np.any(m) else NAN
        t["eps1_min_d"] = float(t["eps1"][m][np.argmin(dil["d"][m])]) if np.any(m) else NAN
        # The largest dilation rate against the axial strain, -d eps_v / d eps_1 (slopes over 1 %
        # of eps_1): where b changes d eps_q / d eps_1, this and -min(d) can order the b apart.
        t["max_dv_de1"] = slope_max_dilation(t["eps1"], t["eps_v"], t["eps1"])
        t["psi0"] = float(t["e"][0] - csl_e(t["p"][0], cpar["e_gamma"], cpar["lambda"], cpar["xi"]))
        t["psi0_group"] = float(t["e"][0] - csl_e(t["p"][0], par["e_gamma"], par["lambda"], par["xi"]))
        a, s, n = initial_linear_part(dil["eta"], dil["d"], m)
        t["initial_linear"] = {"intercept": a, "slope": s, "n": n}

    # m from the phase transformation (or peak) states, each test with its group's M and CSL.
    for key, g in groups.items():
        s = [t["initial_linear"]["slope"] for t in tests if (t["path"], b_key(t)) == key]
        g["initial_slope"] = float(np.nanmedian(s)) if np.any(np.isfinite(s)) else NAN
    states = []
    for t in tests:
        g = groups.get((t["path"], b_key(t)))
        t["state_m"] = characteristic_state(t, g["initial_slope"] if g else NAN)
        if t["state_m"] is not None:
            states.append((t, t["state_m"], g["M"] if g else NAN))
    m_fit = fit_m_pt([s["psi"] for _, s, _ in states], [s["eta_star"] for _, s, _ in states],
                     [M for _, _, M in states])
    # psi and M of a group whose CSL runs through end windows not proven critical are not measured
    # against a critical state: no verdict on m rests on them (the fit is still reported).
    unproven = sorted({f"{g['path']}, b = {g['b']:g}" for t, _, _ in states
                       for g in [groups.get((t["path"], b_key(t)))] if g and g["source"] != "critical points"})
    m_fit["unproven_groups"] = unproven
    if unproven and m_fit["verdict"] != "not identifiable":
        m_fit["verdict_data"] = m_fit["verdict"]
        m_fit["verdict"] = "not identifiable"
        m_fit["note"] = (f"the interval would say: {m_fit['verdict_data']}; but psi and M of {len(unproven)} "
                         "group(s) come from end windows not proven critical")
    m_fit["states"] = [{"test": t["name"], **s, "M": M} for t, s, M in states]
    m_fit["kinds"] = {k: sum(s["kind"] == k for _, s, _ in states)
                      for k in ("phase transformation", "peak", "peak, eta* <= 0")}
    m_fit["kinds"]["none"] = sum(t["state_m"] is None for t in tests)
    m_fit["by_path"] = {}
    for pk in sorted({t["path"] for t in tests}):
        sel = [(t, s, M) for t, s, M in states if t["path"] == pk]
        r = fit_m_pt([s["psi"] for _, s, _ in sel], [s["eta_star"] for _, s, _ in sel], [M for _, _, M in sel])
        if any(u.startswith(pk + ",") for u in unproven) and r["verdict"] != "not identifiable":
            r["note"] = f"psi from end windows (the interval would say: {r['verdict']})"
            r["verdict"] = "not identifiable"
        m_fit["by_path"][pk] = {k: r[k] for k in ("n", "m", "se", "interval", "psi_span", "verdict", "note")}

    # Li & Dafalias (d0, m) on the b = 0 tests of one path, as the study fitted them (for reference).
    if opt.dilatancy_path:
        dpath = opt.dilatancy_path
    else:
        dpath = next((pk for pk in ("constant_p", "constant_sigma3")
                      if any(t["path"] == pk and b_key(t) == 0 for t in tests)), None)
    cv = cross_validate_3d(tests, groups)
    # Every dilatancy verdict that reads psi needs CSLs of proven critical states (as m above).
    psi_unproven = any(g["source"] != "critical points" for g in groups.values())
    if psi_unproven and cv["verdict"] != "not testable":
        cv["verdict_data"], cv["verdict"] = cv["verdict"], "not testable"
        cv["note"] = (f"the MSEs would say: {cv['verdict_data']}; but psi comes from end windows not proven "
                      "critical")
    model = cv["models"].get(dpath) if dpath else None
    if model is None:
        model = _path_model(tests, dpath, groups) if dpath else None
    if model is not None:
        ld, gf = model["li"], model["g"]
        Mc, K = model["M_c"], model["K"]
        ld["tests"], gf["tests"] = model["tests_b0"], model["tests_b"]
    else:
        ld = fit_li_dafalias([], [], [], NAN)
        gf = fit_g_form([], [], [], [], NAN, NAN, NAN, NAN)
        ld["tests"], gf["tests"] = [], []
        Mc, K = NAN, NAN
        ld["note"] = "not fitted: no b = 0 test on a constant-p or constant-sigma3 path"
    ld["path"], gf["path"] = dpath, dpath
    ld["M_source"] = f"mean q/p of the group ({dpath}, b = 0)'s {groups[(dpath, 0.0)]['source']}" \
        if dpath and (dpath, 0.0) in groups else "none"

    # Table 3: MSE per (path, b) of both 3D forms, with the dilatancy path's model.
    mse = []
    d0, mm = ld["params"]["d0"], ld["params"]["m"]
    alpha, beta = gf["params"]["alpha"], gf["params"]["beta"]
    for pk in sorted({t["path"] for t in tests}):
        for bk in sorted({b_key(t) for t in tests if t["path"] == pk and np.isfinite(b_key(t))}):
            ts = [t for t in tests if t["path"] == pk and b_key(t) == bk]
            eta_, psi_, th_, d_ = _pooled(ts, "eta", "psi", "theta", "d")
            row = {"path": pk, "b": bk, "n": int(d_.size), "tests": len(ts),
                   "mse_li3d": NAN, "mse_g": NAN}
            if d_.size and all(np.isfinite(v) for v in (Mc, K, d0, mm)):
                row["mse_li3d"] = _mse(d_, dilatancy_li3d(eta_, psi_, th_, Mc, K, d0, mm))
                if np.isfinite(alpha):
                    row["mse_g"] = _mse(d_, dilatancy_g(eta_, psi_, th_, Mc, K, d0, mm, alpha, beta))
            mse.append(row)

    trends = evaluate_trends(tests, csl, mse, dpath, opt, cv)
    verdicts = study_verdicts(csl, mth, ld, direct, surfaces, m_fit, opt, psi_unproven)
    return {"csl": csl, "m_theta": mth, "psi_source": psi_source, "li_dafalias": ld,
            "g_form": gf, "mse": mse, "trends": trends, "verdicts": verdicts, "warnings": warn,
            "dilatancy_path": dpath, "M_c_dilatancy": Mc, "groups": list(groups.values()),
            "m_identification": m_fit, "cross_validation": cv, "surfaces": surfaces,
            "direct_friction": direct, "early_stop": early, "end_windows": ends}


def early_stop_bias(tests):
    """Where a test reached the critical state (version 3, or 2) at its end: the state at which the
    version 1 first-passage test would have stopped it (replayed row by row on its series) against
    end state. Rows: test, eps_q_v1 (where v1 stops), d_eta and d_e (v1 - end), d_p_rel
    (p_v1 / p_end - 1), and both points ("v1", "end")."""
    rows = []
    for t in tests:
        if not t["critical"]["reached"]:
            continue
        keys = ("p", "q", "eta", "e", "eps_v")
        n = first_critical_row(t["eps1"], {k: t[k] for k in keys}, criterion="v1")
        if n is None:
            rows.append({"test": t["name"], "eps_q_v1": NAN, "d_eta": NAN, "d_e": NAN, "d_p_rel": NAN,
                         "note": "version 1 never passes"})
            continue
        prefix = {k: t[k][:n] for k in keys + ("eps_q",)}
        v1 = detect_critical_v1(t["eps1"][:n], prefix, **APP_CRITERION_V1)["point"]
        end = t["critical"]["point"]
        rows.append({"test": t["name"], "eps_q_v1": float(t["eps_q"][n - 1]), "d_eta": v1["eta"] - end["eta"],
                     "d_e": v1["e"] - end["e"], "d_p_rel": v1["p"] / end["p"] - 1.0, "v1": v1,
                     "end": {k: end[k] for k in ("p", "q", "eta", "e", "M")}})
    return rows


def evaluate_trends(tests, csl, mse, dpath, opt, cv=None):
    groups = {}
    for t in tests:
        groups.setdefault((t["path"], t["p0"]), []).append(t)

    def trend(name, statement, value, sign, label, only_used=False):
        rows = []
        for (pk, p0), ts in sorted(groups.items()):
            if only_used:
                ts = [t for t in ts if t["used"]]
            b = [b_key(t) for t in ts]
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
        trend("dilation_eps1_grows", "dilation against eps_1 grows with b (supplementary)",
              lambda t: t["max_dv_de1"], +1, "max -d eps_v / d eps_1"),
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
    # The study's Fig 10(e): the initial linear part of d against eta (its kept points up to the
    # largest dilation) steepens and rises with b. "Grows" fixed before the data: the slope's
    # magnitude |s| (d = a + s eta, s < 0) and the intercept a, each by Spearman rho >= +0.8.
    out.append(trend("initial_slope_grows", "the slope of the initial linear part of d against eta grows "
                     "with b (the study's Fig 10(e))", lambda t: abs(t["initial_linear"]["slope"]), +1,
                     "abs(slope) of d = a + s eta, initial branch"))
    out.append(trend("initial_intercept_grows", "the intercept of the initial linear part of d against eta "
                     "grows with b (the study's Fig 10(e))", lambda t: t["initial_linear"]["intercept"], +1,
                     "intercept a of d = a + s eta, initial branch"))
    # The g-dependent 3D form judged out of its fitting path (cross_validate_3d).
    rows = []
    if cv is not None:
        for r in cv["rows"]:
            o = r["out_of_path"]
            rows.append({"b": NAN, "fitted_on": r["fitted_on"], "predicts": r["predicts"], "n": o["n"],
                         "mse_g": o["mse_g"], "mse_li3d": o["mse_li3d"],
                         "aic_g_in_path": r["in_path"]["aic_g"], "aic_li3d_in_path": r["in_path"]["aic_li3d"]})
    out.append({"name": "g_form_better",
                "statement": "the g-dependent 3D form predicts d better than Li's 3D form at b > 0",
                "quantity": "MSE of d on the other path", "verdict": cv["verdict"] if cv else "not testable",
                "criterion": cv["criterion"] if cv else "cross-validation across paths",
                "groups": rows})
    return out


# Which verdicts a calibration can have used as targets (--targets): the calibrated campaigns'
# targets were the study's critical state at b = 0 (M_c, i.e. phi_c, and the CSL).
TARGET_KEYS = ("e_gamma", "lambda", "xi", "csl_curve", "R", "phi_c", "phi_e", "d0", "m")


def _role(key, opt):
    return "calibration target" if key in (getattr(opt, "targets", None) or ()) else "prediction"


def study_verdicts(csl, mth, ld, direct=None, surfaces=None, m_fit=None, opt=None, psi_unproven=False):
    """Every published constant against sandcell's, by a criterion fixed before the data; each row
    says whether it was a calibration target (--targets) or a prediction."""
    v = []

    def add(key, quantity, value, se, study, verdict, criterion):
        v.append({"key": key, "quantity": quantity, "value": value, "se": se, "study": study, "verdict": verdict,
                  "criterion": criterion, "role": _role(key, opt)})

    tol = CRIT["e_abs"]
    value, se = csl["params"]["e_gamma"], csl["stderr"]["e_gamma"]
    if not csl["fitted"] or csl["xi_at_bound"]:
        verdict = "not testable"
    elif np.isfinite(se) and 2 * se > tol:
        verdict = "not testable"
    else:
        verdict = "reproduced" if abs(value - STUDY["e_gamma"]) <= tol else "not reproduced"
    add("e_gamma", "CSL e_Gamma", value, se, STUDY["e_gamma"], verdict,
        f"abs(e_Gamma - 0.699) <= {tol:g} (a void ratio: absolute; not testable if 2 SE > {tol:g})")
    for k, label in (("lambda", "lambda"), ("xi", "xi")):
        value, se = csl["params"][k], csl["stderr"][k]
        if not csl["fitted"] or csl["xi_at_bound"] or (k == "xi" and csl["mode"] != "full"):
            verdict = "not testable"
        else:
            verdict = compare(value, se, STUDY[k], CRIT["csl_rel"])
        add(k, f"CSL {label}", value, se, STUDY[k], verdict,
            f"within 2 SE or {100 * CRIT['csl_rel']:g} % of the study's (not testable if 2 SE > the study's "
            "value); lambda and xi trade off: the curve below is the void-ratio test")
    if csl["fitted"]:
        pp = np.geomspace(*csl["p_range"], 50)
        par = csl["params"]
        dev = float(np.max(np.abs(csl_e(pp, par["e_gamma"], par["lambda"], par["xi"])
                                  - csl_e(pp, STUDY["e_gamma"], STUDY["lambda"], STUDY["xi"]))))
        verdict = "reproduced" if dev <= CRIT["csl_curve"] else "not reproduced"
    else:
        dev, verdict = NAN, "not testable"
    add("csl_curve", "CSL curve: max abs(e_CSL - e_CSL,study) over the tested p", dev, NAN, 0.0, verdict,
        f"<= {CRIT['csl_curve']} (absolute)")
    R = csl["R"]
    add("R", "CSL R", R, NAN, STUDY["R"],
        "not testable" if not np.isfinite(R) else ("reproduced" if R >= CRIT["R_min"] else "not reproduced"),
        f"R >= {CRIT['R_min']}")
    phi = STUDY["phi_deg"]
    ptol = CRIT["phi_tol_deg"]
    for k, label in (("phi_c_deg", "phi_c (deg), g(theta) fit"), ("phi_e_deg", "phi_e (deg), g(theta) fit")):
        value = mth[k]
        verdict = "not testable" if not np.isfinite(value) else (
            "reproduced" if abs(value - phi) <= ptol else "not reproduced")
        add(k[:5], label, value, mth["se_" + k], phi, verdict, f"within {ptol:g} deg of 22")
    if direct is not None:
        for k, label, where in (("c", "phi_c (deg), b = 0 tests directly", "theta within 5 deg of 0"),
                                ("e", "phi_e (deg), b = 1 tests directly", "theta within 5 deg of 60 deg")):
            value, se = direct[f"phi_{k}_deg"], direct[f"se_phi_{k}_deg"]
            verdict = "not testable" if not np.isfinite(value) else (
                "reproduced" if abs(value - phi) <= ptol else "not reproduced")
            add(f"phi_{k}", label, value, se, phi, verdict,
                f"within {ptol:g} deg of 22; mean q_c/p_c of the {direct[f'n_{k}']} critical points with {where}")
    if surfaces is not None and surfaces.get("best"):
        f = surfaces["forms"]
        others = sorted((x["delta"], name) for name, x in f.items() if name != surfaces["best"])
        margin = others[0][0] if others else NAN
        if margin >= CRIT["aic_margin"]:
            verdict = f"{surfaces['best']} preferred"
        else:
            verdict = f"not distinguishable ({surfaces['best']} and {others[0][1]} within {CRIT['aic_margin']:g})"
        add("surface", "M(theta): g(theta) vs Matsuoka-Nakai vs Lade-Duncan vs Mohr-Coulomb", margin, NAN, NAN,
            verdict, f"smallest AICc preferred when the next is >= {CRIT['aic_margin']:g} above it")
    for k in ("d0", "m"):
        value, se = ld["params"][k], ld["stderr"][k]
        verdict = "not testable" if psi_unproven else compare(value, se, STUDY[k], CRIT["dil_rel"])
        add(k if k == "d0" else "m_ld", f"Li-Dafalias {k} (b = 0, least squares on d)", value, se, STUDY[k], verdict,
            f"within 2 SE or {100 * CRIT['dil_rel']:g} % of the study's (not testable if 2 SE > the study's value, "
            "or psi from end windows not proven critical)")
    if m_fit is not None:
        verdict = {"consistent with the study": "reproduced", "not the study's": "not reproduced"}.get(
            m_fit["verdict"], "not identifiable")
        lo, hi = m_fit["interval"]
        add("m", "Li-Dafalias m, phase-transformation / peak states, 95 % profile-likelihood interval",
            m_fit["m"], m_fit["se"], M_STUDY, verdict,
            f"identifiable iff >= 4 states, the interval inside [-20, 60] and narrower than {M_STUDY}, and psi "
            f"from CSLs of proven critical states; then "
            f"reproduced iff it holds {M_STUDY} (interval [{_f(lo, '.3g')}, {_f(hi, '.3g')}], "
            f"psi spans {_f(m_fit['psi_span'], '.3f')})")
    return v


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
    add(f"Options: window {opt.window:g} of eps_q, pre-strain {opt.pre_strain:g}, "
        f"min rows {opt.min_points}, criterion {_criterion(opt)}, "
        f"tolerances (change + 2 SE; 6 SE below 10 effective rows in v3) eta {opt.tol_eta:g}, p {opt.tol_p:g}, "
        f"Z_mech {opt.tol_z:g}, F_a {opt.tol_fabric:g} (relative), e {opt.tol_e:g}"
        + (f", eps_v {opt.tol_epsv:g}" if opt.tol_epsv else "") + " (absolute); "
        f"smoothing +-{opt.smooth:g} eps_q (at least {opt.smooth_min:g}), min eps_q "
        f"{opt.min_strain:g}, min d eps_q^p/d eps_q {opt.min_deq:g}"
        + (f"; calibration targets: {', '.join(opt.targets)}" if opt.targets else "")
        + (", --all" if opt.all else "") + (f", xi fixed {opt.fix_xi:g}" if opt.fix_xi else "")
        + ".\n")
    for w in res["warnings"]:
        add(f"> Warning: {w}\n")

    add("## 0. Stress paths\n")
    add("Every test is judged against its path by the app's watchdog rules (docs/physics.md section "
        "6.2; `path_check.py` re-applies them to the series, with the tolerances of the file's own "
        "`[watch]` section): over each trailing window of axial strain "
        f"(default {100 * PATH_DEFAULTS['window']:g} %) after the ramp, p (constant p) or sigma3 "
        f"(constant sigma3) within {100 * PATH_DEFAULTS['stress']:g} % of the target, b within "
        f"{PATH_DEFAULTS['b']:g}, the principal axes within {PATH_DEFAULTS['rotation']:g} deg of the "
        f"cell axes, the largest shear stress within {PATH_DEFAULTS['shear']:g} p, the unbalanced force "
        f"ratio below {PATH_DEFAULTS['unbalanced']:g}, and no overlap beyond "
        f"{PATH_DEFAULTS['overlap']:g} R. A failed or unfinished test is left out of every fit, "
        "table, trend and figure below.\n")
    add("Banded: the verdict of `triaxial localization` (`--localization DIR`: the whole test's strongest "
        "planar mode above the 0.99 quantile of homogeneous surrogates, the band's deps_q >= 2 x the outside's "
        "and its void-ratio contrast grown by >= 0.01 and 3 x noise; band_detector.py), else not judged.\n")
    add("| test | status | largest p/sigma3 error (%) | largest b error | largest rotation (deg) "
        "| largest shear / p | critical | banded | reason |")
    add("|---|---|---|---|---|---|---|---|---|")
    for t in sorted(tests + res.get("excluded", []), key=lambda t: (t["path"], t["p0"], t["b_nominal"])):
        w = t["path_check"]["worst"]
        err = max(w["p"], w["sigma3"])
        add(f"| {t['name']} | {t['status']} | {_f(100 * err, '.2f')} | {_f(w['b'], '.3f')} "
            f"| {_f(w['rotation'], '.1f')} | {_f(w['shear'], '.3f')} "
            f"| {'yes' if t['critical']['reached'] else 'no'} | {banded(t['name'], opt.localization)} "
            f"| {t['status_reason'] or '-'} |")
    add("")

    add("## 1. Tests\n")
    add(f"The critical state is found after the fact on the whole test (version {_criterion(opt)[1]}; "
        "`critical.py`), never "
        "by first passage: over the last "
        f"{opt.window:g} of eps_q (the test must have run to eps_q >= {opt.window + opt.pre_strain:g}, "
        f">= {opt.min_points} rows over 90 % of the window), a least-squares line through each of eta and p "
        f"(relative tolerance {opt.tol_eta:g} / {opt.tol_p:g}), e (absolute {opt.tol_e:g}), Z_mech "
        f"(relative {opt.tol_z:g}) and the fabric anisotropy F_a (relative {opt.tol_fabric:g})"
        + (f", eps_v (absolute {opt.tol_epsv:g})" if opt.tol_epsv else "")
        + "; a quantity is steady when its change over the window plus 2 standard errors (the OLS error "
        "times sqrt((1 + r1)/(1 - r1)), r1 the residuals' lag-1 autocorrelation; in version 3 6 standard errors "
        "where the window holds fewer than 10 effective rows n (1 - r1)/(1 + r1), whose error is then short) "
        "is within its tolerance. "
        "Critical point = window means; M = q_c/p_c; e_c is the critical point's window-mean void ratio "
        "(the CSL's value at p is written e_CSL(p)). eps_v is compression positive; psi0 = e0 - e_CSL(p0) "
        f"with the {res['psi_source']}. `v1`: the first-passage test of the 2026-11-28 campaigns (the "
        "last 5 % of eps_1, change alone) on the same rows.\n")
    add("| test | path | b | p0 (MPa) | eps_q end (%) | critical | v1 | p_c (MPa) | q_c (MPa) | M | e_c "
        "| b_c | theta_c (deg) | Z_mech | F_a | peak eta | at eps1 (%) | min d | psi0 |")
    add("|" + "---|" * 19)
    for t in tests:
        c = t["critical"]
        pt = c["point"]
        add(f"| {t['name']} | {t['path']} | {_f(b_key(t), 'g')} | {_f(t['p0'] / 1e6, 'g')} "
            f"| {_f(100 * t['end']['eps_q'], '.1f')} | {'yes' if c['reached'] else 'no'} "
            f"| {'yes' if t['critical_v1']['reached'] else 'no'} "
            f"| {_f(pt['p'] / 1e6)} | {_f(pt['q'] / 1e6)} | {_f(pt['M'], '.4f')} "
            f"| {_f(pt['e'], '.4f')} | {_f(pt['b'], '.3f')} "
            f"| {_f(math.degrees(pt['theta']), '.1f')} | {_f(pt['Z_mech'], '.3f')} | {_f(pt['F_a'], '.3f')} "
            f"| {_f(t['peak']['eta'], '.4f')} | {_f(100 * t['peak']['eps1_eta'], '.2f')} "
            f"| {_f(t['min_d'], '.3f')} | {_f(t['psi0'], '.4f')} |")
    add("")
    notc = [t for t in tests if not t["critical"]["reached"]]
    if notc:
        add("Not at the critical state, and why:\n")
        for t in notc:
            add(f"- {t['name']}: " + "; ".join(t["critical"]["reasons"]))
        add("")
    if not opt.all and notc:
        add(f"{len(notc)} of {len(tests)} tests did not reach the critical state: they enter no CSL or "
            "M(theta) fit (`--all` fits their end windows, marked).\n")

    add("## 2. Critical state line\n")
    add("e_CSL(p) = e_Gamma - lambda (p/p_a)^xi (Li & Wang 1998), p_a = 101.325 kPa; nonlinear least "
        f"squares over the critical points ({csl['points']}): n = {csl['n']}, "
        f"{csl['distinct_p']} distinct p. Standard errors from the residual variance. Role: a calibration "
        "target (`--targets`) is not a reproduction.\n")
    if csl["note"]:
        add(f"**{csl['note']}**\n")
    add("| parameter | this run | study | role | verdict | criterion |")
    add("|---|---|---|---|---|---|")
    for v in res["verdicts"]:
        if v["key"] in ("e_gamma", "lambda", "xi", "csl_curve", "R"):
            add(f"| {v['quantity']} | {_pm(v['value'], v['se'])} | {_f(v['study'], 'g')} | {v['role']} "
                f"| {v['verdict']} | {v['criterion']} |")
    add(f"\nR^2 = {_f(csl['r2'])}, RMS residual = {_f(csl['rms'])}, mode: {csl['mode'] or 'n/a'}.\n")
    if csl["per_b"]:
        add("Residuals e_c - e_CSL(p_c) per b (one CSL for every b):\n")
        add("| b | n | mean | RMS |")
        add("|---|---|---|---|")
        for r in csl["per_b"]:
            add(f"| {r['b']:g} | {r['n']} | {_f(r['mean'], '.4f')} | {_f(r['rms'], '.4f')} |")
        add("")

    ew = res.get("end_windows") or {}
    if ew and not all(t["critical"]["reached"] for t in tests):
        c, mt, dr, sf = ew["csl"], ew["m_theta"], ew["direct_friction"], ew["surfaces"]
        add("### For reference: the end windows of every test (not proven critical; no verdict)\n")
        add(f"The same fits through the last window of each of the {ew['n']} tests, critical or not (what "
            "`--all` fits): numbers to read beside the study's, not reproductions.\n")
        add("| quantity | end windows | study |")
        add("|---|---|---|")
        add(f"| CSL e_Gamma; lambda; xi | {_pm(c['params']['e_gamma'], c['stderr']['e_gamma'])}; "
            f"{_f(c['params']['lambda'])}; {_f(c['params']['xi'], '.3g')} ({c['mode'] or 'not fitted'}) "
            "| 0.699; 0.0002; 0.971 |")
        add(f"| CSL: max abs(e_CSL - e_CSL,study) over the tested p | {_f(ew.get('csl_curve'), '.4f')} | 0 |")
        add(f"| CSL R | {_f(c['R'], '.3f')} | 0.96 |")
        add(f"| phi_c; phi_e (deg), g(theta) fit | {_f(mt['phi_c_deg'], '.2f')}; {_f(mt['phi_e_deg'], '.2f')} "
            f"(K {_f(mt['params']['K'], '.3f')}) | 22; 22 |")
        add(f"| phi_c; phi_e (deg), b = 0 and b = 1 directly | {_pm(dr['phi_c_deg'], dr['se_phi_c_deg'], '.2f')} "
            f"(n {dr['n_c']}); {_pm(dr['phi_e_deg'], dr['se_phi_e_deg'], '.2f')} (n {dr['n_e']}) | 22; 22 |")
        if sf.get("forms"):
            order = sorted(sf["forms"].items(), key=lambda kv: kv[1]["aicc"])
            add("| M(theta) surfaces, delta AICc | " + "; ".join(f"{k} {_f(v['delta'], '.1f')}" for k, v in order)
                + " | |")
        add("")

    add("## 3. Critical stress ratio M(theta)\n")
    add("M(theta) = M_c g(theta), g = 2K/((1+K) - (1-K) cos 3theta), K = M_e/M_c in "
        f"[{mth['K_bounds'][0]:g}, {mth['K_bounds'][1]:g}], fitted to q_c/p_c at theta_c "
        f"(n = {mth['n']}); sin phi_c = 3M_c/(6+M_c), sin phi_e = 3M_e/(6-M_e). The friction angles also "
        "come from the b = 0 and b = 1 critical points directly (no g(theta) assumed).\n")
    if mth["note"]:
        add(f"**{mth['note']}**\n")
    P, S = mth["params"], mth["stderr"]
    dr = res["direct_friction"]
    add("| quantity | this run | study | role | verdict | criterion |")
    add("|---|---|---|---|---|---|")
    add(f"| M_c (g fit) | {_pm(P['M_c'], S['M_c'])} | | | | |")
    add(f"| K (g fit) | {_pm(P['K'], S['K'])} | | | | |")
    add(f"| M_c, M_e (b = 0, 1 directly) | {_pm(dr['M_c'], dr['se_M_c'])}, {_pm(dr['M_e'], dr['se_M_e'])} "
        "| | | | |")
    for v in res["verdicts"]:
        if v["key"] in ("phi_c", "phi_e"):
            add(f"| {v['quantity']} | {_pm(v['value'], v['se'], '.2f')} | about 22 | {v['role']} "
                f"| {v['verdict']} | {v['criterion']} |")
    conv = {True: "yes", False: "no", None: "n/a"}[mth["convex"]]
    add(f"\nConvex (K >= 7/9 = 0.778): {conv}. A Mohr-Coulomb surface with phi = phi_c would "
        f"have K = {_f(mth['K_mohr_coulomb'], '.3f')}. RMS of M about the fit: "
        f"{_f(mth['rms'], '.4f')}.\n")
    sf = res["surfaces"]
    if sf.get("forms"):
        add("The shape of M(theta) by AIC (AICc = n ln(SSR/n) + 2k + 2k(k+1)/(n-k-1); delta from the "
            f"smallest; n = {sf['n']}):\n")
        add("| surface | parameters | k | RMS of M | AICc | delta | phi_e (deg) |")
        add("|---|---|---|---|---|---|---|")
        for name, f in sorted(sf["forms"].items(), key=lambda kv: kv[1]["aicc"]):
            par = ", ".join(f"{k} {_f(x, '.4g')}" for k, x in f["params"].items())
            add(f"| {name} | {par} | {f['k']} | {_f(f['rms'], '.4f')} | {_f(f['aicc'], '.2f')} "
                f"| {_f(f['delta'], '.2f')} | {_f(f['phi_e_deg'], '.2f')} |")
        for v in res["verdicts"]:
            if v["key"] == "surface":
                add(f"\nVerdict: **{v['verdict']}** ({v['criterion']}).\n")

    add("## 4. Dilatancy\n")
    add("Plastic dilatancy d = d eps_v^p / d eps_q^p with both elastic parts removed: eps_v^p = eps_v - "
        "(p - p0)/K, eps_q^p = eps_q - (q - q0)/(3G), K and G each test's initial tangent moduli (least "
        "squares of p against eps_v and q against eps_q over its first rows, to 20 % of the deviatoric "
        "load, at least 4 rows; lower bounds, as those rows hold some plastic strain; where p moves by "
        "< 5 % over them, a constant-p test, K is not measured and dp/K is taken as 0). Derivatives: "
        "strain-adaptive local quadratics in eps_q over +-max("
        f"{opt.smooth_min:g}, {opt.smooth:g} eps_q) (a constant width in log strain: the pre-peak branch "
        f"and the phase transformation are kept); points where d eps_q^p/d eps_q < {opt.min_deq:g} (the "
        "elastic start) are dropped"
        + (f", and eps_q < {opt.min_strain:g}" if opt.min_strain > 0 else ", no strain cut")
        + ". psi and M from each (path, b) group's own CSL (e_Gamma, lambda; xi the pooled fit's, else the study's) "
        "and "
        "mean q_c/p_c:\n")
    add("| path | b | points | CSL e_Gamma | lambda | xi | M | initial slope (median) | note |")
    add("|---|---|---|---|---|---|---|---|---|")
    for g in res["groups"]:
        c = g["csl"]
        add(f"| {g['path']} | {g['b']:g} | {g['n']} {g['source']} | {_f(c['e_gamma'], '.4f')} "
            f"| {_f(c['lambda'], '.4g')} | {_f(c['xi'], '.3g')} | {_f(g['M'], '.4f')} "
            f"| {_f(g.get('initial_slope'), '.3f')} | {g['note'] or '-'} |")
    add("")
    mi = res["m_identification"]
    lo, hi = mi["interval"]
    add("### m, the state dependence of the dilatancy\n")
    add("From each test's phase transformation (d = 0, interpolated where d turns from contraction to "
        "dilation), else its peak stress ratio with eta* = eta - d/s (s the group's initial slope of d "
        "against eta): ln(eta*/M) = c + m psi, least squares with c free (a CSL or an M off by a "
        "constant moves c, not m: m is identified only by a span of psi). 95 % interval: the profile "
        "likelihood, SSR(m) <= SSR_min (1 + F(0.95; 1, n-2)/(n-2)). Criterion, fixed before the data: "
        f"identifiable iff >= 4 states, the interval inside [-20, 60] and narrower than {M_STUDY} (it "
        f"can tell m = {M_STUDY} from 0); then reproduced iff it holds {M_STUDY}. psi and M measured from "
        "end windows not proven critical carry no verdict (added after the first run on the campaigns, "
        "where no test proved its critical state: a rule that can only withhold a verdict).\n")
    add(f"States used: {mi['n']}: {mi['kinds'].get('phase transformation', 0)} phase transformations, "
        f"{mi['kinds'].get('peak', 0)} peaks ({mi['kinds'].get('peak, eta* <= 0', 0)} more peaks left out: "
        "there d is more negative than the initial slope allows, eta* <= 0, Li's form with one d0 does "
        f"not hold; {mi['kinds'].get('none', 0)} tests without a state); psi spans {_f(mi['psi_span'], '.3f')}. "
        f"m = {_pm(mi['m'], mi['se'], '.3g')}, 95 % interval [{_f(lo, '.3g')}, {_f(hi, '.3g')}] "
        f"(unbounded ends n/a); through the origin (c = 0, for reference) m = {_f(mi['m_origin'], '.3g')}. "
        f"**{mi['verdict']}**" + (f": {mi['note']}" if mi["note"] else "") + ".\n")
    if mi["by_path"]:
        add("| path | states | m | 95 % interval | psi span | verdict |")
        add("|---|---|---|---|---|---|")
        for pk, r in mi["by_path"].items():
            add(f"| {pk} | {r['n']} | {_pm(r['m'], r['se'], '.3g')} | [{_f(r['interval'][0], '.3g')}, "
                f"{_f(r['interval'][1], '.3g')}] | {_f(r['psi_span'], '.3f')} | {r['verdict']} |")
        add("")
    add("### Li & Dafalias fitted on d (as the study did)\n")
    add(f"d = d0/M (M exp(m psi) - eta), least squares on the b = 0 tests of path `{ld['path']}` "
        f"({', '.join(ld['tests']) or 'none'}; {ld['n']} points), M = {_f(res['M_c_dilatancy'], '.4f')}, "
        f"the {ld['M_source']}.\n")
    if ld["note"]:
        add(f"**{ld['note']}**\n")
    add("| parameter | this run | study (b = 0, p = 0.5 MPa) | role | verdict | criterion |")
    add("|---|---|---|---|---|---|")
    for v in res["verdicts"]:
        if v["key"] in ("d0", "m_ld", "m"):
            add(f"| {v['quantity']} | {_pm(v['value'], v['se'])} | {_f(v['study'], 'g')} | {v['role']} "
                f"| {v['verdict']} | {v['criterion']} |")
    add(f"\nMSE of the b = 0 fit: {_f(ld['mse'])}, R^2 = {_f(ld['r2'], '.3f')}.\n")
    add("### The 3D forms, judged across paths\n")
    add("Li's 3D form d = d0/M_c (M_c g(theta) exp(m psi) - eta) and the g-dependent form d = d0 g^-alpha / "
        "M_c (M_c g exp(m g^beta psi) - eta) (the study's exact expression is not available), d0, m from "
        "the path's b = 0 tests, alpha, beta from its b > 0 tests, M_c and K from its b = 0 and b = 1 "
        "groups; each path's model predicts the other path's b > 0 tests. AIC (k = 2 and 4) on the "
        "fitting path beside it.\n")
    cv = res["cross_validation"]
    add("| fitted on | predicts | points | MSE Li 3D | MSE g form | in-path AIC Li 3D | in-path AIC g form |")
    add("|---|---|---|---|---|---|---|")
    for r in cv["rows"]:
        o, i = r["out_of_path"], r["in_path"]
        add(f"| {r['fitted_on']} | {r['predicts']} | {o['n']} | {_f(o['mse_li3d'])} | {_f(o['mse_g'])} "
            f"| {_f(i['aic_li3d'], '.1f')} | {_f(i['aic_g'], '.1f')} |")
    add(f"\nVerdict: **{cv['verdict']}** ({cv['criterion']})" + (f": {cv['note']}" if cv.get("note") else "")
        + ".\n")
    if gf["note"]:
        add(f"g-dependent form on `{gf['path']}`: {gf['note']}\n")
    add("MSE of d per (path, b) (the study's Table 3) with the model of path "
        f"`{ld['path']}` (alpha = {_pm(gf['params']['alpha'], gf['stderr']['alpha'])}, beta = "
        f"{_pm(gf['params']['beta'], gf['stderr']['beta'])}):\n")
    add("| path | b | tests | points | MSE Li 3D | MSE g-dependent |")
    add("|---|---|---|---|---|---|")
    for r in res["mse"]:
        add(f"| {r['path']} | {r['b']:g} | {r['tests']} | {r['n']} | {_f(r['mse_li3d'])} "
            f"| {_f(r['mse_g'])} |")
    add("")
    add("### The initial linear part of d against eta (the study's Fig 10(e))\n")
    add("Per test: d = a + s eta by least squares over its kept points from the first to the largest "
        "dilation (min d). The claim: slope and intercept grow with b; tested by Spearman rho(b, |s|) and "
        "rho(b, a) >= +0.8 in every (path, p0) group with >= 3 b (section 5). Medians per (path, b):\n")
    add("| path | b | tests | median s | median a |")
    add("|---|---|---|---|---|")
    for pk in sorted({t["path"] for t in tests}):
        for bk in sorted({b_key(t) for t in tests if t["path"] == pk and np.isfinite(b_key(t))}):
            ts = [t for t in tests if t["path"] == pk and b_key(t) == bk]
            s_ = [t["initial_linear"]["slope"] for t in ts]
            a_ = [t["initial_linear"]["intercept"] for t in ts]
            med = (lambda v: float(np.nanmedian(v)) if np.any(np.isfinite(v)) else NAN)  # noqa: E731
            add(f"| {pk} | {bk:g} | {len(ts)} | {_f(med(s_), '.3f')} | {_f(med(a_), '.3f')} |")
    add("")
    early = res.get("early_stop", [])
    if early:
        add("### The early stop's bias\n")
        add("Where a test reached the critical state at its end, the state where the first-passage "
            "test (version 1) would have stopped it, replayed on its rows, against the end state:\n")
        add("| test | v1 stop at eps_q (%) | eta v1 - end | e v1 - end | p v1 / end - 1 |")
        add("|---|---|---|---|---|")
        for r in early:
            add(f"| {r['test']} | {_f(100 * r['eps_q_v1'], '.1f')} | {_f(r['d_eta'], '+.4f')} "
                f"| {_f(r['d_e'], '+.4f')} | {_f(r['d_p_rel'], '+.4f')} |")
        add("")

    add("## 5. Trends stated by the study\n")
    add("| statement | quantity | verdict | criterion | groups (path, p0: rho) |")
    add("|---|---|---|---|---|")
    for tr in res["trends"]:
        if tr["name"] == "csl_unique":
            g = "; ".join(f"b = {r['b']:g}: {_f(r['mean'], '.4f')}" for r in tr["groups"])
        elif tr["name"] == "g_form_better":
            g = "; ".join(f"{r['fitted_on']} -> {r['predicts']}: {_f(r['mse_g'])} vs {_f(r['mse_li3d'])}"
                          for r in tr["groups"])
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


def banded(name, folder):
    """yes/no from the test's `triaxial localization --whole` CSV in folder, else "not judged"."""
    import csv
    path = os.path.join(folder, f"{name}-localization.csv") if folder else ""
    if not path or not os.path.exists(path):
        return "not judged"
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows or "banded" not in rows[-1]:  # none, or a CSV of the detector before issue 45: run it again
        return "not judged"
    return "yes" if int(rows[-1]["banded"]) else "no"


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


# The one definition of each quantity the report and summary.json name (README and docs use the same).
DEFINITIONS = {
    "e_c": "the critical point's void ratio: the mean e over the window of eps_q in which the test is "
           "critical (version 3); per test, tests[].critical_point.e",
    "e_CSL(p)": "the critical state line's void ratio at p: e_Gamma - lambda (p/p_a)^xi, p_a = 101.325 kPa, "
                "fitted to the e_c of the critical tests",
    "psi": "e - e_CSL(p) of the test's (path, b) group (groups[]); psi0 uses the pooled CSL",
    "M": "q_c/p_c, mean q over mean p in the critical window",
    "d": "plastic dilatancy d eps_v^p / d eps_q^p (compression positive), elastic parts removed with "
         "the test's initial moduli",
    "role": "calibration target: the value was fitted to the study's (--targets), not reproduced; "
            "prediction: not used in any calibration",
}


def build_summary(tests, res, opt, files, skipped):
    per_test = []
    for t in tests:
        per_test.append({
            "name": t["name"], "file": t["file"], "path": t["path"], "b": b_key(t),
            "p0": t["p0"], "rows": t["rows"], "eps1_end": t["end"]["eps1"],
            "critical": t["critical"]["reached"], "used_in_fits": t["used"],
            "reasons": t["critical"]["reasons"], "checks": t["critical"]["checks"],
            "critical_point": t["critical"]["point"], "peak": t["peak"],
            "min_d": t["min_d"], "eps1_min_d": t["eps1_min_d"], "max_dv_de1": t["max_dv_de1"],
            "eps_v_end": t["end"]["eps_v"],
            "psi0": t["psi0"], "dilatancy_points": int(np.sum(t["dil"]["mask"])),
            "eps_q_end": t["end"]["eps_q"], "criterion": t["critical"]["criterion"],
            "critical_v1": {"reached": t["critical_v1"]["reached"], "point": t["critical_v1"]["point"]},
            "psi0_group": t["psi0_group"], "moduli": t["dil"]["moduli"], "initial_linear": t["initial_linear"],
            "state_for_m": t["state_m"],
        })
    opts = {k: getattr(opt, k) for k in ("window", "pre_strain", "min_points", "tol_eta", "tol_p",
                                         "tol_e", "tol_z", "tol_fabric", "tol_epsv", "all", "fix_xi",
                                         "smooth", "smooth_min", "min_strain", "min_deq", "moduli", "dilatancy_path",
                                         "targets", "title")}
    paths = []
    for t in tests + res.get("excluded", []):
        paths.append({"name": t["name"], "file": t["file"], "status": t["status"],
                      "reason": t["status_reason"], "worst": t["path_check"]["worst"],
                      "critical": t["critical"]["reached"], "used_in_fits": any(t is u for u in tests) and t["used"]})
    return _jsonable({
        "tool": "sandcell analyze.py", "inputs": [t["file"] for t in tests],
        "excluded": [t["name"] for t in res.get("excluded", [])], "path_checks": paths,
        "skipped": [{"file": f, "why": w} for f, w in skipped], "options": opts,
        "study": STUDY, "criteria": CRIT, "tests": per_test, "csl": res["csl"],
        "m_theta": res["m_theta"], "psi_source": res["psi_source"],
        "li_dafalias": res["li_dafalias"], "g_form": res["g_form"], "mse": res["mse"],
        "trends": res["trends"], "verdicts": res["verdicts"], "warnings": res["warnings"],
        "figures": files, "definitions": DEFINITIONS, "groups": res["groups"],
        "m_identification": res["m_identification"], "surfaces": res["surfaces"],
        "direct_friction": res["direct_friction"], "early_stop": res["early_stop"],
        "end_windows": res.get("end_windows") or {},
        "cross_validation": {"rows": res["cross_validation"]["rows"], "verdict": res["cross_validation"]["verdict"],
                             "note": res["cross_validation"].get("note", ""),
                             "criterion": res["cross_validation"]["criterion"],
                             "models": {k: {"M_c": m["M_c"], "K": m["K"], "d0": m["li"]["params"]["d0"],
                                            "m": m["li"]["params"]["m"], "alpha": m["g"]["params"]["alpha"],
                                            "beta": m["g"]["params"]["beta"]}
                                        for k, m in res["cross_validation"]["models"].items()}},
    })


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise InputError(message)


def _positive(v):
    x = to_float(v)
    if not (np.isfinite(x) and x > 0):
        raise argparse.ArgumentTypeError(f"must be a positive number, got {v!r}")
    return x


def _nonneg(v):
    x = to_float(v)
    if not (np.isfinite(x) and x >= 0):
        raise argparse.ArgumentTypeError(f"must be a number >= 0, got {v!r}")
    return x


def parse_args(argv):
    ap = _Parser(prog=os.environ.get("SANDCELL_ANALYZE_PROG", "analyze.py"),
                 description="Critical-state and dilatancy analysis of "
                 "sandcell triaxial results: report.md, summary.json and figures in --out. "
                 "Methods and criteria: the docstring at the top of analyze.py.")
    ap.add_argument("results", nargs="*", metavar="RESULTS",
                    help="results files (<test>.h5) or directories holding them")
    ap.add_argument("--out", metavar="DIR", help="output folder (default: <DIR>/analysis for a "
                    "single directory argument, else ./analysis)")
    ap.add_argument("--title", default="sandcell critical-state analysis",
                    help="title of the report and the figures")
    g = ap.add_argument_group("critical state (version 3, after the fact on the whole test)")
    D = V3_DEFAULTS
    g.add_argument("--criterion", choices=tuple(CRITERIA), default="v3",
                   help="v3: 6 standard errors to spare where a window holds fewer than 10 effective rows, "
                   "2 elsewhere (default); v2: 2 everywhere (the test before 2026-11-29)")
    g.add_argument("--window", type=_positive, default=D["window"], metavar="W",
                   help=f"window at the end of each test, deviatoric strain eps_q (default {D['window']:g})")
    g.add_argument("--pre-strain", type=_nonneg, default=D["pre_strain"], metavar="S",
                   help=f"eps_q the test must have run before the window (default {D['pre_strain']:g})")
    g.add_argument("--min-points", type=int, default=D["min_points"], metavar="N",
                   help=f"rows the window must hold (default {D['min_points']})")
    g.add_argument("--tol-eta", type=_positive, default=D["tol_eta"], metavar="T",
                   help=f"eta: largest relative change + 2 SE over the window (default {D['tol_eta']:g})")
    g.add_argument("--tol-p", type=_positive, default=D["tol_p"], metavar="T",
                   help=f"p: largest relative change + 2 SE over the window (default {D['tol_p']:g})")
    g.add_argument("--tol-e", type=_positive, default=D["tol_e"], metavar="T",
                   help=f"e: largest absolute change + 2 SE over the window (default {D['tol_e']:g})")
    g.add_argument("--tol-z", type=_positive, default=D["tol_z"], metavar="T",
                   help=f"Z_mech: largest relative change + 2 SE over the window (default {D['tol_z']:g})")
    g.add_argument("--tol-fabric", type=_positive, default=D["tol_fabric"], metavar="T",
                   help="fabric anisotropy F_a: largest relative change + 2 SE over the window "
                   f"(default {D['tol_fabric']:g})")
    g.add_argument("--tol-epsv", type=_positive, default=None, metavar="T",
                   help="also test eps_v: largest absolute change + 2 SE (default: not tested; e bounds it)")
    g.add_argument("--all", action="store_true", help="fit the CSL and M(theta) with the end "
                   "windows of every test, critical or not (marked)")
    g.add_argument("--fix-xi", type=_positive, default=None, metavar="X",
                   help="fit the CSL with xi fixed at X (default: xi fitted)")
    g = ap.add_argument_group("dilatancy")
    g.add_argument("--smooth", type=_positive, default=0.25, metavar="R",
                   help="strain-adaptive smoothing: local quadratics in eps_q over +-R eps_q (default 0.25)")
    g.add_argument("--smooth-min", type=_positive, default=2e-4, metavar="H",
                   help="smallest half-width of the smoothing window, eps_q (default 2e-4)")
    g.add_argument("--min-strain", type=_nonneg, default=0.0, metavar="S",
                   help="use points from this eps_q on (default 0: no cut, the elastic start is left out "
                   "by --min-deq)")
    g.add_argument("--moduli", choices=("initial", "none"), default="initial",
                   help="the elastic parts removed from the strain increments: each test's initial moduli "
                   "(default), or none (total increments: for records without an elastic part)")
    g.add_argument("--min-deq", type=_nonneg, default=0.5, metavar="R",
                   help="use points with d eps_q^p / d eps_q >= R (default 0.5)")
    g.add_argument("--targets", default="", metavar="KEYS",
                   help="the verdicts that were calibration targets, comma-separated among "
                   + ", ".join(TARGET_KEYS) + " (default none: every verdict is a prediction)")
    g.add_argument("--dilatancy-path", choices=("constant_p", "constant_sigma3"), default=None,
                   help="path whose tests give d0, m (b = 0) and alpha, beta (b > 0) "
                   "(default: constant_p if it has a b = 0 test, else constant_sigma3)")
    g.add_argument("--localization", metavar="DIR", default=None,
                   help="the <test>-localization.csv files of `triaxial localization --whole`: the table of "
                   "paths says which tests are banded (else: not judged)")
    opt = ap.parse_args(argv)
    if not opt.results:
        raise InputError("no results given (usage: analyze.py RESULTS... [--out DIR])")
    if opt.min_points < 3:
        raise InputError(f"--min-points must be >= 3, got {opt.min_points}")
    opt.targets = tuple(k.strip() for k in opt.targets.split(",") if k.strip())
    bad = [k for k in opt.targets if k not in TARGET_KEYS]
    if bad:
        raise InputError(f"--targets: unknown key(s) {', '.join(bad)} (known: {', '.join(TARGET_KEYS)})")
    if opt.out is None:
        if len(opt.results) == 1 and os.path.isdir(opt.results[0]):
            opt.out = os.path.join(opt.results[0], "analysis")
        else:
            opt.out = "analysis"
    return opt


def path_verdict(path):
    """The test's standing on its stress path: (status, reason, check) with status "done", "failed"
    or "unfinished". The app writes its verdict into the file (root attributes status, status_reason);
    the same rules (path_check.py, the app's [watch] tolerances of the file's config) are applied
    again here, so that a file written before the watchdog is judged too, and a file whose series
    disagrees with its verdict is not trusted. A file of the watchdog's time without a status is a
    test still running or stopped."""
    import tomllib
    with open_results(path) as f:
        status = attr(f, "status")
        reason = attr(f, "status_reason") or ""
        text = attr(f, "config") or ""
        modern = "series" in f and "rotation" in f["series"]
    tol, start = {}, 0.0
    try:
        cfg = tomllib.loads(str(text)) if text else {}
        tol = {k: (int(v) if k == "rows" else float(v)) for k, v in cfg.get("watch", {}).items()
               if k in PATH_DEFAULTS}
        start = float(cfg.get("shear", {}).get("ramp_strain", 0.0))
    except (tomllib.TOMLDecodeError, TypeError, ValueError):
        pass
    check = check_path(path, start=start, tolerances=tol)
    fl = check["failure"]
    if status == "failed":
        return "failed", str(reason), check
    if fl is not None:
        return "failed", (f"left its stress path: {fl['quantity']} {fl['value']:.4g} beyond "
                          f"{fl['tolerance']:g} at eps1 = {100 * fl['eps1']:.2f} % (path_check.py on the "
                          "series)"), check
    if status is None and modern:
        return "unfinished", "no verdict in the file: the test is running or was stopped", check
    return "done", "", check


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
            t["status"], t["status_reason"], t["path_check"] = path_verdict(f)
            tests.append(t)
    if not tests:
        raise InputError(f"no shear tests with data in {len(files)} file(s) read "
                         "(files need the root attribute stage = 'shear')")
    # A test that left its stress path, or has not finished, enters no fit, table, trend or figure.
    excluded = [t for t in tests if t["status"] != "done"]
    tests = [t for t in tests if t["status"] == "done"]
    if not tests:
        raise InputError(f"no shear test on its stress path among {len(excluded)}: "
                         + "; ".join(f"{t['name']}: {t['status']} ({t['status_reason']})" for t in excluded))
    tests.sort(key=lambda t: (PATHS.index(t["path"]) if t["path"] in PATHS else 9,
                              t["p0"], t["b_nominal"], t["name"]))
    try:
        os.makedirs(opt.out, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the output folder {opt.out}: {exc.strerror}") from None
    # The paths of a shearing cell (simple shear, rotation) have no axial strain to fit a critical
    # state line or M(theta) on: their own figures (shearing.py), apart from the triaxial analysis.
    from . import shearing
    shearing_tests = [t for t in tests if t["path"] in shearing.SHEARING_PATHS]
    tests = [t for t in tests if t["path"] not in shearing.SHEARING_PATHS]
    if shearing_tests:
        from . import plots
        shear_figs = []
        shearing.figures(plots.pyplot(), shearing_tests, opt.out, opt.title, shear_figs, plots._save)
        with open(os.path.join(opt.out, "shearing.md"), "w", encoding="utf-8") as fh:
            fh.write(f"# {opt.title}: the paths of a shearing cell\n\n")
            for t in shearing_tests:
                fh.write(f"- {t['name']} ({t['path']}): ![{t['name']}](shearing-{t['name']}.png)\n")
        if not tests:
            return {"shearing": shear_figs}, shearing_tests
    res = analyze_tests(tests, opt)
    res["excluded"] = excluded
    for t in excluded:  # whether it had reached the critical state, for the table of paths only
        t["critical"] = detect_critical(
            t["eps_q"], t, window=opt.window, tol_eta=opt.tol_eta, tol_p=opt.tol_p, tol_e=opt.tol_e,
            tol_z=opt.tol_z, tol_fabric=opt.tol_fabric, tol_epsv=opt.tol_epsv, pre_strain=opt.pre_strain,
            min_points=opt.min_points, k_short=_k_short(opt))
    for t in excluded:
        res["warnings"].append(f"{t['name']} left out of every fit, table, trend and figure: {t['status']}"
                               + (f": {t['status_reason']}" if t["status_reason"] else ""))
    from . import plots
    plt = plots.pyplot()
    figs = []
    plots.figure_stress_strain(plt, tests, opt.out, opt.title, figs)
    plots.figure_csl(plt, tests, res["csl"], opt.out, opt.title, figs)
    plots.figure_pi_plane(plt, tests, res["m_theta"], opt.out, opt.title, figs)
    plots.figure_dilatancy(plt, tests, res, opt.out, opt.title, figs)
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
    crit = sum(t["critical"]["reached"] for t in tests if "critical" in t)  # shearing paths have none
    print(f"analyze.py: {len(tests)} test(s), {crit} at the critical state; "
          f"report: {os.path.join(opt.out, 'report.md')}")
    return 0
