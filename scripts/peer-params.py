#!/usr/bin/env python3
"""The peer scene (Taichi's cloth on a ball) at n x n as `cloth sim --set` overrides, one per
line: the peer's formulas at that n (h = 0.04/n, stiffness and damping scaled with n), exactly
what `cloth_core::presets::peer_ball(n)` builds (repr gives the f32-exact decimal forms).
Shared by scripts/peer-compare.sh and scripts/scaling-series.sh."""
import math
import sys

n = int(sys.argv[1])
q = 1.0 / n
c0 = -0.5 + 0.5 * (n - 1) * q
h = 0.04 / n
sub = int((1.0 / 60.0) / h)
y = 3.0e4
c = 1.0e4 * q
print(f"cloth.resolution=[{n},{n}]")
print(f"cloth.spacing=[{q!r},{q!r}]")
print(f"cloth.origin=[{c0 + 0.037153453!r},0.6,{c0 + 0.027561575!r}]")
for kind, k in (("warp", y / q), ("weft", y / q), ("shear", y / (math.sqrt(2) * q)), ("bend", y / (2 * q))):
    print(f"material.{kind}={{ stiffness = {k!r}, damping = {c!r} }}")
print(f"solver.dt={h * sub!r}")
print(f"solver.substeps={sub}")
