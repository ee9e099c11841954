//! Scene files: one TOML document describing a whole simulation (cloth, material, forces,
//! colliders, solver, run length, camera hint). `docs/scenes.md` documents every key.
//!
//! ```
//! use cloth_core::scene::Scene;
//! let scene = Scene::from_toml(r#"
//!     [cloth]
//!     resolution = [16, 16]
//!     size = [1.0, 1.0]
//!     origin = [0.0, 1.0, 0.0]
//!
//!     [[colliders]]
//!     type = "sphere"
//!     center = [0.0, 0.0, 0.0]
//!     radius = 0.4
//! "#, "inline.toml")?;
//! let mut sim = scene.build()?;
//! sim.step()?;
//! # Ok::<(), cloth_core::ClothError>(())
//! ```
//!
//! Errors name the file, the line and column, the key and what is allowed; unknown keys get
//! the closest known key as a suggestion.

use glam::{EulerRot, Quat, Vec3};
use serde::{Deserialize, Serialize};

use crate::collide::{Collider, Friction, Shape, range};
use crate::config::{
    Air, ForceSwitches, Gust, ImplicitSettings, Integrator, Material, SimConfig, SpringParams,
    StabilityLimits, XpbdSettings,
};
use crate::error::{ClothError, Result};
use crate::grid::{
    Cloth, Corner, Edge, GridBuilder, MAX_CLOTH_EXTENT, MAX_GRID_SIDE, Mass, Orientation,
};
use crate::presets::tune_for_integrator;
use crate::sim::Simulation;

/// A whole scene, as read from a TOML file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Short name. Default empty.
    #[serde(default)]
    pub name: String,
    /// One-line description. Default empty.
    #[serde(default)]
    pub description: String,
    /// Default run length of `cloth sim` (without `--frames` or `--seconds`), s, in `(0, 1e6]`
    /// ([`MAX_DURATION`]). Default 4 s.
    #[serde(default = "default_duration")]
    pub duration: f32,
    /// The cloth grid.
    pub cloth: ClothDesc,
    /// Spring parameters per kind.
    #[serde(default)]
    pub material: MaterialDesc,
    /// Gravity, damping, air.
    #[serde(default)]
    pub forces: ForcesDesc,
    /// Colliders (`[[colliders]]`).
    #[serde(default)]
    pub colliders: Vec<ColliderDesc>,
    /// Integrator and step.
    #[serde(default)]
    pub solver: SolverDesc,
    /// Where the viewer's camera starts.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<CameraDesc>,
}

/// Shortest distance from a `[camera]`'s eye to its target, m: closer, the camera has no
/// direction to look in (refused in a scene file; the viewer looks at the target from 2.5 m).
pub const MIN_CAMERA_DISTANCE: f32 = 1e-6;

/// Longest `duration` of a scene, s (11.6 days of simulated time; `cloth sim --seconds` has
/// the same bound).
pub const MAX_DURATION: f32 = 1.0e6;

/// An array of exactly `N` items: TOML's deserializer would fill a fixed-size array from
/// the first `N` items of a longer one and drop the rest silently.
fn exact<'de, D, T, const N: usize>(d: D) -> std::result::Result<[T; N], D::Error>
where
    D: serde::Deserializer<'de>,
    T: Deserialize<'de>,
{
    let items = Vec::<T>::deserialize(d)?;
    let len = items.len();
    items.try_into().map_err(|_| {
        serde::de::Error::invalid_length(len, &format!("an array of length {N}").as_str())
    })
}

/// [`exact`] for an optional array (a key that may be left out).
fn exact_opt<'de, D, T, const N: usize>(d: D) -> std::result::Result<Option<[T; N]>, D::Error>
where
    D: serde::Deserializer<'de>,
    T: Deserialize<'de>,
{
    exact(d).map(Some)
}

fn default_duration() -> f32 {
    4.0
}

/// `[cloth]`: the grid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClothDesc {
    /// `[rows, cols]`, each 2 ..= 8192.
    #[serde(deserialize_with = "exact")]
    pub resolution: [u32; 2],
    /// `[width, height]`, m. Default `[1, 1]`. Either `size` or `spacing`, not both.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[serde(deserialize_with = "exact_opt")]
    pub size: Option<[f32; 2]>,
    /// `[along_cols, along_rows]` particle spacing, m; instead of `size`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[serde(deserialize_with = "exact_opt")]
    pub spacing: Option<[f32; 2]>,
    /// `"horizontal"` (default) or `"vertical"`.
    #[serde(default)]
    pub orientation: OrientationDesc,
    /// Centre of the grid, m. Default `[0, 0, 0]`.
    #[serde(default)]
    #[serde(deserialize_with = "exact")]
    pub origin: [f32; 3],
    /// Rotation about the origin as XYZ Euler angles, degrees. Default `[0, 0, 0]`.
    #[serde(default)]
    #[serde(deserialize_with = "exact")]
    pub rotation: [f32; 3],
    /// Initial velocity, m/s. Default `[0, 0, 0]`.
    #[serde(default)]
    #[serde(deserialize_with = "exact")]
    pub velocity: [f32; 3],
    /// Areal density, kg/m². Default 0.2 unless `mass_per_particle` is given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub density: Option<f32>,
    /// Mass of every particle, kg; instead of `density`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass_per_particle: Option<f32>,
    /// Pinned particles.
    #[serde(default)]
    pub pins: PinsDesc,
}

/// Plane of the cloth before rotation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum OrientationDesc {
    /// XZ plane, normal +Y.
    #[default]
    Horizontal,
    /// XY plane, row 0 on top, normal +Z.
    Vertical,
}

impl OrientationDesc {
    /// Every orientation (the names a scene file takes).
    pub const ALL: [Self; 2] = [Self::Horizontal, Self::Vertical];
}

/// `[cloth.pins]`.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PinsDesc {
    /// Any of `"top-left"`, `"top-right"`, `"bottom-left"`, `"bottom-right"`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub corners: Vec<CornerDesc>,
    /// Any of `"top"`, `"bottom"`, `"left"`, `"right"`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub edges: Vec<EdgeDesc>,
    /// Particle indices `row * cols + col`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub indices: Vec<u32>,
}

/// A grid corner.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[allow(missing_docs)]
pub enum CornerDesc {
    TopLeft,
    TopRight,
    BottomLeft,
    BottomRight,
}

impl CornerDesc {
    /// Every corner (the names a scene file takes).
    pub const ALL: [Self; 4] = [
        Self::TopLeft,
        Self::TopRight,
        Self::BottomLeft,
        Self::BottomRight,
    ];
}

/// A grid edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[allow(missing_docs)]
pub enum EdgeDesc {
    Top,
    Bottom,
    Left,
    Right,
}

impl EdgeDesc {
    /// Every edge (the names a scene file takes).
    pub const ALL: [Self; 4] = [Self::Top, Self::Bottom, Self::Left, Self::Right];
}

/// `{ stiffness, damping }` of one spring kind.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpringDesc {
    /// N/m, `>= 0`.
    pub stiffness: f32,
    /// N·s/m, `>= 0`. Default 0.
    #[serde(default)]
    pub damping: f32,
}

impl From<SpringParams> for SpringDesc {
    fn from(p: SpringParams) -> Self {
        Self {
            stiffness: p.stiffness,
            damping: p.damping,
        }
    }
}

/// `[material]`: one table per spring kind; defaults are [`Material::default`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(missing_docs)]
pub struct MaterialDesc {
    #[serde(default = "d_warp")]
    pub warp: SpringDesc,
    #[serde(default = "d_weft")]
    pub weft: SpringDesc,
    #[serde(default = "d_shear")]
    pub shear: SpringDesc,
    #[serde(default = "d_bend")]
    pub bend: SpringDesc,
}

fn d_warp() -> SpringDesc {
    Material::default().warp.into()
}
fn d_weft() -> SpringDesc {
    Material::default().weft.into()
}
fn d_shear() -> SpringDesc {
    Material::default().shear.into()
}
fn d_bend() -> SpringDesc {
    Material::default().bend.into()
}

impl Default for MaterialDesc {
    fn default() -> Self {
        Self {
            warp: d_warp(),
            weft: d_weft(),
            shear: d_shear(),
            bend: d_bend(),
        }
    }
}

/// `[forces]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForcesDesc {
    /// m/s². Default `[0, -9.81, 0]`.
    #[serde(default = "d_gravity")]
    #[serde(deserialize_with = "exact")]
    pub gravity: [f32; 3],
    /// Global damping d in F = −d·v, N·s/m. Default 0.002.
    #[serde(default = "d_damping")]
    pub damping: f32,
    /// Air drag, lift and wind.
    #[serde(default)]
    pub air: AirDesc,
    /// Switches per force term (all on by default).
    #[serde(default)]
    pub enabled: EnabledDesc,
}

fn d_gravity() -> [f32; 3] {
    SimConfig::default().gravity.to_array()
}
fn d_damping() -> f32 {
    SimConfig::default().damping
}

impl Default for ForcesDesc {
    fn default() -> Self {
        Self {
            gravity: d_gravity(),
            damping: d_damping(),
            air: AirDesc::default(),
            enabled: EnabledDesc::default(),
        }
    }
}

