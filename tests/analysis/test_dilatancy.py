"""Dilatancy (sandcell_analysis.dilatancy): the Li-Dafalias and 3D fits on data made with known
parameters, and the Savitzky-Golay dilatancy series."""
import math
import unittest

import numpy as np

from helpers import within
from sandcell_analysis import dilatancy
from sandcell_analysis import m_theta


def _dilatancy_data(rng, n, b_values):
    b = rng.choice(b_values, n)
    theta = m_theta.lode_from_b(b)
    eta = rng.uniform(0.3, 1.5, n)
    psi = rng.uniform(-0.15, 0.02, n)
    return eta, psi, theta


class Dilatancy(unittest.TestCase):
    def test_li_dafalias_recovers_d0_m(self):
        # The study's d0 = 0.619, m = 4.57 with M = 1.25; 400 points over eta 0.3-1.5 and psi
        # -0.15..0.02 (dense to critical), noise 0.02 on d (a smoothed DEM dilatancy). Absolute
        # bounds (0.02, 0.2) are ~6 standard errors (0.003, 0.03) of this design.
        rng = np.random.default_rng(3)
        eta, psi, _ = _dilatancy_data(rng, 400, [0.0])
        d = dilatancy.dilatancy_li(eta, psi, 1.25, 0.619, 4.57) + rng.normal(0, 0.02, eta.size)
        r = dilatancy.fit_li_dafalias(eta, psi, d, 1.25)
        self.assertTrue(r["fitted"])
        within(self, r["params"]["d0"], 0.619, r["stderr"]["d0"], 4, 0.02, "d0")
        within(self, r["params"]["m"], 4.57, r["stderr"]["m"], 4, 0.2, "m")
        # the MSE estimates the noise variance 4e-4 (sampling error ~7 % with 400 points)
        self.assertAlmostEqual(r["mse"], 4e-4, delta=1e-4)

    def test_g_form_recovers_alpha_beta(self):
        # alpha = 0.8, beta = 1.5 with K = 0.8 (g from 0.8 to 1): d0 g^-alpha changes by up to
        # 20 % and m g^beta by 30 % across b, measurable with 600 points of noise 0.02. Absolute
        # bounds (0.15, 0.25) are ~6 standard errors (0.023, 0.044) of this design.
        rng = np.random.default_rng(4)
        eta, psi, theta = _dilatancy_data(rng, 600, [0.25, 0.5, 0.75, 1.0])
        args = (1.25, 0.8, 0.619, 4.57)
        d = dilatancy.dilatancy_g(eta, psi, theta, *args, 0.8, 1.5) + rng.normal(0, 0.02, eta.size)
        r = dilatancy.fit_g_form(eta, psi, theta, d, *args)
        self.assertTrue(r["fitted"], r["note"])
        within(self, r["params"]["alpha"], 0.8, r["stderr"]["alpha"], 4, 0.15, "alpha")
        within(self, r["params"]["beta"], 1.5, r["stderr"]["beta"], 4, 0.25, "beta")
        self.assertLess(r["mse"], r["mse_li3d"])  # the data are not Li's form
        # alpha = beta = 0 is Li's 3D form
        self.assertTrue(np.allclose(dilatancy.dilatancy_g(eta, psi, theta, *args, 0.0, 0.0),
                                    dilatancy.dilatancy_li3d(eta, psi, theta, *args)))

    def test_g_form_not_identifiable_at_b0(self):
        eta, psi, theta = _dilatancy_data(np.random.default_rng(5), 50, [0.0])
        r = dilatancy.fit_g_form(eta, psi, theta, eta * 0, 1.25, 0.8, 0.6, 4.0)
        self.assertFalse(r["fitted"])
        self.assertIn("not identifiable", r["note"])

    def test_savitzky_golay_dilatancy_of_a_known_path(self):
        # eps_v = -0.4 eps_q + 0.02 eps_q^2 (d = -0.4 + 0.04 eps_q) is a quadratic, which a
        # quadratic Savitzky-Golay filter differentiates exactly: d to 1e-9 at every kept point.
        eps1 = np.linspace(0, 0.3, 601)
        eps_q = 1.1 * eps1
        eps_v = -0.4 * eps_q + 0.02 * eps_q ** 2
        r = dilatancy.dilatancy_series(eps1, eps_v, eps_q, smooth=0.02, min_strain=0.01)
        m = r["mask"]
        self.assertEqual(r["window_rows"], 41)  # 0.02 / 0.0005 + 1
        self.assertTrue(np.all(eps1[m] >= 0.01) and m[eps1 >= 0.01].all())
        np.testing.assert_allclose(r["d"][m], -0.4 + 0.04 * eps_q[m], atol=1e-9)

    def test_dilatancy_theta_is_that_of_the_smoothed_stress_not_the_smoothed_sorted_rows(self):
        # The same path with the three normal stresses fluctuating +-3 % independently about a
        # state of exact b (0, 0.5, 1). Each row's b from sorted principal stresses is biased away
        # from 0 and 1, and smoothing the rows keeps the bias (theta ~1.3 deg high at b = 0, ~3
        # deg low at b = 1). The smoothed tensor is sorted too, but its noise is ~4x smaller (a
        # 41-row quadratic Savitzky-Golay filter), and so is what is left of the bias: at seeds
        # 21-23, 0.005-0.007 in b at b = 0 and 0.014-0.016 at b = 1. The checks: at b = 0.5
        # (no bias) the mean b within 0.005 (noise of a mean of ~580 smoothed rows, sd ~0.01
        # each); at b = 0 and 1, within 0.02 and a third of the rows' bias in theta or less.
        eps1 = np.linspace(0, 0.3, 601)
        eps_q = 1.1 * eps1
        eps_v = -0.4 * eps_q + 0.02 * eps_q ** 2
        n = eps1.size
        rng = np.random.default_rng(21)
        for b in (0.0, 0.5, 1.0):
            p = 5e5
            s1, s3 = 1.6 * p, 0.7 * p
            s2 = s3 + b * (s1 - s3)
            stress = np.column_stack([s1 * (1 + rng.normal(0, 0.03, n)), s2 * (1 + rng.normal(0, 0.03, n)),
                                      s3 * (1 + rng.normal(0, 0.03, n)), np.zeros((n, 3))])
            ps = np.sort(stress[:, :3], axis=1)[:, ::-1]
            theta_rows = m_theta.lode_from_b((ps[:, 1] - ps[:, 2]) / (ps[:, 0] - ps[:, 2]))
            r = dilatancy.dilatancy_series(eps1, eps_v, eps_q, smooth=0.02, min_strain=0.01,
                                           others={"theta": theta_rows}, stress=stress)
            m = r["mask"]
            self.assertGreater(m.sum(), 500)
            np.testing.assert_allclose(r["theta"], m_theta.lode_from_b(r["b"]))
            truth = float(m_theta.lode_from_b(b))
            bias = float(np.mean(r["theta"][m])) - truth
            bias_rows = float(np.mean(r["theta_rows"][m])) - truth
            if b == 0.5:
                self.assertAlmostEqual(float(np.mean(r["b"][m])), b, delta=0.005)
            else:
                self.assertAlmostEqual(float(np.mean(r["b"][m])), b, delta=0.02)
                self.assertGreater(abs(bias_rows), math.radians(1.0))
                self.assertLess(abs(bias), abs(bias_rows) / 3)
        # Without a stress tensor the smoothed rows' theta is kept as theta.
        r = dilatancy.dilatancy_series(eps1, eps_v, eps_q, smooth=0.02, others={"theta": np.zeros(n)})
        self.assertNotIn("theta_rows", r)
        self.assertTrue(np.all(r["theta"] == 0.0))


