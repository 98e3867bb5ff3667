#!/usr/bin/python3
"""Compare sandcell's simple shear with LAMMPS's (run.sh runs it; README.md reads its tables).

    compare.py --sandcell RESULTS.h5 --lammps PREFIX --control PREFIX [--out DIR]

RESULTS.h5: sandcell's results file (series every 1000 steps, a window of single-step rows around
the flip, particle snapshots); PREFIX.stress.txt / .pos.txt / .xz.txt: shear.in's output of the
compared LAMMPS run (newton on), and of the control run (newton off, stress and positions).

Stress: sandcell's series stress (contact stress, compression positive, symmetrized) beside LAMMPS's
pair virial pressure tensor (compression positive, r_i f_j: not symmetric for frictional contacts),
whose off-diagonal components are symmetrized here with the summed particle torque T:
sum over contacts of r x f = -T (1 - delta/d) (the contacts' torques on the two spheres have the
lever R each in LAMMPS), so sym_xy = P_xy + T_z/(2V), sym_xz = P_xz - T_y/(2V),
sym_yz = P_yz + T_x/(2V) (the delta/d correction, below 1e-3 of an already small term, is left out).
Relative difference: |S_sandcell - S_LAMMPS| / p, p the mean stress (sandcell).

Divergence: the particles' positions in the y and z directions (the lattice vectors have no tilt in
y and z, so the periodic image is found without the tilt, which the two codes step one step apart;
see README.md), minimum image, RMS over particles, in diameters.

Writes comparison.csv, divergence.csv and comparison.png into --out and prints the README's tables.
"""
import argparse
import os
import tomllib

import h5py
import numpy as np

COMP = ["xx", "yy", "zz", "xy", "xz", "yz"]
RANGES = [(0.0, 0.01), (0.01, 0.02), (0.02, 0.05), (0.05, 0.1), (0.1, 0.2), (0.2, 0.4), (0.4, 0.61)]


def read_lammps_stress(prefix, volume):
    a = np.loadtxt(prefix + ".stress.txt")
    step = a[:, 0].astype(np.int64)
    raw = a[:, 1:7].copy()
    torque = a[:, 7:10]
    sym = raw.copy()
    sym[:, 3] += torque[:, 2] / (2 * volume)
    sym[:, 4] -= torque[:, 1] / (2 * volume)
    sym[:, 5] += torque[:, 0] / (2 * volume)
    return step, raw, sym, a[:, 10]


def read_lammps_positions(prefix, n):
    """Frames of a `dump custom id x y z` sorted by id: {step: (n, 3) array}."""
    frames = {}
    with open(prefix + ".pos.txt") as f:
        lines = f.readlines()
    k = 0
    while k < len(lines):
        assert lines[k].startswith("ITEM: TIMESTEP")
        step = int(lines[k + 1])
        assert int(lines[k + 3]) == n
        body = np.array([ln.split() for ln in lines[k + 9:k + 9 + n]], dtype=float)
        assert np.all(body[:, 0] == np.arange(1, n + 1))
        frames[step] = body[:, 1:4]
        k += 9 + n
    return frames


def rms_yz(a, b, length):
    d = a[:, 1:3] - b[:, 1:3]
    d -= length[1:3] * np.round(d / length[1:3])
    return np.sqrt(np.mean(np.sum(d * d, axis=1)))


