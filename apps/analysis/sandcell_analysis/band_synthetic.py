"""Synthetic tests for the band detector (band_detector.py): samples whose answer is known.

A sample is N spheres (d50 = 1 mm, radii 0.45-0.55 mm) on a jittered cubic lattice (N of the M^3 >= N sites
drawn at random, each moved by up to JITTER of the spacing: the density fluctuations of a packing rather than
of a gas) in a cubic periodic cell of void ratio E0, sheared by INCREMENTS equal affine increments
AFFINE = diag(eps, -eps/2, -eps/2) (compression positive, eps_q = eps per increment) plus a non-affine field:
  "noise":    independent Gaussian displacements per particle, NOISE d50 rms per component per increment (the
              homogeneous surrogate (a) of the detector, on other particles);
  "gaussian": a smooth, periodic Gaussian random displacement field of correlation length ELL d50 (covariance
              exp(-r^2 / 2 ell^2) per component), SMOOTH d50 rms per component per increment, a new field in every
              increment (a diffuse but spatially correlated deformation: the old detector's false positive), plus
              the particle noise;
  "band":     the particle noise plus a planar band of normal along the mode (1, 0, 1), of width `width` (d50)
              centred on xi = 0.5: inside it the non-affine shear adds to the affine deviator (its shear direction
              shortens axis 1) and the material dilates, outside it counter-shears and compacts (a fixed periodic
              cell: the band's displacement has no net jump over a period). Per increment the band carries the
              shear gamma = BAND_GAMMA eps and the dilation delta = BAND_DELTA (inside, in the band's thickness).
              Over the INCREMENTS increments its void ratio grows ~0.11 above the outside's, as in the
              committed b = 0.5 bands at 19,436 spheres (0.09-0.15 over their whole tests).
sample(kind, n, seed) returns the snapshots as localization.judge_test takes them and a series. With tilt = (t_xy, t_xz,
t_yz) the cell also shears, as a free cell does: at snapshot k its basis is upper triangular with the tilts k t_xy L_1,
k t_xz L_1, k t_yz L_2 (a few per cent of a length over the test), the particles' reduced coordinates s = C^-1 x carried
by it and the non-affine fields defined on s as before (the band's normal is then the reciprocal lattice vector of its
mode); the first snapshot's cell is orthorhombic (its lengths), the later ones are matrices (localization's cell).
With free=True (kind "band"), the cell shears by the band's own slip, as a free cell does (free_sample).
"""
import math

import numpy as np

D50 = 1.0e-3
E0 = 0.60
JITTER = 0.5
INCREMENTS = 3
EPS = 0.02          # axial strain per increment (a snapshot every 2 %)
NOISE = 0.05        # d50, rms per component per increment (DEM non-affine motion over ~1 % strain: 0.05-0.1 d50)
ELL = 3.0           # d50
SMOOTH = 0.03       # d50 rms per component per increment: strain fluctuations ~ SMOOTH / ELL ~ half the affine eps
BAND_GAMMA = 6.0    # band shear per increment over eps: most of the deviatoric increment goes into the band
BAND_DELTA = 0.030  # band dilation per increment: ~0.11 in void ratio over 3 increments, as the b = 0.5 bands
HKL = (1, 0, 1)


def packing(n, rng):
    """(fractional coordinates [n, 3], radii [n], cell edge L) of n spheres on a jittered lattice at void ratio E0."""
    m = math.ceil(n ** (1.0 / 3.0) - 1e-9)
    sites = np.stack(np.meshgrid(*[np.arange(m)] * 3, indexing="ij"), -1).reshape(-1, 3)
    sites = sites[rng.choice(len(sites), n, replace=False)]
    s = ((sites + 0.5 + JITTER * rng.uniform(-1.0, 1.0, (n, 3))) / m) % 1.0
    r = 0.5 * D50 * rng.uniform(0.9, 1.1, n)
    L = ((1.0 + E0) * (4.0 / 3.0 * np.pi * r ** 3).sum()) ** (1.0 / 3.0)
    return s, r, L


def smooth_field(s, L, rng, ell, grid=32):
    """A periodic Gaussian random vector field at the fractional positions s (unit rms per component): white noise
    on a grid of `grid`^3 filtered by the Gaussian covariance's spectrum exp(-k^2 ell^2 / 2), read by trilinear
    interpolation."""
    L = np.broadcast_to(np.asarray(L, float), (3,))
    k = [2.0 * np.pi * np.fft.fftfreq(grid, L[m] / grid) for m in range(3)]
    k2 = k[0][:, None, None] ** 2 + k[1][None, :, None] ** 2 + k[2][None, None, :] ** 2
    amp = np.exp(-k2 * ell * ell / 4.0)
    out = np.empty((len(s), 3))
    g = s * grid - 0.5
    i0 = np.floor(g).astype(np.int64)
    w = g - i0
    for c in range(3):
        f = np.fft.ifftn(np.fft.fftn(rng.standard_normal((grid,) * 3)) * amp).real
        f /= f.std()
        acc = np.zeros(len(s))
        for corner in np.ndindex(2, 2, 2):
            idx = (i0 + corner) % grid
            wt = np.prod(np.where(corner, w, 1.0 - w), axis=1)
            acc += wt * f[idx[:, 0], idx[:, 1], idx[:, 2]]
        out[:, c] = acc
    return out / out.std(axis=0)


