//! Colliders and the contact response shared by the explicit integrators.

pub mod ccd;
pub mod intersect;
pub mod mesh;
pub mod self_collision;

use std::sync::Arc;

use glam::{Quat, Vec3};

use crate::error::{ClothError, Result, check};
use crate::particles::Particles;
pub use mesh::TriMesh;

/// Coulomb friction coefficients.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Friction {
    /// Static coefficient μ_s, `>= 0`: a contact sticks while the tangential impulse needed
    /// to stop it is at most μ_s times the normal impulse. Default 0.5.
    pub static_coefficient: f32,
    /// Kinetic coefficient μ_k, `>= 0`: a sliding contact loses tangential speed by μ_k
    /// times the normal impulse (per unit mass). Default 0.4.
    pub kinetic_coefficient: f32,
}

impl Default for Friction {
    fn default() -> Self {
        Self {
            static_coefficient: 0.5,
            kinetic_coefficient: 0.4,
        }
    }
}

impl Friction {
    /// No friction.
    pub const NONE: Self = Self {
        static_coefficient: 0.0,
        kinetic_coefficient: 0.0,
    };

    /// Static and kinetic coefficients.
    #[must_use]
    pub const fn new(static_coefficient: f32, kinetic_coefficient: f32) -> Self {
        Self {
            static_coefficient,
            kinetic_coefficient,
        }
    }
}

/// The geometry of a collider, at its current position.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "scene", derive(serde::Serialize, serde::Deserialize))]
pub enum Shape {
    /// A solid ball.
    Sphere {
        /// Centre, m.
        center: Vec3,
        /// Radius, m, `> 0`.
        radius: f32,
    },
    /// An infinite plane; the solid is the half-space behind it.
    Plane {
        /// Any point on the plane, m.
        point: Vec3,
        /// Outward normal (unit length after [`Collider::validate`]).
        normal: Vec3,
    },
    /// A capsule: all points within `radius` of the segment from `a` to `b`.
    Capsule {
        /// One end of the axis, m.
        a: Vec3,
        /// The other end of the axis, m.
        b: Vec3,
        /// Radius, m, `> 0`.
        radius: f32,
    },
    /// An oriented box.
    Box {
        /// Centre, m.
        center: Vec3,
        /// Half the side lengths along the box's own axes, m, each `> 0`.
        half_extents: Vec3,
        /// Orientation of the box's axes (unit quaternion).
        rotation: Quat,
    },
    /// A static triangle mesh (shared, with its BVH) placed at a pose: a point `x` of the
    /// mesh is at `position + rotation · x`.
    Mesh {
        /// The mesh, in its own coordinates.
        mesh: Arc<TriMesh>,
        /// Where the mesh's origin is, m.
        position: Vec3,
        /// Orientation (unit quaternion).
        rotation: Quat,
    },
}

