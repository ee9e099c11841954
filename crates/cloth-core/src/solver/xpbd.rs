//! Extended position-based dynamics (XPBD), after Macklin, Müller & Chentanez 2016, with the
//! many-substeps scheme of Macklin et al. 2019, "Small Steps in Physics Simulation".
//!
//! One substep of length h:
//! 1. predict: v ← v + h·(g + f_ext/m) (global damping and air are the external forces; the
//!    damping coefficient capped at m/h, [`crate::forces::capped_damping`], so that it never
//!    reverses a velocity however large it is), x_prev ← x, x ← x + h·v;
//! 2. `iterations` Gauss–Seidel sweeps, each over: every spring as a distance constraint
//!    C = |x_a − x_b| − L0 with compliance α = 1/k (so a material gives the same cloth as with
//!    the force-based integrators) and the dashpot as XPBD constraint damping β = c, in the
//!    fixed storage order (kind by kind, row-major) — with `XpbdSettings::chains` on a grid,
//!    shear and bend first and then the warp and weft as whole chains ([`super::chains`]);
//!    with `XpbdSettings::shear_chains` on a grid, the shear springs as chains along the
//!    grid's diagonal lines, in their place in the order; then the optional long-range
//!    tethers; then collider contacts as position constraints
//!    with position-level Coulomb friction;
//! 3. velocities from positions: v ← v + (x − x_pred)/h, with x_pred = x_prev + h·v the
//!    prediction recomputed with its own rounding: (x − x_prev)/h in exact arithmetic, without
//!    the f32 rounding of x_pred (which (x − x_prev)/h makes a velocity drift of
//!    ulp(|x|)/(2h), growing with the distance from the origin and the substeps).
//!
//! The sweep order is fixed, so results are deterministic. Springs of one kind on a grid
//! touch each particle at most twice per row parity, which is what a later graph-colouring
//! (parallel) sweep needs; the storage is already grouped per kind for it.

use glam::Vec3;

use super::SubstepCtx;
use crate::topology::SpringKind;

/// A long-range attachment: particle `particle` may be at most `max_distance` from the pinned
/// particle `anchor`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Tether {
    pub particle: u32,
    pub anchor: u32,
    pub max_distance: f32,
}

/// Scratch of the XPBD solver.
#[derive(Debug, Clone, Default)]
pub(crate) struct XpbdScratch {
    prev: Vec<Vec3>,
    lambda: Vec<f32>,
    /// Tethers, rebuilt when the set of pinned particles or the slack changes.
    tethers: Vec<Tether>,
    /// The pinned set the tethers were built for.
    tether_key: Vec<u32>,
    /// The `tether_slack` bits the tethers' lengths were built with.
    tether_slack: u32,
    /// Whether `tethers` were built (for `tether_key`; none when nothing is pinned).
    tethers_built: bool,
    /// Multi-resolution strain limits of the reference path: `(a, b, largest distance)`.
    limits: Vec<Tether>,
    /// `(structural limit bits, levels, slack bits, particles)` the limits were built for.
    limits_key: Option<(Option<u32>, u32, u32, usize)>,
    /// The grid path.
    pub(super) grid: super::grid_xpbd::XpbdGrid,
    /// Multipliers of the chain solves (`XpbdSettings::chains`) by class (warp, weft) and
    /// slot, and the one-chain scratch of the reference path.
    chain_lambda: [Vec<f32>; 2],
    chain_scratch: Vec<f32>,
    /// Multipliers of the shear chains (`XpbdSettings::shear_chains`) by direction
    /// (diagonal, anti-diagonal) and slot.
    shear_lambda: [Vec<f32>; 2],
    /// The shear springs' indices in the grid path's row order (`XpbdSettings::shear_rows`),
    /// for the `(springs, rows, cols)` of `shear_order_key`.
    shear_order: Vec<u32>,
    shear_order_key: Option<(usize, usize, usize)>,
}

