#!/usr/bin/env python3
"""Rewrite the `banded` cells of the campaigns' committed tables with the band detector's verdicts, and nothing else.

    PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-28-band-detector/patch_tables.py [--results DIR]

The tables (tests.md and tests.csv of `campaign-table`, the table of paths in `triaxial analyze`'s report.md) were
made with the old criterion. Regenerating them would also rewrite what other work owns (the report's fits and
figures); this reads each test's verdict from `triaxial localization --whole`'s CSV (its `banded` column) in
RESULTS/<campaign>/localization and replaces only the banded cells, the count line of tests.md and the report's
sentence that states the criterion.
"""
import argparse
import csv
import os
import re
import sys

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
TABLES = (("2026-11-28-campaign-full", "paper-fast"),
          ("2026-11-28-campaign-full-calibrated", "paper-calibrated"),
          ("2026-11-28-campaign-full-calibrated/constant-sigma3", "paper-calibrated"),
          ("2026-11-28-campaign-reduced", "paper-reduced"))
OLD_SENTENCE = re.compile(r"Banded: from `triaxial localization --whole` .*?else not judged\.")
NEW_SENTENCE = ("Banded: the verdict of `triaxial localization` (`--localization DIR`: the whole test's strongest "
                "planar mode above the 0.99 quantile of homogeneous surrogates, the band's deps_q >= 2 x the outside's "
                "and its void-ratio contrast grown by >= 0.01 and 3 x noise; band_detector.py), else not judged.")


def verdict(results, campaign, test):
    path = os.path.join(results, campaign, "localization", f"{test}-localization.csv")
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows or "banded" not in rows[-1]:
        sys.exit(f"{path}: no `banded` column: run `triaxial localization --whole` (this tree's) first")
    return "yes" if int(rows[-1]["banded"]) else "no"


def patch_markdown_table(text, column, results, campaign):
    """Replace the cells of `column` in the markdown table whose first cell is a test name."""
    out, col = [], None
    for line in text.split("\n"):
        cells = line.split(" | ")
        if line.startswith("| test |"):
            names = [c.strip("| ") for c in cells]
            col = names.index(column) if column in names else None
        elif col is not None and re.match(r"\| (p|s3)-b", line):
            cells[col] = verdict(results, campaign, cells[0].lstrip("| "))
            line = " | ".join(cells)
        elif not line.startswith("|"):
            col = None
        out.append(line)
    return "\n".join(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--results", default="/work/campaigns")
    a = ap.parse_args(argv)
    for folder, campaign in TABLES:
        base = os.path.join(ROOT, "experiments", folder)
        tests_md = os.path.join(base, "tests.md")
        if os.path.exists(tests_md):
            text = patch_markdown_table(open(tests_md).read(), "banded", a.results, campaign)
            rows = [ln.split(" | ") for ln in text.split("\n") if re.match(r"\| (p|s3)-b", ln)]
            n_band = sum(r[11] == "yes" for r in rows)
            n_both = sum(r[11] == "yes" and r[7] == "yes" for r in rows)
            text = re.sub(r", \d+ banded, \d+ of the critical points from a banded sample\.",
                          f", {n_band} banded, {n_both} of the critical points from a banded sample.", text)
            open(tests_md, "w").write(text)
            tests_csv = os.path.join(base, "tests.csv")
            with open(tests_csv, newline="") as fh:
                table = list(csv.DictReader(fh))
            for r in table:
                r["banded"] = verdict(a.results, campaign, r["test"])
            with open(tests_csv, "w", newline="") as fh:
                w = csv.DictWriter(fh, fieldnames=list(table[0]))
                w.writeheader()
                w.writerows(table)
            print(f"{tests_md}: {n_band} of {len(rows)} banded")
        report = os.path.join(base, "report.md")
        text = patch_markdown_table(open(report).read(), "banded", a.results, campaign)
        text, n = OLD_SENTENCE.subn(NEW_SENTENCE, text)
        open(report, "w").write(text)
        print(f"{report}: banded cells rewritten, criterion sentence {'rewritten' if n else 'not found'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
