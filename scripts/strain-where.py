#!/usr/bin/env python3
"""Where a grid cloth's structural springs are stretched, from exported OBJ frames.

For each OBJ frame written by `cloth sim --out DIR` of a RES x RES grid cloth of side SIZE
metres (rest spacing SIZE / (RES - 1)), prints for the springs along the rows (weft) and
across them (warp): the largest strain, how many springs are stretched by more than 5 %,
and the TOP worst springs as (row, column, strain %) with the first particle's position and
its distance from the origin (the drape scene's ball is centred there), and how the springs
over 5 % split between even and odd positions along their chain (the two colours of the
structural strain limit's passes: a chain whose excess length the limit cannot remove leaves
it in the colour projected first, every other spring).

With --map FILE.png it also writes a picture of the strain, one pixel per particle (two per
side with --scale 2): red the spring along the row from it, green the one across, full at
10 %; with --ball R, particles within 1.5 mm of a sphere of radius R at the origin are tinted
blue (the drape's ball: R = radius + thickness = 0.308). No packages beyond Python's own.

Usage: scripts/strain-where.py RES SIZE [--top N] [--map FILE.png [--scale K] [--ball R]] frame.obj...
e.g.   scripts/strain-where.py 512 1.2 --map cap.png --ball 0.308 out/frame_0180.obj
"""
import math
import struct
import sys
import zlib


def read_grid(path, res):
    verts = []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                verts.append(tuple(float(t) for t in line.split()[1:4]))
    if len(verts) != res * res:
        sys.exit(f"{path}: {len(verts)} vertices, not {res} x {res}")
    return verts


def write_png(path, width, height, rows):
    """An 8-bit RGB PNG from `rows` (each `width` (r, g, b) tuples of 0..255)."""
    raw = b"".join(b"\x00" + bytes(c for px in row for c in px) for row in rows)

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n")
        f.write(chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)))
        f.write(chunk(b"IDAT", zlib.compress(raw, 6)))
        f.write(chunk(b"IEND", b""))


def strain_map(path, v, res, rest, scale, ball):
    def level(a, b):
        s = math.dist(a, b) / rest - 1.0
        return int(255 * min(max(s / 0.10, 0.0), 1.0))

    rows = []
    for i in range(res):
        row = []
        for j in range(res):
            p = v[i * res + j]
            r = level(p, v[i * res + j + 1]) if j + 1 < res else 0
            g = level(p, v[(i + 1) * res + j]) if i + 1 < res else 0
            b = 90 if ball is not None and math.hypot(*p) < ball + 0.0015 else 0
            row.extend([(r, g, b)] * scale)
        rows.extend([row] * scale)
    write_png(path, res * scale, res * scale, rows)


def option(args, name, parse, default):
    if name not in args:
        return default
    i = args.index(name)
    value = parse(args[i + 1])
    del args[i : i + 2]
    return value


def main(argv):
    args = list(argv)
    top = option(args, "--top", int, 5)
    png = option(args, "--map", str, None)
    scale = option(args, "--scale", int, 1)
    ball = option(args, "--ball", float, None)
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
            # Position along the spring's own chain: its column along a row, its row across.
            even = sum(1 for s in springs if s[0] > 0.05 and (s[1] * di + s[2] * dj) % 2 == 0)
            springs.sort(reverse=True)
            worst = []
            for strain, i, j in springs[:top]:
                p = v[i * res + j]
                worst.append(
                    f"({i}, {j}) {strain * 100:.1f} % at "
                    f"({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}), |p| {math.hypot(*p):.3f}"
                )
            print(
                f"{path} {name}: max {springs[0][0] * 100:.1f} %, {over} over 5 % "
                f"({even} at even positions, {over - even} at odd)"
            )
            for w in worst:
                print(f"    {w}")
        if png:
            strain_map(png, v, res, rest, scale, ball)
            print(f"{path}: strain map in {png}")


if __name__ == "__main__":
    main(sys.argv[1:])
