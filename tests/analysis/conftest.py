"""pytest configuration of the analysis tests: the package sandcell_analysis from the source tree
(apps/analysis, for the tests and the commands they run),
and HDF5 file locking off (as the tools read files of running jobs)."""
import os
import sys

_ANALYSIS = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", "apps", "analysis"))
os.environ["HDF5_USE_FILE_LOCKING"] = "FALSE"
sys.path.insert(0, _ANALYSIS)
# The commands run as `python -m sandcell_analysis ...` in subprocesses: the same package there.
os.environ["PYTHONPATH"] = os.pathsep.join(p for p in (_ANALYSIS, os.environ.get("PYTHONPATH", "")) if p)
