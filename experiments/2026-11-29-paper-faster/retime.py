"""The study's two timed runs, job by job (2026-11-29 on the x86-64-v3 build, 2026-11-30 on the v4
build): steps and wall of each preparation and test from their logs' done lines, and the per-job
ratio of steps per second (second run over first), p10 / median / p90.

    /usr/bin/python3 retime.py                       # from the committed retime.csv
    /usr/bin/python3 retime.py --logs FIRST_LOG SECOND_LOG   # rewrite retime.csv from two runs' logs
"""
import argparse
import csv
import os
import re

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DONE = re.compile(r"^(\S+): done at step (\d+).*?wall ([0-9.]+) s")


def done_lines(path):
    with open(path) as f:
        return {m[1]: (int(m[2]), float(m[3])) for m in map(DONE.match, f) if m}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--logs', nargs=2)
    ap.add_argument('--csv', default=os.path.join(HERE, 'retime.csv'))
    a = ap.parse_args()
    if a.logs:
        first, second = (done_lines(p) for p in a.logs)
        with open(a.csv, 'w', newline='') as f:
            w = csv.writer(f, lineterminator='\n')
            w.writerow(['job', 'steps_first', 'wall_first_s', 'steps_second', 'wall_second_s'])
            for job in sorted(set(first) & set(second)):
                w.writerow([job, *first[job], *second[job]])
    with open(a.csv, newline='') as f:
        rows = list(csv.DictReader(f))
    rate = {k: np.array([int(r['steps_' + k]) / float(r[f'wall_{k}_s']) for r in rows]) for k in ('first', 'second')}
    ratio = rate['second'] / rate['first']
    same = all(r['steps_first'] == r['steps_second'] for r in rows)
    walls = [sum(float(r[f'wall_{k}_s']) for r in rows) for k in ('first', 'second')]
    print(f"{len(rows)} jobs, the same steps in each: {same}; steps {sum(int(r['steps_second']) for r in rows):,}; "
          f"walls summed {walls[0]:.0f} s / {walls[1]:.0f} s")
    print('steps per second, second run / first, per job, p10 / median / p90: '
          + ' / '.join(f'{x:.2f}' for x in np.percentile(ratio, [10, 50, 90])))


if __name__ == '__main__':
    main()
