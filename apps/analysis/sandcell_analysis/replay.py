"""The app's critical-state stop replayed on a shearing test's series (`replay-critical`).

    python -m sandcell_analysis replay-critical RESULTS.h5 [--window 0.05] [--tolerance 0.02]
        [--tolerance-e 0.005]

Applies the app's test (critical.APP_CRITERION, the twin of apps/triaxial/protocol/critical.hpp) after every
series row, as the app does with `shear.stop_at_critical`, and prints the first row where it holds
(axial strain, step, wall time, the three changes, the window means) and the changes over the test's
last window. For a run made without the stop, or before the test changed: where the app would stop
it now. Reads the file with results.read_columns and tests with critical.detect_critical: no second
reader, no second test.
"""
import argparse
import os
import sys

import numpy as np

from .critical import APP_CRITERION, detect_critical, first_critical_row
from .results import InputError, read_columns

PROG = os.environ.get("SANDCELL_ANALYZE_PROG", "replay-critical")


def replay(path, window=0.05, tol_eta=0.02, tol_p=0.02, tol_e=0.005):
    """The app's stop on one results file. Returns a dict: eps1, step, wall (arrays), rows (the number
    of rows read), first (rows of the first critical prefix, None if none), at_first and last
    (detect_critical's verdicts on that prefix and on the whole series), covered (whether the last
    window is long enough to be judged)."""
    s = read_columns(path, ("strain", "p", "q", "e"), optional=("step", "wall_time"))
    eps1 = s["strain"][:, 0]
    series = {"p": s["p"], "q": s["q"], "eta": s["q"] / s["p"], "e": s["e"]}
    criterion = dict(APP_CRITERION, window=window, tol_eta=tol_eta, tol_p=tol_p, tol_e=tol_e)
    first = first_critical_row(eps1, series, **criterion)
    at_first = None
    if first is not None:
        at_first = detect_critical(eps1[:first], {k: v[:first] for k, v in series.items()}, **criterion)
    nan = np.full(eps1.size, np.nan)
    window_rows = eps1 >= eps1[-1] - window if eps1.size else eps1.astype(bool)
    # the last window is covered as the test asks (critical.detect_critical's length checks)
    covered = bool(eps1.size and eps1[-1] >= window + criterion["pre_strain"]
                   and window_rows.sum() >= criterion["min_points"] and np.ptp(eps1[window_rows]) >= 0.9 * window)
    return {"eps1": eps1, "step": s.get("step", nan), "wall": s.get("wall_time", nan), "rows": int(eps1.size),
            "covered": covered, "first": first, "at_first": at_first,
            "last": detect_critical(eps1, series, **criterion)}


def _changes(verdict):
    c = verdict["checks"]
    return f"eta {100 * c['eta']['measure']:.2f} %, p {100 * c['p']['measure']:.2f} %, e {c['e']['measure']:.4f}"


def report(path, r):
    """The lines replay-critical prints for replay()'s result r."""
    eps1 = r["eps1"]
    lines = [f"{path}: {r['rows']} rows to eps1 = {100 * eps1[-1]:.2f} %" if r["rows"] else f"{path}: no rows"]
    n = r["first"]
    if n is None:
        lines.append("not critical at any row")
    else:
        pt = r["at_first"]["point"]
        step, wall = r["step"][n - 1], r["wall"][n - 1]
        step = f"{int(step)}" if np.isfinite(step) else "?"  # files without /series/step or wall_time
        lines.append(f"critical at row {n}: eps1 = {100 * eps1[n - 1]:.2f} %, step {step}, "
                     f"wall {wall:.0f} s; changes over the window: {_changes(r['at_first'])}; "
                     f"window means: p {pt['p'] / 1e6:.4f} MPa, M {pt['M']:.4f}, e {pt['e']:.4f}")
    last = r["last"]
    if r["covered"]:
        lines.append(f"last window: {_changes(last)}")
    return lines


def main(argv=None):
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="\n\n".join(__doc__.split("\n\n")[2:]))
    ap.add_argument("results", help="a shearing test's results file (<test>.h5)")
    ap.add_argument("--window", type=float, default=APP_CRITERION["window"], help="axial strain (0.05)")
    ap.add_argument("--tolerance", type=float, default=APP_CRITERION["tol_eta"],
                    help="largest relative change of q/p and of p over the window (0.02)")
    ap.add_argument("--tolerance-e", type=float, default=APP_CRITERION["tol_e"],
                    help="largest change of e over the window (0.005)")
    a = ap.parse_args(argv)
    try:
        r = replay(a.results, a.window, a.tolerance, a.tolerance, a.tolerance_e)
    except InputError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    print("\n".join(report(a.results, r)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
