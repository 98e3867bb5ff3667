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
