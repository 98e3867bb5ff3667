#!/usr/bin/env python3
"""Plot a triaxial results file: deviatoric stress q and volumetric strain eps_v against the axial
strain eps_1 (soil convention, compression positive).

    plot_triaxial.py RESULTS.h5 OUT.png
"""
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt


def main(argv):
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    with h5py.File(argv[1], "r") as f:
        s = f["series"]
        eps1 = 100.0 * s["strain"][:, 0]
        q = s["q"][:] / 1e6
        p = s["p"][:] / 1e6
        eps_v = 100.0 * s["eps_v"][:]
        e = s["e"][:]
        title = f.attrs.get("job", "")
        if isinstance(title, bytes):
            title = title.decode()
    fig, ax = plt.subplots(2, 2, figsize=(10, 7), sharex=True)
    ax[0, 0].plot(eps1, q, "C0")
    ax[0, 0].set_ylabel("q (MPa)")
    ax[0, 1].plot(eps1, q / p, "C1")
    ax[0, 1].set_ylabel("q/p")
    ax[1, 0].plot(eps1, eps_v, "C2")
    ax[1, 0].set_ylabel("eps_v (%) [compression +]")
    ax[1, 1].plot(eps1, e, "C3")
    ax[1, 1].set_ylabel("void ratio e")
    for a in ax[1]:
        a.set_xlabel("axial strain eps_1 (%)")
    for a in ax.flat:
        a.grid(True, alpha=0.3)
    fig.suptitle(f"sandcell triaxial {title}")
    fig.tight_layout()
    fig.savefig(argv[2], dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