/// `[forces.air]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AirDesc {
    /// kg/m³. Default 1.2.
    #[serde(default = "d_air_density")]
    pub density: f32,
    /// Drag coefficient. Default 1.0.
    #[serde(default = "d_drag")]
    pub drag: f32,
    /// Lift coefficient. Default 0.2.
    #[serde(default = "d_lift")]
    pub lift: f32,
    /// Steady wind, m/s. Default `[0, 0, 0]`.
    #[serde(default)]
    #[serde(deserialize_with = "exact")]
    pub wind: [f32; 3],
    /// Gusts `{ amplitude, frequency }`; none by default.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gust: Option<GustDesc>,
}

fn d_air_density() -> f32 {
    Air::default().density
}
fn d_drag() -> f32 {
    Air::default().drag_coefficient
}
fn d_lift() -> f32 {
    Air::default().lift_coefficient
}

impl Default for AirDesc {
    fn default() -> Self {
        Self {
            density: d_air_density(),
            drag: d_drag(),
            lift: d_lift(),
            wind: [0.0; 3],
            gust: None,
        }
    }
}

/// `[forces.air.gust]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GustDesc {
    /// 0 ..= 1. Default 0.5.
    #[serde(default = "d_gust_amp")]
    pub amplitude: f32,
    /// Hz, `> 0`. Default 0.5.
    #[serde(default = "d_gust_freq")]
    pub frequency: f32,
}

fn d_gust_amp() -> f32 {
    Gust::default().amplitude
}
fn d_gust_freq() -> f32 {
    Gust::default().frequency
}

/// `[forces.enabled]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(missing_docs)]
pub struct EnabledDesc {
    #[serde(default = "yes")]
    pub gravity: bool,
    #[serde(default = "yes")]
    pub springs: bool,
    #[serde(default = "yes")]
    pub dashpots: bool,
    #[serde(default = "yes")]
    pub damping: bool,
    #[serde(default = "yes")]
    pub air: bool,
}

fn yes() -> bool {
    true
}

impl Default for EnabledDesc {
    fn default() -> Self {
        Self {
            gravity: true,
            springs: true,
            dashpots: true,
            damping: true,
            air: true,
        }
    }
}

/// `[[colliders]]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ColliderDesc {
    /// `"sphere"`, `"plane"`, `"capsule"`, `"box"` or `"mesh"`.
    #[serde(rename = "type")]
    pub kind: ColliderKind,
    /// Sphere or box centre; a mesh's position (where its origin goes), m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[serde(deserialize_with = "exact_opt")]
    pub center: Option<[f32; 3]>,
    /// A mesh's Wavefront OBJ file, relative to the scene file (triangles counter-clockwise
    /// seen from outside).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<String>,
    /// The mesh read from `file` (filled by [`Scene::from_toml`] or
    /// [`Scene::load_meshes`]).
    #[serde(skip)]
    pub mesh: Option<std::sync::Arc<crate::collide::TriMesh>>,
    /// Sphere radius, m, `> 0`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f32>,
    /// A point on the plane, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[serde(deserialize_with = "exact_opt")]
    pub point: Option<[f32; 3]>,
    /// Plane outward normal (normalised).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[serde(deserialize_with = "exact_opt")]
    pub normal: Option<[f32; 3]>,
    /// Capsule axis start, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[serde(deserialize_with = "exact_opt")]
    pub a: Option<[f32; 3]>,
    /// Capsule axis end, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[serde(deserialize_with = "exact_opt")]
    pub b: Option<[f32; 3]>,
    /// Box half side lengths, m, each `> 0`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[serde(deserialize_with = "exact_opt")]
    pub half_extents: Option<[f32; 3]>,
    /// Box or mesh orientation as XYZ Euler angles, degrees. Default `[0, 0, 0]`.
    #[serde(default)]
    #[serde(deserialize_with = "exact")]
    pub rotation: [f32; 3],
    /// Angular velocity about the pivot (centre; capsule midpoint; plane point; a mesh's
    /// position, its `center`), rad/s.
    /// Default `[0, 0, 0]`.
    #[serde(default)]
    #[serde(deserialize_with = "exact")]
    pub angular_velocity: [f32; 3],
    /// Prescribed velocity, m/s. Default `[0, 0, 0]`.
    #[serde(default)]
    #[serde(deserialize_with = "exact")]
    pub velocity: [f32; 3],
    /// Contact thickness, m, `>= 0`. Default 0.01.
    #[serde(default = "d_thickness")]
    pub thickness: f32,
    /// Coulomb friction. Default `{ static = 0.5, kinetic = 0.4 }`.
    #[serde(default)]
    pub friction: FrictionDesc,
}

fn d_thickness() -> f32 {
    0.01
}

/// A collider's shape kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
#[allow(missing_docs)]
pub enum ColliderKind {
    Sphere,
    Plane,
    Capsule,
    Box,
    Mesh,
}

impl ColliderKind {
    /// Every shape kind (the names a scene file takes).
    pub const ALL: [Self; 5] = [
        Self::Sphere,
        Self::Plane,
        Self::Capsule,
        Self::Box,
        Self::Mesh,
    ];
}

impl ClothDesc {
    /// The grid's spacing `(along the columns, along the rows)`, m, from `spacing`, else
    /// `size` (default 1 m × 1 m) over the resolution (at least 2 each).
    fn spacing_of(&self) -> (f64, f64) {
        let [rows, cols] = self.resolution.map(|n| f64::from(n.max(2) - 1));
        match (self.spacing, self.size) {
            (Some([along_cols, along_rows]), _) => (f64::from(along_cols), f64::from(along_rows)),
            (None, Some([w, h])) => (f64::from(w) / cols, f64::from(h) / rows),
            (None, None) => (1.0 / cols, 1.0 / rows),
        }
    }
}

/// `friction = { static, kinetic }`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrictionDesc {
    /// μ_s, `>= 0`. Default 0.5.
    #[serde(rename = "static", default = "d_mus")]
    pub static_coefficient: f32,
    /// μ_k, `>= 0`. Default 0.4.
    #[serde(rename = "kinetic", default = "d_muk")]
    pub kinetic_coefficient: f32,
}

fn d_mus() -> f32 {
    Friction::default().static_coefficient
}
fn d_muk() -> f32 {
    Friction::default().kinetic_coefficient
}

impl Default for FrictionDesc {
    fn default() -> Self {
        Self {
            static_coefficient: d_mus(),
            kinetic_coefficient: d_muk(),
        }
    }
}

/// `substeps = 12` or `substeps = "auto"`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(untagged)]
pub enum SubstepsDesc {
    /// A fixed count, 1 ..= 100000.
    Count(u32),
    /// `"auto"`: chosen per integrator (see [`tune_for_integrator`]).
    Word(String),
}

impl<'de> Deserialize<'de> for SubstepsDesc {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct Visitor;
        impl serde::de::Visitor<'_> for Visitor {
            type Value = SubstepsDesc;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("an integer 1 ..= 100000 or \"auto\"")
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> std::result::Result<Self::Value, E> {
                u32::try_from(v)
                    .map(SubstepsDesc::Count)
                    .map_err(|_| E::invalid_value(serde::de::Unexpected::Signed(v), &self))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> std::result::Result<Self::Value, E> {
                u32::try_from(v)
                    .map(SubstepsDesc::Count)
                    .map_err(|_| E::invalid_value(serde::de::Unexpected::Unsigned(v), &self))
            }
            fn visit_str<E: serde::de::Error>(
                self,
                v: &str,
            ) -> std::result::Result<Self::Value, E> {
                Ok(SubstepsDesc::Word(v.to_string()))
            }
        }
        d.deserialize_any(Visitor)
    }
}

impl Default for SubstepsDesc {
    fn default() -> Self {
        Self::Word("auto".into())
    }
}

/// `[solver]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverDesc {
    /// `"forward-euler"`, `"symplectic-euler"` (default), `"verlet"`, `"implicit-euler"` or
    /// `"xpbd"`.
    #[serde(default = "d_kind")]
    pub kind: String,
    /// Step per frame, s, `> 0`. Default 1/60.
    #[serde(default = "d_dt")]
    pub dt: f32,
    /// Substeps per step, or `"auto"` (default).
    #[serde(default)]
    pub substeps: SubstepsDesc,
    /// Provot strain limit for the force-based integrators, `> 0`; none by default.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub strain_limit: Option<f32>,
    /// `{ tolerance, max_iterations }`.
    #[serde(default)]
    pub implicit: ImplicitDesc,
    /// `{ iterations, tethers, tether_slack, hierarchy_levels, hierarchy_slack,
    /// structural_limit, chains, chain_iterations, chain_rounds, chain_relaxation, shear_chains,
    /// shear_rows }`
    /// (see [`XpbdDesc`]).
    #[serde(default)]
    pub xpbd: XpbdDesc,
    /// `{ max_stretch_ratio, max_speed }`.
    #[serde(default)]
    pub limits: LimitsDesc,
    /// Cloth–cloth contact `{ thickness, friction }`; off when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub self_collision: Option<SelfCollisionDesc>,
    /// Continuous collision against the colliders. Default `true`.
    #[serde(default = "d_true")]
    pub continuous_collision: bool,
}

