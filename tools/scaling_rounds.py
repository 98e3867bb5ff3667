#!/usr/bin/python3
"""Thread scaling as a distribution, measured side by side: rounds of

    probe      dem-bench --probe: one register-only FP chain alone, T of them against one, the cache-line
               ping-pong between vCPUs 0 and 1, and one thread against memory (a dependent load
               over 16 MiB, a read stream over 64 MiB): what the machine allows, without any DEM code
    one        dem-bench, 1 thread
    owner      dem-bench, T threads, owner partition with its halo (--partition owner)
    dynamic    dem-bench, T threads, work-stealing partition (--partition dynamic)
    fixed      dem-bench, T threads, TBB's static partition (--partition fixed)
    adaptive   dem-bench, T threads, owner or dynamic as timed during the run (the default,
               --partition adaptive); the CSV's adaptive_owner column is the share of its steps
               run as owner
    liggghts   LIGGGHTS on T MPI ranks (when installed and --liggghts), same scene

for each thread count T of --threads, each run timed by itself, with the CPU time other processes
used meanwhile (from /proc/stat and the run's own rusage), so that rounds run beside a foreign load
can be told apart. Writes one CSV row per round (after every round, so a run stopped by
--minutes or killed keeps the rounds it finished) and prints p10 / median / p90 of every
throughput and of the per-round ratios.

    tools/scaling_rounds.py [--rounds 30] [--threads 2 | --threads 2,4,8,16] [--steps 2000]
        [--partitions adaptive,owner,dynamic,fixed] [--liggghts] [--liggghts-one] [--minutes M]
        [--compat] [--tile K] [--csv results/scaling-rounds.csv] [--bench build/release/apps/dem-bench/dem-bench]

With one T the CSV columns are one, owner, dynamic, fixed, liggghts (as in the published
experiments/2026-11-25-threading-windows/scaling-rounds-*.csv);
with several, each T-thread column is suffixed _T (owner_8,
liggghts_8). --liggghts-one adds LIGGGHTS on 1 rank (liggghts_1), for LIGGGHTS's own scaling.
The probe runs with the largest T.

The scene is dem-bench's dense-20k (scene A), or with --tile K that packing repeated K x K x K
times (2: 160,000 spheres); with --liggghts both codes run it in LIGGGHTS' mode (--compat: no
affine term), as tools/compare-liggghts.sh does.
"""
import argparse
import csv
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def proc_busy_ticks():
    with open("/proc/stat") as f:
        v = [int(x) for x in f.readline().split()[1:9]]
    return v[0] + v[1] + v[2] + v[5] + v[6]  # user nice system irq softirq


def children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def timed(cmd, cwd=None):
    """Runs cmd; returns (stdout, wall seconds, other processes' CPUs over the run)."""
    tick = os.sysconf("SC_CLK_TCK")
    b0, c0, t0 = proc_busy_ticks(), children_cpu(), time.monotonic()
    r = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    b1, c1, t1 = proc_busy_ticks(), children_cpu(), time.monotonic()
    if r.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed ({r.returncode}): {r.stderr.strip()[-500:]}")
    wall = t1 - t0
    foreign = max(0.0, (b1 - b0) / tick - (c1 - c0)) / wall
    return r.stdout, wall, foreign


