#!/usr/bin/env python3
"""Strain localization in a sandcell triaxial test: is the incremental strain field homogeneous or banded?

    triaxial localization RESULTS.h5... [--out DIR] [--grid G] [--whole]

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
     permutations, fixed seed): the share a field of noise would reach. The band normal is
     n ~ (h/L_1, k/L_2, l/L_3); its angle to axis 1 (the most compressed) is reported.
The sampling of ~40 particles a bin leaves a noise floor in the local field: the CV and the mean
local deps_q include it, the shuffled share measures it.

Writes, into --out (default: next to each input), <stem>-localization.csv (one row per increment),
<stem>-localization.md (summary) and <stem>-localization.png: the statistics against eps_1 over q/p
and e, and maps of the local deps_q of the last increment and of the increment with the largest
mode share, averaged along an axis in the plane of the band (its mode component 0; a middle slice
normal to axis 2 when it has none). One line per increment is printed.
Exit status: 0 done; 2 bad input (unreadable file, fewer than 2 snapshots, bad --grid, an empty
bin); 1 numpy, matplotlib or h5py missing.
"""
import os

os.environ["HDF5_USE_FILE_LOCKING"] = "FALSE"  # read files a running job is still writing

import argparse
import csv
import io
import math
import sys

try:
    import numpy as np
except ImportError as _exc:  # run by an interpreter without the scientific stack
    if __name__ != "__main__":
        raise
    print(f"localization.py: error: {_exc} (needs numpy, matplotlib and h5py)", file=sys.stderr)
    sys.exit(1)

PROG = os.environ.get("SANDCELL_ANALYZE_PROG", "localization.py")
TOP = 0.10            # the top-share fraction of bins
MAX_ORDER = 2         # mode components searched: [-2, 2]
SHUFFLES, SEED = 20, 12345
COLUMNS = ["step_a", "step_b", "eps1_mid", "deps_q_macro", "deps_v_macro", "deps_q_mean", "deps_q_cv",
           "top10_share", "mode_h", "mode_k", "mode_l", "mode_share", "shuffled_share", "normal_angle_deg",
           "deps_v_std"]


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


def local_strain(id_a, x_a, L_a, id_b, x_b, L_b, G):
    """Local strain increments [G, G, G, 3, 3] (compression positive) between two snapshots, and the
    particles matched. Raises ValueError on an empty bin."""
    L_a, L_b = np.asarray(L_a, float), np.asarray(L_b, float)
    _, ia, ib = np.intersect1d(id_a, id_b, assume_unique=True, return_indices=True)
    s_a = x_a[ia] / L_a
    ds = x_b[ib] / L_b - s_a
    u = (ds - np.floor(ds + 0.5)) * L_b
    # floor then mod: a coordinate a hair below 0 (unwrapped) lands in the last bin, not at index -1
    cell = np.floor(s_a * G).astype(np.int64) % G
    flat = (cell[:, 0] * G + cell[:, 1]) * G + cell[:, 2]
    count = np.bincount(flat, minlength=G ** 3)
    if not count.all():
        raise ValueError(f"{np.count_nonzero(count == 0)} of {G ** 3} bins are empty")
    U = np.stack([np.bincount(flat, u[:, c], G ** 3) / count for c in range(3)], -1).reshape(G, G, G, 3)
    spacing = 0.5 * (L_a + L_b) / G
    grad = np.stack([(np.roll(U, -1, m) - np.roll(U, 1, m)) / (2.0 * spacing[m]) for m in range(3)], -1)  # [.., i, m]
    affine = np.diag(np.log(L_b / L_a))
    return -(affine + 0.5 * (grad + np.swapaxes(grad, -1, -2))), len(ia)


def mode_table(G):
    """The distinct modes +-(h, k, l), |components| <= 2, on a G-grid: [(hkl, flat FFT indices)],
    lowest order first (on a small grid +-2 can alias onto +-1; each index set is kept once)."""
    seen, table = set(), []
    r = range(-MAX_ORDER, MAX_ORDER + 1)
    for hkl in sorted(((h, k, l) for h in r for k in r for l in r), key=lambda v: (sum(map(abs, v)), v)):
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