fn d_true() -> bool {
    true
}

/// `[solver.self_collision]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SelfCollisionDesc {
    /// Distance particles keep from each other, m, `> 0`. Default 0.01.
    #[serde(default = "d_sc_thickness")]
    pub thickness: f32,
    /// Friction between layers, `>= 0`. Default 0.3.
    #[serde(default = "d_sc_friction")]
    pub friction: f32,
}

fn d_sc_thickness() -> f32 {
    crate::SelfCollision::default().thickness
}
fn d_sc_friction() -> f32 {
    crate::SelfCollision::default().friction
}

fn d_kind() -> String {
    Integrator::default().name().into()
}
fn d_dt() -> f32 {
    SimConfig::default().dt
}

impl Default for SolverDesc {
    fn default() -> Self {
        Self {
            kind: d_kind(),
            dt: d_dt(),
            substeps: SubstepsDesc::default(),
            strain_limit: None,
            implicit: ImplicitDesc::default(),
            xpbd: XpbdDesc::default(),
            limits: LimitsDesc::default(),
            self_collision: None,
            continuous_collision: true,
        }
    }
}

/// `[solver.implicit]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(missing_docs)]
pub struct ImplicitDesc {
    #[serde(default = "d_tol")]
    pub tolerance: f32,
    #[serde(default = "d_maxit")]
    pub max_iterations: u32,
}
fn d_tol() -> f32 {
    ImplicitSettings::default().tolerance
}
fn d_maxit() -> u32 {
    ImplicitSettings::default().max_iterations
}
impl Default for ImplicitDesc {
    fn default() -> Self {
        Self {
            tolerance: d_tol(),
            max_iterations: d_maxit(),
        }
    }
}

/// `[solver.xpbd]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(missing_docs)]
pub struct XpbdDesc {
    #[serde(default = "d_iter")]
    pub iterations: u32,
    #[serde(default = "yes")]
    pub tethers: bool,
    #[serde(default = "d_slack")]
    pub tether_slack: f32,
    #[serde(default)]
    pub hierarchy_levels: u32,
    #[serde(default = "d_hslack")]
    pub hierarchy_slack: f32,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub structural_limit: Option<f32>,
    #[serde(default)]
    pub chains: bool,
    #[serde(default = "d_chain_iter")]
    pub chain_iterations: u32,
    #[serde(default = "d_chain_rounds")]
    pub chain_rounds: u32,
    #[serde(default = "d_chain_relaxation")]
    pub chain_relaxation: f32,
    #[serde(default)]
    pub shear_chains: bool,
    #[serde(default)]
    pub shear_rows: bool,
}
fn d_chain_rounds() -> u32 {
    XpbdSettings::default().chain_rounds
}
fn d_chain_relaxation() -> f32 {
    XpbdSettings::default().chain_relaxation
}
fn d_chain_iter() -> u32 {
    XpbdSettings::default().chain_iterations
}
fn d_hslack() -> f32 {
    XpbdSettings::default().hierarchy_slack
}
fn d_iter() -> u32 {
    XpbdSettings::default().iterations
}
fn d_slack() -> f32 {
    XpbdSettings::default().tether_slack
}
impl Default for XpbdDesc {
    fn default() -> Self {
        Self {
            iterations: d_iter(),
            tethers: true,
            tether_slack: d_slack(),
            hierarchy_levels: 0,
            hierarchy_slack: d_hslack(),
            structural_limit: None,
            chains: false,
            chain_iterations: d_chain_iter(),
            chain_rounds: d_chain_rounds(),
            chain_relaxation: d_chain_relaxation(),
            shear_chains: false,
            shear_rows: false,
        }
    }
}

/// `[solver.limits]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(missing_docs)]
pub struct LimitsDesc {
    #[serde(default = "d_stretch")]
    pub max_stretch_ratio: f32,
    #[serde(default = "d_speed")]
    pub max_speed: f32,
}
fn d_stretch() -> f32 {
    StabilityLimits::default().max_stretch_ratio
}
fn d_speed() -> f32 {
    StabilityLimits::default().max_speed
}
impl Default for LimitsDesc {
    fn default() -> Self {
        Self {
            max_stretch_ratio: d_stretch(),
            max_speed: d_speed(),
        }
    }
}

/// `[camera]`: where the viewer starts.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDesc {
    /// Eye position, m.
    #[serde(deserialize_with = "exact")]
    pub eye: [f32; 3],
    /// Look-at point, m.
    #[serde(deserialize_with = "exact")]
    pub target: [f32; 3],
    /// Vertical field of view, degrees, in (0, 180). Default 45.
    #[serde(default = "d_fov")]
    pub fov_degrees: f32,
}
fn d_fov() -> f32 {
    45.0
}

/// A problem found in a scene: key path and message (before the file position is attached).
struct Invalid {
    key: String,
    message: String,
}

fn invalid(key: impl Into<String>, value: impl std::fmt::Debug, allowed: &str) -> Invalid {
    Invalid {
        key: key.into(),
        message: format!("{value:?} is not allowed: allowed {allowed}"),
    }
}

/// A problem with `key` that is not a value out of range (a key missing, or given where it
/// does not apply): `message` says what is wrong and what is allowed.
fn problem(key: impl Into<String>, message: String) -> Invalid {
    Invalid {
        key: key.into(),
        message,
    }
}

fn finite3(key: &str, v: [f32; 3]) -> std::result::Result<(), Invalid> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(invalid(key, v, "three finite numbers"))
    }
}

fn positive(key: &str, v: f32) -> std::result::Result<(), Invalid> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(invalid(key, v, "a finite number > 0"))
    }
}

fn non_negative(key: &str, v: f32) -> std::result::Result<(), Invalid> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(invalid(key, v, "a finite number >= 0"))
    }
}

/// Bytes a simulation of `particles` particles and `springs` springs needs, roughly: state,
/// scratch and backups per particle, and the springs with the implicit solver's blocks
/// (saturating at `u64::MAX`).
#[must_use]
pub fn memory_estimate(particles: u64, springs: u64) -> u64 {
    particles
        .saturating_mul(12 * 24)
        .saturating_add(springs.saturating_mul(48))
}

impl Scene {
    /// Parses and validates a scene. `file` names the source in error messages.
    ///
    /// # Errors
    /// [`ClothError::Scene`] with the file, line, column, key and what is allowed.
    pub fn from_toml(source: &str, file: &str) -> Result<Scene> {
        if source.contains('\0') {
            return Err(scene_error(
                file,
                None,
                "",
                "the file is binary, not a TOML scene".into(),
            ));
        }
        if source.trim().is_empty() {
            return Err(scene_error(
                file,
                None,
                "",
                "the file is empty: a scene needs at least a [cloth] table with `resolution`"
                    .into(),
            ));
        }
        let mut scene: Scene = toml::from_str(source).map_err(|e| de_error(source, file, &e))?;
        if let Err(bad) = scene.check() {
            let pos = span_of(source, &bad.key).map(|s| line_col(source, s.start));
            return Err(scene_error(file, pos, &bad.key, bad.message));
        }
        scene.load_meshes(file).map_err(|e| match e {
            ClothError::Scene {
                file, key, message, ..
            } => {
                let pos = span_of(source, &key).map(|s| line_col(source, s.start));
                scene_error(&file, pos, &key, message)
            }
            other => other,
        })?;
        Ok(scene)
    }

    /// Reads the OBJ file of every mesh collider, relative to the directory of `file` (the
    /// scene's path); the meshes of the built-in scenes are built in (and found by their
    /// name, e.g. `meshes/table.obj`, when no such file exists next to the scene).
    ///
    /// # Errors
    /// [`ClothError::Scene`] naming `colliders[i].file` when a file cannot be read or is not
    /// a valid mesh.
    pub fn load_meshes(&mut self, file: &str) -> Result<()> {
        let dir = std::path::Path::new(file)
            .parent()
            .unwrap_or(std::path::Path::new(""));
        for (i, col) in self.colliders.iter_mut().enumerate() {
            if col.kind != ColliderKind::Mesh {
                continue;
            }
            let key = format!("colliders[{i}].file");
            let Some(name) = &col.file else {
                return Err(scene_error(file, None, &key, "a mesh needs `file`".into()));
            };
            let path = dir.join(name);
            let shown = path.to_string_lossy().replace('\\', "/");
            // A built-in mesh by its path, else the file, else a built-in mesh the name
            // refers to (a saved copy of a built-in scene, written elsewhere).
            let builtin = |key: &str| BUILTIN_MESHES.iter().find(|(n, _)| *n == key);
            let suffix = format!("/{}", name.trim_start_matches("./"));
            let mesh = match builtin(&shown) {
                Some((_, text)) => crate::collide::TriMesh::from_obj_str(text, &shown),
                None if !path.exists() => {
                    match BUILTIN_MESHES.iter().find(|(n, _)| n.ends_with(&suffix)) {
                        Some((n, text)) => crate::collide::TriMesh::from_obj_str(text, n),
                        None => crate::collide::TriMesh::from_obj(&path),
                    }
                }
                None => crate::collide::TriMesh::from_obj(&path),
            }
            .map_err(|e| scene_error(file, None, &key, e.to_string()))?;
            col.mesh = Some(std::sync::Arc::new(mesh));
        }
        Ok(())
    }

