"""The published campaigns (every experiments/**/index.csv and docs/**/index.csv) hold no test reported
`done` off its stress path.

A campaign run with the stress-path watchdog has its verdict in index.csv (path_error, b_error,
rotation_deg, reason): every `done` test must be within the watchdog's default tolerances, every
`failed` one must say why, the committed tests.md must not call a test done that index.csv does
not, and the committed summary.json must have fitted no test that is not done. A campaign
published before the watchdog cannot be judged from what is committed (its results files are not):
its README must say so, and none of its tests may stay `done` with the run-away's signature (a
final p above 10 p0: on every path of the study p stays within 5 p0; the run-away reached 700-4,000 p0).
"""
import csv
import glob
import json
import math
import os

import pytest

from sandcell_analysis.path_check import DEFAULTS

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
PUBLISHED = [os.path.join(ROOT, "experiments"), os.path.join(ROOT, "docs")]  # where results are published
INDEXES = sorted(p for top in PUBLISHED for p in glob.glob(os.path.join(top, "**", "index.csv"), recursive=True))
BANNER = "published before the stress-path watchdog"


def rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def number(v):
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def nearest_readme(folder):
    """The README.md in folder or the nearest one above it, within the published tree it is in."""
    top = next(t for t in PUBLISHED if folder.startswith(t + os.sep))
    while folder.startswith(top):
        readme = os.path.join(folder, "README.md")
        if os.path.exists(readme):
            return readme
        folder = os.path.dirname(folder)
    return None


def test_there_are_published_campaigns():
    # the four 2026-11-28 campaigns (the full-scale calibrated one in two parts) and the calibration's
    # full-scale test (experiments/2026-11-25-calibration/prep-friction/full-scale)
    assert len(INDEXES) >= 6


@pytest.mark.parametrize("index", INDEXES, ids=lambda p: os.path.relpath(p, ROOT))
def test_no_done_test_off_its_path(index):
    table = rows(index)
    assert table, index
    judged = "path_error" in table[0]
    done = [r for r in table if r["status"].startswith("done")]
    if not judged:
        readme = nearest_readme(os.path.dirname(index))
        assert readme is not None and BANNER in open(readme, encoding="utf-8").read(), \
            f"{index}: no watchdog verdict, and no README saying it was {BANNER}"
        for r in done:
            ratio = number(r["final_p_Pa"]) / number(r["p0_Pa"])
            assert ratio < 10.0, f"{r['test']}: done with final p = {ratio:.0f} p0"
        return
    for r in done:
        # the watchdog's defaults (apps/triaxial/README.md): a done test is inside every one
        assert not r["reason"], r["test"]
        assert number(r["path_error"]) <= DEFAULTS["stress"], r["test"]
        b_error = number(r["b_error"])
        assert math.isnan(b_error) or b_error <= DEFAULTS["b"], r["test"]
        assert number(r["rotation_deg"]) <= DEFAULTS["rotation"], r["test"]
    for r in table:
        if r["status"] == "failed":
            assert r["reason"], r["test"]
    status = {r["test"]: r["status"] for r in table}
    folder = os.path.dirname(index)
    tests_md = os.path.join(folder, "tests.md")
    if os.path.exists(tests_md):
        for line in open(tests_md, encoding="utf-8"):
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if len(cells) > 1 and cells[0] in status and cells[1].startswith("done"):
                assert status[cells[0]].startswith("done"), f"tests.md calls {cells[0]} done"
    summary = os.path.join(folder, "summary.json")
    if os.path.exists(summary):
        s = json.load(open(summary, encoding="utf-8"))
        fitted = [os.path.splitext(os.path.basename(f))[0] for f in s["inputs"]]
        for name in fitted:
            if name in status:
                assert status[name].startswith("done"), f"summary.json fitted {name} ({status[name]})"
        for name, st in status.items():
            if st == "failed":
                assert name in s.get("excluded", []), f"summary.json does not list {name} as left out"
