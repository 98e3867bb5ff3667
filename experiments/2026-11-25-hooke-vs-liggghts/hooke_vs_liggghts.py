#!/usr/bin/python3
"""Two-sphere collisions with the linear spring-dashpot ("hooke") law: LIGGGHTS against the
analytic solution, against a step-by-step Python replica of LIGGGHTS' algorithm, and (optionally)
against sandcell.

    /usr/bin/python3 experiments/2026-11-25-hooke-vs-liggghts/hooke_vs_liggghts.py [--sandcell BIN]
        [--steps-per-contact 50] [--fine 500,5000] [--csv FILE] [--png FILE]

(--csv and --png default to hooke-vs-liggghts.csv and .png beside this script.)

Needs the Debian packages liggghts, python3-numpy and python3-matplotlib.

What LIGGGHTS 3.8.0 computes (`pair_style gran model hooke tangential history`, defaults
tangential_damping on, ktToKnUser off, limitForce off; src/normal_model_hooke.h,
src/tangential_model_history.h, src/surface_model_default.h, src/global_properties.cpp,
src/pair_gran_base.h, src/fix_nve_sphere.cpp) for spheres i, j:

    E*  = 1 / ((1-nu_i^2)/E_i + (1-nu_j^2)/E_j)      R* = R_i R_j/(R_i+R_j)
    m*  = m_i m_j/(m_i+m_j)                          V  = characteristicVelocity
    k_n = 16/15 sqrt(R*) E* (15 m* V^2 / (16 sqrt(R*) E*))^(1/5)
    k_t = k_n                      (2/7 k_n only with ktToKnUser on)
    gamma_n = sqrt(4 m* k_n ln(e)^2 / (ln(e)^2 + pi^2))   (= sqrt(4 m* k_n/(1+(pi/ln e)^2)), m* not m*/2)
    gamma_t = gamma_n              (0 with tangential_damping off)
    delta = R_i + R_j - r,  n = (x_i - x_j)/r,  v_n = (v_i - v_j).n
    F_n = k_n delta - gamma_n v_n  (may be < 0 at the end of a contact: limitForce is off)
    c_i = R_i - delta/2,  v_t = (v_i - v_j) - v_n n + n x (c_i w_i + c_j w_j)
    u  += v_t dt, then u -= (u.n) n           (projected, not rotated: its length may shrink)
    F_t = -k_t u;  if |F_t| > mu |F_n|:  F_t *= mu|F_n|/|F_t|, u = -F_t/k_t   (no damping)
                   else:                 F_t -= gamma_t v_t  (damping added after the Coulomb test,
                                                             so |F_t| may exceed mu|F_n| in stick)
    force on i: F_n n + F_t, on j the opposite; torque on i: -c_i n x F_t, on j: -c_j n x F_t
    integration (fix nve/sphere): velocity Verlet with I = 0.4 m R^2; the contact force is
    evaluated with the half-step velocities.

For a head-on collision the relative overlap obeys m* delta'' + gamma_n delta' + k_n delta = 0,
so with zeta = gamma_n/(2 m*) and w_d = sqrt(k_n/m* - zeta^2):
    delta(t) = v0/w_d exp(-zeta t) sin(w_d t),  t_c = pi/w_d,  e_out = exp(-zeta t_c) = e exactly.
An oblique collision that slides during the whole contact receives the tangential impulse
J_t = mu Int |F_n| dt and the angular impulse mu Int c |F_n| dt on each sphere (closed-form F_n,
fixed normal: the normal's rotation during the contact is neglected, an error of order
(v_t/v_n)^2 delta_max/R).

------------------------------------------------------------------------------------------------
The sandcell side: `--sandcell BIN`  (see run_sandcell below)
------------------------------------------------------------------------------------------------
BIN is run once per scene as

    BIN --radius R --density RHO --young E --poisson NU --restitution E_REST --friction MU
        --vn VN --vt VT --vchar VCHAR --dt DT --steps N --gap GAP

(all SI, every option always given, values printed with repr() so they round-trip exactly). The
scene it must build: two spheres of radius R, density RHO, material (E, NU, E_REST, MU), contact
law hooke with characteristic velocity VCHAR; sphere 1 at (-(R + GAP/2), 0, 0) with velocity
(+VN/2, 0, +VT/2), sphere 2 at (+(R + GAP/2), 0, 0) with velocity (-VN/2, 0, -VT/2), no initial
rotation, no gravity, no walls, a cell (or box) large enough that nothing else touches (e.g. a
periodic cube of edge >= 20 R); time step DT, N steps.

It prints CSV on stdout: one header line, then one row after each step (steps 1..N, not step 0),
values with at least 15 significant digits (e.g. %.17g):

    t,x1,x2,z1,z2,v1x,v2x,v1z,v2z,w1y,w2y,f1x,f1z

t = step * DT; x/z = positions of the sphere centres, v = velocities, w1y/w2y = angular velocity
about y, f1x/f1z = total force on sphere 1 at the end of the step (the contact force). Required
columns: t,x1,x2,v1x,v2x; z1,z2,v1z,v2z,w1y,w2y are needed for oblique scenes (VT != 0); f1x,f1z
are optional (used for the force curves of the figure). Columns may come in any order; lines
starting with '#' and anything on stderr are ignored; a non-zero exit status is an error. This is
exactly what collision.in (beside this script) makes LIGGGHTS print (there space-separated), so the two
tables can be compared row by row.

With no --sandcell the script compares LIGGGHTS with the analytic solution and with the replica
only, and the figure shows where sandcell's curve will go.
"""
import argparse
import math
import os
import shutil
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))  # the experiment's folder
INPUT = os.path.join(HERE, "collision.in")
COLUMNS = ["t", "x1", "x2", "z1", "z2", "v1x", "v2x", "v1z", "v2z", "w1y", "w2y", "f1x", "f1z"]

