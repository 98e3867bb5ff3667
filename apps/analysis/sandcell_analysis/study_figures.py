"""The study's figures redrawn from sandcell results: Liu, Ma, Zhou & Chang (2017), Figs 2-4, 6 and 8-12.

    python -m sandcell_analysis figures RESULTS... --out DIR [--p0 P] [--moduli initial|none]

RESULTS are results files or folders of them (several folders: seeds of one campaign, e.g.
decisive/fixed-s2017 decisive/fixed-s2018). Tests with the same (path, b, p0) are seeds of one test:
curves are drawn as their mean with a +-1 standard deviation band and every seed's end marked;
points as means with +-1 standard deviation bars. Writes into DIR, as PNG:
  stress_strain-<path>-p0_<p0>kPa  Figs 2-3: q/p and eps_v against eps_1 and against eps_q, one p0, every b;
                                   each curve runs to the end of its data; a filled circle marks a test
                                   stopped at the app's critical-state test (index.csv), a diamond one
                                   done at its set end, a cross one that left its stress path (drawn
                                   dashed), an open circle one still running
  csl                              Fig 4: e against (p/p_a)^xi with the study's xi, against log p, and
                                   against (p/p_a)^xi with the project's fitted xi
  m_theta                          Fig 6: critical q/p against the Lode angle and in the pi-plane: the
                                   fitted g(theta), g(theta) from phi = 22 deg, Matsuoka-Nakai and
                                   Lade-Duncan through the b = 0 point
  dilatancy-<path>-p0_<p0>kPa      Figs 8-12: d against eta, one p0, every b, DEM and model, from the
                                   first row (the pre-peak loop and its turning point are kept)
and README.md, the list of the figures and the command that redraws them (also in each PNG's
metadata, key "Description"). Only tests on their stress path that reached the critical state give
the points of Figs 4 and 6 (critical.detect_critical with its defaults); every test is drawn in
Figs 2-3 and 8-12. Exit status: 0 done, 2 bad input, 1 scientific stack missing.

From Python (e.g. after `analyze`, whose tests carry status and critical already):
draw_all(tests, out, command). The calls into critical.py and dilatancy.py are in three adapters,
critical_of(), dilatancy() and dilatancy_model(): the only places to change when their APIs do.
"""
import argparse
import math
import os
import shlex
import sys
import textwrap

import numpy as np

from .critical import detect_critical
from .csl import PA, csl_e, fit_csl
from .fitting import NAN
from .m_theta import fit_m_theta, m_theta
from .reference import STUDY
from .results import PATHS, InputError, attr, b_key, collect_files, open_results, read_index, read_test

PROG = os.environ.get("SANDCELL_ANALYZE_PROG", "python -m sandcell_analysis figures")
PATH_LABEL = {"constant_p": "constant p", "constant_sigma3": "constant sigma3"}
STUDY_XI = STUDY["xi"]  # the study's published CSL exponent (docs/physics.md section 7)
FIT_FROM = 0.01  # the dilatancy model's d0, m are fitted on eps_1 >= 1 % (as `analyze`); all rows are drawn


# ---------------------------------------------------------------- reading and grouping

def load_tests(inputs):
    """The shear tests of the inputs (results.read_test) with status ("done", "failed", "running"),
    status_reason, ended (how: "critical" where the folder's index.csv says "done (critical state)",
    else the status), source (the folder: a seed) and critical (critical_of)."""
    tests, index = [], {}
    for path, _ in collect_files(inputs):
        t, _why = read_test(path)
        if t is None or t["rows"] < 5:
            continue
        with open_results(path) as f:
            status, reason = attr(f, "status"), attr(f, "status_reason")
        t["status"] = str(status) if status else "running"
        t["status_reason"] = str(reason or "")
        t["source"] = os.path.dirname(os.path.abspath(path))
        if t["source"] not in index:
            index[t["source"]] = {r.get("test"): r.get("status", "") for r in read_index(t["source"])}
        said = index[t["source"]].get(t["name"], "")
        t["ended"] = "critical" if t["status"] == "done" and "critical" in said else t["status"]
        t["critical"] = critical_of(t)
        tests.append(t)
    if not tests:
        raise InputError("no shear tests in " + ", ".join(inputs))
    return tests


