//! Time integrators behind one interface.
//!
//! A [`Solver`] owns only reusable scratch memory. Each call to [`Solver::substep`] advances
//! the particles by one substep `h` with the chosen [`Integrator`]; every integrator is
//! responsible for the whole substep (forces, integration, contacts), so that solvers that do
//! not fit "forces then integrate" (implicit, constraint-based) plug in the same way.

pub(crate) mod chains;
mod explicit;
pub(crate) mod grid_kernel;
pub(crate) mod grid_xpbd;
pub(crate) mod implicit;
pub(crate) mod placed;
pub(crate) mod shared_rows;
mod xpbd;

use glam::Vec3;

use crate::collide::{Collider, ContactStats};
use crate::config::{Integrator, SimConfig};
use crate::diagnostics::SolverStats;
use crate::particles::Particles;
use crate::topology::{SpringKind, Topology};

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
    /// Rest-shape positions (for tethers).
    pub rest: &'a [Vec3],
    /// Some particle is pinned ([`Particles::any_pinned`], found once per step: the inverse
    /// masses do not change inside a step).
    pub pinned: bool,
}

/// The reference paths' kick and drift, particle by particle: `v ← v + (h·w)·f`, then
/// `x ← x + drift·v` with the new `v` (symplectic Euler and XPBD's prediction with
/// `drift = h`, position Verlet's second half with `drift = h/2`). A pinned particle
/// (`w = 0`) keeps its velocity.
pub(crate) fn kick_drift(p: &mut Particles, force: &[Vec3], h: f32, drift: f32) {
    for (((x, v), &w), &f) in p
        .position
        .iter_mut()
        .zip(p.velocity.iter_mut())
        .zip(&p.inv_mass)
        .zip(force)
    {
        *v += (h * w) * f;
        *x += drift * *v;
    }
}

/// Provot-style strain limiting (Provot 1995): every structural and shear spring stretched
/// past `(1 + limit)·L0` is shortened back to that length by moving its ends along the spring,
/// mass-weighted (a pinned end does not move); the velocities change by the same displacement
/// divided by `h`, so the correction does not bounce back. One pass in storage order.
pub(crate) fn limit_strain(topology: &Topology, particles: &mut Particles, limit: f32, h: f32) {
    let inv_h = 1.0 / h;
    for kind in [SpringKind::Warp, SpringKind::Weft, SpringKind::Shear] {
        for s in topology.springs_of(kind) {
            let (a, b) = (s.a as usize, s.b as usize);
            let (wa, wb) = (particles.inv_mass[a], particles.inv_mass[b]);
            let w = wa + wb;
            if w == 0.0 {
                continue;
            }
            let l = particles.position[b] - particles.position[a];
            let len = l.length();
            let max = (1.0 + limit) * s.rest_length;
            if len <= max {
                continue;
            }
            let correction = (len - max) / (len * w) * l;
            particles.position[a] += wa * correction;
            particles.position[b] -= wb * correction;
            particles.velocity[a] += (wa * inv_h) * correction;
            particles.velocity[b] -= (wb * inv_h) * correction;
        }
    }
}

/// Reusable scratch of the integrators. Allocated once per particle count; no allocation
/// happens inside a step after the first.
#[derive(Debug, Default, Clone)]
pub(crate) struct Solver {
    /// Force per particle, N.
    force: Vec<Vec3>,
    implicit: implicit::ImplicitScratch,
    xpbd: xpbd::XpbdScratch,
    /// Solver figures accumulated over the current step.
    stats: SolverStats,
    /// Spatial hash of the self-collision pass.
    hash: crate::collide::self_collision::SelfCollisionScratch,
    /// Positions at the start of the substep (for continuous collision; XPBD has its own).
    start: Vec<Vec3>,
    /// Scratch of the explicit integrators' grid fast path.
    grid: grid_kernel::GridScratch,
    /// Whether a substep of the current step could not be solved in f32 (implicit Euler's
    /// linear solve overflowed); [`Solver::take_overflow`].
    overflow: bool,
}

