"""2 threads over LIGGGHTS 2 ranks by where the host put the two vCPUs (the probe's ping-pong: near
below 150 ns, far above), in each set of rounds of tools/scaling_rounds.py given.

    /usr/bin/python3 placement.py [CSV...]   (default: this session's two 30-round sets)
"""
import csv
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT = [os.path.join(HERE, '..', '2026-11-30-rounds-30', 'rounds-20k.csv'),
           os.path.join(HERE, 'rounds-liggghts-20k.csv')]
NEAR_NS = 150.0


def main(paths):
    for path in paths or DEFAULT:
        with open(path, newline='') as f:
            rows = list(csv.DictReader(f))
        near = np.array([float(r['pingpong_ns']) < NEAR_NS for r in rows])
        ratio = np.array([float(r['adaptive']) / float(r['liggghts']) for r in rows])
        parts = []
        for label, sel in (('near', near), ('far', ~near)):
            if sel.sum():
                p = np.percentile(ratio[sel], [10, 50, 90])
                parts.append(f'{label} {sel.sum()} rounds: ' + ' / '.join(f'{x:.2f}' for x in p))
        print(f'{os.path.relpath(path)}: 2 threads / LIGGGHTS 2 ranks p10 / median / p90, ' + '; '.join(parts))


if __name__ == '__main__':
    main(sys.argv[1:])
