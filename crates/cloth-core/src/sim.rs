//! The simulation: a cloth, its parameters and colliders, stepped in time.

use glam::Vec3;

use crate::collide::{Collider, ContactStats};
use crate::config::SimConfig;
use crate::diagnostics::{StepStats, instability_hint, measure};
use crate::error::{ClothError, Result, check};
use crate::grid::Cloth;
use crate::particles::Particles;
use crate::solver::{Solver, SubstepCtx};
use crate::topology::{SpringKind, Topology};

/// A cloth simulation.
///
/// One [`step`](Self::step) advances [`SimConfig::dt`] in [`SimConfig::substeps`] equal
/// substeps. Its stages, in order:
/// 1. **snapshot**: keep the state so that a failed step can be undone;
/// 2. **pins**: each pinned particle gets the velocity that takes it to its target (set with
///    [`set_pin_target`](Self::set_pin_target)) by the end of the step, or zero;
/// 3. **substeps**, each: move the colliders along their prescribed motion, then the
///    integrator's substep (forces → integrate → contacts, for the explicit integrators);
///    on a rayon pool of several threads the other threads poll for work through all the
///    substeps instead of falling asleep between their parallel passes; stages 2 and 3 run
///    once more from the snapshot in the one case where a substep cannot be finished as
///    the reference would (the explicit fast path, updating a large cloth in place, meets a
///    spring of zero length);
/// 4. **pins**: snap moved pins exactly onto their targets and stop them;
/// 5. **diagnostics and instability check**: energies, strains, penetration, contacts; a
///    non-finite value, a runaway speed or a spring past the stretch limit restores the
///    snapshot and returns [`ClothError::Unstable`].
///
/// ```
/// use cloth_core::{Collider, GridBuilder, SimConfig, Simulation};
/// use glam::Vec3;
///
/// let cloth = GridBuilder::new(16, 16).origin(Vec3::new(0.0, 1.0, 0.0)).build()?;
/// let mut sim = Simulation::new(cloth, SimConfig::default())?;
/// sim.add_collider(Collider::sphere(Vec3::ZERO, 0.5))?;
/// for _ in 0..30 {
///     sim.step()?;
/// }
/// assert!(sim.stats().max_penetration <= 1e-6);
/// # Ok::<(), cloth_core::ClothError>(())
/// ```
#[derive(Debug, Clone)]
pub struct Simulation {
    particles: Particles,
    topology: Topology,
    rows: usize,
    cols: usize,
    config: SimConfig,
    colliders: Vec<Collider>,
    /// Target position per particle for the current step's pin motion (pinned only).
    pin_target: Vec<Option<Vec3>>,
    solver: Solver,
    /// State before the current step, restored if it fails.
    backup_position: Vec<Vec3>,
    backup_velocity: Vec<Vec3>,
    backup_colliders: Vec<Collider>,
    /// The diagnostics' spring lengths of a grid cloth (reused from step to step).
    measure_lengths: Vec<f32>,
    time: f64,
    steps: u64,
    stats: StepStats,
    /// Positions of the cloth as built (its rest shape), for tethers.
    rest_position: Vec<Vec3>,
    /// Scratch of the self-contact diagnostics.
    contact_check: crate::collide::intersect::SelfContactCheck,
}

/// A contact found by [`Simulation::contacts`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// The particle in contact.
    pub particle: u32,
    /// Unit normal pushing the particle out of the contact.
    pub normal: Vec3,
    /// What it touches.
    pub with: ContactWith,
}

/// What a particle touches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ContactWith {
    /// The collider with this index.
    Collider(u32),
    /// Another particle of the cloth (self-contact).
    Cloth(u32),
}

/// Everything that changes while a simulation runs: enough to continue it later to the same
/// bits (a checkpoint). The scene (cloth, parameters, colliders' shapes and motions) is not
/// included: restore a state into a simulation built from the same scene.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "scene", derive(serde::Serialize, serde::Deserialize))]
pub struct SimState {
    /// Simulated time, s.
    pub time: f64,
    /// Steps completed.
    pub steps: u64,
    /// Positions, m.
    pub position: Vec<[f32; 3]>,
    /// Velocities, m/s.
    pub velocity: Vec<[f32; 3]>,
    /// Inverse masses (0 = pinned), 1/kg.
    pub inv_mass: Vec<f32>,
    /// Each collider's shape at the saved time (colliders move and turn).
    pub collider_shapes: Vec<crate::collide::Shape>,
}