def key(t):
    """(path, b, p0): tests with one key are seeds of one test."""
    return (t["path"], b_key(t), round(float(t["p0"])))


def seed_groups(tests):
    groups = {}
    for t in tests:
        groups.setdefault(key(t), []).append(t)

    def order(kv):
        (path, b, p0), _ = kv
        return (PATHS.index(path) if path in PATHS else 99, p0, b)
    return dict(sorted(groups.items(), key=order))


def critical_tests(tests):
    """The tests whose end is a critical state on their stress path: the points of Figs 4 and 6."""
    return [t for t in tests if t["status"] == "done" and t["critical"]["reached"]]


def point_stats(ts, name):
    """Mean and sample standard deviation (NaN for one seed) of a critical-point quantity over seeds."""
    v = np.array([t["critical"]["point"][name] for t in ts], float)
    return float(np.mean(v)), (float(np.std(v, ddof=1)) if v.size > 1 else NAN)


def mean_curve(ts, x, y, n=300):
    """Seeds' curves y(x) on one grid up to the longest: (grid, mean, std, count); std NaN where one seed."""
    xs = [np.asarray(t[x], float) for t in ts]
    ys = [np.asarray(t[y], float) for t in ts]
    if len(ts) == 1:
        return xs[0], ys[0], np.full(xs[0].shape, NAN), np.ones(xs[0].shape, int)
    grid = np.linspace(min(float(np.nanmin(a)) for a in xs), max(float(np.nanmax(a)) for a in xs), n)
    stack = np.full((len(ts), n), NAN)
    for i, (a, b) in enumerate(zip(xs, ys)):
        order = np.argsort(a)
        inside = (grid >= a.min()) & (grid <= a.max())
        stack[i, inside] = np.interp(grid[inside], a[order], b[order])
    count = np.sum(np.isfinite(stack), axis=0)
    return grid, _nanmean(stack), np.where(count > 1, _nanstd(stack), NAN), count


def _nanmean(a):
    n = np.sum(np.isfinite(a), axis=0)
    return np.where(n > 0, np.nansum(a, axis=0) / np.maximum(n, 1), NAN)


def _nanstd(a):
    n = np.sum(np.isfinite(a), axis=0)
    m = _nanmean(a)
    return np.sqrt(np.nansum((a - m) ** 2, axis=0) / np.maximum(n - 1, 1))


# ---------------------------------------------------------------- the models drawn

def csl_x(p, xi, pa=PA):
    """The abscissa of the study's Fig 4, (p/p_a)^xi: e = e_Gamma - lambda (p/p_a)^xi is a straight line on it."""
    return np.power(np.asarray(p, float) / pa, xi)


def principal(theta, M, p=1.0):
    """Principal stresses (s1 >= s2 >= s3) of q/p = M at Lode angle theta (0 compression, pi/3 extension)."""
    k = np.arange(3)
    return p + 2.0 / 3.0 * M * p * np.cos(np.asarray(theta, float)[..., None] - 2 * np.pi / 3 * k)


def _criterion(kind, s):
    i1 = s.sum(-1)
    i2 = s[..., 0] * s[..., 1] + s[..., 1] * s[..., 2] + s[..., 2] * s[..., 0]
    i3 = s.prod(-1)
    return i1 * i2 / i3 if kind == "mn" else i1 ** 3 / i3


def surface_M(kind, theta, Mc):
    """q/p at Lode angle theta on the Matsuoka-Nakai ("mn": I1 I2/I3 constant) or Lade-Duncan ("ld":
    I1^3/I3 constant) surface through q/p = Mc in compression (theta = 0)."""
    from scipy import optimize
    target = float(_criterion(kind, principal(np.array(0.0), Mc)))
    out = []
    for th in np.atleast_1d(np.asarray(theta, float)):
        # s3 > 0 up to M = 3 / (2 cos(th - 4 pi/3) * -1): the criterion grows without bound there
        top = 1.5 / -math.cos(th - 4 * math.pi / 3) * (1 - 1e-12)
        out.append(optimize.brentq(lambda M: _criterion(kind, principal(np.array(th), M)) - target,
                                   1e-9, top, xtol=1e-14, rtol=1e-14))
    return np.array(out)


