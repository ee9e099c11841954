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
//! - Coulomb friction is decided before the solve and enforced in it (`constrain`): from the
//!   particle's own row, the contact's normal impulse e and the tangential load ℓ that would
//!   stop it; a contact with |ℓ| ≤ μ_s·e sticks (all three directions fixed at the collider's
//!   velocity, so the solve moves its neighbours around a particle that does not slide), any
//!   other slides with the kinetic impulse −μ_k·e·ℓ/|ℓ| in its right-hand side.
//! - The CG stops at `tolerance` times the larger of the right-hand side and one substep's
//!   gravity impulse on the cloth (both in the preconditioned norm; [`gravity_term`]).
//! - Contact pushes, never pulls: after the solve, a contact whose constraint impulse
//!   c = A·Δv − b pulls its particle in (c·n < 0) is released, and the solve runs again from
//!   its Δv within the substep's iteration cap ([`release`]), so that a cloth can be lifted
//!   off a surface.
//! - Particles that newly reach a collider during the substep are projected out with the
//!   shared contact response.
//!
//! **Parallel and deterministic.** Every pass runs on the current rayon pool over a fixed
//! partition ([`PARTICLES_PER_TASK`] particles or [`SPRINGS_PER_TASK`] springs per task), so
//! the bits never depend on the thread count or the schedule:
//! - a product A·p is two passes: each spring's S·(p_a − p_b) into a per-spring array, then
//!   each particle's sum over its incident springs in spring order (a list built once per
//!   cloth), which adds the same terms in the same order as a sequential scatter would;
//! - the assembly of the right-hand side and of the preconditioner is split the same way, and
//!   so are the forces ([`crate::forces::accumulate`]'s terms: each spring's force and each
//!   triangle's air share, then each particle's sum in the sequential scatter's order, so the
//!   same bits);
//! - a dot product is accumulated in f64 within each task, and the tasks' partial sums are
//!   added in task order.

use glam::{Mat3, Vec3};
use rayon::prelude::*;

pub(crate) mod grid;

use super::SubstepCtx;
use crate::collide::{Collider, resolve_contacts_in};
use crate::config::SimConfig;
use crate::forces::{ZERO_LENGTH_SQUARED, air_share, body_forces, capped_damping, spring_force};
use crate::particles::Particles;
use crate::topology::{Spring, SpringKind, Topology};

/// Particles per task of the parallel passes over particles (a fixed partition).
const PARTICLES_PER_TASK: usize = 1024;
/// Springs per task of the parallel passes over springs (a fixed partition).
const SPRINGS_PER_TASK: usize = 4096;

/// Per-particle velocity filter of the modified CG.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
enum Filter {
    /// Unconstrained.
    #[default]
    Free,
    /// All three directions fixed (pinned).
    Fixed,
    /// The normal direction fixed (a contact with outward normal n).
    Normal(Vec3),
    /// All three directions fixed at the collider's velocity (a contact with outward normal n
    /// that static friction holds).
    Stuck(Vec3),
}

impl Filter {
    /// The contact's outward normal, if the particle is a contact.
    #[inline]
    fn normal(self) -> Option<Vec3> {
        match self {
            Filter::Normal(n) | Filter::Stuck(n) => Some(n),
            Filter::Free | Filter::Fixed => None,
        }
    }

    #[inline]
    fn apply(self, p: Vec3) -> Vec3 {
        match self {
            Filter::Free => p,
            Filter::Fixed | Filter::Stuck(_) => Vec3::ZERO,
            Filter::Normal(n) => p - n.dot(p) * n,
        }
    }
}

/// A symmetric 3×3 block: its diagonal and its entries above it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Sym3 {
    diag: Vec3,
    /// (xy, xz, yz).
    upper: Vec3,
}

impl Sym3 {
    /// d·dᵀ.
    #[inline]
    fn outer(d: Vec3) -> Self {
        Self {
            diag: d * d,
            upper: Vec3::new(d.x * d.y, d.x * d.z, d.y * d.z),
        }
    }

    #[inline]
    fn mul(self, p: Vec3) -> Vec3 {
        let (a, u) = (self.diag, self.upper);
        Vec3::new(
            a.x * p.x + u.x * p.y + u.y * p.z,
            u.x * p.x + a.y * p.y + u.z * p.z,
            u.y * p.x + u.z * p.y + a.z * p.z,
        )
    }

    fn to_mat3(self) -> Mat3 {
        let (a, u) = (self.diag, self.upper);
        Mat3::from_cols(
            Vec3::new(a.x, u.x, u.y),
            Vec3::new(u.x, a.y, u.z),
            Vec3::new(u.y, u.z, a.z),
        )
    }
}

