//! Continuous collision against the colliders: no particle ends a substep on the wrong side
//! of a thin or fast collider.
//!
//! The discrete contact passes of the integrators look only at where a particle ends a
//! substep. A particle that moves further than a collider is thick in one substep (a cloth at
//! 20 m/s against a 1 cm plate, or a thin board swept through a curtain) can end past it, or
//! inside it and be projected out of the far face. This pass runs after the integrator, with
//! the positions from the start of the substep:
//!
//! 1. The start point `a` is carried into the collider's pose at the end of the substep
//!    (undoing the collider's own translation and turn over the substep), so that `a → b`
//!    is the particle's path relative to the collider and `b` is where the integrator left
//!    the particle.
//! 2. Cheap cull: every shape's signed distance `φ` is 1-Lipschitz, so the path cannot touch
//!    the solid when `φ(a) + φ(b) ≥ |b − a|`, which already holds when `φ(b) ≥ |b − a|` (one
//!    distance query). Nearly every particle stops here. For a sphere or a plane, a path that
//!    ends too shallow inside for step 4 ever to correct it (a particle sliding over the
//!    surface) stops here too, by a bound on `(b − p)·n` (`shallow`).
//! 3. Conservative advancement (sphere tracing) along the path finds the first point where it
//!    touches the solid surface, with the outward normal `n` there. It never steps past the
//!    surface, because each step is at most the distance to it.
//! 4. If `b` lies behind that entry point by more than a tolerance — `(b − p)·n < −τ` with
//!    `τ = max(thickness / 4, 0.1 mm)` — the particle went through: it is put back at the
//!    entry point, on the contact surface (`p + thickness·n`), its approaching normal
//!    velocity relative to the collider is removed and Coulomb friction applied as in the
//!    discrete pass. A particle that the discrete pass already put on the correct side is
//!    left alone, so resting and sliding contacts are unchanged.
//!
//! 5. Last, when a pass runs after the integrator's own contact handling (strain limiting or
//!    self-collision with the force-based integrators), `project` puts back on the contact
//!    surface any particle it pushed into the contact layer, so that every substep starts
//!    with the particles outside the solids.
//!
//! Particles starting inside a solid are left to the discrete pass. The passes allocate
//! nothing and visit particles in index order (deterministic).

use glam::{Quat, Vec3};

use super::Collider;
use crate::particles::Particles;

/// Surface tolerance of the advancement, m.
pub(crate) const HIT_EPSILON: f32 = 1e-5;
/// Most advancement steps along one path; a path that grazes the surface for longer is
/// treated as touching at the last point reached (which is still outside).
const MAX_MARCH: usize = 64;

/// Moves every free particle that passed through a collider during the substep back to the
/// side it came from. `start` holds the positions at the start of the substep, `h` is the
/// substep length (the colliders are at their pose at its end). Returns the number of
/// particles corrected.
pub(crate) fn resolve(
    colliders: &[Collider],
    start: &[Vec3],
    particles: &mut Particles,
    h: f32,
) -> u32 {
    use rayon::prelude::*;
    // Each particle is handled on its own: chunks in parallel give the same result.
    const CHUNK: usize = 1024;
    let p = particles;
    p.position
        .par_chunks_mut(CHUNK)
        .zip(p.velocity.par_chunks_mut(CHUNK))
        .zip(p.inv_mass.par_chunks(CHUNK).zip(start.par_chunks(CHUNK)))
        .map(|((x, v), (w, a))| resolve_in(colliders, a, x, v, w, h))
        .sum()
}