    /// Applies `key.path=value` overrides (the value in TOML syntax, e.g. `[64, 64]`, `0.5`,
    /// `"xpbd"`, or a bare word such as `xpbd`, taken as a string) to a scene source and
    /// parses the result. Each override is validated exactly as the file is; errors name the
    /// override.
    pub fn from_toml_with_overrides(
        source: &str,
        file: &str,
        overrides: &[String],
    ) -> Result<Scene> {
        if overrides.is_empty() {
            return Self::from_toml(source, file);
        }
        // Check the file alone first, so that its own errors point into it.
        Self::from_toml(source, file)?;
        let mut doc: toml::Table =
            toml::from_str(source).map_err(|e| de_error(source, file, &e))?;
        for item in overrides {
            let where_ = format!("--set {item}");
            let Some((path, value)) = item.split_once('=') else {
                return Err(scene_error(
                    &where_,
                    None,
                    item,
                    "expected key.path=value".into(),
                ));
            };
            let path = path.trim();
            let value: toml::Value = override_value(value)
                .ok_or_else(|| scene_error(&where_, None, path, not_a_value(value)))?;
            set_path(&mut doc, path, value).map_err(|m| scene_error(&where_, None, path, m))?;
            let text = toml::to_string(&doc).expect("a TOML table serialises");
            let scene: Scene = toml::from_str(&text).map_err(|e| {
                let mut err = de_error(&text, &where_, &e);
                if let ClothError::Scene { line, column, .. } = &mut err {
                    *line = 0;
                    *column = 0;
                }
                err
            })?;
            if let Err(bad) = scene.check() {
                return Err(scene_error(&where_, None, &bad.key, bad.message));
            }
        }
        let text = toml::to_string(&doc).expect("a TOML table serialises");
        // The file and each override passed on their own, so what is left (a mesh file that
        // cannot be read) comes from reading meshes: name the last override of that key's
        // table (positions in the merged text would point nowhere), else the file's line.
        Self::from_toml(&text, file).map_err(|e| match e {
            ClothError::Scene {
                file: f,
                key,
                message,
                ..
            } => {
                let root = |k: &str| k.split(['.', '[']).next().unwrap_or("").trim().to_owned();
                let by = overrides.iter().rev().find(|o| {
                    o.split_once('=')
                        .is_some_and(|(p, _)| root(p) == root(&key))
                });
                match by {
                    Some(item) => scene_error(&format!("--set {item}"), None, &key, message),
                    None => {
                        let pos = span_of(source, &key).map(|s| line_col(source, s.start));
                        scene_error(&f, pos, &key, message)
                    }
                }
            }
            other => other,
        })
    }

    /// Checks a scene built or edited in code exactly as [`Scene::from_toml`] checks a file;
    /// `file` names it in the error (which has no line or column).
    pub fn validate(&self, file: &str) -> Result<()> {
        self.check()
            .map_err(|bad| scene_error(file, None, &bad.key, bad.message))
    }