impl std::ops::Add for Sym3 {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        Self {
            diag: self.diag + o.diag,
            upper: self.upper + o.upper,
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
    /// Whether the solve's dot products overflowed (forces beyond what an f32 solve holds:
    /// its Δv is then meaningless, and the step fails).
    pub overflowed: bool,
}

impl CgStats {
    /// The figures of a solve that stopped after `iterations` at δ = rᵀP⁻¹r, against
    /// δ0 = bᵀP⁻¹b and the squared tolerance `tol2`.
    fn new(iterations: u32, delta: f64, delta0: f64, tol2: f64) -> Self {
        let residual = if delta0 > 0.0 {
            (delta.max(0.0) / delta0).sqrt() as f32
        } else {
            0.0
        };
        Self {
            iterations,
            residual,
            converged: delta <= tol2 * delta0,
            overflowed: !(delta.is_finite() && delta0.is_finite()),
        }
    }
}

/// The contacts the substep's new positions reached, projected out with the shared contact
/// response (particles on their own, in parallel tasks); returns the number of particles in
/// contact: those `constrained` in the solve (by global index) and those projected here, each
/// counted once.
fn new_contacts(
    p: &mut Particles,
    colliders: &[Collider],
    h: f32,
    constrained: impl Fn(usize) -> bool + Sync,
) -> u32 {
    p.position
        .par_chunks_mut(PARTICLES_PER_TASK)
        .zip(p.velocity.par_chunks_mut(PARTICLES_PER_TASK))
        .zip(p.inv_mass.par_chunks(PARTICLES_PER_TASK))
        .enumerate()
        .map(|(task, ((x, v), w))| {
            let base = task * PARTICLES_PER_TASK;
            let mut count = 0;
            for j in 0..x.len() {
                let (x, v, w) = (&mut x[j..=j], &mut v[j..=j], &w[j..=j]);
                let hit = resolve_contacts_in(colliders, x, v, w, h) > 0;
                count += u32::from(hit || constrained(base + j));
            }
            count
        })
        .sum()
}

/// Scratch of the implicit solver, sized once per cloth.
#[derive(Debug, Clone, Default)]
pub(crate) struct ImplicitScratch {
    /// Per spring: S = h·c·d·dᵀ + h²·K.
    block: Vec<Sym3>,
    /// Per spring: h²·K·(v_b − v_a) during the assembly, then S·(p_a − p_b) in each product.
    term: Vec<Vec3>,
    /// Incident springs of every particle, built once per cloth.
    incident: Incident,
    /// Incident triangles of every particle, built once per cloth (for the air).
    triangles: Incident,
    /// Per spring: its force on its first end ([`spring_force`]).
    spring_force: Vec<Option<Vec3>>,
    /// Per triangle: the share of its air force each corner takes ([`air_share`]).
    air: Vec<Vec3>,
    /// Inverse of each particle's diagonal block (the preconditioner).
    precond: Vec<Mat3>,
    filter: Vec<Filter>,
    /// Per particle: the kinetic friction impulse taken out of `rhs` ([`constrain`]).
    friction: Vec<Vec3>,
    rhs: Vec<Vec3>,
    dv: Vec<Vec3>,
    r: Vec<Vec3>,
    c: Vec<Vec3>,
    q: Vec<Vec3>,
    s: Vec<Vec3>,
    /// The terms of a dot product, one per particle (summed by [`reduce`]).
    dots: Vec<f32>,
    /// One partial sum of a dot product per task.
    partial: Vec<f64>,
    /// The grid path's scratch.
    grid: grid::GridScratch,
}

/// Sizes `v` for `n` entries. Nothing is cleared: every pass writes the entries it later reads,
/// so a substep on the same cloth neither allocates nor fills its scratch again.
fn resize(v: &mut Vec<Vec3>, n: usize) {
    v.resize(n, Vec3::ZERO);
}

/// The signed sum `acc + Σ ±term[s]` over the springs of `list` (+ where the particle is the
/// spring's first end), in the list's order.
#[inline]
fn gather(list: &[u32], term: &[Vec3], mut acc: Vec3) -> Vec3 {
    for &e in list {
        let t = term[(e >> 1) as usize];
        if e & 1 == 0 {
            acc += t;
        } else {
            acc -= t;
        }
    }
    acc
}

/// Accumulators of a task's sum.
const SUM_LANES: usize = 16;

/// The sum of the per-particle values `d` (the terms of a dot product), in f64 and in a
/// fixed order whatever the thread count: within each task of [`PARTICLES_PER_TASK`]
/// particles, entry k goes to accumulator k mod [`SUM_LANES`] and the accumulators are added
/// in order; then the tasks' sums (`partial`, one per task) are added in task order. Both
/// paths sum their dot products with it (so the grid path's sums are the reference's).
pub(super) fn reduce(d: &[f32], partial: &mut [f64]) -> f64 {
    partial
        .par_iter_mut()
        .zip(d.par_chunks(PARTICLES_PER_TASK))
        .for_each(|(p, d)| *p = task_sum(d));
    partial.iter().sum()
}

/// One task's sum in [`reduce`] (`d`: the task's values, at most [`PARTICLES_PER_TASK`]).
#[inline]
pub(super) fn task_sum(d: &[f32]) -> f64 {
    let mut acc = [0.0f64; SUM_LANES];
    let mut lanes = d.chunks_exact(SUM_LANES);
    for lane in &mut lanes {
        for (a, &x) in acc.iter_mut().zip(lane) {
            *a += f64::from(x);
        }
    }
    for (a, &x) in acc.iter_mut().zip(lanes.remainder()) {
        *a += f64::from(x);
    }
    acc.iter().sum()
}

/// The springs (or triangles) incident to every particle, in their order: those of particle
/// i are `list[start[i]..start[i + 1]]`; a spring as `spring << 1`, plus 1 when the particle
/// is its second end ([`Incident::springs`]), a triangle as its index
/// ([`Incident::triangles`]).
#[derive(Debug, Clone, Default)]
struct Incident {
    start: Vec<u32>,
    list: Vec<u32>,
}

impl Incident {
    /// The springs' lists, built when the cloth changed.
    fn springs(&mut self, n: usize, springs: &[Spring]) {
        self.build(
            n,
            springs.len(),
            |j| [springs[j].a, springs[j].b],
            |j, end| (j as u32) << 1 | end as u32,
        );
    }

