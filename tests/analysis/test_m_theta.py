"""M(theta) (sandcell_analysis.m_theta): the fit of M_c and K, friction angles, Lode angles."""
import unittest

import numpy as np

from helpers import within
from sandcell_analysis import m_theta


class MTheta(unittest.TestCase):
    def test_recovers_Mc_and_K(self):
        # M_c = 1.25, K = 0.8 at the Lode angles of b = 0..1, 3 samples each; noise 0.01 on q/p
        # (about 1 % of M: the scatter of critical ratios of DEM samples of a few thousand
        # spheres). Absolute bounds 0.02 are ~5 standard errors (0.004) of this design.
        rng = np.random.default_rng(2)
        b = np.repeat(np.linspace(0, 1, 6), 3)
        theta = m_theta.lode_from_b(b)
        M = m_theta.m_theta(theta, 1.25, 0.8) + rng.normal(0, 0.01, b.size)
        r = m_theta.fit_m_theta(theta, M)
        self.assertTrue(r["fitted"])
        within(self, r["params"]["M_c"], 1.25, r["stderr"]["M_c"], 4, 0.02, "M_c")
        within(self, r["params"]["K"], 0.8, r["stderr"]["K"], 4, 0.02, "K")
        self.assertTrue(r["convex"])
        phic, phie = m_theta.friction_angles(r["params"]["M_c"], r["params"]["M_e"])
        self.assertAlmostEqual(r["phi_c_deg"], phic)
        self.assertAlmostEqual(r["phi_e_deg"], phie)
        self.assertTrue(np.isfinite(r["se_phi_c_deg"]) and r["se_phi_c_deg"] > 0)

    def test_compression_only_gives_Mc_without_K(self):
        theta = np.zeros(4)
        r = m_theta.fit_m_theta(theta, [1.2, 1.22, 1.18, 1.2])
        self.assertFalse(r["fitted"])
        self.assertIn("K not fitted", r["note"])
        self.assertAlmostEqual(r["params"]["M_c"], 1.2, places=12)

    def test_formulas(self):
        self.assertAlmostEqual(float(m_theta.g_theta(0.0, 0.7)), 1.0)
        self.assertAlmostEqual(float(m_theta.g_theta(np.pi / 3, 0.7)), 0.7)
        self.assertAlmostEqual(float(m_theta.lode_from_b(1.0)), np.pi / 3)
        # Mohr-Coulomb: M_c = 6 sin(phi)/(3 - sin(phi)), M_e = 6 sin(phi)/(3 + sin(phi)), and the
        # friction-angle formulas must invert these exactly.
        phi = np.radians(22.0)
        mc = float(m_theta.mohr_coulomb_M(0.0, phi))
        me = float(m_theta.mohr_coulomb_M(np.pi / 3, phi))
        s = np.sin(phi)
        self.assertAlmostEqual(mc, 6 * s / (3 - s), places=12)
        self.assertAlmostEqual(me, 6 * s / (3 + s), places=12)
        phic, phie = m_theta.friction_angles(mc, me)
        self.assertAlmostEqual(phic, 22.0, places=10)
        self.assertAlmostEqual(phie, 22.0, places=10)


class Surfaces(unittest.TestCase):
    """Matsuoka-Nakai, Lade-Duncan and Mohr-Coulomb beside g(theta), by AIC (issue 45)."""

    def test_matsuoka_nakai_has_equal_friction_angles(self):
        # An identity of the Matsuoka-Nakai cone: its friction angle is the same in compression and
        # extension; Lade-Duncan's is larger in extension (the bisection converges to 1e-12).
        import math
        for phi in (22.0, 30.0, 40.0):
            s = math.sin(math.radians(phi))
            Mc = 6 * s / (3 - s)
            Me = float(m_theta.surface_M("matsuoka_nakai", [math.pi / 3], Mc)[0])
            self.assertAlmostEqual(m_theta.friction_angles(math.nan, Me)[1], phi, places=8)
            Me_ld = float(m_theta.surface_M("lade_duncan", [math.pi / 3], Mc)[0])
            self.assertGreater(m_theta.friction_angles(math.nan, Me_ld)[1], phi)
            # at theta = 0 both give M_c back
            self.assertAlmostEqual(float(m_theta.surface_M("lade_duncan", [0.0], Mc)[0]), Mc, places=9)

    def test_aic_picks_the_generating_surface(self):
        # 3 points at each of 5 Lode angles from a Matsuoka-Nakai (then a Lade-Duncan) cone of
        # phi_c = 24 deg, noise 0.005 on q/p (half the DEM scatter): the generating surface has the
        # smallest AICc (seeded).
        import math
        rng = np.random.default_rng(31)
        theta = np.repeat(m_theta.lode_from_b(np.array([0.0, 0.25, 0.5, 0.75, 1.0])), 3)
        s = math.sin(math.radians(24.0))
        Mc = 6 * s / (3 - s)
        for kind in ("matsuoka_nakai", "lade_duncan"):
            M = m_theta.surface_M(kind, theta, Mc) + rng.normal(0, 0.005, theta.size)
            r = m_theta.compare_surfaces(theta, M)
            self.assertEqual(r["n"], 15)
            self.assertEqual(set(r["forms"]), {"g(theta)", "matsuoka_nakai", "lade_duncan", "mohr_coulomb"})
            self.assertEqual(r["best"], kind)
            self.assertAlmostEqual(r["forms"][kind]["params"]["M_c"], Mc, delta=0.005)  # ~4 SE of 15 points

    def test_direct_friction_angles(self):
        # The mean q/p of the b = 0 and b = 1 points, no surface assumed: exact means here.
        import math
        theta = np.array([0.0, 0.0, math.pi / 3, math.pi / 3, 0.5])
        M = np.array([0.95, 0.97, 0.74, 0.72, 0.8])
        r = m_theta.direct_friction_angles(theta, M)
        self.assertEqual((r["n_c"], r["n_e"]), (2, 2))
        self.assertAlmostEqual(r["M_c"], 0.96, places=12)
        self.assertAlmostEqual(r["M_e"], 0.73, places=12)
        self.assertAlmostEqual(r["phi_c_deg"], m_theta.friction_angles(0.96, 0.73)[0], places=12)
        self.assertAlmostEqual(r["phi_e_deg"], m_theta.friction_angles(0.96, 0.73)[1], places=12)
