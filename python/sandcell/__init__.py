"""sandcell from Python (docs/python.md).

Everything comes from the extension sandcell._sandcell, including the triaxial app's protocol
(Protocol: the derived time steps, servo gains and models of the app's stages, from the app's own
config and code), its series row (append_row, series_columns) and its accuracy and path watches,
so a script reproduces the app's runs without retyping its rules. The tensor measures of a
shearing cell (log_strain, principal, alpha_deg, noncoaxiality_deg, ...) are systems/kinematics.hpp's.
"""
from ._sandcell import (  # noqa: F401
    AccuracyWatch, ConfigError, ContactSettings, contact_laws, CyclicPath, CyclicSettings, Material, Measures, Model,
    PathFunction, PathInput, PathTargets, PathTolerance, PathWatch, Protocol, ResultsFile, ServoSettings,
    SimulationError, State, StressInvariants, TestSpec, World, __version__, alpha_deg, append_row, axes_rotation_deg,
    derived_gain, derived_servo, finish_preparation, log_strain, median_diameter, noncoaxiality_deg, p0_tag, principal,
    principal_rotation_deg, rayleigh_time, read_checkpoint, sample_diameters, series_columns, servo_time_unit,
    particle_digest, shear_ratio, stable_step, strain_rate_tensor, test_paths, TimeStepSettings, undrained_path,
    write_checkpoint,
)


def verify(path, rows=None, threads=1, triaxial=None):
    """`triaxial verify PATH`: re-run the shear test of a results file from its run record (its sample, config
    text and command-line override) and compare the new file with it bitwise (docs/python.md).

    rows: (K, L) to compare rows K..L only; threads: of the re-run; triaxial: the app's path (default:
    $SANDCELL_TRIAXIAL, else `triaxial` on PATH, else the build tree's). Returns (verified, message): True when
    every compared row and snapshot is bitwise identical, False with the first difference named. A file that
    cannot be verified (no run record, its sample missing or changed) raises ValueError with the app's message."""
    import os
    import shutil
    import subprocess
    app = triaxial or os.environ.get("SANDCELL_TRIAXIAL") or shutil.which("triaxial")
    if not app:
        here = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "apps", "triaxial", "triaxial")
        app = here if os.path.exists(here) else None
    if not app:
        raise ValueError("triaxial: the app was not found (set SANDCELL_TRIAXIAL or put triaxial on PATH)")
    cmd = [app, "verify", os.fspath(path), "--threads", str(int(threads))]
    if rows is not None:
        cmd += ["--rows", f"{int(rows[0])}..{int(rows[1])}"]
    r = subprocess.run(cmd, capture_output=True, text=True)
    message = (r.stdout + r.stderr).strip()
    if r.returncode not in (0, 1):
        raise ValueError(message)
    return r.returncode == 0, message
