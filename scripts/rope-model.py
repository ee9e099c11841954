#!/usr/bin/env python3
"""A one-chain model of the drape's failure at few substeps (issue 7, thirtieth round).

A rope of N particles, rest spacing 1.2/(N - 1) m, each of mass 0.2·spacing² kg (a warp
chain's strip of the drape's cloth, 0.2 kg/m²), springs of stiffness 400 N/m as XPBD
constraints, dropped from 0.55 m across a cylinder of radius 0.3 m + 0.008 m thickness (the
drape's ball, as a cylinder along z), with the contact pass and position-level friction of
`cloth-core` (static 0.6, kinetic 0.5) and the scaled global damping of
`scripts/realtime-series.sh`. Each substep: predict, then ROUNDS rounds of NEWTON iterations
of the chain solve (a contact pass before each round after the first), then the contact pass
and the velocities, as the grid path's sweep with `xpbd.chains` (without the other springs
and the strain limit). Prints the largest strain over the second half of the run.

Methods of the chain solve:
  dual     XPBD's solve of the chain's multipliers (tridiagonal, Gauss-Newton: the springs'
           directions linearised, their sideways stiffness left out), as `chains::solve`;
  contact  the same with particles in contact moving in the cylinder's tangent plane
           (inverse mass w(I - c cᵀ) in the system and the back substitution);
  kkt      Newton on XPBD's (x, λ) system with each spring's Hessian, the geometric
           stiffness (clamped at zero for compressed springs), unknowns interleaved in one
           banded solve;
  geo:S    the dual solve with the geometric stiffness lumped per particle (thirty-first
           round): each particle's inverse mass becomes the 3x3 (m I + S Σ g_k (I - u_k u_kᵀ))⁻¹
           over its two springs, g_k = max(-λ_k, 0)/|d_k|, so the system stays tridiagonal
           (e.g. geo:4).

Any method with the suffix +tether (thirty-third round) adds long-range attachments to the
particles in contact: each particle not in contact at the substep's start is pulled onto the
sphere of radius |i - a|·spacing around its nearest such particle a on each side along the
chain (a kept in place), when it is farther. Where (environment TETHER_AT): after the
prediction (pre), after each round's solves (post), or both (both, the default); e.g.
dual+tether, geo:4+tether.

Two diagnostics of the landing (thirty-first round):
  front    the run with the dual solve, printing also how many particles the contact front
           (the outermost particle on the cylinder) passes per substep while it goes from 3
           to 15 cm from the middle;
  iterate  the chain problem of the first substep of frame FRAME of a run at ROUNDS x NEWTON
           (dual solve), taken alone (no contact) and iterated 20 times from the predicted
           positions with the dual and with the kkt method: the largest strain after each.

Needs numpy and scipy (not the project's: pip install numpy scipy).
Usage: rope-model.py METHOD N ROUNDS NEWTON SUBSTEPS...
       rope-model.py front N ROUNDS NEWTON SUBSTEPS...
       rope-model.py iterate N ROUNDS NEWTON SUBSTEPS FRAME
e.g.   rope-model.py dual 512 2 2 6 8 10
       rope-model.py front 512 2 2 5 10
       rope-model.py iterate 512 2 2 5 15
"""
import sys

import numpy as np
from scipy.linalg import solve_banded

import os

TETHER_AT = os.environ.get("TETHER_AT", "both")
RHO, K, RC, MU = 0.2, 400.0, 0.308, (0.6, 0.5)


def contact(x, x0):
    r = np.hypot(x[:, 0], x[:, 1])
    inside = r < RC
    if not inside.any():
        return x
    nrm = np.zeros_like(x)
    nrm[:, 0], nrm[:, 1] = x[:, 0] / r, x[:, 1] / r
    push = np.where(inside, RC - r, 0.0)
    x = x + push[:, None] * nrm
    rel = x - x0
    t = rel - (rel * nrm).sum(1)[:, None] * nrm
    tl = np.linalg.norm(t, axis=1)
    s = np.where(tl <= MU[0] * push, 1.0, np.minimum(MU[1] * push / np.maximum(tl, 1e-30), 1.0))
    return x - np.where(inside, s, 0.0)[:, None] * t


def tridiagonal(diag, off, rhs):
    ab = np.zeros((3, len(diag)))
    ab[0, 1:], ab[1], ab[2, :-1] = off, diag, off
    return solve_banded((1, 1), ab, rhs)