def phi22_Mc_K(phi_deg=None):
    """M_c and K = M_e/M_c of the friction angle phi in compression and extension (the study's 22 deg)."""
    s = math.sin(math.radians(STUDY["phi_deg"] if phi_deg is None else phi_deg))
    Mc, Me = 6 * s / (3 - s), 6 * s / (3 + s)
    return Mc, Me / Mc


# ---------------------------------------------------------------- the adapters (APIs being changed)

def critical_of(test):
    """ADAPTER to critical.py: the critical-state test (version 3: the last 0.1 of eps_q) of a test's
    series with the package's defaults, detect_critical's dict (reached, point)."""
    return detect_critical(test["eps_q"], test)


def dilatancy(test, cpar, moduli="initial", fit_from=FIT_FROM):
    """ADAPTER to dilatancy.py: the test's plastic dilatancy (the elastic parts removed with its own
    moduli, strain-adaptive smoothing, no strain cut: dilatancy.plastic_dilatancy) over every kept
    row: dict eta, d, psi, theta, eps1 and fit (rows the model is fitted on: eps_1 >= fit_from).
    moduli: "initial" (each test's own), or "none" (total increments: records without an elastic
    part, as `analyze --moduli none`)."""
    from .dilatancy import plastic_dilatancy
    none = {"K": NAN, "G": NAN, "rows": 0, "note": "--moduli none"} if moduli == "none" else None
    dl = plastic_dilatancy(test["eps_v"], test["eps_q"], test["p"], test["q"],
                           others={k: test[k] for k in ("eta", "p", "e", "theta")}, moduli=none)
    psi = dl["e"] - csl_e(dl["p"], cpar["e_gamma"], cpar["lambda"], cpar["xi"])
    keep = dl["mask"]
    return {"eta": dl["eta"][keep], "d": dl["d"][keep], "psi": psi[keep], "theta": dl["theta"][keep],
            "eps1": test["eps1"][keep], "fit": test["eps1"][keep] >= fit_from,
            "increments": "total" if moduli == "none" else "plastic"}


def dilatancy_model(zero, Mc, K):
    """ADAPTER to dilatancy.py: (model(eta, psi, theta), d0, m, note) with d0, m of the Li-Dafalias form
    fitted on the b = 0 tests `zero` (their dilatancy dicts), M_c and K given (Li's 3D form beyond b = 0)."""
    from .dilatancy import dilatancy_li3d, fit_li_dafalias
    if not zero:
        return None, NAN, NAN, "no b = 0 test to fit d0, m on"
    pool = {k: np.concatenate([z[k][z["fit"]] for z in zero]) for k in ("eta", "psi", "d")}
    r = fit_li_dafalias(pool["eta"], pool["psi"], pool["d"], Mc)
    if not r["fitted"]:
        return None, NAN, NAN, r["note"]
    d0, m = r["params"]["d0"], r["params"]["m"]
    return (lambda eta, psi, theta: dilatancy_li3d(eta, psi, theta, Mc, K, d0, m)), d0, m, ""


# ---------------------------------------------------------------- the figures

def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def b_color(b):
    from matplotlib import colormaps
    return colormaps["viridis"](0.9 * min(max(b, 0.0), 1.0)) if np.isfinite(b) else "0.4"


END_MARK = {"critical": ("o", "stopped at the app's critical-state test"), "done": ("D", "done (its set end)"),
            "failed": ("x", "left its stress path"), "running": ("o", "still running (open)")}


def _end(ax, t, x, y, color):
    mk, _ = END_MARK.get(t.get("ended", t["status"]), ("o", ""))
    face = color if t["status"] == "done" else "none"
    ax.plot([x], [y], mk, ms=6, mfc=face, mec=color, color=color, zorder=4)


