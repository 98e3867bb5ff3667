#!/usr/bin/env python3
"""Compares the tests of two triaxial output directories bit for bit.

    compare_results.py DIR_A DIR_B

For every test listed in DIR_A/index.csv: its checkpoint (the final state: particles, contacts,
cell, clock, the series history) and its results file (every /series dataset and every snapshot)
must hold the same datasets with the same bytes in both directories. Wall times are the only
datasets skipped. Exits 1 naming the first difference, 0 when all are identical.
"""
import csv
import os
import sys

import h5py
import numpy as np

SKIP = ("wall_time",)


def datasets(path):
    found = {}
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset) and not name.endswith(SKIP):
                found[name] = np.asarray(obj[()])
        f.visititems(visit)
    return found


def compare(a, b):
    da, db = datasets(a), datasets(b)
    if sorted(da) != sorted(db):
        return f"{a}: datasets differ: {sorted(set(da) ^ set(db))[:5]}"
    for name in sorted(da):
        x, y = da[name], db[name]
        if x.shape != y.shape or x.dtype != y.dtype or x.tobytes() != y.tobytes():
            return f"{a}: /{name} differs from {b}"
    return ""


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    a, b = sys.argv[1:]
    with open(os.path.join(a, "index.csv")) as fh:
        tests = [row["test"] for row in csv.DictReader(fh)]
    if not tests:
        sys.exit(f"{a}/index.csv lists no test")
    for t in tests:
        for suffix in (".checkpoint.h5", ".h5"):
            pa, pb = os.path.join(a, t + suffix), os.path.join(b, t + suffix)
            for p in (pa, pb):
                if not os.path.exists(p):
                    print(f"missing: {p}")
                    return 1
            diff = compare(pa, pb)
            if diff:
                print(diff)
                return 1
    print(f"{len(tests)} tests bitwise identical: {a} and {b}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
