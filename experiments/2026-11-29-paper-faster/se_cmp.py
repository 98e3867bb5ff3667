"""eta's and e's change and serially corrected SE over eps_q 0.4-0.5 (critical.py's trend), fixed
step against stiffness step on the same samples (issues 45, 46).

    PYTHONPATH=apps/analysis /usr/bin/python3 se_cmp.py DECISIVE_DIR STIFF_SEEDS_DIR

DECISIVE_DIR: the one-CSL decisive experiment's results (free-s2017..2019, the fixed 0.2 t_R step);
STIFF_SEEDS_DIR: experiments/2026-11-28-stiffness-step's run-seeds.sh results (the same samples,
time.step = "stiffness"). Prints each pair, the residuals' lag-1 r1 and the ratio of eta's SE.
"""
import sys

import h5py
import numpy as np

from sandcell_analysis.critical import trend

WINDOW = (0.4, 0.5)  # eps_q: the last 0.1 of paper-faster's tests


def measures(path):
    """(|change| of eta relative, its SE, r1, |change| of e, its SE, r1) over WINDOW."""
    with h5py.File(path, 'r') as f:
        s = f['series']
        eq = s['eps_q'][:]
        eta = s['q'][:] / s['p'][:]
        e = s['void_ratio'][:] if 'void_ratio' in s else s['e'][:]
    sel = (eq >= WINDOW[0]) & (eq <= WINDOW[1])
    out = []
    for y, relative in ((eta, True), (e, False)):
        slope, se, r1, _ = trend(eq[sel], y[sel], WINDOW[1] - WINDOW[0])
        scale = abs(np.mean(y[sel])) if relative and sel.any() else 1.0
        width = WINDOW[1] - WINDOW[0]
        out += [abs(slope * width) / scale, se * width / scale, r1]
    return out


def main():
    decisive, stiff = sys.argv[1], sys.argv[2]
    pairs = []
    print('seed p0 b | fixed: eta change, SE, r1; e change, SE | stiffness: the same')
    for seed in (2017, 2018, 2019):
        for p0 in ('500kPa', '8000kPa'):
            for b in ('0.00', '0.50', '1.00'):
                name = f'free-s{seed}/p-b{b}-p0_{p0}.h5'
                fx, st = measures(f'{decisive}/{name}'), measures(f'{stiff}/{name}')
                pairs.append((fx, st))
                print(f'{seed} {p0} {b} | {fx[0]:.4f} {fx[1]:.4f} {fx[2]:.2f}; {fx[3]:.4f} {fx[4]:.4f} | '
                      f'{st[0]:.4f} {st[1]:.4f} {st[2]:.2f}; {st[3]:.4f} {st[4]:.4f}')
    r1 = np.array([m[k] for pair in pairs for m in pair for k in (2, 5)])
    r1 = r1[np.isfinite(r1)]
    print(f'r1: {(r1 >= 0.97).sum()} of {r1.size} at >= 0.97, range {r1.min():.2f}-{r1.max():.2f}')
    ratio = np.array([st[1] / fx[1] for fx, st in pairs])
    ratio = ratio[np.isfinite(ratio)]
    print(f'eta SE ratio stiffness/fixed over {ratio.size} pairs: median {np.median(ratio):.2f}, '
          f'range {ratio.min():.2f}-{ratio.max():.2f}')


if __name__ == '__main__':
    main()