# --- Issue 45: plastic increments, strain-adaptive smoothing, the phase transformation, m ---

G_TRUE, K_TRUE_BULK = 4.0e8, 3.5e8   # Pa: the moduli of the synthetic record below (DEM-like at 0.5 MPa)
G_STAR = 0.004                       # the plastic shear strain of the record's phase transformation


def elastoplastic_record(path="constant_sigma3", noise=0.0, rng=None):
    """A b = 0 test with known elasticity and a known phase transformation.

    Elastic to q_y = 0.3 q_peak (30 rows, no plastic strain), then plastic shear g = eps_q^p on
    rows geometric in g (DEM rows are even in time, the strain rate ramped in: dense at the start),
    q = q_y + (q_peak - q_y)(1 - exp(-g/0.002)), plastic dilatancy d(g) = 0.6 (1 - g/G_STAR)
    exp(-g/0.05) (contraction, the turning point at g = G_STAR, dilation), eps_v^p = its integral.
    Constant sigma3 at b = 0: p = p0 + q/3; constant p: p = p0. Returns the series and the exact
    d as a function of g."""
    p0, qp = 5e5, 7e5
    qy = 0.3 * qp
    q_el = np.linspace(0, qy, 30, endpoint=False)
    g = np.concatenate([np.zeros(30), np.geomspace(1e-6, 0.3, 800)])
    q = np.concatenate([q_el, qy + (qp - qy) * (1 - np.exp(-g[30:] / 0.002))])

    def d_of(g):
        return 0.6 * (1 - g / G_STAR) * np.exp(-g / 0.05)

    # eps_v^p = int_0^g d: closed form of 0.6 (1 - g/G*) e^{-g/c}
    c = 0.05
    evp = 0.6 * (c * (1 - np.exp(-g / c)) - (c * c - (c * c + c * g) * np.exp(-g / c)) / G_STAR)
    p = p0 + q / 3 if path == "constant_sigma3" else np.full(q.size, p0)
    eps_q = g + q / (3 * G_TRUE)
    eps_v = evp + (p - p0) / K_TRUE_BULK
    if noise:
        eps_v = eps_v + rng.normal(0, noise, eps_v.size)
    return {"eps_q": eps_q, "eps_v": eps_v, "p": p, "q": q, "eta": q / p, "g": g}, d_of


