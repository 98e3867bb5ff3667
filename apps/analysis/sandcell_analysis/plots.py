"""The figures: of `triaxial analyze` (stress-strain, CSL, pi plane, dilatancy), of a single run
(plot_triaxial.py, after each test) and of `triaxial localization`. matplotlib is imported when a
figure is drawn (Agg backend), so the other modules need none."""
import math
import os
import textwrap

import numpy as np

from . import localization as loc
from .csl import PA, csl_e
from .dilatancy import dilatancy_g, dilatancy_li, dilatancy_li3d
from .fitting import NAN
from .m_theta import m_theta, mohr_coulomb_M
from .reference import STUDY
from .results import b_key, read_columns, read_job

PATH_LABEL = {"constant_p": "constant p", "constant_sigma3": "constant sigma3", "strain": "strain",
              "undrained": "undrained", "cyclic": "cyclic"}
PATH_MARKER = {"constant_p": "o", "constant_sigma3": "s", "strain": "^", "undrained": "D", "cyclic": "v"}


def pyplot():
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
        for t in sorted(ts, key=b_key):
            c = _b_color(plt, b_key(t))
            lab = f"b = {b_key(t):g}" + ("" if t["critical"]["reached"] else " (not critical)")
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
        c = _b_color(plt, b_key(t))
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
        c = _b_color(plt, b_key(t))
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
        bs = sorted({b_key(t) for t in ts if np.isfinite(b_key(t))}) or [NAN]
        ncol = min(3, len(bs))
        nrow = int(math.ceil(len(bs) / ncol))
        fig, axes = plt.subplots(nrow, ncol, figsize=(4.6 * ncol, 3.9 * nrow), squeeze=False)
        p0s = sorted({t["p0"] for t in ts})
        for ax, bk in zip(axes.flat, bs):
            sel = [t for t in ts if b_key(t) == bk or (not np.isfinite(bk))]
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


def plot_run(results, png):
    """The figure of one run (plot_triaxial.py, drawn after each test): q, q/p, eps_v and e against
    eps_1 (soil convention, compression positive)."""
    from .results import open_results, attr
    from . import shearing
    with open_results(results) as f:
        path = attr(f, "path")
    if path in shearing.SHEARING_PATHS:  # simple shear or rotation: their own axes
        shearing.plot_run(results, png, path, read_job(results))
        return
    plt = pyplot()
    s = read_columns(results, ("strain", "q", "p", "eps_v", "e"))
    eps1 = 100.0 * s["strain"][:, 0]
    q = s["q"] / 1e6
    p = s["p"] / 1e6
    eps_v = 100.0 * s["eps_v"]
    e = s["e"]
    title = read_job(results)
    fig, ax = plt.subplots(2, 2, figsize=(10, 7), sharex=True)
    ax[0, 0].plot(eps1, q, "C0")
    ax[0, 0].set_ylabel("q (MPa)")
    ax[0, 1].plot(eps1, q / p, "C1")
    ax[0, 1].set_ylabel("q/p")
    ax[1, 0].plot(eps1, eps_v, "C2")
    ax[1, 0].set_ylabel("eps_v (%) [compression +]")
    ax[1, 1].plot(eps1, e, "C3")
    ax[1, 1].set_ylabel("void ratio e")
    for a in ax[1]:
        a.set_xlabel("axial strain eps_1 (%)")
    for a in ax.flat:
        a.grid(True, alpha=0.3)
    fig.suptitle(f"sandcell triaxial {title}")
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)


