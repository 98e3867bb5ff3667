"""The study's figures (sandcell_analysis.study_figures) on a synthetic campaign written here: every figure
draws one curve or point per (path, b, p0) with seeds grouped, the CSL axis is the given xi, the
comparison surfaces are what they are named, and each PNG carries the command that redraws it."""
import math
import os

import numpy as np
import pytest

from helpers import caricature, command, write_results
from sandcell_analysis import study_figures as sf
from sandcell_analysis.csl import PA
from sandcell_analysis.m_theta import lode_from_b

P0S, BS = (0.5e6, 2e6, 8e6), (0.0, 0.5, 1.0)
SEEDED = ("constant_p", 0.5, 0.5e6)  # three seeds: s1 (with the others) and s2, s3


def _write(folder, path, b, p0, seed, status="done"):
    """A caricature's results file; in folder s1 its line in index.csv too (the app's status)."""
    name = f"{'p' if path == 'constant_p' else 's3'}-b{b:.2f}-p0_{p0 / 1e3:g}kPa"
    os.makedirs(folder, exist_ok=True)
    if folder.endswith("s1"):
        index = os.path.join(folder, "index.csv")
        with open(index, "a") as fh:
            fh.write(("" if os.path.exists(index) and os.path.getsize(index) else "test,status\n")
                     + f"{name},{'done (critical state)' if status == 'done' else status}\n")
    write_results(os.path.join(folder, name + ".h5"),
                  caricature(p0, b, rows=301, rng=np.random.default_rng(seed)),
                  {"job": name, "stage": "shear", "path": path, "b": str(b), "p0": str(p0), "status": status})


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    root = tmp_path_factory.mktemp("campaign")
    k = 0
    for path in ("constant_p", "constant_sigma3"):
        for p0 in P0S:
            for b in BS:
                k += 1
                failed = path == "constant_sigma3" and b == 0.5 and p0 == 2e6
                _write(str(root / "s1"), path, b, p0, k, "failed" if failed else "done")
    for s in ("s2", "s3"):
        k += 1
        _write(str(root / s), SEEDED[0], SEEDED[1], SEEDED[2], k)
    dirs = [str(root / s) for s in ("s1", "s2", "s3")]
    return dirs, sf.load_tests(dirs)


def _curves(ax):
    return [ln for ln in ax.lines if len(ln.get_xdata()) > 1]


def test_seeds_grouped_by_path_b_p0(campaign):
    _, tests = campaign
    groups = sf.seed_groups(tests)
    assert len(tests) == 2 * len(P0S) * len(BS) + 2
    assert len(groups) == 2 * len(P0S) * len(BS)
    assert len(groups[(SEEDED[0], SEEDED[1], round(SEEDED[2]))]) == 3
    assert sum(len(v) for v in groups.values()) == len(tests)


def test_mean_curve_of_seeds():
    x = np.linspace(0, 1, 11)
    same = [{"x": x, "y": x ** 2}, {"x": x, "y": x ** 2}]
    g, mean, std, n = sf.mean_curve(same, "x", "y", n=21)
    np.testing.assert_allclose(mean, np.interp(g, x, x ** 2), atol=1e-15)
    np.testing.assert_allclose(std, 0.0, atol=1e-15)
    g, mean, std, n = sf.mean_curve([{"x": x, "y": x}, {"x": x, "y": x + 1}], "x", "y", n=21)
    np.testing.assert_allclose(mean, g + 0.5, atol=1e-12)
    np.testing.assert_allclose(std, math.sqrt(0.5), atol=1e-12)
    # a shorter seed: beyond its end the mean is the longer one's and no spread is claimed
    g, mean, std, n = sf.mean_curve([{"x": x, "y": x}, {"x": x[:6], "y": x[:6] + 1}], "x", "y", n=21)
    beyond = g > 0.5
    np.testing.assert_allclose(mean[beyond], g[beyond], atol=1e-12)
    assert np.all(np.isnan(std[beyond])) and np.all(n[beyond] == 1)


@pytest.mark.parametrize("xi", [0.7, 0.971, 1.6])
def test_csl_axis_straightens_the_line_of_its_xi(xi):
    p = np.geomspace(0.3e6, 20e6, 9)
    e = 0.72 - 0.003 * (p / PA) ** xi
    x = sf.csl_x(p, xi)
    fit = np.polyfit(x, e, 1)
    assert np.max(np.abs(e - np.polyval(fit, x))) < 1e-12
    x_other = sf.csl_x(p, xi + 0.3)  # the same points on another xi's axis are curved
    assert np.max(np.abs(e - np.polyval(np.polyfit(x_other, e, 1), x_other))) > 1e-4