class PlasticDilatancy(unittest.TestCase):
    def test_moduli_from_the_elastic_start(self):
        # The first 20 % of the load is purely elastic here: the least-squares slopes are K and 3G
        # to round-off (1e-9 relative).
        s, _ = elastoplastic_record()
        m = dilatancy.elastic_moduli(s["eps_v"], s["eps_q"], s["p"], s["q"])
        self.assertAlmostEqual(m["G"] / G_TRUE, 1.0, delta=1e-9)
        self.assertAlmostEqual(m["K"] / K_TRUE_BULK, 1.0, delta=1e-9)
        # at constant p, K cannot be measured and its term is dropped (dp = 0 exactly here)
        s, _ = elastoplastic_record("constant_p")
        m = dilatancy.elastic_moduli(s["eps_v"], s["eps_q"], s["p"], s["q"])
        self.assertTrue(math.isnan(m["K"]))
        self.assertIn("K not measured", m["note"])
        self.assertAlmostEqual(m["G"] / G_TRUE, 1.0, delta=1e-9)

    def test_plastic_strains_are_the_generating_ones(self):
        # eps^p = eps - elastic parts, exact with the exact moduli (round-off: 1e-15)
        s, _ = elastoplastic_record()
        evp, eqp = dilatancy.plastic_strains(s["eps_v"], s["eps_q"], s["p"], s["q"], K_TRUE_BULK, G_TRUE)
        np.testing.assert_allclose(eqp, s["g"], atol=1e-15)

    def test_local_quadratic_is_exact_on_a_quadratic(self):
        # a quadratic is reproduced exactly by local quadratics, whatever the window (1e-9)
        x = np.geomspace(1e-5, 0.4, 500)
        y = 0.3 - 2.0 * x + 5.0 * x * x
        (v,), (dv,), h = dilatancy.local_quadratic(x, [y])
        np.testing.assert_allclose(v, y, atol=1e-9)
        np.testing.assert_allclose(dv, -2.0 + 10.0 * x, atol=1e-7)
        np.testing.assert_allclose(h, np.maximum(2e-4, 0.25 * x))

    def test_turning_point_is_kept_and_found(self):
        # With the elastic parts removed and the window proportional to strain, the pre-peak branch
        # and its turning point at g = 0.004 (eps_q ~ 0.0054) survive: found within 5 % of its
        # strain (the local quadratic over +-25 % of the strain biases a curved d by ~ h^2 d'' / 6;
        # measured here 1-2 %), and d itself within 0.02 of the generating d at g = G*/2.
        s, d_of = elastoplastic_record(noise=2e-7, rng=np.random.default_rng(3))
        r = dilatancy.plastic_dilatancy(s["eps_v"], s["eps_q"], s["p"], s["q"], others={"g": s["g"]})
        self.assertAlmostEqual(r["moduli"]["G"] / G_TRUE, 1.0, delta=0.01)
        pt = dilatancy.phase_transformation(r["d"], r["mask"], {"g": s["g"], "eta": s["eta"]})
        self.assertIsNotNone(pt)
        self.assertAlmostEqual(pt["g"] / G_STAR, 1.0, delta=0.05)
        k = int(np.argmin(np.abs(s["g"] - G_STAR / 2)))
        self.assertTrue(r["mask"][k])
        self.assertAlmostEqual(r["d"][k], float(d_of(s["g"][k])), delta=0.02)
        # the total-strain series of before (2 % of eps_1, points from 1 %) keeps nothing before the
        # turning point: its first point is beyond it
        old = dilatancy.dilatancy_series(s["eps_q"], s["eps_v"], s["eps_q"], smooth=0.02, min_strain=0.01)
        self.assertGreater(float(s["g"][old["mask"]][0]), G_STAR)

    def test_elastic_volume_change_is_not_a_phase_transformation(self):
        # A sample that dilates plastically from its first plastic strain (d = -0.3 throughout) on a
        # constant-sigma3 path contracts in total volume at first (dp/K): the total increments show
        # a turning point, the plastic ones none.
        s, _ = elastoplastic_record()
        evp = -0.3 * s["g"]
        eps_v = evp + (s["p"] - s["p"][0]) / K_TRUE_BULK
        r = dilatancy.plastic_dilatancy(eps_v, s["eps_q"], s["p"], s["q"])
        self.assertIsNone(dilatancy.phase_transformation(r["d"], r["mask"], {"g": s["g"]}))
        np.testing.assert_allclose(r["d"][r["mask"]], -0.3, atol=1e-6)
        total = dilatancy.plastic_dilatancy(eps_v, s["eps_q"], s["p"], s["q"],
                                            moduli={"K": NAN, "G": NAN}, min_deq=0.0)
        self.assertIsNotNone(dilatancy.phase_transformation(total["d"], total["mask"], {"g": s["g"]}))

    def test_initial_linear_part(self):
        # d = 0.5 - 0.8 eta up to the largest dilation, then back up: the line is recovered exactly
        eta = np.linspace(0.2, 1.4, 61)
        d = 0.5 - 0.8 * eta
        d = np.concatenate([d, d[-1] + 0.01 * np.arange(1, 21)])
        eta = np.concatenate([eta, np.full(20, 1.4)])
        a, s, n = dilatancy.initial_linear_part(eta, d, np.ones(eta.size, bool))
        self.assertAlmostEqual(a, 0.5, places=10)
        self.assertAlmostEqual(s, -0.8, places=10)
        self.assertEqual(n, 61)


