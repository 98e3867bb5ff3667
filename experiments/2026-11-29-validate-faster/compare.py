"""paper-faster.toml against the paper's rate (paper.toml in the free cell), three seeds (issue 46 item 1).

    PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-29-validate-faster/compare.py [WORKDIR] \
        [--tests experiments/2026-11-29-validate-faster/tests.csv] \
        [--out experiments/2026-11-29-validate-faster/compare.csv] \
        [--slower-out experiments/2026-11-29-validate-faster/compare-slower.csv]

WORKDIR is run.sh's: {paper,paper-faster}-s{2017,2018,2019}-p0_{500,16000}kPa-b{0,0.5}/, each with its one
constant-p test. The campaign outlives the machines it runs on (each session may start on a fresh one, and
results files are not committed), so every finished test's measures go into TESTS, a CSV kept in git: a test
found in WORKDIR is measured from its file and its row replaced; the rows of tests run on earlier machines are
kept. Each row carries the test's last state digest, so `triaxial verify` of a re-run checks it bitwise, and
the build that ran it (the first line of WORKDIR/BUILD.txt, run.sh's: the commit it was built from). Each
paper-faster test pairs with the paper-protocol test of its own sample. Writes one row per (p0, b, measure).

The slower shear's validation (run.sh's third stage; README, fixed before its data) is compared the same
way into --slower-out: protocol paper-faster-i1.0e-3 (I = 1e-3) against the paper's, b = 0.5 at both p,
seeds 2019-2021.

Measures: over the last 0.1 of eps_q (the decisive experiment's analyze.one_test) the mean e and q/p; q/p at
eps_q = 0.02; the peak q/p; the steps taken.

Criterion, fixed in README.md before any of these tests finished (as experiments/2026-11-28-stiffness-step's):
- only pairs where both tests held their path (the watchdog's done) to eps_q = 0.5 enter, both run by
  one build (tests.csv's build: the same sample bits);
- D = the mean over seeds of (faster - paper), SE_D = SD of the paired differences / sqrt(n);
- s = the sample SD over seeds of the paper-protocol tests;
- "within the seed scatter" when |D| + 2 SE_D <= s; "beyond" when |D| - 2 SE_D > s; else "not shown".
"""
import argparse
import csv
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "2026-11-28-one-csl-decisive"))
sys.path.append(os.path.join(HERE, "..", "2026-11-28-stiffness-step"))  # after: it has an analyze.py of its own
sys.path.insert(0, os.path.join(HERE, "..", "..", "apps", "analysis"))

import analyze  # noqa: E402
from sandcell_analysis import results  # noqa: E402
from seeds import judge, paired, write_rows  # noqa: E402  (the same criterion and table as the stiffness step's)

SEEDS = (2017, 2018, 2019)
CASES = [(p, b) for p in ("500kPa", "16000kPa") for b in ("0", "0.5")]
SLOW, SLOW_SEEDS = "paper-faster-i1.0e-3", (2019, 2020, 2021)
SLOW_CASES = [(p, "0.5") for p in ("500kPa", "16000kPa")]
MEASURES = ("e", "eta", "eta_2pct", "peak_eta")
KEY = ("protocol", "seed", "p0", "b")


def build_of(work):
    """The first line of WORKDIR/BUILD.txt (the commit the campaign's binary was built from), '' if none."""
    path = os.path.join(work, "BUILD.txt")
    if not os.path.exists(path):
        return ""
    with open(path) as fh:
        return fh.readline().strip()


