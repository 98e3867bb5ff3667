"""Helpers shared by the analysis tests: bounds on fitted values, and synthetic results files."""
import os
import sys

import h5py
import numpy as np

from sandcell_analysis import csl, m_theta

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))
ANALYSIS = os.path.join(ROOT, "apps", "analysis")  # the package sandcell_analysis


def command(name):
    """The argv of an analysis command (what `triaxial NAME` runs): python -m sandcell_analysis NAME."""
    return [sys.executable, "-m", "sandcell_analysis", name]


def ar1(rng, n, phi, sd):
    """AR(1) noise of lag-1 correlation phi and stationary standard deviation sd."""
    z = rng.normal(0.0, sd * np.sqrt(1 - phi ** 2), n)
    out = np.empty(n)
    out[0] = rng.normal(0.0, sd)
    for k in range(1, n):
        out[k] = phi * out[k - 1] + z[k]
    return out


def within(tc, value, truth, se, n_se, abs_bound, what):
    """value must be within n_se reported standard errors AND within abs_bound of the truth.

    The first bound checks the fit against its own stated precision (with Gaussian noise a
    4-sigma miss has probability < 1e-4, and the seeds are fixed); the second keeps a fit whose
    standard error blew up from passing."""
    err = abs(value - truth)
    tc.assertTrue(np.isfinite(se) and se > 0, f"{what}: standard error {se}")
    tc.assertLessEqual(err, n_se * se, f"{what} = {value} vs {truth}: more than {n_se} SE ({se})")
    tc.assertLessEqual(err, abs_bound, f"{what} = {value} vs {truth}: more than {abs_bound}")


CSL_TRUE = (0.9, 0.02, 0.7)  # e_Gamma, lambda, xi of the caricature
MC_TRUE, K_TRUE = 1.2, 0.8
D0_TRUE, M_TRUE = 0.8, 5.0


def caricature(p0, b, psi0=-0.05, eps_end=0.4, rows=801, rng=None):
    """A constant-p test from a simple constitutive caricature.

    The stress ratio hardens to a bounding ratio M(theta) exp(-2 psi) (a peak while dense), the
    dilatancy is Li's 3D form with d0 = 0.8, m = 5, and e follows eps_v; psi decays to ~-0.001
    by the end, so the test ends at the critical state on the CSL above."""
    theta = float(m_theta.lode_from_b(b))
    M = MC_TRUE * float(m_theta.g_theta(theta, K_TRUE))
    ec = float(csl.csl_e(p0, *CSL_TRUE))
    e0 = ec + psi0
    nsub = 10
    de1 = eps_end / ((rows - 1) * nsub)
    eq = ev = 0.0
    e = e0
    rec = np.zeros((rows, 4))
    for k in range(rows):
        psi = e - ec
        eta = M * np.exp(-2 * psi) * (1 - np.exp(-eq / 0.01))
        rec[k] = (eq, ev, e, eta)
        for _ in range(nsub):
            psi = e - ec
            eta = M * np.exp(-2 * psi) * (1 - np.exp(-eq / 0.01))
            d = D0_TRUE / MC_TRUE * (M * np.exp(M_TRUE * psi) - eta)
            deq = de1 / (d / 3 + np.cos(theta))
            eq += deq
            ev += d * deq
            e = (1 + e0) * np.exp(-ev) - 1
    eq, ev, e, eta = rec.T
    eta = eta * (1 + (rng.normal(0, 0.003, rows) if rng is not None else 0))
    dirs = np.cos(theta - 2 * np.pi / 3 * np.arange(3))
    strain = ev[:, None] / 3 + eq[:, None] * dirs[None, :]
    p = np.full(rows, p0)
    q = eta * p
    sig = p[:, None] + 2.0 / 3.0 * q[:, None] * dirs[None, :]
    # Coordination and fabric settle with the same strain scale as the stress ratio (stationary at
    # the end, as version 2 of the critical-state test asks): Z_mech from 6 to 4.2, the fabric's
    # deviator along the stress's principal directions (a = 0.06 at the end).
    z = 4.2 + 1.8 * np.exp(-eq / 0.01)
    a = 0.06 * (1 - np.exp(-eq / 0.01))
    fabric = np.hstack([1.0 / 3.0 + a[:, None] * 2.0 / 3.0 * dirs[None, :], np.zeros((rows, 3))])
    return {"strain": strain, "p": p, "q": q, "eta": eta, "e": e, "eps_v": ev, "eps_q": eq,
            "theta": np.full(rows, theta), "b": np.full(rows, b), "principal_stress": sig,
            "stress": np.hstack([sig, np.zeros((rows, 3))]), "Z_mech": z, "fabric": fabric}


def write_results(path, series, attrs):
    with h5py.File(path, "w") as f:
        for k, v in attrs.items():
            f.attrs[k] = v
        g = f.create_group("series")
        for k, v in series.items():
            g.create_dataset(k, data=v)