/// Largest self-collision thickness, in the cloth's largest structural rest length: a
/// particle's candidate pairs grow with (thickness / spacing)², so 16 spacings (about 800
/// candidates per particle in a flat layer) keeps the pair search's time and memory bounded
/// (a thickness of the cloth's whole size would make every pair a candidate: n² of them).
pub const MAX_SELF_COLLISION_SPACINGS: f32 = 16.0;

/// The cloth's largest structural (warp or weft) rest length, m: its coarsest grid spacing.
fn largest_spacing(topology: &Topology) -> f32 {
    topology
        .springs_of(SpringKind::Warp)
        .iter()
        .chain(topology.springs_of(SpringKind::Weft))
        .map(|s| s.rest_length)
        .fold(0.0, f32::max)
}

/// What a self-collision `thickness` (m) on a grid of largest `spacing` (m) is allowed, when
/// it is more than [`MAX_SELF_COLLISION_SPACINGS`] spacings: the one bound and wording of
/// [`Simulation::new`] and of scene files (which know the spacing before the cloth is built).
pub(crate) fn self_collision_too_thick(thickness: f32, spacing: f32) -> Option<String> {
    let most = MAX_SELF_COLLISION_SPACINGS * spacing;
    (spacing > 0.0 && thickness > most).then(|| {
        format!(
            "(0, {most:.4}] m: at most {MAX_SELF_COLLISION_SPACINGS} grid spacings of \
             {spacing:.4} m (use about one spacing; a thicker layer makes the pair search's \
             time and memory grow with its square)"
        )
    })
}

/// The checks of a configuration that need the cloth: the self-collision thickness against
/// the grid spacing ([`MAX_SELF_COLLISION_SPACINGS`]).
fn check_for_cloth(config: &SimConfig, topology: &Topology) -> Result<()> {
    let Some(sc) = config.self_collision else {
        return Ok(());
    };
    match self_collision_too_thick(sc.thickness, largest_spacing(topology)) {
        Some(allowed) => Err(ClothError::invalid(
            "config.self_collision.thickness",
            sc.thickness,
            allowed,
        )),
        None => Ok(()),
    }
}

/// `velocity` at most `config.limits.max_speed` fast (a faster particle would make every step
/// fail the instability check); the error names `name()`.
fn check_speed(name: impl FnOnce() -> String, velocity: Vec3, config: &SimConfig) -> Result<()> {
    let most = config.limits.max_speed;
    if velocity.as_dvec3().length() > f64::from(most) {
        return Err(ClothError::invalid(
            name(),
            velocity,
            format!("a speed of at most {most} m/s (`limits.max_speed`)"),
        ));
    }
    Ok(())
}

/// The fastest of `velocity`: its index, velocity and speed (m/s, in f64); the first of
/// equals; `None` when there is none.
fn fastest(velocity: impl IntoIterator<Item = Vec3>) -> Option<(usize, Vec3, f64)> {
    velocity
        .into_iter()
        .enumerate()
        .map(|(i, v)| (i, v, v.as_dvec3().length()))
        .fold(None, |best, next| match best {
            Some(b) if b.2 >= next.2 => Some(b),
            _ => Some(next),
        })
}

/// [`check_speed`] of the fastest velocity, the error naming `name[i]`.
fn check_speeds(
    name: &str,
    velocity: impl IntoIterator<Item = Vec3>,
    config: &SimConfig,
) -> Result<()> {
    match fastest(velocity) {
        Some((i, v, _)) => check_speed(|| format!("{name}[{i}]"), v, config),
        None => Ok(()),
    }
}

/// The velocity at which a pin with `target` moves its particle from `position` over a step
/// of `dt` seconds (stage 2 of [`Simulation::step`]), m/s.
fn pin_velocity(target: Vec3, position: Vec3, dt: f32) -> Vec3 {
    (target - position) / dt
}