NAN = float("nan")


class IdentifyM(unittest.TestCase):
    M = 1.2

    def test_psi_span_identifies_m(self):
        # 8 phase-transformation states with psi from -0.2 to 0 (the design of issue 45: psi0 from
        # -0.2 to +0.05, the loose ones turning near 0), eta_PT = M exp(4.57 psi) with 1 % noise:
        # the slope's SE is 0.01 / sqrt(Sxx) ~ 0.08, so the 95 % interval (+- 2.4 SE) is ~0.4 wide,
        # bounded, narrower than 4.57 and holding it.
        rng = np.random.default_rng(21)
        psi = np.linspace(-0.2, 0.0, 8)
        eta = self.M * np.exp(4.57 * psi) * (1 + rng.normal(0, 0.01, psi.size))
        r = dilatancy.fit_m_pt(psi, eta, self.M)
        self.assertEqual(r["verdict"], "consistent with the study", r["note"])
        lo, hi = r["interval"]
        self.assertLess(lo, 4.57)
        self.assertGreater(hi, 4.57)
        self.assertLess(hi - lo, 1.0)
        # the interval is m +- t(0.975, n-2) SE (the exact profile-likelihood interval of a line)
        from scipy import stats
        t = stats.t.ppf(0.975, psi.size - 2)
        self.assertAlmostEqual((hi - lo) / (2 * t * r["se"]), 1.0, delta=1e-7)  # F(1, n-2) = t^2 to scipy's quantiles
        # a CSL (or M) off by a constant shifts every psi (or ln M) alike: m does not move (round-off),
        # the through-origin m does
        r2 = dilatancy.fit_m_pt(psi + 0.03, eta, self.M * 1.05)
        self.assertAlmostEqual(r2["m"], r["m"], places=9)
        self.assertGreater(abs(r2["m_origin"] - r["m_origin"]), 0.5)
        # another m is excluded
        eta7 = self.M * np.exp(7.0 * psi) * (1 + rng.normal(0, 0.01, psi.size))
        self.assertEqual(dilatancy.fit_m_pt(psi, eta7, self.M)["verdict"], "not the study's")

    def test_no_psi_span_is_not_identifiable(self):
        # The campaigns' design: every sample at psi ~ -0.20 (spread 0.002), 2 % noise on eta_PT: the
        # slope's SE is ~0.02 / (0.002 sqrt(7)) ~ 4, the interval ~20 wide, far wider than 4.57, and
        # the verdict says so, though the through-origin m is a definite number (within 0.3 of 4.57:
        # 2 % of ln(eta/M) = -0.91 over psi = -0.2 is 0.1 in m, 3 sd).
        rng = np.random.default_rng(22)
        psi = -0.2 + rng.normal(0, 0.002, 8)
        eta = self.M * np.exp(4.57 * psi) * (1 + rng.normal(0, 0.02, psi.size))
        r = dilatancy.fit_m_pt(psi, eta, self.M)
        self.assertEqual(r["verdict"], "not identifiable")
        self.assertIn("width", r["note"])
        self.assertAlmostEqual(r["m_origin"], 4.57, delta=0.3)
        # exactly one psi: a flat profile
        r = dilatancy.fit_m_pt(np.full(5, -0.2), eta[:5], self.M)
        self.assertEqual(r["verdict"], "not identifiable")
        self.assertIn("does not vary", r["note"])
        self.assertEqual(dilatancy.fit_m_pt(psi[:2], eta[:2], self.M)["verdict"], "not identifiable")

    def test_recovered_through_the_whole_chain(self):
        # Li & Dafalias caricatures (tests/analysis/helpers.py: d0 = 0.8, m = 5, no elastic part) at
        # psi0 = -0.2 .. +0.05 and one p: smoothing, phase transformation, fit. Dense samples turn;
        # loose ones (psi0 >= 0) contract to the end and give no state. m = 5 is recovered, the
        # interval bounded and narrower than 4.57. With every psi0 at -0.2 (6 p0): not identifiable.
        from helpers import M_TRUE, MC_TRUE, caricature

        rng = np.random.default_rng(23)

        def states(cases):
            psi, eta = [], []
            for p0, psi0 in cases:
                s = caricature(p0, 0.0, psi0=psi0, rng=rng)  # 0.3 % noise on eta
                r = dilatancy.plastic_dilatancy(s["eps_v"], s["eps_q"], s["p"], s["q"],
                                                others={"eta": s["eta"], "e": s["e"]},
                                                moduli={"K": NAN, "G": NAN})
                ec = s["e"][0] - psi0
                pt = dilatancy.phase_transformation(r["d"], r["mask"], {"eta": r["eta"], "psi": r["e"] - ec})
                if pt is not None:
                    psi.append(pt["psi"])
                    eta.append(pt["eta"])
            return np.array(psi), np.array(eta)

        psi, eta = states([(0.5e6, x) for x in (-0.2, -0.15, -0.1, -0.07, -0.04, -0.02, 0.0, 0.05)])
        self.assertGreaterEqual(psi.size, 5)
        r = dilatancy.fit_m_pt(psi, eta, MC_TRUE)
        # The smoothing's own bias (the local quadratic over +-25 % of the strain: 1.2 % on m without
        # noise) and the noise's (SE 0.016 here): bound 5 %, and the verdict an identified one.
        self.assertIn(r["verdict"], ("not the study's", "consistent with the study"), r["note"])
        self.assertAlmostEqual(r["m"], M_TRUE, delta=0.05 * M_TRUE)
        self.assertLess(r["interval"][1] - r["interval"][0], 4.57)
        psi, eta = states([(p0, -0.2) for p0 in (0.5e6, 1e6, 2e6, 4e6, 8e6, 16e6)])
        self.assertEqual(dilatancy.fit_m_pt(psi, eta, MC_TRUE)["verdict"], "not identifiable")