impl Shape {
    /// Signed distance from `p` to the surface (positive outside) and the outward normal at
    /// the closest point.
    #[must_use]
    pub fn distance(&self, p: Vec3) -> (f32, Vec3) {
        match *self {
            Shape::Sphere { center, radius } => {
                let d = p - center;
                let len = d.length();
                let n = if len > 0.0 { d / len } else { Vec3::Y };
                (len - radius, n)
            }
            Shape::Plane { point, normal } => ((p - point).dot(normal), normal),
            Shape::Capsule { a, b, radius } => {
                let ab = b - a;
                let len_sq = ab.length_squared();
                let t = if len_sq > 0.0 {
                    ((p - a).dot(ab) / len_sq).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let d = p - (a + t * ab);
                let len = d.length();
                // On the axis every direction across it is a nearest one: take one that is
                // (`any_orthonormal_vector` needs a unit axis; a point capsule has none).
                let n = if len > 0.0 {
                    d / len
                } else {
                    ab.normalize_or(Vec3::Y).any_orthonormal_vector()
                };
                (len - radius, n)
            }
            Shape::Box {
                center,
                half_extents,
                rotation,
            } => {
                let local = rotation.inverse() * (p - center);
                let q = local.abs() - half_extents;
                let outside = q.max(Vec3::ZERO);
                let out_len = outside.length();
                if out_len > 0.0 {
                    let n_local = outside * local.signum() / out_len;
                    (out_len, rotation * n_local)
                } else {
                    // Inside: the nearest face.
                    let axis = if q.x >= q.y && q.x >= q.z {
                        Vec3::X
                    } else if q.y >= q.z {
                        Vec3::Y
                    } else {
                        Vec3::Z
                    };
                    let n_local = axis * local.dot(axis).signum();
                    (q.max_element(), rotation * n_local)
                }
            }
            Shape::Mesh {
                ref mesh,
                position,
                rotation,
            } => {
                let (d, n) = mesh.distance(rotation.inverse() * (p - position));
                (d, rotation * n)
            }
        }
    }

    /// Like [`distance`](Self::distance), but a mesh only looks for surface points within
    /// `max_distance` (returning `max_distance` when there are none): the cheap query of the
    /// contact passes. Exact for the analytic shapes.
    #[must_use]
    #[inline]
    pub fn distance_within(&self, p: Vec3, max_distance: f32) -> (f32, Vec3) {
        match self {
            Shape::Mesh {
                mesh,
                position,
                rotation,
            } => {
                let (d, n) =
                    mesh.distance_within(rotation.inverse() * (p - *position), max_distance);
                (d, *rotation * n)
            }
            _ => self.distance(p),
        }
    }

    /// The point the shape turns about (a sphere's or box's centre, a plane's point, a
    /// capsule's midpoint), m.
    #[must_use]
    pub fn pivot(&self) -> Vec3 {
        match *self {
            Shape::Sphere { center, .. } | Shape::Box { center, .. } => center,
            Shape::Mesh { position, .. } => position,
            Shape::Plane { point, .. } => point,
            Shape::Capsule { a, b, .. } => 0.5 * (a + b),
        }
    }

    /// Every coordinate, size and rotation of the shape finite (a mesh's own vertices are
    /// checked when it is made).
    pub(crate) fn is_finite(&self) -> bool {
        match *self {
            Shape::Sphere { center, radius } => center.is_finite() && radius.is_finite(),
            Shape::Plane { point, normal } => point.is_finite() && normal.is_finite(),
            Shape::Capsule { a, b, radius } => a.is_finite() && b.is_finite() && radius.is_finite(),
            Shape::Box {
                center,
                half_extents,
                rotation,
            } => center.is_finite() && half_extents.is_finite() && rotation.is_finite(),
            Shape::Mesh {
                position, rotation, ..
            } => position.is_finite() && rotation.is_finite(),
        }
    }

    fn translate(&mut self, by: Vec3) {
        match self {
            Shape::Sphere { center, .. } | Shape::Box { center, .. } => *center += by,
            Shape::Mesh { position, .. } => *position += by,
            Shape::Plane { point, .. } => *point += by,
            Shape::Capsule { a, b, .. } => {
                *a += by;
                *b += by;
            }
        }
    }

    /// Turns the shape by `turn` about its pivot.
    fn rotate(&mut self, turn: Quat) {
        let pivot = self.pivot();
        match self {
            Shape::Sphere { .. } => {}
            Shape::Plane { normal, .. } => *normal = (turn * *normal).normalize(),
            Shape::Capsule { a, b, .. } => {
                *a = pivot + turn * (*a - pivot);
                *b = pivot + turn * (*b - pivot);
            }
            Shape::Box { rotation, .. } | Shape::Mesh { rotation, .. } => {
                *rotation = (turn * *rotation).normalize();
            }
        }
    }
}

/// Largest magnitude of a collider's coordinates and sizes (centre, point, axis ends,
/// position, radius, half extents, thickness, and a mesh's vertices), m: a million
/// kilometres, far beyond any scene, and far below where the squared distances the contact
/// passes compute overflow f32 (about 1.8·10¹⁹ m).
pub const MAX_COLLIDER_EXTENT: f32 = 1.0e9;

/// The ranges of a collider's coordinates, sizes and thickness: one definition for
/// [`Collider::validate`], mesh vertices and scene files, which name the fields their own way.
/// Each check returns what is allowed, in words, when the value is outside it.
pub(crate) mod range {
    use super::MAX_COLLIDER_EXTENT as MAX;