/// Whether `shape`'s plane normal or box or mesh rotation has unit length to within f32
/// rounding (as [`Collider::validate`] and a collider's motion leave it).
fn is_unit(shape: &crate::collide::Shape) -> bool {
    use crate::collide::Shape;
    let length = match shape {
        Shape::Plane { normal, .. } => normal.length(),
        Shape::Box { rotation, .. } | Shape::Mesh { rotation, .. } => rotation.length(),
        Shape::Sphere { .. } | Shape::Capsule { .. } => 1.0,
    };
    (length - 1.0).abs() <= 1e-6
}

/// `config.limits.max_speed` at least the speed of every particle now (a slower limit would
/// make every step fail the instability check), the error naming the limit and the fastest
/// particle.
fn check_limit_of_speeds(config: &SimConfig, velocity: &[Vec3]) -> Result<()> {
    let most = config.limits.max_speed;
    match fastest(velocity.iter().copied()) {
        Some((i, _, speed)) if speed > f64::from(most) => Err(ClothError::invalid(
            "config.limits.max_speed",
            most,
            format!(
                "a finite number >= {:e} m/s, the speed of particle {i} now (every step \
                 would be reported unstable)",
                speed as f32
            ),
        )),
        _ => Ok(()),
    }
}

impl Simulation {
    /// The state needed to continue this simulation later to the same bits.
    #[must_use]
    pub fn state(&self) -> SimState {
        SimState {
            time: self.time,
            steps: self.steps,
            position: self
                .particles
                .position
                .iter()
                .map(|p| p.to_array())
                .collect(),
            velocity: self
                .particles
                .velocity
                .iter()
                .map(|v| v.to_array())
                .collect(),
            inv_mass: self.particles.inv_mass.clone(),
            collider_shapes: self.colliders.iter().map(|c| c.shape.clone()).collect(),
        }
    }

    /// Restores a state saved by [`state`](Self::state) from a simulation of the same scene.
    /// A plane's normal or a box's or mesh's rotation that is not of unit length (an edited
    /// state) is normalised, as [`add_collider`](Self::add_collider) normalises it.
    ///
    /// # Errors
    /// [`ClothError::InvalidArgument`] when the state does not fit this simulation (other
    /// particle or collider count, an inverse mass other than 0 or the particle's own
    /// 1/mass, a collider of another kind) or holds non-finite values or a negative time;
    /// nothing changes then.
    pub fn restore(&mut self, state: &SimState) -> Result<()> {
        let n = self.particles.len();
        for (name, len) in [
            ("state.position", state.position.len()),
            ("state.velocity", state.velocity.len()),
            ("state.inv_mass", state.inv_mass.len()),
        ] {
            if len != n {
                return Err(ClothError::invalid(
                    name,
                    len,
                    format!("{n} entries (the cloth's particles)"),
                ));
            }
        }
        if state.collider_shapes.len() != self.colliders.len() {
            return Err(ClothError::invalid(
                "state.collider_shapes",
                state.collider_shapes.len(),
                format!("{} entries (the scene's colliders)", self.colliders.len()),
            ));
        }
        let finite = state
            .position
            .iter()
            .chain(&state.velocity)
            .flatten()
            .all(|x| x.is_finite());
        if !finite {
            return Err(ClothError::invalid(
                "state",
                "non-finite values",
                "finite positions and velocities",
            ));
        }
        check_speeds(
            "state.velocity",
            state.velocity.iter().map(|&v| Vec3::from(v)),
            &self.config,
        )?;
        if !(state.time.is_finite() && state.time >= 0.0) {
            return Err(ClothError::invalid(
                "state.time",
                state.time,
                "a finite time >= 0 s",
            ));
        }
        // A particle is pinned (0) or free with its own mass: a saved state cannot change
        // the cloth's masses.
        if let Some(i) = (0..n).find(|&i| {
            let w = state.inv_mass[i];
            w != 0.0 && w != 1.0 / self.particles.mass[i]
        }) {
            return Err(ClothError::invalid(
                format!("state.inv_mass[{i}]"),
                state.inv_mass[i],
                format!(
                    "0 (pinned) or {} (1/mass of particle {i})",
                    1.0 / self.particles.mass[i]
                ),
            ));
        }
        // Each saved shape must be a valid collider of the same kind as the scene's; a plane's
        // normal or a box's or mesh's rotation off unit length by more than rounding (an
        // edited checkpoint) is normalised as `add_collider` does, the saved bits kept
        // otherwise (so that a checkpoint continues to the same bits).
        let mut shapes = Vec::with_capacity(state.collider_shapes.len());
        for (i, (c, shape)) in self
            .colliders
            .iter()
            .zip(&state.collider_shapes)
            .enumerate()
        {
            if std::mem::discriminant(&c.shape) != std::mem::discriminant(shape) {
                return Err(ClothError::invalid(
                    format!("state.collider_shapes[{i}]"),
                    shape,
                    "the same kind of shape as the scene's collider",
                ));
            }
            let valid = Collider {
                shape: shape.clone(),
                ..c.clone()
            }
            .validate(i)?;
            shapes.push(if is_unit(shape) {
                shape.clone()
            } else {
                valid.shape
            });
        }
        self.time = state.time;
        self.steps = state.steps;
        for (dst, src) in self.particles.position.iter_mut().zip(&state.position) {
            *dst = Vec3::from(*src);
        }
        for (dst, src) in self.particles.velocity.iter_mut().zip(&state.velocity) {
            *dst = Vec3::from(*src);
        }
        self.particles.inv_mass.clone_from(&state.inv_mass);
        for (c, shape) in self.colliders.iter_mut().zip(shapes) {
            c.shape = shape;
        }
        self.pin_target.fill(None);
        self.refresh_stats();
        Ok(())
    }