    /// The triangles' lists, built when the cloth changed (a triangle is listed once per
    /// corner).
    fn triangles(&mut self, n: usize, triangles: &[[u32; 3]]) {
        self.build(n, triangles.len(), |j| triangles[j], |j, _| j as u32);
    }

    /// Builds the lists of `count` items whose particles are `item(j)`, each listed as
    /// `code(j, corner)`, when the cloth changed: a counting sort by particle, so every list
    /// comes out in the items' order (an item's corners in their order).
    fn build<const K: usize>(
        &mut self,
        n: usize,
        count: usize,
        item: impl Fn(usize) -> [u32; K],
        code: impl Fn(usize, usize) -> u32,
    ) {
        if self.start.len() == n + 1 && self.list.len() == K * count {
            return;
        }
        self.start.clear();
        self.start.resize(n + 1, 0);
        for j in 0..count {
            for i in item(j) {
                self.start[i as usize + 1] += 1;
            }
        }
        for i in 0..n {
            self.start[i + 1] += self.start[i];
        }
        self.list.clear();
        self.list.resize(K * count, 0);
        let mut next: Vec<u32> = self.start[..n].to_vec();
        for j in 0..count {
            for (corner, i) in item(j).into_iter().enumerate() {
                let slot = &mut next[i as usize];
                self.list[*slot as usize] = code(j, corner);
                *slot += 1;
            }
        }
    }

    /// The incident springs of particle `i`.
    #[inline]
    fn of(&self, i: usize) -> &[u32] {
        &self.list[self.start[i] as usize..self.start[i + 1] as usize]
    }
}

impl ImplicitScratch {
    /// The forces of [`crate::forces::accumulate`], with the same bits, in parallel passes: each
    /// spring's force and each triangle's air share first, then each particle's sum of its
    /// gravity and damping, its springs' forces in spring order and its triangles' shares in
    /// triangle order (the incidence lists): the terms and the order of the sequential
    /// scatter.
    /// `kinds`: the springs' coefficients ([`KindParams::of`]).
    fn forces(&mut self, ctx: &SubstepCtx<'_>, kinds: &KindParams, force: &mut [Vec3]) {
        let (cfg, topology, p) = (ctx.config, ctx.topology, &*ctx.particles);
        let n = p.len();
        let springs = topology.springs();
        self.incident.springs(n, springs);
        let air = super::grid_kernel::air_active(cfg);
        if air {
            self.triangles.triangles(n, topology.triangles());
        }
        let (x, v) = (&p.position, &p.velocity);
        self.spring_force.resize(springs.len(), None);
        self.spring_force
            .par_chunks_mut(SPRINGS_PER_TASK)
            .zip(springs.par_chunks(SPRINGS_PER_TASK))
            .enumerate()
            .for_each(|(task, (out, chunk))| {
                let base = task * SPRINGS_PER_TASK;
                for (j, (out, s)) in out.iter_mut().zip(chunk).enumerate() {
                    let (k, c) = kinds.get(base + j);
                    let (a, b) = (s.a as usize, s.b as usize);
                    *out = if k == 0.0 && c == 0.0 {
                        None
                    } else {
                        spring_force([x[a], x[b], v[a], v[b]], s.rest_length, k, c)
                    };
                }
            });
        let triangles = topology.triangles();
        let wind = ctx.wind;
        if air {
            resize(&mut self.air, triangles.len());
            self.air
                .par_chunks_mut(SPRINGS_PER_TASK)
                .zip(triangles.par_chunks(SPRINGS_PER_TASK))
                .for_each(|(out, chunk)| {
                    for (out, &tri) in out.iter_mut().zip(chunk) {
                        *out = air_share(cfg, x, v, wind, tri);
                    }
                });
        }
        let (gravity, damping) = body_forces(cfg);
        let (incident, tris) = (&self.incident, &self.triangles);
        let (spring_force, shares) = (&self.spring_force, &self.air);
        force
            .par_chunks_mut(PARTICLES_PER_TASK)
            .enumerate()
            .for_each(|(task, out)| {
                let base = task * PARTICLES_PER_TASK;
                for (k, out) in out.iter_mut().enumerate() {
                    let i = base + k;
                    let m = p.mass[i];
                    let mut f = m * gravity - capped_damping(damping, m, f32::INFINITY) * v[i];
                    for &e in incident.of(i) {
                        if let Some(t) = spring_force[(e >> 1) as usize] {
                            if e & 1 == 0 {
                                f += t;
                            } else {
                                f -= t;
                            }
                        }
                    }
                    if air {
                        for &t in tris.of(i) {
                            f += shares[t as usize];
                        }
                    }
                    *out = f;
                }
            });
    }