def fig_stress_strain(tests, path, p0):
    """Figs 2-3: q/p and eps_v against eps_1 and against eps_q for one (path, p0), every b; seeds averaged."""
    plt = _plt()
    fig, axes = plt.subplots(2, 2, figsize=(10, 7.4), sharex="col")
    groups = {k: ts for k, ts in seed_groups(tests).items() if k[0] == path and k[2] == round(p0)}
    for (_, b, _), ts in groups.items():
        c = b_color(b)
        ls = "--" if any(t["status"] == "failed" for t in ts) else "-"
        lab = f"b = {b:g}" + (f" ({len(ts)} seeds)" if len(ts) > 1 else "")
        for col, x in enumerate(("eps1", "eps_q")):
            for row, y in enumerate(("eta", "eps_v")):
                ax = axes[row, col]
                scale = 1.0 if y == "eta" else 100.0
                g, mean, std, _ = mean_curve(ts, x, y)
                ax.plot(100 * g, scale * mean, ls, color=c, lw=1.3, label=lab if row == col == 0 else None)
                if len(ts) > 1:
                    ax.fill_between(100 * g, scale * (mean - std), scale * (mean + std), color=c, alpha=0.2, lw=0)
                for t in ts:
                    _end(ax, t, 100 * t[x][-1], scale * t[y][-1], c)
    for mk, (sym, text) in END_MARK.items():
        if any(t.get("ended", t["status"]) == mk for ts in groups.values() for t in ts):
            axes[0, 0].plot([], [], sym, color="0.3", mfc="0.3" if mk in ("critical", "done") else "none",
                            label="end: " + text)
    axes[0, 0].set_ylabel("stress ratio q/p")
    axes[1, 0].set_ylabel("volumetric strain eps_v (%), compression +")
    axes[1, 0].set_xlabel("axial strain eps_1 (%)")
    axes[1, 1].set_xlabel("deviatoric strain eps_q (%)")
    for ax in axes.flat:
        ax.grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(f"Figs 2-3: {PATH_LABEL.get(path, path)}, p0 = {p0 / 1e6:g} MPa, every b (each curve to its end)")
    fig.tight_layout()
    b_colorbar(fig, axes)
    return fig


def fit_both_csl(crit, xi=STUDY_XI):
    """The CSL fitted with xi fixed (the study's) and with xi free (csl.fit_csl) on the critical tests."""
    p = [t["critical"]["point"]["p"] for t in crit]
    e = [t["critical"]["point"]["e"] for t in crit]
    b = [b_key(t) for t in crit]
    return fit_csl(p, e, b=b, xi=xi), fit_csl(p, e, b=b)