    /// A simulation of `cloth` with `config` (validated) and no colliders.
    ///
    /// # Errors
    /// [`ClothError::InvalidArgument`] for a bad `config` ([`SimConfig::validate`]), a cloth
    /// whose parts do not fit together ([`Cloth::validate`]: its fields are public), a
    /// self-collision thickness too large for the cloth's spacing, or a particle faster
    /// than `config.limits.max_speed` (every step would be reported unstable).
    pub fn new(cloth: Cloth, config: SimConfig) -> Result<Self> {
        config.validate()?;
        cloth.validate()?;
        check_for_cloth(&config, &cloth.topology)?;
        check_speeds(
            "cloth.particles.velocity",
            cloth.particles.velocity.iter().copied(),
            &config,
        )?;
        let n = cloth.particles.len();
        let mut sim = Self {
            particles: cloth.particles,
            topology: cloth.topology,
            rows: cloth.rows,
            cols: cloth.cols,
            config,
            colliders: Vec::new(),
            pin_target: vec![None; n],
            solver: Solver::default(),
            backup_position: Vec::with_capacity(n),
            backup_velocity: Vec::with_capacity(n),
            backup_colliders: Vec::new(),
            measure_lengths: Vec::new(),
            time: 0.0,
            steps: 0,
            stats: StepStats::default(),
            rest_position: Vec::new(),
            contact_check: Default::default(),
        };
        sim.rest_position.clone_from(&sim.particles.position);
        sim.refresh_stats();
        Ok(sim)
    }

    /// The particle state.
    #[must_use]
    pub fn particles(&self) -> &Particles {
        &self.particles
    }

    /// Springs and triangles.
    #[must_use]
    pub fn topology(&self) -> &Topology {
        &self.topology
    }

    /// Grid size as `(rows, cols)`.
    #[must_use]
    pub fn grid_size(&self) -> (usize, usize) {
        (self.rows, self.cols)
    }

    /// The parameters.
    #[must_use]
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// Replaces the parameters (validated; on error nothing changes). Takes effect at the
    /// next step.
    ///
    /// # Errors
    /// [`ClothError::InvalidArgument`] for a bad `config` ([`SimConfig::validate`]), a
    /// self-collision thickness too large for the cloth's spacing, or a
    /// `limits.max_speed` below the speed of a particle now (every step would be reported
    /// unstable).
    pub fn set_config(&mut self, config: SimConfig) -> Result<()> {
        config.validate()?;
        check_for_cloth(&config, &self.topology)?;
        check_limit_of_speeds(&config, &self.particles.velocity)?;
        self.config = config;
        self.refresh_stats();
        Ok(())
    }

