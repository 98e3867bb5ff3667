"""The measures and figures of the paths of a shearing cell (docs/physics.md sections 1 and 6.0):
simple shear (stress ratio and volumetric strain against the shear strain) and the rotation of the
principal stresses (the non-coaxiality of the principal stress and strain-increment directions
against the stress's angle).

Conventions (soil mechanics, compression positive): the series' stress S (xx yy zz xy xz yz); the
deformation F = H N H0^-1 (row-major), gamma = -F_xz (the engineering shear strain, positive as the
simple shear paths drive it); the strain increment between two rows is
d_eps = -sym(F_next F^-1 - I) (the velocity gradient integrated over the interval, compression
positive). In the xz plane (the rotation's plane, y the intermediate axis) the angle of a symmetric
tensor's major principal direction from x toward z is alpha = atan2(2 T_xz, T_xx - T_zz) / 2, in
(-90, 90] degrees; the non-coaxiality is alpha(S) - alpha(d_eps), folded into (-90, 90].
"""
import math

import numpy as np

from .results import InputError, open_results

SHEARING_PATHS = ("simple_shear", "simple_shear_cv", "rotation")


def read_shearing(path):
    """The series a shearing test's figures need: time, stress (n, 6), F (n, 3, 3), eps_v, e."""
    with open_results(path) as f:
        if "series" not in f:
            raise InputError(f"cannot read {path}: no /series group")
        s = f["series"]
        missing = [k for k in ("time", "stress", "deformation", "eps_v", "e") if k not in s]
        if missing:
            raise InputError(f"cannot read {path}: /series lacks {', '.join(missing)} "
                             "(written by sandcell versions with the shearing cell)")
        n = min(s[k].shape[0] for k in ("time", "stress", "deformation", "eps_v", "e"))
        out = {k: np.asarray(s[k][:n], float) for k in ("time", "stress", "eps_v", "e")}
        out["F"] = np.asarray(s["deformation"][:n], float).reshape(n, 3, 3)
    return out


def major_angle_xz(xx, zz, xz):
    """Angle (degrees, in (-90, 90]) of the major principal direction in the xz plane, from x toward z."""
    return 0.5 * np.degrees(np.arctan2(2.0 * xz, xx - zz))


def fold(angle):
    """An axis angle difference folded into (-90, 90] degrees (a direction and its opposite are one axis)."""
    return (np.asarray(angle) + 90.0) % 180.0 - 90.0


def strain_increments(F):
    """d_eps between consecutive rows, compression positive: -sym(F_{k+1} F_k^-1 - I), shape (n-1, 3, 3)."""
    g = np.einsum("kij,kjl->kil", F[1:], np.linalg.inv(F[:-1])) - np.eye(3)
    return -0.5 * (g + np.transpose(g, (0, 2, 1)))


def simple_shear_measures(d):
    """gamma = -F_xz, tau / sigma_n = S_xz / S_zz (positive for gamma growing), eps_v and e."""
    s = d["stress"]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = s[:, 4] / s[:, 2]
    return {"gamma": -d["F"][:, 0, 2], "ratio": ratio, "sigma_n": s[:, 2], "eps_v": d["eps_v"], "e": d["e"]}


def rotation_measures(d, min_increment=1e-9):
    """Per interval between rows: the stress's major direction alpha_s (mean of the two rows), the
    strain increment's alpha_e and the non-coaxiality alpha_s - alpha_e (folded); intervals whose
    deviatoric increment is below min_increment (no measurable strain) are NaN."""
    s = d["stress"]
    a_s = major_angle_xz(s[:, 0], s[:, 2], s[:, 4])
    mid = a_s[:-1] + 0.5 * fold(a_s[1:] - a_s[:-1])
    de = strain_increments(d["F"])
    dev = de - np.einsum("kii->k", de)[:, None, None] / 3.0 * np.eye(3)
    size = np.sqrt(np.einsum("kij,kij->k", dev, dev))
    a_e = major_angle_xz(de[:, 0, 0], de[:, 2, 2], de[:, 0, 2])
    non = fold(mid - a_e)
    non[size < min_increment] = math.nan
    return {"alpha": fold(mid), "alpha_strain": a_e, "noncoaxiality": non, "increment": size,
            "time": 0.5 * (d["time"][1:] + d["time"][:-1])}


def figures(plt, tests, out, title, files, save):
    """One figure per shearing test: simple shear (tau/sigma_n and eps_v against gamma) or rotation
    (non-coaxiality against the unwrapped alpha of the stress). `tests` are read_test dicts (their
    file and path); `save(fig, out, stem, files)` writes it."""
    for t in tests:
        if t["path"] not in SHEARING_PATHS:
            continue
        d = read_shearing(t["file"])
        if t["path"] == "rotation":
            m = rotation_measures(d)
            turned = np.degrees(np.unwrap(np.radians(2.0 * m["alpha"]))) / 2.0
            fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
            ax[0].plot(turned, m["noncoaxiality"], ".", ms=3, color="C0")
            ax[0].axhline(0.0, color="0.5", lw=0.8)
            ax[0].set_xlabel("alpha of sigma_1 from x toward z (deg, unwrapped)")
            ax[0].set_ylabel("non-coaxiality alpha_sigma - alpha_deps (deg)")
            ax[1].plot(turned, turned - m["noncoaxiality"], ".", ms=3, color="C1", label="strain increment")
            ax[1].plot(turned, turned, "-", color="C0", lw=1, label="stress")
            ax[1].set_xlabel("alpha of sigma_1 (deg, unwrapped)")
            ax[1].set_ylabel("major principal direction (deg, unwrapped)")
            ax[1].legend(fontsize=8)
        else:
            m = simple_shear_measures(d)
            fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
            ax[0].plot(100.0 * m["gamma"], m["ratio"], color="C0")
            ax[0].set_xlabel("shear strain gamma (%)")
            ax[0].set_ylabel("tau / sigma_n = S_xz / S_zz")
            ax[1].plot(100.0 * m["gamma"], 100.0 * m["eps_v"], color="C2")
            ax[1].set_xlabel("shear strain gamma (%)")
            ax[1].set_ylabel("eps_v (%) [compression +]")
        for a in ax:
            a.grid(True, alpha=0.3)
        fig.suptitle(f"{title}: {t['name']} ({t['path']})", fontsize=10)
        fig.tight_layout()
        save(fig, out, f"shearing-{t['name']}", files)
        plt.close(fig)


def plot_run(results, png, path, title):
    """The per-test figure of a shearing path (the app's output.plot)."""
    from .plots import pyplot
    plt = pyplot()
    files = []

    def save(fig, out, stem, names):
        fig.savefig(png, dpi=110)
        names.append(png)

    figures(plt, [{"path": path, "file": results, "name": title}], None, "sandcell triaxial", files, save)
