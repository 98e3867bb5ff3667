"""How short any schedule of the study's jobs could make its wall on 2 cores, from the two timed runs'
per-job walls (retime.csv; issue 46's 45 minutes).

The chained preparations run one at a time on both threads, the 60 tests two at a time on one thread
each (paper-faster.toml's parallel = 2). The core-seconds the jobs took are
2 x (the preparations' walls) + (the tests' walls); no order of the same jobs on the same cores can
finish in less than half of that, and the chain of preparations must finish before its last tests
start. So the wall of a perfect schedule is at least max(core-seconds / 2, the chain + the longest
test of the last sample). (Run on one thread beside the tests, the chain would save at most what its
two threads lose against two jobs: a few per cent of its ~340 s.) Against it, the measured walls
(/usr/bin/time of the whole command) and the cut in core-seconds that 45 minutes would need.

    /usr/bin/python3 experiments/2026-11-29-paper-faster/bound.py
"""
import csv
import os

HERE = os.path.dirname(os.path.abspath(__file__))
MEASURED_S = {'first': 53 * 60 + 59, 'second': 55 * 60 + 49}  # README: "Timed", "Re-timed"
TARGET_S = 45 * 60


def main():
    with open(os.path.join(HERE, 'retime.csv'), newline='') as f:
        rows = list(csv.DictReader(f))
    for run in ('first', 'second'):
        prep = sum(float(r[f'wall_{run}_s']) for r in rows if r['job'].startswith('prepare-'))
        tests = [float(r[f'wall_{run}_s']) for r in rows if not r['job'].startswith('prepare-')]
        last = max(float(r[f'wall_{run}_s']) for r in rows if r['job'].endswith('p0_16000kPa')
                   and not r['job'].startswith('prepare-'))
        core_s = 2 * prep + sum(tests)
        bound = max(core_s / 2, prep + last)
        print(f'{run} run: {len(tests)} tests, preparations {prep:.0f} s on 2 threads, tests {sum(tests):.0f} s '
              f'on 1 thread each: {core_s:.0f} core-s; any schedule >= {bound:.0f} s ({bound / 60:.1f} min); '
              f'measured {MEASURED_S[run]} s ({MEASURED_S[run] / 60:.1f} min, {MEASURED_S[run] / bound:.3f} of the '
              f'bound); 45 min needs {100 * (1 - TARGET_S / bound):.0f} % fewer core-seconds')


if __name__ == '__main__':
    main()