def first_above(gamma, values, limit):
    idx = np.nonzero(values > limit)[0]
    return (gamma[idx[0]], idx[0]) if len(idx) else (None, None)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sandcell", required=True)
    ap.add_argument("--lammps", required=True)
    ap.add_argument("--control", required=True)
    ap.add_argument("--out", default=".")
    ap.add_argument("--sandcell-more", nargs="*", default=[], help="more sandcell results (other round-off)")
    ap.add_argument("--lammps-more", nargs="*", default=[], help="more LAMMPS prefixes (other round-off)")
    ap.add_argument("--every", type=int, default=1000, help="compared output interval, steps")
    args = ap.parse_args()

    f = h5py.File(args.sandcell, "r")
    s = f["series"]
    step_all = s["step"][:].astype(np.int64)
    tilt_all = s["cell_tilt"][:, 1]
    # gamma = |F_xz|: the app's simple shear paths drove L_xz = +rate (F_xz > 0) before commit
    # 1244a26 and L_xz = -rate since (the soil convention gamma = -F_xz); both codes shear alike
    F_all = s["deformation"][:, 2]
    sign = 1.0 if F_all[-1] >= 0 else -1.0
    gamma_all = sign * F_all
    snaps = f["snapshots"]
    first = snaps[sorted(snaps.keys())[0]]
    length = np.array(first.attrs["cell_length"])
    volume = float(np.prod(length))
    radius = first["radius"][:]
    d = 2 * radius[0]
    n = len(radius)
    keep = (step_all % args.every == 0)
    _, uniq = np.unique(step_all[keep], return_index=True)
    rows = np.nonzero(keep)[0][uniq]
    step = step_all[rows]
    gamma = gamma_all[rows]
    S = s["stress"][:][rows]
    p = S[:, :3].mean(axis=1)
    Z = s["Z"][:][rows]
    max_ov = s["max_overlap_ratio"][:][rows]

    ls, lraw, lsym, lxz = read_lammps_stress(args.lammps, volume)
    cs, craw, csym, _ = read_lammps_stress(args.control, volume)
    common = np.intersect1d(np.intersect1d(step, ls), cs)
    i_s = np.searchsorted(step, common)
    i_l = np.searchsorted(ls, common)
    i_c = np.searchsorted(cs, common)
    step, gamma, S, p, Z, max_ov = step[i_s], gamma[i_s], S[i_s], p[i_s], Z[i_s], max_ov[i_s]
    L, Lraw, C = lsym[i_l], lraw[i_l], csym[i_c]
    rel = np.abs(S - L) / p[:, None]
    rel_raw = np.abs(S - Lraw) / p[:, None]
    rel_c = np.abs(L - C) / p[:, None]
    rel_max = rel.max(axis=1)
    rel_c_max = rel_c.max(axis=1)

    # mean overlap from p: p = (1/3V) sum_c f_n r ~ k_n d sum(delta) / (3V), N_c = Z N / 2
    cfg = tomllib.loads(f.attrs["config"] if isinstance(f.attrs["config"], str) else f.attrs["config"].decode())
    mat = cfg["material"]
    e_star = mat["young"] / (2 * (1 - mat["poisson"] ** 2))
    mass = 4.0 / 3.0 * np.pi * radius[0] ** 3 * mat["density"]
    r_star, m_star, V = radius[0] / 2, mass / 2, cfg["contact"]["characteristic_velocity"]
    k_n = 16 / 15 * np.sqrt(r_star) * e_star * (15 * m_star * V * V / (16 * np.sqrt(r_star) * e_star)) ** 0.2
    mean_overlap = 3 * volume * p / (k_n * d * Z * n / 2) / radius[0]

    out = args.out
    with open(os.path.join(out, "comparison.csv"), "w") as o:
        o.write("step,gamma,p_Pa," + ",".join("sandcell_" + c for c in COMP) + "," +
                ",".join("lammps_" + c for c in COMP) + "," + ",".join("rel_" + c for c in COMP) +
                ",rel_max,control_rel_max,mean_overlap_over_R,max_overlap_over_R\n")
        for k in range(len(step)):
            o.write("%d,%.6f,%.6g," % (step[k], gamma[k], p[k]) + ",".join("%.7g" % x for x in S[k]) + "," +
                    ",".join("%.7g" % x for x in L[k]) + "," + ",".join("%.3e" % x for x in rel[k]) +
                    ",%.3e,%.3e,%.4f,%.4f\n" % (rel_max[k], rel_c_max[k], mean_overlap[k], max_ov[k]))

    # divergence of the trajectories
    lpos = read_lammps_positions(args.lammps, n)
    cpos = read_lammps_positions(args.control, n)
    div = []
    for key in sorted(snaps.keys()):
        g = snaps[key]
        st = int(g.attrs["step"])
        if st not in lpos or st not in cpos:
            continue
        order = np.argsort(g["id"][:])
        xs = g["position"][:][order]
        row = np.nonzero(step_all == st)[0]
        gam = gamma_all[row[0]] if len(row) else np.nan
        div.append((st, gam, rms_yz(xs, lpos[st], length) / d, rms_yz(lpos[st], cpos[st], length) / d))
    div = np.array(div)
    with open(os.path.join(out, "divergence.csv"), "w") as o:
        o.write("step,gamma,rms_yz_sandcell_lammps_over_d,rms_yz_lammps_newton_on_off_over_d\n")
        for r in div:
            o.write("%d,%.6f,%.4e,%.4e\n" % tuple(r))

    # flips: LAMMPS's tilt of every step (the box of that step's forces); sandcell's single-step rows
    xz = np.loadtxt(args.lammps + ".xz.txt")
    drop = np.nonzero(np.abs(np.diff(xz[:, 1])) > 0.25 * length[0])[0]
    lmp_flips = [int(xz[k + 1, 0]) for k in drop]
    sdrop = np.nonzero(np.abs(np.diff(tilt_all)) > 0.25 * length[0])[0]
    sand_flips = [(int(step_all[k]), int(step_all[k + 1])) for k in sdrop]

    # ------------------------------------------------------------------ report
    print("## Stress, sandcell vs LAMMPS (%d output steps, every %d steps)\n" % (len(step), args.every))
    print("| gamma | p (kPa, sandcell) | " + " | ".join(COMP) + " | largest | LAMMPS newton on vs off |")
    print("|---|---|" + "---|" * 6 + "---|---|")
    for lo, hi in RANGES:
        sel = (gamma >= lo) & (gamma < hi)
        if not sel.any():
            continue
        print("| %.2f-%.2f | %.0f-%.0f | " % (lo, min(hi, gamma.max()), p[sel].min() / 1e3, p[sel].max() / 1e3) +
              " | ".join("%.2g %%" % (100 * rel[sel, c].max()) for c in range(6)) +
              " | %.2g %% | %.2g %% |" % (100 * rel_max[sel].max(), 100 * rel_c_max[sel].max()))
    g1, k1 = first_above(gamma, rel_max, 0.02)
    gc, kc = first_above(gamma, rel_c_max, 0.02)
    print()
    if g1 is not None:
        print("sandcell vs LAMMPS: first above 2 %% at step %d, gamma = %.4f (%s %.2f %%)"
              % (step[k1], g1, COMP[int(np.argmax(rel[k1]))], 100 * rel_max[k1]))
        print("  rows above 2 %%: %d of %d; from gamma %.3f on: %d of %d"
              % ((rel_max > 0.02).sum(), len(rel_max), g1, (rel_max[k1:] > 0.02).sum(), len(rel_max) - k1))
    else:
        print("sandcell vs LAMMPS: within 2 % at every output step")
    if gc is not None:
        print("LAMMPS newton on vs off: first above 2 %% at step %d, gamma = %.4f" % (cs[i_c][kc], gc))
    print("unsymmetrized LAMMPS shear components (raw virial) vs sandcell, largest over gamma < 0.01: "
          + ", ".join("%s %.2g %%" % (COMP[c], 100 * rel_raw[gamma < 0.01, c].max()) for c in (3, 4, 5)))
    print("largest antisymmetric part |raw - sym| / p: %.2g %%" % (100 * (np.abs(Lraw - L) / p[:, None]).max()))
    print("mean overlap / R: %.4f at gamma 0, %.4f at the end; largest overlap / R %.3f"
          % (mean_overlap[0], mean_overlap[-1], max_ov.max()))

    # realizations: the same scene and physics, other round-off (newton off; other neighbour skins)
    sand_runs = [(gamma, S)]
    for path in args.sandcell_more:
        t = h5py.File(path, "r")["series"]
        st = t["step"][:].astype(np.int64)
        k = np.nonzero(np.isin(st, step))[0]
        sand_runs.append((sign * t["deformation"][:, 2][k], t["stress"][:][k]))
    lmp_runs = [(gamma, L), (gamma, C)]
    for prefix in args.lammps_more:
        ms, _, M, _ = read_lammps_stress(prefix, volume)
        k = np.nonzero(np.isin(ms, step))[0]
        lmp_runs.append((gamma[np.searchsorted(step, ms[k])], M[k]))

    def window(runs, lo, hi):
        p_, t_ = [], []
        for g, X in runs:
            sel = (g >= lo) & (g < hi)
            pp = X[sel, :3].mean(axis=1)
            p_.append(pp.mean())
            t_.append((-X[sel, 4] / pp).mean())
        return np.array(p_), np.array(t_)

    print("\n## Means over gamma windows: %d sandcell and %d LAMMPS runs (other round-off)\n"
          % (len(sand_runs), len(lmp_runs)))
    print("| gamma | p, sandcell (kPa): mean [range] | p, LAMMPS | difference of the means | "
          "-S_xz/p, sandcell | -S_xz/p, LAMMPS | difference |")
    print("|---|---|---|---|---|---|---|")
    windows = []
    for lo in np.arange(0.0, 0.6, 0.1):
        ps, ts = window(sand_runs, lo, lo + 0.1)
        pl, tl = window(lmp_runs, lo, lo + 0.1)
        windows.append((lo, ps, pl, ts, tl))
        print("| %.1f-%.1f | %.1f [%.1f, %.1f] | %.1f [%.1f, %.1f] | %+.1f %% | %.3f [%.3f, %.3f] | "
              "%.3f [%.3f, %.3f] | %+.1f %% |"
              % (lo, lo + 0.1, ps.mean() / 1e3, ps.min() / 1e3, ps.max() / 1e3, pl.mean() / 1e3, pl.min() / 1e3,
                 pl.max() / 1e3, 100 * (pl.mean() / ps.mean() - 1), ts.mean(), ts.min(), ts.max(), tl.mean(),
                 tl.min(), tl.max(), 100 * (tl.mean() / ts.mean() - 1)))
    print("\nEach run's window means (p kPa, -S_xz/p), sandcell runs then LAMMPS runs:")
    for lo, ps, pl, ts, tl in windows:
        print("  %.1f-%.1f: " % (lo, lo + 0.1) + ", ".join("%.0f %.3f" % (a, b) for a, b in zip(ps / 1e3, ts)) +
              " | " + ", ".join("%.0f %.3f" % (a, b) for a, b in zip(pl / 1e3, tl)))

    print("\n## Divergence (RMS of the y, z position differences / d)\n")
    print("| gamma | step | sandcell vs LAMMPS | LAMMPS newton on vs off |")
    print("|---|---|---|---|")
    for target in (0.0, 0.0026, 0.005, 0.01, 0.02, 0.03, 0.05, 0.1, 0.2, 0.4, 0.6):
        k = int(np.argmin(np.abs(div[:, 1] - target)))
        print("| %.4f | %d | %.2e | %.2e |" % (div[k, 1], div[k, 0], div[k, 2], div[k, 3]))
    for name, col in (("sandcell vs LAMMPS", 2), ("LAMMPS on vs off", 3)):
        y = div[:, col]
        sel = (y > 1e-9) & (y < 1e-3) & (div[:, 1] > 0)
        if sel.sum() >= 3:
            slope = np.polyfit(div[sel, 1], np.log(y[sel]), 1)[0]
            print("%s: exponential growth between 1e-9 d and 1e-3 d: rate %.0f per unit gamma "
                  "(e-folding strain %.4f), %d snapshots" % (name, slope, 1 / slope, sel.sum()))

    print("\n## Flips")
    print("LAMMPS: box flipped at step(s) %s (gamma %s)" % (
        lmp_flips, ", ".join("%.5f" % g for g in np.interp(lmp_flips, step_all, gamma_all))))
    print("sandcell: tilt flipped between the rows of steps %s (gamma %s)" % (
        sand_flips, ", ".join("%.5f" % gamma_all[k + 1] for k in sdrop)))
    before = gamma < 0.45
    per_step = gamma[1] / (step[1] - 1)
    print("LAMMPS's tilt / L3 (the box of the step's forces) minus sandcell's, before the flips: "
          "%.3f steps of shear" % np.median((sign * lxz[i_l][before] / length[2] - gamma[before]) / per_step))

    plot(out, gamma, S, L, rel, rel_max, rel_c_max, div, np.interp(lmp_flips, step_all, gamma_all))


