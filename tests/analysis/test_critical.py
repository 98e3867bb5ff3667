"""The critical-state test (sandcell_analysis.critical), version 3 and the kept versions 2 and 1, on
synthetic records with known trends and noise."""
import math
import unittest

import numpy as np

from helpers import ar1
from sandcell_analysis import critical
from sandcell_analysis import m_theta


def fabric_of(a, n):
    """Axisymmetric fabric rows phi = diag(1/3 + 2a/3, 1/3 - a/3, 1/3 - a/3): F_a = 15/2 sqrt(2/3) a."""
    a = np.broadcast_to(np.asarray(a, float), (n,))
    z = np.zeros(n)
    return np.column_stack([1 / 3 + 2 * a / 3, 1 / 3 - a / 3, 1 / 3 - a / 3, z, z, z])


def _tail(rng, x, eta_noise=0.01, drift=None):
    """A record against eps_q = x: peak then softening to a stationary tail, every quantity of
    version 2 with white noise; drift = (name, change over the last 0.1 of x) adds a straight drift."""
    n = x.size
    eta = 1.2 + 0.3 * np.exp(-x / 0.03) * (1 - np.exp(-x / 0.003))
    eta = eta * (1 + rng.normal(0, eta_noise, n))
    p = 5e5 * (1 + rng.normal(0, 0.005, n))
    e = 0.75 - 0.15 * np.exp(-x / 0.04) + rng.normal(0, 5e-4, n)
    z = 4.2 + 1.5 * np.exp(-x / 0.03) + rng.normal(0, 0.01, n)
    a = 0.1 * (1 - np.exp(-x / 0.03)) * (1 + rng.normal(0, 0.005, n))
    s = {"eta": eta, "p": p, "e": e, "Z_mech": z}
    if drift is not None:
        name, change = drift
        u = (x - x[-1]) / 0.1
        if name == "F_a":
            a = a + change * 0.1 * u  # F_a ~ 0.61 at a = 0.1: relative change ~ change
        else:
            s[name] = s[name] * (1 + change * u) if name != "e" else s[name] + change * u
    s["q"] = s["eta"] * s["p"]
    s["fabric"] = fabric_of(a, n)
    s["eps_v"] = np.log((1 + e[0]) / (1 + s["e"]))
    s["b"], s["theta"] = np.zeros(n), np.zeros(n)
    return s


class FabricAnisotropy(unittest.TestCase):
    def test_identities(self):
        # isotropic: 0; axisymmetric diag(a, c, c): 15/2 sqrt(2/3) (a - c), exact to round-off
        self.assertAlmostEqual(float(critical.fabric_anisotropy([1 / 3, 1 / 3, 1 / 3, 0, 0, 0])), 0.0, places=14)
        a, c = 0.45, 0.275
        self.assertAlmostEqual(float(critical.fabric_anisotropy([a, c, c, 0, 0, 0])),
                               7.5 * math.sqrt(2 / 3) * (a - c), places=12)
        # off-diagonals count twice: the same tensor turned 45 deg about z has the same norm
        R = np.array([[math.cos(0.7854), -math.sin(0.7854), 0], [math.sin(0.7854), math.cos(0.7854), 0], [0, 0, 1]])
        T = R @ np.diag([a, 0.3, 1 - a - 0.3]) @ R.T
        rotated = [T[0, 0], T[1, 1], T[2, 2], T[0, 1], T[0, 2], T[1, 2]]
        self.assertAlmostEqual(float(critical.fabric_anisotropy(rotated)),
                               float(critical.fabric_anisotropy([a, 0.3, 1 - a - 0.3, 0, 0, 0])), places=12)