def fig_csl(tests, study_xi=STUDY_XI):
    """Fig 4: e against (p/p_a)^xi with the study's xi, against log p, and against the project's fitted xi."""
    plt = _plt()
    crit = critical_tests(tests)
    fixed, free = fit_both_csl(crit, study_xi)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.8))
    own_xi = free["params"]["xi"] if free["fitted"] else NAN
    xis = (study_xi, None, own_xi)
    pts = [(k, ts) for k, ts in seed_groups(crit).items()]
    p_all = np.array([t["critical"]["point"]["p"] for t in crit] if crit else [t["p0"] for t in tests], float)
    ps = np.geomspace(0.8 * p_all.min(), 1.25 * p_all.max(), 200)
    for ax, xi in zip(axes, xis):
        xf = (lambda p: np.asarray(p, float) / 1e6) if xi is None else (lambda p, s=xi: csl_x(p, s))
        if xi is not None and not np.isfinite(xi):
            ax.text(0.5, 0.5, textwrap.fill("the CSL's xi " + free["note"], 40), transform=ax.transAxes,
                    ha="center", va="center", color="C3")
            continue
        for (path, b, _), ts in pts:
            pm, _ = point_stats(ts, "p")
            em, es = point_stats(ts, "e")
            ax.errorbar(xf(pm), em, yerr=None if not np.isfinite(es) else es, fmt="o" if path == "constant_p" else "s",
                        color=b_color(b), ms=6, capsize=3, mfc=b_color(b) if path == "constant_p" else "none")
        ax.plot(xf(ps), csl_e(ps, STUDY["e_gamma"], STUDY["lambda"], STUDY["xi"]), "--", color="0.45",
                label=f"the study's CSL: {STUDY['e_gamma']} - {STUDY['lambda']} (p/p_a)^{STUDY['xi']}")
        for r, ls, what in ((fixed, "-", "study's xi"), (free, ":", "xi fitted")):
            if r["fitted"]:
                q = r["params"]
                ax.plot(xf(ps), csl_e(ps, q["e_gamma"], q["lambda"], q["xi"]), ls, color="k", lw=1.2,
                        label=f"fit, {what}: {q['e_gamma']:.4f} - {q['lambda']:.3g} (p/p_a)^{q['xi']:.3g}, "
                              f"R = {r['R']:.2f}")
        ax.set_ylabel("void ratio e at the critical state")
        ax.grid(True, alpha=0.3)
        if xi is None:
            ax.set_xscale("log")
            ax.set_xlabel("mean stress p (MPa), log scale")
            ax.set_title("e - log p")
        else:
            ax.set_xlabel(f"(p / p_a)^xi, xi = {xi:.3g}, p_a = 101.325 kPa")
            ax.set_title(f"the study's xi = {xi:g}" if xi == study_xi else
                         f"the project's fitted xi = {xi:.3g} (not the study's)")
    for path, mk in (("constant_p", "o"), ("constant_sigma3", "s")):
        if any(k[0] == path for k, _ in pts):
            axes[0].plot([], [], mk, color="0.4", mfc="0.4" if mk == "o" else "none", label=PATH_LABEL[path])
    axes[0].legend(fontsize=7, loc="lower left")
    axes[2].legend(*axes[0].get_legend_handles_labels(), fontsize=7, loc="lower left") if np.isfinite(own_xi) else None
    left = len(tests) - len(crit)
    fig.suptitle(f"Fig 4: critical state line, {len(crit)} tests at the critical state on their path "
                 f"(colour: b; bars: +-1 SD over seeds){'; ' + str(left) + ' others left out' if left else ''}",
                 fontsize=10)
    fig.tight_layout()
    b_colorbar(fig, axes)
    return fig


