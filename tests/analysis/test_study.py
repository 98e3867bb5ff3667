"""The speed-accuracy study's own computations (sandcell_analysis.study), against analytic results;
the study end to end (`triaxial study`) is analysis.study_command (check_study.py)."""
import math
import tomllib

import numpy as np

from sandcell_analysis import study
from sandcell_analysis.dilatancy import slope_max_dilation


def test_d50_is_the_median_by_mass():
    # Uniform by number on [d_min, d_max]: the mass below d is the integral of x^3, so half the
    # mass lies below d50 (midpoint rule on 200,000 intervals: error ~1e-10).
    d_min, d_max = 5e-3, 7.5e-3
    d50 = study.d50_of({"d_min": d_min, "d_max": d_max})
    x = np.linspace(d_min, d_max, 200001)
    mid = 0.5 * (x[1:] + x[:-1])
    mass = mid ** 3
    assert abs(mass[mid < d50].sum() / mass.sum() - 0.5) < 1e-5  # one interval's share: 1/200000
    # A gradation: linear between its points; one of one size: that size.
    assert study.d50_of({"distribution": "gradation", "gradation": [[1e-3, 0.0], [3e-3, 100.0]]}) == 2e-3
    assert study.d50_of({"distribution": "mono", "d_min": 4e-3, "d_max": 4e-3}) == 4e-3


def test_max_dilation_of_straight_strains_is_their_ratio():
    # eps_v = -0.4 eps_1, eps_q = 0.9 eps_1: every window's least-squares slopes are exact, so the
    # largest -d eps_v / d eps_q is 0.4 / 0.9 to round-off (1e-12).
    eps1 = np.linspace(0.0, 0.1, 1001)
    assert abs(slope_max_dilation(eps1, -0.4 * eps1, 0.9 * eps1) - 0.4 / 0.9) < 1e-12
    # Dilation stopping at 5 %: the largest rate is the early one.
    eps_v = np.where(eps1 < 0.05, -0.4 * eps1, -0.02)
    assert abs(slope_max_dilation(eps1, eps_v, 0.9 * eps1) - 0.4 / 0.9) < 1e-12
    # eps_q not growing (d eps_q / d eps_1 < 0.1): no rate is measured.
    assert math.isnan(slope_max_dilation(eps1, -0.4 * eps1, 0.05 * eps1))


def test_pareto_front_and_mean_std():
    # (cost, error): (3, 1) is dominated by (2, 0.5); the front runs cheapest first.
    assert study.pareto([(1, 2.0), (3, 1.0), (2, 0.5), (4, 0.1)]) == [0, 2, 3]
    mean, std = study.mean_std([1.0, 2.0, 3.0, float("nan")])
    assert mean == 2.0 and std == 1.0  # NaN left out; sample standard deviation
    assert math.isnan(study.mean_std([5.0])[1])


def test_toml_dump_reads_back():
    cfg = {"sample": {"count": 300, "d_min": 5e-3, "seed": 7}, "tests": {"path": "constant_p", "b": [0.0, 0.5]},
           "output": {"plot": False}}
    assert tomllib.loads(study.toml_dump(cfg)) == cfg


def test_time_step_is_the_rayleigh_fraction():
    # dt_R = pi r / (0.1631 nu + 0.8766) sqrt(rho / G), r the smallest radius, G = E / (2 (1 + nu)).
    cfg = {"sample": {"d_min": 4e-3}, "material": {"young": 1e9, "poisson": 0.25, "density": 2000.0},
           "time": {"dt_fraction": 0.2}}
    G = 1e9 / 2.5
    rayleigh = math.pi * 2e-3 * math.sqrt(2000.0 / G) / (0.1631 * 0.25 + 0.8766)
    assert math.isclose(study.time_step(cfg), 0.2 * rayleigh, rel_tol=1e-14)