class CriticalV2(unittest.TestCase):
    x = np.linspace(0, 0.4, 801)  # eps_q; the window 0.1 holds 201 rows

    def test_stationary_tail_with_noise_is_critical(self):
        # White noise 1 % on eta: the change over the window of a line through 201 rows has a
        # standard error 0.01 x 1.2 x sqrt(12/201) / 1.2 = 0.24 %, so change + 2 SE stays near 1 %,
        # half the 2 % tolerance (the other quantities are further inside theirs).
        s = _tail(np.random.default_rng(6), self.x)
        r = critical.detect_critical(self.x, s)
        self.assertTrue(r["reached"], r["reasons"])
        self.assertIn(r["rows"], (200, 201))  # the window's edge 0.3 is a row: round-off decides
        self.assertEqual(set(r["checks"]), {"eta", "p", "e", "Z_mech", "F_a"})  # eps_v not tested
        self.assertAlmostEqual(r["point"]["eta"], 1.2, delta=0.005)  # mean of 201 rows, sd 8.5e-4
        self.assertAlmostEqual(r["point"]["e"], 0.75, delta=0.001)
        self.assertAlmostEqual(r["point"]["F_a"], 7.5 * math.sqrt(2 / 3) * 0.1, delta=0.002)

    def test_each_drifting_quantity_fails_alone(self):
        # A drift of 1.5x the tolerance in one quantity: it fails, named, and the others pass.
        for name, change in (("eta", 0.03), ("p", 0.03), ("e", 0.0075), ("Z_mech", 0.03), ("F_a", 0.075)):
            s = _tail(np.random.default_rng(7), self.x, drift=(name, change))
            r = critical.detect_critical(self.x, s)
            self.assertFalse(r["reached"], name)
            self.assertFalse(r["checks"][name]["ok"], name)
            self.assertEqual([k for k, c in r["checks"].items() if not c["ok"]], [name])
            self.assertTrue(r["reasons"][0].startswith(name))

    def test_unrecorded_quantity_fails(self):
        s = _tail(np.random.default_rng(8), self.x)
        del s["Z_mech"], s["fabric"]
        r = critical.detect_critical(self.x, s)
        self.assertFalse(r["reached"])
        self.assertIn("Z_mech: not recorded in the series", r["reasons"])
        # a tolerance of None leaves a quantity untested
        r = critical.detect_critical(self.x, s, tol_z=None, tol_fabric=None)
        self.assertTrue(r["reached"], r["reasons"])

    def test_serial_correlation_widens_the_error_by_the_ar1_factor(self):
        # The slope's error is the OLS error times sqrt((1 + r1)/(1 - r1)), r1 the residuals' lag-1
        # autocorrelation: an identity, checked to round-off; r1 of AR(1) noise with phi = 0.8 over
        # 201 rows is phi within its sampling error (sd ~ sqrt((1 - phi^2)/n) = 0.04; 3 sd).
        rng = np.random.default_rng(9)
        x = self.x[-201:]
        y = 1.0 + ar1(rng, x.size, 0.8, 0.01)
        slope, se, r1, n = critical.trend(x, y, 0.1)
        xc = x - x.mean()
        resid = (y - y.mean()) - slope * xc
        plain = math.sqrt(float(resid @ resid) / (n - 2) / float(xc @ xc))
        self.assertAlmostEqual(se, plain * math.sqrt((1 + r1) / (1 - r1)), delta=1e-12 * se)
        self.assertAlmostEqual(r1, 0.8, delta=0.12)
        # white noise: r1 clipped at 0 from below, the factor >= 1
        slope, se2, r1w, n = critical.trend(x, 1.0 + rng.normal(0, 0.01, x.size), 0.1)
        self.assertGreaterEqual(r1w, 0.0)
        self.assertLessEqual(r1w, 0.99)

    def test_first_passage_by_noise_is_refused(self):
        # eta drifts by 1.5 % over the window (inside the 2 % tolerance) under AR(1) noise (phi 0.95,
        # sd 2 %): the change alone (version 1's test) passes, but its error (~1 %: AR(1) cuts the
        # 201 rows to ~5 effective ones) puts change + 2 SE beyond 2 %: neither version 2 nor 3
        # (6 SE there) accepts it.
        rng = np.random.default_rng(10)
        s = _tail(rng, self.x)
        u = (self.x - self.x[-1]) / 0.1
        s["eta"] = 1.2 * (1 + 0.015 * u + ar1(rng, self.x.size, 0.95, 0.02))
        s["q"] = s["eta"] * s["p"]
        c = critical.detect_critical(self.x, s)["checks"]["eta"]
        self.assertGreater(c["bound"], 0.02)
        self.assertGreater(c["r1"], 0.8)
        self.assertTrue(c["ok"] is False)

    def test_window_is_in_eps_q(self):
        # Rows every 0.001 of eps_q to 0.35: the window [0.25, 0.35] holds 101 rows whatever eps_1
        x = np.linspace(0, 0.35, 351)
        r = critical.detect_critical(x, _tail(np.random.default_rng(11), x))
        self.assertEqual(r["rows"], 101)
        self.assertAlmostEqual(r["window"][0], 0.25, places=12)
        self.assertEqual(r["variable"], "eps_q")

    def test_short_test_is_not_critical(self):
        x = np.linspace(0, 0.28, 561)  # < window + pre-strain = 0.3
        r = critical.detect_critical(x, _tail(np.random.default_rng(12), x))
        self.assertFalse(r["reached"])
        self.assertIn("window + pre-strain", r["reasons"][0])

    def test_b_and_theta_are_those_of_the_mean_stress_not_the_mean_of_sorted_rows(self):
        # Lateral stresses fluctuating +-3 % independently about a state of exact b (0, 0.5, 1):
        # the rows' b, from sorted principal stresses, is biased away from 0 and 1 (s2 - s3 or
        # s1 - s2 counted positive whatever its sign), while the window-mean tensor's b is the
        # state's to the noise of a mean of 201 rows (sd ~ 0.03 x sigma / (s1 - s3) / 14 < 0.005).
        rng = np.random.default_rng(13)
        n = self.x.size
        for b in (0.0, 0.5, 1.0):
            s = _tail(rng, self.x)
            p = s["p"]
            s1, s3 = 1.6 * p, 0.7 * p
            s2 = s3 + b * (s1 - s3)
            stress = np.column_stack([s1 * (1 + rng.normal(0, 0.03, n)), s2 * (1 + rng.normal(0, 0.03, n)),
                                      s3 * (1 + rng.normal(0, 0.03, n)), np.zeros(n), np.zeros(n), np.zeros(n)])
            ps = np.sort(stress[:, :3], axis=1)[:, ::-1]
            s["b"] = (ps[:, 1] - ps[:, 2]) / (ps[:, 0] - ps[:, 2])
            s["theta"] = m_theta.lode_from_b(s["b"])
            s["stress"] = stress
            pt = critical.detect_critical(self.x, s)["point"]
            self.assertAlmostEqual(pt["b"], b, delta=0.01)
            self.assertAlmostEqual(pt["theta"], float(m_theta.lode_from_b(b)), delta=math.radians(0.6))
            if b in (0.0, 1.0):
                self.assertGreater(abs(pt["b_rows"] - b), 0.02)


