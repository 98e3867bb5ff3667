"""Strain localization in a sandcell triaxial test: is the incremental strain field homogeneous or banded?

    triaxial localization RESULTS.h5... [--out DIR] [--grid G] [--whole] [--slabs K] [--void-ratios]

Reads the particle snapshots of each shearing results file (`output.snapshot_interval` sets how
many; ~1 % of axial strain apart suits the method) and, for each pair of consecutive snapshots a, b
(with --whole: the first and the last only, one increment over the whole test):
  1. matches the particles by id and takes their non-affine displacement: the cell deforms
     affinely, so a particle that follows it keeps its fractional coordinate s = x / L (mod 1), and
     u = wrap(s_b - s_a) L_b, wrap to [-1/2, 1/2) (the increments' non-affine motion is far below
     half a cell).
  2. bins the particles by s_a into a periodic G x G x G grid (default G = max(3, round((N/40)^1/3)),
     ~40 particles a bin) and averages u per bin; an empty bin is an error (use a smaller --grid).
  3. differentiates the bin means by periodic central differences, dU/dx_m = (U[+1] - U[-1]) /
     (2 L_m / G), with L the mean of L_a and L_b (the midpoint of the increment, as the
     logarithmic affine strain is), and takes the local strain increment of each bin,
     deps = -(diag(ln(L_b / L_a)) + sym grad U), compression positive like the series; its
     deviatoric invariant deps_q = sqrt(2/3 e:e) (e its deviator) and volumetric part tr deps.
  4. reports per increment: the macroscopic deps_q (affine part alone), the mean and the coefficient
     of variation of the local deps_q, the top-10 % share (the part of the summed local deps_q
     carried by the 10 % of bins with the largest; 0.10 when uniform, with a fractional last bin),
     and the band mode: a planar band in a periodic cell has a normal along a reciprocal lattice
     vector, so it shows as power of the local deps_q field (mean removed) concentrated in one low
     Fourier mode (h, k, l) in [-2, 2]^3, +-(h, k, l) one mode. The strongest mode's share of the
     variance (Parseval) is given next to the same share of the bins randomly permuted (mean of 20
     permutations, fixed seed; the criterion before issue 45, a spatially white null, kept for
     comparison). The band normal is n ~ (h/L_1, k/L_2, l/L_3); its angle to axis 1 (the most
     compressed) is reported.
  5. the band detector's test of the increment (band_detector.py): the share against the 0.99
     quantile of 200 homogeneous surrogates of each of two kinds at the same grid (particle noise;
     particle noise plus a correlated Gaussian displacement field of the covariance length fitted to
     the test's own bin means): threshold_noise, threshold_gauss, corr_length (m), corr_fraction,
     significant; and across that mode's slabs the band/outside deps_q (strain_ratio). The increment
     detects a band (band_detected) when significant and strain_ratio >= 2. Onset: the first such
     increment; persistent when >= 50 % of the later ones detect it again in the same mode.
The sampling of ~40 particles a bin leaves a noise floor in the local field: the CV and the mean
local deps_q include it, the surrogates of kind (a) measure it.

A cell that shears (a free cell, `shear = "free"`; docs/physics.md section 1): its snapshots give their
cell as C = H N (H upper triangular, lengths and tilts xy, xz, yz, from the snapshot's cell_tilt, or from
the series' row at its step for files written before the snapshots recorded it; N its flips), and every
step above is taken in the reduced coordinates s = C^-1 x of that lattice basis, which the cell's affine
deformation keeps: the bins and the modes are those of s, u = C_b wrap(s_b - s_a) (each snapshot with its
own cell: the minimum image), the gradients dU/dx = dU/ds C^-1 in the mean cell, the affine part the Hencky
strain (1/2) ln(F F^T) of F = C_b C_a^-1 (the series' strain_tensor convention), a mode's normal the
reciprocal lattice vector C^-T (h, k, l) and its spacing 1 / |C^-T (h, k, l)|, the slabs' volume V_cell / K
with V_cell = det C. The surrogates are built in the same geometry (their wave vectors 2 pi C^-T m). A free
cell is thus judged by the same method and criteria as an orthorhombic one. An orthorhombic cell (no
tilts, no flips) keeps its lengths and the arithmetic above, bitwise that of the code before sheared cells
were read.

--void-ratios: also <stem>-localization-void.csv (band_void_ratios, one row): the verdict, the band's
mode and normal, its onset and persistence, and over the critical-state window (the snapshots within the
last 0.1 of eps_q) the mean void ratio of the band's slabs (e_in), of the other slabs (e_out), both empty
(NaN) when the file is not banded, and of all (e_global, the series' e to round-off); also the same two
means over the candidate mode's slabs whatever the verdict (e_in_candidate, e_out_candidate) and the part of
the window's increments that detect the band in that mode (window_detected).

Band profile and verdict (whatever --whole says): is there a band, and is it denser or looser than the
rest? The strongest mode (h, k, l) of the whole-test increment (first snapshot to last) is the file's
candidate. The file is banded (the `banded` column, the same in every row) when its share is above the
surrogates' 0.99 quantile, the band/outside deps_q across it is >= 2 in at least one snapshot increment,
and the band's void ratio minus the outside's grows from the first snapshot to the last by >= 0.01 and
>= 3 times its noise (band_detector.py says why these numbers). xi = frac(h s_1 + k s_2 + l s_3) is
kept by the cell's affine deformation, so K slabs of equal xi width (--slabs, default 10) are material
slabs but for the non-affine motion, each V_cell / K of the cell at every snapshot; they lie across
the band, spacing d = 1 / |n| between the mode's planes, d / K thick.
  - solid volume per slab at every snapshot, exact: each sphere is cut by the slab planes it crosses
    into caps and zones (V = pi (r + z)^2 (2r - z) / 3 below a plane at z from the centre), wrapped
    across xi = 0/1; the void ratio of slab j is e_j = (V_cell / K - V_s,j) / V_s,j.
  - local strain per slab over the whole test: the particles' non-affine displacement (as in 1.)
    averaged per slab of their xi at the first snapshot, differentiated along the normal by periodic
    central differences (zeta = xi d, d in the mean cell), deps = -(diag ln(L_b / L_a) + sym(dU/dzeta
    n^T)); its deps_q locates the band: the slabs above the mean by more than half the way to the
    largest. The rest is "outside".
Its outputs: <stem>-localization-band.csv (one row per snapshot: step, eps_1, e of the band slabs
together, of the outside, of all slabs, which is the series' e = V_cell / V_s - 1, and of each slab;
written only when the file is banded), a "Band profile" section in the summary (the verdict and the
candidate's profile) and a third column in the figure (deps_q and deps_v per slab; e per slab at the
first, middle and last snapshot), and one printed line.

Writes, into --out (default: next to each input), <stem>-localization.csv (one row per increment),
<stem>-localization.md (summary) and <stem>-localization.png: the statistics against eps_1 over q/p
and e, and maps of the local deps_q of the last increment and of the increment with the largest
mode share, averaged along an axis in the plane of the band (its mode component 0; a middle slice
normal to axis 2 when it has none), and the band profile. One line per increment is printed.
Exit status: 0 done (with or without a band); 2 bad input (unreadable file, fewer than 2 snapshots,
bad --grid or --slabs, an empty bin or slab); 1 numpy, matplotlib or h5py missing.
"""
import argparse
import csv
import io
import math
import os
import sys

