//! Contact and statics tests: force balance at the pins, the sphere scene without
//! penetration, Coulomb friction on an incline, and a moving collider.

mod common;
use common::stiff_patch;

use cloth_core::diagnostics::explicit_stability_limit;
use cloth_core::glam::{Quat, Vec3};
use cloth_core::{
    Collider, Corner, Friction, GridBuilder, Integrator, Mass, Material, Orientation, SimConfig,
    Simulation, SpringParams,
};

const G: f32 = 9.81;

/// The fabric of the draping tests, given explicitly so that they do not change when
/// `Material::default()` is retuned: structural 300 N/m, shear 60 N/m, bend 10 N/m, with
/// dashpots of 0.02, 0.01 and 0.005 N·s/m.
const FABRIC: Material = Material::isotropic(
    SpringParams::new(300.0, 0.02),
    SpringParams::new(60.0, 0.01),
    SpringParams::new(10.0, 0.005),
);

fn min_mass(sim: &Simulation) -> f32 {
    sim.particles()
        .mass
        .iter()
        .copied()
        .fold(f32::INFINITY, f32::min)
}

/// Asserts the configuration's substep is below the explicit stability estimate for this
/// cloth, so that the physics tests below are not testing a blow-up.
#[track_caller]
fn assert_stable_substep(sim: &Simulation) {
    let h = sim.config().substep_dt();
    let limit = explicit_stability_limit(sim.config(), min_mass(sim));
    assert!(
        h < limit,
        "substep {h} must be below the stability limit {limit}"
    );
}

// ---------------------------------------------------------------------------------------
// 1. Hanging cloth: the pins carry the weight
// ---------------------------------------------------------------------------------------

/// Static equilibrium of a cloth hung from its two top corners: once it is at rest every
/// free particle has zero net force, the internal forces cancel in pairs, so the pin
/// reactions sum to minus the total gravity force: Σ R = (0, Σm·|g|, 0), where Σm counts
/// every particle, pinned ones too. Tolerance 1% of the weight for the vertical total and
/// for each horizontal component: the residual comes from the cloth not being exactly at
/// rest (kinetic energy < 1e-8 J for 60 consecutive steps, i.e. speeds ~3e-4 m/s, so the
/// leftover inertial and damping forces are orders of magnitude below 1%; f32 rounding
/// keeps the kinetic energy of this cloth from going below ~4e-10 J). By mirror symmetry
/// the two pins carry equal vertical loads (1%) and their sideways pulls are equal and
/// opposite.
#[test]
fn hanging_cloth_pins_carry_its_weight() {
    let cloth = GridBuilder::new(12, 12)
        .size(1.0, 1.0)
        .orientation(Orientation::Vertical)
        .origin(Vec3::new(0.0, 1.0, 0.0))
        .mass(Mass::ArealDensity(0.2))
        .pin_corner(Corner::TopLeft)
        .pin_corner(Corner::TopRight)
        .build()
        .unwrap();
    let config = SimConfig {
        integrator: Integrator::SymplecticEuler,
        damping: 0.01,
        substeps: 40,
        material: FABRIC,
        ..SimConfig::default()
    };
    let mut sim = Simulation::new(cloth, config).unwrap();
    assert_stable_substep(&sim);
    let weight = sim.particles().total_mass() * G;
    // At rest: the kinetic energy stays below 1e-8 J for a whole second (a single low
    // reading can be the turning point of an oscillation).
    let mut settled_at = None;
    let mut quiet_steps = 0;
    for step in 0..3000 {
        let stats = sim.step().unwrap();
        quiet_steps = if stats.kinetic_energy < 1e-8 {
            quiet_steps + 1
        } else {
            0
        };
        if quiet_steps == 60 {
            settled_at = Some(step);
            break;
        }
    }
    let settled_at = settled_at.expect("the damped cloth must come to rest within 50 s");
    let ke = sim.stats().kinetic_energy;
    let reactions = sim.pin_reactions();
    assert_eq!(
        reactions.iter().map(|&(i, _)| i).collect::<Vec<_>>(),
        vec![0, 11]
    );
    let total: Vec3 = reactions.iter().map(|&(_, r)| r).sum();
    eprintln!(
        "hanging: settled at step {settled_at} (KE {ke:e} J), weight {weight} N, \
         Σ reactions {total}, per pin {reactions:?}"
    );
    assert!(
        (total.y - weight).abs() < 0.01 * weight,
        "vertical {} vs weight {weight}",
        total.y
    );
    assert!(total.x.abs() < 0.01 * weight, "x {}", total.x);
    assert!(total.z.abs() < 0.01 * weight, "z {}", total.z);
    let (left, right) = (reactions[0].1, reactions[1].1);
    assert!((left.y - right.y).abs() < 0.01 * weight);
    assert!((left.x + right.x).abs() < 0.01 * weight);
    // the pins pull the cloth outwards (it sags between them) and up
    assert!(left.x < 0.0 && right.x > 0.0 && left.y > 0.0 && right.y > 0.0);
}

