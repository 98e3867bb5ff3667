"""Keeps a run's series in git, so that analyze.one_test (and large.py) can judge its tests without the
results files, which are too large to commit and die with the machine that wrote them.

    PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-28-one-csl-decisive/export_series.py RUN_OUT \
        experiments/2026-11-28-one-csl-decisive/series/NAME

For every TEST.h5 of RUN_OUT (a triaxial --out folder) whose test has ended (index.csv's status not
"running"), writes NAME/TEST.csv.gz with the series columns one_test reads (9 significant digits; gzip
with no time stamp, so the same series gives the same bytes) and copies index.csv beside them. read()
gives the columns back as results.read_columns does.
"""
import argparse
import os
import shutil
import sys

from sandcell_analysis import results

SCALARS = ["step", "eps_q", "eps_v", "p", "q", "eta", "e", "b", "Z_mech"]
TENSORS = ["fabric", "stress", "strain"]  # 2-D datasets: [n, 6], [n, 6], [n, 3]


def write(h5, out):
    """The series of results file H5 into OUT (.csv.gz); returns the number of rows."""
    cols = results.read_columns(h5, SCALARS + TENSORS)
    return results.write_series_csv(out, {k: cols[k] for k in SCALARS + TENSORS})


def read(path, names=None):
    """A series written by write() as {name: array} (the 2-D datasets as [n, k]), only NAMES if given."""
    out = results.read_series_csv(path, tensors=TENSORS)
    if names is not None:
        missing = [k for k in names if k not in out]
        if missing:
            raise results.InputError(f"cannot read {path}: it lacks {', '.join(missing)}")
        out = {k: out[k] for k in names}
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", help="a triaxial --out folder")
    ap.add_argument("dest", help="the folder the series go to (created)")
    a = ap.parse_args(argv)
    status = {r["test"]: r["status"] for r in results.read_csv_rows(os.path.join(a.run, "index.csv"))}
    if not status:
        print(f"{a.run}: no index.csv", file=sys.stderr)
        return 2
    os.makedirs(a.dest, exist_ok=True)
    for test, st in sorted(status.items()):
        h5 = os.path.join(a.run, test + ".h5")
        if st == "running" or not os.path.exists(h5):
            continue
        n = write(h5, os.path.join(a.dest, test + ".csv.gz"))
        print(f"{test}: {st}, {n} rows")
    shutil.copyfile(os.path.join(a.run, "index.csv"), os.path.join(a.dest, "index.csv"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