import numpy as np

from .results import InputError, open_results, read_series, read_snapshot, snapshot_names  # noqa: F401


PROG = os.environ.get("SANDCELL_ANALYZE_PROG", "localization.py")
TOP = 0.10            # the top-share fraction of bins
MAX_ORDER = 2         # mode components searched: [-2, 2]
SHUFFLES, SEED = 20, 12345
SLABS = 10            # default slabs across the band's period
# The criterion before issue 45 (mode share above this many times the shuffled share): a spatially white null that
# any correlated but diffuse field beats. Kept for the comparison only (old_criterion); the verdict is band_detector's.
BAND_CONTRAST = 3.0
COLUMNS = ["step_a", "step_b", "eps1_mid", "deps_q_macro", "deps_v_macro", "deps_q_mean", "deps_q_cv",
           "top10_share", "mode_h", "mode_k", "mode_l", "mode_share", "shuffled_share", "normal_angle_deg",
           "deps_v_std", "threshold_noise", "threshold_gauss", "corr_length", "corr_fraction", "significant",
           "strain_ratio", "band_detected", "banded"]


def fail(msg, code=2):
    print(f"{PROG}: {msg}", file=sys.stderr)
    sys.exit(code)


def default_grid(n):
    return max(3, round((n / 40.0) ** (1.0 / 3.0)))


def strain_invariants(deps):
    """(deps_q, deps_v) of strain tensors [..., 3, 3]."""
    vol = np.trace(deps, axis1=-2, axis2=-1)
    dev = deps - vol[..., None, None] * np.eye(3) / 3.0
    return np.sqrt(2.0 / 3.0 * np.sum(dev * dev, axis=(-2, -1))), vol


# The cell of a snapshot (docs/physics.md section 1) is either its three edge lengths L (an orthorhombic cell: the
# arithmetic below is then exactly that of the code before the cell could shear, bitwise) or the 3 x 3 upper triangular
# matrix C = H N whose columns are the edges of the lattice basis that deforms affinely (H the written basis, N its
# flips; C = H when the cell never flipped). Every quantity is taken in the reduced coordinates s = C^-1 x: bins, modes
# and slabs are those of the lattice basis, which the cell's affine deformation keeps.

def orthorhombic(*cells):
    """Whether every cell is given by its lengths (the orthorhombic arithmetic applies)."""
    return all(np.ndim(c) == 1 for c in cells)


def cell_matrix(c):
    """The cell's basis C (3 x 3, columns the edge vectors) from its lengths or its matrix."""
    c = np.asarray(c, float)
    return c if c.ndim == 2 else np.diag(c)


def cell_lengths(c):
    """The diagonal of the cell's basis (L_1, L_2, L_3)."""
    c = np.asarray(c, float)
    return c if c.ndim == 1 else np.diag(c).copy()


def cell_volume(c):
    """V = det C = L_1 L_2 L_3 (C upper triangular)."""
    return float(np.prod(cell_lengths(c)))


def mean_cell(c_a, c_b):
    """The increment's mean cell (its midpoint, where the gradients are taken): lengths if both are lengths."""
    if orthorhombic(c_a, c_b):
        return 0.5 * (np.asarray(c_a, float) + np.asarray(c_b, float))
    return 0.5 * (cell_matrix(c_a) + cell_matrix(c_b))


def reduced(x, c):
    """Reduced coordinates s = C^-1 x of positions x [n, 3] (x / L for an orthorhombic cell; back substitution in the
    upper triangular C otherwise, as components/cell.hpp's reduced())."""
    c = np.asarray(c, float)
    if c.ndim == 1:
        return x / c
    x = np.asarray(x, float)
    s = np.empty_like(x)
    s[:, 2] = x[:, 2] / c[2, 2]
    s[:, 1] = (x[:, 1] - c[1, 2] * s[:, 2]) / c[1, 1]
    s[:, 0] = (x[:, 0] - c[0, 1] * s[:, 1] - c[0, 2] * s[:, 2]) / c[0, 0]
    return s


def affine_strain(c_a, c_b):
    """The affine (cell) part of the increment's logarithmic strain, tension positive: diag(ln(L_b / L_a)) for an
    orthorhombic cell; for any cell the Hencky strain ln V = (1/2) ln(F F^T) of the increment's deformation
    F = C_b C_a^-1 (its rotation dropped), the series' strain_tensor convention."""
    if orthorhombic(c_a, c_b):
        return np.diag(np.log(np.asarray(c_b, float) / np.asarray(c_a, float)))
    F = cell_matrix(c_b) @ np.linalg.inv(cell_matrix(c_a))
    w, V = np.linalg.eigh(F @ F.T)
    return 0.5 * (V * np.log(w)) @ V.T


def reciprocal(c):
    """C^-T, whose columns are the reciprocal basis (without 2 pi): a plane wave of integer mode m in s has the wave
    vector C^-T m in x, and a gradient over s becomes one over x as d/dx = C^-T d/ds."""
    return np.linalg.inv(cell_matrix(c)).T


def non_affine(id_a, x_a, L_a, id_b, x_b, L_b):
    """The particles matched by id (indices into snapshot a), their fractional coordinates s_a and their
    non-affine displacements u = wrap(s_b - s_a) L_b (with a sheared cell: s = C^-1 x with each snapshot's own cell,
    u = C_b wrap(s_b - s_a), the minimum image)."""
    _, ia, ib = np.intersect1d(id_a, id_b, assume_unique=True, return_indices=True)
    if not orthorhombic(L_a, L_b):
        s_a = reduced(x_a[ia], L_a)
        ds = reduced(x_b[ib], L_b) - s_a
        return ia, s_a, (ds - np.floor(ds + 0.5)) @ cell_matrix(L_b).T
    s_a = x_a[ia] / L_a
    ds = x_b[ib] / L_b - s_a
    return ia, s_a, (ds - np.floor(ds + 0.5)) * L_b


def local_strain(id_a, x_a, L_a, id_b, x_b, L_b, G):
    """Local strain increments [G, G, G, 3, 3] (compression positive) between two snapshots, and the
    particles matched. Raises ValueError on an empty bin."""
    deps, ia, _, _ = increment_field(id_a, x_a, L_a, id_b, x_b, L_b, G)
    return deps, len(ia)


def increment_field(id_a, x_a, L_a, id_b, x_b, L_b, G):
    """local_strain's field, the matched particles (indices into a), their fractional coordinates s_a and their
    non-affine displacements u (what the band detector's surrogates are built on)."""
    L_a, L_b = np.asarray(L_a, float), np.asarray(L_b, float)
    ia, s_a, u = non_affine(id_a, x_a, L_a, id_b, x_b, L_b)
    return binned_strain(s_a, u, L_a, L_b, G), ia, s_a, u