impl Solver {
    /// Starts a step: resets the solver figures.
    pub fn begin_step(&mut self) {
        self.stats = SolverStats::default();
        self.overflow = false;
    }

    /// Whether a substep of this step could not be solved in f32 (implicit Euler's linear
    /// solve overflowed, leaving its Δv meaningless): the step must fail. Clears the flag.
    pub fn take_overflow(&mut self) -> bool {
        std::mem::take(&mut self.overflow)
    }

    /// Ends a step: the state a fast path kept in its own arrays goes back to the particles.
    pub fn end_step(&mut self, particles: &mut Particles) {
        grid_kernel::sync(
            &mut self.grid,
            &mut particles.position,
            &mut particles.velocity,
        );
        self.xpbd.grid.sync(particles);
    }

    /// After a step (and its [`Solver::end_step`]): whether the step must be run again from
    /// its start, which the explicit fast path asks for when a substep that updated its state
    /// in place met a zero-length spring (the reference path, which skips such a spring,
    /// could no longer take that substep over). The step run again does not update in place,
    /// so it gives the reference's result.
    pub fn take_redo(&mut self) -> bool {
        self.grid.take_redo()
    }

    /// The solver figures of the step so far.
    pub fn stats(&self) -> SolverStats {
        self.stats
    }

    /// Advances one substep with `integrator`, then (for the force-based integrators) the
    /// optional strain-limiting and self-collision passes, then continuous collision against
    /// the colliders.
    pub fn substep(&mut self, integrator: Integrator, mut ctx: SubstepCtx<'_>) {
        if self.grid.redo_pending() {
            // The step will be run again (see `take_redo`).
            return;
        }
        let n = ctx.particles.len();
        if self.force.len() != n {
            self.force.resize(n, Vec3::ZERO);
        }
        let grid = grid_kernel::plan(integrator, &ctx, &mut self.grid);
        let ccd = ctx.config.continuous_collision
            && !ctx.colliders.is_empty()
            && !grid.is_some_and(|g| g.ccd);
        // XPBD keeps the substep's start positions itself; the others copy them here.
        let xpbd = integrator == Integrator::Xpbd;
        if ccd && !xpbd {
            self.start.clear();
            self.start.extend_from_slice(&ctx.particles.position);
        }
        let ccd_done = self.integrate(integrator, grid, &mut ctx, ccd);
        if ccd && !ccd_done {
            let start = if xpbd { self.xpbd.start() } else { &self.start };
            ctx.contacts.ccd +=
                crate::collide::ccd::resolve(ctx.colliders, start, ctx.particles, ctx.h);
            // Strain limiting and self-collision run after the contacts of the force-based
            // integrators (XPBD solves contacts last in each sweep).
            let after_contacts =
                !xpbd && (ctx.config.strain_limit.is_some() || ctx.config.self_collision.is_some());
            if after_contacts {
                crate::collide::ccd::project(ctx.colliders, ctx.particles);
            }
        }
    }

