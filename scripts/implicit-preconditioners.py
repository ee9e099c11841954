#!/usr/bin/env python3
"""Preconditioners for implicit Euler's CG, measured on a model system (issue 7, thirty-fourth
round in docs/performance.md; numpy and scipy, not part of the build).

The system is the one `cloth-core`'s implicit Euler solves, A = M + sum_s [S_s, -S_s; -S_s, S_s]
with S = h*c*d*d^T + h^2*k*(d*d^T + max(0, 1 - L0/|L|)*(I - d*d^T)), for an N x N cloth of
the implicit-drape scene's material (400/400/80/10 N/m, 0.2 kg/m^2, 1.2 m, h = 1/120 s) laid
over a ball's cap and hanging beyond it (a made-up shape with stretched and compressed
springs), without the contact filter, and a random right-hand side. It prints the iterations
of the preconditioned CG to a relative residual of 1e-3 (the scene's tolerance) with:
block-Jacobi (the solver's), line solves along rows or columns (block-tridiagonal),
rows-columns-rows (symmetric multiplicative), the additive rows + columns - diagonal, and a
geometric multigrid V-cycle (bilinear prolongation, Galerkin coarse operators, damped
block-Jacobi smoothing).

With `filter` the system is the CG's filtered one, S·A·S + (I − S), with the particles on
the ball's cap held along its normal (S = I − n·nᵀ there), as implicit Euler's contacts
are; the line preconditioners are then skipped (forty-seventh round).

Usage: scripts/implicit-preconditioners.py [N [H [filter]]]   (default 64, 1/120 s)
"""
import numpy as np, scipy.sparse as sp, scipy.sparse.linalg as sla, sys
N = int(sys.argv[1]) if len(sys.argv) > 1 else 64
h = float(sys.argv[2]) if len(sys.argv) > 2 else 1/120; size = 1.2; dens = 0.2
m = dens*size*size/(N*N)
sp_ = size/(N-1)
ks = dict(warp=(400,0.02), weft=(400,0.02), shear=(80,0.01), bend=(10,0.005))
rng = np.random.default_rng(1)
# positions: sheet draped on sphere radius 0.3 (cap) + hanging; approximate by mapping onto a bump
u = np.linspace(-size/2, size/2, N)
X, Z = np.meshgrid(u, u, indexing='ij')
R = 0.31
r = np.hypot(X, Z)
Y = np.where(r < R, np.sqrt(np.maximum(R*R - r*r, 0)), -(r - R)*1.2)
P = np.stack([X, Y, Z], -1).reshape(-1, 3) + rng.normal(0, 0.002, (N*N, 3))
idx = lambda i, j: i*N + j
springs = []
for i in range(N):
    for j in range(N):
        if i+1 < N: springs.append((idx(i,j), idx(i+1,j), 'warp', sp_))
        if j+1 < N: springs.append((idx(i,j), idx(i,j+1), 'weft', sp_))
        if i+1 < N and j+1 < N: springs.append((idx(i,j), idx(i+1,j+1), 'shear', sp_*2**.5))
        if i+1 < N and j > 0: springs.append((idx(i,j), idx(i+1,j-1), 'shear', sp_*2**.5))
        if i+2 < N: springs.append((idx(i,j), idx(i+2,j), 'bend', 2*sp_))
        if j+2 < N: springs.append((idx(i,j), idx(i,j+2), 'bend', 2*sp_))
n = N*N
rows_, cols_, vals = [], [], []
def add(a, b, B):
    for p in range(3):
        for q in range(3):
            rows_.append(3*a+p); cols_.append(3*b+q); vals.append(B[p,q])
blocks = {}
for a, b, kind, L0 in springs:
    k, c = ks[kind]
    l = P[b]-P[a]; ln = np.linalg.norm(l); d = l/ln
    g = max(1-L0/ln, 0)
    K = k*(np.outer(d,d) + g*(np.eye(3)-np.outer(d,d)))
    S = h*c*np.outer(d,d) + h*h*K
    blocks[(a,b,kind)] = S
    add(a,a,S); add(b,b,S); add(a,b,-S); add(b,a,-S)
for i in range(n):
    add(i,i,m*np.eye(3))
