//! Force terms: gravity, Hooke springs, dashpots, the seed's global damping, and air.

use glam::Vec3;

use crate::config::SimConfig;
use crate::particles::Particles;
use crate::topology::{SpringKind, Topology};

/// Accumulates the total force on every particle (pinned ones included, so that pin reactions
/// can be read off) into `force`, overwriting it.
///
/// Terms, each skipped when switched off in [`SimConfig::forces`]:
/// 1. gravity m·g and global damping −d·v, per particle;
/// 2. per spring, Hooke k(|L| − L0)·L/|L| and the dashpot c((v_b − v_a)·d)·d, applied to both
///    ends with opposite signs (so internal forces sum to zero exactly);
/// 3. per triangle, air drag and lift against `wind` (see [`crate::Air`]).
pub(crate) fn accumulate(
    config: &SimConfig,
    topology: &Topology,
    particles: &Particles,
    wind: Vec3,
    force: &mut [Vec3],
) {
    accumulate_capped(config, topology, particles, wind, force, f32::INFINITY);
}

/// [`accumulate`] with the global damping of each particle at most `m·inv_h` (`inv_h` = 1/h
/// of the step the forces are for): the damping force that stops the particle within the
/// step, [`capped_damping`]. XPBD's prediction, where the damping is explicit and nothing
/// else bounds the step, takes it so; the force-based integrators pass no cap.
pub(crate) fn accumulate_capped(
    config: &SimConfig,
    topology: &Topology,
    particles: &Particles,
    wind: Vec3,
    force: &mut [Vec3],
    inv_h: f32,
) {
    let (position, velocity, mass) = (&particles.position, &particles.velocity, &particles.mass);
    let sw = config.forces;
    let (gravity, damping) = body_forces(config);
    for ((f, &m), &v) in force.iter_mut().zip(mass).zip(velocity) {
        *f = m * gravity - capped_damping(damping, m, inv_h) * v;
    }

    if sw.springs || sw.dashpots {
        for kind in SpringKind::ALL {
            let p = config.material.params(kind);
            let k = if sw.springs { p.stiffness } else { 0.0 };
            let c = if sw.dashpots { p.damping } else { 0.0 };
            if k == 0.0 && c == 0.0 {
                continue;
            }
            for s in topology.springs_of(kind) {
                let (a, b) = (s.a as usize, s.b as usize);
                let ends = [position[a], position[b], velocity[a], velocity[b]];
                if let Some(f) = spring_force(ends, s.rest_length, k, c) {
                    force[a] += f;
                    force[b] -= f;
                }
            }
        }
    }

    if sw.air {
        add_air(config, topology, position, velocity, wind, force);
    }
}

/// Gravity (m/s², zero when switched off) and the global damping coefficient (kg/s, zero
/// when switched off) of [`accumulate`]'s first term, m·g − d·v.
pub(crate) fn body_forces(config: &SimConfig) -> (Vec3, f32) {
    let sw = config.forces;
    let gravity = if sw.gravity {
        config.gravity
    } else {
        Vec3::ZERO
    };
    (gravity, if sw.damping { config.damping } else { 0.0 })
}

/// The Hooke and dashpot force of a spring (rest length `rest`, stiffness `k`, damping `c`)
/// on its first end, from its ends' positions and velocities `[x_a, x_b, v_a, v_b]`; its
/// second end takes the opposite. `None` for a spring of zero length (or one so short that
/// its squared length is below [`ZERO_LENGTH_SQUARED`]), which has no direction and adds
/// nothing.
///
/// With `l = x_b − x_a`, the force is `(k·(|l| − rest)·(1/|l|) + c·((v_b − v_a)·l)·(1/|l|²))·l`:
/// the square root and the one division `1/|l|²` both start from `|l|²`, so neither waits
/// for the other (`1/|l|` is the product `|l|·(1/|l|²)`; [`spring_per_length`]). The grid
/// fast paths use the same operations in the same order, so every path gives the same bits.
#[inline]
pub(crate) fn spring_force([xa, xb, va, vb]: [Vec3; 4], rest: f32, k: f32, c: f32) -> Option<Vec3> {
    let l = xb - xa;
    let len2 = l.length_squared();
    if len2 < ZERO_LENGTH_SQUARED {
        return None;
    }
    Some(spring_per_length(len2, (vb - va).dot(l), rest, k, c) * l)
}

