#!/usr/bin/env python3
"""Tests of the band detector (sandcell_analysis.band_detector, issue 45) on synthetic samples whose answer is known
(sandcell_analysis.band_synthetic): homogeneous ones (affine + particle noise; a spatially correlated Gaussian
displacement field) must not be called banded, a planar band must be, at 1,000, 4,000 and 19,436 spheres; and the
diffuse correlated field that the old criterion (strongest mode above 3 x its shuffled share) flagged is not.

    PYTHONPATH=apps/analysis /usr/bin/python3 -m pytest tests/analysis/test_band_detector.py

All seeds are fixed: the counts below are exact for this code, and each bound says how far it is from the
measured rate (experiments/2026-11-28-band-detector: 20 samples of each kind per size).
"""
import csv
import hashlib
import math
import os

import numpy as np
import pytest

from sandcell_analysis import analyze, band_detector as bd, band_synthetic as syn, campaign_table
from sandcell_analysis import localization as loc

SIZES = (1000, 4000, 19436)


def verdicts(kind, n, seeds, **kw):
    """(banded, statistic significant, old criterion) per sample, and the band dicts."""
    out, bands = [], []
    for seed in seeds:
        snaps, series = syn.sample(kind, n, seed, **kw)
        b = loc.judge_test(snaps, series, loc.default_grid(n), whole=True)["band"]
        out.append((b["banded"], b["judged"]["significant"], b["share"] > loc.BAND_CONTRAST * b["shuffled"]))
        bands.append(b)
    return np.array(out, bool), bands


@pytest.mark.parametrize("n", SIZES)
def test_false_positive_rate(n):
    """20 homogeneous samples of each kind per size: at most 1 (5 %) called banded; the statistic alone is held to
    the same 5 %. By construction the statistic's rate is ~1 % (the surrogates' 0.99 quantile, two kinds, the larger
    taken); 20 samples cannot tell 1 % from 5 %, so 5 % (1 of 20) is the bound the issue sets, not a measured rate
    loosened. The physical criteria (band/outside deps_q >= 2, void-ratio contrast >= 0.01 and 3 x noise) are not
    met together by any homogeneous sample (strain ratios up to 2.0, void-ratio growths within their noise)."""
    grid = loc.default_grid(n)
    for kind in ("noise", "gaussian"):
        v, bands = verdicts(kind, n, range(7000 + n, 7020 + n))
        print(f"N = {n} (grid {grid}^3) {kind}: banded {v[:, 0].sum()}/20, statistic {v[:, 1].sum()}/20, old "
              f"criterion {v[:, 2].sum()}/20; largest band/outside deps_q {max(b['ratio'] for b in bands):.2f}")
        assert v[:, 0].sum() <= 1, f"N = {n}, {kind}: {v[:, 0].sum()} of 20 homogeneous samples called banded"
        assert v[:, 1].sum() <= 1, f"N = {n}, {kind}: the statistic flags {v[:, 1].sum()} of 20 homogeneous samples"


