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
     (b) correlated Gaussian: a Gaussian random field on the grid whose spectrum is the particle noise's
         (the mean spectrum of the (a) surrogates) plus a correlated part of exponential covariance
         exp(-r / ell); the correlated fraction nu and the correlation length ell are fitted to the test's
         own field by maximum likelihood (each Fourier coefficient's power exponential about the model),
         the candidate mode and its harmonics left out of the fit so that a band does not make its own null.
   The threshold is the QUANTILE-th quantile of S over N_SURROGATES of each kind, the larger of the two;
   S above it is significant. A homogeneous field is thus flagged with probability ~1 - QUANTILE whatever
   the number of particles and the grid: the false-positive rate is set by construction, not by N.
2. Physically, across the candidate mode (K slabs of equal xi, localization.slab_strain and the exact
   slab void ratios of localization.band_profile), the band slabs being those of localization.band_slabs:
     - strain: the band slabs' mean deps_q at least STRAIN_RATIO times the outside's;
     - void ratio (whole test only, it builds up over the test): the band's void ratio minus the outside's
       grows from the first snapshot to the last by at least VOID_CONTRAST and by at least NOISE_SIGMAS
       times its sampling noise, sigma_slab sqrt(2 (1/n_band + 1/n_out)), sigma_slab the scatter of the
       slabs' void ratios at the first snapshot (a homogeneous sample: the packing's own noise at this N).

The constants were fixed before the detector was run on any campaign file:
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
NUS = np.linspace(0.0, 1.0, 41)  # correlated fractions tried


def mode_family(hkl, G):
    """Flat FFT indices of the mode +-(h, k, l) and its harmonics m (h, k, l) on a G-grid (the zero bin left out)."""
    idx = {np.ravel_multi_index(tuple(m * c % G for c in hkl), (G, G, G)) for m in range(-G, G + 1)}
    idx.discard(0)
    return np.array(sorted(idx), dtype=np.int64)


def wavenumbers2(G, L):
    """|k|^2 (rad^2 / m^2) of every bin of a G-grid over a cell of edges L (fftn's order, flat)."""
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
    rms per component, binned as the test; and their mean power spectrum (the particle noise's)."""
    from .localization import binned_strain, strain_invariants
    sigma = u.std(axis=0)
    fields = np.empty((n, G, G, G))
    for i in range(n):
        fields[i] = strain_invariants(binned_strain(s_a, sigma * rng.standard_normal(u.shape), L_a, L_b, G))[0]
    return shares_of(fields, table)


def fit_correlation(q, L, noise_power, exclude):
    """Maximum-likelihood (nu, ell) of the model spectrum (1 - nu) noise + nu (1 + k^2 ell^2)^-2 (both normalized over
    the bins fitted) to the field q's Fourier powers, the zero bin and `exclude` left out; and the model's spectrum
    over every bin (0 at k = 0): the surrogates' (b) spectrum."""
    G = q.shape[0]
    power = np.abs(np.fft.fftn(q - q.mean())).ravel() ** 2
    keep = np.ones(G ** 3, bool)
    keep[0] = False
    keep[exclude] = False
    k2 = wavenumbers2(G, L)
    noise = np.maximum(noise_power, 1e-300)
    noise = noise / noise[keep].sum()
    best = (math.inf, 0.0, math.nan, None)
    for ell in np.geomspace(ELL_RANGE[0] * min(L), ELL_RANGE[1] * max(L), ELLS):
        g = (1.0 + k2 * ell * ell) ** -2
        g /= g[keep].sum()
        for nu in NUS:
            shape = (1.0 - nu) * noise + nu * g
            sk = shape[keep]
            scale = np.mean(power[keep] / sk)
            nll = np.log(sk).sum() + keep.sum() * math.log(max(scale, 1e-300))
            if nll < best[0]:
                best = (nll, float(nu), float(ell), shape)
    _, nu, ell, shape = best
    model = shape.copy()
    model[0] = 0.0
    return nu, ell, model


def gaussian_surrogates(model, G, table, n, rng):
    """S of n surrogates (b): Gaussian random fields on the G-grid with the model spectrum (flat, fftn order)."""
    amp = np.sqrt(model).reshape(G, G, G)
    white = rng.standard_normal((n, G, G, G))
    fields = np.fft.ifftn(np.fft.fftn(white, axes=(1, 2, 3)) * amp, axes=(1, 2, 3)).real
    return shares_of(fields, table)[0]


def judge_field(q, s_a, u, L_a, L_b, table, n=N_SURROGATES, seed=SEED):
    """The statistical test of one local deps_q field q [G, G, G] (localization.local_strain's invariant), from the
    particles' fractional coordinates s_a and non-affine displacements u: a dict with the strongest mode (hkl) and its
    share, the (a) and (b) thresholds, the fitted correlation length ell (m) and fraction nu, and significant."""
    from .localization import strongest_mode
    G = q.shape[0]
    hkl, share = strongest_mode(q, table)
    out = dict(hkl=hkl, share=share, threshold_noise=math.nan, threshold_gauss=math.nan, ell=math.nan, nu=math.nan,
               significant=False)
    if not any(hkl):
        return out
    rng = np.random.default_rng(seed)
    L = 0.5 * (np.asarray(L_a, float) + np.asarray(L_b, float))
    s_noise, noise_power = noise_surrogates(s_a, u, np.asarray(L_a, float), np.asarray(L_b, float), G, table, n, rng)
    nu, ell, model = fit_correlation(q, L, noise_power, mode_family(hkl, G))
    s_gauss = gaussian_surrogates(model, G, table, n, rng)
    t_noise = float(np.nanquantile(s_noise, QUANTILE)) if np.isfinite(s_noise).any() else 0.0
    t_gauss = float(np.nanquantile(s_gauss, QUANTILE))
    out.update(threshold_noise=t_noise, threshold_gauss=t_gauss, ell=ell, nu=nu,
               significant=bool(share > max(t_noise, t_gauss)))
    return out


def strain_ratio(q_slabs, band):
    """The band slabs' mean deps_q over the outside's (inf when the outside has none)."""
    inside, outside = float(q_slabs[band].mean()), float(q_slabs[~band].mean()) if (~band).any() else 0.0
    return inside / outside if outside > 0 else math.inf


def void_contrast(e_first, e_last, band):
    """(the growth of e_band - e_outside from the first snapshot to the last, its sampling noise) from the slabs'
    void ratios; the noise from the scatter of the slabs at the first snapshot."""
    nb, no = int(band.sum()), int((~band).sum())
    if nb == 0 or no == 0:
        return math.nan, math.nan
    growth = (e_last[band].mean() - e_last[~band].mean()) - (e_first[band].mean() - e_first[~band].mean())
    sigma = float(np.std(e_first, ddof=1))
    return float(growth), sigma * math.sqrt(2.0 * (1.0 / nb + 1.0 / no))


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