def fig_m_theta(tests):
    """Fig 6: critical q/p against the Lode angle and in the pi-plane."""
    plt = _plt()
    crit = critical_tests(tests)
    groups = seed_groups(crit)
    th = np.array([t["critical"]["point"]["theta"] for t in crit], float)
    M = np.array([t["critical"]["point"]["M"] for t in crit], float)
    fit = fit_m_theta(th, M)
    zero = [t["critical"]["point"]["M"] for t in crit if b_key(t) == 0]
    Mb0 = float(np.mean(zero)) if zero else NAN
    theta = np.linspace(0, np.pi / 3, 121)
    curves = []
    if fit["fitted"]:
        q = fit["params"]
        curves.append((m_theta(theta, q["M_c"], q["K"]), "-",
                       f"fitted g(theta): M_c = {q['M_c']:.3f}, K = {q['K']:.3f}"))
    Mc22, K22 = phi22_Mc_K()
    curves.append((m_theta(theta, Mc22, K22), "--",
                   f"g(theta) derived from phi = {STUDY['phi_deg']:g} deg (M_c = {Mc22:.3f}, K = {K22:.3f}); "
                   "not the study's fit"))
    if np.isfinite(Mb0):
        curves.append((surface_M("mn", theta, Mb0), "-.", "Matsuoka-Nakai through the b = 0 point"))
        curves.append((surface_M("ld", theta, Mb0), ":", "Lade-Duncan through the b = 0 point"))
    fig, (ax, axp) = plt.subplots(1, 2, figsize=(13, 5.6))
    for i, (r, ls, lab) in enumerate(curves):
        col = "k" if i == 0 else f"C{i}"
        ax.plot(np.degrees(theta), r, ls, color=col, lw=1.3, label=lab)
        for s in range(6):  # the pi-plane: the curve and its images in the six sectors
            a = (theta if s % 2 == 0 else -theta) + 2 * np.pi / 3 * (s // 2)
            axp.plot(r * np.sin(a), r * np.cos(a), ls, color=col, lw=1.0)
    for (path, b, p0), ts in groups.items():
        thm, ths = point_stats(ts, "theta")
        mm, ms = point_stats(ts, "M")
        c = b_color(b)
        mk, face = ("o", c) if path == "constant_p" else ("s", "none")
        ax.errorbar(np.degrees(thm), mm, xerr=None if not np.isfinite(ths) else np.degrees(ths),
                    yerr=None if not np.isfinite(ms) else ms, fmt=mk, color=c, mfc=face, ms=6, capsize=3)
        axp.plot(mm * math.sin(thm), mm * math.cos(thm), mk, color=c, mfc=face, ms=6)
    for path, mk in (("constant_p", "o"), ("constant_sigma3", "s")):
        if any(k[0] == path for k in groups):
            ax.plot([], [], mk, color="0.4", mfc="0.4" if mk == "o" else "none",
                    label=PATH_LABEL[path] + " (colour: b)")
    ax.set_xlabel("Lode angle theta (deg): 0 compression (b = 0), 60 extension (b = 1)")
    ax.set_ylabel("critical stress ratio M = q/p")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="lower left")
    rmax = 1.2 * max([float(np.nanmax(r)) for r, _, _ in curves] + [float(np.nanmax(M)) if M.size else 0])
    for k, lab in enumerate(("sigma_1", "sigma_2", "sigma_3")):
        a = 2 * np.pi / 3 * k
        axp.plot([0, rmax * math.sin(a)], [0, rmax * math.cos(a)], color="0.75", lw=0.8)
        axp.text(1.05 * rmax * math.sin(a), 1.05 * rmax * math.cos(a), lab, ha="center", va="center", fontsize=8)
    axp.set_aspect("equal")
    axp.set_xlim(-1.15 * rmax, 1.15 * rmax)
    axp.set_ylim(-1.15 * rmax, 1.15 * rmax)
    axp.set_title("the pi-plane (radius q/p)", fontsize=9)
    axp.grid(True, alpha=0.2)
    fig.suptitle(f"Fig 6: critical stress ratio, {len(crit)} tests at the critical state on their path "
                 "(bars: +-1 SD over seeds)", fontsize=10)
    fig.tight_layout()
    b_colorbar(fig, [ax, axp])
    return fig


def dilatancy_inputs(tests, moduli="initial"):
    """Each test's dilatancy (the adapter), psi from the CSL fitted (xi free) on the critical tests (the
    study's CSL if it cannot be fitted); M_c and K of the fitted g(theta). Returns (cpar, Mc, K, note)."""
    crit = critical_tests(tests)
    free = fit_both_csl(crit)[1] if crit else {"fitted": False}
    cpar = free["params"] if free["fitted"] else {k: STUDY[k] for k in ("e_gamma", "lambda", "xi")}
    fit = fit_m_theta([t["critical"]["point"]["theta"] for t in crit], [t["critical"]["point"]["M"] for t in crit])
    Mc, K = fit["params"]["M_c"], fit["params"]["K"]
    note = "" if free["fitted"] else "psi from the study's CSL (none fitted); "
    if not np.isfinite(K):
        K = 1.0
        note += "K = 1 (g(theta) not fitted); "
    for t in tests:
        t["study_dil"] = dilatancy(t, cpar, moduli)
    return cpar, Mc, K, note