def dual(x, lam, xt, rest, m, alpha, in_contact=False):
    w = 1.0 / m
    d = x[1:] - x[:-1]
    ln = np.linalg.norm(d, axis=1)
    u = d / ln[:, None]
    c = np.zeros_like(x)
    if in_contact:
        r = np.hypot(x[:, 0], x[:, 1])
        c[:, 0], c[:, 1] = x[:, 0] / r, x[:, 1] / r
        c *= (r < RC)[:, None]
    ca, cb = (c[:-1] * u).sum(1), (c[1:] * u).sum(1)
    diag = w * (1 - ca**2) + w * (1 - cb**2) + alpha
    ck = c[1:-1]
    off = -w * ((u[:-1] * u[1:]).sum(1) - (ck * u[:-1]).sum(1) * (ck * u[1:]).sum(1))
    dl = tridiagonal(diag, off, -(ln - rest) - alpha * lam)
    f = np.zeros_like(x)
    f[:-1] -= dl[:, None] * u
    f[1:] += dl[:, None] * u
    f -= (f * c).sum(1)[:, None] * c
    return x + w * f, lam + dl


def geo(x, lam, xt, rest, m, alpha, scale):
    n = len(x)
    d = x[1:] - x[:-1]
    ln = np.linalg.norm(d, axis=1)
    u = d / ln[:, None]
    gk = scale * np.maximum(-lam / ln, 0.0)
    proj = np.eye(3)[None] - u[:, :, None] * u[:, None, :]
    h = np.repeat((m * np.eye(3))[None], n, 0)
    h[:-1] += gk[:, None, None] * proj
    h[1:] += gk[:, None, None] * proj
    wi = np.linalg.inv(h)
    wu_a = np.einsum("kij,kj->ki", wi[:-1], u)
    wu_b = np.einsum("kij,kj->ki", wi[1:], u)
    diag = (u * wu_a).sum(1) + (u * wu_b).sum(1) + alpha
    off = -np.einsum("ki,kij,kj->k", u[:-1], wi[1:-1], u[1:])
    dl = tridiagonal(diag, off, -(ln - rest) - alpha * lam)
    f = np.zeros_like(x)
    f[:-1] -= dl[:, None] * u
    f[1:] += dl[:, None] * u
    return x + np.einsum("kij,kj->ki", wi, f), lam + dl


def kkt(x, lam, xt, rest, m, alpha):
    n = len(x)
    d = x[1:] - x[:-1]
    ln = np.linalg.norm(d, axis=1)
    u = d / ln[:, None]
    g = m * (x - xt)
    g[1:] -= lam[:, None] * u
    g[:-1] += lam[:, None] * u
    hres = (ln - rest) + alpha * lam
    gk = np.maximum(-lam / ln, 0.0)
    G = gk[:, None, None] * (np.eye(3)[None] - u[:, :, None] * u[:, None, :])
    size, bw = 4 * n - 1, 6
    ab = np.zeros((2 * bw + 1, size))

    def put(rows, cols, vals):
        np.add.at(ab, (bw + rows - cols, cols), vals)

    j, k = np.arange(n), np.arange(n - 1)
    for p in range(3):
        put(4 * j + p, 4 * j + p, np.full(n, m))
        for q in range(3):
            put(4 * k + p, 4 * k + q, G[:, p, q])
            put(4 * k + 4 + p, 4 * k + 4 + q, G[:, p, q])
            put(4 * k + p, 4 * k + 4 + q, -G[:, p, q])
            put(4 * k + 4 + p, 4 * k + q, -G[:, p, q])
        put(4 * k + 4 + p, 4 * k + 3, -u[:, p])
        put(4 * k + p, 4 * k + 3, u[:, p])
        put(4 * k + 3, 4 * k + 4 + p, u[:, p])
        put(4 * k + 3, 4 * k + p, -u[:, p])
    put(4 * k + 3, 4 * k + 3, np.full(n - 1, alpha))
    rhs = np.zeros(size)
    for p in range(3):
        rhs[4 * j + p] = -g[:, p]
    rhs[4 * k + 3] = -hres
    sol = solve_banded((bw, bw), ab, rhs)
    dx = np.stack([sol[4 * j + p] for p in range(3)], axis=1)
    return x + dx, lam + sol[4 * k + 3]


def tethers(x, anchors, rest):
    """Each particle not an anchor is pulled onto the sphere of radius |i - a|·rest around
    its nearest anchor a along the chain (on each side), when it is farther (the anchor kept
    where it is): long-range attachments to the particles in contact."""
    n = len(x)
    idx = np.arange(n)
    if not anchors.any():
        return x
    a_idx = np.flatnonzero(anchors)
    # nearest anchor on the left and on the right of every particle
    pos = np.searchsorted(a_idx, idx)
    for side in (pos - 1, pos):
        ok = (side >= 0) & (side < len(a_idx))
        a = a_idx[np.clip(side, 0, len(a_idx) - 1)]
        ok &= ~anchors
        d = x - x[a]
        ln = np.linalg.norm(d, axis=1)
        lim = np.abs(idx - a) * rest
        over = ok & (ln > lim)
        scale = np.where(over, lim / np.maximum(ln, 1e-30), 1.0)
        x = x[a] + d * scale[:, None]
    return x


