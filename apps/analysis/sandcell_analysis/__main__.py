"""python -m sandcell_analysis COMMAND [ARGS...]: every command of the analysis package.

Commands (each prints its own options with --help):
  analyze          critical state line, M(theta), dilatancy, report.md and summary.json (`triaxial analyze`)
  study            speed against accuracy, one numerical setting at a time (`triaxial study`)
  calibrate        micro-parameters fitted to macroscopic targets (`triaxial calibrate`)
  localization     local strain fields and the band profile (`triaxial localization`)
  plot             the figure of one results file: plot RESULTS.h5 OUT.png
  replay-critical  the app's critical-state stop replayed on a results file's series
  campaign-table   one row per test of a campaign: its end, critical point and band
  figures          the study's figures (Liu et al. 2017, Figs 2-4, 6, 8-12) redrawn: figures RESULTS... --out DIR

With the package on the path: installed (pip install --no-build-isolation --no-deps apps/analysis), or
PYTHONPATH=apps/analysis from the source tree.
"""
import importlib
import os
import sys

# command -> its module, whose main(argv) returns the exit status (plot: plot_main below)
COMMANDS = {
    "analyze": "analyze",
    "study": "study",
    "calibrate": "calibrate",
    "localization": "localization",
    "plot": None,
    "replay-critical": "replay",
    "campaign-table": "campaign_table",
    "figures": "study_figures",
}
PROG = "python -m sandcell_analysis"


def plot_main(argv):
    """plot RESULTS.h5 OUT.png: q, q/p, eps_v and e against eps_1 (plots.plot_run)."""
    line = f"usage: {PROG} plot RESULTS.h5 OUT.png"
    if argv[:1] in (["-h"], ["--help"]):
        print(line)
        return 0
    if len(argv) != 2:
        print(line, file=sys.stderr)
        return 2
    from .plots import plot_run
    plot_run(argv[0], argv[1])
    return 0


def usage(out):
    print(f"usage: {PROG} COMMAND [ARGS...]\n\n" + __doc__.split("\n\n", 1)[1], file=out, end="")


def main(argv=None):
    argv = sys.argv[1:] if argv is None else list(argv)
    if not argv or argv[0] in ("-h", "--help"):
        usage(sys.stdout if argv else sys.stderr)
        return 0 if argv else 2
    command, rest = argv[0], argv[1:]
    if command not in COMMANDS:
        print(f"{PROG}: error: unknown command '{command}' (one of: {', '.join(COMMANDS)})", file=sys.stderr)
        return 2
    if command == "plot":
        return plot_main(rest)
    # the commands' usage and messages name this command (read when their module is imported)
    os.environ.setdefault("SANDCELL_ANALYZE_PROG", f"{PROG} {command}")
    try:
        module = importlib.import_module(f".{COMMANDS[command]}", __package__)
    except ImportError as exc:  # an interpreter without the scientific stack
        print(f"{PROG}: error: {exc} (needs numpy, scipy, matplotlib and h5py; on Debian: "
              "apt install python3-numpy python3-scipy python3-matplotlib python3-h5py)", file=sys.stderr)
        return 1
    status = module.main(rest)
    return 0 if status is None else status


if __name__ == "__main__":
    sys.exit(main())