// ---------------------------------------------------------------------------------------
// 2. The seed's scene: a cloth on a ball
// ---------------------------------------------------------------------------------------

const RADIUS: f32 = 0.3;
const THICKNESS: f32 = 0.01;
const GROUND_Y: f32 = -0.5;

fn ball_scene(offset_x: f32, friction: Friction) -> Simulation {
    let cloth = GridBuilder::new(24, 24)
        .size(1.0, 1.0)
        .origin(Vec3::new(offset_x, 0.6, 0.0))
        .build()
        .unwrap();
    let config = SimConfig {
        integrator: Integrator::SymplecticEuler,
        substeps: 64,
        material: FABRIC,
        ..SimConfig::default()
    };
    let mut sim = Simulation::new(cloth, config).unwrap();
    sim.add_collider(
        Collider::sphere(Vec3::ZERO, RADIUS)
            .with_thickness(THICKNESS)
            .with_friction(friction),
    )
    .unwrap();
    sim.add_collider(
        Collider::plane(Vec3::new(0.0, GROUND_Y, 0.0), Vec3::Y)
            .with_thickness(THICKNESS)
            .with_friction(friction),
    )
    .unwrap();
    assert_stable_substep(&sim);
    sim
}

/// Runs `steps` steps and checks after every one the non-penetration law of the contact
/// projection: no free particle is inside a collider's contact surface. Returns the
/// deepest penetration seen (from the stats) and the closest distance to the ball centre.
fn run_without_penetration(sim: &mut Simulation, steps: usize) -> (f32, f32) {
    let mut deepest = 0.0_f32;
    let mut closest = f32::INFINITY;
    let mut touched = false;
    for _ in 0..steps {
        let stats = sim.step().unwrap();
        deepest = deepest.max(stats.max_penetration);
        assert!(
            stats.max_penetration <= 1e-5,
            "step {}: penetration {}",
            stats.step,
            stats.max_penetration
        );
        touched |= stats.contacts > 0;
        let p = sim.particles();
        for (i, x) in p.position.iter().enumerate() {
            if p.is_pinned(i) {
                continue;
            }
            let d = x.length();
            closest = closest.min(d);
            assert!(
                d >= RADIUS + THICKNESS - 1e-5,
                "step {}: particle {i} at distance {d} from the ball centre",
                stats.step
            );
            assert!(x.y >= GROUND_Y + THICKNESS - 1e-5);
        }
    }
    assert!(touched, "the cloth must reach the ball");
    (deepest, closest)
}

