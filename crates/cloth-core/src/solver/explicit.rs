//! The explicit integrators: forward Euler, symplectic Euler and position Verlet.
//!
//! Pinned particles (`inv_mass == 0`) get no acceleration and move with their prescribed
//! velocity, so an animated pin moves exactly along its path in every integrator.

use glam::Vec3;

use super::{SubstepCtx, kick_drift};
use crate::collide::resolve_contacts;
use crate::forces::accumulate;

fn forces(ctx: &SubstepCtx<'_>, force: &mut [Vec3]) {
    accumulate(ctx.config, ctx.topology, ctx.particles, ctx.wind, force);
}

/// x ← x + h·v; v ← v + h·F/m(x, v) (both from the old state); contacts.
pub(super) fn forward_euler(ctx: &mut SubstepCtx<'_>, force: &mut [Vec3]) {
    forces(ctx, force);
    let h = ctx.h;
    let p = &mut *ctx.particles;
    for (((x, v), &w), &f) in p
        .position
        .iter_mut()
        .zip(p.velocity.iter_mut())
        .zip(&p.inv_mass)
        .zip(force.iter())
    {
        *x += h * *v;
        *v += (h * w) * f;
    }
    resolve_contacts(ctx.colliders, p, 0.0, ctx.contacts);
}

/// v ← v + h·F/m(x, v); x ← x + h·v (the new v); contacts.
pub(super) fn symplectic_euler(ctx: &mut SubstepCtx<'_>, force: &mut [Vec3]) {
    forces(ctx, force);
    let h = ctx.h;
    let p = &mut *ctx.particles;
    kick_drift(p, force, h, h);
    resolve_contacts(ctx.colliders, p, h, ctx.contacts);
}

/// Drift–kick–drift: x ← x + ½h·v; v ← v + h·F/m(x, v); x ← x + ½h·v; contacts.
pub(super) fn position_verlet(ctx: &mut SubstepCtx<'_>, force: &mut [Vec3]) {
    let half = 0.5 * ctx.h;
    for (x, &v) in ctx
        .particles
        .position
        .iter_mut()
        .zip(&ctx.particles.velocity)
    {
        *x += half * v;
    }
    forces(ctx, force);
    let p = &mut *ctx.particles;
    kick_drift(p, force, ctx.h, half);
    resolve_contacts(ctx.colliders, p, half, ctx.contacts);
}