@pytest.mark.parametrize("n", SIZES)
def test_finds_band(n):
    """A planar band along (1, 0, 1) of width 5 d50 (3 d50 in the 1,000-sphere cell, 9.4 d50 across), carrying most of
    the shear and dilating ~0.11 in void ratio over three increments (as the committed b = 0.5 bands, 0.09-0.15): found
    in its own mode, from the first increment on and in every later one. Five fixed seeds. At 4,000 and 19,436
    spheres every one is found (20 of 20 in the experiment). At 1,000 the slabs across the band are 0.67 d50 thick
    and their void ratios scatter by 0.02-0.05, so the void-ratio criterion (3 x that noise) misses some: 14 of 20 in
    the experiment; here 3 of these 5 (seeds 0 and 3 miss: contrast 0.094 and 0.098 against 3 x noise 0.13 and 0.15),
    and the bound is that count: the seeds are fixed, and a miss at 1,000 spheres is the void-ratio criterion's noise
    floor, which the experiment's table states."""
    found = 0
    for seed in range(5):
        snaps, series = syn.sample("band", n, 9000 + seed, width=3.0 if n < 2000 else 5.0)
        res = loc.judge_test(snaps, series, loc.default_grid(n))
        b = res["band"]
        assert b["hkl"] == syn.HKL, f"N = {n}, seed {seed}: strongest whole-test mode {b['hkl']}, imposed {syn.HKL}"
        assert b["judged"]["significant"], f"N = {n}, seed {seed}: share {b['share']:.3f} not significant"
        # the band/outside ratio: the band carries 6 x eps of shear a increment besides the affine eps_q = eps; the
        # slabs' central differences see ~0.7 of it (test_localization's 11/16): 2.4-3.9 measured over the sizes
        assert b["ratio"] >= bd.STRAIN_RATIO, f"N = {n}, seed {seed}: band/outside deps_q {b['ratio']:.2f}"
        # every increment detects it, in the imposed mode: onset at the first, persistent
        k0, frac, persistent = res["onset"]
        assert k0 == 0 and frac == 1.0 and persistent, f"N = {n}, seed {seed}: onset {k0}, persistence {frac}"
        found += b["banded"]
        print(f"N = {n} seed {seed}: {loc.verdict_text(b)}")
    assert found >= (3 if n < 2000 else 5), f"N = {n}: the band found in {found} of 5 samples"


def test_old_false_positive_regression():
    """The defect of issue 45: a diffuse, correlated but unbanded deformation (a smooth Gaussian displacement field of
    correlation length 3 d50 besides the affine one, new each increment) at 19,436 spheres. The old criterion (the
    whole test's strongest mode above 3 x its shuffled share, ~0.06 on the 8^3 grid) flags most such samples (18 of
    20 in the experiment): here at least 4 of 5. The new detector flags none: its correlated surrogates carry the
    field's own correlation length (fitted: ~3 mm, the imposed 3 d50) and its band/outside strain stays ~1.1."""
    v, bands = verdicts("gaussian", 19436, range(5))
    print("old:", v[:, 2].astype(int), "new:", v[:, 0].astype(int), "ell (mm):",
          [round(b["judged"]["ell"] * 1e3, 2) for b in bands])
    assert v[:, 2].sum() >= 4, f"the old criterion flags only {v[:, 2].sum()} of 5: not the regression case"
    assert not v[:, 0].any() and not v[:, 1].any(), \
        f"the new detector flags {v[:, 0].sum()} (statistic {v[:, 1].sum()})"
    # the correlation length is measured, not assumed: the fit finds the imposed 3 mm within a third (at 19,436
    # spheres 2.9-3.4 mm over the experiment's 20 samples)
    ells = np.array([b["judged"]["ell"] for b in bands])
    assert np.all(np.abs(ells / (syn.ELL * syn.D50) - 1) < 1 / 3), f"fitted ell {ells}"


