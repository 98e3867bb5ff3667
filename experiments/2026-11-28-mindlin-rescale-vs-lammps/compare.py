#!/usr/bin/env python3
"""sandcell's tangential laws `history` and `mindlin_rescale` against LAMMPS GRANULAR's `mindlin` and
`mindlin_rescale` on oblique collisions of two spheres (Hertz normal law, no damping, Coulomb mu 0.5).

    /usr/bin/python3 experiments/2026-11-28-mindlin-rescale-vs-lammps/compare.py build/release/tests/two-sphere

Needs `lmp` (Debian package lammps). Writes comparison.csv and comparison.png here and prints the table
of the README. The two codes are matched where their conventions agree: no damping (restitution 1 in
sandcell, viscoelastic damping 0 in LAMMPS), the same E*, G*, R*, m*, the contact radius a = sqrt(R* delta),
k_t = 8 G* a, the Coulomb cap on the spring force, velocity Verlet (nve/sphere).
"""
import csv
import os
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
# (name, normal speed, tangential speed): sticking then sliding, mostly sliding, mostly sticking
SCENES = [("oblique 45 deg", 0.5, 0.5), ("grazing", 0.2, 1.0), ("steep", 1.0, 0.1)]
COMMON = dict(R=1e-3, rho=2650.0, E=7e10, nu=0.3, mu=0.5, dt=1e-8, nsteps=3000, gap=1e-7)
LAWS = [("history", "mindlin"), ("mindlin_rescale", "mindlin_rescale")]


def lammps(tang, vn, vt, rot, work):
    out = os.path.join(work, f"lmp-{tang}-{vn}-{vt}-{rot}.txt")
    args = ["lmp", "-in", os.path.join(HERE, "collision.in"), "-log", "none", "-screen", "none"]
    for k, v in dict(COMMON, vn=vn, vt=vt, tang=tang, out=out, rot=rot).items():
        args += ["-var", k, str(v)]
    subprocess.run(args, check=True, cwd=work)
    d = np.loadtxt(out)[1:]  # fix print writes step 0 too; two-sphere starts at step 1
    return d[:, 0], d[:, 4], d[:, 5]  # t, f1x (normal), f1z (tangential)


def sandcell(binary, law, vn, vt, rot):
    c = COMMON
    args = [binary, "--radius", str(c["R"]), "--density", str(c["rho"]), "--young", str(c["E"]), "--poisson",
            str(c["nu"]), "--restitution", "1", "--friction", str(c["mu"]), "--vn", str(vn), "--vt", str(vt), "--dt",
            str(c["dt"]), "--steps", str(c["nsteps"]), "--gap", str(c["gap"]), "--normal", "hertz", "--tangential", law,
            "--rotation", str(rot)]
    rows = list(csv.DictReader(subprocess.run(args, check=True, capture_output=True, text=True).stdout.splitlines()))
    return (np.array([float(r[k]) for r in rows]) for k in ("t", "f1x", "f1z"))


def main(binary):
    results, curves = [], {}
    with tempfile.TemporaryDirectory() as work:
        for (scene, vn, vt), rot in [(sc, r) for r in (0, 1) for sc in SCENES]:
            f_t = {}
            for ours, theirs in LAWS:
                t, fn_s, ft_s = sandcell(binary, ours, vn, vt, rot)
                t_l, fn_l, ft_l = lammps(theirs, vn, vt, rot, work)
                n = min(len(t), len(t_l))
                assert np.allclose(t[:n], t_l[:n], rtol=1e-12, atol=0), "rows of other times"
                scale_t, scale_n = np.abs(ft_l[:n]).max(), np.abs(fn_l[:n]).max()
                results.append(dict(scene=scene, vn=vn, vt=vt, rotation="yes" if rot else "no", sandcell=ours,
                                    lammps=theirs,
                                    max_ft_N=f"{scale_t:.6g}",
                                    ft_difference=f"{np.abs(ft_s[:n] - ft_l[:n]).max() / scale_t:.2e}",
                                    fn_difference=f"{np.abs(fn_s[:n] - fn_l[:n]).max() / scale_n:.2e}"))
                f_t[ours] = ft_s[:n]
                if rot:
                    curves[(scene, ours)] = (t[:n], ft_s[:n], ft_l[:n])
            effect = np.abs(f_t["mindlin_rescale"] - f_t["history"]).max() / np.abs(f_t["history"]).max()
            for r in results[-2:]:
                r["rescale_effect"] = f"{effect:.2e}"
    with open(os.path.join(HERE, "comparison.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(results[0]))
        w.writeheader()
        w.writerows(results)
    print("| scene | spheres turn | sandcell | LAMMPS | max F_t, N | F_t difference | F_n difference "
          "| rescale effect on F_t |")
    print("|---|---|---|---|---|---|---|---|")
    for r in results:
        print(f"| {r['scene']} (vn {r['vn']}, vt {r['vt']} m/s) | {r['rotation']} | {r['sandcell']} | {r['lammps']} "
              f"| {r['max_ft_N']} | "
              f"{r['ft_difference']} | {r['fn_difference']} | {r['rescale_effect']} |")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(SCENES), figsize=(4.2 * len(SCENES), 3.4))
    for ax, (scene, vn, vt) in zip(axes, SCENES):
        for ours, style in (("history", "-"), ("mindlin_rescale", "--")):
            t, fs, fl = curves[(scene, ours)]
            ax.plot(1e6 * t, -fs, style, label=f"sandcell {ours}")
            ax.plot(1e6 * t[::40], -fl[::40], "o" if ours == "history" else "x", ms=3, label=f"LAMMPS ({ours})")
        ax.set(title=f"{scene}: vn {vn}, vt {vt} m/s", xlabel="t (us)", ylabel="tangential force on sphere 1 (N)")
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(HERE, "comparison.png"), dpi=110)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "build/release/tests/two-sphere"))