    /// The scene as TOML text; [`Scene::from_toml`] of it gives the same scene.
    #[must_use]
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a scene serialises to TOML")
    }

    /// The integrator named in `[solver] kind`.
    #[must_use]
    pub fn integrator(&self) -> Integrator {
        Integrator::from_name(&self.solver.kind).unwrap_or_default()
    }

    /// Number of particles and springs the scene builds (of any resolution, even one that
    /// [`from_toml`](Self::from_toml) refuses: the counts saturate at `u64::MAX`).
    #[must_use]
    pub fn counts(&self) -> (u64, u64) {
        let (r, c) = (
            u64::from(self.cloth.resolution[0]),
            u64::from(self.cloth.resolution[1]),
        );
        let (r1, c1) = (r.saturating_sub(1), c.saturating_sub(1));
        // Warp, weft, both diagonals, both bends.
        let springs = [
            r1.saturating_mul(c),
            r.saturating_mul(c1),
            r1.saturating_mul(c1).saturating_mul(2),
            r.saturating_mul(c.saturating_sub(2)),
            c.saturating_mul(r.saturating_sub(2)),
        ]
        .into_iter()
        .fold(0_u64, u64::saturating_add);
        (r.saturating_mul(c), springs)
    }

    /// Bytes the scene's simulation needs, roughly: [`memory_estimate`] of its particles and
    /// springs, plus, with self-collision, the candidate pairs within twice the thickness
    /// (12 bytes each; about π(2t)²/(2·Δx·Δy) per particle on a flat sheet, at least the 12
    /// the list reserves) and the positions the list was built at.
    #[must_use]
    pub fn memory_estimate(&self) -> u64 {
        let (particles, springs) = self.counts();
        let base = memory_estimate(particles, springs);
        let Some(sc) = self.solver.self_collision else {
            return base;
        };
        let (dx, dy) = self.cloth.spacing_of();
        let reach = 2.0 * f64::from(sc.thickness);
        let per_particle = (std::f64::consts::PI * reach * reach / (2.0 * dx * dy)).max(12.0);
        // Saturating: a degenerate spacing (refused when the cloth is built) gives u64::MAX.
        base.saturating_add((particles as f64 * (per_particle * 12.0 + 12.0)) as u64)
    }

    fn check(&self) -> std::result::Result<(), Invalid> {
        if !(self.duration.is_finite() && self.duration > 0.0 && self.duration <= MAX_DURATION) {
            return Err(invalid(
                "duration",
                self.duration,
                &format!("a number of seconds in (0, {MAX_DURATION:e}]"),
            ));
        }
        if self.description.contains(['\n', '\r']) {
            return Err(problem(
                "description",
                "more than one line: allowed one line of text".into(),
            ));
        }
        let c = &self.cloth;
        for (i, &n) in c.resolution.iter().enumerate() {
            if !(2..=MAX_GRID_SIDE as u32).contains(&n) {
                return Err(invalid(
                    "cloth.resolution",
                    c.resolution,
                    &format!(
                        "[rows, cols] each in 2 ..= {MAX_GRID_SIDE} ({} is {n})",
                        ["rows", "cols"][i]
                    ),
                ));
            }
        }
        if let Some(size) = c.size
            && !size
                .iter()
                .all(|&v| v.is_finite() && v > 0.0 && v <= MAX_CLOTH_EXTENT)
        {
            return Err(invalid(
                "cloth.size",
                size,
                &format!("[width, height] each in (0, {MAX_CLOTH_EXTENT}] m"),
            ));
        }
        if let Some(sp) = c.spacing {
            // Along the columns, then the rows (the resolution is [rows, cols], checked above).
            let [rows, cols] = c.resolution.map(|n| n as usize);
            let most = [cols, rows].map(crate::grid::max_spacing);
            if !(0..2).all(|i| sp[i].is_finite() && sp[i] > 0.0 && sp[i] <= most[i]) {
                return Err(invalid(
                    "cloth.spacing",
                    sp,
                    &format!(
                        "[along_cols, along_rows] each > 0, with (cols − 1) and (rows − 1) \
                         spacings at most {MAX_CLOTH_EXTENT} m: here at most [{}, {}] m",
                        most[0], most[1]
                    ),
                ));
            }
        }
        if let (Some(_), Some(spacing)) = (c.size, c.spacing) {
            return Err(invalid(
                "cloth.spacing",
                spacing,
                "either `size` or `spacing`, not both",
            ));
        }
        finite3("cloth.origin", c.origin)?;
        finite3("cloth.rotation", c.rotation)?;
        finite3("cloth.velocity", c.velocity)?;
        match (c.density, c.mass_per_particle) {
            (Some(_), Some(_)) => {
                return Err(problem(
                    "cloth.mass_per_particle",
                    "given with `density`: allowed either `density` or `mass_per_particle`, \
                     not both"
                        .into(),
                ));
            }
            (Some(d), None) => positive("cloth.density", d)?,
            (None, Some(m)) => positive("cloth.mass_per_particle", m)?,
            (None, None) => {}
        }
        let n = c.resolution[0] * c.resolution[1];
        if let Some(&i) = c.pins.indices.iter().find(|&&i| i >= n) {
            return Err(invalid(
                "cloth.pins.indices",
                i,
                &format!(
                    "particle indices 0 ..= {} (the grid has {n} particles)",
                    n - 1
                ),
            ));
        }
        for (name, s) in [
            ("warp", self.material.warp),
            ("weft", self.material.weft),
            ("shear", self.material.shear),
            ("bend", self.material.bend),
        ] {
            non_negative(&format!("material.{name}.stiffness"), s.stiffness)?;
            non_negative(&format!("material.{name}.damping"), s.damping)?;
        }
        let f = &self.forces;
        finite3("forces.gravity", f.gravity)?;
        non_negative("forces.damping", f.damping)?;
        non_negative("forces.air.density", f.air.density)?;
        non_negative("forces.air.drag", f.air.drag)?;
        non_negative("forces.air.lift", f.air.lift)?;
        finite3("forces.air.wind", f.air.wind)?;
        if let Some(g) = f.air.gust {
            if !(g.amplitude.is_finite() && (0.0..=1.0).contains(&g.amplitude)) {
                return Err(invalid("forces.air.gust.amplitude", g.amplitude, "0 ..= 1"));
            }
            positive("forces.air.gust.frequency", g.frequency)?;
        }
        for (i, col) in self.colliders.iter().enumerate() {
            let key = |k: &str| format!("colliders[{i}].{k}");
            let point = |k: &str, v: [f32; 3]| {
                range::point(v).map_err(|allowed| invalid(key(k), v, &allowed))
            };
            let size =
                |k: &str, v: f32| range::size(v).map_err(|allowed| invalid(key(k), v, &allowed));
            // The keys each kind reads (`rotation` and the motion keys have defaults).
            let (kind, needs): (&str, &[&str]) = match col.kind {
                ColliderKind::Sphere => ("sphere", &["center", "radius"]),
                ColliderKind::Capsule => ("capsule", &["a", "b", "radius"]),
                ColliderKind::Box => ("box", &["center", "half_extents"]),
                ColliderKind::Plane => ("plane", &["point", "normal"]),
                ColliderKind::Mesh => ("mesh", &["file"]),
            };
            let given = [
                ("center", col.center.is_some()),
                ("radius", col.radius.is_some()),
                ("a", col.a.is_some()),
                ("b", col.b.is_some()),
                ("half_extents", col.half_extents.is_some()),
                ("point", col.point.is_some()),
                ("normal", col.normal.is_some()),
                ("file", col.file.is_some()),
                ("rotation", col.rotation != [0.0; 3]),
            ];
            let optional: &[&str] = match col.kind {
                ColliderKind::Box => &["rotation"],
                ColliderKind::Mesh => &["center", "rotation"],
                _ => &[],
            };
            for (k, present) in given {
                if !present && needs.contains(&k) {
                    return Err(problem(
                        key(k),
                        format!("missing: a {kind} needs `{}`", needs.join("`, `")),
                    ));
                }
                if present && !needs.contains(&k) && !optional.contains(&k) {
                    let mut keys: Vec<&str> = needs.iter().chain(optional).copied().collect();
                    keys.extend(["velocity", "angular_velocity", "thickness", "friction"]);
                    return Err(problem(
                        key(k),
                        format!(
                            "not a key of a {kind}: a {kind} reads `{}` (and `type`)",
                            keys.join("`, `")
                        ),
                    ));
                }
            }
            match col.kind {
                ColliderKind::Sphere => {
                    point("center", col.center.unwrap_or_default())?;
                    size("radius", col.radius.unwrap_or_default())?;
                }
                ColliderKind::Capsule => {
                    point("a", col.a.unwrap_or_default())?;
                    point("b", col.b.unwrap_or_default())?;
                    size("radius", col.radius.unwrap_or_default())?;
                }
                ColliderKind::Mesh => {
                    if col.file.as_deref().is_none_or(|f| f.trim().is_empty()) {
                        return Err(problem(
                            key("file"),
                            "empty: a mesh needs `file`, an OBJ path relative to the scene".into(),
                        ));
                    }
                    point("center", col.center.unwrap_or_default())?;
                    finite3(&key("rotation"), col.rotation)?;
                }
                ColliderKind::Box => {
                    point("center", col.center.unwrap_or_default())?;
                    let h = col.half_extents.unwrap_or_default();
                    if let Some(allowed) = h.iter().find_map(|&x| range::size(x).err()) {
                        return Err(invalid(
                            key("half_extents"),
                            h,
                            &format!("three numbers, each {allowed}"),
                        ));
                    }
                    finite3(&key("rotation"), col.rotation)?;
                }
                ColliderKind::Plane => {
                    point("point", col.point.unwrap_or_default())?;
                    let normal = col.normal.unwrap_or_default();
                    if crate::collide::unit_normal(Vec3::from(normal)).is_none() {
                        return Err(invalid(
                            key("normal"),
                            normal,
                            "three finite numbers, the largest over 1e-6 in magnitude",
                        ));
                    }
                }
            }
            finite3(&key("velocity"), col.velocity)?;
            finite3(&key("angular_velocity"), col.angular_velocity)?;
            range::thickness(col.thickness)
                .map_err(|allowed| invalid(key("thickness"), col.thickness, &allowed))?;
            non_negative(&key("friction.static"), col.friction.static_coefficient)?;
            non_negative(&key("friction.kinetic"), col.friction.kinetic_coefficient)?;
        }
        let s = &self.solver;
        if Integrator::from_name(&s.kind).is_none() {
            let names: Vec<&str> = Integrator::ALL.iter().map(|i| i.name()).collect();
            return Err(invalid("solver.kind", &s.kind, &names.join(", ")));
        }
        positive("solver.dt", s.dt)?;
        let fewest = match &s.substeps {
            SubstepsDesc::Count(n) => *n,
            SubstepsDesc::Word(_) => 1,
        };
        if s.dt / (fewest as f32) < crate::config::MIN_SUBSTEP_DT {
            return Err(invalid(
                "solver.dt",
                s.dt,
                &format!(
                    "a step whose substeps (dt / {fewest}) are at least {:e} s",
                    crate::config::MIN_SUBSTEP_DT
                ),
            ));
        }
        match &s.substeps {
            SubstepsDesc::Count(n) if !(1..=crate::config::MAX_SUBSTEPS).contains(n) => {
                return Err(invalid(
                    "solver.substeps",
                    n,
                    &format!("1 ..= {} or \"auto\"", crate::config::MAX_SUBSTEPS),
                ));
            }
            SubstepsDesc::Word(w) if w != "auto" => {
                return Err(invalid(
                    "solver.substeps",
                    w,
                    "an integer 1 ..= 100000 or \"auto\"",
                ));
            }
            _ => {}
        }
        if let Some(l) = s.strain_limit {
            positive("solver.strain_limit", l)?;
        }
        if !(s.implicit.tolerance.is_finite()
            && s.implicit.tolerance > 0.0
            && s.implicit.tolerance < 1.0)
        {
            return Err(invalid(
                "solver.implicit.tolerance",
                s.implicit.tolerance,
                "a number in (0, 1)",
            ));
        }
        if s.implicit.max_iterations == 0 {
            return Err(invalid(
                "solver.implicit.max_iterations",
                0,
                "an integer >= 1",
            ));
        }
        if !(1..=1000).contains(&s.xpbd.iterations) {
            return Err(invalid(
                "solver.xpbd.iterations",
                s.xpbd.iterations,
                "1 ..= 1000",
            ));
        }
        non_negative("solver.xpbd.tether_slack", s.xpbd.tether_slack)?;
        if s.xpbd.hierarchy_levels > 16 {
            return Err(invalid(
                "solver.xpbd.hierarchy_levels",
                s.xpbd.hierarchy_levels,
                "0 ..= 16",
            ));
        }
        non_negative("solver.xpbd.hierarchy_slack", s.xpbd.hierarchy_slack)?;
        if let Some(l) = s.xpbd.structural_limit
            && !(l.is_finite() && (0.0..=1.0).contains(&l))
        {
            return Err(invalid("solver.xpbd.structural_limit", l, "0 ..= 1"));
        }
        if !(1..=16).contains(&s.xpbd.chain_iterations) {
            return Err(invalid(
                "solver.xpbd.chain_iterations",
                s.xpbd.chain_iterations,
                "1 ..= 16",
            ));
        }
        if !(1..=16).contains(&s.xpbd.chain_rounds) {
            return Err(invalid(
                "solver.xpbd.chain_rounds",
                s.xpbd.chain_rounds,
                "1 ..= 16",
            ));
        }
        let omega = s.xpbd.chain_relaxation;
        if !XpbdSettings::chain_relaxation_allowed(omega) {
            return Err(invalid(
                "solver.xpbd.chain_relaxation",
                omega,
                XpbdSettings::CHAIN_RELAXATION_RANGE,
            ));
        }
        if !(s.limits.max_stretch_ratio.is_finite() && s.limits.max_stretch_ratio > 1.0) {
            return Err(invalid(
                "solver.limits.max_stretch_ratio",
                s.limits.max_stretch_ratio,
                "a finite number > 1",
            ));
        }
        positive("solver.limits.max_speed", s.limits.max_speed)?;
        if let Some(sc) = s.self_collision {
            positive("solver.self_collision.thickness", sc.thickness)?;
            // `Simulation::new`'s bound, known here from the grid's spacing (the largest
            // structural rest length of a flat grid), so that the error points into the file.
            let (dx, dy) = self.cloth.spacing_of();
            if let Some(allowed) =
                crate::sim::self_collision_too_thick(sc.thickness, dx.max(dy) as f32)
            {
                return Err(invalid(
                    "solver.self_collision.thickness",
                    sc.thickness,
                    &allowed,
                ));
            }
            non_negative("solver.self_collision.friction", sc.friction)?;
        }
        if let Some(cam) = &self.camera {
            finite3("camera.eye", cam.eye)?;
            finite3("camera.target", cam.target)?;
            if Vec3::from(cam.eye).distance(Vec3::from(cam.target)) < MIN_CAMERA_DISTANCE {
                return Err(problem(
                    "camera.target",
                    format!(
                        "{:?} is where `camera.eye` is: the camera has no direction to look \
                         in (allowed a target at least {MIN_CAMERA_DISTANCE:e} m from the eye)",
                        cam.target
                    ),
                ));
            }
            if !(cam.fov_degrees.is_finite() && cam.fov_degrees > 0.0 && cam.fov_degrees < 180.0) {
                return Err(invalid(
                    "camera.fov_degrees",
                    cam.fov_degrees,
                    "a number in (0, 180)",
                ));
            }
        }
        Ok(())
    }

    /// The simulation configuration this scene describes, its substeps resolved for `cloth`
    /// (the cloth it builds: "auto" takes the cloth's stability bound).
    #[must_use]
    pub fn config(&self, cloth: &Cloth) -> SimConfig {
        let f = &self.forces;
        let s = &self.solver;
        let m = &self.material;
        let sp = |d: SpringDesc| SpringParams::new(d.stiffness, d.damping);
        let mut config = SimConfig {
            dt: s.dt,
            substeps: 1,
            integrator: self.integrator(),
            gravity: Vec3::from(f.gravity),
            damping: f.damping,
            material: Material {
                warp: sp(m.warp),
                weft: sp(m.weft),
                shear: sp(m.shear),
                bend: sp(m.bend),
            },
            air: Air {
                density: f.air.density,
                drag_coefficient: f.air.drag,
                lift_coefficient: f.air.lift,
                wind: Vec3::from(f.air.wind),
                gust: f.air.gust.map(|g| Gust {
                    amplitude: g.amplitude,
                    frequency: g.frequency,
                }),
            },
            forces: ForceSwitches {
                gravity: f.enabled.gravity,
                springs: f.enabled.springs,
                dashpots: f.enabled.dashpots,
                damping: f.enabled.damping,
                air: f.enabled.air,
            },
            limits: StabilityLimits {
                max_stretch_ratio: s.limits.max_stretch_ratio,
                max_speed: s.limits.max_speed,
            },
            strain_limit: s.strain_limit,
            implicit: ImplicitSettings {
                tolerance: s.implicit.tolerance,
                max_iterations: s.implicit.max_iterations,
            },
            xpbd: XpbdSettings::default(),
            self_collision: s.self_collision.map(|c| crate::SelfCollision {
                thickness: c.thickness,
                friction: c.friction,
            }),
            continuous_collision: s.continuous_collision,
        };
        match s.substeps {
            SubstepsDesc::Count(n) => config.substeps = n,
            SubstepsDesc::Word(_) => tune_for_integrator(&mut config, cloth),
        }
        config.xpbd = XpbdSettings {
            iterations: s.xpbd.iterations,
            tethers: s.xpbd.tethers,
            tether_slack: s.xpbd.tether_slack,
            hierarchy_levels: s.xpbd.hierarchy_levels,
            hierarchy_slack: s.xpbd.hierarchy_slack,
            structural_limit: s.xpbd.structural_limit,
            chains: s.xpbd.chains,
            chain_iterations: s.xpbd.chain_iterations,
            chain_rounds: s.xpbd.chain_rounds,
            chain_relaxation: s.xpbd.chain_relaxation,
            shear_chains: s.xpbd.shear_chains,
            shear_rows: s.xpbd.shear_rows,
        };
        config
    }

    /// Builds the simulation.
    pub fn build(&self) -> Result<Simulation> {
        let c = &self.cloth;
        let [rows, cols] = c.resolution;
        let mut grid = GridBuilder::new(rows as usize, cols as usize)
            .orientation(match c.orientation {
                OrientationDesc::Horizontal => Orientation::Horizontal,
                OrientationDesc::Vertical => Orientation::Vertical,
            })
            .origin(Vec3::from(c.origin))
            .rotation(euler_degrees(c.rotation))
            .velocity(Vec3::from(c.velocity))
            .mass(match (c.density, c.mass_per_particle) {
                (_, Some(m)) => Mass::PerParticle(m),
                (Some(d), None) => Mass::ArealDensity(d),
                (None, None) => Mass::default(),
            });
        grid = match (c.size, c.spacing) {
            (_, Some(sp)) => grid.spacing(sp[0], sp[1]),
            (Some(size), None) => grid.size(size[0], size[1]),
            (None, None) => grid,
        };
        for corner in &c.pins.corners {
            grid = grid.pin_corner(match corner {
                CornerDesc::TopLeft => Corner::TopLeft,
                CornerDesc::TopRight => Corner::TopRight,
                CornerDesc::BottomLeft => Corner::BottomLeft,
                CornerDesc::BottomRight => Corner::BottomRight,
            });
        }
        for edge in &c.pins.edges {
            grid = grid.pin_edge(match edge {
                EdgeDesc::Top => Edge::Top,
                EdgeDesc::Bottom => Edge::Bottom,
                EdgeDesc::Left => Edge::Left,
                EdgeDesc::Right => Edge::Right,
            });
        }
        grid = grid.pin_indices(c.pins.indices.iter().copied());
        // The builder names its arguments `grid.*`; here they are the scene's `cloth.*` keys.
        let cloth = grid.build().map_err(|e| renamed(e, "grid.", "cloth."))?;
        let config = self.config(&cloth);
        // The configuration's `config.self_collision.*` are the scene's `solver.self_collision.*`,
        // and its `config.dt` the scene's `solver.dt` (too short for the substeps "auto" chose:
        // checked only here, where the substeps are known).
        let mut sim = Simulation::new(cloth, config).map_err(|e| {
            let e = renamed(e, "config.self_collision.", "solver.self_collision.");
            renamed(e, "config.dt", "solver.dt")
        })?;
        for (i, col) in self.colliders.iter().enumerate() {
            let shape = match col.kind {
                ColliderKind::Sphere => Shape::Sphere {
                    center: Vec3::from(col.center.unwrap_or_default()),
                    radius: col.radius.unwrap_or(1.0),
                },
                ColliderKind::Plane => Shape::Plane {
                    point: Vec3::from(col.point.unwrap_or_default()),
                    normal: Vec3::from(col.normal.unwrap_or([0.0, 1.0, 0.0])),
                },
                ColliderKind::Capsule => Shape::Capsule {
                    a: Vec3::from(col.a.unwrap_or_default()),
                    b: Vec3::from(col.b.unwrap_or_default()),
                    radius: col.radius.unwrap_or(1.0),
                },
                ColliderKind::Box => Shape::Box {
                    center: Vec3::from(col.center.unwrap_or_default()),
                    half_extents: Vec3::from(col.half_extents.unwrap_or([1.0; 3])),
                    rotation: euler_degrees(col.rotation),
                },
                ColliderKind::Mesh => Shape::Mesh {
                    mesh: col.mesh.clone().ok_or_else(|| {
                        ClothError::invalid(
                            format!("colliders[{i}].file"),
                            &col.file,
                            "a mesh loaded by Scene::from_toml or Scene::load_meshes",
                        )
                    })?,
                    position: Vec3::from(col.center.unwrap_or_default()),
                    rotation: euler_degrees(col.rotation),
                },
            };
            sim.add_collider(Collider {
                shape,
                velocity: Vec3::from(col.velocity),
                angular_velocity: Vec3::from(col.angular_velocity),
                thickness: col.thickness,
                friction: Friction::new(
                    col.friction.static_coefficient,
                    col.friction.kinetic_coefficient,
                ),
            })?;
        }
        Ok(sim)
    }
}