impl XpbdScratch {
    /// Rebuilds the tethers when the pinned set or the slack changed: every free particle is
    /// tethered to its nearest pinned particle (by rest distance), at that distance times
    /// (1 + slack).
    fn update_tethers(&mut self, ctx: &SubstepCtx<'_>) {
        let rest = ctx.rest;
        let p = &*ctx.particles;
        let pinned = p
            .inv_mass
            .iter()
            .enumerate()
            .filter(|&(_, &w)| w == 0.0)
            .map(|(i, _)| i as u32);
        // The pinned set is compared only when its size is unchanged (a count the compiler
        // vectorises; most cloths keep their pins, and many have none).
        let count = p.inv_mass.iter().filter(|&&w| w == 0.0).count();
        let slack_bits = ctx.config.xpbd.tether_slack.to_bits();
        if self.tethers_built
            && slack_bits == self.tether_slack
            && count == self.tether_key.len()
            && (count == 0 || self.tether_key.iter().copied().eq(pinned.clone()))
        {
            return;
        }
        self.tethers_built = true;
        self.tether_slack = slack_bits;
        self.tether_key.clear();
        self.tether_key.extend(pinned);
        self.tethers.clear();
        if self.tether_key.is_empty() {
            return;
        }
        let slack = 1.0 + ctx.config.xpbd.tether_slack;
        for i in 0..p.len() {
            if p.inv_mass[i] == 0.0 {
                continue;
            }
            let mut best = (f32::INFINITY, 0u32);
            for &a in &self.tether_key {
                let d = rest[i].distance(rest[a as usize]);
                if d < best.0 {
                    best = (d, a);
                }
            }
            self.tethers.push(Tether {
                particle: i as u32,
                anchor: best.1,
                max_distance: best.0 * slack,
            });
        }
    }
}

impl XpbdScratch {
    /// Builds the reference path's strain limits (the same pairs as the grid path's, see
    /// `grid_xpbd`): with `structural_limit`, every structural spring at most (1 + limit)
    /// times its rest distance long (on any cloth); then particles 2, 4, …, 2^levels apart
    /// along the warp and the weft of a grid cloth, at most (1 + slack) times their rest
    /// distance apart (none on a cloth that is not a grid).
    fn update_limits(&mut self, ctx: &SubstepCtx<'_>) {
        let settings = ctx.config.xpbd;
        let n = ctx.particles.len();
        let key = (
            settings.structural_limit.map(f32::to_bits),
            settings.hierarchy_levels,
            settings.hierarchy_slack.to_bits(),
            n,
        );
        if self.limits_key == Some(key) {
            return;
        }
        self.limits_key = Some(key);
        self.limits.clear();
        let rest = ctx.rest;
        if let Some(limit) = settings.structural_limit {
            let scale = 1.0 + limit;
            use crate::topology::SpringKind;
            for kind in [SpringKind::Warp, SpringKind::Weft] {
                for spring in ctx.topology.springs_of(kind) {
                    let (a, b) = (spring.a as usize, spring.b as usize);
                    self.limits.push(Tether {
                        particle: spring.a,
                        anchor: spring.b,
                        max_distance: scale * rest[a].distance(rest[b]),
                    });
                }
            }
        }
        let Some((rows, cols)) = ctx.topology.grid() else {
            return;
        };
        let scale = 1.0 + settings.hierarchy_slack;
        for l in 1..=settings.hierarchy_levels {
            let s = 1_usize << l;
            if s >= rows.max(cols) {
                break;
            }
            for (dr, dc) in [(s, 0), (0, s)] {
                for r in 0..rows.saturating_sub(dr) {
                    for c in 0..cols.saturating_sub(dc) {
                        let (a, b) = (r * cols + c, (r + dr) * cols + c + dc);
                        self.limits.push(Tether {
                            particle: a as u32,
                            anchor: b as u32,
                            max_distance: scale * rest[a].distance(rest[b]),
                        });
                    }
                }
            }
        }
    }

    /// The positions at the start of the last substep.
    pub(super) fn start(&self) -> &[Vec3] {
        &self.prev
    }
}