def band_displacement(s, L, width):
    """The band's non-affine displacement per unit gamma and delta: (P(xi) t d, P(xi) n d), xi = frac(s . hkl),
    d the mode's plane spacing, P' = 1 - w/d inside |xi - 0.5| < w / 2d and -w/d outside (zero net jump). L: the
    cell's lengths, or its matrix C (a sheared cell: the normal C^-T hkl)."""
    h = np.array(HKL, float)
    nrm = h / L if np.ndim(L) == 1 else np.linalg.solve(np.asarray(L, float).T, h)
    d = 1.0 / np.linalg.norm(nrm)
    n = nrm * d
    t = np.array([-n[2], 0.0, n[0]])  # in the band plane, the sign that shortens axis 1 (adds to the affine part)
    if np.ndim(L) == 2:
        t /= np.linalg.norm(t)  # a unit vector (already one in an orthorhombic cell, where n_2 = 0)
    xi = (s @ h) % 1.0
    f = width * D50 / d
    y = xi - 0.5
    inside = np.abs(y) < 0.5 * f
    P = np.where(inside, (1.0 - f) * y, np.where(y > 0, 0.5 * f * (1.0 - f) - f * (y - 0.5 * f),
                                                 -0.5 * f * (1.0 - f) - f * (y + 0.5 * f)))
    return P[:, None] * t * d, P[:, None] * n * d


def free_slip(s, C, width):
    """The shear of a band whose slip a free cell takes up (per unit gamma): Q(s) t d with Q' = 1 inside the band and
    0 outside, continuous from one period to the next, Q = clip(frac(s . hkl) - 1/2, -w/2d, w/2d) + (w/d) floor(s .
    hkl); and its jump over the lattice: u(s + e_j) = u(s) + (w/d) h_j t d, so the cell's basis C gets (w/d) d t hkl^T
    per unit gamma. t, n, d as band_displacement's in the cell C."""
    h = np.array(HKL, float)
    nrm = np.linalg.solve(np.asarray(C, float).T, h)
    d = 1.0 / np.linalg.norm(nrm)
    n = nrm * d
    t = np.array([-n[2], 0.0, n[0]])
    t /= np.linalg.norm(t)
    f = width * D50 / d
    xi = s @ h
    Q = np.clip(xi % 1.0 - 0.5, -0.5 * f, 0.5 * f) + f * np.floor(xi)
    return Q[:, None] * t * d, np.outer(f * d * t, h)


def sheared_cell(lengths, tilt, k):
    """The cell matrix of snapshot k: lengths on the diagonal, tilts k (t_xy L_1, t_xz L_1, t_yz L_2)."""
    t = k * np.asarray(tilt, float) * lengths[[0, 0, 1]]
    return np.array([[lengths[0], t[0], t[1]], [0.0, lengths[1], t[2]], [0.0, 0.0, lengths[2]]])


def sample(kind, n, seed, width=5.0, ell=ELL, tilt=None, free=False):
    """(snapshots [(step, ids, positions, cell lengths or matrix, radii)], series {step, strain, e}) of a synthetic test
    of `kind` ("noise", "gaussian", "band") with n spheres; width: the band's (d50); tilt: the cell's tilts per
    increment as fractions of its lengths (None: an orthorhombic cell); free: a "band" whose shear is not
    compensated outside it but taken up by the cell (free_sample: the cell shears by the band's slip)."""
    if kind not in ("noise", "gaussian", "band"):
        raise ValueError(f"kind: {kind!r}, expected noise, gaussian or band")
    if free:
        if kind != "band":
            raise ValueError("free: a band's slip, kind 'band' only")
        return free_sample(n, seed, width)
    if tilt is not None:
        return sheared_sample(kind, n, seed, width, ell, tilt)
    rng = np.random.default_rng(seed)
    s, r, L = packing(n, rng)
    affine = np.array([EPS, -0.5 * EPS, -0.5 * EPS])
    ids = np.arange(n) + 1
    snaps, series = [], dict(step=[], strain=[], e=[])
    cell = np.full(3, L)
    x = s * cell
    for k in range(INCREMENTS + 1):
        if k:
            cell_b = cell * np.exp(-affine)
            u = NOISE * D50 * rng.standard_normal((n, 3))
            if kind == "gaussian":
                u += SMOOTH * D50 * smooth_field(x / cell, cell, rng, ell * D50)
            elif kind == "band":
                shear, dil = band_displacement(x / cell, cell, width)
                u += BAND_GAMMA * EPS * shear + BAND_DELTA * dil
            x = x / cell * cell_b + u
            cell = cell_b
        snaps.append((1000 * k, ids, x.copy(), cell.copy(), r))
        series["step"].append(1000.0 * k)
        series["strain"].append(affine * k)
        series["e"].append(np.prod(cell) / (4.0 / 3.0 * np.pi * r ** 3).sum() - 1.0)
    return snaps, {key: np.asarray(v, float) for key, v in series.items()}


