"""The band detector of `triaxial localization` (issue 45): is a local strain field banded?

A field is judged twice, and called banded only when both say so.

1. Statistically, against homogeneous surrogates at the same grid. The statistic S is the one the
   localization report always gave: the strongest planar mode's share of the variance of the local deps_q
   field (modes (h, k, l) in [-2, 2]^3, localization.strongest_mode). Its null distribution is sampled on
   fields that are homogeneous by construction, built on the test's own particles, grid and cell:
     (a) affine + particle noise: the test's affine increment plus an independent Gaussian displacement
         per particle with the test's own non-affine rms (per component), through the same binning and
         central differences. This is the sampling noise of the bins with its true spatial structure (the
         differences couple bins two apart), which shuffling the bins destroyed.
     (b) correlated Gaussian: bin-mean displacement fields drawn as the particle noise (its level from the
         scatter of the displacements within the bins) plus a spatially correlated Gaussian field, through the
         same differences and invariant. The correlated part's power and covariance length ell (Gaussian or
         exponential covariance, whichever fits better) are fitted to the test's own bin means by maximum
         likelihood (each Fourier coefficient's power exponential about the model), the candidate mode and its
         harmonics left out of the fit so that a band does not make its own null.
   The threshold is the QUANTILE-th quantile of S over N_SURROGATES of each kind, the larger of the two;
   S above it is significant. A homogeneous field is thus flagged with probability ~1 - QUANTILE whatever
   the number of particles and the grid: the false-positive rate is set by construction, not by N.
2. Physically, across the candidate mode (K slabs of equal xi, localization.slab_strain and the exact
   slab void ratios of localization.profile_of), the band slabs being those of localization.band_slabs:
     - strain: the band slabs' mean deps_q increment at least STRAIN_RATIO times the outside's, in at least
       one snapshot-to-snapshot increment (the whole test from its first snapshot averages the deformation
       before the band formed into the band's and the outside's alike);
     - void ratio (whole test only, it builds up over the test): the band's void ratio minus the outside's
       grows from the first snapshot to the last by at least VOID_CONTRAST and by at least NOISE_SIGMAS
       times its sampling noise: the (robust) scatter of the outside slabs' own growth of e through the two
       means (void_contrast; the slabs are material slabs, so the packing's scatter at the first snapshot stays
       in them and cancels in the growth).

The constants were fixed before the detector was run on any campaign file (the parts of the method changed
after that, the constants kept, are listed in experiments/2026-11-28-band-detector/README.md):
  QUANTILE = 0.99: a 1 % false-positive rate for the statistic alone, per field judged.
  STRAIN_RATIO = 2: a shear band is where the shear concentrates; in a band the strain is several times the
    outside's, while a diffuse field's slabs (each a tenth of the cell, averaged over its planes) differ by
    a few tens of percent. Twice the outside lies between the two.
  VOID_CONTRAST = 0.01: a band dilates to its critical state while the outside stays near its peak state;
    the study's dense samples (psi_0 ~ -0.2) dilate by ~0.1-0.2 in e on the way, and a contrast below a
    tenth of that (0.01) is within what the slab scatter of a 20,000-sphere packing allows.
  NOISE_SIGMAS = 3: the contrast clear of the packing's noise at the sample's own size.
Onset and persistence (localization, per increment): an increment's band is detected when its S is
significant and its slab strain ratio across that mode is >= STRAIN_RATIO; the onset is the first such
increment; the band persists when at least PERSISTENCE of the later increments detect it again in the same
mode (+-(h, k, l)).
"""
import math

import numpy as np

QUANTILE = 0.99
N_SURROGATES = 200      # per kind and per field: the 0.99 quantile lies between the 2nd and 3rd largest
STRAIN_RATIO = 2.0
VOID_CONTRAST = 0.01
NOISE_SIGMAS = 3.0
PERSISTENCE = 0.5
SEED = 4501             # the surrogates' seed (fixed: a rerun gives the same thresholds)
ELLS = 40               # correlation lengths tried, log-spaced from ELL_RANGE[0] min(L) to ELL_RANGE[1] max(L)
ELL_RANGE = (0.01, 2.0)