/// The seed's scene (24×24 cloth, 1 m, dropped from 0.6 m onto a ball of radius 0.3 m with
/// contact thickness 0.01 m): the contact projection puts every particle that crosses the
/// contact surface back onto it, so after every step the reported penetration is ≤ 1e-5 m
/// (f32 rounding of a projection at |x| ≈ 0.3 m is ~1e-7 m; 1e-5 m is a thousandth of the
/// thickness), and directly: no free particle is closer than R + thickness − 1e-5 to the
/// centre, nor below the ground's contact surface. 2 s of simulated time.
#[test]
fn cloth_on_ball_never_penetrates() {
    let mut sim = ball_scene(0.0, Friction::new(0.8, 0.6));
    let (deepest, closest) = run_without_penetration(&mut sim, 120);
    eprintln!(
        "ball: deepest reported penetration {deepest:e} m, closest distance {closest} m \
         (contact surface at {})",
        RADIUS + THICKNESS
    );
    // the cloth rests on the ball: some particle is in contact
    assert!(closest < RADIUS + THICKNESS + 1e-4);
}

/// Coulomb friction decides whether a slightly off-centre cloth (0.05 m in x) stays on the
/// ball. With μ_s = 1.0, μ_k = 0.8 the cap of the ball holds the cloth: after 3 s the
/// centre of mass is above the ball's centre and its horizontal offset is below the
/// radius. Without friction the cap cannot hold any tangential load, so the cloth slides
/// off and its centre of mass ends lower than with friction by more than a radius (0.3 m,
/// a clear margin against the ~0.05 m scale of the asymmetry). Neither run penetrates.
#[test]
fn friction_holds_cloth_on_ball_frictionless_slides_off() {
    let mut sticky = ball_scene(0.05, Friction::new(1.0, 0.8));
    run_without_penetration(&mut sticky, 180);
    let com_sticky = sticky.particles().center_of_mass();

    let mut slippery = ball_scene(0.05, Friction::NONE);
    run_without_penetration(&mut slippery, 180);
    let com_slippery = slippery.particles().center_of_mass();
    eprintln!(
        "ball after 3 s: with friction COM {com_sticky}, without friction COM {com_slippery}"
    );

    let horizontal = |c: Vec3| (c.x * c.x + c.z * c.z).sqrt();
    assert!(com_sticky.y > 0.0, "with friction: COM {com_sticky}");
    assert!(
        horizontal(com_sticky) < RADIUS,
        "with friction: COM {com_sticky}"
    );
    assert!(
        com_slippery.y < com_sticky.y - RADIUS,
        "without friction the cloth must slide off: {com_slippery} vs {com_sticky}"
    );
    assert!(com_slippery.y < 0.0);
}

// ---------------------------------------------------------------------------------------
// 3. Coulomb friction on an incline
// ---------------------------------------------------------------------------------------

const THETA: f32 = std::f32::consts::PI / 6.0; // 30°, tan θ ≈ 0.577

/// A small stiff cloth (3×3, 0.1 m, 10 g per particle, k = 1000 N/m) lying on a plane
/// through the origin whose normal is +Y turned by θ about Z, placed at the contact
/// thickness above it. Gravity on; no air, no global damping (dashpots stay on: in a
/// rigid translation they exert nothing).
fn incline(integrator: Integrator, friction: Friction) -> Simulation {
    let q = Quat::from_rotation_z(THETA);
    let normal = q * Vec3::Y;
    let config = SimConfig {
        integrator,
        ..SimConfig::default()
    };
    let mut sim = stiff_patch(q, normal * THICKNESS, Vec3::ZERO, config);
    sim.add_collider(
        Collider::plane(Vec3::ZERO, normal)
            .with_thickness(THICKNESS)
            .with_friction(friction),
    )
    .unwrap();
    assert_stable_substep(&sim);
    sim
}

/// Down-slope unit vector: gravity's component along the plane.
fn downhill() -> Vec3 {
    let n = Quat::from_rotation_z(THETA) * Vec3::Y;
    let g = Vec3::new(0.0, -1.0, 0.0);
    (g - g.dot(n) * n).normalize()
}

