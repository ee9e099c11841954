#!/usr/bin/env python3
"""Writes scenes/meshes/table.obj: a low-poly round pedestal table (three closed cylinders:
base, column, top), triangles counter-clockwise seen from outside. Units: metres.

Run from the repository root: python3 scripts/make-table-obj.py
"""
import math

SEGMENTS = 24
# (radius, y_bottom, y_top) of each closed, convex piece
PIECES = [(0.22, 0.0, 0.04), (0.04, 0.04, 0.70), (0.40, 0.70, 0.74)]

vertices, faces = [], []


def sub(a, b):
    return [a[i] - b[i] for i in range(3)]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def dot(a, b):
    return sum(a[i] * b[i] for i in range(3))


for radius, y0, y1 in PIECES:
    base = len(vertices)
    centre = [0.0, 0.5 * (y0 + y1), 0.0]
    for y in (y0, y1):
        for k in range(SEGMENTS):
            t = 2.0 * math.pi * k / SEGMENTS
            vertices.append([radius * math.cos(t), y, radius * math.sin(t)])
    bottom_c, top_c = len(vertices), len(vertices) + 1
    vertices.append([0.0, y0, 0.0])
    vertices.append([0.0, y1, 0.0])
    tris = []
    for k in range(SEGMENTS):
        b0, b1 = base + k, base + (k + 1) % SEGMENTS
        t0, t1 = b0 + SEGMENTS, b1 + SEGMENTS
        tris += [(b0, b1, t1), (b0, t1, t0), (bottom_c, b0, b1), (top_c, t0, t1)]
    for tri in tris:
        p = [vertices[i] for i in tri]
        n = cross(sub(p[1], p[0]), sub(p[2], p[0]))
        mid = [sum(q[i] for q in p) / 3.0 for i in range(3)]
        if dot(n, sub(mid, centre)) < 0.0:
            tri = (tri[0], tri[2], tri[1])
        faces.append(tri)

with open("scenes/meshes/table.obj", "w") as f:
    f.write("# Low-poly round pedestal table for the `mesh` scene (scripts/make-table-obj.py).\n")
    f.write(f"# {len(vertices)} vertices, {len(faces)} triangles; metres, y up.\n")
    f.write("o table\n")
    for v in vertices:
        f.write("v {:.6f} {:.6f} {:.6f}\n".format(*v))
    for a, b, c in faces:
        f.write(f"f {a + 1} {b + 1} {c + 1}\n")
