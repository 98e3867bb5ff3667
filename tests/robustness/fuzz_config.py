#!/usr/bin/env python3
"""Seeded mutations of the default config, each checked with `triaxial CONFIG --check`: no signal,
no hang past a bound, exit 0 (valid) or 2 (refused) only; a refusal is one line under 300
characters naming a key or the file; nothing is written either way.

    fuzz_config.py TRIAXIAL [MUTATIONS] [SEED]
"""
import os
import random
import shutil
import subprocess
import sys
import tempfile

VALUES = ["-1", "0", "1", "1e308", "-1e308", "1e-308", "nan", "inf", "-inf", "\"text\"", "[]", "[1, 2]",
          "[[1e-9, 0], [1, 100]]", "true", "99999999999999999", "0.5", "2.0", "1000000", "\"" + "x" * 5000 + "\"",
          "{ a = 1 }", "[\"constant_p\", \"bogus\"]", "-0.0", "1e-12", "3", "[0.5e6, -1]"]
KEYS = ["count", "d_min", "d_max", "seed", "solid_fraction", "distribution", "gradation", "density", "young", "poisson",
        "restitution", "friction", "rolling_friction", "dt_fraction", "strain_rate", "inertial_number", "max_axial_strain",
        "ramp_strain", "servo_interval", "p0", "b", "path", "parallel", "series_interval", "chain", "max_rate",
        "tolerance", "skin", "rolling", "tangential", "bogus_key"]
SECTIONS = ["[sample]", "[material]", "[contact]", "[time]", "[prepare]", "[shear]", "[tests]", "[output]", "[bogus]"]


def mutate(lines, rng):
    lines = list(lines)
    for _ in range(rng.randint(1, 3)):
        op = rng.randrange(6)
        k = rng.randrange(len(lines))
        if op == 0 and "=" in lines[k]:  # another value
            lines[k] = lines[k].split("=")[0] + "= " + rng.choice(VALUES)
        elif op == 1:  # a line removed
            del lines[k]
        elif op == 2:  # a key added somewhere
            lines.insert(k, f"{rng.choice(KEYS)} = {rng.choice(VALUES)}")
        elif op == 3:  # a line repeated (duplicate key or section)
            lines.insert(k, lines[k])
        elif op == 4:  # a section header
            lines.insert(k, rng.choice(SECTIONS))
        else:  # garbage
            lines.insert(k, rng.choice(["= 1", "[", "key", "\x00\x01", "a.b = 1", "[[tests]]", "p0 = 1e6 # ok"]))
    return "\n".join(lines) + "\n"


def main():
    triaxial = sys.argv[1]
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 300
    rng = random.Random(int(sys.argv[3]) if len(sys.argv) > 3 else 7)
    base = subprocess.run([triaxial, "--print-default"], capture_output=True, text=True, check=True).stdout.splitlines()
    work = tempfile.mkdtemp(prefix="sandcell-fuzz.")
    counts = {0: 0, 2: 0}
    try:
        for k in range(n):
            text = mutate(base, rng)
            cfg = os.path.join(work, "c.toml")
            with open(cfg, "w") as fh:
                fh.write(text)
            out = os.path.join(work, "out")
            try:
                r = subprocess.run([triaxial, cfg, "--check", "--out", out], capture_output=True, text=True, timeout=20)
            except subprocess.TimeoutExpired:
                sys.exit(f"FAIL: mutation {k} hangs (> 20 s):\n{text}")
            where = f"mutation {k}:\n{text}\n--- stdout:\n{r.stdout}--- stderr:\n{r.stderr}"
            if r.returncode < 0:
                sys.exit(f"FAIL: signal {-r.returncode} on {where}")
            if r.returncode not in (0, 2):
                sys.exit(f"FAIL: exit {r.returncode} on {where}")
            if os.path.exists(out):
                sys.exit(f"FAIL: something was written (exit {r.returncode}) on {where}")
            if r.returncode == 2:
                lines = r.stderr.splitlines()
                if len(lines) != 1 or len(lines[0]) >= 300 or not lines[0].startswith("triaxial: "):
                    sys.exit(f"FAIL: not one line under 300 characters on {where}")
            counts[r.returncode] += 1
        print(f"fuzz_config: {n} mutations: {counts[2]} refused (one line, exit 2), {counts[0]} valid; "
              "no signal, hang or file written")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
