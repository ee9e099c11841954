//! # cloth-view
//!
//! The viewer of the cloth simulator: a wgpu renderer (cloth, colliders, ground, wireframe and
//! springs), cameras with orbit and fly controllers, a winit window app with an egui panel,
//! and offscreen rendering to PNG.
//!
//! The data of one frame flows one way: scene → [`cloth_core::Simulation::step`] (on a
//! [`timestep::FixedStep`] accumulator) → diagnostics → [`renderer::Renderer::prepare`] →
//! [`renderer::Renderer::paint`]. Input flows back only through the camera controllers, the
//! picking ray and the panel's settings.
//!
//! ## Conventions
//! Right-handed, Y up, metres (as `cloth-core`); wgpu clip space (depth 0..1); pixels with
//! the origin at the top-left corner.

pub mod app;
pub mod camera;
pub mod gpu;
pub mod offscreen;
pub mod renderer;
pub mod scene;
pub mod timestep;
pub mod ui;

/// Vertical field of view of the main built-in scenes' hand-tuned framings, radians (40°).
pub const FOVY: f32 = 40.0 * std::f32::consts::PI / 180.0;

pub use camera::{Camera, FlyController, OrbitController, Projection, Ray};
pub use gpu::{Gpu, GpuError};
pub use offscreen::Offscreen;
pub use renderer::{RenderOptions, Renderer};
pub use scene::SceneKind;

/// The render options that suit `scene` (its display floor).
#[must_use]
pub fn default_options(scene: &SceneKind) -> RenderOptions {
    RenderOptions {
        floor: Some(scene.display_floor()),
        ..RenderOptions::default()
    }
}
