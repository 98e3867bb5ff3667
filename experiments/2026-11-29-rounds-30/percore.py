"""Summaries of percore.sh's runs: per round, the 160k / 20k throughput ratio (whole run, and
without the list build, which both runs do once), and each scene's gather and contact pass per
particle-step. Writes a CSV of every round.

Usage: percore.py OUT CSV
"""
import csv
import glob
import json
import os
import sys

import numpy as np


def load(path):
    with open(path) as f:
        return json.load(f)


def no_build(d):
    """Particle-steps per second over the systems' time less the broadphase (the one list build)."""
    s = d['system_s']
    return d['particles'] * d['steps'] / sum(v for k, v in s.items() if k != 'broadphase')


def main(out, csv_path):
    rounds = sorted({int(os.path.basename(p).split('.')[0][1:]) for p in glob.glob(os.path.join(out, 'r*.json'))})
    rows = []
    for r in rounds:
        files = {os.path.basename(p).split('.')[1]: load(p) for p in glob.glob(os.path.join(out, f'r{r}.*.json'))}
        a, b = files['20k'], files['160k']
        rows.append({'round': r, 'a': '20k', 'b': '160k',
                     'a_mps': a['particle_steps_per_s'] / 1e6, 'b_mps': b['particle_steps_per_s'] / 1e6,
                     'ratio': b['particle_steps_per_s'] / a['particle_steps_per_s'],
                     'ratio_no_build': no_build(b) / no_build(a),
                     'a_gather_ns': 1e9 * a['system_s']['force_gather'] / (a['particles'] * a['steps']),
                     'b_gather_ns': 1e9 * b['system_s']['force_gather'] / (b['particles'] * b['steps']),
                     'a_contact_ns': 1e9 * a['system_s']['contact'] / (a['particles'] * a['steps']),
                     'b_contact_ns': 1e9 * b['system_s']['contact'] / (b['particles'] * b['steps'])})
    with open(csv_path, 'w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    for key in [k for k in rows[0] if k not in ('round', 'a', 'b')]:
        v = np.percentile([row[key] for row in rows], [10, 50, 90])
        print(f'{key:15s} p10 / median / p90  {v[0]:.3f} / {v[1]:.3f} / {v[2]:.3f}')


if __name__ == '__main__':
    main(sys.argv[1], sys.argv[2])