def fig_dilatancy(tests, path, p0, Mc, K, note=""):
    """Figs 8-12: d against eta for one (path, p0), every b; DEM (line with markers, a triangle at the peak
    of q/p: the turning point of the loop) and the model along each test's own eta, psi, theta (dashed);
    d0, m fitted on the path's b = 0 tests (every p0); seeds overlaid."""
    plt = _plt()
    on_path = [t for t in tests if t["path"] == path]
    zero = [t["study_dil"] for t in on_path if b_key(t) == 0 and t["status"] == "done"]
    model, d0, m, why = dilatancy_model(zero, Mc, K) if np.isfinite(Mc) else (None, NAN, NAN, "M_c not fitted")
    fig, ax = plt.subplots(figsize=(7.5, 5.6))
    groups = {k: ts for k, ts in seed_groups(on_path).items() if k[2] == round(p0)}
    shown = []
    for (_, b, _), ts in groups.items():
        c = b_color(b)
        for i, t in enumerate(ts):
            dl = t["study_dil"]
            if not dl["d"].size:
                continue
            shown.append(dl["d"])
            ax.plot(dl["eta"], dl["d"], "-", marker="o", markevery=max(1, dl["d"].size // 40), ms=3, lw=0.8,
                    color=c, alpha=0.8, label=(f"DEM b = {b:g}" + (f" ({len(ts)} seeds)" if len(ts) > 1 else "")
                                               + (" (left its path)" if t["status"] == "failed" else ""))
                    if i == 0 else None)
            k = int(np.nanargmax(dl["eta"]))
            ax.plot(dl["eta"][k], dl["d"][k], "^", ms=8, color=c, mec="k", zorder=5)
            if model is not None:
                ax.plot(dl["eta"], model(dl["eta"], dl["psi"], dl["theta"]), "--", color=c, lw=1.4)
    ax.plot([], [], "^", color="0.5", mec="k", ms=8, label="peak q/p (the loop's turning point)")
    if model is not None:
        ax.plot([], [], "--", color="k", label=f"model, Li 3D: d0 = {d0:.3g}, m = {m:.3g}, M_c = {Mc:.3g}, K = {K:.3g}")
    else:
        ax.text(0.5, 0.9, "model not drawn: " + why, transform=ax.transAxes, ha="center", color="C3")
    if shown:  # the first rows' derivatives can be large: keep the loop in frame, say what is cut
        d = np.concatenate(shown)
        top = float(np.clip(np.nanpercentile(d, 99.5), 0.3, 2.0)) + 0.1
        ax.set_ylim(float(np.nanmin(d)) - 0.1, top)
        if np.sum(d > top):
            ax.text(0.99, 0.99, f"{int(np.sum(d > top))} point(s) above the frame", transform=ax.transAxes,
                    ha="right", va="top", fontsize=7)
    ax.axhline(0, color="0.6", lw=0.8)
    ax.set_xlabel("stress ratio eta = q/p")
    ax.set_ylabel("dilatancy d = d eps_v^p / d eps_q^p (plastic increments), compression +")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="lower left")
    ax.set_title(f"Figs 8-12: {PATH_LABEL.get(path, path)}, p0 = {p0 / 1e6:g} MPa, every b, from the first row\n"
                 f"({note}d0, m fitted on this path's b = 0 tests at eps_1 >= {100 * FIT_FROM:g} %, every p0)",
                 fontsize=9)
    fig.tight_layout()
    b_colorbar(fig, ax)
    return fig


def b_colorbar(fig, axes):
    from matplotlib import colormaps, colors
    from matplotlib.cm import ScalarMappable
    cmap = colors.ListedColormap(colormaps["viridis"](np.linspace(0, 0.9, 256)))
    fig.colorbar(ScalarMappable(norm=colors.Normalize(0, 1), cmap=cmap), ax=axes, label="b", fraction=0.03, pad=0.02)


# ---------------------------------------------------------------- writing

def save(fig, out, stem, command, files, dpi=90):
    """PNG with the command that redraws it in its metadata (Description)."""
    name = stem + ".png"
    fig.savefig(os.path.join(out, name), dpi=dpi, bbox_inches="tight",
                metadata={"Title": stem, "Description": command, "Software": "sandcell_analysis.study_figures"})
    _plt().close(fig)
    files.append(name)


def p0_tag(p0):
    return f"p0_{p0 / 1e3:g}kPa"


