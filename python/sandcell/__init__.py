"""sandcell from Python (docs/python.md).

Everything comes from the extension sandcell._sandcell, including the triaxial app's protocol
(Protocol: the derived time steps, servo gains and models of the app's stages, from the app's own
config and code), its series row (append_row, series_columns) and its accuracy and path watches,
so a script reproduces the app's runs without retyping its rules.
"""
from ._sandcell import (  # noqa: F401
    AccuracyWatch, ConfigError, ContactSettings, contact_laws, CyclicPath, CyclicSettings, Material, Measures, Model,
    PathFunction, PathInput, PathTargets, PathTolerance, PathWatch, Protocol, ResultsFile, ServoSettings,
    SimulationError, State, StressInvariants, TestSpec, World, __version__, append_row, derived_gain, derived_servo,
    finish_preparation, median_diameter, p0_tag, principal_rotation_deg, rayleigh_time, read_checkpoint,
    sample_diameters, series_columns, servo_time_unit, shear_ratio, test_paths, undrained_path, write_checkpoint,
)