def strain(x, rest):
    return np.linalg.norm(x[1:] - x[:-1], axis=1) / rest - 1


def run(method, n, rounds, newton, substeps, seconds=3.0, seed=1, front=None, stop=None):
    """The largest strain over the run's second half. `front`, a list, gets the front's
    distance from the middle (m) after every substep; `stop`, a frame, ends the run at that
    frame's first substep and returns (start positions, predicted positions, rest, mass, h)."""
    rng = np.random.default_rng(seed)
    rest = 1.2 / (n - 1)
    m = RHO * rest * rest
    h = (1 / 60) / substeps
    alpha = 1.0 / (K * h * h)
    damp = 2e-4 * (48 / n) ** 2
    x = np.zeros((n, 3))
    x[:, 0], x[:, 1] = np.linspace(-0.6, 0.6, n), 0.55
    x[:, 2] = 1e-4 * rng.standard_normal(n)
    v = np.zeros((n, 3))
    g = np.array([0.0, -9.81, 0.0])
    tether = method.endswith("+tether")
    if tether:
        method = method[: -len("+tether")]
    if method.startswith("geo:"):
        scale = float(method[4:])
        solve = lambda *a: geo(*a, scale)  # noqa: E731
    else:
        solve = {
            "dual": dual,
            "contact": lambda *a: dual(*a, in_contact=True),
            "kkt": kkt,
        }[method]
    frames = int(round(seconds * 60))
    late = 0.0
    for frame in range(frames):
        for _ in range(substeps):
            x0 = x.copy()
            v = v + h * g - (h * damp / m) * v
            xt = x + h * v
            if stop == frame:
                return x0, xt, rest, m, h
            x, lam = xt.copy(), np.zeros(n - 1)
            anchors = np.hypot(x0[:, 0], x0[:, 1]) < RC + 1e-7 if tether else None
            if tether and TETHER_AT in ("pre", "both"):
                x = tethers(x, anchors, rest)
            for r in range(rounds):
                if r > 0:
                    x = contact(x, x0)
                for _ in range(newton):
                    x, lam = solve(x, lam, xt, rest, m, alpha)
                if tether and TETHER_AT in ("post", "both"):
                    x = tethers(x, anchors, rest)
            x = contact(x, x0)
            v = (x - x0) / h
            if not np.isfinite(x).all() or np.abs(v).max() > 1e3:
                return float("inf")
            if front is not None:
                on = np.flatnonzero(np.hypot(x[:, 0], x[:, 1]) < RC + 1e-7)
                front.append((on.max() - (n - 1) / 2) * rest if len(on) else 0.0)
        if frame >= frames // 2:
            late = max(late, strain(x, rest).max())
    return late


def front_advance(front, rest, a=0.03, b=0.15):
    """Particles the front passes per substep while it goes from a to b metres out."""
    f = np.array(front)
    i, j = int(np.argmax(f > a)), int(np.argmax(f > b))
    return (f[j] - f[i]) / max(j - i, 1) / rest


def iterate(n, rounds, newton, substeps, frame):
    x0, xt, rest, m, h = run("dual", n, rounds, newton, substeps, stop=frame)
    alpha = 1.0 / (K * h * h)
    print(f"start of frame {frame}: largest strain {100 * strain(x0, rest).max():.1f} %")
    for name, solve in (("dual", dual), ("kkt", kkt)):
        x, lam, out = xt.copy(), np.zeros(n - 1), []
        for _ in range(20):
            x, lam = solve(x, lam, xt, rest, m, alpha)
            out.append(f"{100 * strain(x, rest).max():.1f}")
        print(f"{name:5s}", " ".join(out), flush=True)


if __name__ == "__main__":
    if len(sys.argv) < 6:
        sys.exit(__doc__)
    method, n, rounds, newton = sys.argv[1], *map(int, sys.argv[2:5])
    if method == "iterate":
        iterate(n, rounds, newton, *map(int, sys.argv[5:7]))
        sys.exit()
    for s in map(int, sys.argv[5:]):
        front = [] if method == "front" else None
        late = run("dual" if front is not None else method, n, rounds, newton, s, front=front)
        line = f"{method} N={n} {s} x {rounds} x {newton}: late max {100 * late:.2f} %"
        if front is not None:
            line += f", front {front_advance(front, 1.2 / (n - 1)):.2f} particles per substep"
        print(line, flush=True)