A = sp.csr_matrix((vals,(rows_,cols_)),shape=(3*n,3*n))
b = rng.normal(0,1,3*n)*m  # rhs scale
FILTER = len(sys.argv) > 3 and sys.argv[3] == 'filter'
if FILTER:
    proj = []
    for i in range(n):
        if np.hypot(P[i,0], P[i,2]) < R:
            nrm = P[i]/np.linalg.norm(P[i]); proj.append(np.eye(3) - np.outer(nrm, nrm))
        else:
            proj.append(np.eye(3))
    S = sp.block_diag(proj).tocsr()
    A = (S @ A @ S + (sp.eye(3*n) - S @ S)).tocsr()
    b = S @ b
    print('filtered particles', sum(np.hypot(P[i,0], P[i,2]) < R for i in range(n)), 'of', n)
def pcg(A, b, Minv, tol=1e-3, maxit=1000):
    x = np.zeros_like(b); r = b.copy(); s = Minv(r); c = s.copy()
    d0 = b @ Minv(b); d = r @ s; it = 0
    while d > tol*tol*d0 and it < maxit:
        q = A @ c; al = d/(c@q); x += al*c; r -= al*q; s = Minv(r); dn = r@s; c = s + dn/d*c; d = dn; it += 1
    return it
# block Jacobi
D = [A[3*i:3*i+3,3*i:3*i+3].toarray() for i in range(n)]
Dinv = sp.block_diag([np.linalg.inv(x) for x in D]).tocsr()
print('block-jacobi', pcg(A, b, lambda r: Dinv @ r))
# line preconditioners: keep only couplings within a row (i fixed) / column
def keep(pred):
    Acoo = A.tocoo()
    pa, pb = Acoo.row//3, Acoo.col//3
    mask = pred(pa, pb)
    return sp.csr_matrix((Acoo.data[mask], (Acoo.row[mask], Acoo.col[mask])), shape=A.shape)
same_i = lambda a, b: (a//N) == (b//N)
same_j = lambda a, b: (a%N) == (b%N)
if not FILTER:
    Ti = keep(same_i).tocsc(); Tj = keep(same_j).tocsc()
    fi = sla.splu(Ti); fj = sla.splu(Tj)
    print('rows (weft lines)', pcg(A, b, fi.solve))
    print('cols (warp lines)', pcg(A, b, fj.solve))
    # symmetric multiplicative: x = Ti^-1 r; x += Tj^-1 (r - A x); x += Ti^-1 (r - A x)
    def sym(r):
        x = fi.solve(r); x = x + fj.solve(r - A@x); x = x + fi.solve(r - A@x); return x
    print('rows-cols-rows', pcg(A, b, sym))
    # additive: Ti^-1 + Tj^-1 - D^-1
    print('additive', pcg(A, b, lambda r: fi.solve(r)+fj.solve(r)-Dinv@r))

# geometric multigrid V-cycle preconditioner: bilinear prolongation on the grid, Galerkin
# coarse operators, damped block-Jacobi smoothing (symmetric: nu pre, nu post).
def prolong(Nf):
    Nc = (Nf+1)//2
    def w1(Nf, Nc):
        Pm = sp.lil_matrix((Nf, Nc))
        for i in range(Nf):
            if i % 2 == 0: Pm[i, i//2] = 1
            else:
                Pm[i, i//2] = .5
                if i//2+1 < Nc: Pm[i, i//2+1] = .5
                else: Pm[i, i//2] = 1
        return Pm.tocsr()
    P1 = w1(Nf, Nc)
    P2 = sp.kron(P1, P1)
    return sp.kron(P2, sp.eye(3)).tocsr(), Nc
levels = []
Al = A.tocsr(); Nl = N
while Nl > 8:
    Pm, Nc = prolong(Nl)
    nl = Nl*Nl
    Dl = sp.block_diag([np.linalg.inv(Al[3*i:3*i+3,3*i:3*i+3].toarray()) for i in range(nl)]).tocsr()
    levels.append((Al, Dl, Pm))
    Al = (Pm.T @ Al @ Pm).tocsr(); Nl = Nc
coarse = sla.splu(Al.tocsc())
def vcycle(r, l=0, nu=1, om=0.7):
    if l == len(levels): return coarse.solve(r)
    Al, Dl, Pm = levels[l]
    x = om*(Dl@r)
    for _ in range(nu-1): x = x + om*(Dl@(r - Al@x))
    x = x + Pm @ vcycle(Pm.T @ (r - Al@x), l+1, nu, om)
    for _ in range(nu): x = x + om*(Dl@(r - Al@x))
    return x
for nu in (1, 2):
    print('mg V(%d,%d)' % (nu, nu), pcg(A, b, lambda r: vcycle(r, 0, nu)))
