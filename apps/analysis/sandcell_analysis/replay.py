"""The app's critical-state stop replayed on a shearing test's series (`replay-critical`).

    python -m sandcell_analysis replay-critical RESULTS.h5 [--criterion v3|v2|v1] [--window W]
        [--tolerance T] [--tolerance-e T]

Applies the app's test (critical.APP_CRITERION, version 3, the twin of apps/triaxial/protocol/critical.hpp:
the last 0.1 of eps_q, eta, p, e, Z_mech and the fabric anisotropy by change + 2 standard errors, 6 in a
window of fewer than 10 effective rows; --criterion v2: 2 whatever the window; --criterion v1: the
first-passage test of the 2026-11-28 campaigns, the last 5 % of eps_1) after
every series row, as the app does with `shear.stop_at_critical`, and prints the first row where it
holds (strain, step, wall time, the changes, the window means) and the changes over the test's last
window. For a run made without the stop, or before the test changed: where the app would stop it
now. Reads the file with results.read_columns and tests with critical.detect_critical: no second
reader, no second test.
"""
import argparse
import os
import sys

import numpy as np

from .critical import (APP_CRITERION_V1, CRITERIA, detect_critical, detect_critical_v1, first_critical_row,
                       with_fabric_anisotropy)
from .results import InputError, read_columns

PROG = os.environ.get("SANDCELL_ANALYZE_PROG", "replay-critical")


def replay(path, window=None, tol_eta=None, tol_p=None, tol_e=None, criterion="v3"):
    """The app's stop on one results file. Returns a dict: x (eps_q for v3 and v2, eps_1 for v1), eps1, step,
    wall (arrays), rows (the number of rows read), first (rows of the first critical prefix, None if
    none is), at_first and last (the test's verdicts on that prefix and on the whole series),
    covered (whether the last window is long enough to be judged), criterion."""
    s = read_columns(path, ("strain", "p", "q", "e"), optional=("step", "wall_time", "eps_q", "Z_mech", "fabric"))
    eps1 = s["strain"][:, 0]
    series = {"p": s["p"], "q": s["q"], "eta": s["q"] / s["p"], "e": s["e"]}
    if criterion == "v1":
        base, test, x = APP_CRITERION_V1, detect_critical_v1, eps1
    else:
        if "eps_q" not in s:
            raise InputError(f"cannot read {path}: /series lacks eps_q (the version {criterion[1]} test's strain)")
        base, test, x = CRITERIA[criterion], detect_critical, s["eps_q"]
        series.update({k: s[k] for k in ("Z_mech", "fabric") if k in s})
        series = with_fabric_anisotropy(series)
        series.pop("fabric", None)
    given = dict(window=window, tol_eta=tol_eta, tol_p=tol_p, tol_e=tol_e)
    criterion_kw = dict(base, **{k: v for k, v in given.items() if v is not None})
    first = first_critical_row(x, series, criterion=criterion, **criterion_kw)
    at_first = None
    if first is not None:
        at_first = test(x[:first], {k: v[:first] for k, v in series.items()}, **criterion_kw)
    nan = np.full(eps1.size, np.nan)
    w = criterion_kw["window"]
    window_rows = x >= np.nanmax(x) - w if x.size else x.astype(bool)
    # the last window is covered as the test asks (critical.detect_critical's length checks)
    covered = bool(x.size and np.nanmax(x) >= w + criterion_kw["pre_strain"]
                   and window_rows.sum() >= criterion_kw["min_points"] and np.ptp(x[window_rows]) >= 0.9 * w)
    return {"x": x, "eps1": eps1, "step": s.get("step", nan), "wall": s.get("wall_time", nan), "rows": int(x.size),
            "covered": covered, "first": first, "at_first": at_first, "criterion": criterion,
            "last": test(x, series, **criterion_kw)}


def _changes(verdict):
    out = []
    for k, c in verdict["checks"].items():
        if c["relative"]:
            bound = f" (+2 SE {100 * c['bound']:.2f} %)" if "bound" in c else ""
            out.append(f"{k} {100 * c['measure']:.2f} %{bound}")
        else:
            out.append(f"{k} {c['measure']:.4f}" + (f" (+2 SE {c['bound']:.4f})" if "bound" in c else ""))
    return ", ".join(out)


def report(path, r):
    """The lines replay-critical prints for replay()'s result r."""
    eps1, x = r["eps1"], r["x"]
    lines = [f"{path}: {r['rows']} rows to eps1 = {100 * eps1[-1]:.2f} %" if r["rows"] else f"{path}: no rows"]
    n = r["first"]
    if n is None:
        lines.append(f"not critical at any row ({r['criterion']})")
    else:
        pt = r["at_first"]["point"]
        step, wall = r["step"][n - 1], r["wall"][n - 1]
        step = f"{int(step)}" if np.isfinite(step) else "?"  # files without /series/step or wall_time
        at = f", eps_q = {100 * x[n - 1]:.2f} %" if r["criterion"] != "v1" else ""
        lines.append(f"critical ({r['criterion']}) at row {n}: eps1 = {100 * eps1[n - 1]:.2f} %{at}, "
                     f"step {step}, wall {wall:.0f} s; changes over the window: "
                     f"{_changes(r['at_first'])}; window means: p {pt['p'] / 1e6:.4f} MPa, M {pt['M']:.4f}, "
                     f"e {pt['e']:.4f}")
    if r["covered"]:
        lines.append(f"last window: {_changes(r['last'])}")
    return lines


def main(argv=None):
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="\n\n".join(__doc__.split("\n\n")[2:]))
    ap.add_argument("results", help="a shearing test's results file (<test>.h5)")
    ap.add_argument("--criterion", choices=("v3", "v2", "v1"), default="v3",
                    help="v3: the app's test (default); v2: 2 standard errors whatever the window; "
                         "v1: the 2026-11-28 campaigns' first passage")
    ap.add_argument("--window", type=float, default=None,
                    help="eps_q for v3 and v2 (0.1), eps_1 for v1 (0.05)")
    ap.add_argument("--tolerance", type=float, default=None,
                    help="largest relative change of q/p and of p over the window (0.02)")
    ap.add_argument("--tolerance-e", type=float, default=None,
                    help="largest change of e over the window (0.005)")
    a = ap.parse_args(argv)
    try:
        r = replay(a.results, a.window, a.tolerance, a.tolerance, a.tolerance_e, criterion=a.criterion)
    except InputError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    print("\n".join(report(a.results, r)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
