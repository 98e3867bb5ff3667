#!/usr/bin/env python3
"""Seeded bit flips of a checkpoint: every resume from a flipped checkpoint must either stop with
exit 1 naming the file, or end bitwise identical to the resume from the intact one (a flip in bytes
the reader never uses). Never a crash (a signal), a hang, or a silently different result.

    corrupt_checkpoint.py TRIAXIAL [FLIPS] [SEED]
"""
import os
import random
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "cluster"))
from compare_results import compare  # noqa: E402

CONFIG = """[sample]
count = 300
d_min = 5.0e-3
d_max = 7.5e-3
seed = 3
[material]
young = 1.0e9
[prepare]
max_rate = 20.0
check_interval = 500
[shear]
strain_rate = 2.0
max_axial_strain = 0.004
[tests]
path = "constant_p"
b = 0.5
p0 = 0.1e6
[output]
series_interval = 100
plot = false
"""
TEST = "p-b0.50-p0_100kPa"


def run(triaxial, work, out, *args):
    return subprocess.run([triaxial, os.path.join(work, "run.toml"), "--out", out, "--threads", "1", *args],
                          capture_output=True, text=True, timeout=120)


def main():
    triaxial = sys.argv[1]
    flips = int(sys.argv[2]) if len(sys.argv) > 2 else 40
    rng = random.Random(int(sys.argv[3]) if len(sys.argv) > 3 else 2026)
    work = tempfile.mkdtemp(prefix="sandcell-corrupt.")
    try:
        with open(os.path.join(work, "run.toml"), "w") as fh:
            fh.write(CONFIG)
        stopped = os.path.join(work, "stopped")
        r = run(triaxial, work, stopped, "--prepare-only")
        if r.returncode != 0:
            sys.exit(f"FAIL: the preparation exited {r.returncode}: {r.stdout}{r.stderr}")
        r = run(triaxial, work, stopped, "--resume", "--stop-after", "300")
        if r.returncode != 3:
            sys.exit(f"FAIL: the stopped run exited {r.returncode}: {r.stdout}{r.stderr}")
        reference = os.path.join(work, "reference")
        shutil.copytree(stopped, reference)
        if run(triaxial, work, reference, "--resume").returncode != 0:
            sys.exit("FAIL: the reference resume failed")
        ckpt = os.path.join(stopped, TEST + ".checkpoint.h5")
        size = os.path.getsize(ckpt)
        outcomes = {"error": 0, "identical": 0}
        for k in range(flips):
            trial = os.path.join(work, f"trial{k}")
            shutil.copytree(stopped, trial)
            path = os.path.join(trial, TEST + ".checkpoint.h5")
            byte, bit = rng.randrange(size), rng.randrange(8)
            with open(path, "r+b") as fh:
                fh.seek(byte)
                b = fh.read(1)[0]
                fh.seek(byte)
                fh.write(bytes([b ^ (1 << bit)]))
            try:
                r = run(triaxial, work, trial, "--resume")
            except subprocess.TimeoutExpired:
                sys.exit(f"FAIL: flip {k} (byte {byte}, bit {bit}): the resume hangs")
            what = f"flip {k} (byte {byte} of {size}, bit {bit})"
            if r.returncode < 0:
                sys.exit(f"FAIL: {what}: killed by signal {-r.returncode}\n{r.stdout}{r.stderr}")
            if r.returncode == 1:
                if path not in r.stdout + r.stderr:
                    sys.exit(f"FAIL: {what}: exit 1 without naming the checkpoint\n{r.stdout}{r.stderr}")
                outcomes["error"] += 1
            elif r.returncode == 0:
                diff = compare(os.path.join(reference, TEST + ".h5"), os.path.join(trial, TEST + ".h5")) or \
                    compare(os.path.join(reference, TEST + ".checkpoint.h5"), os.path.join(trial, TEST + ".checkpoint.h5"))
                if diff:
                    sys.exit(f"FAIL: {what}: resumed silently to a different result: {diff}")
                outcomes["identical"] += 1
            else:
                sys.exit(f"FAIL: {what}: exit {r.returncode}\n{r.stdout}{r.stderr}")
            shutil.rmtree(trial)
        print(f"corrupt_checkpoint: {flips} flips: {outcomes['error']} exit 1 naming the file, "
              f"{outcomes['identical']} bitwise identical resumes; no crash, hang or silent difference")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
