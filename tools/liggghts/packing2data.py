#!/usr/bin/env python3
"""Writes a sandcell plain-text packing (Lx Ly Lz N, then x y z r) as a LIGGGHTS data file
(atom_style granular: id type diameter density x y z).
usage: packing2data.py PACKING.txt OUT.data [density kg/m^3, default 2650]"""
import sys

src, dst = sys.argv[1], sys.argv[2]
density = float(sys.argv[3]) if len(sys.argv) > 3 else 2650.0
data = [line.split() for line in open(src) if line.strip() and not line.lstrip().startswith("#")]
lx, ly, lz, n = data[0]
with open(dst, "w") as out:
    out.write(f"sandcell packing {src}\n\n{int(n)} atoms\n1 atom types\n\n")
    out.write(f"0 {lx} xlo xhi\n0 {ly} ylo yhi\n0 {lz} zlo zhi\n\nAtoms\n\n")
    for k, (x, y, z, r) in enumerate(data[1:1 + int(n)], start=1):
        out.write(f"{k} 1 {2.0 * float(r):.17g} {density} {x} {y} {z}\n")