def mode_family(hkl, G):
    """Flat FFT indices of the mode +-(h, k, l) and its harmonics m (h, k, l) on a G-grid (the zero bin left out)."""
    idx = {np.ravel_multi_index(tuple(m * c % G for c in hkl), (G, G, G)) for m in range(-G, G + 1)}
    idx.discard(0)
    return np.array(sorted(idx), dtype=np.int64)


def wavenumbers2(G, L):
    """|k|^2 (rad^2 / m^2) of every bin of a G-grid over a cell of edges L (fftn's order, flat). A sheared cell C
    (localization's cell matrix): the grid is over the reduced coordinates, and the integer mode m has the wave vector
    k = 2 pi C^-T m."""
    from .localization import orthorhombic, reciprocal
    if not orthorhombic(L):
        m = np.stack(np.meshgrid(*[np.fft.fftfreq(G, 1.0 / G)] * 3, indexing="ij"), -1).reshape(-1, 3)
        return np.sum((2.0 * np.pi * m @ reciprocal(L).T) ** 2, axis=1)
    k = [2.0 * np.pi * np.fft.fftfreq(G, 1.0 / G) / L[m] for m in range(3)]
    return (k[0][:, None, None] ** 2 + k[1][None, :, None] ** 2 + k[2][None, None, :] ** 2).ravel()