def bin_counts(s_a, G):
    """The bin of each particle (flat index into the G-grid) and the particles per bin. Raises ValueError on an
    empty bin."""
    # floor then mod: a coordinate a hair below 0 (unwrapped) lands in the last bin, not at index -1
    cell = np.floor(s_a * G).astype(np.int64) % G
    flat = (cell[:, 0] * G + cell[:, 1]) * G + cell[:, 2]
    count = np.bincount(flat, minlength=G ** 3)
    if not count.all():
        raise ValueError(f"{np.count_nonzero(count == 0)} of {G ** 3} bins are empty")
    return flat, count


def binned_strain(s_a, u, L_a, L_b, G):
    """Local strain increments [G, G, G, 3, 3] from the particles' fractional coordinates s_a (at a) and non-affine
    displacements u, the cell going from L_a to L_b. Raises ValueError on an empty bin."""
    flat, count = bin_counts(s_a, G)
    U = np.stack([np.bincount(flat, u[:, c], G ** 3) / count for c in range(3)], -1).reshape(G, G, G, 3)
    return strain_of_means(U, L_a, L_b)


def strain_of_means(U, L_a, L_b):
    """The local strain [..., G, G, G, 3, 3] of bin-mean non-affine displacements U [..., G, G, G, 3]: periodic
    central differences over the mean cell's bin spacing, plus the affine increment, compression positive. A sheared
    cell: the differences are taken along the reduced axes, dU/ds_m = (U[+1] - U[-1]) / (2 / G), and turned into
    dU/dx = dU/ds C^-1 with the mean cell C; the affine part is affine_strain's."""
    G = U.shape[-2]
    if not orthorhombic(L_a, L_b):
        axes = range(U.ndim - 4, U.ndim - 1)
        grad_s = np.stack([(np.roll(U, -1, a) - np.roll(U, 1, a)) * (0.5 * G) for a in axes], -1)  # [..., i, m]
        grad = grad_s @ np.linalg.inv(cell_matrix(mean_cell(L_a, L_b)))  # [..., i, j]
        return -(affine_strain(L_a, L_b) + 0.5 * (grad + np.swapaxes(grad, -1, -2)))
    spacing = 0.5 * (L_a + L_b) / G
    axes = range(U.ndim - 4, U.ndim - 1)
    grad = np.stack([(np.roll(U, -1, a) - np.roll(U, 1, a)) / (2.0 * spacing[m]) for m, a in enumerate(axes)],
                    -1)  # [..., i, m]
    affine = np.diag(np.log(L_b / L_a))
    return -(affine + 0.5 * (grad + np.swapaxes(grad, -1, -2)))


def mode_table(G):
    """The distinct modes +-(h, k, l), |components| <= 2, on a G-grid: [(hkl, flat FFT indices)],
    lowest order first (on a small grid +-2 can alias onto +-1; each index set is kept once)."""
    seen, table = set(), []
    r = range(-MAX_ORDER, MAX_ORDER + 1)
    for hkl in sorted(((h, k, l) for h in r for k in r for l in r),  # noqa: E741 (Miller indices h, k, l)
                      key=lambda v: (sum(map(abs, v)), v)):
        if hkl == (0, 0, 0):
            continue
        idx = frozenset(np.ravel_multi_index(tuple(sgn * c % G for c in hkl), (G, G, G)) for sgn in (1, -1))
        if idx not in seen:
            seen.add(idx)
            first = next(c for c in hkl if c)
            table.append((tuple(c if first > 0 else -c for c in hkl), np.array(sorted(idx))))
    return table


def strongest_mode(field, table):
    """(hkl, share of the variance) of the strongest mode of the field; (0, 0, 0), NaN for a field uniform to
    round-off (a mode of round-off would be noise)."""
    if field.std() <= 1e-9 * abs(field.mean()):
        return (0, 0, 0), math.nan
    power = np.abs(np.fft.fftn(field - field.mean())).ravel() ** 2
    shares = np.array([power[idx].sum() for _, idx in table]) / power.sum()
    best = int(np.argmax(shares))
    return table[best][0], float(shares[best])


def top_share(values, fraction=TOP):
    """Part of the sum carried by the largest `fraction` of the values (the last one counted in part)."""
    v = np.sort(values.ravel())[::-1]
    k = fraction * v.size
    m = int(k)
    total = v.sum()
    return float((v[:m].sum() + (k - m) * (v[m] if m < v.size else 0.0)) / total) if total > 0 else math.nan


def increment_stats(deps, L_a, L_b, table, rng_seed=SEED, particles=None):
    """The statistics of one increment's local strain field (a dict, keys as COLUMNS up to deps_v_std; with
    particles = (s_a, u), also the band detector's test of the field: band_detector.judge_field) and its deps_q
    field."""
    q, v = strain_invariants(deps)
    q_macro, v_macro = strain_invariants(-affine_strain(L_a, L_b))
    hkl, share = strongest_mode(q, table)
    rng = np.random.default_rng(rng_seed)
    shuffled = float(np.mean([strongest_mode(rng.permutation(q.ravel()).reshape(q.shape), table)[1]
                              for _ in range(SHUFFLES)]))
    L = mean_cell(L_a, L_b)
    normal = np.array(hkl, float) / L if orthorhombic(L) else reciprocal(L) @ np.array(hkl, float)
    mean = float(q.mean())
    return dict(deps_q_macro=float(q_macro), deps_v_macro=float(v_macro), deps_q_mean=mean,
                deps_q_cv=float(q.std() / mean) if mean > 0 else math.nan, top10_share=top_share(q),
                mode_h=hkl[0], mode_k=hkl[1], mode_l=hkl[2], mode_share=share, shuffled_share=shuffled,
                normal_angle_deg=math.degrees(math.atan2(np.hypot(normal[1], normal[2]), abs(normal[0])))
                if any(hkl) else math.nan,
                deps_v_std=float(v.std()), **detector_columns(q, L_a, L_b, table, particles)), q


def detector_columns(q, L_a, L_b, table, particles):
    """The band detector's columns of an increment (NaN without the particles)."""
    if particles is None:
        return dict(threshold_noise=math.nan, threshold_gauss=math.nan, corr_length=math.nan,
                    corr_fraction=math.nan, significant=0)
    from .band_detector import judge_field
    j = judge_field(q, *particles, L_a, L_b, table)
    return dict(threshold_noise=j["threshold_noise"], threshold_gauss=j["threshold_gauss"], corr_length=j["ell"],
                corr_fraction=j["nu"], significant=int(j["significant"]))


def old_criterion(row):
    """The pre-issue-45 verdict of a row (mode share above BAND_CONTRAST x the shuffled share): for comparison only."""
    return float(row["mode_share"]) > BAND_CONTRAST * float(row["shuffled_share"])


def mode_geometry(L, hkl):
    """Plane spacing d (m) and unit normal of the mode (h, k, l) in a cell of edges L: its field is constant on the
    planes n . x = const (mod 1), n = (h/L_1, k/L_2, l/L_3), d = 1 / |n| apart. A sheared cell C: n = C^-T (h, k, l),
    the reciprocal lattice vector (n . x = (h, k, l) . s)."""
    n = np.asarray(hkl, float) / np.asarray(L, float) if orthorhombic(L) else reciprocal(L) @ np.asarray(hkl, float)
    d = 1.0 / np.linalg.norm(n)
    return d, n * d


