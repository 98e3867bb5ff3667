"""Speed versus accuracy of a sandcell triaxial test: what each numerical setting costs and buys.

    study.py [CONFIG] [--preset quick|inertia|full|size] [--out DIR] [--threads T] [--tolerance peak=X,res=X,e=X,d=X]
             [--triaxial PATH]

Takes the first test of CONFIG (default: the embedded default of `triaxial`; its p0, path and b,
its material and gradation) as the reference, run at the most accurate setting of every axis, and
varies one setting at a time from there:
  dt      time step as a fraction of the Rayleigh time
  I       inertial number I = eps_dot d50 sqrt(rho / p0) (sets the axial strain rate)
  E       Young's modulus scaled down (stiffness; the time step follows through the Rayleigh time)
  e       restitution (the contact damping)
  N       number of spheres
  seed    other random samples at the reference setting: the sample-to-sample scatter, i.e. the
          noise floor below which an error is not resolved at this N
The dt, I and e variants shear the reference's own prepared sample (copied, then `--resume`), so
their differences are the shearing numerics alone; E, N and seed variants prepare their own sample.

For every run: peak q/p, residual q/p and void ratio (means over the last --window of axial strain,
the critical state when the test reached it), the largest dilation rate -d eps_v / d eps_q (slopes
over 0.01 of axial strain), the mean inertial number after 1 %, the largest overlap / radius, the
shearing steps, wall seconds and particle-steps per second. Errors are absolute differences from
the reference. Written into --out: study.md (table, noise floor, recommendation), study.csv,
study.json, study.png and study.svg (each error against cost, particle-steps per unit axial
strain, with the Pareto front and the noise floor), and one folder of `triaxial` results per run.
Runs already complete in --out are reused (the study can be stopped and started again). The
recommendation names, per shearing axis, the cheapest setting whose errors are all within
--tolerance (default: the noise floor).

Presets (reference first):
  quick   400 spheres to 12 % axial strain; dt 0.05 | 0.1 0.2 0.35 0.5; I 3e-4 | 1e-3 3e-3 1e-2;
          E x 1 | 1/10 1/100; e 0.5 | 0.1 0.9; N 400 | 200 800; seeds 2, 3.  ~20 min on 2 cores.
  full    2000 spheres to 30 %; dt 0.05 | 0.1 0.2 0.35 0.5; I 1e-5 | 1e-4 1e-3 3e-3 1e-2;
          E x 1 | 1/10 1/100; e 0.5 | 0.1 0.9; N 2000 | 500 1000 5000 20000; seeds 2, 3, 4.
          The I = 1e-5 reference alone is ~2e8 steps: days on 16 cores. Axes can be narrowed.
  inertia the inertial number alone: 2000 spheres to 10 % at dt 0.2 dt_R; I 1e-5 | 3e-5 1e-4 3e-4
          1e-3 3e-3 1e-2. ~1 h on 2 cores. No seeds, so --tolerance is required for every metric
          (e.g. the size study's scatter at N = 2000: peak=0.014,res=0.016,e=0.004,d=0.015).
  size    the sample size on its own: N 500, 1000, 2000, 5000, 20000 x seeds 1, 2, 3, at dt 0.2 dt_R
          and I 1e-3, to 20 %; every run prepares its own sample and writes 20 particle snapshots
          (for `triaxial localization`). Per N: mean and standard deviation over the seeds of every
          measure, and the size error |mean(N) - mean(20000)|. ~1.7 h on 2 cores (each 20,000-sphere
          run ~22 min, 15 of them its preparation).
Exit status: 0 done; 2 bad input; 1 a run failed (its log is in <out>/<run>/log.txt).
"""
import argparse
import csv
import json
import math
import os
import shutil
import subprocess
import sys
import tomllib

from .dilatancy import slope_max_dilation  # noqa: F401 (re-exported)
from .results import read_columns, read_index, read_samples


PROG = os.environ.get("SANDCELL_ANALYZE_PROG", "study.py")


