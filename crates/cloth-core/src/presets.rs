//! Ready-made scenes, built in code: the seed's drape (and its real-time XPBD setting), a
//! hanging curtain, and the peer benchmark's cloth on a ball. Each returns a [`Simulation`]
//! ready to step.

use glam::Vec3;

use crate::collide::{Collider, Friction};
use crate::config::{Air, Integrator, Material, SimConfig, SpringParams};
use crate::diagnostics::{explicit_stability_limit, explicit_stability_limit_of};
use crate::error::{ClothError, Result};
use crate::grid::{Cloth, GridBuilder, Mass};
use crate::sim::Simulation;

/// Substeps per step that keep symplectic Euler and Verlet inside the stiffness-only stability
/// estimate of [`explicit_stability_limit`] with a safety factor of 1.25. "auto" substeps
/// ([`tune_for_integrator`]) take the cloth's own bound, dashpots and damping included.
#[must_use]
pub fn stable_substeps(config: &SimConfig, min_mass: f32) -> u32 {
    substeps_within(config, explicit_stability_limit(config, min_mass))
}

/// Substeps per step that keep the substep under `limit` (s) with a safety factor of 1.25
/// (at least 1, at most [`crate::config::MAX_SUBSTEPS`]).
fn substeps_within(config: &SimConfig, limit: f32) -> u32 {
    ((1.25 * config.dt / limit).ceil() as u32).clamp(1, crate::config::MAX_SUBSTEPS)
}

/// Chooses the substeps of `config.integrator` for `cloth`: the explicit integrators stay
/// 1.25× under [`explicit_stability_limit_of`] (the Gershgorin bound of each free particle's
/// springs, dashpots and damping, never above the stiffness-only [`explicit_stability_limit`];
/// the dashpots set it at high resolutions); implicit Euler takes one substep per 1/60 s step
/// (it is stable at any step); XPBD 20 substeps per 1/60 s. Never more than
/// [`crate::config::MAX_SUBSTEPS`].
pub fn tune_for_integrator(config: &mut SimConfig, cloth: &Cloth) {
    let per_frame = |substeps: f64| {
        // dt in 1/60 s frames, in f64: the f32 nearest 1/60 lies 3·10⁻⁹ above it, and its
        // 20 substeps per frame in f32 (20.000002) rounded up to 21. A count within a
        // millionth of a whole number is that number. (A float-to-int cast saturates.)
        let wanted = f64::from(config.dt) * 60.0 * substeps;
        let whole = wanted.round();
        let count = if (wanted - whole).abs() <= 1e-6 * whole {
            whole
        } else {
            wanted.ceil()
        };
        (count as u32).clamp(1, crate::config::MAX_SUBSTEPS)
    };
    config.substeps = match config.integrator {
        Integrator::ImplicitEuler => per_frame(1.0),
        Integrator::Xpbd => per_frame(20.0),
        _ => substeps_within(
            config,
            explicit_stability_limit_of(config, &cloth.topology, &cloth.particles),
        ),
    };
}

/// A built-in scene with its resolution set to `n × n` and its integrator to `integrator`
/// (substeps "auto", see [`tune_for_integrator`]).
#[cfg(feature = "scene")]
fn builtin_at(name: &str, n: usize, integrator: Integrator) -> Result<Simulation> {
    let mut scene = crate::scene::builtin(name).expect("built-in scene");
    let side = u32::try_from(n).unwrap_or(u32::MAX);
    scene.cloth.resolution = [side, side];
    scene.solver.kind = integrator.name().into();
    scene.solver.substeps = crate::scene::SubstepsDesc::default();
    scene.build()
}

/// The seed paper's scene (`scenes/drape.toml`) at `n × n` particles: a 1.2 m cloth,
/// 0.2 kg/m², dropped flat from 0.55 m onto a ball of radius 0.3 m resting on the ground
/// (y = −0.3), with friction μ_s = 0.6, μ_k = 0.5 on both. Substeps from
/// [`tune_for_integrator`].
#[cfg(feature = "scene")]
pub fn drape(n: usize, integrator: Integrator) -> Result<Simulation> {
    builtin_at("drape", n, integrator)
}