def mode_coordinate(x, L, hkl):
    """xi = frac(h s_1 + k s_2 + l s_3) in [0, 1), s = x / L (s = C^-1 x in a sheared cell): the position across the
    mode's planes. The cell's affine deformation keeps it, so a slab of xi holds the same particles at every snapshot
    but for their non-affine motion."""
    xi = (reduced(np.asarray(x, float), L) if not orthorhombic(L) else np.asarray(x, float) / np.asarray(L, float)) \
        @ np.asarray(hkl, float)
    xi -= np.floor(xi)
    return np.where(xi < 1.0, xi, 0.0)  # -1e-18 - floor(-1e-18) rounds to 1.0


def sphere_below(t, r):
    """Volume of a sphere of radius r on the negative side of a plane at signed distance t from its centre (t beyond
    +-r: all or nothing): the cap pi (r + t)^2 (2r - t) / 3, above the centre the sphere less the cap above (the
    smaller part is the one computed, for accuracy)."""
    t = np.clip(t, -r, r)
    h = r - np.abs(t)  # height of the smaller cap
    cap = np.pi * h * h * (2.0 * r + np.abs(t)) / 3.0
    return np.where(t <= 0.0, cap, 4.0 / 3.0 * np.pi * r ** 3 - cap)


def slab_solid_volumes(x, r, L, hkl, K):
    """Solid volume (m^3) of the spheres (centres x, radii r) in each of K slabs of equal xi width across the mode
    (h, k, l): slab j spans xi in [j/K, (j+1)/K), distances [j d/K, (j+1) d/K) mod d along the normal. Exact: each
    sphere is cut by every slab plane it crosses (r may exceed d/K) into pieces that go to their slabs modulo K (a
    sphere across xi = 0/1 wraps). The pieces telescope: the slabs sum to the spheres' volume to round-off."""
    d, _ = mode_geometry(L, hkl)
    w = d / K
    r = np.broadcast_to(np.asarray(r, float), (len(x),))[:, None]
    z = mode_coordinate(x, L, hkl)[:, None] * d
    first = np.floor((z - r) / w).astype(np.int64)  # the slab plane below each sphere
    pieces = int((np.floor((z + r) / w).astype(np.int64) - first).max()) + 1  # the most slabs a sphere touches
    planes = first + np.arange(pieces + 1)
    vol = np.diff(sphere_below(planes * w - z, r), axis=1)  # piece j: between planes j and j + 1
    return np.bincount((planes[:, :-1] % K).ravel(), vol.ravel(), K)


def slab_strain(id_a, x_a, L_a, id_b, x_b, L_b, hkl, K):
    """Local strain [K, 3, 3] (compression positive) of K slabs across the mode (h, k, l) between two snapshots: the
    non-affine displacement averaged per slab of the particles' xi at a, differentiated along the normal by periodic
    central differences over zeta = xi d (d and the normal in the mean cell, as local_strain's gradients).
    Raises ValueError on an empty slab."""
    L_a, L_b = np.asarray(L_a, float), np.asarray(L_b, float)
    ia, _, u = non_affine(id_a, x_a, L_a, id_b, x_b, L_b)
    slab = np.floor(mode_coordinate(x_a[ia], L_a, hkl) * K).astype(np.int64) % K
    count = np.bincount(slab, minlength=K)
    if not count.all():
        raise ValueError(f"{np.count_nonzero(count == 0)} of {K} slabs are empty")
    U = np.stack([np.bincount(slab, u[:, c], K) / count for c in range(3)], -1)
    d, normal = mode_geometry(mean_cell(L_a, L_b), hkl)
    grad = ((np.roll(U, -1, 0) - np.roll(U, 1, 0)) / (2.0 * d / K))[:, :, None] * normal  # [slab, i, m]
    return -(affine_strain(L_a, L_b) + 0.5 * (grad + np.swapaxes(grad, -1, -2)))


def band_slabs(q):
    """The band's slabs (a mask): deps_q above the mean by more than half the way to the largest (that one at least)."""
    mean = q.mean()
    band = q - mean > 0.5 * (q.max() - mean)
    band[np.argmax(q)] = True
    return band


def void_ratio(volume, solid):
    with np.errstate(divide="ignore", invalid="ignore"):
        return (volume - solid) / solid


def profile_of(snaps, series, G, K, whole=None):
    """The band profile of a test and its verdict (a dict) from its snapshots [(step, ids, positions, cell lengths,
    radii or None)]: the strongest mode of the whole-test increment (first snapshot to last) and the band detector's
    test of that field (band_detector: "judged", "banded" and the reasons "why" not), the local strain of K slabs
    across the mode over the whole test, its band slabs and their strain ratio, the void ratio per slab, of the
    band's slabs, of the rest and of all at every snapshot, and the growth of the band's void-ratio contrast. "rows"
    is None with a "note" when there is no profile (a uniform field, no radii). The strain criterion ("ratio") is
    the largest band/outside deps_q ratio of the snapshot-to-snapshot increments across the whole test's mode
    ("ratios"; "ratio_whole": the whole test's). whole: the whole-test increment's
    stats if already computed (increment_stats with particles). series: /series (step, strain, e) for eps_1 and e.
    Raises ValueError on an empty bin or slab."""
    from . import band_detector as bd
    step_a, id_a, x_a, L_a, _ = snaps[0]
    step_b, id_b, x_b, L_b, _ = snaps[-1]
    if whole is None:
        try:
            deps, _, s_a, u = increment_field(id_a, x_a, L_a, id_b, x_b, L_b, G)
        except ValueError as e:
            raise ValueError(f"{e} (G = {G}): use a smaller --grid") from None
        whole, _ = increment_stats(deps, L_a, L_b, mode_table(G), particles=(s_a, u))
    hkl = (whole["mode_h"], whole["mode_k"], whole["mode_l"])
    judged = dict(hkl=hkl, share=whole["mode_share"], threshold_noise=whole["threshold_noise"],
                  threshold_gauss=whole["threshold_gauss"], ell=whole["corr_length"], nu=whole["corr_fraction"],
                  significant=bool(whole["significant"]))
    out = dict(hkl=hkl, share=whole["mode_share"], shuffled=whole["shuffled_share"], K=K,
               angle=whole["normal_angle_deg"], steps=(step_a, step_b), rows=None, judged=judged, banded=False,
               ratio=math.nan, growth=math.nan, noise=math.nan)
    if not any(hkl):
        out["why"] = ["the field is uniform to round-off"]
        out["note"] = f"no band: the whole test's local deps_q (steps {step_a}-{step_b}) is uniform to round-off"
        return out
    try:
        deps = slab_strain(id_a, x_a, L_a, id_b, x_b, L_b, hkl, K)
    except ValueError as e:
        raise ValueError(f"{e}: use fewer --slabs") from None
    q, v = strain_invariants(deps)
    band = band_slabs(q)
    # the strain criterion on the strain increments (snapshot to snapshot) across the whole test's mode: the whole
    # test averages the deformation before the band formed into the band's and the outside's alike
    ratios = []
    for (_, id_p, x_p, L_p, _), (_, id_n, x_n, L_n, _) in zip(snaps[:-1], snaps[1:]):
        try:
            q_inc = strain_invariants(slab_strain(id_p, x_p, L_p, id_n, x_n, L_n, hkl, K))[0]
        except ValueError as e:
            raise ValueError(f"{e}: use fewer --slabs") from None
        ratios.append(bd.strain_ratio(q_inc, band_slabs(q_inc)))
    out.update(deps_q=q, deps_v=v, band=band, ratio_whole=bd.strain_ratio(q, band), ratios=ratios,
               ratio=max(ratios))
    missing = [str(sn[0]) for sn in snaps if sn[4] is None]
    if missing:
        out["why"] = ["no void ratios (snapshots without radii)"]
        out["note"] = (f"no band verdict: snapshot(s) at step {', '.join(missing[:3])} lack the particle radii (no "
                       "void ratios); no band profile")
        return out
    rows = []
    for step, _, x, L, r in snaps:
        solid = slab_solid_volumes(x, r, L, hkl, K)
        V = cell_volume(L)
        rows.append(dict(step=step, eps_1=float(np.interp(step, series["step"], series["strain"][:, 0])) + 0.0,  # no -0
                         e_band=void_ratio(band.sum() * V / K, solid[band].sum()),
                         e_outside=void_ratio((K - band.sum()) * V / K, solid[~band].sum()),
                         e_whole=void_ratio(V, solid.sum()), e_slab=void_ratio(V / K, solid),
                         e_series=float(np.interp(step, series["step"], series["e"])) if "e" in series else math.nan,
                         series_row=bool(np.isin(step, series["step"])), d=mode_geometry(L, hkl)[0]))
    growth, noise = bd.void_contrast(rows[0]["e_slab"], rows[-1]["e_slab"], band)
    banded, why = bd.verdict(judged, out["ratio"], growth, noise)
    out.update(rows=rows, growth=growth, noise=noise, banded=banded, why=why)
    if not banded:
        out["note"] = "no band: " + "; ".join(why)
    return out