/// [`resolve`] on a range of particles (slices of equal length). Each particle is handled on
/// its own, so ranges can run in any order.
pub(crate) fn resolve_in(
    colliders: &[Collider],
    start: &[Vec3],
    position: &mut [Vec3],
    velocity: &mut [Vec3],
    inv_mass: &[f32],
    h: f32,
) -> u32 {
    let mut corrected = 0;
    for col in colliders {
        let pivot_end = col.shape.pivot();
        let pivot_start = pivot_end - col.velocity * h;
        let turn = if col.angular_velocity == Vec3::ZERO {
            None
        } else {
            Some(Quat::from_scaled_axis(col.angular_velocity * h))
        };
        let tau = tolerance(col);
        let radius = curvature_radius(&col.shape);
        let (mu_s, mu_k) = (
            col.friction.static_coefficient,
            col.friction.kinetic_coefficient,
        );
        for (((x, v), &w), &a) in position
            .iter_mut()
            .zip(velocity.iter_mut())
            .zip(inv_mass)
            .zip(start)
        {
            if w == 0.0 {
                continue;
            }
            // 1. the path relative to the collider, in its end pose
            let a = match turn {
                Some(q) => pivot_end + q * (a - pivot_start),
                None => a + (pivot_end - pivot_start),
            };
            let b = *x;
            let path = b - a;
            // Cheaper first cut, without the square root: |path| < 0.45·τ (see below).
            if path.length_squared() < 0.2 * tau * tau {
                continue;
            }
            let len = path.length();
            // A path shorter than τ can never end more than τ behind its entry point (every
            // point of it is within `len` of the end); half of τ leaves room for rounding.
            if len.is_nan() || len < 0.5 * tau {
                continue;
            }
            // 2. cull: φ(a) ≥ φ(b) − |b − a|, so φ(b) ≥ |b − a| alone implies the test
            let (db, _) = col.shape.distance_within(b, len);
            if db >= len {
                continue;
            }
            if radius.is_some_and(|r| shallow(r, tau, len, db)) {
                continue;
            }
            let Some((p, n)) = went_through(&col.shape, a, b, len, db, tau) else {
                continue;
            };
            corrected += 1;
            *x = p + col.thickness * n;
            let _ = super::respond(col, *x, v, n, mu_s, mu_k);
        }
    }
    corrected
}

/// Steps 2 (the start's part of the cull) to 4 for one path `a → b` of length `len` whose
/// end lies at signed distance `db` from `shape`: the entry point on the surface and the
/// normal there if the end lies more than `tau` behind it, else `None`.
#[inline]
fn went_through(
    shape: &super::Shape,
    a: Vec3,
    b: Vec3,
    len: f32,
    db: f32,
    tau: f32,
) -> Option<(Vec3, Vec3)> {
    let (da, _) = shape.distance_within(a, len);
    if da < 0.0 || da + db >= len {
        return None;
    }
    // 3. advance to the first touch
    let path = b - a;
    let mut t = 0.0;
    let mut p = a;
    let mut hit = None;
    for _ in 0..MAX_MARCH {
        let (d, n) = shape.distance_within(p, len);
        if d <= HIT_EPSILON {
            hit = Some(n);
            break;
        }
        t += d / len;
        if t >= 1.0 {
            break;
        }
        p = a + t * path;
        hit = Some(n);
    }
    let n = hit?;
    if t >= 1.0 || n == Vec3::ZERO {
        return None;
    }
    // 4. through? back to the entry point
    if (b - p).dot(n) >= -tau {
        return None;
    }
    Some((p, n))
}

/// The radius of curvature of a shape's whole surface for [`shallow`]: a sphere's radius,
/// infinite for a plane, `None` for the other shapes.
#[inline(always)]
pub(crate) fn curvature_radius(shape: &super::Shape) -> Option<f32> {
    match *shape {
        super::Shape::Sphere { radius, .. } => Some(radius),
        super::Shape::Plane { .. } => Some(f32::INFINITY),
        _ => None,
    }
}

/// Whether a path of length `len` that ends at signed distance `db` from a sphere of radius
/// `radius` (`f32::INFINITY`: a plane) can never be corrected by [`resolve_in`]: wherever the
/// advancement stops on the path (a point `p` within [`HIT_EPSILON`] of the surface, normal
/// `n`), the end lies less than `τ` behind it.
///
/// For a sphere of centre `c`, with `u = b − c`, `q = p − c` and `|b − p| ≤ len`:
/// `(b − p)·n = (|u|² − |q|² − |b − p|²) / (2|q|) ≥ (db − ε)(1 + len/(2|q|)) − len²/(2|q|)`,
/// which is above `−¾τ` when `−db + ε + len²/r ≤ ½τ` and `r ≥ τ`; for a plane
/// `(b − p)·n = db − φ(p) ≥ db − ε`. The quarter of `τ` left over is far above the rounding of
/// the marching (positions of order 1 m: ~1e-7 m). This only skips particles that the march
/// would leave alone, so the result is the same bits; it saves the march for particles that
/// slide along or rest just inside a sphere or plane.
#[inline(always)]
pub(crate) fn shallow(radius: f32, tau: f32, len: f32, db: f32) -> bool {
    let room = 0.5 * tau - HIT_EPSILON + db;
    if radius == f32::INFINITY {
        room >= 0.0
    } else {
        (radius >= tau) & (len * len <= room * radius)
    }
}

