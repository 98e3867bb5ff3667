"""The exploratory slower shear of the banded test (explore_inertial.sh), beside the validation's
paper and paper-faster tests of the same samples (tests.csv): e and q/p over the last 0.1 of eps_q,
q/p at eps_q 0.02, the peak q/p, steps. Exploratory: chosen after the interim data, no verdict.

Usage: PYTHONPATH=apps/analysis explore_inertial.py WORKDIR [INERTIAL_NUMBER (default 1.0e-3)]
           [--p0 500kPa] [--b 0.5] [--csv PATH]
"""
import argparse
import csv
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from compare import measures, read_tests  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("work")
    ap.add_argument("inertial", nargs="?", default="1.0e-3")
    ap.add_argument("--p0", default="500kPa", help="500kPa or 16000kPa")
    ap.add_argument("--b", default="0.5", help="0 or 0.5 (the validation's tests.csv holds both)")
    ap.add_argument("--csv", default=None,
                    help="default: explore-inertial.csv (500kPa, b 0.5), else explore-inertial[-P0][-bB].csv")
    a = ap.parse_args(argv)
    tests = read_tests(os.path.join(HERE, "tests.csv"))
    name = "explore-inertial" + ("" if a.p0 == "500kPa" else f"-{a.p0}") + ("" if a.b == "0.5" else f"-b{a.b}")
    out = a.csv or os.path.join(HERE, name + ".csv")
    slow = f"paper-faster-i{a.inertial}"
    rows = []
    for seed in (2017, 2018):
        m = measures(a.work, slow, seed, a.p0, a.b)
        if m is None:
            print(f"seed {seed}: no {slow} results in {a.work}")
            continue
        for protocol in ("paper", "paper-faster"):
            t = tests.get((protocol, seed, a.p0, a.b))
            if t:
                keys = ("protocol", "seed", "status", "ok", "eps_q_end", "e", "eta", "eta_2pct", "peak_eta", "steps",
                        "state_digest")
                rows.append({k: t[k] for k in keys})
        m = {k: round(v, 6) if isinstance(v, float) else v for k, v in m.items()}  # as tests.csv's rows
        rows.append({k: m[k] for k in rows[-1]} if rows else m)  # the same columns as the rows beside it
    with open(out, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    for r in rows:
        print(f"{r['protocol']:24s} {r['seed']} {r['status']:8s} eps_q {r['eps_q_end']:.3f} e {r['e']:.4f} "
              f"q/p {r['eta']:.4f} at 0.02 {r['eta_2pct']:.4f} peak {r['peak_eta']:.4f} steps {r['steps']}")


if __name__ == "__main__":
    main()
