#!/usr/bin/env python3
"""Writes a sandcell plain-text packing (Lx Ly Lz N, then x y z r) as a LIGGGHTS data file
(atom_style granular: id type diameter density x y z).
usage: packing2data.py PACKING.txt OUT.data [density kg/m^3, default 2650] [--tile K]
--tile K repeats the periodic packing K x K x K times in a K times larger box, as dem-bench --tile K
does (sandcell::tile_packing: the copies' x offset outermost, z innermost, each copy's spheres in
file order)."""
import sys

args = sys.argv[1:]
tile = 1
if "--tile" in args:
    k = args.index("--tile")
    tile = int(args[k + 1])
    del args[k:k + 2]
    if tile < 1:
        sys.exit(f"--tile {tile}: must be an integer >= 1")
src, dst = args[0], args[1]
density = float(args[2]) if len(args) > 2 else 2650.0
data = [line.split() for line in open(src) if line.strip() and not line.lstrip().startswith("#")]
lx, ly, lz, n = (float(v) for v in data[0])
n = int(n)
spheres = [tuple(float(v) for v in row) for row in data[1:1 + n]]
with open(dst, "w") as out:
    out.write(f"sandcell packing {src}, tiled {tile}^3\n\n{n * tile ** 3} atoms\n1 atom types\n\n")
    out.write(f"0 {lx * tile!r} xlo xhi\n0 {ly * tile!r} ylo yhi\n0 {lz * tile!r} zlo zhi\n\nAtoms\n\n")
    k = 0
    for cx in range(tile):
        for cy in range(tile):
            for cz in range(tile):
                for x, y, z, r in spheres:
                    k += 1
                    out.write(f"{k} 1 {2.0 * r:.17g} {density} {x + cx * lx!r} {y + cy * ly!r} {z + cz * lz!r}\n")
