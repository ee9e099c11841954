//! Linearised backward (implicit) Euler after Baraff & Witkin 1998, "Large steps in cloth
//! simulation".
//!
//! One substep solves
//! (M − h·∂f/∂v − h²·∂f/∂x)·Δv = h·(f + h·∂f/∂x·v)
//! for the velocity change Δv, then sets v ← v + Δv and x ← x + h·v.
//!
//! - Each spring contributes the 3×3 block S = h·c·d·dᵀ + h²·K with
//!   K = k·(d·dᵀ + max(0, 1 − L0/|L|)·(I − d·dᵀ)): the geometric (transverse) part is dropped
//!   when the spring is compressed, which keeps the matrix symmetric positive definite.
//!   The global damping −d·v adds h·d·I to the diagonal. Air is taken explicitly (in f).
//! - The system is solved matrix-free by the filtered ("modified") preconditioned conjugate
//!   gradient of the paper (§5.3) with a block-Jacobi preconditioner. Pinned particles are
//!   fully constrained (their Δv is zero: they keep the prescribed velocity); a particle
//!   touching a collider at the start of the substep has its normal velocity constrained to
//!   the collider's. Neither enters as a penalty spring.
//! - After the solve, the constraint impulse on each contact, e = A·Δv − b, gives the
//!   normal velocity change that Coulomb friction uses (stick when |v_t| ≤ μ_s·e_n/m, else
//!   slide losing μ_k·e_n/m), and particles that newly reach a collider during the substep are
//!   projected out with the shared contact response.
//! - Every sum runs in a fixed order, and the dot products of the CG accumulate in f64.

use glam::{Mat3, Vec3};

use super::SubstepCtx;
use crate::collide::resolve_contacts;
use crate::forces::accumulate;
use crate::topology::SpringKind;

/// Per-particle velocity filter of the modified CG.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Filter {
    /// Unconstrained.
    Free,
    /// All three directions fixed (pinned).
    Fixed,
    /// The normal direction fixed (a contact with outward normal n), index of the collider.
    Normal(Vec3, u32),
}

impl Filter {
    #[inline]
    fn apply(self, p: Vec3) -> Vec3 {
        match self {
            Filter::Free => p,
            Filter::Fixed => Vec3::ZERO,
            Filter::Normal(n, _) => p - n.dot(p) * n,
        }
    }
}

/// Result of the last linear solve.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct CgStats {
    /// Iterations of the last solve.
    pub iterations: u32,
    /// Final preconditioned relative residual √(rᵀP⁻¹r / bᵀP⁻¹b).
    pub residual: f32,
    /// Whether the residual reached the tolerance.
    pub converged: bool,
}

/// Scratch of the implicit solver, sized once per cloth.
#[derive(Debug, Clone, Default)]
pub(crate) struct ImplicitScratch {
    /// Per spring: S = h·c·d·dᵀ + h²·K.
    block: Vec<Mat3>,
    /// Inverse of each particle's diagonal block (the preconditioner).
    precond: Vec<Mat3>,
    filter: Vec<Filter>,
    rhs: Vec<Vec3>,
    dv: Vec<Vec3>,
    r: Vec<Vec3>,
    c: Vec<Vec3>,
    q: Vec<Vec3>,
    s: Vec<Vec3>,
}

fn resize(v: &mut Vec<Vec3>, n: usize) {
    v.clear();
    v.resize(n, Vec3::ZERO);
}

impl ImplicitScratch {
    /// y = A·p over the free directions (unfiltered product).
    fn multiply(&self, ctx: &SubstepCtx<'_>, diag: f32, p: &[Vec3], y: &mut [Vec3]) {
        for ((y, &m), &p) in y.iter_mut().zip(&ctx.particles.mass).zip(p) {
            *y = (m + diag) * p;
        }
        for (s, block) in ctx.topology.springs().iter().zip(&self.block) {
            let (a, b) = (s.a as usize, s.b as usize);
            let t = *block * (p[a] - p[b]);
            y[a] += t;
            y[b] -= t;
        }
    }
}

