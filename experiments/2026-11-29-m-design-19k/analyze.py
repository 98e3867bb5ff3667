"""m identified at the study's size (issue 45 item 3): 19,436-sphere samples spanning psi0 at one p,
three seeds; from the committed series alone.

    PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-29-m-design-19k/analyze.py \
        [--dir experiments/2026-11-29-m-design-19k] [--plot]

Reads DIR/tests.csv and DIR/series/*.csv.gz (export.py); writes DIR/states.csv (per test: e0, its
end window, whether e, p, Z_mech and F_a are steady there, its characteristic state) and DIR/m.json
(the pooled fit, the verdict, and each seed's fit).

Method, fixed before the data (as experiments/2026-11-28-m-design at 4,000 spheres, with the
stationarity rule now in force and seeds):
- tests that ended off their path (status not done) are left out of everything;
- e_c(0.5 MPa) and M: the means over the end windows (the last 0.1 of eps_q) of the tests whose e,
  p, Z_mech and F_a are steady there (critical.detect_critical, version 3, eta untested); when none
  is, the means over every test's end window, flagged "e_c and M from unproven end states". Every
  test is at p = 0.5 MPa and the fit's intercept is free, so e_c and M move every point's psi and
  ln(eta*/M) alike: they set psi's scale for the table, not m;
- plastic dilatancy (dilatancy.plastic_dilatancy: dp/K and dq/3G removed with each test's moduli);
- each test's characteristic state (analyze.characteristic_state): its phase transformation where d
  turns before the peak of eta, else its peak with eta* = eta - d/s, s the mean initial d-eta slope
  of the two densest samples of each seed;
- m by dilatancy.fit_m_pt over all seeds' states (the verdict: "identified" iff the 95 %
  profile-likelihood interval is narrower than 4.57, then "consistent with the study" if it contains
  4.57, "not the study's" if not; else "not identifiable"), and per seed (the seeds' spread, reported
  beside the pooled interval; a pooled interval much narrower than the seeds' spread would mean the
  residuals miss a seed effect, and is said).

Added after seeds 2017 and 2018 were seen, before seed 2019 ran; a sensitivity, never the verdict:
the peak states' eta* depends on s, so the pooled m is also given with s at the smallest and the
largest of the dense samples' own slopes (the phase transformations do not use s).
Added after all 18 were seen, not the verdict: form_check (is ln(eta*/M) straight in psi?).
"""
import argparse
import csv
import json
import math
import os
import sys

import numpy as np

from sandcell_analysis import critical, dilatancy
from sandcell_analysis.analyze import characteristic_state

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from export import read_series  # noqa: E402  (the experiment's own reader of its series)


def load(folder):
    with open(os.path.join(folder, "tests.csv"), newline="") as fh:
        rows = list(csv.DictReader(fh))
    tests = []
    for r in rows:
        path = os.path.join(folder, "series", f"s{r['seed']}-e{r['target_e0']}.csv.gz")
        if not os.path.exists(path):
            continue
        s = read_series(path)
        tests.append({"name": f"s{r['seed']}-e{r['target_e0']}", "seed": int(r["seed"]), "row": r,
                      "ok": r["status"].startswith("done"), "e0": float(s["e"][0]), "t": s})
    return tests


def form_check(tests, M):
    """Whether ln(eta*/M) is straight in psi, as Li & Dafalias's e^{m psi} says (added after the data were
    seen; not the verdict): a quadratic fitted to all states (its psi^2 term and its slope at psi = 0 with
    their OLS standard errors), and straight lines fitted on either side of psi = -0.1."""
    use = [x["state"] for x in tests if math.isfinite(x["state"]["eta_star"])]
    x = np.array([st["psi"] for st in use])
    y = np.log(np.array([st["eta_star"] for st in use]) / M)
    out = {}
    a = np.column_stack([x, x ** 2, np.ones_like(x)])
    coef = np.linalg.lstsq(a, y, rcond=None)[0]
    r = y - a @ coef
    cov = (r @ r) / (len(y) - 3) * np.linalg.inv(a.T @ a)
    out.update(quadratic=float(coef[1]), quadratic_se=float(math.sqrt(cov[1, 1])), slope_at_0=float(coef[0]),
               slope_at_0_se=float(math.sqrt(cov[0, 0])))
    for name, k in (("dense", x <= -0.1), ("loose", x > -0.1)):
        f = dilatancy.fit_m_pt(x[k], np.exp(y[k]) * M, M)
        out[f"m_{name}"], out[f"n_{name}"] = f["m"], int(k.sum())
    return out