    /// `term[s] = S_s·(p_a − p_b)` for every spring.
    fn spring_products(&mut self, springs: &[Spring], p: &[Vec3]) {
        self.term
            .par_chunks_mut(SPRINGS_PER_TASK)
            .zip(springs.par_chunks(SPRINGS_PER_TASK))
            .zip(self.block.par_chunks(SPRINGS_PER_TASK))
            .for_each(|((term, springs), block)| {
                for ((t, s), b) in term.iter_mut().zip(springs).zip(block) {
                    *t = b.mul(p[s.a as usize] - p[s.b as usize]);
                }
            });
    }

    /// `self.q = A·Δv` (unfiltered) for the Δv in `self.dv`.
    fn product_of_dv(&mut self, ctx: &SubstepCtx<'_>, diag: f32) {
        let mut q = std::mem::take(&mut self.q);
        let dv = std::mem::take(&mut self.dv);
        self.multiply(ctx, diag, &dv, &mut q, false);
        (self.q, self.dv) = (q, dv);
    }

    /// Modified PCG (Baraff & Witkin 1998, §5.3) on the filters in `self.filter`, from the Δv
    /// in `self.dv` with its product A·Δv in `self.q` ([`Self::product_of_dv`]), to
    /// `tolerance` of the larger of the filtered right-hand side and `floor` (δ = rᵀ·P·r), in
    /// at most `cap` iterations; returns the iterations, δ and that δ0.
    fn pcg(
        &mut self,
        ctx: &SubstepCtx<'_>,
        diag: f32,
        floor: f64,
        tolerance: f32,
        cap: u32,
    ) -> (u32, f64, f64) {
        // δ0 from the filtered, preconditioned right-hand side: s = filter(b), c = P·s.
        self.s
            .par_chunks_mut(PARTICLES_PER_TASK)
            .zip(self.c.par_chunks_mut(PARTICLES_PER_TASK))
            .zip(self.rhs.par_chunks(PARTICLES_PER_TASK))
            .zip(self.precond.par_chunks(PARTICLES_PER_TASK))
            .zip(self.filter.par_chunks(PARTICLES_PER_TASK))
            .zip(self.dots.par_chunks_mut(PARTICLES_PER_TASK))
            .for_each(|(((((s, c), b), m), f), dots)| {
                for (((((s, c), b), m), f), dot) in
                    s.iter_mut().zip(c).zip(b).zip(m).zip(f).zip(dots)
                {
                    *s = f.apply(*b);
                    *c = *m * *s;
                    *dot = s.dot(*c);
                }
            });
        let delta0 = reduce(&self.dots, &mut self.partial).max(floor);
        // r = filter(b − A·Δv), c = filter(P·r).
        let mut q = std::mem::take(&mut self.q);
        self.r
            .par_chunks_mut(PARTICLES_PER_TASK)
            .zip(self.c.par_chunks_mut(PARTICLES_PER_TASK))
            .zip(self.rhs.par_chunks(PARTICLES_PER_TASK))
            .zip(q.par_chunks(PARTICLES_PER_TASK))
            .zip(self.precond.par_chunks(PARTICLES_PER_TASK))
            .zip(self.filter.par_chunks(PARTICLES_PER_TASK))
            .zip(self.dots.par_chunks_mut(PARTICLES_PER_TASK))
            .for_each(|((((((r, c), b), aq), m), f), dots)| {
                for ((((((r, c), b), aq), m), f), dot) in
                    r.iter_mut().zip(c).zip(b).zip(aq).zip(m).zip(f).zip(dots)
                {
                    *r = f.apply(*b - *aq);
                    *c = f.apply(*m * *r);
                    *dot = r.dot(*c);
                }
            });
        let mut delta = reduce(&self.dots, &mut self.partial);
        let tol2 = f64::from(tolerance) * f64::from(tolerance);
        let mut iterations = 0;
        while delta > tol2 * delta0 && iterations < cap {
            // q = filter(A·c), c·q.
            let c = std::mem::take(&mut self.c);
            let cq = self.multiply(ctx, diag, &c, &mut q, true);
            self.c = c;
            if cq <= 0.0 {
                break;
            }
            let alpha = (delta / cq) as f32;
            // Δv += α·c, r −= α·q, s = P·r, r·s.
            self.dv
                .par_chunks_mut(PARTICLES_PER_TASK)
                .zip(self.r.par_chunks_mut(PARTICLES_PER_TASK))
                .zip(self.s.par_chunks_mut(PARTICLES_PER_TASK))
                .zip(self.c.par_chunks(PARTICLES_PER_TASK))
                .zip(q.par_chunks(PARTICLES_PER_TASK))
                .zip(self.precond.par_chunks(PARTICLES_PER_TASK))
                .zip(self.dots.par_chunks_mut(PARTICLES_PER_TASK))
                .for_each(|((((((dv, r), s), c), q), m), dots)| {
                    for ((((((dv, r), s), c), q), m), dot) in
                        dv.iter_mut().zip(r).zip(s).zip(c).zip(q).zip(m).zip(dots)
                    {
                        *dv += alpha * *c;
                        *r -= alpha * *q;
                        *s = *m * *r;
                        *dot = r.dot(*s);
                    }
                });
            let delta_old = delta;
            delta = reduce(&self.dots, &mut self.partial);
            let beta = (delta / delta_old) as f32;
            // c = filter(s + β·c).
            self.c
                .par_chunks_mut(PARTICLES_PER_TASK)
                .zip(self.s.par_chunks(PARTICLES_PER_TASK))
                .zip(self.filter.par_chunks(PARTICLES_PER_TASK))
                .for_each(|((c, s), f)| {
                    for ((c, s), f) in c.iter_mut().zip(s).zip(f) {
                        *c = f.apply(*s + beta * *c);
                    }
                });
            iterations += 1;
        }
        self.q = q;
        (iterations, delta, delta0)
    }