def sheared_sample(kind, n, seed, width, ell, tilt):
    """sample's test in a cell that shears by `tilt` per increment: the same packing, affine increments and non-affine
    fields (drawn in the same order from the same seed), carried by the sheared cell."""
    rng = np.random.default_rng(seed)
    s, r, L = packing(n, rng)
    affine = np.array([EPS, -0.5 * EPS, -0.5 * EPS])
    ids = np.arange(n) + 1
    snaps, series = [], dict(step=[], strain=[], e=[])
    lengths = np.full(3, L)
    cell = sheared_cell(lengths, tilt, 0)
    x = s @ cell.T
    for k in range(INCREMENTS + 1):
        if k:
            lengths_b = lengths * np.exp(-affine)
            cell_b = sheared_cell(lengths_b, tilt, k)
            s = np.linalg.solve(cell, x.T).T
            u = NOISE * D50 * rng.standard_normal((n, 3))
            if kind == "gaussian":
                u += SMOOTH * D50 * smooth_field(s % 1.0, lengths, rng, ell * D50)
            elif kind == "band":
                shear, dil = band_displacement(s, cell, width)
                u += BAND_GAMMA * EPS * shear + BAND_DELTA * dil
            x = s @ cell_b.T + u
            lengths, cell = lengths_b, cell_b
        snaps.append((1000 * k, ids, x.copy(), cell.copy() if k else lengths.copy(), r))
        series["step"].append(1000.0 * k)
        series["strain"].append(affine * k)
        series["e"].append(np.prod(lengths) / (4.0 / 3.0 * np.pi * r ** 3).sum() - 1.0)
    return snaps, {key: np.asarray(v, float) for key, v in series.items()}


def free_sample(n, seed, width):
    """sample's band in a free cell: the outside follows the cell (particle noise only), the band carries the shear
    BAND_GAMMA EPS a increment (free_slip) and the dilation (band_displacement's, compensated outside), and the cell
    takes up the band's slip: its basis becomes D C + gamma (w/d) d t hkl^T (D the axial affine increment), turned
    back to upper triangular by the rotation of its QR decomposition, which turns the particles with it (a rigid
    rotation, which the periodic sample does not feel: docs/physics.md section 1). The tilts grow to a few per cent
    of the lengths over the three increments, as in the free cells of experiments/2026-11-28-free-cell-banded."""
    rng = np.random.default_rng(seed)
    s, r, L = packing(n, rng)
    stretch = np.diag(np.exp(-np.array([EPS, -0.5 * EPS, -0.5 * EPS])))
    ids = np.arange(n) + 1
    snaps, series = [], dict(step=[], strain=[], e=[])
    cell = np.diag(np.full(3, L))
    x = s @ cell.T
    for k in range(INCREMENTS + 1):
        if k:
            s = np.linalg.solve(cell, x.T).T
            u = NOISE * D50 * rng.standard_normal((n, 3))
            shear, jump = free_slip(s, cell, width)
            _, dil = band_displacement(s, cell, width)
            gamma = BAND_GAMMA * EPS
            u += gamma * shear + BAND_DELTA * dil
            Q, R = np.linalg.qr(stretch @ cell + gamma * jump)
            sign = np.sign(np.diag(R))
            Q, R = Q * sign, sign[:, None] * R
            x = (s @ (stretch @ cell).T + u) @ Q  # each row Q^T x: the configuration turned with its cell
            cell = np.triu(R)
        snaps.append((1000 * k, ids, x.copy(), cell.copy() if k else np.diag(cell).copy(), r))
        series["step"].append(1000.0 * k)
        series["strain"].append(-np.log(np.diag(cell) / L))
        series["e"].append(np.prod(np.diag(cell)) / (4.0 / 3.0 * np.pi * r ** 3).sum() - 1.0)
    return snaps, {key: np.asarray(v, float) for key, v in series.items()}