class FirstPassage(unittest.TestCase):
    def test_version_1_stops_earlier_than_version_3_on_a_settling_test(self):
        # eta settles exponentially (scale 0.05 of strain) under AR(1) noise: version 1 (change
        # alone over 5 % of eps_1, from 10 %) passes on the first window whose line happens to be
        # flat; version 3 (change + 2 SE over 0.1 of eps_q, from 0.3; 6 SE in a window of < 10
        # effective rows) needs the tail. eps_1 = eps_q
        # here (a b = 0 test at constant volume, for the sake of one axis).
        rng = np.random.default_rng(14)
        x = np.linspace(0, 0.6, 1201)
        s = _tail(rng, x)
        s["eta"] = 1.2 * (1 + 0.3 * np.exp(-x / 0.05) + ar1(rng, x.size, 0.9, 0.01))
        s["q"] = s["eta"] * s["p"]
        n1 = critical.first_critical_row(x, s, criterion="v1")
        n2 = critical.first_critical_row(x, s)
        self.assertIsNotNone(n1)
        self.assertIsNotNone(n2)
        self.assertGreaterEqual(x[n2 - 1], 0.3)  # never before window + pre-strain
        self.assertLess(n1, n2)
        # the prefix version 3 stops at is critical, the row before is not
        self.assertTrue(critical.detect_critical(x[:n2], {k: v[:n2] for k, v in s.items()})["reached"])
        self.assertFalse(critical.detect_critical(x[:n2 - 1], {k: v[:n2 - 1] for k, v in s.items()})["reached"])

    def test_app_criterion_is_version_3(self):
        self.assertEqual(critical.APP_CRITERION, critical.V3_DEFAULTS)
        self.assertEqual((critical.APP_CRITERION["window"], critical.APP_CRITERION["pre_strain"]), (0.1, 0.2))
        self.assertEqual((critical.APP_CRITERION["neff_min"], critical.APP_CRITERION["k_short"]), (10.0, 6.0))
        self.assertEqual(dict(critical.V2_DEFAULTS, k_short=6.0), critical.V3_DEFAULTS)
        with self.assertRaises(ValueError):
            critical.first_critical_row(np.zeros(3), {}, criterion="v4")


