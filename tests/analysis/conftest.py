"""pytest configuration of the analysis tests: the package sandcell_analysis from the source tree
(apps/analysis), and HDF5 file locking off (as the tools read files of running jobs)."""
import os
import sys

os.environ["HDF5_USE_FILE_LOCKING"] = "FALSE"
sys.path.insert(0, os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", "apps", "analysis")))
