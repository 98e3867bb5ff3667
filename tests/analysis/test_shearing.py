"""The shearing paths' measures (sandcell_analysis/shearing.py) on series with closed-form answers:
an isotropic linear elastic solid under a pure rotation of the principal stresses (its strain
increment is coaxial with the stress increment, 45 deg ahead of the stress: non-coaxiality -45 deg),
proportional loading at a fixed angle (coaxial: 0, the false-positive check), and simple shear."""
import math

import numpy as np
import pytest

from sandcell_analysis import shearing


def rotated(p, b, q, alpha):
    """R(alpha) diag(s1, s2, s3) R^T in the xz plane, y intermediate (systems/stress_paths.cpp)."""
    d = q / math.sqrt(1 - b + b * b)
    s3 = p - d * (1 + b) / 3
    s1, s2 = s3 + d, s3 + b * d
    c, s = math.cos(alpha), math.sin(alpha)
    return np.array([[s1 * c * c + s3 * s * s, 0, (s1 - s3) * c * s], [0, s2, 0],
                     [(s1 - s3) * c * s, 0, s1 * s * s + s3 * c * c]])


def elastic_series(stresses, shear_modulus=1e8, bulk=2e8):
    """Series of an isotropic linear elastic solid driven through `stresses` (compression positive):
    d_eps = dev(dS) / 2G + tr(dS) / 9K, accumulated as F = exp(-eps) to first order per increment
    (F_next = (I - d_eps) F, symmetric: no spin)."""
    n = len(stresses)
    F = np.zeros((n, 3, 3))
    F[0] = np.eye(3)
    for k in range(1, n):
        ds = stresses[k] - stresses[k - 1]
        tr = np.trace(ds)
        de = (ds - tr / 3 * np.eye(3)) / (2 * shear_modulus) + tr / (9 * bulk) * np.eye(3)
        F[k] = (np.eye(3) - de) @ F[k - 1]
    s6 = np.array([[t[0, 0], t[1, 1], t[2, 2], t[0, 1], t[0, 2], t[1, 2]] for t in stresses])
    return {"time": np.arange(n, dtype=float), "stress": s6, "F": F, "eps_v": np.zeros(n), "e": np.zeros(n)}


def test_pure_rotation_of_an_elastic_solid_is_45_degrees_non_coaxial():
    alphas = np.radians(np.linspace(0.0, 180.0, 721))
    d = elastic_series([rotated(1e5, 0.5, 3e4, a) for a in alphas])
    m = shearing.rotation_measures(d)
    # Each increment of a pure rotation is dS = dalpha dS/dalpha, whose major direction is alpha + 45
    # deg; the elastic strain increment is coaxial with dS. The only error is the finite step
    # (0.25 deg: the chord's direction is the tangent's at the mid-angle, exact for a circle) and the
    # first-order F update: 1e-6 deg is far below both the physics and a 1 deg mistake.
    assert np.all(np.isfinite(m["noncoaxiality"]))
    assert np.max(np.abs(m["noncoaxiality"] + 45.0)) < 1e-6
    # The stress's own angle follows alpha (folded into (-90, 90]).
    mid = np.degrees(0.5 * (alphas[1:] + alphas[:-1]))
    assert np.max(np.abs(shearing.fold(m["alpha"] - mid))) < 1e-9


def test_proportional_loading_is_coaxial():
    # A fixed angle (30 deg), q growing: dS has the stress's own axes; non-coaxiality 0 to round-off:
    # increments of 1e-5 taken from products of F near I (1e-16 each) carry ~1e-11 relative error,
    # ~1e-9 deg in the angle (measured 1.4e-9); 1e-7 deg is far below any physical non-coaxiality.
    d = elastic_series([rotated(1e5, 0.3, q, math.radians(30.0)) for q in np.linspace(1e4, 8e4, 50)])
    m = shearing.rotation_measures(d)
    assert np.max(np.abs(m["noncoaxiality"])) < 1e-7
    assert np.max(np.abs(m["alpha"] - 30.0)) < 1e-9


def test_no_strain_increment_is_no_angle():
    d = elastic_series([rotated(1e5, 0.3, 3e4, 0.0)] * 5)
    assert np.all(np.isnan(shearing.rotation_measures(d)["noncoaxiality"]))


def test_simple_shear_measures():
    g = np.linspace(0.0, 2.0, 11)
    F = np.array([[[1, 0, -x], [0, 1, 0], [0, 0, 1]] for x in g], float)  # gamma = -F_xz (soil convention)
    s6 = np.tile([1e5, 1e5, 1e5, 0.0, 4e4, 0.0], (11, 1))
    m = shearing.simple_shear_measures({"stress": s6, "F": F, "eps_v": np.zeros(11), "e": np.zeros(11)})
    assert np.array_equal(m["gamma"], g)
    assert m["ratio"] == pytest.approx(np.full(11, 0.4), rel=1e-15)
    # Simple shear's strain increment: -sym(dF F^-1) = (dg/2)(e_x e_z^T + e_z e_x^T): principal
    # directions at +-45 deg in xz, compression along +45 deg (alpha 45 for gamma growing).
    de = shearing.strain_increments(F)
    assert shearing.major_angle_xz(de[:, 0, 0], de[:, 2, 2], de[:, 0, 2]) == pytest.approx(np.full(10, 45.0))