/// Slides for 1 s and returns the acceleration measured two ways: from the displacement
/// along the slope, a = 2s/t², and from the mean down-slope velocity, a = v/t.
fn measured_acceleration(sim: &mut Simulation) -> (f32, f32) {
    let start = sim.particles().center_of_mass();
    for _ in 0..60 {
        sim.step().unwrap();
    }
    let t = sim.time() as f32;
    let p = sim.particles();
    let s = (p.center_of_mass() - start).dot(downhill());
    let v = p.momentum().dot(downhill()) / p.total_mass();
    // it stays on the plane
    let n = Quat::from_rotation_z(THETA) * Vec3::Y;
    for x in &p.position {
        assert!((x.dot(n) - THICKNESS).abs() < 1e-5, "left the plane: {x}");
    }
    (2.0 * s / (t * t), v / t)
}

/// Coulomb's law, static case: with μ_s = 0.8 > tan 30° ≈ 0.577 the friction needed to
/// hold the cloth (m·g·sin θ) is below μ_s times the normal force (m·g·cos θ), so it does
/// not move: after 1 s the centre of mass has moved less than 1e-5 m (f32 rounding of the
/// projection, ~1e-8 m per substep, over 1920 substeps), for symplectic Euler, Verlet,
/// implicit Euler and XPBD.
#[test]
fn incline_static_friction_holds() {
    for integrator in [
        Integrator::SymplecticEuler,
        Integrator::Verlet,
        Integrator::ImplicitEuler,
        Integrator::Xpbd,
    ] {
        let mut sim = incline(integrator, Friction::new(0.8, 0.6));
        let start = sim.particles().center_of_mass();
        for _ in 0..60 {
            sim.step().unwrap();
        }
        let moved = (sim.particles().center_of_mass() - start).length();
        eprintln!("incline {integrator:?}: static displacement {moved:e} m");
        assert!(moved < 1e-5, "{integrator:?}: moved {moved} m");
    }
}

/// Coulomb's law, kinetic case: with μ_s = 0.4 < tan 30° the cloth slides, and kinetic
/// friction μ_k·N opposes it: a = g(sin θ − μ_k cos θ) = 2.357 m/s² for μ_k = 0.3. The
/// acceleration measured from the distance slid in 1 s (s = ½at²) and from the velocity
/// (v = at) is within 2% of it (the integrators' own error here is ~1/N = 0.05% for N =
/// 1920 substeps; 2% leaves room without hiding a wrong friction law, which would be off by
/// ≥ 10%), for symplectic Euler, Verlet, implicit Euler (its kinetic impulse in the solve's
/// right-hand side) and XPBD (0.7 % over: its friction acts on positions).
#[test]
fn incline_kinetic_friction_acceleration() {
    let (mu_s, mu_k) = (0.4_f32, 0.3_f32);
    assert!(mu_s < THETA.tan());
    let expected = G * (THETA.sin() - mu_k * THETA.cos());
    for integrator in [
        Integrator::SymplecticEuler,
        Integrator::Verlet,
        Integrator::ImplicitEuler,
        Integrator::Xpbd,
    ] {
        let mut sim = incline(integrator, Friction::new(mu_s, mu_k));
        let (a_s, a_v) = measured_acceleration(&mut sim);
        eprintln!(
            "incline {integrator:?}: kinetic a from s {a_s}, from v {a_v}, expected {expected}"
        );
        assert!(
            (a_s - expected).abs() < 0.02 * expected,
            "{integrator:?}: {a_s}"
        );
        assert!(
            (a_v - expected).abs() < 0.02 * expected,
            "{integrator:?}: {a_v}"
        );
    }
}

/// Frictionless incline: a = g sin θ = 4.905 m/s², from the distance and from the velocity,
/// within 2% (same reasoning as the kinetic case), for the same four integrators.
#[test]
fn incline_frictionless_acceleration() {
    let expected = G * THETA.sin();
    for integrator in [
        Integrator::SymplecticEuler,
        Integrator::Verlet,
        Integrator::ImplicitEuler,
        Integrator::Xpbd,
    ] {
        let mut sim = incline(integrator, Friction::NONE);
        let (a_s, a_v) = measured_acceleration(&mut sim);
        eprintln!(
            "incline {integrator:?}: frictionless a from s {a_s}, from v {a_v}, expected {expected}"
        );
        assert!(
            (a_s - expected).abs() < 0.02 * expected,
            "{integrator:?}: {a_s}"
        );
        assert!(
            (a_v - expected).abs() < 0.02 * expected,
            "{integrator:?}: {a_v}"
        );
    }
}