def write_atomic(path, write):
    """write(tmp) into a temporary file next to path, then renamed: a reader never sees half a file."""
    tmp = f"{path}.tmp{os.getpid()}"
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def write_text(path, text):
    def write(tmp):
        with open(tmp, "w") as f:
            f.write(text)
    write_atomic(path, write)


def read_snapshots(f, path):
    """The snapshots of an open results file for the increments and the band profile: [(step, ids, positions, cell
    lengths or matrix, radii or None)] (snapshot_names: the stage's end replacing the last interval snapshot). When
    any snapshot's cell is sheared, every snapshot's cell is given as its matrix (same_cell_kind)."""
    snaps = []
    for name in snapshot_names(f, path):
        g = f["snapshots"][name]
        snaps.append(read_snapshot(f, name, path) + (np.asarray(g["radius"][:], float) if "radius" in g else None,))
    return same_cell_kind(snaps)


def same_cell_kind(snaps):
    """The snapshots with every cell as its matrix when any is one (a free cell starts orthorhombic and then shears:
    one arithmetic for the whole test), else unchanged."""
    if orthorhombic(*(sn[3] for sn in snaps)):
        return snaps
    return [sn[:3] + (cell_matrix(sn[3]),) + tuple(sn[4:]) for sn in snaps]


def band_profile(f, path, series, G, K):
    """The band profile of a results file and its verdict (profile_of on its snapshots; exit 2 on an empty bin or
    slab)."""
    snaps = read_snapshots(f, path)
    try:
        return profile_of(snaps, series, G, K)
    except ValueError as e:
        fail(f"{path}: whole test, steps {snaps[0][0]}-{snaps[-1][0]}: {e}")


def analyse(path, G_opt, whole, K=SLABS):
    """Rows of statistics and the local deps_q fields of every increment of one results file, its band profile and
    verdict, and the band's onset and persistence over the increments (judge_test on its snapshots)."""
    with open_results(path) as f:
        series = read_series(f, path)
        snaps = read_snapshots(f, path)
    G = G_opt or default_grid(len(snaps[0][1]))
    name = os.path.basename(path)

    def log(r):
        print(f"{PROG}: {name}: steps {r['step_a']}-{r['step_b']}, eps1 {r['eps1_mid']:.4f}: deps_q macro "
              f"{r['deps_q_macro']:.3e}, local mean {r['deps_q_mean']:.3e}, CV {r['deps_q_cv']:.3f}, "
              f"top-10% {r['top10_share']:.3f}, mode ({r['mode_h']},{r['mode_k']},{r['mode_l']}) "
              f"{r['mode_share']:.3f} (shuffled {r['shuffled_share']:.3f}; surrogates' quantile "
              f"{max(r['threshold_noise'], r['threshold_gauss']):.3f}), normal {r['normal_angle_deg']:.1f} deg "
              f"to axis 1, band/outside deps_q {r['strain_ratio']:.2f}: "
              f"{'band' if r['band_detected'] else 'no band'}", flush=True)
    try:
        res = judge_test(snaps, series, G, K, whole, log)
    except ValueError as e:
        fail(f"{path}: {e}")
    print(f"{PROG}: {name}: {band_line(res['band'])}", flush=True)
    return res


def judge_test(snaps, series, G, K=SLABS, whole=False, log=None):
    """The increments (snapshot to snapshot; with whole, the first to the last only) of a test's snapshots
    [(step, ids, positions, cell lengths, radii or None)]: their rows of statistics (COLUMNS), the band detector's
    test of each and its slab strain ratio across its mode, their deps_q fields, the band profile and verdict of the
    whole test (profile_of), and the onset and persistence (band_detector.onset_persistence). log(row) is called
    for each increment. Raises ValueError (naming the steps) on an empty bin or slab."""
    from . import band_detector as bd
    table = mode_table(G)
    snaps = same_cell_kind(snaps)
    rows, fields = [], []
    pairs = [(snaps[0], snaps[-1])] if whole else list(zip(snaps[:-1], snaps[1:]))
    for (step_a, id_a, x_a, L_a, _), (step_b, id_b, x_b, L_b, _) in pairs:
        try:
            deps, ia, s_a, u = increment_field(id_a, x_a, L_a, id_b, x_b, L_b, G)
        except ValueError as e:
            raise ValueError(f"steps {step_a}-{step_b}: {e} (G = {G}): use a smaller --grid") from None
        stats, q = increment_stats(deps, L_a, L_b, table, particles=(s_a, u))
        hkl = (stats["mode_h"], stats["mode_k"], stats["mode_l"])
        ratio = math.nan
        if any(hkl):
            try:
                q_slab = strain_invariants(slab_strain(id_a, x_a, L_a, id_b, x_b, L_b, hkl, K))[0]
            except ValueError as e:
                raise ValueError(f"steps {step_a}-{step_b}: {e}: use fewer --slabs") from None
            ratio = bd.strain_ratio(q_slab, band_slabs(q_slab))
        stats.update(strain_ratio=ratio, band_detected=int(bool(stats["significant"]) and ratio >= bd.STRAIN_RATIO))
        eps1 = float(np.interp(0.5 * (step_a + step_b), series["step"], series["strain"][:, 0]))
        rows.append(dict(step_a=step_a, step_b=step_b, eps1_mid=eps1, **stats))
        fields.append((q, cell_lengths(mean_cell(L_a, L_b))))  # the maps: reduced axes times the lengths
        if log:
            log(rows[-1])
    same = rows[-1] if (rows[-1]["step_a"], rows[-1]["step_b"]) == (snaps[0][0], snaps[-1][0]) else None
    try:
        band = profile_of(snaps, series, G, K, whole=same)
    except ValueError as e:
        raise ValueError(f"whole test, steps {snaps[0][0]}-{snaps[-1][0]}: {e}") from None
    for r in rows:
        r["banded"] = int(band["banded"])
    return dict(rows=rows, fields=fields, series=series, G=G, N=len(snaps[-1][1]), matched=len(ia), band=band,
                onset=bd.onset_persistence(rows), whole=whole)