/// One XPBD substep. With `ccd`, the grid path also runs continuous collision on its arrays
/// and returns `true`; otherwise the caller runs it (from [`XpbdScratch::start`]).
pub(super) fn substep(
    ctx: &mut SubstepCtx<'_>,
    force: &mut [Vec3],
    sc: &mut XpbdScratch,
    hash: &mut crate::collide::self_collision::SelfCollisionScratch,
    ccd: bool,
) -> bool {
    let h = ctx.h;
    let cfg = ctx.config;
    let settings = cfg.xpbd;

    // 1. predict, with external forces (gravity, damping, air) only: on the grid path when it
    //    applies (same bits, rows in parallel).
    let grid = crate::simd::kernel() != crate::simd::Kernel::Reference
        && super::grid_xpbd::applies(cfg, ctx.topology, ctx.pinned)
        && sc.grid.prepare(ctx.topology, ctx.particles.len());
    if grid {
        sc.grid.predict(ctx);
    } else {
        // The grid path keeps the state in its arrays during a step: back to the particles.
        sc.grid.sync(ctx.particles);
        let mut ext = *cfg;
        ext.forces.springs = false;
        ext.forces.dashpots = false;
        // The global damping capped at m/h, so that it never reverses a velocity (XPBD's
        // step is otherwise stable for any h).
        crate::forces::accumulate_capped(
            &ext,
            ctx.topology,
            ctx.particles,
            ctx.wind,
            force,
            1.0 / h,
        );
        sc.prev.clone_from(&ctx.particles.position);
        super::kick_drift(ctx.particles, force, h, h);
    }

    // 2. constraint sweeps: on the grid path when it applies (which it does only when no
    //    tether is needed: nothing pinned, or tethers off).
    if grid {
        // Stages 2 and 3 (and continuous collision), on the arrays.
        sc.grid.sweeps(ctx, ccd);
        return true;
    }
    if settings.tethers {
        sc.update_tethers(ctx);
    }
    reference_sweeps(ctx, sc, hash);

    // 3. velocities from positions (`v` is still the predicted velocity, and x_prev + h·v the
    //    predicted position, as `kick_drift` rounded it).
    let inv_h = 1.0 / h;
    let p = &mut *ctx.particles;
    for ((v, &x), (&x0, &w)) in p
        .velocity
        .iter_mut()
        .zip(&p.position)
        .zip(sc.prev.iter().zip(&p.inv_mass))
    {
        if w != 0.0 {
            *v += (x - (x0 + h * *v)) * inv_h;
        }
    }
    false
}

/// Stage 2 on the reference path: `iterations` sweeps in storage order.
fn reference_sweeps(
    ctx: &mut SubstepCtx<'_>,
    sc: &mut XpbdScratch,
    hash: &mut crate::collide::self_collision::SelfCollisionScratch,
) {
    let h = ctx.h;
    let cfg = ctx.config;
    let settings = cfg.xpbd;
    let limits = settings.hierarchy_levels > 0 || settings.structural_limit.is_some();
    if limits {
        sc.update_limits(ctx);
    }
    sc.lambda.clear();
    sc.lambda.resize(ctx.topology.springs().len(), 0.0);
    let grid = (settings.chains || settings.shear_chains)
        && sc.grid.prepare(ctx.topology, ctx.particles.len());
    let chains = (grid && settings.chains, grid && settings.shear_chains);
    for (on, lambda) in [
        (chains.0, &mut sc.chain_lambda),
        (chains.1, &mut sc.shear_lambda),
    ] {
        if on {
            for l in lambda {
                l.clear();
                l.resize(ctx.particles.len(), 0.0);
            }
        }
    }
    let mut contacts = 0;
    for _ in 0..settings.iterations {
        solve_springs(ctx, sc, h, chains);
        if settings.tethers {
            solve_tethers(&mut *ctx.particles, &sc.tethers);
        }
        if limits {
            solve_limits(&mut *ctx.particles, &sc.limits);
        }
        if let Some(settings) = cfg.self_collision {
            crate::collide::self_collision::resolve(hash, ctx.particles, ctx.rest, settings, false);
        }
        contacts = solve_contacts(ctx, &sc.prev, h);
    }
    ctx.contacts.contacts = contacts;
}