    /// A point or a vector of lengths: finite, each component at most [`MAX`] in magnitude.
    pub(crate) fn point(v: [f32; 3]) -> Result<(), String> {
        if v.iter().all(|x| x.is_finite() && x.abs() <= MAX) {
            Ok(())
        } else {
            Err(format!(
                "three finite numbers of magnitude at most {MAX:e} m"
            ))
        }
    }

    /// A radius or a half extent: finite, > 0 and at most [`MAX`].
    pub(crate) fn size(v: f32) -> Result<(), String> {
        if v.is_finite() && v > 0.0 && v <= MAX {
            Ok(())
        } else {
            Err(format!("a finite number > 0 and at most {MAX:e} m"))
        }
    }

    /// A contact thickness: finite, >= 0 and at most [`MAX`].
    pub(crate) fn thickness(v: f32) -> Result<(), String> {
        if v.is_finite() && (0.0..=MAX).contains(&v) {
            Ok(())
        } else {
            Err(format!("a finite number >= 0 and at most {MAX:e} m"))
        }
    }
}

/// Depth below the contact surface within which the discrete contact passes find mesh
/// contacts, m (see [`Collider::contact_range`]).
pub const CONTACT_MARGIN: f32 = 0.05;

/// A kinematic collider: a shape moving with a prescribed velocity, with a contact thickness
/// and friction.
#[derive(Debug, Clone, PartialEq)]
pub struct Collider {
    /// Geometry at the current time.
    pub shape: Shape,
    /// Prescribed linear velocity, m/s. Default zero (static).
    pub velocity: Vec3,
    /// Prescribed angular velocity about the shape's pivot ([`Shape::pivot`]), rad/s.
    /// Default zero.
    pub angular_velocity: Vec3,
    /// Contact thickness, m, `>= 0`: particles are kept this far outside the surface.
    /// Default 0.01 m.
    pub thickness: f32,
    /// Friction against the cloth. Default [`Friction::default`].
    pub friction: Friction,
}

/// `normal` scaled to unit length, when it is finite and its largest component is over
/// 10⁻⁶ in magnitude (scaled by that component first, so that no square overflows or
/// underflows): the plane normals of the API and of scene files.
pub(crate) fn unit_normal(normal: Vec3) -> Option<Vec3> {
    let largest = normal.abs().max_element();
    if !(normal.is_finite() && largest > 1e-6) {
        return None;
    }
    Some((normal / largest).normalize())
}

impl Collider {
    /// A static sphere with default thickness and friction.
    #[must_use]
    pub fn sphere(center: Vec3, radius: f32) -> Self {
        Self::new(Shape::Sphere { center, radius })
    }

    /// A static plane through `point` with outward `normal` (normalised when added).
    #[must_use]
    pub fn plane(point: Vec3, normal: Vec3) -> Self {
        Self::new(Shape::Plane { point, normal })
    }

    /// A static collider of `shape` with default thickness and friction.
    #[must_use]
    pub fn new(shape: Shape) -> Self {
        Self {
            shape,
            velocity: Vec3::ZERO,
            angular_velocity: Vec3::ZERO,
            thickness: 0.01,
            friction: Friction::default(),
        }
    }

    /// With contact thickness `thickness`, m.
    #[must_use]
    pub fn with_thickness(mut self, thickness: f32) -> Self {
        self.thickness = thickness;
        self
    }

    /// With friction coefficients.
    #[must_use]
    pub fn with_friction(mut self, friction: Friction) -> Self {
        self.friction = friction;
        self
    }

    /// Moving at `velocity`, m/s.
    #[must_use]
    pub fn with_velocity(mut self, velocity: Vec3) -> Self {
        self.velocity = velocity;
        self
    }

    /// Turning at `angular_velocity` (rad/s) about its pivot.
    #[must_use]
    pub fn with_angular_velocity(mut self, angular_velocity: Vec3) -> Self {
        self.angular_velocity = angular_velocity;
        self
    }

    /// A static capsule around the segment `a`–`b`.
    #[must_use]
    pub fn capsule(a: Vec3, b: Vec3, radius: f32) -> Self {
        Self::new(Shape::Capsule { a, b, radius })
    }