END_WINDOW = 0.1      # band_void_ratios: the critical-state window, the last 0.1 of eps_q
VOID_COLUMNS = ["banded", "why", "mode_h", "mode_k", "mode_l", "normal_angle_deg", "onset_step", "onset_eps_q",
                "persistence", "persistent", "eps_q_end", "window_from", "window_snapshots", "window_detected", "e_in",
                "e_out", "e_global", "e_series", "e_in_candidate", "e_out_candidate"]


def eps_q_series(path):
    """(step, eps_q) of a results file's /series (eps_q from the principal strains when the file has no column)."""
    from .results import read_columns
    cols = read_columns(path, ["step", "strain"], optional=["eps_q"])
    if "eps_q" in cols:
        return cols["step"], cols["eps_q"]
    a, b_, c = (cols["strain"][:, k] for k in range(3))
    return cols["step"], math.sqrt(2) / 3 * np.sqrt((a - b_) ** 2 + (b_ - c) ** 2 + (c - a) ** 2)


def end_void_ratios(res, step, eps_q, window=END_WINDOW):
    """The void ratios at the end of a test from its judgement (judge_test's result) and its (step, eps_q) series:
    over the snapshots in the critical-state window (eps_q within `window` of the last snapshot's), the means of the
    void ratio of the band's slabs (e_in), of the other slabs (e_out) and of all (e_global; e_series: the series' e
    there), with the detector's verdict, the band's mode and normal (its angle to axis 1), onset (the first snapshot
    increment that detects the band: its later step, and eps_q at its midpoint) and persistence, and window_detected:
    the part of the increments in the window (their midpoint's eps_q) that detect a band in the file's mode. e_in and
    e_out are NaN when the file is not banded (the candidate mode's slabs are no band); e_in_candidate and
    e_out_candidate are the same means for the candidate mode's slabs whatever the verdict (to be read only with
    it); all are NaN without a band profile (no radii)."""
    b = res["band"]
    rows = res["rows"]
    k0, frac, persistent = res["onset"]
    out = dict(banded=int(bool(b["banded"])), why="; ".join(b.get("why", [])), mode_h=b["hkl"][0], mode_k=b["hkl"][1],
               mode_l=b["hkl"][2], normal_angle_deg=b["angle"], onset_step=rows[k0]["step_b"] if k0 is not None else -1,
               onset_eps_q=float(np.interp(0.5 * (rows[k0]["step_a"] + rows[k0]["step_b"]), step, eps_q))
               if k0 is not None else math.nan,
               persistence=frac, persistent=int(bool(persistent)), eps_q_end=math.nan, window_from=math.nan,
               window_snapshots=0, window_detected=math.nan, e_in=math.nan, e_out=math.nan, e_global=math.nan,
               e_series=math.nan, e_in_candidate=math.nan, e_out_candidate=math.nan)
    if b["rows"] is None:
        return out
    q = np.interp([r["step"] for r in b["rows"]], step, eps_q)
    keep = q >= q[-1] - window
    sel = [r for r, k in zip(b["rows"], keep) if k]
    mid = np.interp([0.5 * (r["step_a"] + r["step_b"]) for r in rows], step, eps_q)
    late = [r for r, m in zip(rows, mid) if m >= q[keep][0]]
    same = [r["band_detected"] and tuple(r[c] for c in ("mode_h", "mode_k", "mode_l")) == tuple(b["hkl"]) for r in late]
    out.update(eps_q_end=float(q[-1]), window_from=float(q[keep][0]), window_snapshots=len(sel),
               window_detected=float(np.mean(same)) if same else math.nan,
               e_global=float(np.mean([r["e_whole"] for r in sel])),
               e_series=float(np.mean([r["e_series"] for r in sel])),
               e_in_candidate=float(np.mean([r["e_band"] for r in sel])),
               e_out_candidate=float(np.mean([r["e_outside"] for r in sel])))
    if b["banded"]:
        out.update(e_in=out["e_in_candidate"], e_out=out["e_out_candidate"])
    return out


def band_void_ratios(path, G=None, K=SLABS, window=END_WINDOW):
    """For a results file: the band detector's verdict (analyse, every snapshot increment) and, over its last
    snapshots (the critical-state window: the last `window` of eps_q), the void ratio inside the band's slabs, outside
    them and of the whole cell, with the band's mode (end_void_ratios' dict). Exits as analyse does on bad input."""
    res = analyse(path, G, False, K)
    step, eps_q = eps_q_series(path)
    return end_void_ratios(res, step, eps_q, window)


def band_summary(b):
    """The band's and the outside's figures of a band profile: e first and last, mean deps_q and deps_v, the
    volumetric strain of their change of e, -ln((1 + e_last) / (1 + e_first)) (the slabs keep V_cell / K), and the
    band's share of the summed slab deps_q."""
    first, last = b["rows"][0], b["rows"][-1]
    out = {}
    for key, mask in (("band", b["band"]), ("outside", ~b["band"])):
        e0, e1 = first[f"e_{key}"], last[f"e_{key}"]
        out[key] = dict(e0=e0, e1=e1, q=float(b["deps_q"][mask].mean()) if mask.any() else math.nan,
                        v=float(b["deps_v"][mask].mean()) if mask.any() else math.nan,
                        v_e=-math.log((1.0 + e1) / (1.0 + e0)) if mask.any() else math.nan)
    out["share"] = float(b["deps_q"][b["band"]].sum() / b["deps_q"].sum())
    return out


def mode_str(hkl):
    return "(" + ",".join(str(int(c)) for c in hkl) + ")"


def slab_list(mask):
    return ",".join(str(j) for j in np.flatnonzero(mask))


