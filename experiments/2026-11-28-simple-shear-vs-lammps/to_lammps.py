#!/usr/bin/python3
"""sandcell's prepared sample -> LAMMPS data file and the pair constants (used by run.sh).

    to_lammps.py SAMPLE.h5 CONFIG.toml CHECKPOINT.h5 OUT_DIR

SAMPLE.h5 is the sample the shear test starts from (sample-p0_*.h5, a sandcell checkpoint),
CONFIG.toml the test's config (shear.toml), CHECKPOINT.h5 the test's checkpoint a few steps in (its
cell's velocity gradient L_xz: the direction of the shear, which LAMMPS's erate takes with its sign;
the app's simple shear paths drove L_xz = +shear.strain_rate before commit 1244a26 and -rate since).
Writes OUT_DIR/sample.data (atom_style sphere, triclinic box with zero tilt, positions,
fluctuating velocities v~ and angular velocities at full precision) and OUT_DIR/vars.txt (one
`-var NAME VALUE` a line for shear.in): the linear spring-dashpot constants of LIGGGHTS `model
hooke` (docs/physics.md section 2.1) that sandcell uses, in pair_style gran/hooke/history's units
(kn, kt in N/m; gamma_n, gamma_t in 1/s, LAMMPS multiplies them by m* = m_i m_j / (m_i + m_j)), the
friction, the time step, the sphere mass, erate = L_xz and the neighbour skin.
"""
import math
import sys
import tomllib

import h5py
import numpy as np


def main(sample, config, checkpoint, out):
    f = h5py.File(sample, "r")
    par = f["particles"]
    ids = par["id"][:]
    x = par["position"][:]
    v = par["velocity"][:]
    w = par["angular_velocity"][:]
    r = par["radius"][:]
    m = par["mass"][:]
    cell = f["cell"].attrs
    L = cell["length"]
    if np.any(cell["tilt"] != 0.0):
        sys.exit("the sample's cell is tilted: this script writes an orthogonal start")
    if np.ptp(r) != 0.0 or np.ptp(m) != 0.0:
        sys.exit("monodisperse spheres only: the constants of gran/hooke/history are global")
    if np.any(f["contacts/tangential"][:] != 0.0):
        sys.exit("the sample has tangential springs: LAMMPS would start without them")

    with open(config, "rb") as c:
        cfg = tomllib.load(c)

    mat = cfg["material"]
    E, nu, e, mu = mat["young"], mat["poisson"], mat["restitution"], mat["friction"]
    # dt = time.dt_fraction x the Rayleigh time of the smallest sphere (engine/model.cpp)
    shear_modulus = E / (2.0 * (1.0 + nu))
    t_r = math.pi * r.min() * math.sqrt(mat["density"] / shear_modulus) / (0.1631 * nu + 0.8766)
    dt = cfg["time"]["dt_fraction"] * t_r  # compare.py checks it against sandcell's series
    V = cfg["contact"]["characteristic_velocity"]
    assert cfg["contact"]["normal"] == "hooke" and cfg["contact"]["tangential"] == "history"
    assert cfg["contact"]["rolling"] == "none"
    rate = float(h5py.File(checkpoint, "r")["cell"].attrs["shear_rate"][1])  # L_xz, 1/s, signed
    if abs(abs(rate) / cfg["shear"]["strain_rate"] - 1.0) > 1e-12:
        sys.exit("the checkpoint's L_xz %g is not +-shear.strain_rate" % rate)
    # docs/physics.md section 2 and 2.1 (systems/laws/hooke.hpp), for two equal spheres
    e_star = 1.0 / (2.0 * (1.0 - nu * nu) / E)
    r_star = r[0] * r[0] / (r[0] + r[0])
    m_star = m[0] * m[0] / (m[0] + m[0])
    sqrt_r = math.sqrt(r_star)
    k_n = 16.0 / 15.0 * sqrt_r * e_star * (15.0 * m_star * V * V / (16.0 * sqrt_r * e_star)) ** 0.2
    beta = math.log(e) / math.sqrt(math.log(e) ** 2 + math.pi ** 2)
    gamma_n = -2.0 * beta * math.sqrt(m_star * k_n)  # N s/m
    g = gamma_n / m_star  # 1/s, LAMMPS's gamma_n and gamma_t

    with open(f"{out}/sample.data", "w") as o:
        o.write("sandcell sample %s (positions, v~, omega), monodisperse\n\n" % sample)
        o.write("%d atoms\n1 atom types\n\n" % len(ids))
        o.write("0 %.17g xlo xhi\n0 %.17g ylo yhi\n0 %.17g zlo zhi\n0 0 0 xy xz yz\n\n" % tuple(L))
        o.write("Atoms # sphere\n\n")
        density = mat["density"]
        for k in range(len(ids)):
            o.write("%d 1 %.17g %.17g %.17g %.17g %.17g\n" % (ids[k] + 1, 2 * r[k], density, *x[k]))
        o.write("\nVelocities\n\n")
        for k in range(len(ids)):
            o.write("%d %.17g %.17g %.17g %.17g %.17g %.17g\n" % (ids[k] + 1, *v[k], *w[k]))
    with open(f"{out}/vars.txt", "w") as o:
        for name, val in [("kn", k_n), ("kt", k_n), ("gn", g), ("gt", g), ("mu", mu), ("dt", dt),
                          ("mass", m[0]), ("erate", rate),
                          ("skin", 0.2 * r[0])]:
            o.write("-var %s %.17g\n" % (name, val))
    print("k_n = %.6g N/m, gamma_n = %.6g N s/m (%.6g 1/s x m*), dt = %.6g s, t_c = %.4g s = %.1f dt"
          % (k_n, gamma_n, g, dt, math.pi / math.sqrt(k_n / m_star - (gamma_n / (2 * m_star)) ** 2),
             math.pi / math.sqrt(k_n / m_star - (gamma_n / (2 * m_star)) ** 2) / dt))


if __name__ == "__main__":
    main(*sys.argv[1:5])