/// A rotation from XYZ Euler angles in degrees.
fn euler_degrees(deg: [f32; 3]) -> Quat {
    Quat::from_euler(
        EulerRot::XYZ,
        deg[0].to_radians(),
        deg[1].to_radians(),
        deg[2].to_radians(),
    )
}

/// Sets `path` (dotted, `colliders[1].radius` style indices allowed) in a TOML table.
fn set_path(
    doc: &mut toml::Table,
    path: &str,
    value: toml::Value,
) -> std::result::Result<(), String> {
    let parts: Vec<&str> = path.split('.').collect();
    let mut table = doc;
    for (i, part) in parts.iter().enumerate() {
        let last = i + 1 == parts.len();
        let (name, index) = match part.split_once('[') {
            Some((n, rest)) => {
                let idx: usize = rest
                    .strip_suffix(']')
                    .and_then(|s| s.parse().ok())
                    .ok_or_else(|| format!("bad index in `{part}`"))?;
                (n, Some(idx))
            }
            None => (*part, None),
        };
        if name.is_empty() {
            return Err("empty key".into());
        }
        match index {
            None if last => {
                table.insert(name.to_string(), value);
                return Ok(());
            }
            None => {
                let entry = table
                    .entry(name.to_string())
                    .or_insert_with(|| toml::Value::Table(toml::Table::new()));
                table = entry
                    .as_table_mut()
                    .ok_or_else(|| format!("`{name}` is not a table"))?;
            }
            Some(idx) => {
                let array = table
                    .get_mut(name)
                    .and_then(toml::Value::as_array_mut)
                    .ok_or_else(|| format!("`{name}` is not an array of tables"))?;
                let len = array.len();
                let item = array.get_mut(idx).ok_or_else(|| {
                    format!("`{name}` has {len} entries; index {idx} is out of range")
                })?;
                if last {
                    *item = value;
                    return Ok(());
                }
                table = item
                    .as_table_mut()
                    .ok_or_else(|| format!("`{name}[{idx}]` is not a table"))?;
            }
        }
    }
    Ok(())
}

