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
    shear_ratio, stable_step, strain_rate_tensor, test_paths, TimeStepSettings, undrained_path, write_checkpoint,
)
