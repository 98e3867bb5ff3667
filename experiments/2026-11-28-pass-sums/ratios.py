"""p10 / median / p90 of the per-round ratio new/old from rounds.sh output (stdin or files)."""
import sys

import numpy as np

for path in sys.argv[1:]:
    runs = {}
    for line in open(path):
        r, v, x = line.split()
        v = {'fc97e26': 'old'}.get(v, 'new' if v != 'old' else 'old')
        runs.setdefault(v, {})[int(r)] = float(x)
    rounds = sorted(set(runs['old']) & set(runs['new']))
    old = np.array([runs['old'][r] for r in rounds])
    new = np.array([runs['new'][r] for r in rounds])
    q = new / old
    print(f'{path}: {len(rounds)} rounds, old median {np.median(old) / 1e6:.2f} M, '
          f'new median {np.median(new) / 1e6:.2f} M '
          f'particle-steps/s; new/old p10 {np.percentile(q, 10):.3f} median {np.median(q):.3f} '
          f'p90 {np.percentile(q, 90):.3f}')