/// One linearised backward-Euler substep.
pub(super) fn substep(
    ctx: &mut SubstepCtx<'_>,
    force: &mut [Vec3],
    sc: &mut ImplicitScratch,
    cg: &mut CgStats,
) {
    let n = ctx.particles.len();
    let h = ctx.h;
    let cfg = ctx.config;
    let settings = cfg.implicit;
    accumulate(cfg, ctx.topology, ctx.particles, ctx.wind, force);

    // Right-hand side b = h·f + h²·(∂f/∂x)·v, the spring blocks S, the preconditioner.
    let diag = if cfg.forces.damping {
        h * cfg.damping
    } else {
        0.0
    };
    sc.block.clear();
    sc.block.reserve(ctx.topology.springs().len());
    resize(&mut sc.rhs, n);
    for (b, &f) in sc.rhs.iter_mut().zip(force.iter()) {
        *b = h * f;
    }
    sc.precond.clear();
    sc.precond.extend(
        ctx.particles
            .mass
            .iter()
            .map(|&m| Mat3::from_diagonal(Vec3::splat(m + diag))),
    );
    let (x, v) = (&ctx.particles.position, &ctx.particles.velocity);
    for kind in SpringKind::ALL {
        let p = cfg.material.params(kind);
        let k = if cfg.forces.springs { p.stiffness } else { 0.0 };
        let c = if cfg.forces.dashpots { p.damping } else { 0.0 };
        for s in ctx.topology.springs_of(kind) {
            let (a, b) = (s.a as usize, s.b as usize);
            let l = x[b] - x[a];
            let len = l.length();
            if len <= 0.0 || (k == 0.0 && c == 0.0) {
                sc.block.push(Mat3::ZERO);
                continue;
            }
            let d = l / len;
            let ddt = Mat3::from_cols(d * d.x, d * d.y, d * d.z);
            let geometric = (1.0 - s.rest_length / len).max(0.0);
            let stiff = k * (ddt + geometric * (Mat3::IDENTITY - ddt));
            let kv = stiff * (v[b] - v[a]);
            sc.rhs[a] += (h * h) * kv;
            sc.rhs[b] -= (h * h) * kv;
            let block = (h * c) * ddt + (h * h) * stiff;
            sc.precond[a] += block;
            sc.precond[b] += block;
            sc.block.push(block);
        }
    }
    for m in &mut sc.precond {
        *m = m.inverse();
    }

    // Filters: pins fixed, resting contacts constrained along their normal. A contact counts
    // as resting when the particle is within the slack of the contact surface (plus the
    // distance gravity pulls it in one substep) and leaves it slower than gravity would stop
    // it within the substep: otherwise it would fall back in during the substep and be
    // projected out afterwards, a hop that never settles.
    let g_h = if cfg.forces.gravity {
        cfg.gravity.length() * h
    } else {
        0.0
    };
    sc.filter.clear();
    resize(&mut sc.dv, n);
    for i in 0..n {
        if ctx.particles.inv_mass[i] == 0.0 {
            sc.filter.push(Filter::Fixed);
            continue;
        }
        let mut filter = Filter::Free;
        for (ci, col) in ctx.colliders.iter().enumerate() {
            let (dist, nrm) = col.shape.distance_within(x[i], col.contact_range());
            let slack = 0.1 * col.thickness + 1e-5 + g_h * h;
            if dist - col.thickness < slack {
                let vn = (v[i] - col.velocity_at(x[i])).dot(nrm);
                if vn <= g_h {
                    // Δv·n = −v_rel·n: the new normal velocity equals the collider's.
                    sc.dv[i] = -vn * nrm;
                    filter = Filter::Normal(nrm, ci as u32);
                    break;
                }
            }
        }
        sc.filter.push(filter);
    }

    // Modified PCG (Baraff & Witkin 1998, §5.3).
    let filt = |f: &[Filter], v: &mut [Vec3]| {
        for (v, f) in v.iter_mut().zip(f) {
            *v = f.apply(*v);
        }
    };
    let dot = |a: &[Vec3], b: &[Vec3]| -> f64 {
        a.iter().zip(b).map(|(a, b)| f64::from(a.dot(*b))).sum()
    };
    resize(&mut sc.r, n);
    resize(&mut sc.c, n);
    resize(&mut sc.q, n);
    resize(&mut sc.s, n);
    // δ0 from the filtered, preconditioned right-hand side.
    let mut tmp = std::mem::take(&mut sc.s);
    tmp.copy_from_slice(&sc.rhs);
    filt(&sc.filter, &mut tmp);
    for (c, (m, t)) in sc.c.iter_mut().zip(sc.precond.iter().zip(&tmp)) {
        *c = *m * *t;
    }
    let delta0 = dot(&tmp, &sc.c);
    sc.s = tmp;
    let mut q = std::mem::take(&mut sc.q);
    sc.multiply(ctx, diag, &sc.dv, &mut q);
    for ((r, b), aq) in sc.r.iter_mut().zip(&sc.rhs).zip(&q) {
        *r = *b - *aq;
    }
    filt(&sc.filter, &mut sc.r);
    for (c, (m, r)) in sc.c.iter_mut().zip(sc.precond.iter().zip(&sc.r)) {
        *c = *m * *r;
    }
    filt(&sc.filter, &mut sc.c);
    let mut delta = dot(&sc.r, &sc.c);
    let tol2 = f64::from(settings.tolerance) * f64::from(settings.tolerance);
    let mut iterations = 0;
    while delta > tol2 * delta0 && iterations < settings.max_iterations {
        sc.multiply(ctx, diag, &sc.c, &mut q);
        filt(&sc.filter, &mut q);
        let cq = dot(&sc.c, &q);
        if cq <= 0.0 {
            break;
        }
        let alpha = (delta / cq) as f32;
        for ((dv, r), (c, q)) in sc
            .dv
            .iter_mut()
            .zip(sc.r.iter_mut())
            .zip(sc.c.iter().zip(&q))
        {
            *dv += alpha * *c;
            *r -= alpha * *q;
        }
        for (s, (m, r)) in sc.s.iter_mut().zip(sc.precond.iter().zip(&sc.r)) {
            *s = *m * *r;
        }
        let delta_old = delta;
        delta = dot(&sc.r, &sc.s);
        let beta = (delta / delta_old) as f32;
        for (c, s) in sc.c.iter_mut().zip(&sc.s) {
            *c = *s + beta * *c;
        }
        filt(&sc.filter, &mut sc.c);
        iterations += 1;
    }
    let residual = if delta0 > 0.0 {
        (delta.max(0.0) / delta0).sqrt() as f32
    } else {
        0.0
    };
    *cg = CgStats {
        iterations,
        residual,
        converged: delta <= tol2 * delta0,
    };

    // Constraint impulses e = A·Δv − b on contacts, for friction.
    sc.multiply(ctx, diag, &sc.dv, &mut q);
    sc.q = q;
    let p = &mut *ctx.particles;
    for i in 0..n {
        let mut v_new = p.velocity[i] + sc.dv[i];
        if let Filter::Normal(nrm, ci) = sc.filter[i] {
            let col = &ctx.colliders[ci as usize];
            let impulse = (sc.q[i] - sc.rhs[i]).dot(nrm).max(0.0);
            let dvn = impulse * p.inv_mass[i];
            let v_rel = v_new - col.velocity_at(p.position[i]);
            let vt = v_rel - v_rel.dot(nrm) * nrm;
            let vt_len = vt.length();
            let fr = col.friction;
            let vt_new = if vt_len <= fr.static_coefficient * dvn {
                Vec3::ZERO
            } else {
                vt * (1.0 - fr.kinetic_coefficient * dvn / vt_len).max(0.0)
            };
            v_new += vt_new - vt;
        }
        p.velocity[i] = v_new;
        p.position[i] += h * v_new;
    }
    resolve_contacts(ctx.colliders, p, h, ctx.contacts);
    let constrained = sc
        .filter
        .iter()
        .filter(|f| matches!(f, Filter::Normal(..)))
        .count();
    ctx.contacts.contacts += constrained as u32;
}