/// The drape of issue 7's real-time target at `n × n` particles, as
/// `scripts/realtime-series.sh` and the criterion benches run it: XPBD with `substeps`
/// substeps, each with `rounds` rounds of chain solves of two Newton iterations relaxed by
/// `relaxation` (`xpbd.chains`, `xpbd.chain_rounds`, `xpbd.chain_iterations`,
/// `xpbd.chain_relaxation`), the shear springs swept row by row (`xpbd.shear_rows`) and the
/// 2 % structural strain limit (`xpbd.structural_limit`); the scene's global damping, set for
/// its native 48², scaled by (48/n)² so that the cloth's total damping, and so its fall, is
/// the same at every resolution. 3 substeps of 2 rounds (relaxation 1) meet the strain
/// figures at 256², 4 of 4 with relaxation 1.3 at 512² (4 of 5 with relaxation 1).
///
/// # Errors
/// As [`drape`], and [`ClothError::InvalidArgument`] for `substeps` outside
/// `1 ..= MAX_SUBSTEPS`, `rounds` outside `1 ..= 16` or `relaxation` outside `(0, 2)`.
#[cfg(feature = "scene")]
pub fn realtime_drape(n: usize, substeps: u32, rounds: u32, relaxation: f32) -> Result<Simulation> {
    let native = crate::scene::builtin("drape").expect("built-in scene");
    let side = native.cloth.resolution[0] as f32;
    let mut sim = drape(n, Integrator::Xpbd)?;
    let mut config = *sim.config();
    config.substeps = substeps;
    config.damping *= (side / n as f32).powi(2);
    config.xpbd.chains = true;
    config.xpbd.chain_iterations = 2;
    config.xpbd.chain_rounds = rounds;
    config.xpbd.chain_relaxation = relaxation;
    config.xpbd.structural_limit = Some(0.02);
    config.xpbd.shear_rows = true;
    sim.set_config(config)?;
    Ok(sim)
}

/// A curtain (`scenes/hanging.toml`) at `n × n` particles: 1 m square, 0.2 kg/m², pinned along
/// its top edge at y = 1.5 m, above the ground. Substeps from [`tune_for_integrator`].
#[cfg(feature = "scene")]
pub fn hanging(n: usize, integrator: Integrator) -> Result<Simulation> {
    builtin_at("hanging", n, integrator)
}

/// The scene of the peer benchmark (Taichi's `mass_spring_3d_ggui` example): `n × n`
/// particles of 1 kg, spacing q = 1/n, flat at y = 0.6 over x, z ∈ [−0.5, 0.5) shifted by
/// (0.0372, 0.0276); springs to all neighbours with |di| + |dj| ≤ 2 (our structural, shear and
/// bend classes) with k = Y/L0, Y = 3·10⁴, and dashpots c = 10⁴·q; gravity 9.8 m/s²; the
/// drag v ← v·e^(−h) as global damping d = 1 N·s/m; a frictionless ball of radius 0.3 at the
/// origin with zero thickness; symplectic Euler with h = 0.04/n and 53 substeps per step
/// (n = 128: h = 3.125·10⁻⁴ s).
///
/// The one difference from the peer: our contact also projects a particle that is inside the
/// ball back to its surface, where the peer only removes the inward velocity.
///
/// # Errors
/// [`ClothError::InvalidArgument`] for `n` outside `3 ..= 8192` (the peer's step takes
/// ⌊(1/60)/(0.04/n)⌋ substeps, none below n = 3).
pub fn peer_ball(n: usize) -> Result<Simulation> {
    if !(3..=crate::grid::MAX_GRID_SIDE).contains(&n) {
        return Err(ClothError::invalid(
            "peer_ball n",
            n,
            format!("3 ..= {}", crate::grid::MAX_GRID_SIDE),
        ));
    }
    let q = 1.0 / n as f32;
    let (ox, oz) = (0.037_153_453_f32, 0.027_561_575_f32);
    let centre = -0.5 + 0.5 * (n - 1) as f32 * q;
    let cloth = GridBuilder::new(n, n)
        .spacing(q, q)
        .origin(Vec3::new(centre + ox, 0.6, centre + oz))
        .mass(Mass::PerParticle(1.0))
        .build()?;
    let young = 3.0e4;
    let c = 1.0e4 * q;
    let h = 0.04 / n as f32;
    let substeps = ((1.0 / 60.0) / (0.04 / n as f64)) as u32;
    let config = SimConfig {
        dt: h * substeps as f32,
        substeps,
        integrator: Integrator::SymplecticEuler,
        gravity: Vec3::new(0.0, -9.8, 0.0),
        damping: 1.0,
        material: Material::isotropic(
            SpringParams::new(young / q, c),
            SpringParams::new(young / (std::f32::consts::SQRT_2 * q), c),
            SpringParams::new(young / (2.0 * q), c),
        ),
        air: Air {
            density: 0.0,
            ..Air::default()
        },
        ..SimConfig::default()
    };
    let mut sim = Simulation::new(cloth, config)?;
    sim.add_collider(
        Collider::sphere(Vec3::ZERO, 0.3)
            .with_thickness(0.0)
            .with_friction(Friction::NONE),
    )?;
    Ok(sim)
}
