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
  --localization DIR the <test>-localization.csv of `triaxial localization --whole`: the table of
                     paths says which tests are banded (else "not judged")

Stress paths: every test is judged by the app's watchdog rules (path_check.py, with the tolerances of
  the file's [watch]); a test that failed (the file's status, or its series off its path) or has no
  verdict yet (running) enters no fit, table, trend or figure, and is listed in report.md (a table of
  paths: status, largest errors, turn of the axes, critical, banded) and summary.json (excluded,
  path_checks, warnings).

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
import argparse
import datetime
import json
import math
import os
import sys
import time

import numpy as np
from scipy import stats

from .critical import detect_critical
from .csl import csl_e, fit_csl
from .dilatancy import (dilatancy_g, dilatancy_li3d, dilatancy_series, fit_g_form, fit_li_dafalias,
                        slope_max_dilation)
from .fitting import NAN
from .m_theta import fit_m_theta
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
    csl = fit_csl(cp("p"), cp("e"), b=np.array([b_key(t) for t in used]), xi=opt.fix_xi)
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
        # The largest dilation rate against the axial strain, -d eps_v / d eps_1 (slopes over 1 %
        # of eps_1): where b changes d eps_q / d eps_1, this and -min(d) can order the b apart.
        t["max_dv_de1"] = slope_max_dilation(t["eps1"], t["eps_v"], t["eps1"])
        t["psi0"] = float(t["e"][0] - csl_e(t["p"][0], cpar["e_gamma"], cpar["lambda"],
                                            cpar["xi"]))

    # Dilatancy fits.
    if opt.dilatancy_path:
        dpath = opt.dilatancy_path
    else:
        dpath = next((pk for pk in ("constant_p", "constant_sigma3")
                      if any(t["path"] == pk and b_key(t) == 0 for t in tests)), None)
    zero = [t for t in tests if t["path"] == dpath and b_key(t) == 0]
    pos = [t for t in tests if t["path"] == dpath and np.isfinite(b_key(t)) and b_key(t) > 0]

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
        for bk in sorted({b_key(t) for t in tests if t["path"] == pk and np.isfinite(b_key(t))}):
            ts = [t for t in tests if t["path"] == pk and b_key(t) == bk]
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
        add(f"| {t['name']} | {t['path']} | {_f(b_key(t), 'g')} | {_f(t['p0'] / 1e6, 'g')} "
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
        })
    opts = {k: getattr(opt, k) for k in ("window", "pre_strain", "min_points", "tol_eta", "tol_p",
                                         "tol_e", "tol_epsv", "all", "fix_xi", "smooth",
                                         "min_strain", "min_deq", "dilatancy_path", "title")}
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
        "figures": files,
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
    g.add_argument("--localization", metavar="DIR", default=None,
                   help="the <test>-localization.csv files of `triaxial localization --whole`: the table of "
                   "paths says which tests are banded (else: not judged)")
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
            t["eps1"], t, window=opt.window, tol_eta=opt.tol_eta, tol_p=opt.tol_p, tol_e=opt.tol_e,
            tol_epsv=opt.tol_epsv, pre_strain=opt.pre_strain, min_points=opt.min_points)
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
