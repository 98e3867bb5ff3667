"""The two vCPUs' runs of run.sh: per round, each CPU alone, each while the other also runs, and
2 threads; the 2-thread run over the faster and the slower CPU alone of its round.

    /usr/bin/python3 analyze.py OUT [--csv FILE]
"""
import argparse
import collections
import csv
import glob
import json
import os

import numpy as np

KINDS = ['alone0', 'alone1', 'both0', 'both1', 'two']


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('dir')
    ap.add_argument('--csv')
    args = ap.parse_args()
    runs = collections.defaultdict(dict)
    for p in glob.glob(os.path.join(args.dir, '*.json')):
        r, kind = os.path.basename(p)[:-5].split('-', 1)
        with open(p) as f:
            text = f.read()
        if text.strip():  # a run still being written is skipped
            runs[int(r)][kind] = json.loads(text)['particle_steps_per_s'] / 1e6
    rounds = sorted(r for r in runs if all(k in runs[r] for k in KINDS))
    q = [10, 50, 90]

    def pct(x):
        return ' / '.join(f'{v:.3f}' for v in np.percentile(x, q))
    col = {k: np.array([runs[r][k] for r in rounds]) for k in KINDS}
    print(f'{len(rounds)} rounds, M particle-steps/s, p10 / median / p90:')
    for k in KINDS:
        print(f'  {k:7s} {pct(col[k])}')
    print(f'CPU 1 / CPU 0 alone:        {pct(col["alone1"] / col["alone0"])}')
    print(f'CPU 1 / CPU 0 both running: {pct(col["both1"] / col["both0"])}')
    print(f'both at once, sum / the faster alone: '
          f'{pct((col["both0"] + col["both1"]) / np.maximum(col["alone0"], col["alone1"]))}')
    print(f'2 threads / the faster CPU alone: {pct(col["two"] / np.maximum(col["alone0"], col["alone1"]))}')
    print(f'2 threads / the slower CPU alone: {pct(col["two"] / np.minimum(col["alone0"], col["alone1"]))}')
    print(f'2 threads / (CPU 0 alone + CPU 1 alone): {pct(col["two"] / (col["alone0"] + col["alone1"]))}')
    slower = np.minimum(col['alone0'], col['alone1'])
    faster = np.maximum(col['alone0'], col['alone1'])
    print(f'the ceiling of 2 threads / 1 thread where the 1 thread runs on the faster CPU, '
          f'1 + slower / faster: {pct(1 + slower / faster)}')
    if args.csv:
        with open(args.csv, 'w', newline='') as f:
            w = csv.writer(f)
            w.writerow(['round'] + KINDS)
            for r in rounds:
                w.writerow([r] + [f'{runs[r][k]:.3f}' for k in KINDS])


if __name__ == '__main__':
    main()