    /// y = A·p (`filtered`: then y is filtered too); returns p·y.
    fn multiply(
        &mut self,
        ctx: &SubstepCtx<'_>,
        diag: f32,
        p: &[Vec3],
        y: &mut [Vec3],
        filtered: bool,
    ) -> f64 {
        self.spring_products(ctx.topology.springs(), p);
        let (incident, term, filter) = (&self.incident, &self.term, &self.filter);
        let mass = &ctx.particles.mass;
        y.par_chunks_mut(PARTICLES_PER_TASK)
            .zip(self.dots.par_chunks_mut(PARTICLES_PER_TASK))
            .enumerate()
            .for_each(|(task, (y, dots))| {
                let base = task * PARTICLES_PER_TASK;
                for (k, (y, dot)) in y.iter_mut().zip(dots).enumerate() {
                    let i = base + k;
                    let mut v = gather(incident.of(i), term, (mass[i] + diag) * p[i]);
                    if filtered {
                        v = filter[i].apply(v);
                    }
                    *y = v;
                    *dot = p[i].dot(v);
                }
            });
        reduce(&self.dots, &mut self.partial)
    }
}

/// The stiffness and damping coefficient of a spring kind, N/m and N·s/m, with the force
/// switches applied.
fn spring_params(cfg: &SimConfig, kind: SpringKind) -> (f32, f32) {
    let p = cfg.material.params(kind);
    let k = if cfg.forces.springs { p.stiffness } else { 0.0 };
    let c = if cfg.forces.dashpots { p.damping } else { 0.0 };
    (k, c)
}

/// The stiffness and damping coefficient of every spring of a topology's list, kind by kind
/// ([`spring_params`]): each kind's end in the list and its coefficients.
struct KindParams([(usize, f32, f32); 4]);

impl KindParams {
    fn of(cfg: &SimConfig, topology: &Topology) -> Self {
        let mut kinds = [(0usize, 0.0f32, 0.0f32); 4];
        let mut end = 0;
        for (slot, kind) in kinds.iter_mut().zip(SpringKind::ALL) {
            end += topology.springs_of(kind).len();
            let (k, c) = spring_params(cfg, kind);
            *slot = (end, k, c);
        }
        Self(kinds)
    }

