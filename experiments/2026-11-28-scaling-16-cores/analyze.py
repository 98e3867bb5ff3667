"""Thread scaling of dem-bench on the tiled scenes on a lent 16-core machine (issue 46 item 3): per scene and thread
count, throughput by wall (dem-bench's particle_steps_per_s, the first neighbour-list build and spatial sort
included) and per step in steady state (the per-system timers of integrate, contact and gather; the one-off build
and sort left out), each against the 1-thread median of the same scene. Writes scaling.csv.

    /usr/bin/python3 experiments/2026-11-28-scaling-16-cores/analyze.py
"""
import csv
import json
import os

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
STEADY = ("integrate_initial", "contact", "force_gather", "integrate_final")


def read(name):
    rows = []
    for line in open(os.path.join(HERE, name)):
        line = line.strip()
        if line:
            body, rnd = line.rsplit(" round=", 1)
            rows.append(dict(json.loads(body), round=int(rnd), file=name))
    return rows


def main():
    out = []
    for name in ("scaling.jsonl", "long.jsonl", "long2.jsonl"):
        rows = read(name)
        for n in sorted({r["particles"] for r in rows}):
            sel = [r for r in rows if r["particles"] == n]
            one_wall = np.median([r["particle_steps_per_s"] for r in sel if r["threads"] == 1])
            one_step = np.median([sum(r["system_s"][k] for k in STEADY) / r["steps"] for r in sel if r["threads"] == 1])
            for r in sel:
                step = sum(r["system_s"][k] for k in STEADY) / r["steps"]
                out.append(dict(file=name, round=r["round"], particles=n, threads=r["threads"], steps=r["steps"],
                                wall_s=r["wall_s"], mps=r["particle_steps_per_s"] / 1e6,
                                eff_wall=r["particle_steps_per_s"] / one_wall / r["threads"],
                                step_ms=step * 1e3, eff_steady=one_step / step / r["threads"],
                                peak_mib=r["peak_mib"]))
    with open(os.path.join(HERE, "scaling.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(out[0]))
        w.writeheader()
        for r in out:
            w.writerow({k: (f"{v:.4g}" if isinstance(v, float) else v) for k, v in r.items()})
    for file in ("scaling.jsonl", "long.jsonl", "long2.jsonl"):
        for n in sorted({r["particles"] for r in out if r["file"] == file}):
            for t in sorted({r["threads"] for r in out if r["file"] == file and r["particles"] == n}):
                s = [r for r in out if r["file"] == file and r["particles"] == n and r["threads"] == t]
                print(f"{file} {n:8d} spheres, {t:2d} threads: {np.median([r['mps'] for r in s]):6.1f} M p-steps/s, "
                      f"efficiency by wall {min(r['eff_wall'] for r in s):.2f}-{max(r['eff_wall'] for r in s):.2f}, "
                      f"steady {min(r['eff_steady'] for r in s):.2f}-{max(r['eff_steady'] for r in s):.2f} "
                      f"({len(s)} runs)")


def per_round():
    """1,280,000 spheres, 16 threads against 1 thread of the same round (long.jsonl, long2.jsonl): p10 / median / p90
    of the ratio / 16, by wall and in steady state."""
    rows = read("long.jsonl") + read("long2.jsonl")
    wall, steady = [], []
    for r in sorted({x["round"] for x in rows}):
        one = [x for x in rows if x["round"] == r and x["threads"] == 1]
        many = [x for x in rows if x["round"] == r and x["threads"] == 16]
        if one and many:
            a, b = one[0], many[0]
            wall.append(b["particle_steps_per_s"] / a["particle_steps_per_s"] / 16)
            steady.append(sum(a["system_s"][k] for k in STEADY) / a["steps"] /
                          (sum(b["system_s"][k] for k in STEADY) / b["steps"]) / 16)
    for label, v in (("by wall", wall), ("steady", steady)):
        p10, med, p90 = np.percentile(v, [10, 50, 90])
        print(f"1,280,000 spheres, 16 threads / 1 thread of the same round / 16, {label}: p10 {p10:.2f}, median "
              f"{med:.2f}, p90 {p90:.2f} ({len(v)} rounds)")


if __name__ == "__main__":
    main()
    per_round()