    /// Stepping proper; returns whether it also ran continuous collision (`ccd`).
    fn integrate(
        &mut self,
        integrator: Integrator,
        grid: Option<grid_kernel::Plan>,
        ctx: &mut SubstepCtx<'_>,
        ccd: bool,
    ) -> bool {
        match integrator {
            _ if grid.is_some() => grid_kernel::run(ctx, &mut self.grid, grid, &mut self.force),
            Integrator::ForwardEuler => explicit::forward_euler(ctx, &mut self.force),
            Integrator::SymplecticEuler => explicit::symplectic_euler(ctx, &mut self.force),
            Integrator::Verlet => explicit::position_verlet(ctx, &mut self.force),
            Integrator::ImplicitEuler => {
                let mut cg = implicit::CgStats::default();
                implicit::substep(ctx, &mut self.force, &mut self.implicit, &mut cg);
                self.stats.iterations = self.stats.iterations.max(cg.iterations);
                self.stats.residual = self.stats.residual.max(cg.residual);
                self.stats.converged &= cg.converged;
                self.overflow |= cg.overflowed;
            }
            Integrator::Xpbd => {
                self.stats.iterations = ctx.config.xpbd.iterations;
                return xpbd::substep(ctx, &mut self.force, &mut self.xpbd, &mut self.hash, ccd);
            }
        }
        if let Some(limit) = ctx.config.strain_limit {
            limit_strain(ctx.topology, ctx.particles, limit, ctx.h);
        }
        if let Some(settings) = ctx.config.self_collision {
            crate::collide::self_collision::resolve(
                &mut self.hash,
                ctx.particles,
                ctx.rest,
                settings,
                true,
            );
        }
        false
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
        crate::forces::accumulate(config, topology, particles, wind, &mut self.force);
        &self.force
    }
}