/// Every spring in storage order; with `chains.0` (`xpbd.chains`), the warp and the weft as
/// chains instead ([`super::chains::solve_reference`]), after the others, in
/// `xpbd.chain_rounds` rounds; with `chains.1` (`xpbd.shear_chains`), the shear springs as
/// chains along the diagonal lines, in their place in the order
/// ([`super::chains::solve_reference_diagonal`]).
fn solve_springs(
    ctx: &mut SubstepCtx<'_>,
    sc: &mut XpbdScratch,
    h: f32,
    (chains, shear_chains): (bool, bool),
) {
    let cfg = ctx.config;
    let p = &mut *ctx.particles;
    // Offsets of each kind's multipliers (the storage order).
    let mut offsets = [0; 4];
    let mut offset = 0;
    for kind in SpringKind::ALL {
        offsets[kind as usize] = offset;
        offset += ctx.topology.springs_of(kind).len();
    }
    // With chains the structural springs go last (as on the grid path).
    let grid = ctx.topology.grid().filter(|_| chains);
    let kinds: &[SpringKind] = if grid.is_some() {
        &[SpringKind::Shear, SpringKind::Bend]
    } else {
        &SpringKind::ALL
    };
    for &kind in kinds {
        let springs = ctx.topology.springs_of(kind);
        let offset = offsets[kind as usize];
        let lambda = &mut sc.lambda[offset..offset + springs.len()];
        let Some((alpha, gamma)) = compliance(cfg, kind, h) else {
            continue;
        };
        if let (SpringKind::Shear, true, Some((rows, cols))) =
            (kind, shear_chains, ctx.topology.grid())
        {
            let params = super::chains::Params::new(alpha, gamma, &cfg.xpbd);
            for dir in 0..2 {
                super::chains::solve_reference_diagonal(
                    &mut *p,
                    &sc.prev,
                    sc.grid.class_rest(2 + dir),
                    &mut sc.shear_lambda[dir],
                    (rows, cols, dir),
                    (params, cfg.xpbd.chain_iterations),
                    &mut sc.chain_scratch,
                );
            }
            continue;
        }
        // `shear_rows`: the grid path's row order (two halves of cell rows, then the row
        // between them; each row's diagonals, then its anti-diagonals), kept in the scratch.
        let rows_order =
            kind == SpringKind::Shear && cfg.xpbd.shear_rows && ctx.topology.grid().is_some();
        if let (true, Some((rows, cols))) = (rows_order, ctx.topology.grid())
            && sc.shear_order_key != Some((springs.len(), rows, cols))
        {
            let between = super::grid_xpbd::shear_rows_between(rows);
            let key = |i: u32| {
                let s = &springs[i as usize];
                let (a, b) = (s.a as usize, s.b as usize);
                // Either end first: a diagonal's ends are cols + 1 apart, an anti-diagonal's
                // cols − 1; the cell row is the upper end's.
                let anti = usize::from(a.abs_diff(b) != cols + 1);
                let r = a.min(b) / cols;
                let half = match r.cmp(&between) {
                    std::cmp::Ordering::Less => 0,
                    std::cmp::Ordering::Greater => 1,
                    std::cmp::Ordering::Equal => 2,
                };
                (half, r, anti, i)
            };
            sc.shear_order.clear();
            sc.shear_order.extend(0..springs.len() as u32);
            sc.shear_order.sort_unstable_by_key(|&i| key(i));
            sc.shear_order_key = Some((springs.len(), rows, cols));
        }
        for j in 0..springs.len() {
            let i = if rows_order {
                sc.shear_order[j] as usize
            } else {
                j
            };
            let (s, lambda) = (&springs[i], &mut lambda[i]);
            let (a, b) = (s.a as usize, s.b as usize);
            let (wa, wb) = (p.inv_mass[a], p.inv_mass[b]);
            let w = wa + wb;
            if w == 0.0 {
                continue;
            }
            let l = p.position[a] - p.position[b];
            let len = l.length();
            if len <= 0.0 {
                continue;
            }
            let grad = l / len;
            let constraint = len - s.rest_length;
            let rate = grad.dot((p.position[a] - sc.prev[a]) - (p.position[b] - sc.prev[b]));
            let dl = (-constraint - alpha * *lambda - gamma * rate) / ((1.0 + gamma) * w + alpha);
            *lambda += dl;
            p.position[a] += (wa * dl) * grad;
            p.position[b] -= (wb * dl) * grad;
        }
    }
    // `chain_rounds` rounds of warp then weft chains, each after a contact pass when there
    // are several (as on the grid path).
    let Some((rows, cols)) = grid else { return };
    let rounds = cfg.xpbd.chain_rounds;
    for _ in 0..rounds {
        if rounds > 1 {
            solve_contacts(ctx, &sc.prev, h);
        }
        for (class, kind) in [SpringKind::Warp, SpringKind::Weft].into_iter().enumerate() {
            let Some((alpha, gamma)) = compliance(cfg, kind, h) else {
                continue;
            };
            let params = super::chains::Params::new(alpha, gamma, &cfg.xpbd);
            super::chains::solve_reference(
                ctx.particles,
                &sc.prev,
                sc.grid.class_rest(class),
                &mut sc.chain_lambda[class],
                (rows, cols, class),
                (params, cfg.xpbd.chain_iterations),
                &mut sc.chain_scratch,
            );
        }
    }
}

