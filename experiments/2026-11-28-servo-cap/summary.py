"""b = 1, 0.5 MPa, to eps_q = 0.04: how far p leaves its target with the servo cap at 10x and 20x the
axial rate (3 seeds, free and fixed cells). Usage: summary.py RUN_ROOT (run.sh's); prints one row
per run and writes RUN_ROOT/servo-cap.csv."""
import csv
import glob
import sys

import h5py
import numpy as np

rows = []
for d in sorted(glob.glob(sys.argv[1] + '/*-s20??-r??')):
    name = d.rsplit('/', 1)[1]
    cell, seed, ratio = name.split('-')
    with h5py.File(d + '/p-b1.00-p0_500kPa.h5', 'r') as f:
        s = f['series']
        p = s['p'][:] / 5e5
        q = s['q'][:]
        eps_q = s['eps_q'][:]
        rate = s['strain_rate'][:]
        # The cap in effect at each row (systems/servo.cpp limits): the run record's fixed floor
        # servo.max_rate, or the ratio times the driven axis's rate (x) when that is larger.
        settings = f.attrs['settings']
        settings = settings.decode() if isinstance(settings, bytes) else settings
        record = dict(line.split(' = ', 1) for line in settings.splitlines() if ' = ' in line)
        floor = float(record['servo.max_rate'])
        cap = np.maximum(floor, int(ratio[1:]) * np.abs(rate[:, 0]))
        at_cap = np.max(np.abs(rate[:, 1:]), axis=1) >= 0.999 * cap
        w = (eps_q >= 0.002) & (eps_q <= 0.03)
        eta = q / s['p'][:]
        rows.append(dict(cell=cell, seed=seed[1:], ratio=int(ratio[1:]),
                         max_p_error=float(np.max(np.abs(p - 1))),
                         mean_p_error_eps_q_0_002_0_03=float(np.mean(np.abs(p[w] - 1))),
                         rows_at_cap=int(np.sum(at_cap)), rows=len(p),
                         peak_eta=float(np.max(eta)), eta_at_eps_q_0_03=float(np.interp(0.03, eps_q, eta))))
keys = list(rows[0])
print(' '.join(keys))
for r in rows:
    print(' '.join(f'{r[k]:.4f}' if isinstance(r[k], float) else str(r[k]) for k in keys))
with open(sys.argv[1] + '/servo-cap.csv', 'w', newline='') as out:
    w = csv.DictWriter(out, fieldnames=keys)
    w.writeheader()
    w.writerows(rows)
