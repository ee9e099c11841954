//! Time integrators behind one interface.
//!
//! A [`Solver`] owns only reusable scratch memory. Each call to [`Solver::substep`] advances
//! the particles by one substep `h` with the chosen [`Integrator`]; every integrator is
//! responsible for the whole substep (forces, integration, contacts), so that solvers that do
//! not fit "forces then integrate" (implicit, constraint-based) plug in the same way.

mod explicit;

use glam::Vec3;

use crate::collide::{Collider, ContactStats};
use crate::config::{Integrator, SimConfig};
use crate::particles::Particles;
use crate::topology::Topology;

/// What one substep acts on.
pub(crate) struct SubstepCtx<'a> {
    /// The particle state, advanced in place.
    pub particles: &'a mut Particles,
    /// Springs and triangles.
    pub topology: &'a Topology,
    /// Parameters.
    pub config: &'a SimConfig,
    /// Colliders at their position at the end of the substep.
    pub colliders: &'a [Collider],
    /// Wind velocity during the substep, m/s.
    pub wind: Vec3,
    /// Substep length, s.
    pub h: f32,
    /// Contact counts of the substep (written by the integrator).
    pub contacts: &'a mut ContactStats,
}

/// Reusable scratch of the integrators. Allocated once per particle count; no allocation
/// happens inside a step after the first.
#[derive(Debug, Default, Clone)]
pub(crate) struct Solver {
    /// Force per particle, N.
    force: Vec<Vec3>,
}

impl Solver {
    /// Advances one substep with `integrator`.
    pub fn substep(&mut self, integrator: Integrator, ctx: SubstepCtx<'_>) {
        let n = ctx.particles.len();
        if self.force.len() != n {
            self.force.resize(n, Vec3::ZERO);
        }
        match integrator {
            Integrator::ForwardEuler => explicit::forward_euler(ctx, &mut self.force),
            Integrator::SymplecticEuler => explicit::symplectic_euler(ctx, &mut self.force),
            Integrator::Verlet => explicit::position_verlet(ctx, &mut self.force),
        }
    }

    /// The total force on every particle at the current state, into the scratch, and
    /// returned.
    pub fn forces(
        &mut self,
        config: &SimConfig,
        topology: &Topology,
        particles: &Particles,
        wind: Vec3,
    ) -> &[Vec3] {
        self.force.resize(particles.len(), Vec3::ZERO);
        crate::forces::accumulate(
            config,
            topology,
            &particles.position,
            &particles.velocity,
            &particles.mass,
            wind,
            &mut self.force,
        );
        &self.force
    }
}
