#!/usr/bin/python3
"""The first 0.05 of shear strain, every 200 steps, with and without damping (run.sh runs it).

    early.py --dir DIR --out OUT

DIR holds, for each restitution e in 0.5 and 1.0, sandcell's results e<e>/sand/sscv-p0_100kPa.h5
(series and snapshots every 200 steps) and LAMMPS's e<e>-on.* (newton on) and e<e>-off.* (newton
off) outputs of shear.in, and e05-deform2.* (e = 0.5, newton on, the box deformed every 2 steps: the
lag of LAMMPS's box behind the positions doubled). With e = 1 there is no damping: the two codes'
contact laws then differ only by the levers (LAMMPS R, sandcell R - delta/2); with e = 0.5 also by
the damping of a sliding contact (LIGGGHTS/sandcell: none, the spring force capped; LAMMPS
gran/hooke/history: spring plus dashpot capped together, README.md). Writes OUT/early.csv and
OUT/early.png and prints a table.
"""
import argparse
import os

import h5py
import numpy as np

from compare import read_lammps_positions, read_lammps_stress, rms_yz


def one(dirname, e):
    f = h5py.File(os.path.join(dirname, "e%s/sand/sscv-p0_100kPa.h5" % e), "r")
    s = f["series"]
    snaps = f["snapshots"]
    first = snaps[sorted(snaps.keys())[0]]
    length = np.array(first.attrs["cell_length"])
    volume = float(np.prod(length))
    d = 2 * first["radius"][0]
    n = len(first["radius"])
    step = s["step"][:].astype(np.int64)
    gamma = np.abs(s["deformation"][:, 2])  # the direction of the shear: compare.py
    S = s["stress"][:]
    p = S[:, :3].mean(axis=1)
    on = os.path.join(dirname, "e%s-on" % ("05" if e == "0.5" else "1"))
    off = os.path.join(dirname, "e%s-off" % ("05" if e == "0.5" else "1"))
    ls, _, L, _ = read_lammps_stress(on, volume)
    cs, _, C, _ = read_lammps_stress(off, volume)
    common = np.intersect1d(np.intersect1d(step, ls), cs)
    i_s, i_l, i_c = (np.searchsorted(a, common) for a in (step, ls, cs))
    rel = (np.abs(S[i_s] - L[i_l]) / p[i_s, None]).max(axis=1)
    relc = (np.abs(L[i_l] - C[i_c]) / p[i_s, None]).max(axis=1)
    lpos, cpos = read_lammps_positions(on, n), read_lammps_positions(off, n)
    div, divc = [], []
    for st in common:
        g = snaps["%012d" % st]
        xs = g["position"][:][np.argsort(g["id"][:])]
        div.append(rms_yz(xs, lpos[st], length) / d)
        divc.append(rms_yz(lpos[st], cpos[st], length) / d)
    out = dict(step=common, gamma=gamma[i_s], p=p[i_s], rel=rel, relc=relc, div=np.array(div),
               divc=np.array(divc), ke=(s["kinetic_energy"][:] / s["elastic_energy"][:])[i_s])
    probe = os.path.join(dirname, "e05-deform2")
    if e == "0.5" and os.path.exists(probe + ".stress.txt"):
        ds, _, D, _ = read_lammps_stress(probe, volume)
        i_d = np.searchsorted(ds, common)
        assert np.array_equal(ds[i_d], common)
        out["reld"] = (np.abs(L[i_l] - D[i_d]) / p[i_s, None]).max(axis=1)
        dpos = read_lammps_positions(probe, n)
        out["divd"] = np.array([rms_yz(lpos[st], dpos[st], length) / d for st in common])
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dir", required=True)
    ap.add_argument("--out", default=".")
    args = ap.parse_args()
    runs = {e: one(args.dir, e) for e in ("0.5", "1.0")}
    with open(os.path.join(args.out, "early.csv"), "w") as o:
        o.write("step,gamma," + ",".join("%s_e%s" % (q, e) for e in runs for q in
                ("p_Pa", "rel_max_sandcell_lammps", "rel_max_lammps_on_off", "rms_yz_sandcell_lammps_over_d",
                 "rms_yz_lammps_on_off_over_d")) + ",rel_max_lammps_deform1_deform2_e0.5,"
                "rms_yz_lammps_deform1_deform2_over_d_e0.5\n")
        a, b = runs["0.5"], runs["1.0"]
        assert np.array_equal(a["step"], b["step"])
        for k in range(len(a["step"])):
            o.write("%d,%.6f" % (a["step"][k], a["gamma"][k]))
            for r in (a, b):
                o.write(",%.6g,%.3e,%.3e,%.3e,%.3e" % (r["p"][k], r["rel"][k], r["relc"][k], r["div"][k], r["divc"][k]))
            o.write(",%.3e,%.3e\n" % (a["reld"][k], a["divd"][k]))

    print("## The first 0.05 of shear strain: largest |dS|/p and RMS y,z position difference / d\n")
    print("| step | gamma | e = 0.5: sandcell vs LAMMPS | LAMMPS on vs off | LAMMPS box every step vs every "
          "2 steps | e = 1: sandcell vs LAMMPS | LAMMPS on vs off |")
    print("|---|---|---|---|---|---|---|")
    a, b = runs["0.5"], runs["1.0"]
    for st in (200, 400, 1000, 2000, 4000, 8000, 12000, 16000, 24000, 32000, 39000):
        k = int(np.searchsorted(a["step"], st))
        if k >= len(a["step"]):
            continue
        print("| %d | %.4f | %.2g, %.2g d | %.2g, %.2g d | %.2g, %.2g d | %.2g, %.2g d | %.2g, %.2g d |"
              % (a["step"][k], a["gamma"][k], a["rel"][k], a["div"][k], a["relc"][k], a["divc"][k],
                 a["reld"][k], a["divd"][k], b["rel"][k], b["div"][k], b["relc"][k], b["divc"][k]))
    for e, r in runs.items():
        for name, col in (("sandcell vs LAMMPS", "rel"), ("LAMMPS on vs off", "relc")):
            idx = np.nonzero(r[col] > 0.02)[0]
            print("e = %s, %s: first above 2 %% at %s" % (
                e, name, "gamma %.4f (step %d)" % (r["gamma"][idx[0]], r["step"][idx[0]]) if len(idx) else "none"))
        print("e = %s: kinetic / elastic energy, median over the run %.2g" % (e, np.median(r["ke"])))

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(13, 4.5), constrained_layout=True)
    for e, r, c in (("0.5", a, "k"), ("1.0", b, "C1")):
        ax[0].semilogy(r["gamma"], np.maximum(r["rel"], 1e-12), color=c, label="e = %s, sandcell vs LAMMPS" % e)
        ax[0].semilogy(r["gamma"], np.maximum(r["relc"], 1e-12), color=c, ls=":",
                       label="e = %s, LAMMPS newton on vs off" % e)
        ax[1].semilogy(r["gamma"], np.maximum(r["div"], 1e-17), color=c, label="e = %s, sandcell vs LAMMPS" % e)
        ax[1].semilogy(r["gamma"], np.maximum(r["divc"], 1e-17), color=c, ls=":",
                       label="e = %s, LAMMPS newton on vs off" % e)
    ax[0].semilogy(a["gamma"], np.maximum(a["reld"], 1e-12), color="C2", lw=0.8,
                   label="e = 0.5, LAMMPS box deformed every step vs every 2 steps")
    ax[1].semilogy(a["gamma"], np.maximum(a["divd"], 1e-17), color="C2", lw=0.8,
                   label="e = 0.5, LAMMPS box deformed every step vs every 2 steps")
    ax[0].axhline(0.02, color="r", ls=":", label="2 %")
    ax[0].set_ylabel("largest |S_a - S_b| / p")
    ax[1].set_ylabel("RMS of the y, z position differences / d")
    for x in ax:
        x.set_xlabel("gamma")
        x.grid(alpha=0.3)
        x.legend(fontsize=8)
    ax[0].set_title("stress, every 200 steps")
    ax[1].set_title("trajectories, every 200 steps")
    fig.savefig(os.path.join(args.out, "early.png"), dpi=80)


if __name__ == "__main__":
    main()
