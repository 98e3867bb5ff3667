"""The CSL fit (sandcell_analysis.csl) on synthetic critical points with known parameters."""
import unittest

import numpy as np

from helpers import within
from sandcell_analysis import csl


class CSLFit(unittest.TestCase):
    def test_recovers_parameters_from_noisy_points(self):
        # e_Gamma = 0.9, lambda = 0.02, xi = 0.7 over 0.5-16 MPa: e_c spans ~0.4, so all three
        # parameters are measurable; noise 0.003 is a typical DEM scatter of e_c between samples.
        rng = np.random.default_rng(1)
        truth = (0.9, 0.02, 0.7)
        p = np.repeat(np.geomspace(0.5e6, 16e6, 6), 5)
        b = np.tile([0.0, 0.25, 0.5, 0.75, 1.0], 6)
        e = csl.csl_e(p, *truth) + rng.normal(0, 0.003, p.size)
        r = csl.fit_csl(p, e, b=b)
        self.assertTrue(r["fitted"])
        self.assertEqual(r["mode"], "full")
        # Absolute bounds ~5 x the standard errors this design gives (about 0.002, 0.0006,
        # 0.005): loose enough never to fail on a correct fit, tight enough to catch a wrong
        # model or a fit stuck at its start.
        within(self, r["params"]["e_gamma"], truth[0], r["stderr"]["e_gamma"], 4, 0.01, "e_Gamma")
        within(self, r["params"]["lambda"], truth[1], r["stderr"]["lambda"], 4, 0.003, "lambda")
        within(self, r["params"]["xi"], truth[2], r["stderr"]["xi"], 4, 0.03, "xi")
        self.assertGreater(r["R"], 0.99)  # noise 0.003 against a 0.4 range of e_c
        # The RMS residual estimates the noise 0.003 (27 degrees of freedom: sampling sd ~14 %,
        # i.e. 0.0004): within 0.001.
        self.assertAlmostEqual(r["rms"], 0.003, delta=0.001)
        self.assertEqual([g["b"] for g in r["per_b"]], [0.0, 0.25, 0.5, 0.75, 1.0])
        for g in r["per_b"]:
            # a mean of 6 residuals of sd 0.003: |mean| < 4 x 0.003/sqrt(6) = 0.005
            self.assertLess(abs(g["mean"]), 0.005)

    def test_recovers_the_study_values_without_noise(self):
        # lambda = 0.0002 with xi ~ 1 moves e_c by only ~0.03 over 0.5-16 MPa: only noise-free
        # data pin the three numbers; the optimum is then exact up to the solver tolerance, so
        # the values must come back to 1e-4 relative.
        p = np.geomspace(0.5e6, 16e6, 6)
        e = csl.csl_e(p, 0.699, 0.0002, 0.971)
        r = csl.fit_csl(p, e)
        self.assertTrue(r["fitted"])
        self.assertAlmostEqual(r["params"]["e_gamma"], 0.699, delta=0.699e-4)
        self.assertAlmostEqual(r["params"]["lambda"], 0.0002, delta=0.0002e-4)
        self.assertAlmostEqual(r["params"]["xi"], 0.971, delta=0.971e-4)
        self.assertAlmostEqual(r["r2"], 1.0, places=8)

    def test_two_pressures_fix_xi_one_pressure_not_fitted(self):
        p = np.array([0.5e6, 0.5e6, 2e6, 2e6])
        e = csl.csl_e(p, 0.8, 0.01, 1.0)
        r = csl.fit_csl(p, e)
        self.assertTrue(r["fitted"])
        self.assertEqual(r["mode"], "xi = 1 fallback")
        self.assertIn("fallback", r["note"])
        self.assertEqual(r["params"]["xi"], 1.0)
        self.assertAlmostEqual(r["params"]["e_gamma"], 0.8, places=10)  # exact: xi is the true one
        self.assertAlmostEqual(r["params"]["lambda"], 0.01, places=10)
        r = csl.fit_csl([0.5e6, 0.51e6], [0.7, 0.71])  # 2 % apart: one pressure level
        self.assertFalse(r["fitted"])
        self.assertIn("not fitted", r["note"])
        r = csl.fit_csl([], [])
        self.assertFalse(r["fitted"])