    /// The colliders, at their current positions.
    #[must_use]
    pub fn colliders(&self) -> &[Collider] {
        &self.colliders
    }

    /// Adds a collider (validated) and returns its index.
    pub fn add_collider(&mut self, collider: Collider) -> Result<usize> {
        let index = self.colliders.len();
        self.colliders.push(collider.validate(index)?);
        self.refresh_stats();
        Ok(index)
    }

    /// Replaces collider `index` (validated; on error nothing changes).
    pub fn set_collider(&mut self, index: usize, collider: Collider) -> Result<()> {
        if index >= self.colliders.len() {
            let allowed = match self.colliders.len() {
                0 => "none: there are no colliders (add one with `add_collider`)".to_string(),
                len => format!("0 ..= {} (there are {len} colliders)", len - 1),
            };
            return Err(ClothError::invalid("collider index", index, allowed));
        }
        self.colliders[index] = collider.validate(index)?;
        self.refresh_stats();
        Ok(())
    }

    /// Removes every collider.
    pub fn clear_colliders(&mut self) {
        self.colliders.clear();
        self.refresh_stats();
    }

    /// Simulated time, s.
    #[must_use]
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Steps completed.
    #[must_use]
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Diagnostics of the last completed step; before the first step, of the state when the
    /// simulation was created (or its config or colliders last changed). Edits between steps
    /// (`set_position`, `pin`, …) are not reflected until the next step: use
    /// [`measure`](Self::measure) for the current state.
    #[must_use]
    pub fn stats(&self) -> &StepStats {
        &self.stats
    }

    /// Diagnostics of the current state, computed now (one pass over particles and springs).
    /// `contacts` and `solver` are those of the last step.
    #[must_use]
    pub fn measure(&self) -> StepStats {
        let (mut stats, _) = measure(
            &self.config,
            &self.topology,
            &self.particles,
            &self.colliders,
            &mut Vec::new(),
        );
        stats.step = self.steps;
        stats.time = self.time;
        stats.contacts = self.stats.contacts;
        stats.solver = self.stats.solver;
        stats
    }

    fn check_index(&self, name: &str, i: usize) -> Result<()> {
        if i < self.particles.len() {
            Ok(())
        } else {
            Err(ClothError::IndexOutOfRange {
                name: name.into(),
                index: i,
                len: self.particles.len(),
            })
        }
    }

    /// Pins particle `i` where it is, at rest.
    pub fn pin(&mut self, i: usize) -> Result<()> {
        self.check_index("pin", i)?;
        self.particles.inv_mass[i] = 0.0;
        self.particles.velocity[i] = Vec3::ZERO;
        Ok(())
    }

    /// Unpins particle `i`; it keeps its current velocity and gets its own mass back.
    pub fn unpin(&mut self, i: usize) -> Result<()> {
        self.check_index("unpin", i)?;
        self.particles.inv_mass[i] = 1.0 / self.particles.mass[i];
        self.pin_target[i] = None;
        Ok(())
    }

    /// How far a pin target may be from its particle, m: `limits.max_speed · dt`, the distance
    /// the fastest particle allowed covers in a step ([`set_pin_target`](Self::set_pin_target)).
    #[must_use]
    pub fn pin_target_reach(&self) -> f32 {
        self.config.limits.max_speed * self.config.dt
    }

