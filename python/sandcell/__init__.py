"""sandcell from Python (docs/python.md).

The engine's classes come from the extension sandcell._sandcell; this package adds the series row
of the triaxial app (append_row: the same datasets, names and units as the app's results files)
and the app's derived servo settings (derived_gain), so a script can reproduce the app's runs.
"""
import math

from ._sandcell import (  # noqa: F401
    ContactSettings, CyclicPath, CyclicSettings, Material, Measures, Model, PathFunction, PathInput,
    PathTargets, PathTolerance, PathWatch, ResultsFile, ServoSettings, SimulationError, State,
    StressInvariants, World, __version__, median_diameter, principal_rotation_deg, rayleigh_time,
    read_checkpoint, sample_diameters, shear_ratio, undrained_path, write_checkpoint,
)


def derived_gain(alpha, p, material, servo_time):
    """The triaxial app's servo gain, 1/s: alpha (p/E*)^(2/3) / t_s, E* = E / (2 (1 - nu^2))
    (docs/physics.md section 6)."""
    e_star = material.young / (2.0 * (1.0 - material.poisson * material.poisson))
    return alpha * math.pow(p / e_star, 2.0 / 3.0) / servo_time


def append_row(results, state, m, wall=0.0):
    """Appends one row of the app's series (docs/physics.md section 8) from measure()'s `m`;
    `state` is a World or a State (its clock gives time and step)."""
    s, f = m.stress, m.fabric
    six = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]
    step = state.step_count if isinstance(state, World) else state.step
    results.append("time", state.time, "s")
    results.append("step", float(step), "-")
    results.append("strain", m.strain, "- (logarithmic, compression positive)")
    results.append("strain_engineering", m.strain_engineering, "-")
    results.append("strain_rate", m.strain_rate, "1/s (compression positive)")
    results.append("stress", [s[a, b] for a, b in six], "Pa (xx yy zz xy xz yz, compression positive)")
    results.append("principal_stress", m.inv.principal, "Pa (s1 >= s2 >= s3)")
    results.append("p", m.p, "Pa")
    results.append("q", m.q, "Pa")
    results.append("eta", m.eta, "-")
    results.append("b", m.b, "-")
    results.append("theta", m.theta, "rad")
    results.append("eps_v", m.eps_v, "-")
    results.append("eps_q", m.eps_q, "-")
    results.append("e", m.void_ratio, "-")
    results.append("Z", m.z, "-")
    results.append("Z_mech", m.z_mech, "-")
    results.append("rattlers", float(m.rattlers), "-")
    results.append("fabric", [f[a, b] for a, b in six], "- (xx yy zz xy xz yz)")
    results.append("kinetic_energy", m.kinetic_energy, "J")
    results.append("elastic_energy", m.elastic_energy, "J")
    results.append("max_overlap_ratio", m.max_overlap_ratio, "- (largest overlap / smaller radius)")
    results.append("unbalanced_force_ratio", m.unbalanced, "-")
    results.append("inertial_number", m.inertial_number, "- ((eps_dot_1 - eps_dot_3) d50 sqrt(rho/p))")
    results.append("inertial_number_axial", m.inertial_number_axial,
                   "- (eps_dot_1 d50 sqrt(rho/p): what shear.inertial_number sets)")
    results.append("rotation", principal_rotation_deg(s),
                   "degrees (the principal axes' turn off the cell axes, 1/2 asin(2 |tau| / (s1 - s3)))")
    results.append("shear_ratio", shear_ratio(s), "- (largest |shear stress| / p)")
    results.append("wall_time", wall, "s")