def test_criteria_identities():
    """The physical criteria on hand-made slab profiles, and onset and persistence on hand-made rows."""
    band = np.zeros(10, bool)
    band[[4, 5]] = True
    q = np.full(10, 0.1)
    q[[4, 5]] = 0.3
    assert bd.strain_ratio(q, band) == pytest.approx(3.0, rel=1e-14)
    assert bd.strain_ratio(np.where(band, 0.3, 0.0), band) == math.inf
    # void ratios: slabs 4, 5 grow by 0.05 more than the rest, whose growths scatter by a normal-consistent MAD
    e0 = np.full(10, 0.6)
    g = np.array([0.01, 0.02, 0.00, 0.01, 0.06, 0.06, 0.02, 0.00, 0.01, 0.01])
    growth, noise = bd.void_contrast(e0, e0 + g, band)
    rest = g[~band]
    assert growth == pytest.approx(0.06 - rest.mean(), abs=1e-15)
    mad = 1.4826 * np.median(np.abs(rest - np.median(rest)))
    assert noise == pytest.approx(mad * math.sqrt(1 / 2 + 1 / 8), rel=1e-12)
    # the verdict: each criterion alone fails it, all together pass it
    judged = dict(hkl=(1, 0, 1), share=0.8, threshold_noise=0.2, threshold_gauss=0.3, significant=True)
    assert bd.verdict(judged, 2.5, 0.05, 0.01) == (True, [])
    assert not bd.verdict(dict(judged, significant=False), 2.5, 0.05, 0.01)[0]
    assert not bd.verdict(judged, 1.9, 0.05, 0.01)[0]
    assert not bd.verdict(judged, 2.5, 0.009, 0.001)[0], "below the absolute 0.01"
    assert not bd.verdict(judged, 2.5, 0.05, 0.02)[0], "below 3 x noise"
    assert bd.verdict(dict(judged, hkl=(0, 0, 0)), 2.5, 0.05, 0.01) == (False, ["the field is uniform to round-off"])
    # onset: the first detected increment; persistence: the later ones detecting the same mode (+-hkl normalized)
    rows = [dict(band_detected=d, mode_h=h, mode_k=0, mode_l=1) for d, h in ((0, 1), (1, 1), (1, 1), (0, 1), (1, 2))]
    assert bd.onset_persistence(rows)[:2] == (1, pytest.approx(1 / 3)) and not bd.onset_persistence(rows)[2]
    rows[3]["band_detected"] = 1
    assert bd.onset_persistence(rows)[1:] == (pytest.approx(2 / 3), True)
    assert bd.onset_persistence([dict(r, band_detected=0) for r in rows])[0] is None
    # the family of a mode: its harmonics on the grid, aliased, the zero bin left out
    fam = bd.mode_family((1, 0, 1), 4)
    expect = {np.ravel_multi_index((m % 4, 0, m % 4), (4, 4, 4)) for m in (1, 2, 3)}
    assert set(fam.tolist()) == expect, f"family {fam}"


def test_noise_surrogates_bin_means():
    """The (a) surrogates draw the bin means as Gaussians of sigma / sqrt(count): their mean power spectrum is the one
    of binning particle draws. 400 of each on 8,000 points (G = 6): the mean powers agree within 3 x their standard
    error (the powers are exponential: relative error 1/sqrt(400) = 5 % per bin; averaged over the 215 bins, ~0.4 %)."""
    rng = np.random.default_rng(3)
    n, G = 8000, 6
    s = rng.random((n, 3))
    u = 1e-5 * rng.standard_normal((n, 3))
    La, Lb = np.full(3, 0.05), np.full(3, 0.05) * np.exp(-np.array([0.01, -0.005, -0.005]))
    table = loc.mode_table(G)
    _, fast = bd.noise_surrogates(s, u, La, Lb, G, table, 400, np.random.default_rng(1))
    sigma = u.std(axis=0)
    draws = np.stack([loc.strain_invariants(loc.binned_strain(s, sigma * rng.standard_normal(u.shape), La, Lb, G))[0]
                      for _ in range(400)])
    _, slow = bd.shares_of(draws, table)
    ratio = fast[1:].sum() / slow[1:].sum()
    assert abs(ratio - 1) < 3 * 0.05 / math.sqrt(215) * math.sqrt(2), f"power ratio {ratio}"


def test_readers_of_the_verdict(tmp_path):
    """`triaxial analyze` and `campaign-table` read the `banded` column; a CSV from before it is not judged."""
    old = tmp_path / "t-localization.csv"
    old.write_text("step_a,step_b,mode_share,shuffled_share,mode_h,mode_k,mode_l\n0,10,0.9,0.02,1,0,1\n")
    assert analyze.banded("t", str(tmp_path)) == "not judged"
    assert campaign_table.band_of(str(tmp_path), "t")[0] == "?"
    new = tmp_path / "u-localization.csv"
    with open(new, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=loc.COLUMNS)
        w.writeheader()
        w.writerow({c: 0 for c in loc.COLUMNS} | dict(mode_share=0.9, shuffled_share=0.02, mode_h=1, banded=0))
    # the old criterion would call this row banded (0.9 > 3 x 0.02): the verdict column rules
    assert analyze.banded("u", str(tmp_path)) == "no" and campaign_table.band_of(str(tmp_path), "u")[0] == "no"
    assert os.path.exists(new)