    /// Moves pinned particle `i` to `target` (m) over the next step, at constant velocity:
    /// an animated attachment. Call it before every step to follow a path. The target is
    /// within [`pin_target_reach`](Self::pin_target_reach) of the particle: a pin faster than
    /// `limits.max_speed` is refused (it would tear the cloth apart and make every step fail).
    pub fn set_pin_target(&mut self, i: usize, target: Vec3) -> Result<()> {
        self.check_index("set_pin_target", i)?;
        check::finite_vec("set_pin_target.target", target)?;
        if !self.particles.is_pinned(i) {
            return Err(ClothError::invalid(
                "set_pin_target index",
                i,
                "a pinned particle (pin it first)",
            ));
        }
        // The pin's speed as the step will take it.
        let x = self.particles.position[i];
        let speed = pin_velocity(target, x, self.config.dt).as_dvec3().length();
        if speed > f64::from(self.config.limits.max_speed) {
            return Err(ClothError::invalid(
                "set_pin_target.target",
                target,
                format!(
                    "a point at most {:.4e} m from the particle's position {x} (\
                     `limits.max_speed` × `dt` = {} m/s × {} s; it would move the pin at \
                     {speed:.4e} m/s)",
                    self.pin_target_reach(),
                    self.config.limits.max_speed,
                    self.config.dt
                ),
            ));
        }
        self.pin_target[i] = Some(target);
        Ok(())
    }

    /// Teleports particle `i` to `position` (m).
    pub fn set_position(&mut self, i: usize, position: Vec3) -> Result<()> {
        self.check_index("set_position", i)?;
        check::finite_vec("set_position.position", position)?;
        self.particles.position[i] = position;
        Ok(())
    }

    /// Sets the velocity of particle `i` (m/s), at most `limits.max_speed` fast. Pinned
    /// particles ignore it until unpinned.
    pub fn set_velocity(&mut self, i: usize, velocity: Vec3) -> Result<()> {
        self.check_index("set_velocity", i)?;
        check::finite_vec("set_velocity.velocity", velocity)?;
        check_speed(|| "set_velocity.velocity".into(), velocity, &self.config)?;
        if !self.particles.is_pinned(i) {
            self.particles.velocity[i] = velocity;
        }
        Ok(())
    }

    /// The force each pin exerts on the cloth to hold its particle, N: for pinned particle i,
    /// R_i = −F_i, with F_i every other force on it at the current state (springs, gravity,
    /// damping, air). Returns `(particle, force)` pairs in index order. At rest, the pins
    /// together carry the whole weight: Σ R_i = −Σ m·g.
    pub fn pin_reactions(&mut self) -> Vec<(u32, Vec3)> {
        let wind = self.config.air.wind_at(self.time);
        let force = self
            .solver
            .forces(&self.config, &self.topology, &self.particles, wind);
        self.particles
            .inv_mass
            .iter()
            .enumerate()
            .filter(|&(_, &w)| w == 0.0)
            .map(|(i, _)| (i as u32, -force[i]))
            .collect()
    }

    /// Self-contact diagnostics of the cloth now: the exact number of intersecting triangle
    /// pairs (sharing no vertex) and the smallest distance from a particle to a triangle that
    /// is not its neighbour, looking within `range` m (see [`crate::collide::intersect`]).
    /// `range` defaults to the self-collision thickness when `None`, or to the cloth's
    /// largest rest spacing when self-collision is off. Not allocating after the first call.
    ///
    /// # Errors
    /// [`ClothError::InvalidArgument`] when `range` is not a finite length > 0.
    pub fn self_contact(
        &mut self,
        range: Option<f32>,
    ) -> Result<crate::collide::intersect::SelfContact> {
        let range = range.unwrap_or_else(|| match self.config.self_collision {
            Some(sc) => sc.thickness,
            None => largest_spacing(&self.topology),
        });
        self.contact_check.run(
            &self.particles.position,
            &self.rest_position,
            self.topology.triangles(),
            range,
        )
    }

    /// The contacts of the current state, for display and inspection (appended to `out`):
    /// every free particle within the contact layer of a collider (distance to the surface at
    /// most the thickness plus 10 % of it plus 0.1 mm), with the collider's outward normal,
    /// and, with self-collision on, every pair of particles closer than 1.05 × the
    /// self-collision thickness that were further apart than that in the rest shape (layers
    /// touching, not neighbours), with the unit vector from the other particle to this one.
    pub fn contacts(&self, out: &mut Vec<Contact>) {
        for (ci, col) in self.colliders.iter().enumerate() {
            let reach = 1.1 * col.thickness + 1e-4;
            for (i, &x) in self.particles.position.iter().enumerate() {
                if self.particles.inv_mass[i] == 0.0 {
                    continue;
                }
                let (d, n) = col.shape.distance_within(x, col.contact_range());
                if d <= reach && n != Vec3::ZERO {
                    out.push(Contact {
                        particle: i as u32,
                        normal: n,
                        with: ContactWith::Collider(ci as u32),
                    });
                }
            }
        }
        if let Some(sc) = self.config.self_collision {
            crate::collide::self_collision::layer_contacts(
                &self.particles,
                &self.rest_position,
                1.05 * sc.thickness,
                out,
            );
        }
    }