// ---------------------------------------------------------------------------------------
// 4. A moving collider
// ---------------------------------------------------------------------------------------

/// A ground plane rising at V = 0.5 m/s lifts a cloth resting on it. The contact removes
/// the approaching relative normal velocity, so a particle pressed onto the plane by
/// gravity ends every substep moving with the plane: for symplectic Euler, Verlet, implicit
/// Euler (whose sticking contacts are fixed at the plane's velocity in its solve) and XPBD,
/// after every step each particle's velocity equals (0, V, 0) within 1e-4 m/s (f32 rounding; the
/// gravity kick of one substep, g·h ≈ 5e-3 m/s, is fifty times larger, so a missed contact
/// would show). Forward Euler moves positions with the velocity from before the substep,
/// so a particle that sits exactly on the moving surface may be caught only one substep
/// later: its velocity is within one substep's kick, 2·g·h (gravity plus the air drag and
/// spring forces of that substep), of V. For all five, no particle is ever below the
/// plane's contact surface (1e-5 m), and after 1 s the plane has risen V·t = 0.5 m
/// (1e-4 m) and the cloth with it (its centre of mass at the contact surface, 1e-5 m).
#[test]
fn rising_plane_carries_the_cloth() {
    for integrator in [
        Integrator::ForwardEuler,
        Integrator::SymplecticEuler,
        Integrator::Verlet,
        Integrator::ImplicitEuler,
        Integrator::Xpbd,
    ] {
        let cloth = GridBuilder::new(8, 8)
            .size(0.5, 0.5)
            .origin(Vec3::new(0.0, THICKNESS, 0.0))
            .build()
            .unwrap();
        let config = SimConfig {
            integrator,
            material: FABRIC,
            ..SimConfig::default()
        };
        let mut sim = Simulation::new(cloth, config).unwrap();
        let speed = 0.5;
        sim.add_collider(
            Collider::plane(Vec3::ZERO, Vec3::Y)
                .with_thickness(THICKNESS)
                .with_velocity(Vec3::new(0.0, speed, 0.0)),
        )
        .unwrap();
        assert_stable_substep(&sim);
        let mut worst_v = 0.0_f32;
        for _ in 0..60 {
            sim.step().unwrap();
            let plane_y = match sim.colliders()[0].shape {
                cloth_core::Shape::Plane { point, .. } => point.y,
                _ => unreachable!("collider 0 is the plane"),
            };
            let p = sim.particles();
            for (x, v) in p.position.iter().zip(&p.velocity) {
                assert!(x.y >= plane_y + THICKNESS - 1e-5, "{integrator:?}: {x}");
                worst_v = worst_v.max((*v - Vec3::new(0.0, speed, 0.0)).length());
            }
        }
        let plane_y = match sim.colliders()[0].shape {
            cloth_core::Shape::Plane { point, .. } => point.y,
            _ => unreachable!("collider 0 is the plane"),
        };
        let com = sim.particles().center_of_mass();
        eprintln!(
            "rising plane {integrator:?}: worst |v − V| {worst_v:e} m/s, plane at {plane_y}, \
             COM {com}"
        );
        let tolerance = if integrator == Integrator::ForwardEuler {
            2.0 * G * sim.config().substep_dt()
        } else {
            1e-4
        };
        assert!(
            worst_v < tolerance,
            "{integrator:?}: |v − V| up to {worst_v}"
        );
        assert!((plane_y - 0.5).abs() < 1e-4, "plane at {plane_y}");
        assert!((com.y - (plane_y + THICKNESS)).abs() < 1e-5, "COM {com}");
    }
}
