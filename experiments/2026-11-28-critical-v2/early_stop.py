#!/usr/bin/env python3
"""The early stop's bias (issue 45 item 2): on each test's series, where the first-passage test of
the 2026-11-28 campaigns (critical.py version 1: 5 % of eps_1, the change alone) stops, where
version 2 (0.1 of eps_q after 0.2, change + 2 SE, Z_mech and fabric too) would stop the app
(shear.stop_at_critical), and version 2 on the whole test (what `triaxial analyze` reports), with
the window means of eta = q/p, e and p at each. Prints a markdown table; --json FILE writes the rows.

    PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-28-critical-v2/early_stop.py RESULTS.h5|DIR...
"""
import argparse
import glob
import json
import math
import os
import sys

import numpy as np

from sandcell_analysis import critical, results


def files(args):
    out = []
    for a in args:
        if os.path.isdir(a):
            out += sorted(f for f in glob.glob(os.path.join(a, "*.h5"))
                          if not os.path.basename(f).startswith(("sample-", "prepare-")) and "checkpoint" not in f)
        else:
            out.append(a)
    return out


def state(r):
    pt = r["point"]
    return {k: pt.get(k, math.nan) for k in ("eta", "e", "p", "Z_mech", "F_a", "eps_q")}


def one(path):
    t, why = results.read_test(path)
    if t is None:
        return None
    s = critical.with_fabric_anisotropy(t)
    keys = ("p", "q", "eta", "e", "eps_v", "Z_mech", "F_a")
    cols = {k: s[k] for k in keys if k in s}
    row = {"test": t["name"], "rows": t["rows"], "eps1_end": float(t["eps1"][-1]), "eps_q_end": float(t["eps_q"][-1])}
    n1 = critical.first_critical_row(t["eps1"], cols, criterion="v1")
    row["v1_stop_eps_q"] = float(t["eps_q"][n1 - 1]) if n1 else math.nan
    row["v1"] = state(critical.detect_critical_v1(t["eps1"][:n1], {k: v[:n1] for k, v in cols.items()},
                                                  **critical.APP_CRITERION_V1)) if n1 else None
    n2 = critical.first_critical_row(t["eps_q"], cols)
    row["v2_stop_eps_q"] = float(t["eps_q"][n2 - 1]) if n2 else math.nan
    row["v2_stop"] = state(critical.detect_critical(t["eps_q"][:n2], {k: v[:n2] for k, v in cols.items()})) \
        if n2 else None
    end = critical.detect_critical(t["eps_q"], cols)
    row["v2_end_reached"] = end["reached"]
    row["v2_end"] = state(end)
    row["v2_end_reasons"] = end["reasons"]
    return row


def fmt(x, f=".4f"):
    return "-" if x is None or not np.isfinite(x) else format(x, f)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("results", nargs="+")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    rows = [r for r in (one(f) for f in files(a.results)) if r is not None]
    print("| test | eps_q end | v1 stop eps_q | v2 stop eps_q | v2 at end | eta v1 / v2 stop / v2 end "
          "| e v1 / v2 stop / v2 end | p v1 / v2 end - 1 |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        v1, v2s, v2e = r["v1"] or {}, r["v2_stop"] or {}, r["v2_end"]
        dp = v1.get("p", math.nan) / v2e["p"] - 1 if v1 else math.nan
        print(f"| {r['test']} | {fmt(r['eps_q_end'], '.3f')} | {fmt(r['v1_stop_eps_q'], '.3f')} "
              f"| {fmt(r['v2_stop_eps_q'], '.3f')} | {'critical' if r['v2_end_reached'] else 'not critical'} "
              f"| {fmt(v1.get('eta'))} / {fmt(v2s.get('eta'))} / {fmt(v2e['eta'])} "
              f"| {fmt(v1.get('e'))} / {fmt(v2s.get('e'))} / {fmt(v2e['e'])} | {fmt(dp, '+.4f')} |")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(rows, fh, indent=1, default=lambda x: None)
    return 0


if __name__ == "__main__":
    sys.exit(main())
