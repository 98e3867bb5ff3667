"""path_check.py judges a results file as the app's watchdog (systems/path_watch.cpp) judged it while
the test ran: on the small campaigns' files (the fixtures of analysis.campaign_run and
campaign_stop_run), the verdict and the largest errors the app wrote into each file agree with
path_check's on the series, to rounding (the window means are summed in another order: 1e-9)."""
import glob
import math
import os

import pytest

from sandcell_analysis.analyze import path_verdict
from sandcell_analysis.results import attr, open_results

DIRS = [d for d in os.environ.get("SANDCELL_TWIN_RESULTS", "").split(":") if d]


@pytest.mark.skipif(not DIRS, reason="SANDCELL_TWIN_RESULTS not set (the small campaigns' folders)")
def test_path_check_agrees_with_the_apps_watchdog():
    files = [f for d in DIRS for f in glob.glob(os.path.join(d, "*.h5"))
             if os.path.basename(f).startswith(("p-", "s3-")) and "checkpoint" not in f]
    assert len(files) >= 9
    for f in files:
        with open_results(f) as h:
            app = {k: attr(h, k) for k in ("status", "path_error", "b_error", "rotation_deg")}
        status, _, check = path_verdict(f)
        assert status == app["status"], f
        w = check["worst"]
        for mine, theirs in ((max(w["p"], w["sigma3"]), app["path_error"]), (w["b"], app["b_error"]),
                             (w["rotation"], app["rotation_deg"])):
            assert math.isclose(mine, float(theirs), rel_tol=1e-9, abs_tol=1e-12), (f, mine, theirs)