def draw_all(tests, out, command, p0s=None, moduli="initial"):
    """Every figure of the study for the tests (read_test dicts with status and critical); returns the
    file names. `command` (the command line that redraws them) goes into each PNG and README.md."""
    os.makedirs(out, exist_ok=True)
    files = []
    pairs = sorted({(t["path"], round(float(t["p0"]))) for t in tests if t["path"] in PATH_LABEL},
                   key=lambda k: (PATHS.index(k[0]), k[1]))
    if p0s:
        pairs = [k for k in pairs if any(abs(k[1] - p) <= 1e-3 * p for p in p0s)]
    for path, p0 in pairs:
        save(fig_stress_strain(tests, path, p0), out, f"stress_strain-{path}-{p0_tag(p0)}", command, files)
    save(fig_csl(tests), out, "csl", command, files)
    save(fig_m_theta(tests), out, "m_theta", command, files)
    _, Mc, K, note = dilatancy_inputs(tests, moduli)
    for path, p0 in pairs:
        save(fig_dilatancy(tests, path, p0, Mc, K, note), out, f"dilatancy-{path}-{p0_tag(p0)}", command, files)
    seeds = max(len(ts) for ts in seed_groups(tests).values())
    what = {"stress_strain": "Figs 2-3: q/p and eps_v against eps_1 and eps_q, one p0, every b; each curve to the end "
                             "of its data (filled circle: stopped at the app's critical-state test; diamond: done at "
                             "its set end; cross and dashed: left its stress path; open circle: running)",
            "csl": f"Fig 4: the critical state line on (p/p_a)^xi with the study's xi = {STUDY_XI}, on log p, and on "
                   "the project's fitted xi (the study's line curved there)",
            "m_theta": "Fig 6: critical q/p against the Lode angle and in the pi-plane: the fitted g(theta), "
                       f"g(theta) derived from phi = {STUDY['phi_deg']:g} deg (not the study's fit), Matsuoka-Nakai "
                       "and Lade-Duncan through the b = 0 point",
            "dilatancy": "Figs 8-12: d = d eps_v^p / d eps_q^p (plastic increments) against eta, one p0, every b, "
                         "from the first row (the pre-peak loop; triangle: the peak of q/p, its turning point), "
                         "DEM against Li's 3D form with d0, m fitted on the path's b = 0 tests at eps_1 >= 1 %"}
    with open(os.path.join(out, "README.md"), "w", encoding="utf-8") as fh:
        fh.write("# The study's figures (Liu, Ma, Zhou & Chang 2017), redrawn\n\n"
                 f"Redrawn by (from the repository root; `study_figures.py`):\n\n```sh\n{command}\n```\n\n"
                 f"{len(tests)} tests, {len(critical_tests(tests))} at the critical state on their stress path (the "
                 f"points of Figs 4 and 6); up to {seeds} seed(s) per (path, b, p0): curves are the seeds' mean with "
                 "a +-1 SD band, points the mean with +-1 SD bars. Each PNG holds this command in its metadata "
                 "(key Description).\n\n")
        for stem, text in what.items():
            names = [f for f in files if f.split("-")[0] == stem or f == stem + ".png"]
            fh.write(f"- {text}: " + ", ".join(f"[{f}]({f})" for f in names) + "\n")
    return files


def main(argv=None):
    argv = sys.argv[1:] if argv is None else list(argv)
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n\n")[0],
                                 epilog=__doc__.split("\n\n", 2)[2],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results", nargs="+", help="results files or folders (several folders: seeds)")
    ap.add_argument("--out", required=True, help="output folder")
    ap.add_argument("--p0", type=float, action="append",
                    help="draw Figs 2-3 and 8-12 for this p0 only (Pa; repeatable)")
    ap.add_argument("--moduli", choices=("initial", "none"), default="initial",
                    help="the elastic parts removed from the dilatancy's increments: each test's initial moduli, "
                         "or none (total increments)")
    opt = ap.parse_args(argv)
    command = shlex.join(["PYTHONPATH=apps/analysis", "python3", "-m", "sandcell_analysis", "figures", *argv])
    try:
        files = draw_all(load_tests(opt.results), opt.out, command, opt.p0, opt.moduli)
    except InputError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    print(f"{PROG}: {len(files)} figures in {opt.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
