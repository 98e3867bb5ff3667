#!/usr/bin/env python3
"""analysis.study_command: `triaxial study` with the smoke preset writes its table, data and figure,
and its runs are what it says they are.

    check_study.py TRIAXIAL CONFIG WORKDIR
"""
import json
import os
import shutil
import subprocess
import sys

triaxial, config, work = sys.argv[1:4]


def run_study(preset, folder):
    """Runs the preset into work/folder from scratch; checks it wrote every output; returns the folder
    and study.json."""
    out = os.path.join(work, folder)
    shutil.rmtree(out, ignore_errors=True)
    r = subprocess.run([triaxial, "study", config, "--preset", preset, "--out", out, "--threads", "1"],
                       capture_output=True, text=True)
    assert r.returncode == 0, f"triaxial study --preset {preset} exited {r.returncode}:\n{r.stdout}\n{r.stderr}"
    for f in ("study.md", "study.csv", "study.json", "study.png", "study.svg"):
        assert os.path.exists(os.path.join(out, f)), f"study --preset {preset} did not write {f}"
    return out, json.load(open(os.path.join(out, "study.json")))


out, data = run_study("smoke", "study")
runs = {m["name"]: m for m in data["runs"]}
ref = runs["ref"]
assert set(runs) == {"ref", "dt_0.4", "I_0.03", "E_x0.3", "e_0.9", "N_160", "seed_2", "safety_0.8"}, sorted(runs)
# The reference's errors are zero by definition; every metric is finite.
for key in ("peak_eta", "res_eta", "res_e", "max_dilation"):
    assert ref[f"err_{key}"] == 0.0
    for m in runs.values():
        assert m[key] == m[key], f"{m['name']}: {key} is NaN"
# dt, I and e variants shear the reference's own prepared sample: the same e0 bit for bit; the
# seed and N variants prepare another sample.
for name in ("dt_0.4", "I_0.03", "e_0.9", "safety_0.8"):
    assert runs[name]["e0"] == ref["e0"], (name, runs[name]["e0"], ref["e0"])
for name in ("seed_2", "N_160"):
    assert runs[name]["e0"] != ref["e0"], name
# Steps to the same strain scale as 1 / (rate dt): dt x 2 halves them, I x 3 divides them by 3
# (within one step of rounding each, and the +1 of the stop test).
assert abs(runs["dt_0.4"]["steps"] / ref["steps"] - 0.5) < 3.0 / ref["steps"], runs["dt_0.4"]["steps"]
assert abs(runs["I_0.03"]["steps"] / ref["steps"] - 1.0 / 3.0) < 3.0 / ref["steps"], runs["I_0.03"]["steps"]
# The stiffness step: at 0.5 MPa the contacts of a sheared sample allow about 0.5 t_R before the
# safety factor (docs/physics.md section 4.1: 0.52 t_R measured at 1,000 spheres), so safety 0.8
# steps about 0.4 t_R, twice the reference's 0.2 t_R: fewer than 0.8x its steps to the same strain.
assert runs["safety_0.8"]["steps"] < 0.8 * ref["steps"], (runs["safety_0.8"]["steps"], ref["steps"])
assert runs["safety_0.8"]["set_safety"] == 0.8
# The measured inertial number follows the set one (it is (eps_dot_1 - eps_dot_3) d50 sqrt(rho/p),
# so not equal to the set axial value, but 3x the rate is 2-4x the measure).
ratio = runs["I_0.03"]["I"] / ref["I"]
assert 2.0 < ratio < 4.0, ratio
# Softer spheres overlap more: Hertz at the same p gives delta/R ~ (p/E*)^(2/3), x 2.2 for E x 0.3;
# the largest overlap of a 120-sphere sample is an extreme value, so only 1.3x-3.5x is asserted.
ratio = runs["E_x0.3"]["max_overlap"] / ref["max_overlap"]
assert 1.3 < ratio < 3.5, ratio
md = open(os.path.join(out, "study.md")).read()
assert "Noise floor" in md and "| ref |" in md
# A second call reuses every finished run (nothing is re-run).
r = subprocess.run([triaxial, "study", config, "--preset", "smoke", "--out", out, "--threads", "1"],
                   capture_output=True, text=True)