PRESETS = {
    # safety: the stiffness time step's factors (time.step = "stiffness", docs/physics.md section 4.1).
    "quick": dict(count=400, strain=0.12, dt=[0.05, 0.1, 0.2, 0.35, 0.5], I=[3e-4, 1e-3, 3e-3, 1e-2],
                  E=[1.0, 0.1, 0.01], e=[0.5, 0.1, 0.9], N=[400, 200, 800], seeds=[2, 3], safety=[0.6, 0.8, 1.0]),
    # A seconds-long pipeline check (tests/CMakeLists.txt, label analysis): not physics.
    "smoke": dict(count=120, strain=0.03, dt=[0.2, 0.4], I=[1e-2, 3e-2], E=[1.0, 0.3], e=[0.5, 0.9], N=[120, 160],
                  seeds=[2], safety=[0.8]),
    # Sample size and seed scatter at one practical setting (size_study): N x seeds.
    # `largest_seeds` (default: all) runs the largest N for the first seeds only; each 20,000-sphere
    # run takes ~23 min on 2 cores, 15 of them its preparation. `snapshots`: particle snapshots per
    # test, evenly spaced in strain (the strain fields of `triaxial localization`).
    "size": dict(kind="size", strain=0.2, dt=[0.2], I=[1e-3], E=[1.0], e=[0.5],
                 N=[500, 1000, 2000, 5000, 20000], seeds=[1, 2, 3], snapshots=20),
    "size-smoke": dict(kind="size", strain=0.03, dt=[0.2], I=[1e-2], E=[1.0], e=[0.5], N=[120, 160, 200],
                       seeds=[1, 2], largest_seeds=1),
    # The inertial-number axis alone, down to I = 1e-5 (quasi-static: docs/studies.md), at the
    # default's N and dt (the dt axis of `quick` moves the peak by 1e-3 at most): ~1 h on 2 cores,
    # 40 min of it the reference.
    # No seeds (one more I = 1e-5 run each): pass --tolerance from the size study's scatter at N = 2000.
    "inertia": dict(count=2000, strain=0.1, dt=[0.2], I=[1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2], E=[1.0],
                    e=[0.5], N=[2000], seeds=[]),
    "full": dict(count=2000, strain=0.3, dt=[0.05, 0.1, 0.2, 0.35, 0.5], I=[1e-5, 1e-4, 1e-3, 3e-3, 1e-2],
                 E=[1.0, 0.1, 0.01], e=[0.5, 0.1, 0.9], N=[2000, 500, 1000, 5000, 20000], seeds=[2, 3, 4],
                 safety=[0.6, 0.8, 1.0]),
}


# The keys that shape a prepared sample which the dt and e axes vary: their runs shear the
# reference's sample as it is (`triaxial --allow-change`).
SHARED_SAMPLE_KEYS = ("prepare.dt_fraction", "material.restitution")


METRICS = [("peak_eta", "peak q/p"), ("res_eta", "residual q/p"), ("res_e", "residual e"),
           ("max_dilation", "max -d")]


def fail(msg, code=2):
    print(f"{PROG}: {msg}", file=sys.stderr)
    sys.exit(code)


def toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    raise TypeError(v)


def toml_dump(cfg):
    out = []
    for table, body in cfg.items():
        out.append(f"[{table}]")
        out.extend(f"{k} = {toml_value(v)}" for k, v in body.items())
        out.append("")
    return "\n".join(out)


def first(v):
    return v[0] if isinstance(v, list) else v


def d50_of(sample):
    """Median diameter by mass of the configured gradation (what the app's inertial number uses)."""
    dist = sample.get("distribution", "uniform")
    if dist == "gradation":
        pts = sample["gradation"]
        for (d0, p0), (d1, p1) in zip(pts, pts[1:]):
            if p0 <= 50.0 <= p1:
                return d0 + (d1 - d0) * (50.0 - p0) / (p1 - p0) if p1 > p0 else d0
        fail("sample.gradation does not pass 50 %")
    d_min, d_max = sample.get("d_min", 5e-3), sample.get("d_max", 7.5e-3)
    if dist == "mono" or d_max <= d_min:
        return d_min
    # uniform by number: mass fraction below d is (d^4 - d_min^4) / (d_max^4 - d_min^4)
    return ((d_min ** 4 + d_max ** 4) / 2.0) ** 0.25


def base_config(path, triaxial):
    if path:
        try:
            with open(path, "rb") as f:
                cfg = tomllib.load(f)
        except (OSError, tomllib.TOMLDecodeError) as e:
            fail(f"{path}: {e}")
    else:
        text = subprocess.run([triaxial, "--print-default"], capture_output=True, text=True, check=True).stdout
        cfg = tomllib.loads(text)
    if "file" in cfg.get("sample", {}):
        fail("sample.file: the study varies N and the seed, so it needs a generated sample "
             "(count, d_min/d_max or gradation)")
    return cfg


