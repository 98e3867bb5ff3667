"""The critical-state test (sandcell_analysis.critical) on synthetic stress-strain records."""
import math
import unittest

import numpy as np

from sandcell_analysis import critical
from sandcell_analysis import m_theta


def _tail(rng, eps1, rising_eta=False, drifting_e=False):
    """A stress-strain record: peak then softening to a stationary tail (noise like DEM)."""
    n = eps1.size
    eta = 1.2 + 0.3 * np.exp(-eps1 / 0.03) * (1 - np.exp(-eps1 / 0.003))
    if rising_eta:
        eta = 1.0 + 2.0 * eps1  # still rising: +0.1 (5.6 %) over the last 5 %
    eta = eta * (1 + rng.normal(0, 0.02, n))
    p = 5e5 * (1 + rng.normal(0, 0.005, n))
    e = 0.75 - 0.15 * np.exp(-eps1 / 0.04) + rng.normal(0, 5e-4, n)
    if drifting_e:
        e = 0.6 + 0.2 * eps1 + rng.normal(0, 5e-4, n)  # +0.01 over the last 5 %
    eps_v = np.log((1 + e[0]) / (1 + e))
    return {"eta": eta, "p": p, "q": eta * p, "e": e, "eps_v": eps_v,
            "b": np.zeros(n), "theta": np.zeros(n)}


class CriticalDetection(unittest.TestCase):
    eps1 = np.linspace(0, 0.4, 801)

    def test_stationary_tail_with_noise_is_critical(self):
        # Noise 2 % on eta, 0.5 % on p, 5e-4 on e: the slope of a line through 101 rows has a
        # standard error ~10x below the tolerances, so the tail is detected whatever the seed.
        s = _tail(np.random.default_rng(6), self.eps1)
        r = critical.detect_critical(self.eps1, s)
        self.assertTrue(r["reached"], r["reasons"])
        self.assertAlmostEqual(r["point"]["eta"], 1.2, delta=0.01)  # mean of 101 rows, sd 2.4e-2
        self.assertAlmostEqual(r["point"]["M"], 1.2, delta=0.01)
        self.assertAlmostEqual(r["point"]["e"], 0.75, delta=0.001)
        self.assertEqual(r["rows"], 101)

    def test_rising_eta_is_not_critical(self):
        s = _tail(np.random.default_rng(7), self.eps1, rising_eta=True)
        r = critical.detect_critical(self.eps1, s)
        self.assertFalse(r["reached"])
        self.assertFalse(r["checks"]["eta"]["ok"])
        self.assertTrue(any(x.startswith("eta") for x in r["reasons"]))

    def test_drifting_void_ratio_is_not_critical(self):
        s = _tail(np.random.default_rng(8), self.eps1, drifting_e=True)
        r = critical.detect_critical(self.eps1, s)
        self.assertFalse(r["reached"])
        self.assertFalse(r["checks"]["e"]["ok"])
        self.assertTrue(r["checks"]["eta"]["ok"])

    def test_b_and_theta_are_those_of_the_mean_stress_not_the_mean_of_sorted_rows(self):
        # Lateral stresses fluctuating +-3 % independently about a state of exact b (0, 0.5, 1):
        # the rows' b, from sorted principal stresses, is biased away from 0 and 1 (s2 - s3 or
        # s1 - s2 counted positive whatever its sign), while the window-mean tensor's b is the
        # state's to the noise of a mean of 101 rows (sd ~ 0.03 x sigma / (s1 - s3) / 10 < 0.005).
        rng = np.random.default_rng(11)
        n = self.eps1.size
        for b in (0.0, 0.5, 1.0):
            s = _tail(rng, self.eps1)
            p = s["p"]
            s1, s3 = 1.6 * p, 0.7 * p  # q/p = 0.9 at b = 0: shear stresses zero, axes principal
            s2 = s3 + b * (s1 - s3)
            lat2 = s2 * (1 + rng.normal(0, 0.03, n))
            lat3 = s3 * (1 + rng.normal(0, 0.03, n))
            ax = s1 * (1 + rng.normal(0, 0.03, n))
            stress = np.column_stack([ax, lat2, lat3, np.zeros(n), np.zeros(n), np.zeros(n)])
            ps = np.sort(stress[:, :3], axis=1)[:, ::-1]
            s["b"] = (ps[:, 1] - ps[:, 2]) / (ps[:, 0] - ps[:, 2])
            s["theta"] = m_theta.lode_from_b(s["b"])
            s["stress"] = stress
            pt = critical.detect_critical(self.eps1, s)["point"]
            self.assertAlmostEqual(pt["b"], b, delta=0.01)
            self.assertAlmostEqual(pt["theta"], float(m_theta.lode_from_b(b)), delta=math.radians(0.6))
            if b in (0.0, 1.0):  # the rows' mean is off by more than the tolerance above
                self.assertGreater(abs(pt["b_rows"] - b), 0.02)
        # Without a stress tensor, the rows' mean is all there is.
        s = _tail(np.random.default_rng(12), self.eps1)
        pt = critical.detect_critical(self.eps1, s)["point"]
        self.assertEqual(pt["b"], 0.0)
        self.assertNotIn("b_rows", pt)

    def test_short_test_is_not_critical(self):
        eps1 = np.linspace(0, 0.08, 161)
        r = critical.detect_critical(eps1, _tail(np.random.default_rng(9), eps1))
        self.assertFalse(r["reached"])
        self.assertIn("window + pre-strain", r["reasons"][0])
