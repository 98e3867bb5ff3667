"""Per-round throughput ratios of dem-bench runs written by rounds.sh (issue 46).

    /usr/bin/python3 ratios.py DIR BASE [--csv FILE]

For each scene and thread count (L = 160,000 spheres, S = dense-20k; 1 or 2 threads): BASE's median
throughput and force_gather time, and for every other binary the ratio of its throughput to BASE's in
the same round (p10 / median / p90 over the rounds) and the median per-round ratio of the contact pass's
own time. --csv writes every run (round, binary, throughput, gather and contact pass times, gather calls
per order).
"""
import argparse
import collections
import csv
import glob
import json
import os

import numpy as np


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('dir')
    ap.add_argument('base')
    ap.add_argument('--csv')
    args = ap.parse_args()
    rate = collections.defaultdict(dict)
    gather = collections.defaultdict(dict)
    contact = collections.defaultdict(dict)
    rows = []
    for f in sorted(glob.glob(os.path.join(args.dir, '[LS][12]-*.json'))):
        cfg, r, name = os.path.basename(f)[:-5].split('-', 2)
        d = json.load(open(f))
        rate[(cfg, name)][r] = d['particle_steps_per_s'] / 1e6
        gather[(cfg, name)][r] = d['system_s']['force_gather']
        contact[(cfg, name)][r] = d['system_s']['contact']
        calls = d.get('gather_calls', {})
        rows.append(dict(scene='160k' if cfg[0] == 'L' else '20k', threads=cfg[1], round=r, binary=name,
                         mps=round(rate[(cfg, name)][r], 4), gather_s=gather[(cfg, name)][r],
                         contact_s=contact[(cfg, name)][r],
                         sorted_calls=calls.get('sorted', ''), array_calls=calls.get('array', ''),
                         digest=d['digest']))
    for cfg in sorted({k[0] for k in rate}):
        label = ('160k' if cfg[0] == 'L' else '20k') + ', ' + cfg[1] + ' thread' + ('s' if cfg[1] != '1' else '')
        base = rate[(cfg, args.base)]
        print(f'{label}: {args.base} median {np.median(list(base.values())):.2f} M particle-steps/s, '
              f'gather {np.median(list(gather[(cfg, args.base)].values())):.3f} s')
        for name in sorted({k[1] for k in rate if k[0] == cfg} - {args.base}):
            rs = [rate[(cfg, name)][r] / base[r] for r in rate[(cfg, name)] if r in base]
            p10, p50, p90 = np.percentile(rs, [10, 50, 90])
            pass_ratio = np.median([contact[(cfg, name)][r] / contact[(cfg, args.base)][r]
                                    for r in contact[(cfg, name)] if r in contact[(cfg, args.base)]])
            print(f'  {name} / {args.base}: p10 {p10:.3f} median {p50:.3f} p90 {p90:.3f} ({len(rs)} rounds), '
                  f'gather {np.median(list(gather[(cfg, name)].values())):.3f} s, '
                  f'contact pass time / {args.base}\'s {pass_ratio:.3f} (median per round)')
    if args.csv:
        with open(args.csv, 'w', newline='') as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)


if __name__ == '__main__':
    main()