/// Squared lengths below this (`f32::MIN_POSITIVE`, a spring shorter than about 1.1·10⁻¹⁹ m)
/// are a spring of zero length to every path: its `1/|l|²` would overflow. The reference
/// skips such a spring; the grid kernels flag it and hand the substep to the reference.
pub(crate) const ZERO_LENGTH_SQUARED: f32 = f32::MIN_POSITIVE;

/// The scalar force of a spring per unit of its vector `l`, from its squared length `len2`
/// and `along = (v_b − v_a)·l`: `k·(|l| − rest)·(1/|l|) + c·along·(1/|l|²)`, with `1/|l|`
/// as `|l|·(1/|l|²)`. The reference and the compiled row kernel both call it, so both give
/// these bits; the fused SIMD row (`simd::spring`) runs the same operations in this order.
#[inline(always)]
pub(crate) fn spring_per_length(len2: f32, along: f32, rest: f32, k: f32, c: f32) -> f32 {
    let len = len2.sqrt();
    let inv2 = 1.0 / len2;
    let inv = len * inv2;
    k * (len - rest) * inv + c * along * inv2
}

fn add_air(
    config: &SimConfig,
    topology: &Topology,
    position: &[Vec3],
    velocity: &[Vec3],
    wind: Vec3,
    force: &mut [Vec3],
) {
    let air = &config.air;
    if air.density == 0.0 || (air.drag_coefficient == 0.0 && air.lift_coefficient == 0.0) {
        return;
    }
    for &tri in topology.triangles() {
        let f = air_share(config, position, velocity, wind, tri);
        for i in tri {
            force[i as usize] += f;
        }
    }
}

/// The share of triangle `tri`'s air force ([`triangle_air_force`]) each of its corners takes.
#[inline]
pub(crate) fn air_share(
    config: &SimConfig,
    position: &[Vec3],
    velocity: &[Vec3],
    wind: Vec3,
    tri: [u32; 3],
) -> Vec3 {
    let air = &config.air;
    let [i, j, k] = tri.map(|i| i as usize);
    triangle_air_force(
        air.density,
        air.drag_coefficient,
        air.lift_coefficient,
        [position[i], position[j], position[k]],
        (velocity[i] + velocity[j] + velocity[k]) * THIRD,
        wind,
    ) * THIRD
}

/// One third, as the factor of the triangle's mean velocity and of each corner's share of its
/// air force (a product instead of a division).
pub(crate) const THIRD: f32 = 1.0 / 3.0;

/// Total air force on one triangle with corners `x` moving at `v_tri` in `wind`: drag
/// ½ρ|v_rel|²·C_d·A·cos θ along the normal and lift ½ρ|v_rel|²·C_l·A·|cos θ|·sin θ
/// perpendicular to the flow (see [`crate::Air`]).
///
/// With `c` the corners' cross product (A = |c|/2, n = c/|c|), `r` the relative wind,
/// `C = |c|²`, `S = |r|²` and `t = 1/√(C·S)`: cos θ = (c·r)·t and
/// `F = ¼ρ·(c·r)·t·((C_d + C_l)·S·c − C_l·(c·r)·r)`, one square root and one division per
/// triangle (the grid paths' air kernel does the same operations). A triangle with no area, in
/// no wind, or whose `C·S` is not a normal positive `f32` (below about 10⁻³⁸, where the force
/// is far below anything that could move a particle, or past 3·10³⁸) gets none.
#[must_use]
pub fn triangle_air_force(
    density: f32,
    drag_coefficient: f32,
    lift_coefficient: f32,
    x: [Vec3; 3],
    v_tri: Vec3,
    wind: Vec3,
) -> Vec3 {
    let c = (x[1] - x[0]).cross(x[2] - x[0]);
    let r = wind - v_tri;
    let (cc, ss) = (c.length_squared(), r.length_squared());
    let p = cc * ss;
    if !(f32::MIN_POSITIVE..f32::INFINITY).contains(&p) {
        return Vec3::ZERO;
    }
    let t = 1.0 / p.sqrt();
    let cr = c.dot(r);
    let k = 0.25 * density * cr * t;
    k * ((drag_coefficient + lift_coefficient) * ss * c - lift_coefficient * cr * r)
}