def verdict_text(b):
    """The file's verdict in one phrase: "banded (...)" or "no band: <reasons>"."""
    from . import band_detector as bd
    j = b["judged"]
    if not any(b["hkl"]):
        return b["note"]
    tests = (f"mode {mode_str(b['hkl'])} share {j['share']:.3f} against the surrogates' {bd.QUANTILE:g} quantile "
             f"{max(j['threshold_noise'], j['threshold_gauss']):.3f} (particle noise {j['threshold_noise']:.3f}, "
             f"correlated Gaussian {j['threshold_gauss']:.3f}, ell {j['ell'] * 1e3:.2f} mm, fraction {j['nu']:.2f}); "
             f"band/outside deps_q {b['ratio']:.2f} (largest of the {len(b.get('ratios', []))} increments across this "
             f"mode; whole test {b.get('ratio_whole', math.nan):.2f}; >= {bd.STRAIN_RATIO:g}); void-ratio contrast "
             f"growth {b['growth']:+.4f} (noise {b['noise']:.4f}; >= {bd.VOID_CONTRAST:g} and {bd.NOISE_SIGMAS:g} x "
             "noise)")
    return ("banded: " if b["banded"] else "no band: " + "; ".join(b["why"]) + ". Whole test: ") + tests


def band_line(b):
    if b["rows"] is None:
        return b["note"]
    s = band_summary(b)
    return (f"{verdict_text(b)}. Profile: whole-test mode {mode_str(b['hkl'])} share {b['share']:.3f} (shuffled "
            f"{b['shuffled']:.3f}), {b['K']} slabs, band slab(s) {slab_list(b['band'])}: e_band "
            f"{s['band']['e0']:.4f} -> "
            f"{s['band']['e1']:.4f} ({s['band']['e1'] - s['band']['e0']:+.4f}), e_outside {s['outside']['e0']:.4f} "
            f"-> {s['outside']['e1']:.4f} ({s['outside']['e1'] - s['outside']['e0']:+.4f}); band share of the "
            f"slabs' deps_q {s['share']:.3f}")


def write_band_csv(path, b):
    """One row per snapshot: step, eps_1, e of the band's slabs, of the outside, of all slabs, of each slab."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["step", "eps_1", "e_band", "e_outside", "e_whole"] + [f"e_{j}" for j in range(b["K"])])
    for r in b["rows"]:
        w.writerow([r["step"]] + [f"{v:.10g}" for v in (r["eps_1"], r["e_band"], r["e_outside"], r["e_whole"])]
                   + [f"{v:.10g}" for v in r["e_slab"]])
    write_text(path, buf.getvalue())


def write_void_csv(path, v):
    """end_void_ratios' dict as a one-row CSV (VOID_COLUMNS)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(VOID_COLUMNS)
    w.writerow([f"{v[c]:.6g}" if isinstance(v[c], float) else v[c] for c in VOID_COLUMNS])
    write_text(path, buf.getvalue())


def write_csv(path, rows):
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(COLUMNS)
    for r in rows:
        w.writerow([f"{r[c]:.6g}" if isinstance(r[c], float) else r[c] for c in COLUMNS])
    write_text(path, buf.getvalue())


def write_summary(path, src, res):
    rows, G = res["rows"], res["G"]
    best = max(range(len(rows)), key=lambda k: np.nan_to_num(rows[k]["mode_share"], nan=-1.0))
    b = rows[best]
    lines = [f"# Strain localization: {os.path.basename(src)}", "",
             f"{res['N']} particles ({res['matched']} matched by id), {G}^3 bins (~{res['N'] / G ** 3:.0f} "
             f"particles a bin), {len(rows)} increments.", "",
             "Uniform field: CV ~ 0 (plus the sampling noise of the bins), top-10 % share 0.10, mode share "
             "close to the shuffled one. A band: the top-10 % share well above 0.10 and one mode far above "
             "the shuffled share; the band normal is at the given angle to axis 1.", "",
             f"Largest mode share: {b['mode_share']:.3f} (shuffled {b['shuffled_share']:.3f}), mode "
             f"({b['mode_h']},{b['mode_k']},{b['mode_l']}), normal {b['normal_angle_deg']:.1f} deg to axis 1, "
             f"in steps {b['step_a']}-{b['step_b']} (eps_1 = {b['eps1_mid']:.4f}).", "",
             "| steps | eps_1 | deps_q macro | deps_q local mean | CV | top-10 % | mode | share | shuffled | "
             "normal to axis 1 (deg) |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['step_a']}-{r['step_b']} | {r['eps1_mid']:.4f} | {r['deps_q_macro']:.3e} | "
                     f"{r['deps_q_mean']:.3e} | {r['deps_q_cv']:.3f} | {r['top10_share']:.3f} | "
                     f"({r['mode_h']},{r['mode_k']},{r['mode_l']}) | {r['mode_share']:.3f} | "
                     f"{r['shuffled_share']:.3f} | {r['normal_angle_deg']:.1f} |")
    write_text(path, "\n".join(lines + [""] + onset_section(res) + band_section(res["band"])) + "\n")
    return best


def onset_section(res):
    """The summary's "Onset" section: per increment, band detected or not, and the onset and persistence."""
    from . import band_detector as bd
    rows = res["rows"]
    k0, frac, persistent = res["onset"]
    lines = ["## Band detector per increment", "",
             f"An increment's band is detected when its strongest mode's share is above the {bd.QUANTILE:g} quantile "
             f"of {bd.N_SURROGATES} homogeneous surrogates of each kind (particle noise; correlated Gaussian of the "
             f"fitted correlation length) and the slabs across that mode carry >= {bd.STRAIN_RATIO:g} times the "
             "outside's deps_q in the band.", "",
             "| steps | eps_1 | mode | share | surrogates (noise / Gaussian) | ell (mm) | band/outside deps_q | "
             "detected |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['step_a']}-{r['step_b']} | {r['eps1_mid']:.4f} | ({r['mode_h']},{r['mode_k']},"
                     f"{r['mode_l']}) | {r['mode_share']:.3f} | {r['threshold_noise']:.3f} / "
                     f"{r['threshold_gauss']:.3f} | {r['corr_length'] * 1e3:.2f} | {r['strain_ratio']:.2f} | "
                     f"{'yes' if r['band_detected'] else 'no'} |")
    if res.get("whole"):
        lines += ["", "--whole: one increment, the whole test (the file's verdict, below, takes the strain criterion "
                  "from the snapshot increments); the onset and persistence need those increments: run without "
                  "--whole."]
    elif k0 is None:
        lines += ["", "Onset: none (no increment detects a band)."]
    else:
        r = rows[k0]
        lines += ["", f"Onset: steps {r['step_a']}-{r['step_b']} (eps_1 = {r['eps1_mid']:.4f} at the midpoint), mode "
                  f"({r['mode_h']},{r['mode_k']},{r['mode_l']}); detected again in the same mode in "
                  + ("no later increment (the last one)" if math.isnan(frac) else
                     f"{frac:.0%} of the later increments: {'persistent' if persistent else 'not persistent'} "
                     f"(>= {bd.PERSISTENCE:.0%})") + "."]
    return lines + [""]


