"""Calibration of a triaxial configuration's micro-parameters against macroscopic targets
(`triaxial calibrate`).

    triaxial calibrate CONFIG --targets FILE --param KEY=LO:HI [--param ...] [--choice KEY=A,B,...]
        [--budget N] [--out DIR] [--threads T] [--seed S] [--resume]

Method (a surrogate and its posterior, all in numpy/scipy):
1. Design: `budget` points of a scrambled Sobol sequence over the box of the free parameters (a
   parameter spanning more than a decade, e.g. `material.young`, is sampled in log).
2. Runs: each point is CONFIG with the parameters replaced, run by the triaxial binary in
   OUT/runs/run-NNN (resumable: a finished run is never run again; `--resume` continues a killed
   calibration). Campaign-level targets also run `triaxial analyze` on it.
3. Surrogate: per target, a quadratic polynomial in the normalized parameters, by least squares;
   its residual standard deviation s_t (over the runs' degrees of freedom) is the surrogate error.
4. Posterior: uniform prior on the box, Gaussian likelihood of every target with variance
   sigma_t^2 + s_t^2, evaluated on 2^16 Sobol points of the box: posterior mean, standard deviation
   and 5-95 % interval of each parameter, and its MAP.
5. Identifiability: a parameter whose posterior standard deviation is above half its prior's
   (range / sqrt 12) is reported as not identified by these targets; the sensitivity table gives,
   per target and parameter, the change of the target across the parameter's range in units of
   the target's sigma (at the posterior mean of the others).
6. A discrete choice (--choice, e.g. the rolling model): the design is run for every option, each
   with its own surrogates and posterior. Each option's evidence is the mean of its likelihood over
   the prior box (the same 2^16 points); with equal prior odds, the options' posterior
   probabilities are the evidences normalized. The chosen option is the most probable one, and
   steps 5-7 report it.
7. Check: one more run at the posterior mean, against every target.
Outputs in OUT: runs.csv (every run's parameters and measures), calibration.json, calibration.md,
calibration.png (each target against each parameter, with the surrogate's slice; the marginals).

Targets (TOML): one entry per measure, value and sigma (the tolerance the fit should respect):
    [targets]
    phi_c = { value = 22.0, sigma = 0.5 }        # campaign measures: triaxial analyze's summary
    "peak_eta:p-b0.00-p0_500kPa" = { value = 1.1, sigma = 0.02 }   # one test's index.csv column
    e0 = { value = 0.65, sigma = 0.01 }          # without ':TEST', the mean over the tests
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

import numpy as np

from .results import read_index
from .study import toml_dump

PROG = os.environ.get("SANDCELL_ANALYZE_PROG", "calibrate.py")

# The free parameters a calibration may vary: config key -> (lowest allowed, highest allowed).
PARAMETERS = {
    "material.friction": (0.0, 10.0),
    "material.rolling_friction": (0.0, 10.0),
    "material.restitution": (1e-3, 1.0),
    "material.young": (1e3, 1e13),
    "material.poisson": (-0.99, 0.49),
    "prepare.friction": (0.0, 10.0),
    "prepare.rolling_friction": (0.0, 10.0),
    "contact.rolling_damping": (0.0, 10.0),
}

# The discrete choices a calibration may make: config key -> the options allowed.
CHOICES = {
    "contact.rolling": ("none", "epsd2", "epsd", "cdt"),
    "contact.tangential": ("history", "incremental", "mindlin_rescale"),
}

# Campaign measures (triaxial analyze's summary.json): name -> path of keys.
CAMPAIGN_TARGETS = {
    "phi_c": ("m_theta", "phi_c_deg"),
    "phi_e": ("m_theta", "phi_e_deg"),
    "M_c": ("m_theta", "params", "M_c"),
    "e_Gamma": ("csl", "params", "e_gamma"),
    "lambda": ("csl", "params", "lambda"),
    "xi": ("csl", "params", "xi"),
    "d0": ("li_dafalias", "params", "d0"),
    "m": ("li_dafalias", "params", "m"),
}
# Per-test measures (index.csv columns), as NAME (mean over the tests) or NAME:TEST.
TEST_TARGETS = ("e0", "Z0", "peak_eta", "eps1_at_peak", "final_eta", "final_e", "final_p_Pa")


def fail(msg, code=2):
    print(f"{PROG}: {msg}", file=sys.stderr)
    sys.exit(code)


def parse_param(text):
    if "=" not in text or ":" not in text.split("=", 1)[1]:
        fail(f"--param {text}: expected KEY=LO:HI, e.g. material.friction=0.2:0.8")
    key, rng = text.split("=", 1)
    if key not in PARAMETERS:
        fail(f"--param {key}: unknown parameter (allowed: {', '.join(PARAMETERS)})")
    try:
        lo, hi = (float(x) for x in rng.split(":", 1))
    except ValueError:
        fail(f"--param {text}: LO and HI must be numbers")
    a, b = PARAMETERS[key]
    if not (math.isfinite(lo) and math.isfinite(hi)) or not lo < hi:
        fail(f"--param {key}={lo:g}:{hi:g}: the range must be non-empty with LO < HI")
    if lo < a or hi > b:
        fail(f"--param {key}={lo:g}:{hi:g}: outside what the config allows, [{a:g}, {b:g}]")
    return key, lo, hi


def parse_choice(text):
    if "=" not in text:
        fail(f"--choice {text}: expected KEY=A,B,..., e.g. contact.rolling=epsd2,epsd,cdt")
    key, opts = text.split("=", 1)
    if key not in CHOICES:
        fail(f"--choice {key}: unknown choice (allowed: {', '.join(CHOICES)})")
    options = [o for o in opts.split(",") if o]
    bad = [o for o in options if o not in CHOICES[key]]
    if bad:
        fail(f"--choice {key}: unknown option {bad[0]!r} (allowed: {', '.join(CHOICES[key])})")
    if len(set(options)) != len(options) or len(options) < 2:
        fail(f"--choice {text}: needs at least two different options")
    return key, options


def parse_targets(path):
    try:
        with open(path, "rb") as f:
            doc = tomllib.load(f)
    except (OSError, tomllib.TOMLDecodeError) as e:
        fail(f"--targets {path}: {e}")
    table = doc.get("targets")
    if not isinstance(table, dict) or not table:
        fail(f"--targets {path}: expected a [targets] table with at least one entry")
    targets = {}
    for name, spec in table.items():
        base = name.split(":", 1)[0]
        if base not in CAMPAIGN_TARGETS and base not in TEST_TARGETS:
            fail(f"--targets {path}: targets.{name}: unknown measure (allowed: "
                 f"{', '.join(list(CAMPAIGN_TARGETS) + list(TEST_TARGETS))}, the latter optionally as NAME:TEST)")
        if base in CAMPAIGN_TARGETS and ":" in name:
            fail(f"--targets {path}: targets.{name}: {base} is a campaign measure, it takes no ':TEST'")
        if not isinstance(spec, dict) or "value" not in spec or "sigma" not in spec:
            fail(f"--targets {path}: targets.{name}: expected {{ value = ..., sigma = ... }}")
        value, sigma = spec["value"], spec["sigma"]
        if not all(isinstance(x, (int, float)) and math.isfinite(x) for x in (value, sigma)) or not sigma > 0:
            fail(f"--targets {path}: targets.{name}: value must be a finite number and sigma > 0 "
                 f"(got {value!r}, {sigma!r})")
        targets[name] = (float(value), float(sigma))
    return targets


def n_coefficients(p):
    return (p + 1) * (p + 2) // 2


def min_budget(p):
    """A quadratic surrogate in p parameters, with two degrees of freedom left for its error."""
    return n_coefficients(p) + 2


# ------------------------------------------------------------------------------ design and runs
def log_scale(lo, hi):
    return lo > 0 and hi / lo > 10.0


def to_params(u, space):
    """Unit-cube points -> parameter values (log where the range spans more than a decade)."""
    out = np.empty_like(u)
    for k, (_, lo, hi) in enumerate(space):
        if log_scale(lo, hi):
            out[:, k] = np.exp(np.log(lo) + u[:, k] * (np.log(hi) - np.log(lo)))
        else:
            out[:, k] = lo + u[:, k] * (hi - lo)
    return out


def to_unit(x, space):
    u = np.empty_like(x, dtype=float)
    for k, (_, lo, hi) in enumerate(space):
        if log_scale(lo, hi):
            u[..., k] = (np.log(x[..., k]) - np.log(lo)) / (np.log(hi) - np.log(lo))
        else:
            u[..., k] = (x[..., k] - lo) / (hi - lo)
    return u


def design(space, budget, seed):
    import warnings
    from scipy.stats import qmc
    with warnings.catch_warnings():  # a budget that is not a power of 2 loses the balance, not the coverage
        warnings.simplefilter("ignore", UserWarning)
        return qmc.Sobol(d=len(space), scramble=True, seed=seed).random(budget)


def run_config(base, space, x, choice=None):
    cfg = json.loads(json.dumps(base))
    for (key, _, _), v in zip(space, x):
        table, name = key.split(".", 1)
        cfg.setdefault(table, {})[name] = float(v)
    if choice is not None:
        table, name = choice[0].split(".", 1)
        cfg.setdefault(table, {})[name] = choice[1]
    cfg.setdefault("output", {})["plot"] = False
    return cfg


def measures_of(folder, targets, triaxial):
    """The targets' measures of one finished run: NaN for a target whose tests all left their stress
    path (status failed): such a test is no measure of anything, and the run leaves that target's
    surrogate (fit_targets)."""
    every = read_index(folder)
    rows = [r for r in every if r.get("status", "").startswith("done")]
    if not rows:
        return None
    out = {}
    summary = None
    for name in targets:
        base, _, test = name.partition(":")
        if base in CAMPAIGN_TARGETS:
            if summary is None:
                analysis = os.path.join(folder, "analysis")
                path = os.path.join(analysis, "summary.json")
                if not os.path.exists(path):
                    subprocess.run([triaxial, "analyze", folder, "--out", analysis], capture_output=True, text=True)
                summary = json.load(open(path)) if os.path.exists(path) else {}
            v = summary
            for k in CAMPAIGN_TARGETS[base]:
                v = v.get(k) if isinstance(v, dict) else None
            out[name] = float(v) if isinstance(v, (int, float)) else float("nan")
        else:
            chosen = [r for r in rows if not test or r["test"] == test]
            if test and not any(r["test"] == test for r in every):
                fail(f"targets.{name}: no test named {test} in {folder}/index.csv "
                     f"(tests: {', '.join(r['test'] for r in every)})")
            out[name] = float(np.mean([float(r[base]) for r in chosen])) if chosen else float("nan")
    return out


def run_point(name, cfg, args):
    folder = os.path.join(args.out, "runs", name)
    os.makedirs(folder, exist_ok=True)
    path = os.path.join(folder, "config.toml")
    text = toml_dump(cfg)
    rows = read_index(folder) if os.path.exists(os.path.join(folder, "index.csv")) else []
    old = open(path).read() if os.path.exists(path) else None
    same = old == text  # a folder of another point (changed ranges, a new posterior mean) is run again
    if same and rows and all(complete(r) for r in rows):
        return folder
    with open(path, "w") as f:
        f.write(text)
    shutil.rmtree(os.path.join(folder, "analysis"), ignore_errors=True)  # the measures of what runs now
    resume = same and any(fn.endswith(".checkpoint.h5") or fn.startswith("sample-") for fn in os.listdir(folder))
    cmd = [args.triaxial, path, "--out", folder, "--threads", str(args.threads),
           "--resume" if resume else "--overwrite"]
    print(f"{PROG}: {name}: {' '.join(cmd)}", flush=True)
    with open(os.path.join(folder, "log.txt"), "a") as log:
        rc = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT).returncode
    rows = read_index(folder) if os.path.exists(os.path.join(folder, "index.csv")) else []
    # Exit 1 with every test complete is a test that left its stress path: it enters no measure
    # (measures_of reads done tests only), the point's other tests do.
    if rc != 0 and not (rc == 1 and rows and all(complete(r) for r in rows)):
        fail(f"{name}: triaxial exited {rc}; see {os.path.join(folder, 'log.txt')}", 1)
    return folder


def fit_targets(u, ys, targets, need):
    """One quadratic surrogate per target, fit on the runs that measured it (a run whose test left its
    stress path did not); fewer than NEED such runs cannot determine the surrogate: exit 1."""
    surrogates = {}
    for tname in targets:
        y = np.array([m[tname] for m in ys])
        ok = np.isfinite(y)
        if ok.sum() < need:
            fail(f"targets.{tname}: measured in {int(ok.sum())} of {len(y)} runs (runs.csv; the others' tests left "
                 f"their stress path or the analysis could not fit it): a quadratic surrogate in {u.shape[1]} "
                 f"parameter(s) needs at least {need}", 1)
        surrogates[tname] = fit_surrogate(u[ok], y[ok])
    return surrogates


def complete(row):
    """A test that ran to its end: done, or failed for leaving its stress path (its reason given)."""
    status = row.get("status", "")
    return status.startswith("done") or (status == "failed" and bool(row.get("reason")))


# ------------------------------------------------------------------------------ surrogate, posterior
def features(u):
    """[1, u_k, u_k u_l (k <= l)] of points in [-1, 1]^p."""
    u = np.atleast_2d(u)
    cols = [np.ones(len(u))]
    p = u.shape[1]
    cols += [u[:, k] for k in range(p)]
    cols += [u[:, k] * u[:, j] for k in range(p) for j in range(k, p)]
    return np.stack(cols, axis=1)


def fit_surrogate(u, y):
    """Least-squares quadratic; returns (coefficients, residual standard deviation)."""
    a = features(2.0 * u - 1.0)
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    resid = y - a @ coef
    dof = max(1, len(y) - a.shape[1])
    return coef, float(np.sqrt(np.sum(resid ** 2) / dof))


def predict(coef, u):
    return features(2.0 * np.atleast_2d(u) - 1.0) @ coef


def posterior(space, targets, surrogates, seed, n=1 << 16):
    from scipy.stats import qmc
    u = qmc.Sobol(d=len(space), scramble=True, seed=seed + 1).random(n)
    logl = np.zeros(n)
    for name, (value, sigma) in targets.items():
        coef, s = surrogates[name]
        logl += -0.5 * (predict(coef, u) - value) ** 2 / (sigma ** 2 + s ** 2)
    w = np.exp(logl - logl.max())
    log_evidence = float(logl.max() + np.log(w.mean()))  # log of the mean likelihood over the prior box
    w /= w.sum()
    x = to_params(u, space)
    mean = w @ x
    std = np.sqrt(np.maximum(w @ (x - mean) ** 2, 0.0))
    out = {}
    for k, (key, lo, hi) in enumerate(space):
        order = np.argsort(x[:, k])
        cdf = np.cumsum(w[order])
        q05, q95 = (float(x[order, k][np.searchsorted(cdf, q)]) for q in (0.05, 0.95))
        prior_std = (hi - lo) / math.sqrt(12.0) if not log_scale(lo, hi) else float(np.std(x[:, k]))
        out[key] = dict(mean=float(mean[k]), std=float(std[k]), q05=q05, q95=q95, map=float(x[np.argmax(w), k]),
                        prior_std=prior_std, identified=bool(std[k] < 0.5 * prior_std))
    ess = float(1.0 / np.sum(w ** 2))
    return out, u, w, ess, log_evidence


def sensitivity(space, targets, surrogates, center_u):
    """Per target and parameter: the target's change across the parameter's range, in sigmas."""
    table = {}
    for name, (value, sigma) in targets.items():
        coef, s = surrogates[name]
        row = {}
        for k, (key, _, _) in enumerate(space):
            ends = np.repeat(center_u[None, :], 2, axis=0)
            ends[:, k] = (0.0, 1.0)
            lo, hi = predict(coef, ends)
            row[key] = float((hi - lo) / sigma)
        table[name] = row
    return table


# ------------------------------------------------------------------------------ reports
def write_runs(path, space, targets, rows, choice_key=None):
    """rows: (run name, option or None, parameters, measures)."""
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["run"] + ([choice_key] if choice_key else []) + [k for k, _, _ in space] + list(targets))
        for name, option, x, y in rows:
            w.writerow([name] + ([option] if choice_key else []) + [f"{v:.10g}" for v in x] +
                       [f"{y[n]:.10g}" for n in targets])


def plot(path, space, targets, xs, ys, surrogates, post, center_u):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    p, t = len(space), len(targets)
    fig, axes = plt.subplots(t + 1, p, figsize=(3.6 * p, 2.8 * (t + 1)), squeeze=False)
    for j, (name, (value, sigma)) in enumerate(targets.items()):
        for k, (key, lo, hi) in enumerate(space):
            ax = axes[j][k]
            ax.plot(xs[:, k], [y[name] for y in ys], "o", ms=4, label="runs")
            grid = np.repeat(center_u[None, :], 60, axis=0)
            grid[:, k] = np.linspace(0.0, 1.0, 60)
            ax.plot(to_params(grid, space)[:, k], predict(surrogates[name][0], grid), "-",
                    label="surrogate (others at the posterior mean)")
            ax.axhspan(value - sigma, value + sigma, color="tab:green", alpha=0.25, label="target +- sigma")
            ax.set_xlabel(key)
            ax.set_ylabel(name)
    for k, (key, lo, hi) in enumerate(space):
        ax = axes[t][k]
        x = to_params(post["u"], space)[:, k]
        ax.hist(x, bins=40, weights=post["w"], color="tab:purple")
        ax.axvline(post["params"][key]["mean"], color="k", lw=1)
        ax.set_xlabel(key)
        ax.set_ylabel("posterior")
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def report_md(path, args, space, targets, result):
    lines = [f"# Calibration of {args.config}", "",
             f"Command: `triaxial calibrate {' '.join(sys.argv[1:])}`", "",
             f"{len(result['runs'])} runs (budget {args.budget}"
             f"{' per option' if result.get('choice') else ''}) and one check run; quadratic surrogate per target; "
             f"effective posterior sample size {result['ess']:.0f}.", "",
             "| parameter | range | posterior mean +- std | 5-95 % | MAP | identified |", "|---|---|---|---|---|---|"]
    for key, lo, hi in space:
        q = result["params"][key]
        lines.append(f"| {key} | {lo:g} - {hi:g} | {q['mean']:.4g} +- {q['std']:.2g} | {q['q05']:.4g} - {q['q95']:.4g} "
                     f"| {q['map']:.4g} | {'yes' if q['identified'] else 'no'} |")
    if result.get("choice"):
        c = result["choice"]
        lines += ["", f"Discrete choice {c['key']}: the design run for each option; posterior probability of each "
                  f"(equal prior odds), and its continuous posterior. Chosen: **{c['chosen']}**; the tables below "
                  "are for it.", "",
                  "| option | probability | log evidence | " + " | ".join(k for k, _, _ in space) + " |",
                  "|---|---|---|" + "---|" * len(space)]
        for opt, q in c["options"].items():
            cells = [f"{q['params'][k]['mean']:.4g} +- {q['params'][k]['std']:.2g}" for k, _, _ in space]
            lines.append(f"| {opt} | {q['probability']:.3g} | {q['log_evidence']:.2f} | " + " | ".join(cells) + " |")
    lines += ["", "Measured in: the design runs whose test of that target held its stress path (a test the path "
              "watchdog failed measures nothing; the surrogate is fit on the others).", "",
              "| target | value +- sigma | measured in | surrogate error | check run | z |",
              "|---|---|---|---|---|---|"]
    n_runs = len(result["runs"])
    for name, (value, sigma) in targets.items():
        c = result["check"].get(name, float("nan"))
        check = f"{c:.4g} | {(c - value) / sigma:+.2f}" if math.isfinite(c) else "left its path | -"
        lines.append(f"| {name} | {value:.4g} +- {sigma:.2g} | {result['measured'][name]} of {n_runs} | "
                     f"{result['surrogate_error'][name]:.2g} | {check} |")
    lines += ["", "Sensitivity: change of each target across each parameter's range, in sigmas of the target:", "",
              "| target | " + " | ".join(k for k, _, _ in space) + " |", "|---|" + "---|" * len(space)]
    for name in targets:
        lines.append(f"| {name} | " + " | ".join(f"{result['sensitivity'][name][k]:+.1f}" for k, _, _ in space) + " |")
    lines += ["", "![targets against parameters, surrogate slices and posterior marginals](calibration.png)", ""]
    with open(path, "w") as f:
        f.write("\n".join(lines))


# ------------------------------------------------------------------------------ main
def main(argv=None):
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="Free parameters: " + ", ".join(PARAMETERS) + ". Targets: " +
                                 ", ".join(CAMPAIGN_TARGETS) + " (campaign), " + ", ".join(TEST_TARGETS) +
                                 " (per test, NAME or NAME:TEST).")
    ap.add_argument("config", help="the triaxial configuration (TOML) whose parameters are calibrated")
    ap.add_argument("--targets", required=True, help="TOML file with a [targets] table")
    ap.add_argument("--param", action="append", default=[], metavar="KEY=LO:HI", help="a free parameter and its range")
    ap.add_argument("--choice", default=None, metavar="KEY=A,B,...",
                    help="a discrete choice and its options (" + "; ".join(f"{k}: {', '.join(v)}"
                                                                           for k, v in CHOICES.items()) + ")")
    ap.add_argument("--budget", type=int, default=None,
                    help="runs of the design, per option of --choice (default: 4 x the minimum)")
    ap.add_argument("--out", default=None, help="output directory (default: results/calibrate-<config name>)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1, help="the design's Sobol scrambling seed")
    ap.add_argument("--resume", action="store_true", help="continue a calibration in OUT (finished runs are kept)")
    args = ap.parse_args(argv)
    if not args.param:
        fail("no --param given: at least one free parameter KEY=LO:HI")
    space = [parse_param(p) for p in args.param]
    keys = [k for k, _, _ in space]
    if len(set(keys)) != len(keys):
        fail(f"--param: a parameter is given twice ({', '.join(keys)})")
    choice = parse_choice(args.choice) if args.choice else None
    targets = parse_targets(args.targets)
    need = min_budget(len(space))
    if args.budget is None:
        args.budget = 4 * need
    if args.budget < need:
        fail(f"--budget {args.budget}: a quadratic surrogate in {len(space)} parameter(s) needs at least {need} runs")
    if args.threads < 1:
        fail(f"--threads {args.threads}: must be >= 1")
    args.triaxial = os.environ.get("SANDCELL_TRIAXIAL", "triaxial")
    try:
        with open(args.config, "rb") as f:
            base = tomllib.load(f)
    except (OSError, tomllib.TOMLDecodeError) as e:
        fail(f"{args.config}: {e}")
    if args.out is None:
        args.out = os.path.join("results", "calibrate-" + os.path.splitext(os.path.basename(args.config))[0])
    if os.path.exists(os.path.join(args.out, "calibration.json")) and not args.resume:
        fail(f"--out {args.out}: holds a finished calibration; pass --resume to reuse its runs, or another --out")
    os.makedirs(args.out, exist_ok=True)

    u = design(space, args.budget, args.seed)
    xs = to_params(u, space)
    options = choice[1] if choice else [None]
    rows, fits = [], {}
    for option in options:
        ys = []
        for i, x in enumerate(xs):
            name = f"run-{i:03d}" + (f"-{option}" if option else "")
            folder = run_point(name, run_config(base, space, x, (choice[0], option) if option else None), args)
            m = measures_of(folder, targets, args.triaxial)
            if m is None:  # every test of the run left its stress path: it measures nothing
                print(f"{PROG}: {name}: no test held its stress path (index.csv): the run measures nothing",
                      flush=True)
                m = {t: float("nan") for t in targets}
            ys.append(m)
            rows.append((name, option, x, m))
        # runs.csv before the fits: a calibration that cannot fit (too few runs held their path) keeps its evidence
        write_runs(os.path.join(args.out, "runs.csv"), space, targets, rows, choice[0] if choice else None)
        surrogates = fit_targets(u, ys, targets, need)
        fits[option] = (ys, surrogates, posterior(space, targets, surrogates, args.seed))
    write_runs(os.path.join(args.out, "runs.csv"), space, targets, rows, choice[0] if choice else None)
    log_z = {o: fits[o][2][4] for o in options}
    top = max(log_z.values())
    norm = sum(math.exp(v - top) for v in log_z.values())
    chosen = max(options, key=lambda o: log_z[o]) if choice else None
    ys, surrogates, (params, pu, pw, ess, _) = fits[chosen]
    center = np.array([params[k]["mean"] for k in keys])
    center_u = to_unit(center[None, :], space)[0]
    check_folder = run_point("check", run_config(base, space, center, (choice[0], chosen) if choice else None), args)
    check = measures_of(check_folder, targets, args.triaxial) or {t: float("nan") for t in targets}
    result = dict(config=args.config, budget=args.budget, seed=args.seed, runs=[r[0] for r in rows],
                  params=params, ess=ess, targets={n: dict(value=v, sigma=s) for n, (v, s) in targets.items()},
                  surrogate_error={n: surrogates[n][1] for n in targets}, check=check,
                  measured={n: int(sum(math.isfinite(m[n]) for m in ys)) for n in targets},
                  sensitivity=sensitivity(space, targets, surrogates, center_u))
    if choice:
        result["choice"] = dict(key=choice[0], chosen=chosen, options={
            o: dict(probability=math.exp(log_z[o] - top) / norm, log_evidence=log_z[o], params=fits[o][2][0])
            for o in options})
    with open(os.path.join(args.out, "calibration.json"), "w") as f:
        json.dump(result, f, indent=1)
    report_md(os.path.join(args.out, "calibration.md"), args, space, targets, result)
    plot(os.path.join(args.out, "calibration.png"), space, targets, xs, ys, surrogates,
         dict(u=pu, w=pw, params=params), center_u)
    chose = (f"{choice[0]} = {chosen} (probability {result['choice']['options'][chosen]['probability']:.3g}), "
             if choice else "")
    print(f"{PROG}: " + chose + ", ".join(f"{k} = {params[k]['mean']:.4g} +- {params[k]['std']:.2g}" for k in keys) +
          f"; report {os.path.join(args.out, 'calibration.md')}")
    return 0
