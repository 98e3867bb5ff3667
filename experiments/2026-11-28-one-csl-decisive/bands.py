"""The decisive experiment's shear bands (issue 45 item 7): per test, the band detector's verdict and the void ratio
inside and outside the band at the end of the test.

    PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-28-one-csl-decisive/bands.py \
        --decisive RUN_ROOT [--free-cell FREE_CELL_OUT] [--large LARGE_OUT] [--out .../bands.csv]

RUN_ROOT holds the run folders {fixed,free}-s{2017,2018,2019} (p-b*kPa.h5: constant p, b = 0, 0.5, 1, p0 = 0.5 and
8 MPa, to eps_q = 0.6); FREE_CELL_OUT is experiments/2026-11-28-free-cell-banded's run folder (free cell, b = 0.25,
0.5, 0.75 at 0.5 MPa, to the critical state). The files are read as they are (a running test's too: HDF5 locking is off
in the package's reader), one at a time; a file with fewer than MIN_SNAPSHOTS particle snapshots is listed with
verdict "skipped" and no numbers. For each other one, sandcell_analysis.localization.band_void_ratios: the band
detector on every snapshot increment and the whole test (its verdict: banded, or the criteria it fails; the fixed
and free cells judged by the same method, a sheared cell in its reduced coordinates), its onset (eps_q at the midpoint
of the first increment that detects the band) and persistence (the later increments that detect it again in the
same mode), and over the last 0.1 of eps_q (the critical-state window: the snapshots there) the mean void ratio of
the band's slabs (e_in), of the rest (e_out) and of all (e_global, which is the series' e to round-off); e_in and e_out
are empty when the test is not banded; e_in_candidate and e_out_candidate are the same means over the candidate
mode's slabs whatever the verdict (read them only with it: for a test not banded they are the slabs of its strongest
mode, not a band's); window_detected: the part of the snapshot increments in the window that detect a band in that
mode. status is the results file's (running when it has none yet); eps_q_end the last snapshot's; file: the results
file, relative to RUN_ROOT (decisive) or FREE_CELL_OUT.

Writes bands.csv and prints one line per test. About 2-10 s a test on one core.
"""
import argparse
import contextlib
import csv
import glob
import io
import math
import os
import re
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "apps", "analysis"))

from sandcell_analysis import localization as loc  # noqa: E402
from sandcell_analysis.results import InputError, attr, open_results  # noqa: E402

MIN_SNAPSHOTS = 4   # three increments at least (as the synthetic tests): an onset and two later ones
COLUMNS = ["campaign", "cell", "seed", "b", "p0_kPa", "status", "snapshots", "eps_q_end", "verdict", "mode",
           "normal_angle_deg", "onset_eps_q", "persistence", "window_eps_q", "window_snapshots", "window_detected",
           "e_in", "e_out", "e_global", "e_in_candidate", "e_out_candidate", "file"]


def tests(decisive, free_cell, large=None):
    """(campaign, cell, seed, path, its name in the CSV) of every results file, in a fixed order."""
    out = []
    if large:  # the larger cell (large-s2020.toml: free cell, seed 2020)
        for path in sorted(glob.glob(os.path.join(large, "p-b*kPa.h5"))):
            out.append(("large", "free", 2020, path, os.path.basename(path)))
    if decisive:
        for cell in ("fixed", "free"):
            for seed in (2017, 2018, 2019):
                for path in sorted(glob.glob(os.path.join(decisive, f"{cell}-s{seed}", "p-b*kPa.h5"))):
                    out.append(("decisive", cell, seed, path, os.path.relpath(path, decisive)))
    if free_cell:
        for path in sorted(glob.glob(os.path.join(free_cell, "p-b*kPa.h5"))):
            out.append(("free-cell-banded", "free", "", path, os.path.basename(path)))
    return out


def fmt(v, digits=4):
    return "" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.{digits}f}"


def judge(campaign, cell, seed, path, name):
    m = re.search(r"p-b([0-9.]+)-p0_([0-9]+)kPa\.h5$", path)
    row = dict(campaign=campaign, cell=cell, seed=seed, b=m.group(1), p0_kPa=m.group(2), file=name)
    with open_results(path) as f:
        row["status"] = attr(f, "status") or "running"
        row["snapshots"] = len(f["snapshots"]) if "snapshots" in f else 0
    if row["snapshots"] < MIN_SNAPSHOTS:
        row.update(verdict="skipped", mode="", eps_q_end="")
        return row
    log = io.StringIO()
    try:
        with contextlib.redirect_stdout(log):
            v = loc.band_void_ratios(path)
    except (InputError, SystemExit) as e:
        row.update(verdict=f"skipped: {e}", mode="")
        return row
    verdict = "banded" if v["banded"] else "no band: " + v["why"]
    row.update(eps_q_end=fmt(v["eps_q_end"], 3), verdict=verdict,
               mode=f"({v['mode_h']},{v['mode_k']},{v['mode_l']})", normal_angle_deg=fmt(v["normal_angle_deg"], 1),
               onset_eps_q=fmt(v["onset_eps_q"], 3), persistence=fmt(v["persistence"], 2),
               window_eps_q=f"{v['window_from']:.3f}-{v['eps_q_end']:.3f}", window_snapshots=v["window_snapshots"],
               window_detected=fmt(v["window_detected"], 2), e_in=fmt(v["e_in"]), e_out=fmt(v["e_out"]),
               e_global=fmt(v["e_global"]), e_in_candidate=fmt(v["e_in_candidate"]),
               e_out_candidate=fmt(v["e_out_candidate"]))
    return row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--decisive", help="the decisive experiment's run root ({fixed,free}-s{2017,2018,2019})")
    ap.add_argument("--free-cell", help="experiments/2026-11-28-free-cell-banded's run folder")
    ap.add_argument("--large", help="the larger cell's --out folder (large-s2020.toml)")
    ap.add_argument("--out", default=os.path.join(HERE, "bands.csv"))
    a = ap.parse_args(argv)
    rows = []
    for t in tests(a.decisive, a.free_cell, a.large):
        rows.append(judge(*t))
        r = rows[-1]
        print(f"{r['campaign']} {r['cell']} {r['seed']} b {r['b']} p0 {r['p0_kPa']} kPa ({r['status']}, "
              f"{r['snapshots']} snapshots, eps_q {r.get('eps_q_end', '')}): {r['verdict'][:60]}, mode {r['mode']}, "
              f"onset {r.get('onset_eps_q')}, "
              f"e_in {r.get('e_in')}, e_out {r.get('e_out')}, e_global {r.get('e_global')}", flush=True)
    with open(a.out, "w", newline="") as fh:
        w = csv.DictWriter(fh, COLUMNS, lineterminator="\n")
        w.writeheader()
        for r in rows:
            w.writerow({c: r.get(c, "") for c in COLUMNS})
    print(f"wrote {a.out} ({len(rows)} tests)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
