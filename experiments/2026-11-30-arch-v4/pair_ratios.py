"""Per-round ratios of the runs of pairs.sh (two binaries side by side, the same rounds).

    /usr/bin/python3 pair_ratios.py DIR BASE OTHER [--csv FILE]

Prints OTHER / BASE of the throughput and of the contact pass's own time, p10 / median / p90 over
the rounds, and each binary's median throughput; then, since the two CPUs need not run at the same
speed, each CPU's OTHER / BASE from neighbouring rounds (1 and 2, 3 and 4, ...: the two binaries on
that CPU); --csv writes every run.
"""
import argparse
import csv
import glob
import json
import os

import numpy as np


def load(path):
    with open(path) as f:
        j = json.load(f)
    return j['particle_steps_per_s'], j['system_s']['contact'], j['digest']


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('dir')
    ap.add_argument('base')
    ap.add_argument('other')
    ap.add_argument('--csv')
    args = ap.parse_args()
    runs = {}
    for p in glob.glob(os.path.join(args.dir, '*.json')):
        r, rest = os.path.basename(p)[:-5].split('-', 1)
        name, cpu = rest.split('@cpu')
        runs[(int(r), name)] = load(p) + (int(cpu),)
    rounds = sorted({r for r, n in runs if (r, args.base) in runs and (r, args.other) in runs})
    rate = np.array([runs[(r, args.other)][0] / runs[(r, args.base)][0] for r in rounds])
    pass_time = np.array([runs[(r, args.other)][1] / runs[(r, args.base)][1] for r in rounds])
    q = [10, 50, 90]
    med_base = np.median([runs[(r, args.base)][0] for r in rounds]) / 1e6
    med_other = np.median([runs[(r, args.other)][0] for r in rounds]) / 1e6
    print(f'{len(rounds)} rounds; {args.base} median {med_base:.2f} M, '
          f'{args.other} median {med_other:.2f} M particle-steps/s')
    print(f'{args.other} / {args.base} throughput p10 / median / p90: '
          + ' / '.join(f'{x:.3f}' for x in np.percentile(rate, q)))
    print(f'{args.other} / {args.base} contact pass time p10 / median / p90: '
          + ' / '.join(f'{x:.3f}' for x in np.percentile(pass_time, q)))
    for cpu in sorted({v[3] for v in runs.values()}):
        on = {(r, n): v[0] for (r, n), v in runs.items() if v[3] == cpu}
        same = [on[(r + 1 - 2 * (r % 2 == 0), args.other)] / on[(r, args.base)]
                for r in rounds if (r, args.base) in on and (r + 1 - 2 * (r % 2 == 0), args.other) in on]
        print(f'CPU {cpu}: {args.other} / {args.base} from neighbouring rounds ({len(same)} pairs): '
              + ', '.join(f'{x:.3f}' for x in same))
    digests = {runs[k][2] for k in runs}
    print('digests: ' + ', '.join(sorted(digests)))
    if args.csv:
        with open(args.csv, 'w', newline='') as f:
            w = csv.writer(f)
            w.writerow(['round', 'binary', 'cpu', 'particle_steps_per_s', 'contact_s', 'state_digest'])
            for (r, n), (t, c, d, cpu) in sorted(runs.items()):
                w.writerow([r, n, cpu, f'{t:.0f}', f'{c:.4f}', d])


if __name__ == '__main__':
    main()