/// One-sided distance limits between two free-or-pinned particles, mass-weighted.
fn solve_limits(p: &mut crate::particles::Particles, limits: &[Tether]) {
    for t in limits {
        let (a, b) = (t.particle as usize, t.anchor as usize);
        let (wa, wb) = (p.inv_mass[a], p.inv_mass[b]);
        let w = wa + wb;
        let l = p.position[a] - p.position[b];
        let len = l.length();
        if w > 0.0 && len > t.max_distance {
            let grad = l / len;
            let dl = (t.max_distance - len) / w;
            p.position[a] += (wa * dl) * grad;
            p.position[b] -= (wb * dl) * grad;
        }
    }
}

/// Largest α̃ = 1/(k·h²) of a spring XPBD projects, and largest γ = c/(k·h) it uses. A
/// spring more compliant than that within a substep moves its ends by less than 10⁻³⁰ of its
/// constraint's value times their inverse masses: nothing an f32 position can show, so it
/// is left out like a spring of no stiffness (beyond it α̃ overflows f32, and α̃ = ∞ with
/// γ = ∞ would make a correction ∞/∞). A larger γ gives the same correction to f32
/// precision (the rigid dashpot's limit Δλ → −rate/w), so γ is capped there.
const MAX_COMPLIANCE: f32 = 1.0e30;

/// XPBD's constants of a spring kind at substep `h`: `(α̃, γ)` with α̃ = α/h², α = 1/k, and
/// γ = α̃·β̃/h with β̃ = h²·β, β = c (the dashpot), capped at [`MAX_COMPLIANCE`]. `None` when
/// the kind has no stiffness, the springs are switched off, or α̃ is past
/// [`MAX_COMPLIANCE`]. Shared by the reference and grid paths.
pub(super) fn compliance(
    cfg: &crate::config::SimConfig,
    kind: SpringKind,
    h: f32,
) -> Option<(f32, f32)> {
    let params = cfg.material.params(kind);
    let k = if cfg.forces.springs {
        params.stiffness
    } else {
        0.0
    };
    if k == 0.0 {
        return None;
    }
    let c = if cfg.forces.dashpots {
        params.damping
    } else {
        0.0
    };
    let alpha = 1.0 / (k * h * h);
    if alpha > MAX_COMPLIANCE {
        return None;
    }
    Some((alpha, (c / (k * h)).min(MAX_COMPLIANCE)))
}

fn solve_tethers(p: &mut crate::particles::Particles, tethers: &[Tether]) {
    for t in tethers {
        let (i, a) = (t.particle as usize, t.anchor as usize);
        let d = p.position[i] - p.position[a];
        let len = d.length();
        if len > t.max_distance && len > 0.0 {
            p.position[i] -= (len - t.max_distance) / len * d;
        }
    }
}

/// Projects particles out of colliders; position-level Coulomb friction on the substep's
/// tangential displacement relative to the collider. Returns the number of contacts.
fn solve_contacts(ctx: &mut SubstepCtx<'_>, prev: &[Vec3], h: f32) -> u32 {
    let mut contacts = 0;
    let p = &mut *ctx.particles;
    for col in ctx.colliders {
        for ((x, &x0), &w) in p.position.iter_mut().zip(prev).zip(&p.inv_mass) {
            if w != 0.0 && contact(col, x, x0, h) {
                contacts += 1;
            }
        }
    }
    contacts
}

/// The contact of one free particle at `x` (at `x0` at the start of the substep) with one
/// collider: pushed out along the normal, then position-level Coulomb friction on its
/// tangential displacement relative to the collider (static while it is at most μs times the
/// push, else shortened by μk times the push). Returns whether it touched.
#[inline]
pub(super) fn contact(col: &crate::collide::Collider, x: &mut Vec3, x0: Vec3, h: f32) -> bool {
    let (mu_s, mu_k) = (
        col.friction.static_coefficient,
        col.friction.kinetic_coefficient,
    );
    let (dist, nrm) = col.shape.distance_within(*x, col.contact_range());
    let phi = dist - col.thickness;
    if phi >= 0.0 {
        return false;
    }
    let push = -phi;
    *x += push * nrm;
    let rel = (*x - x0) - col.velocity_at(*x) * h;
    let tangential = rel - rel.dot(nrm) * nrm;
    let t_len = tangential.length();
    if t_len <= mu_s * push {
        *x -= tangential;
    } else if t_len > 0.0 {
        *x -= tangential * (mu_k * push / t_len).min(1.0);
    }
    true
}