def _fake(path, b, p0, e, M, source="s1"):
    return {"path": path, "b_nominal": b, "p0": p0, "status": "done", "source": source,
            "critical": {"reached": True, "point": {"p": p0, "e": e, "M": M, "theta": float(lode_from_b(b))}}}


@pytest.mark.parametrize("xi", [0.7, 0.971])
def test_csl_figure_draws_points_at_the_given_xi(xi):
    eg, lam = 0.75, 0.0004
    tests = [_fake(pk, b, p0, eg - lam * (p0 / PA) ** xi, 1.0)
             for pk in ("constant_p", "constant_sigma3") for b in BS for p0 in (0.5e6, 1e6, 4e6, 16e6)]
    fig = sf.fig_csl(tests, study_xi=xi)
    ax = fig.axes[0]
    pts = np.array([c.lines[0].get_xydata()[0] for c in ax.containers])
    assert len(pts) == len(tests)
    np.testing.assert_allclose(np.sort(np.unique(pts[:, 0])), np.sort(sf.csl_x([0.5e6, 1e6, 4e6, 16e6], xi)),
                               rtol=1e-14)
    line = np.polyfit(pts[:, 0], pts[:, 1], 1)
    assert np.max(np.abs(pts[:, 1] - np.polyval(line, pts[:, 0]))) < 1e-12
    np.testing.assert_allclose(line, [-lam, eg], rtol=1e-9)
    assert "the study's xi" in ax.get_title() and "log" in fig.axes[1].get_xscale()


@pytest.mark.parametrize("kind", ["mn", "ld"])
def test_comparison_surfaces_are_their_invariants(kind):
    Mc = 1.1
    theta = np.linspace(0, np.pi / 3, 13)
    M = sf.surface_M(kind, theta, Mc)
    assert M[0] == pytest.approx(Mc, rel=1e-12)
    values = [sf._criterion(kind, sf.principal(np.array(t), m)) for t, m in zip(theta, M)]
    np.testing.assert_allclose(values, values[0], rtol=1e-10)
    if kind == "mn":  # Matsuoka-Nakai: the same friction angle in extension as in compression
        s = 3 * Mc / (6 + Mc)
        assert M[-1] == pytest.approx(6 * s / (3 + s), rel=1e-10)


def test_principal_stresses_have_their_b_p_q():
    for b in (0.0, 0.3, 1.0):
        s = sf.principal(np.array(lode_from_b(b)), 0.9, p=2.0)
        assert (s[1] - s[2]) / (s[0] - s[2]) == pytest.approx(b, abs=1e-12)
        assert s.mean() == pytest.approx(2.0)
        q = math.sqrt(0.5 * ((s[0] - s[1]) ** 2 + (s[1] - s[2]) ** 2 + (s[2] - s[0]) ** 2))
        assert q == pytest.approx(1.8)


def test_phi22_reference():
    Mc, K = sf.phi22_Mc_K(22.0)
    s = math.sin(math.radians(22))
    assert 3 * Mc / (6 + Mc) == pytest.approx(s) and 3 * Mc * K / (6 - Mc * K) == pytest.approx(s)


def test_stress_strain_figure(campaign):
    _, tests = campaign
    fig = sf.fig_stress_strain(tests, *SEEDED[::2])
    ts = [t for t in tests if t["path"] == SEEDED[0] and t["p0"] == SEEDED[2]]
    for ax in fig.axes[:4]:
        assert len(_curves(ax)) == len(BS)  # one (mean) curve per b
        ends = [ln for ln in ax.lines if len(ln.get_xdata()) == 1]
        assert len(ends) == len(ts)  # every seed's end marked
        assert len(ax.collections) == 1  # the seeds' band, of the one seeded group
    # how each ended: s1's index.csv says critical state (circle); s2, s3 have none (done: diamond)
    ends = [ln.get_marker() for ln in fig.axes[0].lines if len(ln.get_xdata()) == 1]
    assert sorted(ends) == ["D", "D", "o", "o", "o"]
    # each single-seed curve runs to its test's last row
    for t in ts:
        if b_of(t) != SEEDED[1]:
            x_end = [ln.get_xdata()[-1] for ln in _curves(fig.axes[0])]
            assert any(x == pytest.approx(100 * t["eps1"][-1]) for x in x_end)


def b_of(t):
    return round(t["b_nominal"], 3)