class FalsePositives(unittest.TestCase):
    """The rule as a detector of stationarity, on series known to drift beyond the tolerance
    (experiments/2026-11-29-rule-check maps the whole grid; these are its worst cells)."""

    @staticmethod
    def accepted(phi, drift, tau, reps, criterion, rows=100, seed=45):
        """Share of `reps` eta series accepted: eta drifts by `drift` tolerances over the window in
        AR(1) noise of lag-1 coefficient phi, scaled so the least-squares change has a standard
        deviation of `tau` tolerances (measured on drift-free replicates); every other quantity
        steady and noiseless, so eta alone decides."""
        rng = np.random.default_rng(seed)
        tol = critical.V3_DEFAULTS["tol_eta"]
        x = np.linspace(0.3, 0.4, rows)
        xc = x - x.mean()

        def noise():
            return np.array([ar1(rng, rows, phi, 1.0) for _ in range(reps)])

        unit = np.std(noise() @ xc / float(xc @ xc) * 0.1)
        ok = 0
        for y in noise() * (tau * tol / unit):
            eta = 1.2 * (1.0 + drift * tol * (x - x[-1]) / 0.1 + y)
            s = {"p": np.full(rows, 5e5), "q": 5e5 * eta, "eta": eta, "e": np.full(rows, 0.75),
                 "Z_mech": np.full(rows, 4.2), "F_a": np.full(rows, 0.3)}
            ok += critical.detect_critical(x, s, **criterion)["reached"]
        return ok / reps

    def test_drift_of_one_and_a_half_tolerances_is_refused(self):
        # Series known to be negative: eta drifts by 1.5 tolerances over the window. The criterion
        # (rule_check's, the band detector's bound): at most 5 % accepted. The cell is the grid's
        # worst (phi 0.998, ~6 effective rows of 100, tau one tolerance): version 3 accepted 2.1 %
        # of 4,000 there, version 2 8.4 %. 1,000 replicates: the binomial SD of 2-8 % is 0.4-0.9 %,
        # so 5 % separates the two by > 3 SD each side.
        v3 = self.accepted(0.998, 1.5, 1.0, 1000, critical.V3_DEFAULTS)
        v2 = self.accepted(0.998, 1.5, 1.0, 1000, critical.V2_DEFAULTS)
        self.assertLessEqual(v3, 0.05)
        self.assertGreater(v2, 0.05)  # the defect version 3 mends: version 2's SE is short there

    def test_steady_series_with_small_fluctuation_still_pass(self):
        # Not a rule that refuses everything: eta steady (no drift), its change's SD a quarter of the
        # tolerance, in a window of ~19 effective rows (phi 0.9, 300 rows): 95 % accepted in the grid
        # (4,000 replicates); here >= 85 % of 400 (binomial SD 1.1 %: 9 SD of room).
        self.assertGreaterEqual(self.accepted(0.9, 0.0, 0.25, 400, critical.V3_DEFAULTS, rows=300), 0.85)