BASE = dict(R=1e-3, rho=2650.0, E=7e10, nu=0.3, e=0.9, mu=0.5, vn=1.0, vt=0.0, vchar=1.0)

# The scenes: four head-on collisions (e x impact velocity, char. velocity = impact velocity) and
# two oblique ones at mu = 0.5: v_t/v_n = 0.5 sticks then slips, v_t/v_n = 5 slides throughout.
SCENES = [
    dict(name="normal-e0.5-v0.1", e=0.5, vn=0.1, vchar=0.1),
    dict(name="normal-e0.5-v1", e=0.5, vn=1.0, vchar=1.0),
    dict(name="normal-e0.9-v0.1", e=0.9, vn=0.1, vchar=0.1),
    dict(name="normal-e0.9-v1", e=0.9, vn=1.0, vchar=1.0),
    dict(name="oblique-stick-slip", e=0.9, vn=0.1, vt=0.05, vchar=0.1),
    dict(name="oblique-sliding", e=0.9, vn=0.1, vt=0.5, vchar=0.1),
]


def scene_params(s):
    p = dict(BASE)
    p.update(s)
    return p


# ------------------------------------------------------------------------------ LIGGGHTS' law
def constants(p):
    """The pair's constants exactly as LIGGGHTS 3.8.0 forms them (see the module docstring)."""
    R, rho, E, nu = p["R"], p["rho"], p["E"], p["nu"]
    m = rho * 4.0 / 3.0 * math.pi * R ** 3
    meff = m * m / (m + m)
    reff = R * R / (R + R)
    yeff = 1.0 / ((1.0 - nu ** 2) / E + (1.0 - nu ** 2) / E)
    sq = math.sqrt(reff)
    kn = 16.0 / 15.0 * sq * yeff * math.pow(15.0 * meff * p["vchar"] ** 2 / (16.0 * sq * yeff), 0.2)
    lne = math.log(p["e"])
    gn = math.sqrt(4.0 * meff * kn * lne * lne / (lne * lne + math.pi ** 2))
    zeta = gn / (2.0 * meff)
    wd = math.sqrt(kn / meff - zeta ** 2)
    return dict(m=m, meff=meff, reff=reff, yeff=yeff, kn=kn, kt=kn, gn=gn, gt=gn,
                zeta=zeta, wd=wd, tc=math.pi / wd, inertia=0.4 * m * R * R)