def increment_stats(deps, L_a, L_b, table, rng_seed=SEED):
    """The statistics of one increment's local strain field (a dict, keys as COLUMNS) and its deps_q field."""
    q, v = strain_invariants(deps)
    q_macro, v_macro = strain_invariants(-np.diag(np.log(np.asarray(L_b, float) / np.asarray(L_a, float))))
    hkl, share = strongest_mode(q, table)
    rng = np.random.default_rng(rng_seed)
    shuffled = float(np.mean([strongest_mode(rng.permutation(q.ravel()).reshape(q.shape), table)[1]
                              for _ in range(SHUFFLES)]))
    L = 0.5 * (np.asarray(L_a, float) + np.asarray(L_b, float))
    normal = np.array(hkl, float) / L
    mean = float(q.mean())
    return dict(deps_q_macro=float(q_macro), deps_v_macro=float(v_macro), deps_q_mean=mean,
                deps_q_cv=float(q.std() / mean) if mean > 0 else math.nan, top10_share=top_share(q),
                mode_h=hkl[0], mode_k=hkl[1], mode_l=hkl[2], mode_share=share, shuffled_share=shuffled,
                normal_angle_deg=math.degrees(math.atan2(np.hypot(normal[1], normal[2]), abs(normal[0])))
                if any(hkl) else math.nan,
                deps_v_std=float(v.std())), q


def read_series(f, path):
    if "series" not in f or "step" not in f["series"] or "strain" not in f["series"]:
        fail(f"{path}: no /series/step and /series/strain: not a triaxial results file")
    s = f["series"]
    names = [k for k in ("step", "strain", "eta", "e") if k in s]
    n = min(s[k].shape[0] for k in names)  # a running job's datasets may differ by a row
    return {k: np.asarray(s[k][:n], float) for k in names}


def snapshot_names(f, path, whole=False):
    names = sorted(f["snapshots"].keys(), key=int) if "snapshots" in f else []
    if len(names) < 2:
        fail(f"{path}: {len(names)} particle snapshot(s); localization needs at least 2: set "
             "output.snapshot_interval (steps between snapshots, e.g. 1 % of axial strain) and run the test again")
    # The stage's end is written as well as the interval's snapshots: a few steps after the last
    # of them, it would make an increment of noise. It then replaces that last one.
    if whole:
        return [names[0], names[-1]]
    if len(names) >= 3:
        gaps = np.diff([int(k) for k in names])
        if gaps[-1] < 0.5 * np.median(gaps[:-1]):
            del names[-2]
    return names


def read_snapshot(f, name, path):
    g = f["snapshots"][name]
    missing = [k for k in ("id", "position") if k not in g] + ([] if "cell_length" in g.attrs else ["cell_length"])
    if missing:
        fail(f"{path}: snapshot {name} lacks {', '.join(missing)}")
    return int(g.attrs.get("step", int(name))), g["id"][:], np.asarray(g["position"][:], float), \
        np.asarray(g.attrs["cell_length"], float)


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


def open_results(path):
    import h5py
    try:
        return h5py.File(path, "r")
    except OSError as e:
        fail(f"{path}: cannot read ({e})")


def analyse(path, G_opt, whole):
    """Rows of statistics and the local deps_q fields of every increment of one results file."""
    with open_results(path) as f:
        series = read_series(f, path)
        names = snapshot_names(f, path, whole)
        rows, fields = [], []
        step_a, id_a, x_a, L_a = read_snapshot(f, names[0], path)
        G = G_opt or default_grid(len(id_a))
        table = mode_table(G)
        for name in names[1:]:
            step_b, id_b, x_b, L_b = read_snapshot(f, name, path)
            try:
                deps, matched = local_strain(id_a, x_a, L_a, id_b, x_b, L_b, G)
            except ValueError as e:
                fail(f"{path}: steps {step_a}-{step_b}: {e} (G = {G}): use a smaller --grid")
            stats, q = increment_stats(deps, L_a, L_b, table)
            eps1 = float(np.interp(0.5 * (step_a + step_b), series["step"], series["strain"][:, 0]))
            rows.append(dict(step_a=step_a, step_b=step_b, eps1_mid=eps1, **stats))
            fields.append((q, 0.5 * (L_a + L_b)))
            r = rows[-1]
            print(f"{PROG}: {os.path.basename(path)}: steps {step_a}-{step_b}, eps1 {eps1:.4f}: deps_q macro "
                  f"{r['deps_q_macro']:.3e}, local mean {r['deps_q_mean']:.3e}, CV {r['deps_q_cv']:.3f}, "
                  f"top-10% {r['top10_share']:.3f}, mode ({r['mode_h']},{r['mode_k']},{r['mode_l']}) "
                  f"{r['mode_share']:.3f} (shuffled {r['shuffled_share']:.3f}), normal "
                  f"{r['normal_angle_deg']:.1f} deg to axis 1", flush=True)
            step_a, id_a, x_a, L_a = step_b, id_b, x_b, L_b
    return dict(rows=rows, fields=fields, series=series, G=G, N=len(id_a), matched=matched)


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
    write_text(path, "\n".join(lines) + "\n")
    return best


