"""Steps of the paper-faster study against paper-fast's, per p0.

    /usr/bin/python3 steps.py PAPER_FASTER/index.csv PAPER_FAST/index.csv
"""
import csv
import collections
import sys

new = list(csv.DictReader(open(sys.argv[1])))
old = list(csv.DictReader(open(sys.argv[2])))
by = collections.defaultdict(lambda: [0, 0, 0, 0])
for rows, k in ((new, 0), (old, 2)):
    for r in rows:
        by[float(r['p0_Pa'])][k] += int(float(r['steps'] or 0))
        by[float(r['p0_Pa'])][k + 1] += 1
print('p0 (MPa) | paper-faster steps (tests) | paper-fast steps (tests) | ratio')
tn = to = 0
for p in sorted(by):
    n, cn, o, co = by[p]
    tn += n
    to += o
    print(f'{p / 1e6:g} | {n:,} ({cn}) | {o:,} ({co}) | {o / n if n else float("nan"):.2f}')
print(f'total | {tn:,} | {to:,} | {to / tn:.2f}; particle-steps {tn * 19436:.3e} / {to * 19436:.3e}')
print('statuses:', collections.Counter(r['status'] for r in new))