def test_failed_test_drawn_dashed(campaign):
    _, tests = campaign
    fig = sf.fig_stress_strain(tests, "constant_sigma3", 2e6)
    styles = sorted(ln.get_linestyle() for ln in _curves(fig.axes[0]))
    assert styles == ["-", "-", "--"]
    assert any(ln.get_marker() == "x" for ln in fig.axes[0].lines if len(ln.get_xdata()) == 1)


def test_m_theta_figure(campaign):
    _, tests = campaign
    crit = sf.critical_tests(tests)
    assert len(crit) == len(tests) - 1  # the failed test gives no point
    fig = sf.fig_m_theta(tests)
    ax = fig.axes[0]
    assert len(ax.containers) == len(sf.seed_groups(crit))
    labels = [ln.get_label() for ln in _curves(ax)]
    assert len(labels) == 4
    assert any("derived from phi = 22 deg" in s and "not the study's fit" in s for s in labels)
    assert any(s.startswith("Matsuoka-Nakai through the b = 0") for s in labels)
    assert any(s.startswith("Lade-Duncan through the b = 0") for s in labels)
    seeded = [c for c in ax.containers if c.has_yerr]
    assert len(seeded) == 1  # error bars only where seeds are


def test_dilatancy_figure_keeps_the_first_rows(campaign):
    _, tests = campaign
    _, Mc, K, _ = sf.dilatancy_inputs(tests, "none")  # the caricature has no elastic part
    ts = [t for t in tests if t["path"] == SEEDED[0] and t["p0"] == SEEDED[2]]
    for t in ts:  # the first 1 % is not cut
        assert t["study_dil"]["eps1"][0] < 0.002 and t["study_dil"]["eps1"][0] == t["eps1"][0]
    zero = [t["study_dil"] for t in tests if b_of(t) == 0 and t["path"] == "constant_p"]
    model, d0, m, why = sf.dilatancy_model(zero, Mc, K)
    assert model is not None and np.isfinite(d0) and np.isfinite(m), why
    fig = sf.fig_dilatancy(tests, SEEDED[0], SEEDED[2], Mc, K)
    ax = fig.axes[0]
    dem = [ln for ln in _curves(ax) if ln.get_linestyle() == "-" and ln.get_marker() == "o"]
    mod = [ln for ln in _curves(ax) if ln.get_linestyle() == "--"]
    peaks = [ln for ln in ax.lines if ln.get_marker() == "^" and len(ln.get_xdata()) == 1]
    assert len(dem) == len(mod) == len(peaks) == len(ts)  # every seed, its model, its turning point
    dl = ts[0]["study_dil"]
    np.testing.assert_allclose(mod[0].get_ydata(), model(dl["eta"], dl["psi"], dl["theta"]))


def test_command_writes_figures_with_their_command(campaign, tmp_path):
    import subprocess
    from PIL import Image
    dirs, _ = campaign
    out = str(tmp_path / "figs")
    argv = [*dirs, "--out", out, "--p0", "500000", "--moduli", "none"]
    r = subprocess.run(command("figures") + argv, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    pngs = sorted(f for f in os.listdir(out) if f.endswith(".png"))
    pairs = [(k, p) for k in ("dilatancy", "stress_strain") for p in ("constant_p", "constant_sigma3")]
    assert pngs == sorted(["csl.png", "m_theta.png"] + [f"{k}-{p}-p0_500kPa.png" for k, p in pairs])
    readme = open(os.path.join(out, "README.md")).read()
    for f in pngs:
        desc = Image.open(os.path.join(out, f)).info["Description"]
        assert desc in readme and desc.endswith(" ".join(argv)) and " figures " in desc
        assert os.path.getsize(os.path.join(out, f)) < 300_000
        assert f"]({f})" in readme
    r = subprocess.run(command("figures") + [str(tmp_path / "none"), "--out", out], capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.count("\n") == 1
    r = subprocess.run(command("figures")[:-1] + ["--help"], capture_output=True, text=True)
    assert "\n  figures " in r.stdout


def test_no_critical_point_still_draws(campaign, tmp_path):
    """A campaign still running (no test at the critical state on its path): Figs 2-3 and 8-12 are drawn,
    Figs 4 and 6 with the study's curves only, and no model."""
    _, tests = campaign
    running = [dict(t, status="running") for t in tests if t["p0"] == SEEDED[2]]
    files = sf.draw_all(running, str(tmp_path), "the command", moduli="none")
    assert len(files) == 2 + 2 * 2
    fig = sf.fig_m_theta(running)
    assert len(fig.axes[0].containers) == 0 and len(_curves(fig.axes[0])) == 1