def draw_map(fig, ax, q, L, r, title):
    """deps_q averaged along an axis in the band plane (its mode component 0), else a slice normal to axis 2."""
    hkl = (r["mode_h"], r["mode_k"], r["mode_l"])
    flat = [a for a in (1, 2, 0) if hkl[a] == 0]
    if flat:
        axis, how = flat[0], f"mean along x{flat[0] + 1}"
        image = q.mean(axis=axis)
    else:
        axis, how = 1, f"slice x2 = {L[1] * (q.shape[1] // 2 + 0.5) / q.shape[1]:.3g} m"
        image = q[:, q.shape[1] // 2, :]
    rr, cc = [a for a in range(3) if a != axis]
    im = ax.imshow(image, origin="lower", interpolation="nearest", extent=[0, L[cc], 0, L[rr]], cmap="viridis")
    ax.set_xlabel(f"x{cc + 1} (m)")
    ax.set_ylabel(f"x{rr + 1} (m)")
    ax.set_title(f"{title}: steps {r['step_a']}-{r['step_b']}, eps_1 = {r['eps1_mid']:.3f}\n"
                 f"{how}; mode {hkl} share {r['mode_share']:.2f}", fontsize=8)
    fig.colorbar(im, ax=ax, label="local deps_q")


def write_figure(path, src, res, best):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rows, series = res["rows"], res["series"]
    eps1 = [r["eps1_mid"] for r in rows]
    fig, axs = plt.subplots(2, 2, figsize=(12, 9))
    ax = axs[0, 0]
    for key, label, style in (("deps_q_cv", "CV of local deps_q", "o-"), ("top10_share", "top-10 % share", "s-"),
                              ("mode_share", "largest mode share", "^-"),
                              ("shuffled_share", "mode share, bins shuffled", "v:")):
        ax.plot(eps1, [r[key] for r in rows], style, ms=4, label=label)
    ax.axhline(TOP, color="0.6", lw=0.8, ls="--", label="top-10 % share if uniform")
    ax.set_xlabel("eps_1 (increment midpoint)")
    ax.set_ylabel("localization measures")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    ax = axs[1, 0]
    if "eta" in series:
        ax.plot(series["strain"][:, 0], series["eta"], color="C0")
    ax.set_ylabel("q/p", color="C0")
    ax.set_xlabel("eps_1")
    ax.grid(alpha=0.3)
    if "e" in series:
        tw = ax.twinx()
        tw.plot(series["strain"][:, 0], series["e"], color="C3")
        tw.set_ylabel("void ratio e", color="C3")
    # both panels over the whole test: a few increments are read against the whole curve
    lo, hi = min(series["strain"][:, 0].min(), min(eps1)), max(series["strain"][:, 0].max(), max(eps1))
    for a in axs[:, 0]:
        a.set_xlim(lo - 0.02 * (hi - lo), hi + 0.02 * (hi - lo))
    for k, ax, title in ((len(rows) - 1, axs[0, 1], "last increment"), (best, axs[1, 1], "largest mode share")):
        draw_map(fig, ax, *res["fields"][k], rows[k], title)
    fig.suptitle(f"local strain increments of {os.path.basename(src)} ({res['G']}^3 bins)", fontsize=10)
    fig.tight_layout()
    write_atomic(path, lambda tmp: fig.savefig(tmp, format="png", dpi=110))
    plt.close(fig)


def grid_arg(v):
    try:
        g = int(v)
    except ValueError:
        g = None
    if g is None or g < 3:
        raise argparse.ArgumentTypeError(f"must be an integer >= 3 (bins along each cell edge), got {v!r}")
    return g


def main():
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="\n\n".join(__doc__.split("\n\n")[2:]))
    ap.add_argument("results", nargs="+", help="shearing results files (<test>.h5) with >= 2 snapshots")
    ap.add_argument("--out", default=None, help="output folder (default: next to each input)")
    ap.add_argument("--grid", type=grid_arg, default=None,
                    help="bins along each cell edge, >= 3 (default: ~40 particles a bin)")
    ap.add_argument("--whole", action="store_true",
                    help="one increment, from the first snapshot to the last (the whole test)")
    args = ap.parse_args()
    try:
        import h5py  # noqa: F401 (checked here: used where the files are read and drawn)
        import matplotlib  # noqa: F401
    except ImportError as e:
        fail(f"needs python3 with numpy, matplotlib and h5py ({e})", 1)
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
        res = analyse(src, args.grid, args.whole)
        write_csv(prefix + ".csv", res["rows"])
        best = write_summary(prefix + ".md", src, res)
        write_figure(prefix + ".png", src, res, best)
        print(f"{PROG}: wrote {prefix}.md (+ csv, png)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