def plot(out, gamma, S, L, rel, rel_max, rel_c_max, div, gflip):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 2, figsize=(13, 9), constrained_layout=True)
    colors = ["C0", "C1", "C2", "C3", "C4", "C5"]
    a = ax[0, 0]
    for c in range(3):
        a.plot(gamma, S[:, c] / 1e3, color=colors[c], lw=1.2, label="S_%s sandcell" % COMP[c])
        a.plot(gamma, L[:, c] / 1e3, color=colors[c], lw=1.0, ls="--", label="S_%s LAMMPS" % COMP[c])
    a.set_ylabel("normal stress, kPa (compression +)")
    a.set_title("simple shear at constant volume, 2000 spheres: normal stresses")
    a.legend(fontsize=8, ncol=2)
    a = ax[0, 1]
    for c in range(3, 6):
        a.plot(gamma, S[:, c] / 1e3, color=colors[c], lw=1.2, label="S_%s sandcell" % COMP[c])
        a.plot(gamma, L[:, c] / 1e3, color=colors[c], lw=1.0, ls="--", label="S_%s LAMMPS" % COMP[c])
    a.set_ylabel("shear stress, kPa")
    a.set_title("shear stresses (compression positive)")
    a.legend(fontsize=8, ncol=2)
    a = ax[1, 0]
    for c in range(6):
        a.semilogy(gamma, np.maximum(rel[:, c], 1e-9), color=colors[c], lw=0.6, alpha=0.6, label=COMP[c])
    a.semilogy(gamma, np.maximum(rel_max, 1e-9), color="k", lw=1.3, label="largest, sandcell vs LAMMPS")
    a.semilogy(gamma, np.maximum(rel_c_max, 1e-9), color="m", lw=1.3,
               label="largest, LAMMPS newton on vs off")
    a.axhline(0.02, color="r", ls=":", lw=1.5, label="2 %")
    a.set_ylabel("|S_sandcell - S_LAMMPS| / p")
    a.set_xlabel("gamma = |F_xz|")
    a.set_ylim(1e-6, 1)
    a.set_title("relative differences")
    a.legend(fontsize=8, ncol=2, loc="lower right")
    a = ax[1, 1]
    a.semilogy(div[:, 1], div[:, 2], "k.-", ms=3, lw=1, label="sandcell vs LAMMPS")
    a.semilogy(div[:, 1], div[:, 3], "m.-", ms=3, lw=1, label="LAMMPS newton on vs off")
    a.set_xscale("symlog", linthresh=0.01)
    a.set_xlabel("gamma (linear to 0.01, then log)")
    a.set_ylabel("RMS of the y, z position differences / d")
    a.set_title("divergence of the trajectories")
    a.legend(fontsize=8)
    for a in (ax[0, 0], ax[0, 1], ax[1, 0], ax[1, 1]):
        for g in gflip:
            a.axvline(g, color="gray", lw=0.8, ls="-.")
        a.grid(alpha=0.3)
    fig.savefig(os.path.join(out, "comparison.png"), dpi=90)


if __name__ == "__main__":
    main()