def variant_config(base, preset, ref, **over):
    """The reference test with some settings replaced."""
    cfg = json.loads(json.dumps(base))  # deep copy
    for t in ("sample", "material", "time", "shear", "tests", "output"):
        cfg.setdefault(t, {})
    s = dict(ref, **over)
    tests = cfg["tests"]
    p0 = float(first(tests.get("p0", 0.5e6)))
    cfg["tests"] = {"path": first(tests.get("path", "constant_p")), "b": float(first(tests.get("b", 0.5))), "p0": p0}
    cfg["sample"]["count"] = int(s["N"])
    cfg["sample"]["seed"] = int(s["seed"])
    if s.get("safety"):  # the stiffness step in place of the Rayleigh fraction (whose key it refuses)
        cfg["time"] = {"step": "stiffness", "safety": float(s["safety"])}
    else:
        cfg["time"]["dt_fraction"] = float(s["dt"])
    mat = cfg["material"]
    young0 = float(base.get("material", {}).get("young", 70e9))
    mat["young"] = young0 * float(s["E"])
    mat["restitution"] = float(s["e"])
    rho = float(mat.get("density", 2650.0))
    rate = float(s["I"]) / (d50_of(cfg["sample"]) * math.sqrt(rho / p0))
    cfg["shear"].update(strain_rate=rate, max_axial_strain=preset["strain"], stop_at_critical=False)
    # About 400 rows per test whatever the step count: the metrics need the curves resolved.
    steps = preset["strain"] / (rate * time_step(cfg))
    cfg["output"].update(plot=False, series_interval=max(1, int(steps / 400)))
    if preset.get("snapshots"):
        cfg["output"]["snapshot_interval"] = max(1, int(steps / preset["snapshots"]))
    return cfg, rate


def time_step(cfg):
    """dt_fraction x the Rayleigh time of the smallest sphere (as the app computes it); for the stiffness step its
    bound, max_dt_fraction (default 1): the most a step can be, so the step count it gives is the fewest."""
    sample, mat = cfg["sample"], cfg["material"]
    if sample.get("distribution", "uniform") == "gradation":
        d_min = sample["gradation"][0][0]
    else:
        d_min = sample.get("d_min", 5e-3)
    young, nu, rho = float(mat.get("young", 70e9)), float(mat.get("poisson", 0.3)), float(mat.get("density", 2650.0))
    shear = young / (2.0 * (1.0 + nu))
    t = cfg["time"]
    fraction = t.get("max_dt_fraction", 1.0) if t.get("step") == "stiffness" else t["dt_fraction"]
    return fraction * math.pi * 0.5 * d_min * math.sqrt(rho / shear) / (0.1631 * nu + 0.8766)


def run_variant(name, cfg, args, share_sample_from=None):
    out = os.path.join(args.out, name)
    index = os.path.join(out, "index.csv")
    if os.path.exists(index):
        rows = read_index(out)
        if rows and finished(rows[-1]):
            return rows[-1], out
    os.makedirs(out, exist_ok=True)
    # Every run goes to its end: one that leaves its stress path is a result of the study (the
    # setting cannot hold the path), recorded, drawn, and never recommended.
    cfg.setdefault("watch", {})["stop"] = False
    cfg_path = os.path.join(out, "config.toml")
    with open(cfg_path, "w") as f:
        f.write(toml_dump(cfg))
    cmd = [args.triaxial, cfg_path, "--out", out, "--threads", str(args.threads)]
    if share_sample_from:
        for fn in os.listdir(share_sample_from):
            if fn.startswith("sample-") and fn.endswith(".h5") and not os.path.exists(os.path.join(out, fn)):
                shutil.copy2(os.path.join(share_sample_from, fn), os.path.join(out, fn))
        # The reference's sample was prepared at its own dt and restitution: sheared as it is on purpose
        # (the app refuses a sample whose preparation differs from the config unless told).
        cmd += ["--resume", "--allow-change", *SHARED_SAMPLE_KEYS]
    elif any(fn.endswith(".checkpoint.h5") for fn in os.listdir(out)):
        cmd.append("--resume")
    else:
        cmd.append("--overwrite")
    print(f"{PROG}: {name}: {' '.join(cmd)}", flush=True)
    with open(os.path.join(out, "log.txt"), "a") as log:
        rc = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT).returncode
    rows = read_index(out)
    left = rc == 1 and rows and rows[-1]["status"] == "failed" and rows[-1].get("reason")
    if (rc != 0 and not left) or not rows or not finished(rows[-1]):
        fail(f"{name}: triaxial exited {rc}; see {os.path.join(out, 'log.txt')}", 1)
    if left:
        print(f"{PROG}: {name}: {rows[-1]['reason']}", flush=True)
    return rows[-1], out


def finished(row):
    """A run that went to its end: done, or failed for leaving its stress path (watch.stop = false)."""
    return row["status"].startswith("done") or (row["status"] == "failed" and bool(row.get("reason")))