def plot(tests, pooled, sensitivity, M, path):
    """ln(eta*/M) against psi at each test's characteristic state, by seed and kind, with the pooled line,
    its 95 % band for m (the intercept at its fitted value), and the lines of the sensitivity to s."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    colours = {}
    for x in tests:
        st = x["state"]
        if not math.isfinite(st["eta_star"]):
            continue
        first = x["seed"] not in colours  # the seed's first point carries its label
        c = colours.setdefault(x["seed"], f"C{len(colours)}")
        pt = st["kind"] == "phase transformation"
        ax.plot(st["psi"], math.log(st["eta_star"] / M), "o" if pt else "s", color=c, mfc="none" if pt else c,
                label=f"seed {x['seed']}" if first else None)
    xs = np.linspace(-0.2, 0.0, 50)
    ax.plot(xs, pooled["c"] + pooled["m"] * xs, "k-", label=f"pooled m = {pooled['m']:.2f}")
    lo, hi = pooled["interval"]
    if math.isfinite(lo) and math.isfinite(hi):
        xm = float(np.mean([x["state"]["psi"] for x in tests if math.isfinite(x["state"]["eta_star"])]))
        ym = pooled["c"] + pooled["m"] * xm
        ax.fill_between(xs, ym + lo * (xs - xm), ym + hi * (xs - xm), color="k", alpha=0.12,
                        label=f"95 % for m [{lo:.2f}, {hi:.2f}]")
    for label, v in sensitivity.items():
        f = v["fit"]
        if math.isfinite(f["m"]):
            ax.plot(xs, f["c"] + f["m"] * xs, "k:", lw=1)
            ax.annotate(f"s = {v['s']:.2f}: m = {f['m']:.2f}", (xs[3], f["c"] + f["m"] * xs[3] + 0.01), fontsize=7)
    ax.plot(xs, 4.57 * xs, "r--", lw=1, label="the study's m = 4.57 (through the origin)")
    ax.set_xlabel("psi at the state (e - e_c)")
    ax.set_ylabel("ln(eta* / M)")
    ax.set_title("m design, 19,436 spheres, 0.5 MPa, b = 0 (filled: peak; open: phase transformation)",
                 fontsize=8)
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def plot_curves(tests, e_c, M, path):
    """q/p, e and eps_v against eps_q for every test, coloured by its target e0 (one line style per seed),
    with e_c and M (the steady tests' end windows) as dashed lines: the same critical state from both sides."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 3, figsize=(12.0, 3.9))
    targets = sorted({float(x["row"]["target_e0"]) for x in tests})
    cmap = plt.get_cmap("viridis")
    styles = {}
    labelled = min(x["seed"] for x in tests)  # one seed's lines carry the targets' labels
    for x in sorted(tests, key=lambda x: (x["seed"], x["e0"])):
        t = x["t"]
        k = targets.index(float(x["row"]["target_e0"]))
        ls = styles.setdefault(x["seed"], ["-", "--", ":"][len(styles) % 3])
        colour = cmap(k / max(1, len(targets) - 1))
        lab = f"e0 target {targets[k]:.2f}" if x["seed"] == labelled else None
        for ax, y in zip(axes, (t["eta"], t["e"], t["eps_v"])):
            ax.plot(t["eps_q"], y, ls, color=colour, lw=0.8, label=lab)
    axes[0].axhline(M, color="k", ls="--", lw=0.8)
    axes[1].axhline(e_c, color="k", ls="--", lw=0.8)
    for ax, name in zip(axes, ("q/p", "e", "eps_v (compression +)")):
        ax.set_xlabel("eps_q")
        ax.set_ylabel(name)
    axes[0].legend(fontsize=7)
    axes[1].set_title(f"19,436 spheres, 0.5 MPa, b = 0; seeds {', '.join(str(s) for s in styles)} "
                      f"({', '.join(styles.values())}); dashed: e_c {e_c:.4f}, M {M:.3f}", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default=HERE)
    ap.add_argument("--seeds", type=int, nargs="*", help="only these seeds (an interim look; the verdict pools all)")
    ap.add_argument("--out", default=None, help="where states.csv and m.json go (default --dir)")
    ap.add_argument("--plot", action="store_true",
                    help="also m.png (ln(eta*/M) against psi, the fit and its interval) and curves.png "
                         "(q/p, e, eps_v against eps_q)")
    a = ap.parse_args(argv)
    tests = [x for x in load(a.dir) if x["ok"] and (not a.seeds or x["seed"] in a.seeds)]
    if not tests:
        print("no test ended on its path", file=sys.stderr)
        return 1
    for x in tests:
        t = x["t"]
        series = {k: t[k] for k in ("p", "q", "eta", "e", "Z_mech", "fabric", "stress")}
        x["check"] = critical.detect_critical(t["eps_q"], series, tol_eta=None)
        x["steady"] = bool(x["check"]["reached"])
    steady = [x for x in tests if x["steady"]]
    basis = steady or tests
    e_c = float(np.mean([x["check"]["point"]["e"] for x in basis]))
    M = float(np.mean([x["check"]["point"]["eta"] for x in basis]))
    caveat = "" if steady else "e_c and M from unproven end states (no test steady at its end)"
    for x in tests:
        t = x["t"]
        dl = dilatancy.plastic_dilatancy(t["eps_v"], t["eps_q"], t["p"], t["q"],
                                         others={"eta": t["eta"], "e": t["e"], "p": t["p"]})
        dl["psi"] = dl["e"] - e_c
        x["dil"] = dl
    slopes = []
    for seed in sorted({x["seed"] for x in tests}):
        dense = sorted((x for x in tests if x["seed"] == seed), key=lambda x: x["e0"])[:2]
        slopes += [dilatancy.initial_linear_part(x["dil"]["eta"], x["dil"]["d"], x["dil"]["mask"])[1] for x in dense]
    s = float(np.nanmean(slopes)) if np.any(np.isfinite(slopes)) else math.nan

    def fit(group, key="state"):
        use = [x for x in group if math.isfinite(x[key]["eta_star"])]
        return dilatancy.fit_m_pt([x[key]["psi"] for x in use], [x[key]["eta_star"] for x in use], M)

    none = {"kind": "none", "eta": math.nan, "psi": math.nan, "eta_star": math.nan, "eps_q": math.nan}
    sensitivity = {}
    finite = [v for v in slopes if math.isfinite(v)]
    for label, s_alt in (("s_min", min(finite, default=math.nan)), ("s_max", max(finite, default=math.nan))):
        for x in tests:
            x["alt"] = characteristic_state({"dil": x["dil"], "eps_q": x["t"]["eps_q"]}, s_alt) or none
        sensitivity[label] = {"s": s_alt, "fit": fit(tests, "alt")}
    rows = []
    for x in tests:
        st = characteristic_state({"dil": x["dil"], "eps_q": x["t"]["eps_q"]}, s)
        x["state"] = st or none
        pt = x["check"]["point"]
        rows.append({"test": x["name"], "seed": x["seed"], "e0": x["e0"], "psi0": x["e0"] - e_c,
                     "steady_end": x["steady"], "e_end": pt["e"], "eta_end": pt["eta"],
                     "state": x["state"]["kind"], "eps_q_state": x["state"]["eps_q"], "eta_state": x["state"]["eta"],
                     "psi_state": x["state"]["psi"], "eta_star": x["state"]["eta_star"]})

    pooled = fit(tests)
    form = form_check(tests, M)
    seeds = {str(seed): fit([x for x in tests if x["seed"] == seed]) for seed in sorted({x["seed"] for x in tests})}
    per_seed = [f["m"] for f in seeds.values() if math.isfinite(f["m"])]
    spread = float(np.std(per_seed, ddof=1)) if len(per_seed) >= 2 else math.nan
    out = {"e_c": e_c, "M": M, "n_steady": len(steady), "caveat": caveat, "initial_slope": s,
           "pooled": pooled, "seeds": seeds, "seed_sd_of_m": spread, "initial_slopes": slopes,
           "sensitivity_to_s": sensitivity, "form_check": form}
    out_dir = a.out or a.dir
    os.makedirs(out_dir, exist_ok=True)
    with open(os.path.join(out_dir, "states.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    with open(os.path.join(out_dir, "m.json"), "w") as f:
        json.dump(out, f, indent=1, sort_keys=True, default=float)
    for r in rows:
        print(f"{r['test']:12s} e0 {r['e0']:.4f} psi0 {r['psi0']:+.3f} {r['state']:20s} eta* {r['eta_star']:.3f} "
              f"psi {r['psi_state']:+.3f} steady end {r['steady_end']}")
    print(f"e_c {e_c:.4f} M {M:.3f} ({len(steady)} steady{'; ' + caveat if caveat else ''}); initial slope {s:.3f}")
    for name, f in [("pooled", pooled)] + [(f"seed {k}", v) for k, v in seeds.items()]:
        print(f"{name}: m = {f['m']:.3g}, 95 % [{f['interval'][0]:.3g}, {f['interval'][1]:.3g}] (n {f['n']}, "
              f"psi span {f['psi_span']:.3f}): {f['verdict']} {f['note']}")
    if a.plot:
        plot(tests, pooled, sensitivity, M, os.path.join(out_dir, "m.png"))
        plot_curves(tests, e_c, M, os.path.join(out_dir, "curves.png"))
    print(f"the seeds' m: SD {spread:.3g} against the pooled SE {pooled['se']:.3g}")
    print(f"form check (after the data, not the verdict): quadratic term {form['quadratic']:.3g} +- "
          f"{form['quadratic_se']:.2g}, its slope at psi = 0 {form['slope_at_0']:.3g} +- {form['slope_at_0_se']:.2g}; "
          f"straight-line slope for psi <= -0.1: {form['m_dense']:.3g} (n {form['n_dense']}), "
          f"psi > -0.1: {form['m_loose']:.3g} (n {form['n_loose']})")
    for label, v in sensitivity.items():
        f = v["fit"]
        print(f"sensitivity, s = {v['s']:.3f} ({label}): m = {f['m']:.3g}, 95 % [{f['interval'][0]:.3g}, "
              f"{f['interval'][1]:.3g}] (not the verdict)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
