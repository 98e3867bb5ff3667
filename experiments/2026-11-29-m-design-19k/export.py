"""Keeps the m design's finished tests in git: each test's series as a compressed CSV and its row in
tests.csv, so that analyze.py needs no results file and the campaign can span machines that do not
keep their files.

    PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-29-m-design-19k/export.py WORKDIR \
        [--out experiments/2026-11-29-m-design-19k]

WORKDIR (run.sh's) holds s<seed>-e<target>/ run folders and BUILD.txt. For every test that ended
(done, or failed: a failed test's row says why and keeps it out of the fit), writes
series/s<seed>-e<target>.csv.gz (the columns analyze.py reads, every series row, 9 significant
digits), searches/s<seed>-e<target>.csv (the preparation's trials) and its row in tests.csv (rows of
other machines are kept; a test already there from the same build with the same status is not
exported again).
"""
import argparse
import csv
import os
import re
import shutil
import sys

import numpy as np

from sandcell_analysis import results

HERE = os.path.dirname(os.path.abspath(__file__))
TEST = "p-b0.00-p0_500kPa"
SCALARS = ["step", "eps_q", "eps_v", "p", "q", "eta", "e", "Z_mech"]
TENSORS = ["fabric", "stress"]  # [n, 6] each (xx, yy, zz, xy, xz, yz)
FIELDS = ["seed", "target_e0", "e0", "status", "ok", "prepare_friction", "eps_q_end", "e_end",
          "steps", "rows", "path_error", "rotation_deg", "reason", "state_digest", "build"]


def write_series(h5, out):
    cols = results.read_columns(h5, SCALARS + TENSORS)
    return results.write_series_csv(out, {k: cols[k] for k in SCALARS + TENSORS})


def read_series(path):
    """A series CSV (write_series) as float arrays; fabric and stress as [n, 6]."""
    return results.read_series_csv(path, tensors=TENSORS)


def read_tests(path):
    if not os.path.exists(path):
        return {}
    with open(path, newline="") as fh:
        return {(r["seed"], r["target_e0"]): r for r in csv.DictReader(fh)}


def write_tests(path, rows):
    tmp = path + ".tmp"
    with open(tmp, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=FIELDS)
        w.writeheader()
        for key in sorted(rows, key=lambda k: (int(k[0]), float(k[1]))):
            w.writerow(rows[key])
    os.replace(tmp, path)


def prepare_friction(sample):
    """The friction the preparation used (the one prepare.target_e0 found), NaN if not recorded."""
    import h5py
    try:
        with h5py.File(sample, "r") as f:
            return float(f["extra/doubles/prepare_friction"][0])
    except (OSError, KeyError):
        return float("nan")


def export(work, out):
    """Exports every ended test of WORKDIR; returns the number exported."""
    stamp = os.path.join(work, "BUILD.txt")  # run.sh's: the commit the campaign's binary was built from
    with open(stamp) if os.path.exists(stamp) else open(os.devnull) as fh:
        build = fh.readline().strip()
    tests_csv = os.path.join(out, "tests.csv")
    rows = read_tests(tests_csv)
    os.makedirs(os.path.join(out, "series"), exist_ok=True)
    os.makedirs(os.path.join(out, "searches"), exist_ok=True)
    done = 0
    for name in sorted(os.listdir(work)):
        m = re.fullmatch(r"s(\d+)-e([0-9.]+)", name)
        folder = os.path.join(work, name)
        if not m or not os.path.isdir(folder):
            continue
        index = {r["test"]: r for r in results.read_csv_rows(os.path.join(folder, "index.csv"))}
        r = index.get(TEST)
        if r is None or r["status"] == "running" or not os.path.exists(os.path.join(folder, TEST + ".h5")):
            continue
        key = (m.group(1), m.group(2))
        old = rows.get(key)
        # A finished test resumed again (run.sh on a machine that kept WORKDIR) says "done (earlier run)".
        status = r["status"].removesuffix(" (earlier run)")
        if old is not None and old["build"] == build and old["status"].removesuffix(" (earlier run)") == status:
            continue
        n = write_series(os.path.join(folder, TEST + ".h5"), os.path.join(out, "series", f"{name}.csv.gz"))
        search = os.path.join(folder, "target_e0-p0_500kPa.csv")
        if os.path.exists(search):
            shutil.copyfile(search, os.path.join(out, "searches", f"{name}.csv"))
        friction = prepare_friction(os.path.join(folder, "sample-p0_500kPa.h5"))
        cols = results.read_columns(os.path.join(folder, TEST + ".h5"), ["eps_q", "e"], optional=["state_digest"])
        halves = np.ravel(cols["state_digest"][-1]) if "state_digest" in cols else ()
        rows[key] = {
            "seed": key[0], "target_e0": key[1], "e0": r["e0"], "status": status,
            "ok": status.startswith("done"),
            "prepare_friction": f"{friction:.6g}",
            "eps_q_end": f"{float(cols['eps_q'][-1]):.6g}", "e_end": f"{float(cols['e'][-1]):.6g}",
            "steps": r["steps"], "rows": n, "path_error": r["path_error"], "rotation_deg": r["rotation_deg"],
            "reason": r.get("reason", ""),
            "state_digest": f"{(int(halves[0]) << 32) | int(halves[1]):016x}" if len(halves) == 2 else "",
            "build": build}
        done += 1
        print(f"{name}: {r['status']}, e0 {r['e0']}, {n} rows exported")
    if rows:
        write_tests(tests_csv, rows)
    return done


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("work")
    ap.add_argument("--out", default=HERE)
    a = ap.parse_args(argv)
    export(a.work, a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