    /// A static box.
    #[must_use]
    pub fn cuboid(center: Vec3, half_extents: Vec3, rotation: Quat) -> Self {
        Self::new(Shape::Box {
            center,
            half_extents,
            rotation,
        })
    }

    /// A static triangle mesh at `position` turned by `rotation`.
    #[must_use]
    pub fn mesh(mesh: Arc<TriMesh>, position: Vec3, rotation: Quat) -> Self {
        Self::new(Shape::Mesh {
            mesh,
            position,
            rotation,
        })
    }

    /// How far from the surface the discrete contact passes look (thickness +
    /// [`CONTACT_MARGIN`]), m. Only matters for meshes: a particle more than
    /// [`CONTACT_MARGIN`] inside a mesh is not seen by the discrete pass (continuous
    /// collision stops particles from getting there).
    #[inline]
    #[must_use]
    pub fn contact_range(&self) -> f32 {
        self.thickness + CONTACT_MARGIN
    }

    /// Velocity of the collider's surface material at `p`: v + ω × (p − pivot), m/s.
    #[inline]
    #[must_use]
    pub fn velocity_at(&self, p: Vec3) -> Vec3 {
        if self.angular_velocity == Vec3::ZERO {
            self.velocity
        } else {
            self.velocity + self.angular_velocity.cross(p - self.shape.pivot())
        }
    }

    /// Checks every field (naming the collider by `index`) and normalises a plane's normal.
    pub fn validate(mut self, index: usize) -> Result<Self> {
        let name = |field: &str| format!("colliders[{index}].{field}");
        let point = |field: &str, v: Vec3| {
            range::point(v.to_array())
                .map_err(|allowed| ClothError::invalid(name(field), v, allowed))
        };
        let size = |field: &str, v: f32| {
            range::size(v).map_err(|allowed| ClothError::invalid(name(field), v, allowed))
        };
        // A box's or mesh's rotation: a finite quaternion of unit length (within 1e-3),
        // normalised.
        let unit_rotation = |rotation: &mut Quat| {
            if !rotation.is_finite() || (rotation.length() - 1.0).abs() > 1e-3 {
                return Err(ClothError::invalid(
                    name("rotation"),
                    *rotation,
                    "a finite unit quaternion",
                ));
            }
            *rotation = rotation.normalize();
            Ok(())
        };
        match &mut self.shape {
            Shape::Sphere { center, radius } => {
                point("center", *center)?;
                size("radius", *radius)?;
            }
            Shape::Plane { point: p, normal } => {
                point("point", *p)?;
                *normal = unit_normal(*normal).ok_or_else(|| {
                    ClothError::invalid(
                        name("normal"),
                        *normal,
                        "a non-zero finite vector (its largest component over 1e-6 in magnitude)",
                    )
                })?;
            }
            Shape::Capsule { a, b, radius } => {
                point("a", *a)?;
                point("b", *b)?;
                size("radius", *radius)?;
            }
            Shape::Box {
                center,
                half_extents,
                rotation,
            } => {
                point("center", *center)?;
                size("half_extents.x", half_extents.x)?;
                size("half_extents.y", half_extents.y)?;
                size("half_extents.z", half_extents.z)?;
                unit_rotation(rotation)?;
            }
            Shape::Mesh {
                position, rotation, ..
            } => {
                point("position", *position)?;
                unit_rotation(rotation)?;
            }
        }
        check::finite_vec(&name("velocity"), self.velocity)?;
        check::finite_vec(&name("angular_velocity"), self.angular_velocity)?;
        range::thickness(self.thickness)
            .map_err(|allowed| ClothError::invalid(name("thickness"), self.thickness, allowed))?;
        check::non_negative(
            &name("friction.static_coefficient"),
            self.friction.static_coefficient,
        )?;
        check::non_negative(
            &name("friction.kinetic_coefficient"),
            self.friction.kinetic_coefficient,
        )?;
        Ok(self)
    }