def metrics(row, out, window):
    s = read_columns(os.path.join(out, row["file"]), ("strain", "eta", "e", "eps_v", "eps_q", "inertial_number",
                                                      "max_overlap_ratio", "wall_time"))
    eps1 = s["strain"][:, 0]
    eta, e, eps_v, eps_q = s["eta"], s["e"], s["eps_v"], s["eps_q"]
    inertial, overlap, wall_time = s["inertial_number"], s["max_overlap_ratio"], s["wall_time"]
    tail = eps1 >= eps1[-1] - window
    after = eps1 >= 0.01
    steps, wall = float(row["steps"]), float(wall_time[-1])
    return dict(peak_eta=float(eta.max()), peak_strain=float(eps1[eta.argmax()]), res_eta=float(eta[tail].mean()),
                res_e=float(e[tail].mean()), max_dilation=slope_max_dilation(eps1, eps_v, eps_q),
                I=float(inertial[after].mean()), max_overlap=float(overlap[after].max()), e0=float(row["e0"]),
                steps=steps, wall=wall, strain=float(eps1[-1]))


def pareto(points):
    """Indices of the points not dominated in (cost, error), cheapest first."""
    order = sorted(range(len(points)), key=lambda k: (points[k][0], points[k][1]))
    front, best = [], math.inf
    for k in order:
        if points[k][1] < best:
            front.append(k)
            best = points[k][1]
    return front


def save_figure(fig, title, out):
    """Titles and writes study.png and study.svg into `out`; reports the outputs. Returns 0 (done)."""
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    for ext in ("png", "svg"):
        fig.savefig(os.path.join(out, f"study.{ext}"), dpi=110)
    print(f"{PROG}: wrote {os.path.join(out, 'study.md')} (+ csv, json, png, svg)")
    return 0


def mean_std(vals):
    """Mean and sample standard deviation (NaN for a single value) of the finite values."""
    vals = [v for v in vals if math.isfinite(v)]
    if not vals:
        return float("nan"), float("nan")
    mean = sum(vals) / len(vals)
    if len(vals) < 2:
        return mean, float("nan")
    return mean, math.sqrt(sum((v - mean) ** 2 for v in vals) / (len(vals) - 1))


def preparation(out):
    """Steps and wall seconds of the run's sample preparation (samples.csv; NaN without one)."""
    rows = read_samples(out)
    return (float(rows[0]["steps"]), float(rows[0]["wall_s"])) if rows else (float("nan"), float("nan"))