/// The global damping coefficient `d` (kg/s) of a particle of mass `m`, at most `m·inv_h`:
/// an explicit step of −d·v then never reverses a velocity (`v·(1 − h·d/m)` stays ≥ 0), and
/// at the cap it stops the particle within the step, as an overdamped damper would. Below the
/// cap (h·d/m < 1, every practical setting: the drape's 512² cloth has 3·10⁻³) it is `d`
/// itself, bit for bit. With `inv_h` infinite there is no cap.
#[inline(always)]
pub(crate) fn capped_damping(d: f32, m: f32, inv_h: f32) -> f32 {
    d.min(m * inv_h)
}

#[cfg(test)]
mod tests {
    use super::spring_force;
    use crate::test_rng::uniform;
    use glam::{DVec3, Vec3};

    /// Hooke's law with a dashpot along the spring, F = (k(|L| − L0) + c·(v_b − v_a)·L̂)·L̂ on
    /// the first end: [`spring_force`] (its reciprocal length as |L|·(1/|L|²)) matches the law
    /// evaluated in f64 from the same f32 differences on 10,000 random springs (lengths 10⁻³ to
    /// 1 m, rest lengths 0.5 to 1.5 times the length, stiffness to 10⁴ N/m, damping to
    /// 10 N·s/m, velocity components to ±10 m/s).
    /// Tolerance: 10⁻⁶ of the size of the terms the result cancels from, k(|L| + L0) +
    /// c·|Δv| (|L| rounded to f32 is off by up to an ulp of |L|, which k(|L| − L0) keeps
    /// however small the strain), a few f32 roundings.
    #[test]
    fn spring_force_is_hookes_law_with_a_dashpot() {
        let mut u = uniform(0x005e_ed48);
        let mut v3 = |s: f32| Vec3::new(u() - 0.5, u() - 0.5, u() - 0.5) * s;
        for _ in 0..10_000 {
            let xa = v3(2.0);
            let dir = v3(1.0);
            if dir.length() < 1e-3 {
                continue;
            }
            let len = 10f32.powf(-3.0 * (v3(1.0).x + 0.5));
            let xb = xa + dir.normalize() * len;
            let rest = len * (1.0 + v3(1.0).y);
            let (va, vb) = (v3(20.0), v3(20.0));
            let (k, c) = (1e4 * (v3(1.0).z + 0.5), 10.0 * (v3(1.0).x + 0.5));
            let f = spring_force([xa, xb, va, vb], rest, k, c).expect("a spring of length");
            // The law from the same f32 difference L the function starts from (the
            // subtraction's rounding, up to 10⁻⁴ of a 1 mm spring, is the input's).
            let l = (xb - xa).as_dvec3();
            let d = l / l.length();
            let dv: DVec3 = (vb - va).as_dvec3();
            let stretch = f64::from(k) * (l.length() - f64::from(rest));
            let damp = f64::from(c) * dv.dot(d);
            let exact = (stretch + damp) * d;
            // The size of the terms the difference |L| − L0 and the sum cancel from.
            let scale = f64::from(k) * (l.length() + f64::from(rest)) + f64::from(c) * dv.length();
            let err = (f.as_dvec3() - exact).length();
            assert!(
                err <= 1e-6 * scale,
                "{f} against {exact}: {err} > 1e-6 × {scale}"
            );
        }
    }

    /// A spring of zero length has no direction and adds nothing; so does one whose squared
    /// length is below `f32::MIN_POSITIVE` (shorter than about 1.1·10⁻¹⁹ m), whose 1/|L|²
    /// would overflow. Just above that the force is finite. Tolerance: none.
    #[test]
    fn a_spring_too_short_to_square_has_no_force() {
        let x = Vec3::ZERO;
        let v = Vec3::ZERO;
        let force = |len: f32| spring_force([x, Vec3::new(len, 0.0, 0.0), v, v], 0.1, 100.0, 1.0);
        assert_eq!(force(0.0), None);
        assert_eq!(force(1e-20), None, "squared length 1e-40 is subnormal");
        let just_above = force(1.2e-19).expect("squared length 1.44e-38 is normal");
        assert!(just_above.is_finite(), "{just_above}");
        // k(|L| − L0) pulls the ends apart towards the rest length: the first end goes −x.
        assert!(just_above.x < 0.0 && just_above.y == 0.0 && just_above.z == 0.0);
    }
}