def q(a):
    a = np.asarray(a, dtype=float)
    return np.percentile(a, [10, 50, 90])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[1])
    ap.add_argument("--rounds", type=int, default=30)
    ap.add_argument("--threads", default="2", help="T, or a comma-separated list of T (each >= 2)")
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--partitions", default="adaptive,owner,dynamic",
                    help="comma-separated, of adaptive, owner, dynamic, fixed")
    ap.add_argument("--liggghts", action="store_true", help="add LIGGGHTS on T ranks to every round")
    ap.add_argument("--liggghts-one", action="store_true", help="with --liggghts: LIGGGHTS on 1 rank too")
    ap.add_argument("--minutes", type=float, default=0.0, help="start no round after this many minutes (0: no limit)")
    ap.add_argument("--compat", action="store_true", help="dem-bench --compat (implied by --liggghts)")
    ap.add_argument("--tile", type=int, default=1,
                    help="the scene repeated K x K x K times (dem-bench --tile K; LIGGGHTS gets the same packing)")
    ap.add_argument("--csv", default=os.path.join(ROOT, "results", "scaling-rounds.csv"))
    ap.add_argument("--bench", default=os.path.join(ROOT, "build", "release", "apps", "dem-bench", "dem-bench"))
    args = ap.parse_args()
    try:
        threads = [int(t) for t in args.threads.split(",")]
    except ValueError:
        sys.exit(f"--threads {args.threads}: must be an integer or a comma-separated list of integers >= 2")
    partitions = args.partitions.split(",")
    if args.rounds < 1 or min(threads) < 2 or args.steps < 1 or args.minutes < 0:
        sys.exit("--rounds >= 1, --threads >= 2 (each), --steps >= 1, --minutes >= 0")
    known = ("owner", "dynamic", "fixed", "adaptive")
    if not partitions or any(p not in known for p in partitions) or len(set(partitions)) != len(partitions):
        sys.exit(f"--partitions {args.partitions}: a comma-separated list of distinct owner, dynamic, fixed, "
                 "adaptive")
    if not os.access(args.bench, os.X_OK):
        sys.exit(f"--bench {args.bench}: not an executable (build first)")
    if args.tile < 1:
        sys.exit(f"--tile {args.tile}: must be an integer >= 1")
    compat = ["--compat"] if (args.compat or args.liggghts) else []
    compat += ["--tile", str(args.tile)] if args.tile > 1 else []
    name = (lambda k, T: k) if len(threads) == 1 else (lambda k, T: f"{k}_{T}")  # noqa: E731
    ranks = ([1] if args.liggghts and args.liggghts_one else []) + (threads if args.liggghts else [])
    work = tempfile.mkdtemp(prefix="scaling-")
    if args.liggghts:
        if not shutil.which("liggghts") or not shutil.which("mpirun"):
            sys.exit("--liggghts: liggghts and mpirun must be installed (apt-get install liggghts)")
        subprocess.run([sys.executable, os.path.join(ROOT, "tools", "liggghts", "packing2data.py"),
                        os.path.join(ROOT, "apps", "dem-bench", "scenes", "dense-20k.txt"),
                        os.path.join(work, "dense-20k.data"), "--tile", str(args.tile)], check=True)
    os.makedirs(os.path.dirname(os.path.abspath(args.csv)), exist_ok=True)
    rows = []
    t_start = time.monotonic()
    try:
        for r in range(1, args.rounds + 1):
            if args.minutes and r > 1 and time.monotonic() - t_start > 60 * args.minutes:
                print(f"--minutes {args.minutes:g}: stopping after {r - 1} rounds", flush=True)
                break
            row = {"round": r}
            out, _, foreign = timed([args.bench, "--probe", "--threads", str(max(threads))])
            p = json.loads(out)
            row.update(alu_ratio=p["alu_ratio"], pingpong_ns=p["pingpong_ns"], probe_foreign=foreign)
            if "chase_ns" in p:  # older dem-bench binaries have no memory probe
                row.update(chase_ns=p["chase_ns"], stream_gbs=p["stream_gbs"])
            if "alu_one" in p:
                row.update(alu_one=p["alu_one"])
            runs = [("one", ["--threads", "1"])]
            for T in threads:
                runs += [(name(k, T), ["--threads", str(T), "--partition", k]) for k in partitions]
            for key, extra in runs:
                out, _, foreign = timed([args.bench, "--steps", str(args.steps), "--json", *compat, *extra])
                report = json.loads(out)
                row[key] = report["particle_steps_per_s"]
                particles = report["particles"]  # the same scene LIGGGHTS runs
                row[key + "_foreign"] = foreign
                steps = report.get("partition_steps", {})
                if key.startswith("adaptive") and steps.get("owner", 0) + steps.get("dynamic", 0) > 0:
                    row[key + "_owner"] = steps["owner"] / (steps["owner"] + steps["dynamic"])
            for T in ranks:
                out, _, foreign = timed(["mpirun", "--allow-run-as-root", "-np", str(T), "liggghts", "-in",
                                         os.path.join(ROOT, "tools", "liggghts", "bench.in"), "-var", "data",
                                         "dense-20k.data", "-var", "nsteps", str(args.steps), "-var", "erate", "0",
                                         "-log", "none"], cwd=work)
                loops = [float(line.split()[3]) for line in out.splitlines() if "Loop time" in line]
                key = "liggghts_1" if T == 1 else name("liggghts", T)
                row[key] = particles * args.steps / loops[1]  # the timed run, between the two `run 0`
                row[key + "_foreign"] = foreign
            rows.append(row)
            print(" ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in row.items()), flush=True)
            with open(args.csv, "w", newline="") as f:
                w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
                w.writeheader()
                w.writerows(rows)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    if not rows:
        sys.exit("no round finished")
    col = lambda k: np.array([row[k] for row in rows], dtype=float)  # noqa: E731
    one_median = np.median(col("one"))
    print(f"\n{len(rows)} rounds, {args.steps} steps, T = {args.threads}; p10 / median / p90")
    a = q(col("one") / 1e6)
    print(f"  {'one':12s} {a[0]:7.2f} {a[1]:7.2f} {a[2]:7.2f} M particle-steps/s")
    if args.liggghts and args.liggghts_one:
        a = q(col("liggghts_1") / 1e6)
        print(f"  {'liggghts_1':12s} {a[0]:7.2f} {a[1]:7.2f} {a[2]:7.2f} M particle-steps/s")
    for T in threads:
        for k in partitions + (["liggghts"] if args.liggghts else []):
            a = q(col(name(k, T)) / 1e6)
            print(f"  {name(k, T):12s} {a[0]:7.2f} {a[1]:7.2f} {a[2]:7.2f} M particle-steps/s")
        for k in partitions:
            a = q(col(name(k, T)) / col("one"))
            print(f"  {name(k, T)}/one per round {a[0]:.2f} {a[1]:.2f} {a[2]:.2f};  p10 of {name(k, T)} / median one "
                  f"{np.percentile(col(name(k, T)), 10) / one_median:.2f}")
            if args.liggghts:
                a = q(col(name(k, T)) / col(name("liggghts", T)))
                print(f"  {name(k, T)}/{name('liggghts', T)} per round {a[0]:.2f} {a[1]:.2f} {a[2]:.2f}")
            if k == "adaptive" and all(name(k, T) + "_owner" in row for row in rows):
                a = q(col(name(k, T) + "_owner"))
                print(f"  {name(k, T)} steps as owner {a[0]:.2f} {a[1]:.2f} {a[2]:.2f}")
        if args.liggghts and args.liggghts_one:
            a = q(col(name("liggghts", T)) / col("liggghts_1"))
            print(f"  {name('liggghts', T)}/liggghts_1 per round {a[0]:.2f} {a[1]:.2f} {a[2]:.2f}")
    # The host's two placements of the vCPUs (experiments/2026-11-25-threading-windows): near (a shared L3, ping-pong
    # ~40 ns) and far (~190 ns); the probe runs at the start of its round.
    far = col("pingpong_ns") > 120
    keys = ["one"] + [name(k, T) for T in threads for k in partitions + (["liggghts"] if args.liggghts else [])]
    for label, sel in (("near", ~far), ("far", far)):
        if sel.any():
            print(f"  {label} rounds ({sel.sum()}): median " + ", ".join(
                f"{k} {np.median(col(k)[sel]) / 1e6:.2f}" for k in keys) + " M")
    a = q(col("alu_ratio"))
    print(f"  register-only {max(threads)}/1 ratio {a[0]:.2f} {a[1]:.2f} {a[2]:.2f}; ping-pong ns "
          + " ".join(f"{x:.0f}" for x in q(col('pingpong_ns'))))
    # The host's own drift: a T-thread run exactly T times the 1-thread run of its round would score
    # T p10(one) / median(one) in the form p10(T threads) / median(one).
    print(f"  1-thread p10 / median {np.percentile(col('one'), 10) / one_median:.2f}: runs exactly T times the "
          "1-thread run of their round would give p10 / median one " + ", ".join(
              f"{T * np.percentile(col('one'), 10) / one_median:.2f} (T = {T})" for T in threads))
    # What the machine alone did in each round, against what each program did (probe.hpp).
    probes = [(k, label) for k, label in (("alu_one", "register-only chain, 1 thread"),
                                          ("chase_ns", "dependent load over 16 MiB, ns"),
                                          ("stream_gbs", "read stream over 64 MiB, GB/s"))
              if all(k in row for row in rows)]
    for k, label in probes:
        v = col(k) / (1e6 if k == "alu_one" else 1)
        print(f"  {label}{' (M/s)' if k == 'alu_one' else ''}: " + " ".join(f"{x:.4g}" for x in q(v)))
    if probes and len(rows) > 2:
        for k in keys:
            print(f"  correlation over rounds of log({k}) with log of " + ", ".join(
                f"{p} {np.corrcoef(np.log(col(k)), np.log(col(p)))[0, 1]:+.2f}" for p, _ in probes))
    quiet = [row for row in rows if max(v for k, v in row.items() if k.endswith("_foreign")) < 0.1]
    print(f"  rounds with no other process above 0.1 CPU: {len(quiet)} of {len(rows)}")
    print(f"wrote {args.csv}")


if __name__ == "__main__":
    main()
