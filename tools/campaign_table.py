#!/usr/bin/env python3
"""One row per test of a campaign: how it ended, its critical point, and whether it localized.

    campaign_table.py RUN_DIR ANALYSIS_DIR LOCALIZATION_DIR [--out FILE.md]

RUN_DIR holds the campaign's index.csv; ANALYSIS_DIR the summary.json of `triaxial analyze`;
LOCALIZATION_DIR the <test>-localization.csv files of `triaxial localization --whole` (one
increment, first snapshot to last). A test is banded when its whole-test strongest Fourier mode holds
more than localization.py's BAND_CONTRAST times the share of the same bins shuffled (its own
criterion for a band profile). Writes the table as markdown (--out, default stdout) and as CSV next
to it.
"""
import argparse
import csv
import json
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "apps", "triaxial"))
import localization  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run")
    ap.add_argument("analysis")
    ap.add_argument("localization")
    ap.add_argument("--out")
    a = ap.parse_args()
    with open(os.path.join(a.run, "index.csv")) as fh:
        index = list(csv.DictReader(fh))
    with open(os.path.join(a.analysis, "summary.json")) as fh:
        summary = json.load(fh)
    tests = {t["name"]: t for t in summary["tests"]}
    paths = {t["name"]: t for t in summary.get("path_checks", [])}  # every test, fitted or left out
    rows = []
    for r in index:
        name = r["test"]
        t = tests.get(name, {})
        cp = t.get("critical_point") or {}
        band, mode, share = "?", "", float("nan")
        loc = os.path.join(a.localization, f"{name}-localization.csv")
        if os.path.exists(loc):
            with open(loc) as fh:
                whole = list(csv.DictReader(fh))[-1]
            share, shuffled = float(whole["mode_share"]), float(whole["shuffled_share"])
            banded = share > localization.BAND_CONTRAST * shuffled
            band = "yes" if banded else "no"
            mode = f"({whole['mode_h']},{whole['mode_k']},{whole['mode_l']})"
        critical = t.get("critical") if t else paths.get(name, {}).get("critical")
        rows.append(dict(test=name, status=r["status"], final_eps1=float(r["final_eps1"]), steps=int(r["steps"]),
                         wall_s=float(r["wall_s"]), critical="yes" if critical else "no",
                         path_error=float(r.get("path_error", "nan")), rotation=float(r.get("rotation_deg", "nan")),
                         p_c=cp.get("p", float("nan")), M=cp.get("eta", float("nan")), e_c=cp.get("e", float("nan")),
                         banded=band, mode=mode, mode_share=share))
    lines = ["| test | status | path error % | rotation deg | final eps1 | steps | wall s | critical (analyze) | p_c MPa "
             "| q/p | e_c | banded | mode (share) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['test']} | {r['status']} | {100 * r['path_error']:.2f} | {r['rotation']:.1f} "
                     f"| {r['final_eps1']:.3f} | {r['steps']} | {r['wall_s']:.0f} | {r['critical']} | "
                     f"{r['p_c'] / 1e6:.3f} | {r['M']:.3f} | {r['e_c']:.4f} | {r['banded']} | {r['mode']} ({r['mode_share']:.2f}) |")
    n_crit = sum(r["critical"] == "yes" for r in rows)
    n_band = sum(r["banded"] == "yes" for r in rows)
    n_both = sum(r["critical"] == "yes" and r["banded"] == "yes" for r in rows)
    n_failed = sum(r["status"] == "failed" for r in rows)
    lines += ["", f"{len(rows)} tests: {n_failed} failed (left their stress path: not fitted), {n_crit} critical by "
              f"`triaxial analyze`, {n_band} banded, {n_both} of the critical points from a banded sample."]
    text = "\n".join(lines) + "\n"
    if a.out:
        with open(a.out, "w") as fh:
            fh.write(text)
        with open(os.path.splitext(a.out)[0] + ".csv", "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    else:
        sys.stdout.write(text)


if __name__ == "__main__":
    main()