def test_bad_kind():
    with pytest.raises(ValueError, match="kind: 'slab'"):
        syn.sample("slab", 1000, 0)
    with pytest.raises(ValueError, match="free: a band's slip"):
        syn.sample("noise", 1000, 0, free=True)


# A cell that shears as a free cell does (issue 45: the detector in reduced coordinates s = C^-1 x): tilts grow by
# these fractions of the lengths per 2 % increment, xy 1.5 %, xz -3 %, yz 1.5 % at the end of the three increments
# (the free cells of experiments/2026-11-28-free-cell-banded end at |F_xz| 0.6-5.3 % over 20-30 % of axial strain).
TILT = (0.005, -0.01, 0.005)


def tilted_verdicts(kind, n, seeds, **kw):
    out, bands = [], []
    for seed in seeds:
        snaps, series = syn.sample(kind, n, seed, tilt=TILT, **kw)
        assert np.ndim(snaps[-1][3]) == 2 and snaps[-1][3][0, 2] != 0.0, "the sample's cell does not shear"
        b = loc.judge_test(snaps, series, loc.default_grid(n), whole=True)["band"]
        out.append((b["banded"], b["judged"]["significant"]))
        bands.append(b)
    return np.array(out, bool), bands


@pytest.mark.parametrize("n", SIZES)
def test_tilted_false_positive_rate(n):
    """test_false_positive_rate's 20 homogeneous samples of each kind per size (the same seeds), in a cell that
    shears: the same bound, at most 1 of 20 (5 %) called banded and at most 1 flagged by the statistic alone. The
    surrogates are built in the sheared cell's own geometry (its reduced grid, its reciprocal wave vectors, its
    Hencky affine increment), so their false-positive rate is set by construction as in an orthorhombic cell."""
    for kind in ("noise", "gaussian"):
        v, bands = tilted_verdicts(kind, n, range(7000 + n, 7020 + n))
        print(f"N = {n} sheared {kind}: banded {v[:, 0].sum()}/20, statistic {v[:, 1].sum()}/20; largest band/outside "
              f"deps_q {max(b['ratio'] for b in bands):.2f}")
        assert v[:, 0].sum() <= 1, f"N = {n}, {kind}: {v[:, 0].sum()} of 20 homogeneous sheared samples called banded"
        assert v[:, 1].sum() <= 1, f"N = {n}, {kind}: the statistic flags {v[:, 1].sum()} of 20 sheared samples"


@pytest.mark.parametrize("n", SIZES)
def test_tilted_finds_band(n):
    """test_finds_band's bands (same seeds and widths) in a cell that shears: found in their mode (1, 0, 1), whose
    normal is now the reciprocal lattice vector C^-T (1, 0, 1), from the first increment on and in every later one;
    banded in all 5 at 4,000 and 19,436 spheres, as in the orthorhombic cell. At 1,000 spheres every miss is the
    void-ratio criterion's alone (its noise floor there, test_finds_band): 2 of these 5 are banded (seeds 1 and 2;
    the orthorhombic cell 3, seed 4 there passing at contrast 0.094 and missing here at 0.098 against 3 x noise 0.112:
    the slabs' noise moves with the particles' paths), and the bound is that count, the seeds being fixed. The cell's
    own shear is an affine deviatoric increment that adds to the outside's deps_q as much as to the band's, so the
    band/outside ratio is lower than in the orthorhombic cell (2.2-3.0 against 2.5-3.5 at 4,000 and 19,436 spheres)
    but still >= 2."""
    found = 0
    for seed in range(5):
        snaps, series = syn.sample("band", n, 9000 + seed, width=3.0 if n < 2000 else 5.0, tilt=TILT)
        res = loc.judge_test(snaps, series, loc.default_grid(n))
        b = res["band"]
        assert b["hkl"] == syn.HKL, f"N = {n}, seed {seed}: strongest whole-test mode {b['hkl']}, imposed {syn.HKL}"
        assert b["judged"]["significant"], f"N = {n}, seed {seed}: share {b['share']:.3f} not significant"
        if n > 2000:
            assert b["ratio"] >= bd.STRAIN_RATIO, f"N = {n}, seed {seed}: band/outside deps_q {b['ratio']:.2f}"
            k0, frac, persistent = res["onset"]
            assert k0 == 0 and frac == 1.0 and persistent, f"N = {n}, seed {seed}: onset {k0}, persistence {frac}"
        # the band's normal: the reciprocal lattice vector of (1, 0, 1) in the mean cell of the whole test, whose
        # angle to axis 1 differs from the orthorhombic cell's (h/L_1, 0, l/L_3) by the tilts
        C = loc.mean_cell(snaps[0][3], snaps[-1][3])
        n_expect = np.linalg.solve(C.T, np.array(syn.HKL, float))
        angle = math.degrees(math.atan2(math.hypot(n_expect[1], n_expect[2]), abs(n_expect[0])))
        assert b["angle"] == pytest.approx(angle, abs=1e-9)
        found += b["banded"]
        print(f"N = {n} seed {seed} sheared: {loc.verdict_text(b)}")
        if not b["banded"]:
            assert n < 2000 and len(b["why"]) == 1 and b["why"][0].startswith("void-ratio contrast"), b["why"]
    assert found >= (2 if n < 2000 else 5), f"N = {n}: the band found in {found} of 5 sheared samples"