    /// The rest shape: the positions of the cloth as built, m.
    #[must_use]
    pub fn rest_positions(&self) -> &[Vec3] {
        &self.rest_position
    }

    /// Total force of the springs, dashpots, damping and air on each particle right now
    /// (gravity included), N. Useful for force-balance checks.
    pub fn forces(&mut self) -> &[Vec3] {
        let wind = self.config.air.wind_at(self.time);
        self.solver
            .forces(&self.config, &self.topology, &self.particles, wind)
    }

    fn refresh_stats(&mut self) {
        self.stats = self.measure();
    }

    /// Advances one step of [`SimConfig::dt`] seconds (see the type's docs for the stages).
    ///
    /// # Errors
    /// [`ClothError::Unstable`] when the step would leave a non-finite or runaway state; the
    /// simulation then keeps the state it had before the call.
    pub fn step(&mut self) -> Result<StepStats> {
        // 1. snapshot (the colliders here; the particles below, in parallel)
        self.backup_colliders.clone_from(&self.colliders);
        let n = self.particles.len();
        if self.backup_position.len() != n {
            self.backup_position.resize(n, Vec3::ZERO);
            self.backup_velocity.resize(n, Vec3::ZERO);
        }

        self.solver.begin_step();
        let dt = self.config.dt;
        let h = self.config.substep_dt();
        let mut contacts = ContactStats::default();
        let (time, config, topology, rest) =
            (self.time, &self.config, &self.topology, &self.rest_position);
        let (colliders, solver, particles, pin_target, backup_colliders) = (
            &mut self.colliders,
            &mut self.solver,
            &mut self.particles,
            &self.pin_target,
            &self.backup_colliders,
        );
        let (backup_position, backup_velocity, measure_lengths) = (
            &mut self.backup_position,
            &mut self.backup_velocity,
            &mut self.measure_lengths,
        );
        // Stages 1 to 5 with the pool's threads kept awake: the copies and the diagnostics'
        // parallel passes then start at once instead of waking a sleeping thread for each.
        let (mut stats, bad) = crate::solver::with_pool_awake(|| {
            copy_in_parallel(backup_position, &particles.position);
            copy_in_parallel(backup_velocity, &particles.velocity);

            let any_pinned = particles.any_pinned();
            // Stages 2 and 3 run again from the snapshot when the solver asks for it
            // (`Solver::take_redo`: a substep that lost its old state); at most once.
            loop {
                // 2. pins (stages 2 and 4 touch only pinned particles: skipped when there
                //    are none, which one vectorised pass over the inverse masses tells)
                if any_pinned {
                    for (i, target) in pin_target.iter().enumerate() {
                        if particles.inv_mass[i] != 0.0 {
                            continue;
                        }
                        particles.velocity[i] = match target {
                            Some(t) => pin_velocity(*t, particles.position[i], dt),
                            None => Vec3::ZERO,
                        };
                    }
                }

                // 3. substeps
                for s in 0..config.substeps {
                    let t = time + f64::from(h) * f64::from(s);
                    for c in colliders.iter_mut() {
                        c.advance(h);
                    }
                    solver.substep(
                        config.integrator,
                        SubstepCtx {
                            particles,
                            topology,
                            config,
                            colliders,
                            wind: config.air.wind_at(t),
                            h,
                            contacts: &mut contacts,
                            rest,
                            pinned: any_pinned,
                        },
                    );
                }

                solver.end_step(particles);
                if !solver.take_redo() {
                    break;
                }
                copy_in_parallel(&mut particles.position, backup_position);
                copy_in_parallel(&mut particles.velocity, backup_velocity);
                colliders.clone_from(backup_colliders);
                contacts = ContactStats::default();
                solver.begin_step();
            }

            // 4. pins (the targets are cleared only once the step is accepted, so that a
            //    failed step leaves them set, like the rest of the state)
            if any_pinned {
                for (i, target) in pin_target.iter().enumerate() {
                    if particles.inv_mass[i] != 0.0 {
                        continue;
                    }
                    if let Some(t) = *target {
                        particles.position[i] = t;
                    }
                    particles.velocity[i] = Vec3::ZERO;
                }
            }

            // 5. diagnostics and instability check: a collider whose prescribed motion carried
            //    it past f32's range fails the step first (the particles it touched then went
            //    bad because of it), then the particles and springs, then a solve that
            //    overflowed.
            let (stats, bad) = measure(config, topology, particles, colliders, measure_lengths);
            let overflow = solver.take_overflow();
            let collider = colliders
                .iter()
                .position(|c| !c.shape.is_finite())
                .map(|i| crate::diagnostics::Instability {
                    particle: 0,
                    reason: format!(
                        "collider {i}'s pose became non-finite (its velocity or angular \
                         velocity carried it past f32's range): {:?}",
                        colliders[i].shape
                    ),
                });
            let bad = collider.or(bad).or_else(|| {
                if !overflow {
                    return None;
                }
                // Name the particle whose acceleration is the largest: the forces that were
                // too large to solve for.
                let mut force = vec![Vec3::ZERO; particles.len()];
                crate::forces::accumulate(
                    config,
                    topology,
                    particles,
                    config.air.wind_at(time),
                    &mut force,
                );
                let accel =
                    |i: usize| f64::from(particles.inv_mass[i]) * force[i].as_dvec3().length();
                let i =
                    (0..particles.len()).fold(0, |a, i| if accel(i) > accel(a) { i } else { a });
                Some(crate::diagnostics::Instability {
                    particle: i as u32,
                    reason: format!(
                        "implicit Euler's linear solve overflowed f32: the largest \
                         acceleration, on this particle, is {:.3e} m/s² (forces this large \
                         cannot be solved for)",
                        accel(i)
                    ),
                })
            });
            (stats, bad)
        });
        if let Some(bad) = bad {
            self.particles.position.clone_from(&self.backup_position);
            self.particles.velocity.clone_from(&self.backup_velocity);
            self.colliders.clone_from(&self.backup_colliders);
            let mut hint = instability_hint(
                &self.config,
                crate::diagnostics::explicit_stability_limit_of(
                    &self.config,
                    &self.topology,
                    &self.particles,
                ),
            );
            // The step's pin targets are the user's input: name the fastest moving pin.
            let pins = self.pin_target.iter().zip(&self.particles.position);
            let velocity = pins.map(|(t, &x)| t.map_or(Vec3::ZERO, |t| pin_velocity(t, x, dt)));
            if let Some((i, _, speed)) = fastest(velocity).filter(|f| f.2 > 0.0) {
                hint.push_str(&format!(
                    "; this step's pin targets (`set_pin_target`) move particle {i} at up to \
                     {speed:.3e} m/s"
                ));
            }
            return Err(ClothError::Unstable {
                step: self.steps,
                time: self.time,
                particle: bad.particle,
                reason: bad.reason,
                hint,
            });
        }
        self.pin_target.fill(None);
        self.steps = self.steps.saturating_add(1);
        self.time += f64::from(dt);
        stats.step = self.steps;
        stats.time = self.time;
        stats.contacts = contacts.contacts;
        stats.ccd_corrections = contacts.ccd;
        stats.solver = self.solver.stats();
        self.stats = stats;
        Ok(stats)
    }
}

/// `dst.copy_from_slice(src)` in chunks shared among the current rayon pool's threads (a
/// copy: the same bits however the chunks are shared).
fn copy_in_parallel(dst: &mut [Vec3], src: &[Vec3]) {
    use rayon::prelude::*;
    const CHUNK: usize = 4096;
    dst.par_chunks_mut(CHUNK)
        .zip(src.par_chunks(CHUNK))
        .for_each(|(d, s)| d.copy_from_slice(s));
}
