#!/usr/bin/env python3
"""Where a grid cloth's structural springs are stretched, from exported OBJ frames.

For each OBJ frame written by `cloth sim --out DIR` of a RES x RES grid cloth of side SIZE
metres (rest spacing SIZE / (RES - 1)), prints for the springs along the rows (weft) and
across them (warp): the largest strain, how many springs are stretched by more than 5 %,
and the TOP worst springs as (row, column, strain %) with the first particle's position and
its distance from the origin (the drape scene's ball is centred there).

Usage: scripts/strain-where.py RES SIZE [--top N] frame.obj...
e.g.   scripts/strain-where.py 512 1.2 out/frame_0180.obj
"""
import math
import sys


def read_grid(path, res):
    verts = []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                verts.append(tuple(float(t) for t in line.split()[1:4]))
    if len(verts) != res * res:
        sys.exit(f"{path}: {len(verts)} vertices, not {res} x {res}")
    return verts


def main(argv):
    args = list(argv)
    top = 5
    if "--top" in args:
        i = args.index("--top")
        top = int(args[i + 1])
        del args[i : i + 2]
    if len(args) < 3:
        sys.exit(__doc__)
    res, size = int(args[0]), float(args[1])
    rest = size / (res - 1)
    for path in args[2:]:
        v = read_grid(path, res)
        for name, (di, dj) in (("along rows", (0, 1)), ("across rows", (1, 0))):
            springs = []
            for i in range(res - di):
                for j in range(res - dj):
                    a, b = v[i * res + j], v[(i + di) * res + j + dj]
                    strain = math.dist(a, b) / rest - 1.0
                    springs.append((strain, i, j))
            over = sum(1 for s in springs if s[0] > 0.05)
            springs.sort(reverse=True)
            worst = []
            for strain, i, j in springs[:top]:
                p = v[i * res + j]
                worst.append(
                    f"({i}, {j}) {strain * 100:.1f} % at "
                    f"({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}), |p| {math.hypot(*p):.3f}"
                )
            print(f"{path} {name}: max {springs[0][0] * 100:.1f} %, {over} over 5 %")
            for w in worst:
                print(f"    {w}")


if __name__ == "__main__":
    main(sys.argv[1:])