def analytic(p, t):
    """Head-on closed form: overlap, its rate and the normal force at times t after first touch."""
    c = constants(p)
    v0, z, w = p["vn"], c["zeta"], c["wd"]
    t = np.clip(t, 0.0, c["tc"])
    ex = np.exp(-z * t)
    d = v0 / w * ex * np.sin(w * t)
    dd = v0 * ex * (np.cos(w * t) - z / w * np.sin(w * t))
    fn = c["kn"] * d + c["gn"] * dd
    return d, dd, fn


def analytic_numbers(p):
    c = constants(p)
    tm = math.atan2(c["wd"], c["zeta"]) / c["wd"]
    dmax = p["vn"] / c["wd"] * math.exp(-c["zeta"] * tm) * math.sin(c["wd"] * tm)
    out = dict(e=math.exp(-c["zeta"] * c["tc"]), tc=c["tc"], dmax=dmax)
    if p["vt"] != 0.0:
        # whole-contact sliding: impulses of mu|F_n| (closed-form F_n, fine quadrature)
        t = np.linspace(0.0, c["tc"], 200001)
        d, _, fn = analytic(p, t)
        jt = p["mu"] * np.trapz(np.abs(fn), t)
        jw = p["mu"] * np.trapz((p["R"] - 0.5 * d) * np.abs(fn), t)
        m = c["m"]
        out.update(v1z=p["vt"] / 2 - jt / m, w1y=jw / c["inertia"],
                   slides=p["vt"] - 7.0 * jt / m > 0.0,
                   int_fn=np.trapz(fn, t), int_abs_fn=np.trapz(np.abs(fn), t))
    return out


# ------------------------------------------------------------------------------ the replica
def replica(p, dt, nsteps, gap):
    """LIGGGHTS' algorithm step by step in Python (two spheres, the same operations in the same
    order): the check that the formulas above are what LIGGGHTS does."""
    c = constants(p)
    R, m = p["R"], c["m"]
    kn, kt, gn, gt, mu = c["kn"], c["kt"], c["gn"], c["gt"], p["mu"]
    x0 = R + 0.5 * gap
    x = np.array([[-x0, 0.0, 0.0], [x0, 0.0, 0.0]])
    v = np.array([[0.5 * p["vn"], 0.0, 0.5 * p["vt"]], [-0.5 * p["vn"], 0.0, -0.5 * p["vt"]]])
    w = np.zeros((2, 3))
    shear = np.zeros(3)
    dtf = 0.5 * dt
    dtfm = dtf / m
    dtir = dtf / 0.4 / (R * R * m)

    def forces():
        nonlocal shear
        f = np.zeros((2, 3))
        tq = np.zeros((2, 3))
        delta = x[0] - x[1]
        rsq = delta @ delta
        if rsq >= (2 * R) ** 2:
            shear = np.zeros(3)
            return f, tq
        r = math.sqrt(rsq)
        en = delta / r
        vr = v[0] - v[1]
        vn = vr @ en
        vt = vr - vn * en
        dn = 2 * R - r
        cri = crj = R - 0.5 * dn
        wr = (cri * w[0] + crj * w[1]) / r
        vtr = vt - np.array([delta[2] * wr[1] - delta[1] * wr[2],
                             delta[0] * wr[2] - delta[2] * wr[0],
                             delta[1] * wr[0] - delta[0] * wr[1]])
        fn = kn * dn - gn * vn
        shear = shear + vtr * dt
        shear = shear - (shear @ en) * en
        shrmag = math.sqrt(shear @ shear)
        ft = -kt * shear
        if kt * shrmag > mu * abs(fn):
            if shrmag != 0.0:
                ft = ft * (mu * abs(fn) / (kt * shrmag))
                shear = -ft / kt
            else:
                ft = np.zeros(3)
        else:
            ft = ft - gt * vtr
        tor = np.cross(en, ft)
        f[0] = fn * en + ft
        f[1] = -f[0]
        tq[0] = -cri * tor
        tq[1] = -crj * tor
        return f, tq

    f, tq = forces()
    rows = []
    for step in range(1, nsteps + 1):
        v += dtfm * f
        x += dt * v
        w += dtir * tq
        f, tq = forces()
        v += dtfm * f
        w += dtir * tq
        rows.append([step * dt, x[0, 0], x[1, 0], x[0, 2], x[1, 2], v[0, 0], v[1, 0], v[0, 2],
                     v[1, 2], w[0, 1], w[1, 1], f[0, 0], f[0, 2]])
    a = np.array(rows)
    return {k: a[:, i] for i, k in enumerate(COLUMNS)}