def test_phase_transformation_is_sought_before_the_peak_only():
    """A dense test dilates from its first plastic point (d < 0) and, past its peak, d crosses 0
    back and forth at the critical state: with end = the peak there is no phase transformation
    (without it, a noise crossing at psi ~ 0 was taken for one). A medium test that contracts, then
    dilates before its peak keeps its phase transformation, interpolated at d = 0 exactly."""
    from sandcell_analysis.dilatancy import phase_transformation
    n = 200
    eta = np.concatenate([np.linspace(0.2, 1.4, 60), np.linspace(1.4, 0.95, 140)])
    peak = 59
    d_dense = np.concatenate([np.linspace(-0.2, -0.8, 60), 0.05 * np.sin(np.arange(140))])
    mask = np.ones(n, bool)
    assert phase_transformation(d_dense, mask, {"eta": eta})["index"] > peak  # the defect, without end
    assert phase_transformation(d_dense, mask, {"eta": eta}, end=peak) is None
    d_medium = np.concatenate([np.linspace(0.3, -0.6, 60), 0.05 * np.sin(np.arange(140))])
    pt = phase_transformation(d_medium, mask, {"eta": eta}, end=peak)
    k = pt["index"]
    assert k < peak and d_medium[k] > 0 >= d_medium[k + 1]
    w = d_medium[k] / (d_medium[k] - d_medium[k + 1])
    assert abs(pt["eta"] - (eta[k] + w * (eta[k + 1] - eta[k]))) < 1e-12  # linear interpolation at d = 0