fn scene_error(file: &str, pos: Option<(usize, usize)>, key: &str, message: String) -> ClothError {
    let (line, column) = pos.unwrap_or((0, 0));
    ClothError::Scene {
        file: file.to_string(),
        line,
        column,
        key: key.to_string(),
        message,
    }
}

/// 1-based line and column of byte offset `at`.
fn line_col(source: &str, at: usize) -> (usize, usize) {
    let before = &source[..at.min(source.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// Known keys of every table, for "did you mean" suggestions.
const KNOWN_KEYS: &[&str] = &[
    "name",
    "description",
    "duration",
    "cloth",
    "material",
    "forces",
    "colliders",
    "solver",
    "camera",
    "resolution",
    "size",
    "spacing",
    "orientation",
    "origin",
    "rotation",
    "velocity",
    "density",
    "mass_per_particle",
    "pins",
    "corners",
    "edges",
    "indices",
    "warp",
    "weft",
    "shear",
    "bend",
    "stiffness",
    "damping",
    "gravity",
    "air",
    "enabled",
    "drag",
    "lift",
    "wind",
    "gust",
    "amplitude",
    "frequency",
    "springs",
    "dashpots",
    "type",
    "center",
    "radius",
    "point",
    "normal",
    "thickness",
    "friction",
    "static",
    "kinetic",
    "kind",
    "dt",
    "substeps",
    "strain_limit",
    "implicit",
    "xpbd",
    "limits",
    "tolerance",
    "max_iterations",
    "iterations",
    "tethers",
    "tether_slack",
    "hierarchy_levels",
    "hierarchy_slack",
    "structural_limit",
    "chains",
    "chain_iterations",
    "chain_rounds",
    "chain_relaxation",
    "shear_chains",
    "shear_rows",
    "max_stretch_ratio",
    "max_speed",
    "eye",
    "target",
    "fov_degrees",
];

/// `e` with an argument named `from…` renamed `to…` (the scene's key for a builder's or a
/// configuration's argument); any other error as it is.
fn renamed(e: ClothError, from: &str, to: &str) -> ClothError {
    match e {
        ClothError::InvalidArgument {
            name,
            value,
            allowed,
        } if name.starts_with(from) => ClothError::InvalidArgument {
            name: name.replacen(from, to, 1),
            value,
            allowed,
        },
        other => other,
    }
}

fn de_error(source: &str, file: &str, e: &toml::de::Error) -> ClothError {
    let pos = e.span().map(|s| line_col(source, s.start));
    let mut message = e.message().to_string();
    let key = e
        .span()
        .and_then(|s| key_at(source, s.start))
        .unwrap_or_default();
    if let Some((field, expected)) = message
        .strip_prefix("unknown field `")
        .and_then(|rest| rest.split_once('`'))
    {
        let candidates: Vec<&str> = expected.split('`').skip(1).step_by(2).collect();
        let pool: Vec<&str> = if candidates.is_empty() {
            KNOWN_KEYS.to_vec()
        } else {
            candidates
        };
        if let Some(best) = pool
            .iter()
            .map(|k| (strsim::jaro_winkler(field, k), *k))
            .filter(|(score, _)| *score > 0.7)
            .max_by(|a, b| a.0.total_cmp(&b.0))
        {
            let hint = format!("; did you mean `{}`?", best.1);
            message.push_str(&hint);
        }
    }
    // A field missing from the top level is reported at the document's start, where the
    // first key is: it is not that key's fault.
    let top_level = message.starts_with("missing field") && e.span().is_some_and(|s| s.start == 0);
    let key = if key.len() > 60 || top_level {
        String::new()
    } else {
        key
    };
    let mut message = plain_types(&message);
    // An enum given a number or an array: name what it takes.
    if message.contains("wanted string or table") {
        let names = if key.ends_with("orientation") {
            quoted_names(&OrientationDesc::ALL)
        } else if key.ends_with(".type") {
            quoted_names(&ColliderKind::ALL)
        } else if key.ends_with("corners") {
            quoted_names(&CornerDesc::ALL)
        } else if key.ends_with("edges") {
            quoted_names(&EdgeDesc::ALL)
        } else {
            "a name in quotes (docs/scenes.md lists them)".to_owned()
        };
        message = format!("expected {names}");
    }
    scene_error(file, pos, &key, message)
}

/// The names scene files use for `all` (as serde writes them), quoted and joined:
/// `"a", "b" or "c"`.
fn quoted_names<T: Serialize>(all: &[T]) -> String {
    let names: Vec<String> = all
        .iter()
        .map(|v| match toml::Value::try_from(v) {
            Ok(toml::Value::String(name)) => format!("\"{name}\""),
            _ => unreachable!("a unit variant serialises to its name"),
        })
        .collect();
    match names.split_last() {
        Some((last, [])) => last.clone(),
        Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
        None => String::new(),
    }
}

/// serde's type names in `message` in words (`expected f32` → `expected a number`).
fn plain_types(message: &str) -> String {
    let mut out = message.to_owned();
    for (rust, words) in [
        ("expected f32", "expected a number"),
        ("expected f64", "expected a number"),
        ("expected u32", "expected a whole number 0 ..= 4294967295"),
        ("expected u64", "expected a whole number >= 0"),
        ("expected usize", "expected a whole number >= 0"),
        ("expected a boolean", "expected true or false"),
        ("expected a sequence", "expected an array"),
        ("expected a map", "expected a table"),
    ] {
        out = out.replace(rust, words);
    }
    // `expected struct ClothDesc` and the like: a table of keys.
    if let Some(at) = out.find("expected struct ") {
        let end = out[at + 16..]
            .find(|c: char| !c.is_alphanumeric() && c != '_')
            .map_or(out.len(), |e| at + 16 + e);
        out.replace_range(at..end, "expected a table");
    }
    out
}

/// The dotted key path whose key or value holds byte `at` of `source` (the deepest one).
fn key_at(source: &str, at: usize) -> Option<String> {
    fn walk(table: &toml::de::DeTable<'_>, at: usize, prefix: &str) -> Option<String> {
        for (k, v) in table {
            let key = if prefix.is_empty() {
                k.get_ref().to_string()
            } else {
                format!("{prefix}.{}", k.get_ref())
            };
            let (ks, vs) = (k.span(), v.span());
            let inside = ks.contains(&at) || vs.contains(&at);
            match v.get_ref() {
                toml::de::DeValue::Table(t) => {
                    if let Some(deeper) = walk(t, at, &key) {
                        return Some(deeper);
                    }
                }
                toml::de::DeValue::Array(items) => {
                    for (i, item) in items.iter().enumerate() {
                        if let toml::de::DeValue::Table(t) = item.get_ref()
                            && let Some(deeper) = walk(t, at, &format!("{key}[{i}]"))
                        {
                            return Some(deeper);
                        }
                    }
                }
                _ => {}
            }
            if inside {
                return Some(key);
            }
        }
        None
    }
    let root = toml::de::DeTable::parse(source).ok()?;
    walk(root.get_ref(), at, "")
}

/// Byte span of the value at a dotted key path in `source` (best effort, for positions).
fn span_of(source: &str, path: &str) -> Option<std::ops::Range<usize>> {
    let root = toml::de::DeTable::parse(source).ok()?;
    let mut table = root.get_ref();
    let mut span = None;
    let parts: Vec<&str> = path.split('.').collect();
    for (i, part) in parts.iter().enumerate() {
        let (name, index) = match part.split_once('[') {
            Some((n, rest)) => (
                n,
                rest.strip_suffix(']').and_then(|s| s.parse::<usize>().ok()),
            ),
            None => (*part, None),
        };
        let (_, value) = table.iter().find(|(k, _)| k.get_ref() == name)?;
        span = Some(value.span());
        let mut value = value.get_ref();
        if let (Some(idx), toml::de::DeValue::Array(items)) = (index, value) {
            let item = items.get(idx)?;
            span = Some(item.span());
            value = item.get_ref();
        }
        if i + 1 < parts.len() {
            match value {
                toml::de::DeValue::Table(t) => table = t,
                _ => return span,
            }
        }
    }
    span
}

/// The built-in scenes: `(name, TOML source)`, shipped in the repository's `scenes/` folder and
/// embedded here.
pub const BUILTIN: &[(&str, &str)] = &[
    ("drape", include_str!("../../../scenes/drape.toml")),
    ("hanging", include_str!("../../../scenes/hanging.toml")),
    ("flag", include_str!("../../../scenes/flag.toml")),
    ("peer-ball", include_str!("../../../scenes/peer-ball.toml")),
    ("table", include_str!("../../../scenes/table.toml")),
    (
        "euler-sheet",
        include_str!("../../../scenes/euler-sheet.toml"),
    ),
    (
        "verlet-swing",
        include_str!("../../../scenes/verlet-swing.toml"),
    ),
    (
        "implicit-drape",
        include_str!("../../../scenes/implicit-drape.toml"),
    ),
    (
        "xpbd-curtain",
        include_str!("../../../scenes/xpbd-curtain.toml"),
    ),
    (
        "xpbd-drape",
        include_str!("../../../scenes/xpbd-drape.toml"),
    ),
    ("sweep", include_str!("../../../scenes/sweep.toml")),
    ("fold", include_str!("../../../scenes/fold.toml")),
    ("pile", include_str!("../../../scenes/pile.toml")),
    ("mesh", include_str!("../../../scenes/mesh.toml")),
];

/// The meshes the built-in scenes use, by their path as seen from the scene files.
pub const BUILTIN_MESHES: &[(&str, &str)] = &[(
    "scenes/meshes/table.obj",
    include_str!("../../../scenes/meshes/table.obj"),
)];

/// The TOML source of built-in scene `name`.
#[must_use]
pub fn builtin_source(name: &str) -> Option<&'static str> {
    BUILTIN.iter().find(|(n, _)| *n == name).map(|(_, s)| *s)
}

/// Built-in scene `name`, parsed.
///
/// # Panics
/// Never for the names in [`BUILTIN`] (a test parses each of them).
pub fn builtin(name: &str) -> Option<Scene> {
    builtin_source(name).map(|src| {
        Scene::from_toml(src, &format!("scenes/{name}.toml")).expect("built-in scenes are valid")
    })
}

/// Reads a scene: a built-in name, or a path to a TOML file. Returns the scene and its source
/// text. A missing, unreadable, empty or binary file is an error naming it.
pub fn load(name_or_path: &str, overrides: &[String]) -> Result<(Scene, String)> {
    let (source, file) = match builtin_source(name_or_path) {
        Some(src) => (src.to_string(), format!("scenes/{name_or_path}.toml")),
        None => {
            let path = std::path::Path::new(name_or_path);
            let bytes = std::fs::read(path).map_err(|e| {
                let names: Vec<&str> = BUILTIN.iter().map(|(n, _)| *n).collect();
                scene_error(
                    name_or_path,
                    None,
                    "",
                    format!(
                        "cannot read the scene file ({e}); built-in scenes are: {}",
                        names.join(", ")
                    ),
                )
            })?;
            let text = String::from_utf8(bytes).map_err(|_| {
                scene_error(
                    name_or_path,
                    None,
                    "",
                    "the file is binary, not a TOML scene".into(),
                )
            })?;
            (text, name_or_path.to_string())
        }
    };
    let scene = Scene::from_toml_with_overrides(&source, &file, overrides)?;
    Ok((scene, source))
}

/// The value of an override `key.path=value`, read as [`Scene::from_toml_with_overrides`]
/// reads it (TOML syntax); `None` when it is not a TOML value.
fn override_value(value: &str) -> Option<toml::Value> {
    toml::from_str::<toml::Table>(&format!("v = {value}"))
        .ok()
        .and_then(|mut t| t.remove("v"))
        .or_else(|| bare_word(value).map(|w| toml::Value::String(w.to_owned())))
}

/// Why an override's `value` is not a TOML value, in words.
fn not_a_value(value: &str) -> String {
    let v = value.trim();
    let why = match v.chars().next() {
        Some('[') if !v.ends_with(']') => "an array needs its closing `]`: [1, 2]",
        Some('{') if !v.ends_with('}') => "a table needs its closing `}`: {a = 1}",
        Some('[' | '{') => "check the items and the commas between them",
        Some(c) if c.is_ascii_digit() || matches!(c, '-' | '+' | '.') => {
            "a number must be finite and in range (up to about 1.8e308), written like 0.5 or 1e-3"
        }
        _ => "a string other than a bare word needs quotes: name=\"my drape\"",
    };
    format!("{value:?} is not a TOML value ({why})")
}

/// A value that is not TOML but a bare word (`xpbd`, `symplectic-euler`, `auto`: letters,
/// digits, `_`, `-` and `.`, starting with a letter) is taken as that string, since a shell
/// strips the quotes of `--set solver.kind="xpbd"`.
fn bare_word(value: &str) -> Option<&str> {
    let word = value.trim();
    let mut chars = word.chars();
    (chars.next()?.is_ascii_alphabetic()
        && chars.all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.')))
    .then_some(word)
}

/// Whether one of `overrides` (`key.path=value`, as [`Scene::from_toml_with_overrides`]
/// reads them) sets the key `path` (dotted, e.g. `solver.substeps`): the key itself or one
/// under it (`camera.eye=…` sets `camera`), or through a table that holds it
/// (`solver={substeps=8}` sets `solver.substeps`). The viewer keeps such keys when it adjusts
/// a scene (its substeps when the resolution changes, its `[camera]` framing).
#[must_use]
pub fn overrides_set(overrides: &[String], path: &str) -> bool {
    overrides.iter().any(|item| {
        let Some((key, value)) = item.split_once('=') else {
            return false;
        };
        let key = key.trim();
        if key
            .strip_prefix(path)
            .is_some_and(|rest| rest.is_empty() || rest.starts_with(['.', '[']))
        {
            return true;
        }
        let Some(inner) = path.strip_prefix(key).and_then(|r| r.strip_prefix('.')) else {
            return false;
        };
        let mut value = override_value(value);
        for field in inner.split('.') {
            value = match value {
                Some(toml::Value::Table(mut t)) => t.remove(field),
                _ => None,
            };
        }
        value.is_some()
    })
}

impl Scene {
    /// This scene with the settings of a running simulation built from it: integrator, step,
    /// substeps, solver settings, material, forces, colliders' thickness, friction and motion
    /// (at their initial positions), and the pinned particles. Building the result and running
    /// it gives the same simulation as restarting `sim` with its current settings. This is what
    /// the viewer's "save scene" writes.
    #[must_use]
    pub fn with_settings_of(&self, sim: &Simulation) -> Scene {
        let mut scene = self.clone();
        let c = sim.config();
        let sp = |p: SpringParams| SpringDesc {
            stiffness: p.stiffness,
            damping: p.damping,
        };
        scene.material = MaterialDesc {
            warp: sp(c.material.warp),
            weft: sp(c.material.weft),
            shear: sp(c.material.shear),
            bend: sp(c.material.bend),
        };
        scene.forces = ForcesDesc {
            gravity: c.gravity.to_array(),
            damping: c.damping,
            air: AirDesc {
                density: c.air.density,
                drag: c.air.drag_coefficient,
                lift: c.air.lift_coefficient,
                wind: c.air.wind.to_array(),
                gust: c.air.gust.map(|g| GustDesc {
                    amplitude: g.amplitude,
                    frequency: g.frequency,
                }),
            },
            enabled: EnabledDesc {
                gravity: c.forces.gravity,
                springs: c.forces.springs,
                dashpots: c.forces.dashpots,
                damping: c.forces.damping,
                air: c.forces.air,
            },
        };
        scene.solver = SolverDesc {
            kind: c.integrator.name().into(),
            dt: c.dt,
            substeps: SubstepsDesc::Count(c.substeps),
            strain_limit: c.strain_limit,
            implicit: ImplicitDesc {
                tolerance: c.implicit.tolerance,
                max_iterations: c.implicit.max_iterations,
            },
            xpbd: XpbdDesc {
                iterations: c.xpbd.iterations,
                tethers: c.xpbd.tethers,
                tether_slack: c.xpbd.tether_slack,
                hierarchy_levels: c.xpbd.hierarchy_levels,
                hierarchy_slack: c.xpbd.hierarchy_slack,
                structural_limit: c.xpbd.structural_limit,
                chains: c.xpbd.chains,
                chain_iterations: c.xpbd.chain_iterations,
                chain_rounds: c.xpbd.chain_rounds,
                chain_relaxation: c.xpbd.chain_relaxation,
                shear_chains: c.xpbd.shear_chains,
                shear_rows: c.xpbd.shear_rows,
            },
            limits: LimitsDesc {
                max_stretch_ratio: c.limits.max_stretch_ratio,
                max_speed: c.limits.max_speed,
            },
            self_collision: c.self_collision.map(|s| SelfCollisionDesc {
                thickness: s.thickness,
                friction: s.friction,
            }),
            continuous_collision: c.continuous_collision,
        };
        for (desc, col) in scene.colliders.iter_mut().zip(sim.colliders()) {
            desc.thickness = col.thickness;
            desc.velocity = col.velocity.to_array();
            desc.angular_velocity = col.angular_velocity.to_array();
            desc.friction = FrictionDesc {
                static_coefficient: col.friction.static_coefficient,
                kinetic_coefficient: col.friction.kinetic_coefficient,
            };
        }
        let pinned: Vec<u32> = (0..sim.particles().len())
            .filter(|&i| sim.particles().is_pinned(i))
            .map(|i| i as u32)
            .collect();
        scene.cloth.pins = PinsDesc {
            corners: Vec::new(),
            edges: Vec::new(),
            indices: pinned,
        };
        scene
    }
}