def draw_map(fig, ax, q, L, r, title):
    """deps_q averaged along an axis in the band plane (its mode component 0), else a slice normal to axis 2."""
    hkl = (r["mode_h"], r["mode_k"], r["mode_l"])
    flat = [a for a in (1, 2, 0) if hkl[a] == 0]
    if flat:
        axis, how = flat[0], f"mean along x{flat[0] + 1}"
        image = q.mean(axis=axis)
    else:
        axis, how = 1, f"slice x2 = {L[1] * (q.shape[1] // 2 + 0.5) / q.shape[1]:.3g} m"
        image = q[:, q.shape[1] // 2, :]
    rr, cc = [a for a in range(3) if a != axis]
    im = ax.imshow(image, origin="lower", interpolation="nearest", extent=[0, L[cc], 0, L[rr]], cmap="viridis")
    ax.set_xlabel(f"x{cc + 1} (m)")
    ax.set_ylabel(f"x{rr + 1} (m)")
    ax.set_title(f"{title}: steps {r['step_a']}-{r['step_b']}, eps_1 = {r['eps1_mid']:.3f}\n"
                 f"{how}; mode {hkl} share {r['mode_share']:.2f}", fontsize=8)
    fig.colorbar(im, ax=ax, label="local deps_q")


def draw_band(ax_q, ax_e, b):
    """The band profile: whole-test deps_q and deps_v per slab, and e per slab at the first, middle and last
    snapshot, across xi; the band's slabs shaded. Without a band, the reason."""
    if b["rows"] is None:
        for ax in (ax_q, ax_e):
            ax.axis("off")
        ax_q.text(0.5, 0.5, "band profile\n\n" + textwrap.fill(b["note"], 40), ha="center", va="center", fontsize=9,
                  transform=ax_q.transAxes)
        return
    K, rows = b["K"], b["rows"]
    edges = np.arange(K + 1) / K
    for ax in (ax_q, ax_e):
        for j in np.flatnonzero(b["band"]):
            ax.axvspan(edges[j], edges[j + 1], color="C1", alpha=0.15, lw=0)
        ax.set_xlim(0, 1)
        ax.grid(alpha=0.3)
    ax_q.stairs(b["deps_q"], edges, baseline=None, color="C0", lw=1.5, label="deps_q")
    ax_q.stairs(b["deps_v"], edges, baseline=None, color="C3", lw=1.5, ls="--", label="deps_v (compression +)")
    ax_q.axhline(0.0, color="0.5", lw=0.6)
    ax_q.set_ylabel("local strain, whole test")
    j = b["judged"]
    ax_q.set_title(f"{'BANDED' if b['banded'] else 'no band (candidate mode)'}: mode {loc.mode_str(b['hkl'])} share "
                   f"{b['share']:.2f} (surrogates {max(j['threshold_noise'], j['threshold_gauss']):.2f})\nband/outside "
                   f"deps_q {b['ratio']:.2f} (>= 2), e contrast growth {b['growth']:+.3f} (noise {b['noise']:.3f})\n"
                   f"{K} slabs of equal xi; band slabs shaded", fontsize=8)
    ax_q.legend(fontsize=7)
    picks = sorted({0, len(rows) // 2, len(rows) - 1})
    for c, k in enumerate(picks):
        r = rows[k]
        ax_e.stairs(r["e_slab"], edges, baseline=None, color=f"C{c}", lw=1.5,
                    label=f"step {r['step']}, eps_1 = {r['eps_1']:.3f}")
        ax_e.axhline(r["e_whole"], color=f"C{c}", lw=0.8, ls=":")
    shown = np.concatenate([rows[k]["e_slab"] for k in picks])
    shown = shown[np.isfinite(shown)]
    if shown.size:  # the data's range, not down to 0
        pad = 0.08 * max(shown.max() - shown.min(), 1e-3)
        ax_e.set_ylim(shown.min() - pad, shown.max() + pad)
    s = loc.band_summary(b)
    ax_e.set_xlabel("xi = frac(h s1 + k s2 + l s3) (kept by the cell's affine deformation)")
    ax_e.set_ylabel("void ratio of the slab (dotted: all)")
    ax_e.set_title(f"e band {s['band']['e0']:.3f} -> {s['band']['e1']:.3f}, outside {s['outside']['e0']:.3f} -> "
                   f"{s['outside']['e1']:.3f}", fontsize=8)
    ax_e.legend(fontsize=7)


def localization_figure(path, src, res, best):
    plt = pyplot()
    rows, series = res["rows"], res["series"]
    eps1 = [r["eps1_mid"] for r in rows]
    fig, axs = plt.subplots(2, 3, figsize=(17, 9))
    ax = axs[0, 0]
    for key, label, style in (("deps_q_cv", "CV of local deps_q", "o-"), ("top10_share", "top-10 % share", "s-"),
                              ("mode_share", "largest mode share", "^-"),
                              ("shuffled_share", "mode share, bins shuffled (old null)", "v:")):
        ax.plot(eps1, [r[key] for r in rows], style, ms=4, label=label)
    ax.plot(eps1, [max(r["threshold_noise"], r["threshold_gauss"]) for r in rows], "k_", ms=12, mew=2,
            label="mode share: surrogates' 0.99 quantile")
    hit = [k for k, r in enumerate(rows) if r["band_detected"]]
    if hit:
        ax.plot([eps1[k] for k in hit], [rows[k]["mode_share"] for k in hit], "o", mfc="none", mec="r", ms=10,
                label="band detected")
    ax.axhline(loc.TOP, color="0.6", lw=0.8, ls="--", label="top-10 % share if uniform")
    ax.set_xlabel("eps_1 (increment midpoint)")
    ax.set_ylabel("localization measures")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    ax = axs[1, 0]
    if "eta" in series:
        ax.plot(series["strain"][:, 0], series["eta"], color="C0")
    ax.set_ylabel("q/p", color="C0")
    ax.set_xlabel("eps_1")
    ax.grid(alpha=0.3)
    if "e" in series:
        tw = ax.twinx()
        tw.plot(series["strain"][:, 0], series["e"], color="C3")
        tw.set_ylabel("void ratio e", color="C3")
    # both panels over the whole test: a few increments are read against the whole curve
    lo, hi = min(series["strain"][:, 0].min(), min(eps1)), max(series["strain"][:, 0].max(), max(eps1))
    for a in axs[:, 0]:
        a.set_xlim(lo - 0.02 * (hi - lo), hi + 0.02 * (hi - lo))
    for k, ax, title in ((len(rows) - 1, axs[0, 1], "last increment"), (best, axs[1, 1], "largest mode share")):
        draw_map(fig, ax, *res["fields"][k], rows[k], title)
    draw_band(axs[0, 2], axs[1, 2], res["band"])
    fig.suptitle(f"local strain increments of {os.path.basename(src)} ({res['G']}^3 bins): "
                 f"{'banded' if res['band']['banded'] else 'no band'}. "
                 f"Reproduce: triaxial localization {'--whole ' if res.get('whole') else ''}{os.path.basename(src)}",
                 fontsize=10)
    fig.tight_layout()
    loc.write_atomic(path, lambda tmp: fig.savefig(tmp, format="png", dpi=110))
    plt.close(fig)