def measures(work, protocol, seed, p0, b):
    folder = os.path.join(work, f"{protocol}-s{seed}-p0_{p0}-b{b}")
    test = f"p-b{float(b):.2f}-p0_{p0}"
    path = os.path.join(folder, test + ".h5")
    if not os.path.exists(path):
        return None
    status = analyze.index_status(folder).get(test, "running")
    end = analyze.one_test(path, status)
    cols = results.read_columns(path, ["eps_q", "eta", "step"], optional=["state_digest"])
    k = min(int(np.searchsorted(cols["eps_q"], 0.02)), len(cols["eta"]) - 1)
    halves = np.ravel(cols["state_digest"][-1]) if "state_digest" in cols else ()  # verify.cpp's row_digest
    last = f"{(int(halves[0]) << 32) | int(halves[1]):016x}" if len(halves) == 2 else ""
    return dict(protocol=protocol, seed=seed, p0=p0, b=b, status=status.split()[0] if status else "running",
                ok=status.startswith("done") and end["eps_q_end"] >= 0.499, eps_q_end=end["eps_q_end"],
                e=end["e"], eta=end["eta"], eta_2pct=float(cols["eta"][k]), peak_eta=float(np.nanmax(cols["eta"])),
                steps=int(cols["step"][-1]), rows=len(cols["step"]), state_digest=last, build=build_of(work))


def read_tests(path):
    """tests.csv's rows by (protocol, seed, p0, b), numbers parsed back."""
    if not os.path.exists(path):
        return {}
    out = {}
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            for k in ("eps_q_end", "e", "eta", "eta_2pct", "peak_eta"):
                r[k] = float(r[k])
            r["seed"], r["steps"], r["rows"] = int(r["seed"]), int(r["steps"]), int(r["rows"])
            r["ok"] = r["ok"] == "True"
            out[tuple(r[k] for k in KEY)] = r
    return out


def update_tests(work, path):
    """Measures every test of WORKDIR into tests.csv (rows of other machines kept); returns all rows by key."""
    tests = read_tests(path)
    wanted = {(pr, seed, p0, b) for pr in ("paper", "paper-faster") for seed in SEEDS for p0, b in CASES}
    wanted |= {(pr, seed, p0, b) for pr in ("paper", SLOW) for seed in SLOW_SEEDS for p0, b in SLOW_CASES}
    for key in sorted(wanted) if work else ():
        m = measures(work, *key)
        if m is not None and m["ok"]:
            tests[key] = m
    if tests:
        write_rows(path, [tests[k] for k in sorted(tests, key=lambda k: (k[1], k[0], k[2], k[3]))])
    return tests


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("work", nargs="?", help="run.sh's WORKDIR (omit to compare tests.csv's rows alone)")
    ap.add_argument("--tests", default=os.path.join(HERE, "tests.csv"))
    ap.add_argument("--out", default=os.path.join(HERE, "compare.csv"))
    ap.add_argument("--slower-out", default=os.path.join(HERE, "compare-slower.csv"))
    a = ap.parse_args(argv)
    tests = update_tests(a.work, a.tests)
    write_rows(a.out, compare(tests, "paper-faster", SEEDS, CASES))
    slower = compare(tests, SLOW, SLOW_SEEDS, SLOW_CASES)
    if any(r["pairs"] for r in slower):
        write_rows(a.slower_out, slower)
    return 0


def compare(tests, faster, seeds, cases):
    """One row per (p0, b, measure): protocol `faster` against the paper's over `seeds`, by the criterion."""
    rows = []
    for p0, b in cases:
        pairs = []
        for seed in seeds:
            ref = tests.get(("paper", seed, p0, b))
            fast = tests.get((faster, seed, p0, b))
            # One build's pair: another build's stress sums round otherwise, so its sample is another.
            if ref and fast and ref["ok"] and fast["ok"] and ref["build"] == fast["build"]:
                pairs.append((seed, ref, fast))
        for m in MEASURES:
            n = len(pairs)
            mean, d, se, s = paired(pairs, m)
            rows.append(dict(p0=p0, b=b, measure=m, pairs=n, seeds=" ".join(str(p[0]) for p in pairs),
                             paper_mean=mean, D=d, SE_D=se, seed_sd=s, verdict=judge(d, se, s),
                             steps_paper=int(sum(f["steps"] for _, f, _ in pairs)),
                             steps_faster=int(sum(g["steps"] for _, _, g in pairs))))
            r = rows[-1]
            print(f"{faster} {p0} b {b} {m:8s}: n {n}, paper {r['paper_mean']:.4f}, D {d:+.4f} +- {se:.4f}, "
                  f"seed SD {s:.4f}: {r['verdict']}; steps {r['steps_paper']} -> {r['steps_faster']}")
    return rows


if __name__ == "__main__":
    sys.exit(main())