/// How far behind the entry point a particle must end to count as having gone through
/// `col`, m: `max(thickness / 4, 0.1 mm)`. A path shorter than this can never be corrected
/// (every point of the path is within its length of the end), which the grid fast path uses
/// to skip the pass for slow particles.
pub(crate) fn tolerance(col: &Collider) -> f32 {
    (0.25 * col.thickness).max(1e-4)
}

/// Depth below the contact surface that [`project`] tolerates, m (rounding of the contact
/// passes themselves).
const PROJECT_SLACK: f32 = 1e-6;

/// Moves every free particle that is more than [`PROJECT_SLACK`] inside a collider's
/// contact surface back onto it along the surface normal, and removes its velocity into the
/// collider (relative to the collider's surface). No friction: this only undoes what later
/// passes did to particles the contact pass had already handled.
pub(crate) fn project(colliders: &[Collider], particles: &mut Particles) {
    let p = particles;
    project_in(colliders, &mut p.position, &mut p.velocity, &p.inv_mass);
}

/// [`project`] on a range of particles (slices of equal length).
pub(crate) fn project_in(
    colliders: &[Collider],
    position: &mut [Vec3],
    velocity: &mut [Vec3],
    inv_mass: &[f32],
) {
    for col in colliders {
        for ((x, v), &w) in position.iter_mut().zip(velocity.iter_mut()).zip(inv_mass) {
            if w == 0.0 {
                continue;
            }
            let (dist, n) = col.shape.distance_within(*x, col.contact_range());
            let phi = dist - col.thickness;
            if phi >= -PROJECT_SLACK || n == Vec3::ZERO {
                continue;
            }
            *x -= phi * n;
            let vn = (*v - col.velocity_at(*x)).dot(n);
            if vn < 0.0 {
                *v -= vn * n;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collide::Shape;

    /// Soundness of [`shallow`] (the bound derived in its docs): over many short paths that
    /// end just inside or outside a sphere or a plane (grazing, sliding, diving; the centre
    /// and radius varied), every path that `shallow` skips is one the march leaves alone
    /// (`went_through` gives `None`). Tolerance: none (an exact implication), and the test
    /// also checks that it skips most of the sliding paths it was made for.
    #[test]
    fn shallow_paths_are_never_corrected_by_the_march() {
        let mut uniform = crate::test_rng::uniform(0x2545_f491_4f6c_dd1d);
        let (mut skipped, mut sliding, mut sliding_skipped, mut corrected) = (0, 0, 0, 0);
        for case in 0..200_000 {
            let plane = case % 4 == 0;
            let radius = [0.05, 0.3, 1.0, 4.0][case % 4];
            let center = Vec3::new(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5);
            let normal = Vec3::new(uniform() - 0.5, 1.0, uniform() - 0.5).normalize();
            let shape = if plane {
                Shape::Plane {
                    point: center,
                    normal,
                }
            } else {
                Shape::Sphere { center, radius }
            };
            let tau = [1e-4, 2.5e-4, 1e-3][case % 3];
            // A start at height 0 .. 3τ above the surface, a path of 0.5τ .. 20τ, mostly
            // along the surface and down into it.
            let dir = Vec3::new(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5).normalize();
            let up = if plane {
                normal
            } else {
                Vec3::new(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5).normalize()
            };
            let base = if plane { center } else { center + radius * up };
            let a = base + up * (3.0 * tau * uniform());
            let tangent = (dir - dir.dot(up) * up).normalize_or_zero();
            let dive = uniform() * uniform();
            let step = (tangent - dive * up).normalize_or_zero();
            let b = a + step * (tau * (0.5 + 19.5 * uniform() * uniform()));
            let len = (b - a).length();
            let (db, _) = shape.distance_within(b, len);
            if db >= len || len < 0.5 * tau {
                continue;
            }
            let r = curvature_radius(&shape).expect("a sphere or a plane");
            let is_sliding = dive < 0.05;
            sliding += usize::from(is_sliding);
            if shallow(r, tau, len, db) {
                skipped += 1;
                sliding_skipped += usize::from(is_sliding);
                assert!(
                    went_through(&shape, a, b, len, db, tau).is_none(),
                    "case {case}: skipped a path the march corrects (a {a}, b {b}, r {r}, τ {tau})"
                );
            } else if went_through(&shape, a, b, len, db, tau).is_some() {
                corrected += 1;
            }
        }
        // The sample also holds paths that do go through (the implication is not vacuous).
        assert!(corrected > 1_000, "only {corrected} paths corrected");
        assert!(skipped > 10_000, "only {skipped} paths skipped");
        assert!(
            sliding_skipped * 2 > sliding,
            "{sliding_skipped} of {sliding} sliding paths skipped"
        );
    }
}