    /// The coefficients of spring `j` of the list.
    #[inline]
    fn get(&self, j: usize) -> (f32, f32) {
        let (_, k, c) = self.0[self.0.iter().position(|e| j < e.0).unwrap_or(3)];
        (k, c)
    }
}

/// One spring's block S = h·c·d·dᵀ + h²·K and its term h²·K·(v_b − v_a) of the right-hand
/// side (both zero for a spring of zero length, or with neither stiffness nor damping).
#[inline]
#[allow(clippy::too_many_arguments)]
fn assemble(
    xa: Vec3,
    xb: Vec3,
    va: Vec3,
    vb: Vec3,
    rest: f32,
    k: f32,
    c: f32,
    h: f32,
) -> (Sym3, Vec3) {
    let l = xb - xa;
    let len2 = l.length_squared();
    // Zero length as `forces::spring_force` sees it.
    if len2 < ZERO_LENGTH_SQUARED || (k == 0.0 && c == 0.0) {
        return (Sym3::default(), Vec3::ZERO);
    }
    let len = len2.sqrt();
    let d = l / len;
    let dd = Sym3::outer(d);
    let geometric = (1.0 - rest / len).max(0.0);
    // K = k·(d·dᵀ + g·(I − d·dᵀ)).
    let stiff = Sym3 {
        diag: k * (dd.diag + geometric * (Vec3::ONE - dd.diag)),
        upper: k * (dd.upper - geometric * dd.upper),
    };
    let term = (h * h) * stiff.mul(vb - va);
    let block = Sym3 {
        diag: (h * c) * dd.diag + (h * h) * stiff.diag,
        upper: (h * c) * dd.upper + (h * h) * stiff.upper,
    };
    (block, term)
}

/// A particle's filter and the start of its Δv, with Coulomb friction in the solve.
///
/// - Pinned: fixed.
/// - Touching a collider at rest (see the substep's stage 2): its normal velocity
///   constrained to the collider's. With friction, the contact's normal impulse over the
///   substep is estimated from the particle's own row of the system, uncoupled from its
///   neighbours: e = max(0, −m̃·v_n − b·n), with m̃ = m + h·d the row's mass and v_n the
///   relative normal velocity (the impulse that holds the normal velocity against the
///   approach and the forces pressing the particle in). The tangential impulse that would
///   stop the particle relative to the collider is the load ℓ = m̃·v_t + b_t. Coulomb's law:
///   - |ℓ| ≤ μ_s·e: it sticks, [`Filter::Stuck`] with Δv = −v_rel, so that the solve moves
///     its neighbours against a particle that does not slide;
///   - otherwise it slides, and kinetic friction −μ_k·e·ℓ/|ℓ| is added to its `b` (the
///     normal stays constrained); `friction` returns μ_k·e·ℓ/|ℓ| (zero otherwise), for
///     [`release`].
/// - Otherwise free.
///
/// Friction was a velocity filter after the solve (Bridson et al. 2002) before this: the
/// solve then moved a stuck particle's neighbours as if it slid, and a cloth held by friction
/// stretched a little more every substep (151 % in the 128² drape at 2 substeps).
#[inline]
#[allow(clippy::too_many_arguments)]
fn constrain(
    x: Vec3,
    v: Vec3,
    mass: f32,
    inv_mass: f32,
    b: &mut Vec3,
    friction: &mut Vec3,
    colliders: &[Collider],
    h: f32,
    g_h: f32,
) -> (Filter, Vec3) {
    *friction = Vec3::ZERO;
    if inv_mass == 0.0 {
        return (Filter::Fixed, Vec3::ZERO);
    }
    for col in colliders {
        let (dist, nrm) = col.shape.distance_within(x, col.contact_range());
        let slack = 0.1 * col.thickness + 1e-5 + g_h * h;
        if dist - col.thickness < slack {
            let v_rel = v - col.velocity_at(x);
            let vn = v_rel.dot(nrm);
            if vn <= g_h {
                let fr = col.friction;
                if fr.static_coefficient > 0.0 || fr.kinetic_coefficient > 0.0 {
                    let bn = b.dot(nrm);
                    let e = (-mass * vn - bn).max(0.0);
                    let load = mass * (v_rel - vn * nrm) + (*b - bn * nrm);
                    let load_len = load.length();
                    if load_len <= fr.static_coefficient * e {
                        return (Filter::Stuck(nrm), -v_rel);
                    }
                    // load_len > μ_s·e ≥ 0 here.
                    *friction = (fr.kinetic_coefficient * e / load_len) * load;
                    *b -= *friction;
                }
                // Δv·n = −v_rel·n: the new normal velocity equals the collider's.
                return (Filter::Normal(nrm), -vn * nrm);
            }
        }
    }
    (Filter::Free, Vec3::ZERO)
}

/// Releases a contact whose constraint pulled its particle onto the collider: with `aq` the
/// particle's row of A·Δv after the solve, the constraint's impulse is c = A·Δv − b, and where
/// c·n < 0 (the springs pull the particle off harder than its approach and the forces on it
/// press it on) the particle becomes free and its kinetic `friction` (there is no normal
/// force to carry it) is taken back out of `b`. Returns whether it was released.
///
/// Without it a resting contact let go only when its particle moved away, which the
/// constraint itself prevents: a cloth lying on the ground could not be lifted (a corner
/// raised at 0.6 m/s tore a spring to 10× its length in 26 steps while its neighbours stayed
/// on the ground).
#[inline]
fn release(filter: &mut Filter, b: &mut Vec3, friction: Vec3, aq: Vec3) -> bool {
    match filter.normal() {
        Some(n) if (aq - *b).dot(n) < 0.0 => {
            *filter = Filter::Free;
            *b += friction;
            true
        }
        _ => false,
    }
}

/// A particle's share of the CG's floor: its gravity impulse over the substep, g·h·m, in the
/// preconditioned norm (gᵀ·P·g with g = h·m·gravity); zero for a pinned particle.
///
/// The solve stops when its residual is `tolerance` times the larger of the right-hand side
/// and this impulse summed over the cloth (both in the norm of δ = rᵀ·P·r). A purely relative
/// stop asks a settled cloth, whose right-hand side is almost zero, for an absolute accuracy
/// a hundred times finer than a falling one's: in the 128² drape at 2 substeps, δ0 falls to
/// a hundredth of the free fall's once draped, and the solve ran 230–300 iterations instead of
/// 60–90.
#[inline]
fn gravity_term(gravity: Vec3, h: f32, mass: f32, inv_mass: f32, precond: Mat3) -> f32 {
    if inv_mass == 0.0 {
        return 0.0;
    }
    let g = gravity * (h * mass);
    g.dot(precond * g)
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
    let kinds = KindParams::of(cfg, ctx.topology);
    sc.forces(ctx, &kinds, force);
    if crate::simd::kernel() != crate::simd::Kernel::Reference && grid::applies(ctx.topology) {
        grid::substep(ctx, force, &mut sc.grid, cg);
        return;
    }

    let springs = ctx.topology.springs();
    let tasks = n.div_ceil(PARTICLES_PER_TASK);
    // Sized, not cleared (see `resize`).
    sc.partial.resize(tasks, 0.0);
    sc.dots.resize(n, 0.0);
    sc.block.resize(springs.len(), Sym3::default());
    resize(&mut sc.term, springs.len());
    for v in [
        &mut sc.friction,
        &mut sc.rhs,
        &mut sc.dv,
        &mut sc.r,
        &mut sc.c,
        &mut sc.q,
        &mut sc.s,
    ] {
        resize(v, n);
    }
    sc.precond.resize(n, Mat3::ZERO);
    sc.filter.resize(n, Filter::Free);

    // 1. The spring blocks S and the terms h²·K·(v_b − v_a) of b = h·f + h²·(∂f/∂x)·v.
    let diag = if cfg.forces.damping {
        h * cfg.damping
    } else {
        0.0
    };
    {
        let (x, v) = (&ctx.particles.position, &ctx.particles.velocity);
        sc.block
            .par_chunks_mut(SPRINGS_PER_TASK)
            .zip(sc.term.par_chunks_mut(SPRINGS_PER_TASK))
            .zip(springs.par_chunks(SPRINGS_PER_TASK))
            .enumerate()
            .for_each(|(task, ((block, term), chunk))| {
                let base = task * SPRINGS_PER_TASK;
                for (j, ((block, term), s)) in block.iter_mut().zip(term).zip(chunk).enumerate() {
                    let (k, c) = kinds.get(base + j);
                    let (a, b) = (s.a as usize, s.b as usize);
                    (*block, *term) = assemble(x[a], x[b], v[a], v[b], s.rest_length, k, c, h);
                }
            });
    }

    // 2. Per particle: the right-hand side, the preconditioner, the filter (pins fixed,
    // resting contacts constrained along their normal) and the start of Δv. A contact counts
    // as resting when the particle is within the slack of the contact surface (plus the
    // distance gravity pulls it in one substep) and leaves it slower than gravity would stop
    // it within the substep: otherwise it would fall back in during the substep and be
    // projected out afterwards, a hop that never settles.
    let gravity = if cfg.forces.gravity {
        cfg.gravity
    } else {
        Vec3::ZERO
    };
    let g_h = gravity.length() * h;
    {
        let (incident, term, block) = (&sc.incident, &sc.term, &sc.block);
        let p = &*ctx.particles;
        let colliders = ctx.colliders;
        let force = &*force;
        sc.rhs
            .par_chunks_mut(PARTICLES_PER_TASK)
            .zip(sc.precond.par_chunks_mut(PARTICLES_PER_TASK))
            .zip(sc.filter.par_chunks_mut(PARTICLES_PER_TASK))
            .zip(sc.dv.par_chunks_mut(PARTICLES_PER_TASK))
            .zip(sc.dots.par_chunks_mut(PARTICLES_PER_TASK))
            .zip(sc.friction.par_chunks_mut(PARTICLES_PER_TASK))
            .enumerate()
            .for_each(
                |(task, (((((rhs, precond), filter), dv), dots), friction))| {
                    let base = task * PARTICLES_PER_TASK;
                    for (k, (((((rhs, precond), filter), dv), dot), friction)) in rhs
                        .iter_mut()
                        .zip(precond)
                        .zip(filter)
                        .zip(dv)
                        .zip(dots)
                        .zip(friction)
                        .enumerate()
                    {
                        let i = base + k;
                        let list = incident.of(i);
                        *rhs = gather(list, term, h * force[i]);
                        let mut sum = Sym3 {
                            diag: Vec3::splat(p.mass[i] + diag),
                            upper: Vec3::ZERO,
                        };
                        for &e in list {
                            sum = sum + block[(e >> 1) as usize];
                        }
                        *precond = sum.to_mat3().inverse();
                        *dot = gravity_term(gravity, h, p.mass[i], p.inv_mass[i], *precond);
                        (*filter, *dv) = constrain(
                            p.position[i],
                            p.velocity[i],
                            p.mass[i] + diag,
                            p.inv_mass[i],
                            rhs,
                            friction,
                            colliders,
                            h,
                            g_h,
                        );
                    }
                },
            );
    }

    let floor = reduce(&sc.dots, &mut sc.partial);

    // 3. Modified PCG (Baraff & Witkin 1998, §5.3).
    sc.product_of_dv(ctx, diag);
    let (mut iterations, mut delta, mut delta0) = sc.pcg(
        ctx,
        diag,
        floor,
        settings.tolerance,
        settings.max_iterations,
    );

    // 4. Contacts that pull: the impulse a contact's constraint supplied, c = A·Δv − b, pulls
    // the particle onto the collider where c·n < 0; those contacts are released (free, and
    // their kinetic friction taken back out of b) and the solve runs again from its Δv, once
    // ([`release`]). The second solve starts from this product: Δv and A are unchanged.
    sc.product_of_dv(ctx, diag);
    let released: u32 = sc
        .filter
        .par_chunks_mut(PARTICLES_PER_TASK)
        .zip(sc.rhs.par_chunks_mut(PARTICLES_PER_TASK))
        .zip(sc.friction.par_chunks(PARTICLES_PER_TASK))
        .zip(sc.q.par_chunks(PARTICLES_PER_TASK))
        .map(|(((filter, rhs), friction), aq)| {
            let mut count = 0;
            for (((f, b), fr), aq) in filter.iter_mut().zip(rhs).zip(friction).zip(aq) {
                count += u32::from(release(f, b, *fr, *aq));
            }
            count
        })
        .sum();
    if released > 0 && iterations < settings.max_iterations {
        let cap = settings.max_iterations - iterations;
        let (more, d, d0) = sc.pcg(ctx, diag, floor, settings.tolerance, cap);
        iterations += more;
        (delta, delta0) = (d, d0);
    }
    let tol2 = f64::from(settings.tolerance) * f64::from(settings.tolerance);
    *cg = CgStats::new(iterations, delta, delta0, tol2);

    // 5. The new velocities and positions (friction was in the solve), then the contacts the
    // substep reached.
    let colliders = ctx.colliders;
    let p = &mut *ctx.particles;
    p.position
        .par_chunks_mut(PARTICLES_PER_TASK)
        .zip(p.velocity.par_chunks_mut(PARTICLES_PER_TASK))
        .zip(sc.dv.par_chunks(PARTICLES_PER_TASK))
        .for_each(|((x, v), dv)| {
            for ((x, v), dv) in x.iter_mut().zip(v).zip(dv) {
                *v += *dv;
                *x += h * *v;
            }
        });
    let filter = &sc.filter;
    ctx.contacts.contacts = new_contacts(p, colliders, h, |i| {
        matches!(filter[i], Filter::Normal(_) | Filter::Stuck(_))
    });
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::{ImplicitScratch, KindParams, SubstepCtx};
    use crate::GridBuilder;
    use crate::collide::ContactStats;
    use crate::config::{SimConfig, SpringParams};
    use crate::forces::accumulate;

    /// The implicit solver's parallel forces are [`accumulate`]'s, bit for bit (both sum the
    /// same terms per particle in the same order: gravity and damping, springs in spring
    /// order, triangles' air shares in triangle order), on 1, 2 and 3 threads, with wind, a
    /// pinned particle, a spring of zero length (no direction: it must add nothing, not NaN)
    /// and a kind switched off. The 40 × 60 cloth is 3 tasks of particles, 4 of springs and 2
    /// of triangles.
    #[test]
    fn parallel_forces_are_accumulate_bit_for_bit() {
        let mut cloth = GridBuilder::new(40, 60).build().expect("a grid");
        let p = &mut cloth.particles;
        for i in 0..p.len() {
            let t = i as f32;
            p.position[i] += Vec3::new(0.01 * (t * 1.3).sin(), 0.02 * (t * 0.7).cos(), 0.0);
            p.velocity[i] = Vec3::new((t * 0.9).cos(), 0.3 * (t * 1.1).sin(), -0.2 * t.sin());
        }
        // Particles 10 and 11 share a weft spring, now of zero length.
        p.position[11] = p.position[10];
        p.inv_mass[0] = 0.0;
        let mut config = SimConfig {
            damping: 0.01,
            ..SimConfig::default()
        };
        config.material.bend = SpringParams::new(0.0, 0.0);
        let wind = Vec3::new(3.0, 0.5, -1.0);
        let mut expected = vec![Vec3::ZERO; p.len()];
        accumulate(&config, &cloth.topology, p, wind, &mut expected);
        let bits = |f: &[Vec3]| -> Vec<[u32; 3]> {
            f.iter().map(|v| v.to_array().map(f32::to_bits)).collect()
        };
        for threads in 1..=3 {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a pool");
            let mut force = vec![Vec3::ZERO; p.len()];
            let mut contacts = ContactStats::default();
            let mut particles = p.clone();
            let ctx = SubstepCtx {
                particles: &mut particles,
                topology: &cloth.topology,
                config: &config,
                colliders: &[],
                wind,
                h: 1e-3,
                contacts: &mut contacts,
                rest: &[],
                pinned: true,
            };
            let kinds = KindParams::of(&config, &cloth.topology);
            pool.install(|| ImplicitScratch::default().forces(&ctx, &kinds, &mut force));
            assert_eq!(bits(&force), bits(&expected), "{threads} threads");
        }
    }
}