/// Runs `f` (a step's substeps and diagnostics) on the current rayon pool with its other
/// threads kept awake:
/// each polls for work (`rayon::yield_now`, and the operating system's yield when there is
/// none) until `f` returns, instead of falling asleep whenever it runs out of work.
///
/// A substep is many short parallel passes (XPBD's grid path: about 25 per substep, each a
/// few hundred microseconds at 256²). Between two passes rayon lets an idle thread spin for
/// a few dozen yields and then sleep, and on a virtual machine waking it takes tens of
/// microseconds, often more than the imbalance it was waiting out: the 256² drape (3 substeps
/// × 5 rounds × 2 iterations, 2 threads) spent ≈ 20 % of its wall time with a thread off the
/// processor or in the scheduler, and runs ≈ 8 % faster with the threads kept awake
/// (interleaved medians, `docs/performance.md`). The pollers yield to the operating system
/// whenever they find nothing, so a machine with more threads than cores still runs the
/// work. Which thread runs which piece of work never changes the results (every parallel pass
/// writes disjoint data in a fixed order).
///
/// Allocation-free (nested `rayon::join`s, one per other thread; the pollers leave when a
/// flag is set, also when `f` panics). With one thread, `f` runs directly.
pub(crate) fn with_pool_awake<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    use std::sync::atomic::{AtomicBool, Ordering};
    let threads = rayon::current_num_threads();
    if threads < 2 {
        return f();
    }
    let done = AtomicBool::new(false);
    // Sets the flag when dropped: after `f` returns or while it unwinds (a panic in `f` would
    // otherwise leave the pollers running, and `join` waits for them).
    struct Done<'a>(&'a AtomicBool);
    impl Drop for Done<'_> {
        fn drop(&mut self) {
            self.0.store(true, Ordering::Release);
        }
    }
    // Nested joins: `f` on this thread, a poller offered to the others at each level.
    fn nest<R: Send>(
        pollers: usize,
        owner: usize,
        done: &AtomicBool,
        f: impl FnOnce() -> R + Send,
    ) -> R {
        if pollers == 0 {
            let _done = Done(done);
            return f();
        }
        let (r, ()) = rayon::join(
            || nest(pollers - 1, owner, done, f),
            || {
                // Not on the thread running `f` (it takes back an unstolen poller after `f`).
                if rayon::current_thread_index() == Some(owner) {
                    return;
                }
                while !done.load(Ordering::Acquire) {
                    if rayon::yield_now() != Some(rayon::Yield::Executed) {
                        std::thread::yield_now();
                    }
                }
            },
        );
        r
    }
    match rayon::current_thread_index() {
        Some(owner) => nest(threads - 1, owner, &done, f),
        // From outside the pool: `join` moves the whole call into it (the owner is then the
        // pool thread that runs `f`), with the caller's choice of kernel (thread-local,
        // `simd::set_kernel`), restored on that thread afterwards.
        None => {
            struct Restore(Option<crate::simd::Kernel>);
            impl Drop for Restore {
                fn drop(&mut self) {
                    crate::simd::choose(self.0);
                }
            }
            let chosen = crate::simd::chosen();
            rayon::join(
                || {
                    let _restore = Restore(crate::simd::choose(chosen));
                    let owner = rayon::current_thread_index().expect("`join` runs on the pool");
                    nest(threads - 1, owner, &done, f)
                },
                || (),
            )
            .0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::with_pool_awake;

    fn pool(threads: usize) -> rayon::ThreadPool {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a thread pool")
    }

    /// `f`'s result comes back, and parallel work inside `f` runs, on 1, 2 and 3 threads,
    /// from a pool thread and from outside any pool.
    #[test]
    fn with_pool_awake_runs_f_and_its_parallel_work() {
        use rayon::prelude::*;
        let sum = || (0..10_000_u64).into_par_iter().map(|i| i * i).sum::<u64>();
        let expected: u64 = (0..10_000_u64).map(|i| i * i).sum();
        for threads in 1..=3 {
            assert_eq!(pool(threads).install(|| with_pool_awake(sum)), expected);
        }
        assert_eq!(with_pool_awake(sum), expected);
    }

    /// A panic in `f` reaches the caller (the pollers stop; no hang), and the pool still
    /// works afterwards.
    #[test]
    fn with_pool_awake_passes_a_panic_on() {
        let pool = pool(2);
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            pool.install(|| with_pool_awake(|| panic!("inside the step")))
        }));
        assert!(caught.is_err());
        assert_eq!(pool.install(|| with_pool_awake(|| 7)), 7);
    }

    /// Simulations stepped from inside a parallel iterator (each step polling the pool while
    /// the others' steps are queued on it) all finish, with the bits of a serial run.
    #[test]
    fn steps_inside_a_parallel_iterator_finish_with_the_serial_bits() {
        use crate::{Collider, GridBuilder, Integrator, SimConfig, Simulation};
        use rayon::prelude::*;
        let make = |i: usize| {
            let cloth = GridBuilder::new(12 + i, 10)
                .origin(glam::Vec3::new(0.0, 1.0, 0.0))
                .build()
                .expect("a grid");
            let integrator = [Integrator::Xpbd, Integrator::SymplecticEuler][i % 2];
            let config = SimConfig {
                integrator,
                substeps: 24,
                ..SimConfig::default()
            };
            let mut sim = Simulation::new(cloth, config).expect("a simulation");
            sim.add_collider(Collider::sphere(glam::Vec3::ZERO, 0.5))
                .expect("a sphere");
            sim
        };
        let run = |sim: &mut Simulation| {
            for _ in 0..5 {
                sim.step().expect("a stable step");
            }
            sim.particles().position.clone()
        };
        let serial: Vec<_> = (0..6).map(|i| run(&mut make(i))).collect();
        let parallel: Vec<_> = pool(3).install(|| {
            let mut sims: Vec<_> = (0..6).map(make).collect();
            sims.par_iter_mut().map(run).collect()
        });
        assert_eq!(serial, parallel);
    }

    /// The caller's kernel choice (thread-local) holds for `f` when the call moves onto a
    /// pool thread.
    #[test]
    fn with_pool_awake_keeps_the_callers_kernel() {
        use crate::simd::{self, Kernel};
        // With several threads the call moves onto a pool thread (this test's thread is not
        // one), which is what the kernel must survive.
        if rayon::current_num_threads() > 1 {
            assert!(with_pool_awake(rayon::current_thread_index).is_some());
        }
        simd::set_kernel(Some(Kernel::Reference)).expect("the reference kernel runs anywhere");
        assert_eq!(with_pool_awake(simd::kernel), Kernel::Reference);
        simd::set_kernel(None).expect("the default");
        assert_eq!(with_pool_awake(simd::kernel), Kernel::best());
    }
}
