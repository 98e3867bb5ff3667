"""The critical-state rule proposed for issue 45 (stop 54's note, before this study's data), applied to this
study's windows at eps_q 0.4-0.5 and 0.7-0.8 beside v2 (critical.py's rule): a measurement for the decision on
the rule's form, not a verdict; critical.py is unchanged.

    /usr/bin/python3 experiments/2026-11-29-paper-faster/proposal.py \
        [--out experiments/2026-11-29-paper-faster/proposal.csv]

Reads se_methods.csv and se_methods-08.csv (se_methods.py's: per test and quantity the window's change and two
standard errors, both as shares of the tolerance), so it needs no results file.
- v2: every quantity's |change| + 2 SE <= tolerance (eta, p, Z_mech 2 %; F_a 5 %; e 0.005).
- proposal: e, p, Z_mech and F_a as v2; eta only refused when its trend is significant (|change| > 2 SE),
  its window mean then reported as M_c with its SE.
Each under the rule's own SE (ar1: AR(1)-inflated, r1 clipped at 0.99) and under the batch-means SE of
10 blocks (batch10), per path and b.
"""
import argparse
import csv
import os
import re
import sys
from collections import defaultdict

HERE = os.path.dirname(os.path.abspath(__file__))
STATIONARY = ("p", "e", "Z_mech", "F_a")
WINDOWS = (("0.4-0.5", "se_methods.csv"), ("0.7-0.8", "se_methods-08.csv"))


def load(path):
    """{test: {quantity: row}} of a se_methods CSV."""
    by = defaultdict(dict)
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            by[r["test"]][r["quantity"]] = r
    return by


def judge(q, se):
    """(v2 passes, proposal passes, quantities the proposal refuses) of one test's rows under SE column se."""
    def within(k):
        return abs(float(q[k]["change"])) + float(q[k][se]) <= 1.0
    refused = [k for k in STATIONARY if not within(k)]
    eta_trend = abs(float(q["eta"]["change"])) > float(q["eta"][se])
    if eta_trend:
        refused.append("eta trend")
    return all(within(k) for k in (*STATIONARY, "eta")), not refused, refused


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=os.path.join(HERE, "proposal.csv"))
    a = ap.parse_args(argv)
    rows = []
    for window, name in WINDOWS:
        tests = load(os.path.join(HERE, name))
        for se in ("ar1", "batch10"):
            groups = defaultdict(list)
            for test, q in tests.items():
                path, b = test.split("-")[0], re.search(r"-b([\d.]+)-", test).group(1)
                groups[(path, b)].append(judge(q, se))
            for (path, b), js in sorted(groups.items()):
                refused = defaultdict(int)
                for _, _, why in js:
                    for k in why:
                        refused[k] += 1
                rows.append(dict(window=window, se=se, path=path, b=b, tests=len(js),
                                 v2=sum(j[0] for j in js), proposal=sum(j[1] for j in js),
                                 **{f"refused_{k.replace(' ', '_')}": refused[k] for k in (*STATIONARY, "eta trend")}))
            total = [r for r in rows if r["window"] == window and r["se"] == se]
            print(f"eps_q {window}, {se}: v2 passes {sum(r['v2'] for r in total)} of {sum(r['tests'] for r in total)},"
                  f" the proposal {sum(r['proposal'] for r in total)}; refused on " +
                  ", ".join(f"{k} {sum(r['refused_' + k.replace(' ', '_')] for r in total)}"
                            for k in (*STATIONARY, "eta trend")))
            for r in total:
                print(f"  {r['path']:2s} b {r['b']}: {r['proposal']} of {r['tests']} (e {r['refused_e']}, "
                      f"p {r['refused_p']}, F_a {r['refused_F_a']}, eta trend {r['refused_eta_trend']})")
    with open(a.out, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]), lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