# ------------------------------------------------------------------------------ the two codes
def run_liggghts(p, dt, nsteps, gap, work):
    out = os.path.join(work, "collision.txt")
    cmd = ["liggghts", "-in", INPUT, "-log", "none", "-echo", "none"]
    for k in ("R", "rho", "E", "nu", "e", "mu", "vn", "vt", "vchar"):
        cmd += ["-var", k, repr(float(p[k]))]
    cmd += ["-var", "dt", repr(dt), "-var", "nsteps", str(nsteps), "-var", "gap", repr(gap),
            "-var", "out", out]
    r = subprocess.run(cmd, cwd=work, capture_output=True, text=True)
    if r.returncode != 0 or not os.path.exists(out):
        sys.exit(f"liggghts failed ({r.returncode}):\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}")
    a = np.loadtxt(out, comments="#", ndmin=2)
    return {k: a[:, i] for i, k in enumerate(COLUMNS)}


# ==============================================================================================
# SANDCELL SIDE: the one function to keep in step with the C++ program (contract in the
# module docstring). Returns the same dict of numpy arrays as run_liggghts: t, x1, x2, z1, z2,
# v1x, v2x, v1z, v2z, w1y, w2y, f1x, f1z (missing optional columns come back as NaN).
# ==============================================================================================
def run_sandcell(p, dt, nsteps, gap, binary):
    cmd = [binary, "--radius", repr(float(p["R"])), "--density", repr(float(p["rho"])),
           "--young", repr(float(p["E"])), "--poisson", repr(float(p["nu"])),
           "--restitution", repr(float(p["e"])), "--friction", repr(float(p["mu"])),
           "--vn", repr(float(p["vn"])), "--vt", repr(float(p["vt"])),
           "--vchar", repr(float(p["vchar"])), "--dt", repr(dt), "--steps", str(nsteps),
           "--gap", repr(gap)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"sandcell failed ({r.returncode}): {' '.join(cmd)}\n{r.stderr[-3000:]}")
    lines = [ln for ln in r.stdout.splitlines() if ln.strip() and not ln.startswith("#")]
    header = [h.strip() for h in lines[0].split(",")]
    a = np.array([[float(x) for x in ln.split(",")] for ln in lines[1:]], ndmin=2)
    out = {}
    for k in COLUMNS:
        out[k] = a[:, header.index(k)] if k in header else np.full(len(a), np.nan)
    for k in ("t", "x1", "x2", "v1x", "v2x"):
        if k not in header:
            sys.exit(f"sandcell output lacks the column {k} (has {header})")
    if p["vt"] != 0.0:
        for k in ("z1", "z2", "v1z", "v2z", "w1y", "w2y"):
            if k not in header:
                sys.exit(f"sandcell output lacks the column {k}, needed for an oblique scene")
    return out


# ------------------------------------------------------------------------------ measurements
def measure(d, p):
    """e, contact time, peak overlap and the rebound from one trajectory table."""
    R = p["R"]
    dz = np.nan_to_num(d["z2"] - d["z1"])
    r = np.hypot(d["x2"] - d["x1"], dz)
    ov = 2 * R - r
    t = d["t"]
    inside = np.nonzero(ov > 0)[0]
    if len(inside) == 0:
        sys.exit("no contact in the run")
    i0, i1 = inside[0], inside[-1]
    if i0 == 0 or i1 == len(t) - 1:
        sys.exit("run too short: the contact is not enclosed")
    # crossings by linear interpolation between the rows either side
    ts = t[i0 - 1] + (t[i0] - t[i0 - 1]) * (-ov[i0 - 1]) / (ov[i0] - ov[i0 - 1])
    te = t[i1] + (t[i1 + 1] - t[i1]) * ov[i1] / (ov[i1] - ov[i1 + 1])
    vrel0 = d["v1x"][0] - d["v2x"][0]
    vrel1 = d["v1x"][-1] - d["v2x"][-1]
    m = dict(e=-vrel1 / vrel0, tc=te - ts, dmax=ov.max(), t_start=ts, overlap=ov,
             steps_in_contact=int(i1 - i0 + 1))
    if p["vt"] != 0.0:
        # normal restitution along the separation direction at the end, and the rebound
        n1 = np.array([d["x1"][-1] - d["x2"][-1], d["z1"][-1] - d["z2"][-1]])
        n1 /= np.linalg.norm(n1)
        vr1 = np.array([vrel1, d["v1z"][-1] - d["v2z"][-1]])
        m.update(e_n=(vr1 @ n1) / vrel0, v1x=d["v1x"][-1], v1z=d["v1z"][-1], w1y=d["w1y"][-1],
                 w2y=d["w2y"][-1])
        # Coulomb check on each contact step: |F_t| / (mu |F_n|) in the frame of that step
        sl = slice(i0, i1 + 1)
        nx = (d["x1"][sl] - d["x2"][sl]) / r[sl]
        nz = (d["z1"][sl] - d["z2"][sl]) / r[sl]
        fn = d["f1x"][sl] * nx + d["f1z"][sl] * nz
        ftn = np.abs(-d["f1x"][sl] * nz + d["f1z"][sl] * nx)
        ratio = ftn / (p["mu"] * np.abs(fn))
        m.update(cap_ratio_max=float(ratio.max()),
                 slip_fraction=float(np.mean(np.abs(ratio - 1.0) < 1e-9)))
    return m


