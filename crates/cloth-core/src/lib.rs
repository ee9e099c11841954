//! # cloth-core
//!
//! A mass-spring cloth simulator: a grid of particles joined by structural, shear and bending
//! springs, under gravity, damping, air and wind, colliding with spheres, capsules, boxes,
//! planes, triangle meshes and itself, stepped by interchangeable integrators (forward and
//! symplectic Euler, position Verlet, implicit Euler, XPBD). No graphics dependencies.
//!
//! ## Conventions
//! SI units throughout (metres, kilograms, seconds, newtons). Y is up; coordinates are
//! right-handed. Particle `(row, col)` of a grid has index `row * cols + col`.
//!
//! ## Example
//! ```
//! use cloth_core::{Collider, Friction, GridBuilder, Integrator, SimConfig, Simulation};
//! use glam::Vec3;
//!
//! // The seed's scene: a cloth dropped onto a ball.
//! let cloth = GridBuilder::new(24, 24)
//!     .size(1.0, 1.0)
//!     .origin(Vec3::new(0.0, 0.8, 0.0))
//!     .build()?;
//! let config = SimConfig { integrator: Integrator::SymplecticEuler, ..SimConfig::default() };
//! let mut sim = Simulation::new(cloth, config)?;
//! sim.add_collider(Collider::sphere(Vec3::ZERO, 0.3).with_friction(Friction::new(0.8, 0.6)))?;
//! for _ in 0..60 {
//!     let stats = sim.step()?;
//!     assert!(stats.max_penetration <= 1e-6);
//! }
//! # Ok::<(), cloth_core::ClothError>(())
//! ```
//!
//! ## Modules
//! - [`grid`]: the grid builder, producing a [`Cloth`] (particles + topology);
//! - [`particles`]: structure-of-arrays particle state;
//! - [`topology`]: springs by kind in one flat `Vec`, triangles;
//! - [`config`]: every parameter, with units and defaults;
//! - [`forces`]: gravity, springs, dashpots, damping, air;
//! - [`collide`]: colliders and contact response with Coulomb friction, continuous collision,
//!   self-collision;
//! - [`diagnostics`]: per-step energies, strains, penetration, instability check;
//! - [`presets`]: ready-made scenes built in code;
//! - `scene` (feature `scene`, on by default): TOML scene files, the built-in scenes;
//! - [`simd`]: the run-time choice of the fast path's instruction set;
//! - [`error`]: [`ClothError`], the crate's one error type;
//! - [`Simulation`]: the step pipeline.

// `unsafe` is denied everywhere but in `simd` and `solver/shared_rows.rs` (and the few blocks of
// `solver/grid_kernel.rs` that call `SharedRows`), whose unsafe calls carry `SAFETY` comments.
#![deny(unsafe_code)]
// `!(x > 0.0)` is the deliberate NaN-catching test of the contact code.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
#![warn(missing_docs)]

pub mod collide;
pub mod config;
pub mod diagnostics;
pub mod error;
pub mod forces;
pub mod grid;
pub mod particles;
pub mod presets;
#[cfg(feature = "scene")]
pub mod scene;
mod sim;
pub mod simd;
mod solver;
pub mod topology;

pub use collide::intersect::SelfContact;
pub use collide::self_collision::SelfCollision;
pub use collide::{Collider, Friction, Shape, TriMesh};
pub use config::{
    Air, ForceSwitches, Gust, ImplicitSettings, Integrator, Material, SimConfig, SpringParams,
    StabilityLimits, XpbdSettings,
};
pub use diagnostics::{SolverStats, StepStats};
pub use error::{ClothError, Result};
pub use glam;
pub use grid::{Cloth, Corner, Edge, GridBuilder, Mass, Orientation};
pub use particles::Particles;
pub use sim::{Contact, ContactWith, MAX_SELF_COLLISION_SPACINGS, SimState, Simulation};
pub use topology::{Spring, SpringClass, SpringKind, Topology};

/// The README's examples, compiled and run as doc-tests.
#[doc = include_str!("../../../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;

/// Seeded numbers for the unit tests.
#[cfg(test)]
mod test_rng {
    /// Uniform numbers in [0, 1) from a xorshift64 generator started at `seed` (24 bits each,
    /// exact in `f32`): the same sequence on every run.
    pub(crate) fn uniform(mut seed: u64) -> impl FnMut() -> f32 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 40) as f32 / (1u64 << 24) as f32
        }
    }
}