def band_section(b):
    """The summary's "Band profile" section."""
    lines = ["## Band profile", ""]
    if b["rows"] is None:
        return lines + [b["note"][0].upper() + b["note"][1:] + "; the band profile is skipped."]
    s, rows, K = band_summary(b), b["rows"], b["K"]
    first, last = rows[0], rows[-1]
    v = verdict_text(b)
    lines += [v[0].upper() + v[1:] + ". (Band detector: apps/analysis/sandcell_analysis/band_detector.py; banded "
              "only when the mode beats both kinds of homogeneous surrogates and the strain and void-ratio criteria "
              "hold.)" + ("" if b["banded"] else " The profile below is the candidate mode's."), ""]
    lines += [f"Mode {mode_str(b['hkl'])} of the whole test (steps {b['steps'][0]}-{b['steps'][1]}): "
              f"share {b['share']:.3f} against {b['shuffled']:.3f} shuffled, normal {b['angle']:.1f} deg to axis 1. "
              f"{K} slabs of equal xi across it, each 1/{K} of the cell at every snapshot, "
              f"{first['d'] / K * 1e3:.2f} -> {last['d'] / K * 1e3:.2f} mm thick (plane spacing d = "
              f"{first['d'] * 1e3:.2f} -> {last['d'] * 1e3:.2f} mm). Band slab(s): {slab_list(b['band'])} (whole-test "
              "deps_q above the mean by more than half the way to the largest).", "",
              "| slab | xi | deps_q | deps_v | e first | e last | change | |", "|---|---|---|---|---|---|---|---|"]
    for j in range(K):
        lines.append(f"| {j} | {j / K:.2f}-{(j + 1) / K:.2f} | {b['deps_q'][j]:.4f} | {b['deps_v'][j]:+.4f} | "
                     f"{first['e_slab'][j]:.4f} | {last['e_slab'][j]:.4f} | "
                     f"{last['e_slab'][j] - first['e_slab'][j]:+.4f} | {'band' if b['band'][j] else ''} |")
    lines += ["", "deps_q, deps_v: the whole test's local strain of the slab from the particles' displacement "
              "(compression positive); e: the void ratio of the slab from its exact solid volume, first and last "
              f"snapshot (steps {first['step']} and {last['step']}, eps_1 = {first['eps_1']:.4f} and "
              f"{last['eps_1']:.4f}).", "",
              "| | slabs | e first | e last | change | mean deps_q | mean deps_v | -ln((1+e last)/(1+e first)) |",
              "|---|---|---|---|---|---|---|---|"]
    for key in ("band", "outside"):
        t = s[key]
        lines.append(f"| {key} | {slab_list(b['band'] if key == 'band' else ~b['band']) or '-'} | {t['e0']:.4f} | "
                     f"{t['e1']:.4f} | {t['e1'] - t['e0']:+.4f} | {t['q']:.4f} | {t['v']:+.4f} | {t['v_e']:+.4f} |")
    diff = [abs(r["e_whole"] - r["e_series"]) for r in rows]
    exact = all(r["series_row"] for r in rows)
    lines += ["", f"The band's slabs carry {s['share']:.3f} of the summed slab deps_q ({b['band'].sum()} of {K} "
              "slabs). The last column is the volumetric strain (compression positive) that the change of e means "
              "for slabs that keep their share of the cell; it differs from the mean deps_v by the particles "
              "crossing the slabs' planes and by the central differences' smoothing.", "",
              f"All slabs together: e {first['e_whole']:.4f} -> {last['e_whole']:.4f}; the series' e (the app's "
              f"V_cell / V_s - 1) at the same steps{'' if exact else ' (interpolated between its rows)'} differs by "
              f"{np.nanmax(diff) if not all(map(math.isnan, diff)) else math.nan:.2e} at most."]
    return lines


def int_at_least(low, what):
    """An argparse type: an integer >= low, else an error saying what the number counts."""
    def parse(v):
        try:
            k = int(v)
        except ValueError:
            k = None
        if k is None or k < low:
            raise argparse.ArgumentTypeError(f"must be an integer >= {low} ({what}), got {v!r}")
        return k
    return parse


grid_arg = int_at_least(3, "bins along each cell edge")


slabs_arg = int_at_least(4, "slabs across the band's period")


def main(argv=None):
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="\n\n".join(__doc__.split("\n\n")[2:]))
    ap.add_argument("results", nargs="+", help="shearing results files (<test>.h5) with >= 2 snapshots")
    ap.add_argument("--out", default=None, help="output folder (default: next to each input)")
    ap.add_argument("--grid", type=grid_arg, default=None,
                    help="bins along each cell edge, >= 3 (default: ~40 particles a bin)")
    ap.add_argument("--whole", action="store_true",
                    help="one increment, from the first snapshot to the last (the whole test)")
    ap.add_argument("--slabs", type=slabs_arg, default=SLABS,
                    help=f"slabs across the band's period for its profile, >= 4 (default {SLABS})")
    ap.add_argument("--void-ratios", action="store_true",
                    help=f"also the void ratio inside and outside the band and of the whole cell over the last "
                    f"{END_WINDOW:g} of eps_q (the critical-state window): <test>-localization-void.csv, one row")
    args = ap.parse_args(argv)
    try:
        return run(args)
    except InputError as e:  # the reader's one-line error (results.py): exit 2
        fail(str(e))


def run(args):
    """The command's work once its arguments are parsed (main)."""
    try:
        import h5py  # noqa: F401 (checked here: used where the files are read and drawn)
        import matplotlib  # noqa: F401
    except ImportError as e:
        fail(f"needs python3 with numpy, matplotlib and h5py ({e})", 1)
    from . import plots
    outputs = {}
    for src in args.results:
        if not os.path.isfile(src):
            fail(f"{src}: no such file")
        stem = os.path.splitext(os.path.basename(src))[0] + "-localization"
        prefix = os.path.join(args.out or os.path.dirname(os.path.abspath(src)), stem)
        if prefix in outputs.values():
            fail(f"{src}: its outputs {prefix}.* would overwrite another input's: give the files one at a time "
                 "with different --out folders")
        outputs[src] = prefix
        with open_results(src) as f:  # every input checked before anything is written
            read_series(f, src)
            snapshot_names(f, src)
    if args.out:
        try:
            os.makedirs(args.out, exist_ok=True)
        except OSError as e:
            fail(f"--out {args.out}: cannot create the folder ({e.strerror})")
    for src, prefix in outputs.items():
        res = analyse(src, args.grid, args.whole, args.slabs)
        write_csv(prefix + ".csv", res["rows"])
        if res["band"]["rows"] is not None and res["band"]["banded"]:
            write_band_csv(prefix + "-band.csv", res["band"])
        elif os.path.exists(prefix + "-band.csv"):
            os.remove(prefix + "-band.csv")  # an earlier run's profile: this one found no band
        best = write_summary(prefix + ".md", src, res)
        if getattr(args, "void_ratios", False):
            v = end_void_ratios(res, *eps_q_series(src))
            write_void_csv(prefix + "-void.csv", v)
            print(f"{PROG}: {os.path.basename(src)}: end window (eps_q {v['window_from']:.3f}-{v['eps_q_end']:.3f}, "
                  f"{v['window_snapshots']} snapshots): {'banded' if v['banded'] else 'no band'}, mode "
                  f"({v['mode_h']},{v['mode_k']},{v['mode_l']}), e_in {v['e_in']:.4f}, e_out {v['e_out']:.4f}, "
                  f"e_global {v['e_global']:.4f}", flush=True)
        plots.localization_figure(prefix + ".png", src, res, best)
        print(f"{PROG}: wrote {prefix}.md (+ csv, {'band csv, ' if res['band']['banded'] else ''}png)")
    return 0