def digits(a, b):
    """Agreeing significant digits, -log10 of the relative difference (16 = identical)."""
    if a == b:
        return 16.0
    return min(16.0, -math.log10(abs(a - b) / abs(b)))


# ------------------------------------------------------------------------------ main
def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sandcell", help="the sandcell two-sphere program (contract in the docstring)")
    ap.add_argument("--steps-per-contact", type=float, default=50.0,
                    help="dt = t_c / this (default 50)")
    ap.add_argument("--fine", default="500,5000",
                    help="more LIGGGHTS runs at dt = t_c / each of these, for the convergence "
                         "(comma-separated; '' for none)")
    ap.add_argument("--csv", default=os.path.join(HERE, "hooke-vs-liggghts.csv"))
    ap.add_argument("--png", default=os.path.join(HERE, "hooke-vs-liggghts.png"))
    args = ap.parse_args()
    if shutil.which("liggghts") is None:
        sys.exit("liggghts not installed: apt-get install liggghts")
    if args.sandcell and not os.access(args.sandcell, os.X_OK):
        sys.exit(f"--sandcell {args.sandcell}: not an executable")

    work = tempfile.mkdtemp(prefix="hooke-")
    rows, curves = [], []
    try:
        for s in SCENES:
            p = scene_params(s)
            c = constants(p)
            an = analytic_numbers(p)
            runs = [("liggghts", args.steps_per_contact)]
            runs += [("liggghts", float(x)) for x in args.fine.split(",") if x.strip()]
            runs.append(("replica", args.steps_per_contact))
            if args.sandcell:
                runs.append(("sandcell", args.steps_per_contact))
            for code, spc in runs:
                dt = c["tc"] / spc
                gap = 2.5 * p["vn"] * dt
                nsteps = int(math.ceil((gap / p["vn"] + 1.3 * c["tc"]) / dt)) + 5
                if code == "liggghts":
                    d = run_liggghts(p, dt, nsteps, gap, work)
                elif code == "replica":
                    d = replica(p, dt, nsteps, gap)
                else:
                    d = run_sandcell(p, dt, nsteps, gap, args.sandcell)
                ms = measure(d, p)
                row = dict(scene=s["name"], code=code, steps_per_contact=spc, dt=dt,
                           e_input=p["e"], vn=p["vn"], vt=p["vt"], mu=p["mu"], vchar=p["vchar"],
                           kn=c["kn"], gamma_n=c["gn"],
                           e=ms["e"], e_analytic=an["e"], e_digits=digits(ms["e"], an["e"]),
                           tc=ms["tc"], tc_analytic=an["tc"], tc_digits=digits(ms["tc"], an["tc"]),
                           dmax=ms["dmax"], dmax_analytic=an["dmax"],
                           dmax_digits=digits(ms["dmax"], an["dmax"]))
                if p["vt"] != 0.0:
                    row.update(e_n=ms["e_n"], v1z=ms["v1z"], w1y=ms["w1y"],
                               v1z_slide_analytic=an["v1z"], w1y_slide_analytic=an["w1y"],
                               slides_analytic=an["slides"], cap_ratio_max=ms["cap_ratio_max"],
                               slip_fraction=ms["slip_fraction"])
                rows.append(row)
                curves.append((s["name"], code, spc, p, d, ms))
    finally:
        shutil.rmtree(work, ignore_errors=True)

    # replica (and sandcell) vs LIGGGHTS, row by row at the same dt: the formulas check
    byname = {(n, code, spc): (d, ms) for n, code, spc, _, d, ms in curves}
    others = ["replica"] + (["sandcell"] if args.sandcell else [])
    for other in others:
        print(f"LIGGGHTS vs {other}, same dt, whole trajectory, max |diff| / max |value| over "
              "x1, v1x, v1z, w1y, f1x, f1z:")
        for s in SCENES:
            dl = byname[(s["name"], "liggghts", args.steps_per_contact)][0]
            do = byname[(s["name"], other, args.steps_per_contact)][0]
            n = min(len(dl["t"]), len(do["t"]))
            worst = 0.0
            for k in ("x1", "v1x", "v1z", "w1y", "f1x", "f1z"):
                if np.all(np.isnan(do[k][:n])):
                    continue
                scale = np.max(np.abs(dl[k][:n])) or 1.0
                worst = max(worst, float(np.nanmax(np.abs(dl[k][:n] - do[k][:n]))) / scale)
            print(f"  {s['name']:20s} {worst:.1e}")
            for r in rows:
                if r["scene"] == s["name"] and r["code"] == other:
                    r["vs_liggghts_maxrel"] = worst
        print()

    print("scene                 code      dt=tc/N   e(meas)            e dig  t_c(meas) s        t_c dig  dmax dig")
    for r in rows:
        print(f"{r['scene']:21s} {r['code']:9s} {r['steps_per_contact']:6.0f}  {r['e']:.15f} {r['e_digits']:5.1f}"
              f"  {r['tc']:.12e} {r['tc_digits']:5.1f}  {r['dmax_digits']:5.1f}")
    print("\noblique: rebound of sphere 1 (v1z m/s, w1y rad/s) and the whole-contact-sliding closed form")
    for r in rows:
        if r["vt"] != 0.0:
            print(f"{r['scene']:21s} {r['code']:9s} {r['steps_per_contact']:6.0f}  e_n {r['e_n']:.6f}"
                  f"  v1z {r['v1z']:.6f}  w1y {r['w1y']:8.4f}"
                  + (f"  (sliding closed form: v1z {r['v1z_slide_analytic']:.6f}, "
                     f"{digits(r['v1z'], r['v1z_slide_analytic']):.1f} dig;"
                     f" w1y {r['w1y_slide_analytic']:.4f}, {digits(r['w1y'], r['w1y_slide_analytic']):.1f} dig)"
                     if r["slides_analytic"] else "  (sticks: no closed form)")
                  + f"  steps at the cap {100 * r['slip_fraction']:.1f} %"
                  f"  max |Ft|/(mu|Fn|) {r['cap_ratio_max']:.3f}")

    write_csv(rows, args.csv)
    plot(curves, args, args.png)
    print(f"\nwrote {args.csv} and {args.png}")