def shares_of(fields, table):
    """The strongest mode's share of each field [n, G, G, G] (NaN where a field is uniform), and their mean power
    spectrum (flat)."""
    f = fields - fields.mean(axis=(1, 2, 3), keepdims=True)
    power = (np.abs(np.fft.fftn(f, axes=(1, 2, 3))) ** 2).reshape(len(f), -1)
    total = power.sum(axis=1)
    modes = np.stack([power[:, idx].sum(axis=1) for _, idx in table], 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        share = modes.max(axis=1) / total
    share[total <= 0] = math.nan
    return share, power.mean(axis=0)


def noise_surrogates(s_a, u, L_a, L_b, G, table, n, rng):
    """S of n surrogates (a): the affine increment plus independent Gaussian particle displacements of the test's
    rms per component, binned as the test; and their mean power spectrum (the particle noise's). The mean of c
    independent Gaussians of standard deviation sigma is Gaussian of sigma / sqrt(c): the bin means are drawn so,
    exactly as binning the particles' draws would give them, at the cost of the grid instead of the particles."""
    from .localization import bin_counts, strain_of_means, strain_invariants
    sigma = u.std(axis=0)
    _, count = bin_counts(s_a, G)
    U = sigma * rng.standard_normal((n, G, G, G, 3)) / np.sqrt(count).reshape(G, G, G, 1)
    return shares_of(strain_invariants(strain_of_means(U, L_a, L_b))[0], table)


def chunks(n, per_item, budget=2_000_000):
    """Batch sizes summing to n, each batch at most ~budget values of per_item each (memory)."""
    per = max(1, budget // per_item)
    return [min(per, n - i) for i in range(0, n, per)]


def covariance_spectrum(k2, ell, shape):
    """The spectrum (up to a factor) of an isotropic covariance of length ell: "gaussian" exp(-r^2 / 2 ell^2) or
    "exponential" exp(-r / ell)."""
    if shape == "gaussian":
        return np.exp(-0.5 * k2 * ell * ell)
    return (1.0 + k2 * ell * ell) ** -2


def fit_correlation(s_a, u, L, G, exclude):
    """The test's non-affine displacement field as the bin means see it: independent particle noise (its level known
    from the scatter of u within the bins) plus a spatially correlated Gaussian part of covariance length ell. The
    correlated part's power c, its length ell and its covariance shape (Gaussian or exponential) are the maximum-
    likelihood fit to the Fourier powers of the bin means (each exponential about the model), the zero bin and
    `exclude` (the candidate mode's family) left out. Returns a dict: ell (m), shape, fraction (the correlated part's
    share of the bin means' variance in the model), sigma_bin [G^3, 3] (the noise of each bin mean) and spectrum
    (flat, fftn order: E|fft|^2 of one component's correlated part)."""
    from .localization import bin_counts, cell_lengths
    flat, count = bin_counts(s_a, G)
    mean = np.stack([np.bincount(flat, u[:, c], G ** 3) / count for c in range(3)], -1)
    within = np.stack([np.bincount(flat, (u[:, c] - mean[flat, c]) ** 2, G ** 3) for c in range(3)], -1)
    var = within.sum(axis=0) / max(len(u) - G ** 3, 1)  # pooled within-bin variance per component
    sigma_bin = np.sqrt(var[None, :] / count[:, None])
    power = sum(np.abs(np.fft.fftn((mean[:, c] - mean[:, c].mean()).reshape(G, G, G))).ravel() ** 2 for c in range(3))
    # E|fft|^2 of the noise, summed over components (a floor for displacements without scatter in their bins)
    white = max(G ** 3 * float((sigma_bin ** 2).mean(axis=0).sum()), 1e-300)
    keep = np.ones(G ** 3, bool)
    keep[0] = False
    keep[exclude] = False
    k2 = wavenumbers2(G, L)
    pk = power[keep]
    best = (math.inf, 0.0, math.nan, "none")
    scales = np.concatenate([[0.0], white * np.geomspace(1e-4, 1e6, 81)])
    for shape in ("gaussian", "exponential"):
        for ell in np.geomspace(ELL_RANGE[0] * min(cell_lengths(L)), ELL_RANGE[1] * max(cell_lengths(L)), ELLS):
            g = covariance_spectrum(k2[keep], ell, shape)
            g /= g.mean()
            model = white + scales[:, None] * g[None, :]
            nll = (np.log(model) + pk / model).sum(axis=1)
            m = int(np.argmin(nll))
            if nll[m] < best[0]:
                best = (float(nll[m]), float(scales[m]), float(ell), shape)
    _, c, ell, shape = best
    g = covariance_spectrum(k2, ell, shape)
    g /= g[keep].mean()
    spectrum = c * g / 3.0
    spectrum[0] = 0.0
    corr_var = spectrum.sum() * 3.0 / G ** 6
    noise_var = white / G ** 3  # the particle noise's variance of the bin means, summed over components
    return dict(ell=ell if c > 0 else 0.0, shape=shape, fraction=float(corr_var / (corr_var + noise_var))
                if corr_var + noise_var > 0 else 0.0, sigma_bin=sigma_bin, spectrum=spectrum)


def gaussian_surrogates(fit, L_a, L_b, G, table, n, rng):
    """S of n surrogates (b): bin-mean displacements drawn as the fit's particle noise (per bin) plus its correlated
    Gaussian field, through the test's differences and invariant."""
    from .localization import strain_of_means, strain_invariants
    amp = np.sqrt(fit["spectrum"] / G ** 3).reshape(G, G, G, 1)
    shares = []
    for m in chunks(n, G ** 3):
        white = rng.standard_normal((m, G, G, G, 3))
        corr = np.fft.ifftn(np.fft.fftn(white, axes=(1, 2, 3)) * amp, axes=(1, 2, 3)).real
        U = corr + fit["sigma_bin"].reshape(G, G, G, 3) * rng.standard_normal((m, G, G, G, 3))
        shares.append(shares_of(strain_invariants(strain_of_means(U, L_a, L_b))[0], table)[0])
    return np.concatenate(shares)


def judge_field(q, s_a, u, L_a, L_b, table, n=N_SURROGATES, seed=SEED):
    """The statistical test of one local deps_q field q [G, G, G] (localization.local_strain's invariant), from the
    particles' fractional coordinates s_a and non-affine displacements u: a dict with the strongest mode (hkl) and its
    share, the (a) and (b) thresholds, the fitted correlation length ell (m), shape and correlated fraction nu, and
    significant."""
    from .localization import mean_cell, strongest_mode
    G = q.shape[0]
    hkl, share = strongest_mode(q, table)
    out = dict(hkl=hkl, share=share, threshold_noise=math.nan, threshold_gauss=math.nan, ell=math.nan, nu=math.nan,
               shape="", significant=False)
    if not any(hkl):
        return out
    rng = np.random.default_rng(seed)
    L_a, L_b = np.asarray(L_a, float), np.asarray(L_b, float)
    s_noise, _ = noise_surrogates(s_a, u, L_a, L_b, G, table, n, rng)
    fit = fit_correlation(s_a, u, mean_cell(L_a, L_b), G, mode_family(hkl, G))
    s_gauss = gaussian_surrogates(fit, L_a, L_b, G, table, n, rng)
    t_noise = float(np.nanquantile(s_noise, QUANTILE)) if np.isfinite(s_noise).any() else 0.0
    t_gauss = float(np.nanquantile(s_gauss, QUANTILE)) if np.isfinite(s_gauss).any() else 0.0
    out.update(threshold_noise=t_noise, threshold_gauss=t_gauss, ell=fit["ell"], nu=fit["fraction"],
               shape=fit["shape"], significant=bool(share > max(t_noise, t_gauss)))
    return out


def strain_ratio(q_slabs, band):
    """The band slabs' mean deps_q over the outside's (inf when the outside has none)."""
    inside, outside = float(q_slabs[band].mean()), float(q_slabs[~band].mean()) if (~band).any() else 0.0
    return inside / outside if outside > 0 else math.inf


def void_contrast(e_first, e_last, band):
    """(the growth of e_band - e_outside from the first snapshot to the last, its sampling noise) from the slabs'
    void ratios. The slabs are material slabs (localization.mode_coordinate), so the packing's own scatter at the
    first snapshot largely stays in them and cancels in the growth; what does not is the slabs' change of e by the
    particles' motion and any diffuse dilation. The noise is that: the scatter of the outside slabs' growth of e,
    sigma_g, through the two means, sigma_g sqrt(1/n_band + 1/n_out). sigma_g is the normal-consistent median
    absolute deviation (1.4826 MAD), so that the band's edge slabs, left outside by band_slabs when the band is
    wider than they, do not count as noise."""
    nb, no = int(band.sum()), int((~band).sum())
    if nb == 0 or no < 2:
        return math.nan, math.nan
    g = np.asarray(e_last, float) - np.asarray(e_first, float)
    growth = g[band].mean() - g[~band].mean()
    out = g[~band]
    sigma = 1.4826 * float(np.median(np.abs(out - np.median(out))))  # robust: the band's edge slabs left outside
    return float(growth), sigma * math.sqrt(1.0 / nb + 1.0 / no)


def verdict(judged, ratio, growth=None, noise=None):
    """(banded, the reasons it is not: a list of short phrases) from the statistical test, the strain ratio and, when
    given, the void-ratio growth and its noise."""
    why = []
    if not any(judged["hkl"]):
        return False, ["the field is uniform to round-off"]
    if not judged["significant"]:
        why.append(f"mode share {judged['share']:.3f} not above the surrogates' {QUANTILE:g} quantile "
                   f"{max(judged['threshold_noise'], judged['threshold_gauss']):.3f}")
    if not ratio >= STRAIN_RATIO:
        why.append(f"band/outside deps_q {ratio:.2f} < {STRAIN_RATIO:g}")
    if growth is not None:
        need = max(VOID_CONTRAST, NOISE_SIGMAS * noise) if math.isfinite(noise) else VOID_CONTRAST
        if not growth >= need:
            why.append(f"void-ratio contrast {growth:+.4f} < {need:.4f} (max of {VOID_CONTRAST:g} and "
                       f"{NOISE_SIGMAS:g} x noise {noise:.4f})")
    return not why, why


def onset_persistence(rows):
    """(index of the first increment whose band is detected or None, the fraction of the later increments that
    detect it again in the same mode or NaN, persistent: bool) from rows with band_detected and mode_h/k/l."""
    hits = [k for k, r in enumerate(rows) if r["band_detected"]]
    if not hits:
        return None, math.nan, False
    k0 = hits[0]
    key = tuple(rows[k0][c] for c in ("mode_h", "mode_k", "mode_l"))
    later = rows[k0 + 1:]
    if not later:
        return k0, math.nan, False
    same = sum(1 for r in later if r["band_detected"] and tuple(r[c] for c in ("mode_h", "mode_k", "mode_l")) == key)
    frac = same / len(later)
    return k0, frac, frac >= PERSISTENCE
