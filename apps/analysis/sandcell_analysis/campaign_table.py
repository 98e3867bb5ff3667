"""One row per test of a campaign: how it ended, its critical point, and whether it localized
(`campaign-table`).

    python -m sandcell_analysis campaign-table RUN_DIR ANALYSIS_DIR LOCALIZATION_DIR [--out FILE.md]

RUN_DIR holds the campaign's index.csv; ANALYSIS_DIR the summary.json of `triaxial analyze`;
LOCALIZATION_DIR the <test>-localization.csv files of `triaxial localization --whole` (one
increment, first snapshot to last). A test is banded when those files' `banded` column says so: the
band detector's verdict (band_detector.py: the whole test's strongest Fourier mode above homogeneous
surrogates and the physical criteria on strain and void ratio); a CSV without that column (written
before issue 45) is not judged ("?"). Writes the table as markdown (--out, default stdout) and as CSV
next to it.
"""
import argparse
import csv
import json
import os
import sys

from .results import InputError, read_csv_rows, read_index

PROG = os.environ.get("SANDCELL_ANALYZE_PROG", "campaign-table")
NAN = float("nan")
HEADER = ("| test | status | path error % | rotation deg | final eps1 | steps | wall s | critical (analyze) "
          "| p_c MPa | q/p | e_c | banded | mode (share) |")


def band_of(localization_dir, name):
    """(banded 'yes' / 'no' / '?', the mode '(h,k,l)', its share) of a test's whole-test increment."""
    rows = read_csv_rows(os.path.join(localization_dir, f"{name}-localization.csv"))
    if not rows:
        return "?", "", NAN
    whole = rows[-1]
    share = float(whole["mode_share"])
    band = ("yes" if int(whole["banded"]) else "no") if "banded" in whole else "?"
    return band, f"({whole['mode_h']},{whole['mode_k']},{whole['mode_l']})", share


def campaign_rows(run_dir, analysis_dir, localization_dir):
    """The table's rows (dicts, in index.csv's order)."""
    index = read_index(run_dir)
    if not index:
        raise InputError(f"no index.csv in {run_dir}")
    summary_path = os.path.join(analysis_dir, "summary.json")
    if not os.path.exists(summary_path):
        raise InputError(f"no summary.json in {analysis_dir}")
    with open(summary_path, encoding="utf-8") as fh:
        summary = json.load(fh)
    tests = {t["name"]: t for t in summary["tests"]}
    paths = {t["name"]: t for t in summary.get("path_checks", [])}  # every test, fitted or left out
    rows = []
    for r in index:
        name = r["test"]
        t = tests.get(name, {})
        cp = t.get("critical_point") or {}
        band, mode, share = band_of(localization_dir, name)
        critical = t.get("critical") if t else paths.get(name, {}).get("critical")
        rows.append(dict(test=name, status=r["status"], final_eps1=float(r["final_eps1"]), steps=int(r["steps"]),
                         wall_s=float(r["wall_s"]), critical="yes" if critical else "no",
                         path_error=float(r.get("path_error", "nan")), rotation=float(r.get("rotation_deg", "nan")),
                         p_c=cp.get("p", NAN), M=cp.get("eta", NAN), e_c=cp.get("e", NAN),
                         banded=band, mode=mode, mode_share=share))
    return rows


def markdown(rows):
    """The rows as a markdown table and a one-line count."""
    lines = [HEADER, "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['test']} | {r['status']} | {100 * r['path_error']:.2f} | {r['rotation']:.1f} "
                     f"| {r['final_eps1']:.3f} | {r['steps']} | {r['wall_s']:.0f} | {r['critical']} | "
                     f"{r['p_c'] / 1e6:.3f} | {r['M']:.3f} | {r['e_c']:.4f} | {r['banded']} | "
                     f"{r['mode']} ({r['mode_share']:.2f}) |")
    n_crit = sum(r["critical"] == "yes" for r in rows)
    n_band = sum(r["banded"] == "yes" for r in rows)
    n_both = sum(r["critical"] == "yes" and r["banded"] == "yes" for r in rows)
    n_failed = sum(r["status"] == "failed" for r in rows)
    lines += ["", f"{len(rows)} tests: {n_failed} failed (left their stress path: not fitted), {n_crit} critical "
              f"by `triaxial analyze`, {n_band} banded, {n_both} of the critical points from a banded sample."]
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n\n")[0].replace("\n", " "),
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="\n\n".join(__doc__.split("\n\n")[2:]))
    ap.add_argument("run", help="the campaign's folder (index.csv)")
    ap.add_argument("analysis", help="the folder of `triaxial analyze` (summary.json)")
    ap.add_argument("localization", help="the folder of `triaxial localization --whole`")
    ap.add_argument("--out", help="markdown file (a CSV is written next to it); default: stdout")
    a = ap.parse_args(argv)
    try:
        rows = campaign_rows(a.run, a.analysis, a.localization)
    except InputError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    text = markdown(rows)
    if not a.out:
        sys.stdout.write(text)
        return 0
    with open(a.out, "w", encoding="utf-8") as fh:
        fh.write(text)
    with open(os.path.splitext(a.out)[0] + ".csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