assert r.returncode == 0 and " --out " not in r.stdout, r.stdout
# Bad input: exit 2 with one line naming the option.
r = subprocess.run([triaxial, "study", config, "--axes", "dt,bogus", "--out", out], capture_output=True, text=True)
assert r.returncode == 2 and "bogus" in r.stderr, (r.returncode, r.stderr)
# No other seeds, so no noise floor: the errors need a tolerance for every metric, or nothing runs.
fresh = os.path.join(work, "study-noseeds")
r = subprocess.run([triaxial, "study", config, "--preset", "smoke", "--axes", "dt", "--tolerance", "peak=0.05",
                    "--out", fresh], capture_output=True, text=True)
assert r.returncode == 2 and "--tolerance" in r.stderr and "res, e, d" in r.stderr, (r.returncode, r.stderr)
assert not os.path.exists(fresh), "a study with no tolerance to judge by created its folder"
# Every option is checked before anything runs: a negative or NaN --window (the residual window, in
# axial strain) and a --threads the app would refuse, each one line naming it, no folder created.
for option, value in (("--window", "-1"), ("--window", "nan"), ("--threads", "0"), ("--threads", "1025"),
                      ("--triaxial", "/nonexistent/triaxial")):
    r = subprocess.run([triaxial, "study", config, "--preset", "smoke", option, value, "--out", fresh],
                       capture_output=True, text=True)
    assert r.returncode == 2 and f"{option} = {value}" in r.stderr and len(r.stderr.splitlines()) == 1, \
        (option, value, r.returncode, r.stdout, r.stderr)
    assert not os.path.exists(fresh), f"study {option} {value} created its folder before refusing the option"

# The size preset: N x seeds at one setting, every sample prepared on its own; the largest N with
# its first seed only (preset largest_seeds).
out, data = run_study("size-smoke", "study-size")
runs = {m["name"]: m for m in data["runs"]}
assert set(runs) == {"N120_seed1", "N120_seed2", "N160_seed1", "N160_seed2", "N200_seed1"}, sorted(runs)
# Each run is its own sample: the configured count and seed, and five different preparations.
for m in runs.values():
    cfg = open(os.path.join(out, m["name"], "config.toml")).read()
    assert f"count = {m['N']}" in cfg and f"seed = {m['seed']}" in cfg, m["name"]
assert len({m["e0"] for m in runs.values()}) == 5, [m["e0"] for m in runs.values()]
# The per-size rows are the mean and sample standard deviation of their runs (two seeds: the std is
# |a - b| / sqrt(2); one seed: the value, std NaN); the size error is measured from the largest N,
# whose own error is 0. Exact up to the round-off of a two-term mean (1e-12 relative).
groups = {g["N"]: g for g in data["by_size"]}
keys = ("peak_eta", "res_eta", "res_e", "max_dilation", "e0")
for n in (120, 160):
    g, a, b = groups[n], runs[f"N{n}_seed1"], runs[f"N{n}_seed2"]
    for key in keys:
        assert abs(g[key] - (a[key] + b[key]) / 2) <= 1e-12 * abs(g[key]), (n, key)
        assert abs(g["std_" + key] - abs(a[key] - b[key]) / 2 ** 0.5) <= 1e-12 * max(abs(a[key]), 1.0), (n, key)
        assert abs(g["err_" + key] - abs(g[key] - runs["N200_seed1"][key])) <= 1e-12 * max(abs(g[key]), 1.0), (n, key)
    assert g["prep_wall"] > 0 and g["wall"] > 0 and g["prep_steps"] > 0, g
for key in keys:
    assert groups[200][key] == runs["N200_seed1"][key] and groups[200]["err_" + key] == 0.0, key
    assert groups[200]["std_" + key] != groups[200]["std_" + key], key  # NaN: one sample has no scatter
md = open(os.path.join(out, "study.md")).read()
assert "| 120 |" in md and "| 200 |" in md and "error / scatter" in md
print("study checks passed")