@pytest.mark.parametrize("n", SIZES)
def test_free_cell_band(n):
    """A band whose slip the cell takes up, as in a free cell (band_synthetic.free_sample: the outside follows the
    cell, the band carries the shear, and the cell's basis gets the band's jump, turned back to upper triangular):
    the cell ends with a tilt xz of 1.2 % (19,436 spheres) to 2.9 % (1,000) of L_1, which is the band's slip, not a
    deformation of the material outside it. Read in the sheared cell's reduced coordinates, the band is found in its
    mode in every increment and banded in all 5 samples at every size (the outside carries no counter-shear here,
    so its slabs' void ratios scatter less than test_finds_band's at 1,000 spheres); the slabs' void ratio of the
    whole cell is the series' e (det C over the solid) to round-off."""
    for seed in range(5):
        snaps, series = syn.sample("band", n, 9000 + seed, width=3.0 if n < 2000 else 5.0, free=True)
        C = snaps[-1][3]
        assert 0.01 < C[0, 2] / C[0, 0] < 0.04 and abs(C[0, 1]) < 1e-12 * C[0, 0], f"tilts {C}"
        res = loc.judge_test(snaps, series, loc.default_grid(n))
        b = res["band"]
        assert b["hkl"] == syn.HKL and b["banded"], f"N = {n}, seed {seed}: {loc.verdict_text(b)}"
        assert res["onset"][:2] == (0, 1.0), f"N = {n}, seed {seed}: onset {res['onset']}"
        assert max(abs(r["e_whole"] - r["e_series"]) for r in b["rows"]) < 1e-12
        print(f"N = {n} seed {seed} free cell (tilt xz {C[0, 2] / C[0, 0]:.4f}): {loc.verdict_text(b)}")


def digest(res):
    """SHA-256 of every number of a test's judgement (the rows, the fields, the band profile and verdict, the onset),
    bit for bit: floats by their hex form, arrays by their bytes."""
    h = hashlib.sha256()

    def add(v):
        if isinstance(v, (list, tuple)):
            for x in v:
                add(x)
        elif isinstance(v, dict):
            for k in sorted(v):
                h.update(str(k).encode())
                add(v[k])
        elif isinstance(v, np.ndarray):
            h.update(str(v.dtype).encode() + str(v.shape).encode())
            h.update(np.ascontiguousarray(v).tobytes())
        elif isinstance(v, (float, np.floating)):
            h.update(float(v).hex().encode())
        else:
            h.update(repr(v).encode())
    b = res["band"]
    add(res["rows"])
    add([f[0] for f in res["fields"]])
    add([f[1] for f in res["fields"]])
    add({k: b[k] for k in ("hkl", "share", "shuffled", "deps_q", "deps_v", "band", "ratios", "ratio", "growth",
                           "noise", "banded", "why")})
    add([{k: r[k] for k in ("step", "eps_1", "e_band", "e_outside", "e_whole", "e_slab", "d")} for r in b["rows"]])
    add(res["onset"])
    return h.hexdigest()