def write_csv(rows, path):
    keys = []
    for r in rows:
        for k in r:
            if k not in keys:
                keys.append(k)
    with open(path, "w") as f:
        f.write(",".join(keys) + "\n")
        for r in rows:
            f.write(",".join("" if k not in r else (f"{r[k]:.17g}" if isinstance(r[k], float) else str(r[k]))
                             for k in keys) + "\n")


def plot(curves, args, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(16, 4.8))
    colors = {"normal-e0.5-v0.1": "C0", "normal-e0.5-v1": "C1", "normal-e0.9-v0.1": "C2",
              "normal-e0.9-v1": "C3"}
    have_sandcell = any(code == "sandcell" for _, code, _, _, _, _ in curves)
    for name, code, spc, p, d, ms in curves:
        if not name.startswith("normal") or spc != args.steps_per_contact:
            continue
        c = constants(p)
        tn = (d["t"] - ms["t_start"]) / c["tc"]
        f0 = c["kn"] * p["vn"] / c["wd"]  # force scale: k_n v0/w_d
        d0 = p["vn"] / c["wd"]
        col = colors[name]
        if code == "liggghts":
            mk = dict(marker="o", ms=4, ls="none", color=col) if p["vn"] < 0.5 else \
                dict(marker="s", ms=6, ls="none", mfc="none", color=col)
            axes[0].plot(tn, -d["f1x"] / f0, label=f"LIGGGHTS {name}", **mk)
            axes[1].plot(tn, ms["overlap"] / d0, **mk)
            tt = np.linspace(-0.1, 1.15, 1001)
            dd, _, fn = analytic(p, tt * c["tc"])
            inside = (tt >= 0) & (tt <= 1)
            axes[0].plot(tt, np.where(inside, fn, 0.0) / f0, "-", lw=1, color=col)
            axes[1].plot(tt, np.where(inside, dd, np.nan) / d0, "-", lw=1, color=col)
        elif code == "sandcell":
            axes[0].plot(tn, -d["f1x"] / f0, "x", ms=5, color=col, label=f"sandcell {name}")
            axes[1].plot(tn, ms["overlap"] / d0, "x", ms=5, color=col)
    axes[0].plot([], [], "k-", lw=1, label="analytic (lines)")
    axes[0].set_xlabel("t / t_c (t = 0 at first touch)")
    axes[0].set_ylabel("normal force F_n / (k_n v0 / w_d)")
    axes[0].set_title(f"head-on: normal force, dt = t_c/{args.steps_per_contact:g}\n"
                      "(in these units 0.1 and 1 m/s coincide)", fontsize=10)
    axes[0].axhline(0, color="0.7", lw=0.5)
    axes[0].legend(fontsize=7, loc="upper right")
    axes[1].set_xlabel("t / t_c")
    axes[1].set_ylabel("overlap / (v0 / w_d)")
    axes[1].set_title("head-on: overlap (o/squares LIGGGHTS, x sandcell, lines analytic)", fontsize=10)
    axes[1].set_ylim(bottom=-0.05)
    if not have_sandcell:
        for ax in axes[:2]:
            ax.text(0.02, 0.03, "sandcell: curve pending (run with --sandcell BIN)",
                    transform=ax.transAxes, fontsize=8, color="0.4", style="italic")
    ax = axes[2]
    for name, code, spc, p, d, ms in curves:
        if not name.startswith("oblique") or spc != args.steps_per_contact or code == "replica":
            continue
        c = constants(p)
        tn = (d["t"] - ms["t_start"]) / c["tc"]
        col = "C4" if "stick" in name else "C5"
        r = np.hypot(d["x1"] - d["x2"], d["z1"] - d["z2"])
        nx, nz = (d["x1"] - d["x2"]) / r, (d["z1"] - d["z2"]) / r
        fn = d["f1x"] * nx + d["f1z"] * nz
        ft = -d["f1x"] * nz + d["f1z"] * nx
        f0 = c["kn"] * p["vn"] / c["wd"]
        mk = "o" if code == "liggghts" else "x"
        lab = f"{code} {name} (v_t/v_n = {p['vt'] / p['vn']:g})"
        ax.plot(tn, ft / f0, mk + "-", ms=3, lw=0.6, color=col, label="F_t, " + lab)
        if "stick" in name and code == "liggghts":
            tt = np.linspace(0.0, 1.0, 1001)
            _, _, fna = analytic(p, tt * c["tc"])
            for sgn in (1, -1):
                ax.plot(tt, sgn * p["mu"] * np.abs(fna) / f0, "k:", lw=1.2,
                        label="+-mu |F_n|, analytic F_n (Coulomb cap)" if sgn > 0 else None)
    ax.axhline(0, color="0.7", lw=0.5)
    ax.set_xlabel("t / t_c")
    ax.set_ylabel("tangential force on sphere 1 / (k_n v_n / w_d)")
    ax.set_title("oblique, mu = 0.5, e = 0.9, v_n = 0.1 m/s")
    ax.legend(fontsize=7)
    if not have_sandcell:
        ax.text(0.02, 0.03, "sandcell: curve pending", transform=ax.transAxes, fontsize=8,
                color="0.4", style="italic")
    for a in axes:
        a.set_xlim(-0.1, 1.15)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