    /// Advances the collider along its prescribed motion by `h` seconds.
    pub(crate) fn advance(&mut self, h: f32) {
        if self.velocity != Vec3::ZERO {
            self.shape.translate(self.velocity * h);
        }
        if self.angular_velocity != Vec3::ZERO {
            self.shape
                .rotate(Quat::from_scaled_axis(self.angular_velocity * h));
        }
    }
}

/// Coulomb friction of a contact (after Bridson et al. 2002) whose approaching normal relative
/// velocity `vn < 0` along `n` is being removed: returns the tangential relative velocity
/// `v_t` and what it becomes, zero when |v_t| ≤ μ_s·|vn| (sticking), else shortened by
/// μ_k·|vn| (sliding).
#[inline]
pub(crate) fn coulomb(v_rel: Vec3, vn: f32, n: Vec3, mu_s: f32, mu_k: f32) -> (Vec3, Vec3) {
    let dvn = -vn;
    let vt = v_rel - vn * n;
    let vt_len = vt.length();
    let vt_new = if vt_len <= mu_s * dvn {
        Vec3::ZERO
    } else {
        vt * (1.0 - mu_k * dvn / vt_len).max(0.0)
    };
    (vt, vt_new)
}

/// The velocity response of a particle at `x` touching `collider` with outward normal `n`:
/// when it approaches (relative normal velocity < 0), the normal part of its velocity
/// relative to the collider's surface is removed and Coulomb friction ([`coulomb`]) applied.
/// Returns the change of the tangential relative velocity, or `None` when it separates.
#[inline]
pub(crate) fn respond(
    collider: &Collider,
    x: Vec3,
    v: &mut Vec3,
    n: Vec3,
    mu_s: f32,
    mu_k: f32,
) -> Option<Vec3> {
    let v_col = collider.velocity_at(x);
    let v_rel = *v - v_col;
    let vn = v_rel.dot(n);
    if vn >= 0.0 {
        return None;
    }
    let (vt, vt_new) = coulomb(v_rel, vn, n, mu_s, mu_k);
    *v = v_col + vt_new;
    Some(vt_new - vt)
}

/// Counts of the contacts handled in one substep.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct ContactStats {
    pub contacts: u32,
    /// Continuous-collision corrections, summed over the step.
    pub ccd: u32,
}

/// Projects every free particle that is inside a collider's contact surface (surface +
/// thickness) back onto it, removes the approaching normal velocity relative to the collider
/// and applies Coulomb friction to the tangential part.
///
/// Friction, after Bridson et al. 2002: with Δv_n the normal velocity removed, a contact
/// sticks (tangential relative velocity set to zero) when |v_t| ≤ μ_s·Δv_n, else it slides
/// with |v_t| reduced by μ_k·Δv_n. The integrator already moved the particle with the
/// velocity from before the contact; `pos_weight` is how much of the new velocity enters the
/// new position (h for symplectic Euler, h/2 for position Verlet, 0 for forward Euler), and
/// the tangential velocity change times `pos_weight` is applied to the position too, so that
/// a sticking contact does not creep.
pub(crate) fn resolve_contacts(
    colliders: &[Collider],
    particles: &mut Particles,
    pos_weight: f32,
    stats: &mut ContactStats,
) {
    let p = particles;
    stats.contacts = resolve_contacts_in(
        colliders,
        &mut p.position,
        &mut p.velocity,
        &p.inv_mass,
        pos_weight,
    );
}

/// [`resolve_contacts`] on a range of particles (slices of equal length); returns the number
/// of contacts. Each particle is handled on its own, so ranges can run in any order.
pub(crate) fn resolve_contacts_in(
    colliders: &[Collider],
    position: &mut [Vec3],
    velocity: &mut [Vec3],
    inv_mass: &[f32],
    pos_weight: f32,
) -> u32 {
    let mut contacts = 0;
    for collider in colliders {
        let mu_s = collider.friction.static_coefficient;
        let mu_k = collider.friction.kinetic_coefficient;
        for ((x, v), &w) in position.iter_mut().zip(velocity.iter_mut()).zip(inv_mass) {
            if w == 0.0 {
                continue;
            }
            let (dist, n) = collider.shape.distance_within(*x, collider.contact_range());
            let phi = dist - collider.thickness;
            if phi >= 0.0 {
                continue;
            }
            contacts += 1;
            *x -= phi * n;
            if let Some(dvt) = respond(collider, *x, v, n, mu_s, mu_k) {
                *x += pos_weight * dvt;
            }
        }
    }
    contacts
}