def size_study(args, preset, base):
    """N x seeds at one setting: how each measure's mean and its sample-to-sample scatter move with N.

    The largest N is the reference: |mean(N) - mean(N_max)| is the size error of N, and the standard
    deviation over the seeds at N is what one test of that size can resolve. Every run prepares its
    own sample (the seed is the sample's), so the scatter is that of the whole test. With fewer seeds
    at the largest N (preset largest_seeds), its own scatter is part of every size error.
    """
    seeds = preset["seeds"]
    n_max = max(preset["N"])
    seeds_max = seeds[:preset.get("largest_seeds", len(seeds))]
    ref = dict(dt=preset["dt"][0], I=preset["I"][0], E=preset["E"][0], e=preset["e"][0])
    os.makedirs(args.out, exist_ok=True)
    runs = []
    for n in preset["N"]:
        for seed in seeds_max if n == n_max else seeds:
            name = f"N{n}_seed{seed}"
            cfg, rate = variant_config(base, preset, ref, N=n, seed=seed)
            row, out = run_variant(name, cfg, args)
            m = metrics(row, out, args.window)
            m["left_path"] = row.get("reason", "") if row["status"] == "failed" else ""
            prep_steps, prep_wall = preparation(out)
            m.update(name=name, N=n, seed=seed, rate=rate, prep_steps=prep_steps, prep_wall=prep_wall,
                     Z0=float(row["Z0"]))
            m["psteps_per_s"] = n * m["steps"] / m["wall"] if m["wall"] > 0 else float("nan")
            m["cost"] = n * m["steps"] / max(m["strain"], 1e-12)
            runs.append(m)
            print(f"{PROG}: {name}: peak q/p {m['peak_eta']:.4f}, residual q/p {m['res_eta']:.4f}, e {m['res_e']:.4f}, "
                  f"max -d {m['max_dilation']:.3f}, {m['steps']:.0f} steps, {m['wall']:.1f} s", flush=True)

    keys = [k for k, _ in METRICS] + ["e0", "Z0", "peak_strain"]
    groups = []
    for n in preset["N"]:
        sel = [m for m in runs if m["N"] == n]
        g = dict(N=n, seeds=len(sel), wall=sum(m["wall"] for m in sel) / len(sel),
                 prep_wall=sum(m["prep_wall"] for m in sel) / len(sel),
                 prep_steps=sum(m["prep_steps"] for m in sel) / len(sel),
                 cost=sum(m["cost"] for m in sel) / len(sel),
                 psteps_per_s=sum(m["psteps_per_s"] for m in sel) / len(sel))
        for k in keys:
            g[k], g[f"std_{k}"] = mean_std([m[k] for m in sel])
        groups.append(g)
    top = groups[-1]
    for g in groups:
        for k in keys:
            g[f"err_{k}"] = abs(g[k] - top[k])

    fields = ["name", "N", "seed", "rate", "e0", "Z0", "prep_steps", "prep_wall", "peak_eta", "peak_strain", "res_eta",
              "res_e", "max_dilation", "I",
              "max_overlap", "steps", "wall", "psteps_per_s", "cost"]
    with open(os.path.join(args.out, "study.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, extrasaction="ignore")
        w.writeheader()
        w.writerows(runs)
    with open(os.path.join(args.out, "study.json"), "w") as f:
        json.dump(dict(preset=args.preset, setting=ref, window=args.window, runs=runs, by_size=groups), f, indent=1)

    cmd = f"triaxial study{' ' + args.config if args.config else ''} --preset {args.preset} --threads {args.threads}"
    labels = dict(METRICS, e0="e0", Z0="Z0", peak_strain="eps1 at peak")
    lines = [f"# Sample size: `{cmd}`", "",
             f"Setting: dt = {ref['dt']} dt_R, I = {ref['I']:g} (axial rate {runs[0]['rate']:.3g} /s), "
             f"E x {ref['E']:g}, e = {ref['e']}; seeds {', '.join(map(str, seeds))} per N "
             f"({', '.join(map(str, seeds_max))} at N = {n_max}), "
             "each sample prepared on its own "
             f"and sheared to {preset['strain']} axial strain. Residual values: means over the last {args.window} of "
             "axial strain. Per N: mean +- standard deviation over the seeds; size error: |mean - mean at the "
             f"largest N ({top['N']})|.", "",
             "| N | " + " | ".join(labels[k] for k in keys)
             + " | preparation steps | wall s, preparation + shearing | shearing M p-steps/s | "
             "cost (p-steps per unit strain) |",
             "|---" * (len(keys) + 5) + "|"]
    for g in groups:
        cells = [f"{g[k]:.4f} +- {g['std_' + k]:.4f}" if math.isfinite(g["std_" + k]) else
                 f"{g[k]:.4f} ({g['seeds']} seed)" for k in keys]
        lines.append(f"| {g['N']} | " + " | ".join(cells) + f" | {g['prep_steps']:.0f} | {g['prep_wall']:.0f} + "
                     f"{g['wall']:.0f} | {g['psteps_per_s'] / 1e6:.2f} | "
                     f"{g['cost']:.3g} |")
    lines += ["", "Size error |mean(N) - mean(N_max)| against the scatter of one test (standard deviation over the "
              "seeds at N):", "",
              "| N | " + " | ".join(f"{labels[k]}: error / scatter" for k, _ in METRICS) + " |",
              "|---" * (len(METRICS) + 1) + "|"]
    for g in groups:
        lines.append(f"| {g['N']} | " + " | ".join(f"{g['err_' + k]:.4f} / {g['std_' + k]:.4f}" if math.isfinite(
            g["std_" + k]) else f"{g['err_' + k]:.4f} / -" for k, _ in METRICS)
                     + " |")
    lines.append("")
    with open(os.path.join(args.out, "study.md"), "w") as f:
        f.write("\n".join(lines) + "\n")

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axs = plt.subplots(2, 3, figsize=(13, 7.5))
    for ax, k in zip(axs.flat, [k for k, _ in METRICS] + ["e0", "wall"]):
        if k == "wall":
            ax.plot([m["N"] for m in runs], [m["wall"] for m in runs], "o", color="C0", ms=4, label="shearing")
            ax.plot([m["N"] for m in runs], [m["prep_wall"] for m in runs], "^", color="C1", ms=4, label="preparation")
            ax.set_yscale("log")
            ax.set_ylabel("wall s per test")
            ax.legend(fontsize=7)
        else:
            ax.plot([m["N"] for m in runs], [m[k] for m in runs], "o", color="0.6", ms=3, label="one sample")
            ax.errorbar([g["N"] for g in groups], [g[k] for g in groups],
                        yerr=[g["std_" + k] if math.isfinite(g["std_" + k]) else 0.0 for g in groups], color="C0",
                        marker="s", ms=4, capsize=3, label="mean +- std over seeds")
            ax.set_ylabel(labels[k])
        ax.set_xscale("log")
        ax.set_xlabel("N (spheres)")
        ax.grid(True, which="both", alpha=0.3)
    axs.flat[0].legend(fontsize=7)
    return save_figure(fig, f"sandcell sample size ({cmd})", args.out)


def main(argv=None):
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="\n\n".join(__doc__.split("\n\n")[2:]))
    ap.add_argument("config", nargs="?", help="TOML configuration (default: the embedded default)")
    ap.add_argument("--preset", choices=sorted(PRESETS), default="quick")
    ap.add_argument("--out", default=None, help="output folder (default: results/study-<preset>)")
    ap.add_argument("--threads", type=int, default=2, help="threads of each run (default 2)")
    ap.add_argument("--axes", default="dt,I,E,e,N,seed,safety", help="axes to vary (default: all)")
    ap.add_argument("--window", type=float, default=0.03, help="residual window, axial strain (0.03)")
    ap.add_argument("--tolerance", default="",
                    help="accepted error per metric for the recommendation, e.g. peak=0.05,res=0.05,e=0.01,d=0.05 "
                         "(default: the noise floor of the seeds)")
    ap.add_argument("--triaxial", default=os.environ.get("SANDCELL_TRIAXIAL", "triaxial"),
                    help="the triaxial binary (default: the one that started the study)")
    args = ap.parse_args(argv)
    # Every option is checked before anything runs (a bad --window used to fail after the runs).
    if not 1 <= args.threads <= 1024:
        fail(f"--threads = {args.threads}: must be in [1, 1024] (the range of triaxial --threads)")
    if not (math.isfinite(args.window) and args.window > 0.0):
        fail(f"--window = {args.window}: must be > 0 (axial strain; values above a third of the preset's strain "
             "are cut to it)")
    if shutil.which(args.triaxial) is None:
        fail(f"--triaxial = {args.triaxial}: not an executable (give the path of the triaxial binary)")
    axes = args.axes.split(",")
    for a in axes:
        if a not in ("dt", "I", "E", "e", "N", "seed", "safety"):
            fail(f"--axes: unknown axis {a!r}; allowed: dt, I, E, e, N, seed, safety")
    names = dict(peak="peak_eta", res="res_eta", e="res_e", d="max_dilation")
    tolerances = {}
    for item in filter(None, args.tolerance.split(",")):
        key, _, value = item.partition("=")
        if key not in names:
            fail(f"--tolerance: unknown metric {key!r} in {item!r}; allowed: peak, res, e, d (e.g. peak=0.05)")
        try:
            tolerances[names[key]] = float(value)
        except ValueError:
            fail(f"--tolerance: {key} = {value!r} is not a number")
        if not tolerances[names[key]] >= 0.0:
            fail(f"--tolerance: {key} = {value}: must be >= 0")
    try:
        import h5py  # noqa: F401
        import matplotlib
        import numpy  # noqa: F401
    except ImportError as e:
        fail(f"needs python3 with numpy, matplotlib and h5py ({e})", 1)
    preset = PRESETS[args.preset]
    args.window = min(args.window, preset["strain"] / 3.0)
    args.out = args.out or os.path.join("results", f"study-{args.preset}")
    base = base_config(args.config, args.triaxial)
    if preset.get("kind") == "size":
        return size_study(args, preset, base)
    seed0 = int(base.get("sample", {}).get("seed", 1))
    ref = dict(dt=preset["dt"][0], I=preset["I"][0], E=preset["E"][0], e=preset["e"][0], N=preset["count"], seed=seed0)
    if preset["N"][0] != preset["count"]:
        raise AssertionError("the N axis starts at the reference count")

    plan = [("ref", "ref", {}, False)]
    if "dt" in axes:
        plan += [(f"dt_{v:g}", "dt", dict(dt=v), True) for v in preset["dt"][1:]]
    if "I" in axes:
        plan += [(f"I_{v:g}", "I", dict(I=v), True) for v in preset["I"][1:]]
    if "E" in axes:
        plan += [(f"E_x{v:g}", "E", dict(E=v), False) for v in preset["E"][1:]]
    if "e" in axes:
        plan += [(f"e_{v:g}", "e", dict(e=v), True) for v in preset["e"][1:]]
    if "N" in axes:
        plan += [(f"N_{v}", "N", dict(N=v), False) for v in preset["N"][1:]]
    if "seed" in axes:
        plan += [(f"seed_{v}", "seed", dict(seed=v), False) for v in preset["seeds"]]
    if "safety" in axes:  # the stiffness time step; shears the reference's sample
        plan += [(f"safety_{v:g}", "safety", dict(safety=v), True) for v in preset.get("safety", [])]

    # Without other seeds there is no noise floor: every error would pass a NaN tolerance.
    n_seeds = 1 + sum(1 for _, axis, _, _ in plan if axis == "seed")
    missing = [key for key, value in names.items() if value not in tolerances]
    if n_seeds < 2 and missing:
        fail(f"no other seeds run (preset {args.preset}, --axes {args.axes}), so no noise floor to judge the errors "
             f"by: give --tolerance for {', '.join(missing)} (e.g. the size study's scatter at this N)")

    os.makedirs(args.out, exist_ok=True)
    runs = []
    ref_out = None
    for name, axis, over, shares in plan:
        cfg, rate = variant_config(base, preset, ref, **over)
        row, out = run_variant(name, cfg, args, share_sample_from=ref_out if shares else None)
        if name == "ref":
            ref_out = out
        m = metrics(row, out, args.window)
        m["left_path"] = row.get("reason", "") if row["status"] == "failed" else ""
        setting = dict(ref, **over)
        m.update(name=name, axis=axis, rate=rate, **{f"set_{k}": v for k, v in setting.items()})
        m["N"] = setting["N"]
        m["psteps_per_s"] = m["N"] * m["steps"] / m["wall"] if m["wall"] > 0 else float("nan")
        m["cost"] = m["N"] * m["steps"] / max(m["strain"], 1e-12)  # particle-steps per unit axial strain
        runs.append(m)
        print(f"{PROG}: {name}: peak q/p {m['peak_eta']:.4f}, residual q/p {m['res_eta']:.4f}, e {m['res_e']:.4f}, "
              f"max -d {m['max_dilation']:.3f}, {m['steps']:.0f} steps, {m['wall']:.1f} s", flush=True)

    r0 = runs[0]
    for m in runs:
        for key, _ in METRICS:
            m[f"err_{key}"] = abs(m[key] - r0[key])
    seeds = [m for m in runs if m["axis"] in ("ref", "seed")]
    noise = {}
    for key, _ in METRICS:
        vals = [m[key] for m in seeds]
        mean = sum(vals) / len(vals)
        noise[key] = math.sqrt(sum((v - mean) ** 2 for v in vals) / (len(vals) - 1)) if len(vals) > 1 else float("nan")

    # Recommendation: per shearing axis (dt, I, e share the reference's sample, so their errors are
    # the numerics alone), the cheapest setting whose every error is within the tolerance (default:
    # the sample-to-sample scatter, below which an error is not resolved at this N).
    tol = dict(noise)
    for key, value in tolerances.items():
        tol[key] = value

    def within(m):
        return not m["left_path"] and all(not (m[f"err_{k}"] > tol[k]) for k, _ in METRICS)

    per_axis = {}
    for axis in ("dt", "I", "safety"):  # the axes that change the cost (e does not)
        ok = [m for m in runs if m["axis"] in ("ref", axis) and within(m)]
        per_axis[axis] = min(ok, key=lambda m: m["cost"]) if any(m["axis"] == axis for m in runs) and ok else None
    candidates = [m for m in runs if m["axis"] in ("ref", "dt", "I", "e", "safety")]
    ok = [m for m in candidates if within(m)]
    best = min(ok, key=lambda m: m["cost"]) if ok else None

    fields = ["name", "axis", "set_dt", "set_I", "set_E", "set_e", "set_N", "set_seed", "set_safety", "rate", "e0",
              "peak_eta", "peak_strain", "res_eta", "res_e", "max_dilation", "I", "max_overlap", "steps", "wall",
              "psteps_per_s", "cost"] + [f"err_{k}" for k, _ in METRICS] + ["left_path"]
    with open(os.path.join(args.out, "study.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, extrasaction="ignore")
        w.writeheader()
        w.writerows(runs)
    with open(os.path.join(args.out, "study.json"), "w") as f:
        json.dump(dict(preset=args.preset, reference=ref, window=args.window, noise_floor=noise, tolerance=tol,
                       runs=runs, recommended=best["name"] if best else None,
                       recommended_per_axis={a: (m["name"] if m else None) for a, m in per_axis.items()}), f, indent=1)

    cmd = f"triaxial study{' ' + args.config if args.config else ''} --preset {args.preset} " \
        f"--threads {args.threads}" + \
        (f" --tolerance {args.tolerance}" if args.tolerance else "")
    lines = [f"# Speed versus accuracy: `{cmd}`", "",
             f"Reference: {r0['N']} spheres, dt = {ref['dt']} dt_R, I = {ref['I']:g} (axial rate {r0['rate']:.3g} /s), "
             f"E x {ref['E']:g}, e = {ref['e']}, seed {ref['seed']}; sheared to {preset['strain']} axial strain. "
             f"Residual values: means over the last {args.window} of axial strain. Errors: |value - reference|. "
             "dt, I and e variants shear the reference's prepared sample; E, N and seed variants prepare their "
             "own.", "",
             "| run | peak q/p | residual q/p | residual e | max -d | mean I | max overlap/R | steps | wall s | "
             "M p-steps/s | err peak | err res q/p | err e | err -d |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for m in runs:
        mark = " (left its path)" if m["left_path"] else ""
        lines.append(f"| {m['name']}{mark} | {m['peak_eta']:.4f} | {m['res_eta']:.4f} | {m['res_e']:.4f} | "
                     f"{m['max_dilation']:.3f} | "
                     f"{m['I']:.2g} | {m['max_overlap']:.3g} | {m['steps']:.0f} | {m['wall']:.1f} | "
                     f"{m['psteps_per_s'] / 1e6:.2f} | {m['err_peak_eta']:.4f} | {m['err_res_eta']:.4f} | "
                     f"{m['err_res_e']:.4f} | {m['err_max_dilation']:.3f} |")
    if len(seeds) > 1:
        lines += ["", "Noise floor (standard deviation over the reference and the other seeds, same settings): " +
                  ", ".join(f"{label} {noise[k]:.4f}" for k, label in METRICS) + ".", ""]
    else:
        lines += ["", "Noise floor: not measured (no other seeds were run); the tolerance below is what stands "
                  "against the errors.", ""]
    tol_src = "the noise floor" if not tolerances else "--tolerance " + args.tolerance
    lines.append(f"Tolerance ({tol_src}): " + ", ".join(f"{label} {tol[k]:.4f}" for k, label in METRICS) + ".")
    lines.append("")
    if best:
        lines.append(f"Recommended (cheapest single change from the reference with every error within the tolerance): "
                     f"**{best['name']}** ("
                     + (f"stiffness step, safety {best['set_safety']:g}" if best.get("set_safety")
                        else f"dt = {best['set_dt']} dt_R") + f", I = {best['set_I']:g}, e = {best['set_e']}): "
                     f"{r0['cost'] / best['cost']:.1f}x cheaper than the reference per unit strain.")
    else:
        lines.append("No variant has every error within the tolerance.")
    for axis, m in per_axis.items():
        if m is None:
            continue
        key = dict(dt="set_dt", I="set_I", safety="set_safety")[axis]
        lines.append(f"- {axis}: the cheapest value within the tolerance is {m[key]:g} "
                     f"({r0['cost'] / m['cost']:.1f}x cheaper than the reference per unit strain)")
    lines.append("(one setting varied at a time: a combination of them is not measured here)")
    with open(os.path.join(args.out, "study.md"), "w") as f:
        f.write("\n".join(lines) + "\n")

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axs = plt.subplots(2, 2, figsize=(11, 8.5))
    colors = dict(ref="k", dt="C0", I="C1", E="C2", e="C3", N="C4", seed="C7", safety="C5")
    for ax, (key, label) in zip(axs.flat, METRICS):
        finite = [m for m in runs if math.isfinite(m[f"err_{key}"])]
        pts = [(m["cost"], m[f"err_{key}"]) for m in finite]
        for m in finite:
            ax.scatter(m["cost"], max(m[f"err_{key}"], 1e-5), color=colors[m["axis"]], s=28, zorder=3)
            ax.annotate(m["name"], (m["cost"], max(m[f"err_{key}"], 1e-5)), fontsize=7, xytext=(3, 3),
                        textcoords="offset points")
        front = pareto(pts)
        ax.plot([pts[k][0] for k in front], [max(pts[k][1], 1e-5) for k in front], "k--", lw=0.8, label="Pareto front")
        if math.isfinite(noise[key]) and noise[key] > 0:
            ax.axhline(noise[key], color="0.5", lw=0.8, ls=":", label="noise floor (seeds)")
        if key in tolerances:
            ax.axhline(tolerances[key], color="C3", lw=0.8, ls="-.", label="--tolerance")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("cost: particle-steps per unit axial strain")
        ax.set_ylabel(f"|error| of {label}")
        ax.grid(True, which="both", alpha=0.3)
    handles = [plt.Line2D([], [], marker="o", ls="", color=c, label=a) for a, c in colors.items()]
    axs.flat[0].legend(handles=handles + axs.flat[0].get_legend_handles_labels()[0], fontsize=7)
    return save_figure(fig, f"sandcell speed vs accuracy ({cmd})", args.out)