# judge_test's digests of three orthorhombic samples as computed by the code before the detector read sheared cells
# (commit 22235cb, numpy 1.24 on Debian 12). A change of numpy's FFT or random streams would change them too: then
# recompute them with that commit's code and the same numpy before reading a failure as a change of the detector.
ORTHORHOMBIC_DIGESTS = {
    ("band", 4000, 9001): "98cab2563299f155ed93d40281792829b3e6b1e9418d7273bb4a71d8dd6a5c43",
    ("noise", 1000, 7003): "c50c5b44650a46c3b3414c6eeecec3d0c636d69f50f77f8a3354072f187f8698",
    ("gaussian", 4000, 7005): "f5c226213c18e647f436358738c71b1130b78827954ee1b47b19feb0da132077",
}


def test_orthorhombic_bitwise():
    """An orthorhombic cell (its snapshots give the cell lengths) takes exactly the arithmetic it took before sheared
    cells were read: every number of the judgement is bitwise the earlier code's (the digests above)."""
    for (kind, n, seed), expect in ORTHORHOMBIC_DIGESTS.items():
        snaps, series = syn.sample(kind, n, seed)
        assert all(np.ndim(sn[3]) == 1 for sn in snaps)
        assert digest(loc.judge_test(snaps, series, loc.default_grid(n))) == expect, f"{kind} {n} {seed}"


def test_orthorhombic_through_sheared_arithmetic():
    """The sheared cell's arithmetic (a 3 x 3 cell matrix: back substitution, Hencky strain by eigendecomposition,
    gradients through C^-1, reciprocal wave vectors) given an orthorhombic cell as a diagonal matrix judges it as the
    orthorhombic arithmetic does: the same modes, detections, band slabs and verdicts, and every number equal to a
    relative 1e-9. The two differ only in the order of their roundings (a few ulps an operation, ~1e-16 relative),
    which the 200 surrogates' quantiles and the slab sums carry through unamplified; 1e-9 leaves 7 orders for that,
    and any error of geometry (a length on the wrong axis, a transposed C) is of order 1."""
    for kind, n, seed in (("band", 4000, 9001), ("gaussian", 4000, 7005)):
        snaps, series = syn.sample(kind, n, seed)
        plain = loc.judge_test(snaps, series, loc.default_grid(n))
        as_matrix = [sn[:3] + (np.diag(sn[3]),) + sn[4:] for sn in snaps]
        sheared = loc.judge_test(as_matrix, series, loc.default_grid(n))
        for r0, r1 in zip(plain["rows"], sheared["rows"]):
            for c in loc.COLUMNS:
                if isinstance(r0[c], float) and math.isfinite(r0[c]):
                    assert r1[c] == pytest.approx(r0[c], rel=1e-9, abs=1e-15), f"{kind}: {c} {r0[c]} {r1[c]}"
                else:
                    assert r1[c] == r0[c] or (math.isnan(r0[c]) and math.isnan(r1[c])), f"{kind}: {c}"
        b0, b1 = plain["band"], sheared["band"]
        assert (b0["hkl"], b0["banded"], b0["band"].tolist(), plain["onset"][0]) == \
            (b1["hkl"], b1["banded"], b1["band"].tolist(), sheared["onset"][0])
        for k in ("share", "ratio", "growth", "noise"):
            assert b1[k] == pytest.approx(b0[k], rel=1e-9), k
        np.testing.assert_allclose(b1["deps_q"], b0["deps_q"], rtol=1e-9)
        np.testing.assert_allclose([r["e_slab"] for r in b1["rows"]], [r["e_slab"] for r in b0["rows"]], rtol=1e-12)
