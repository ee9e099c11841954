//! Continuous collision against colliders: a cloth moving further than a collider is thick in
//! one substep never ends a step on the wrong side of it. Each test also runs with continuous
//! collision off and checks that the same setup then does tunnel (so the test can fail).

use cloth_core::glam::{Quat, Vec3};
use cloth_core::{
    Collider, Edge, Friction, GridBuilder, Integrator, Mass, Orientation, SimConfig, Simulation,
};

const INTEGRATORS: [Integrator; 3] = [
    Integrator::SymplecticEuler,
    Integrator::ImplicitEuler,
    Integrator::Xpbd,
];

/// A 1 cm thick plate (half height 5 mm, contact thickness 2 mm) and a horizontal cloth
/// (2 kg/m², heavy enough for symplectic Euler at this step) thrown at it at 20 m/s. With 16 substeps of 1/960 s each particle moves 20.8 mm per
/// substep, more than the plate and both contact layers (14 mm). Returns the lowest height
/// any particle reached at the end of a step over the plate's footprint.
fn plate_drop(integrator: Integrator, ccd: bool) -> f32 {
    let cloth = GridBuilder::new(12, 12)
        .size(0.5, 0.5)
        .origin(Vec3::new(0.0, 0.25, 0.0))
        .velocity(Vec3::new(0.0, -20.0, 0.0))
        .mass(Mass::ArealDensity(2.0))
        .build()
        .expect("cloth");
    let config = SimConfig {
        integrator,
        substeps: 16,
        continuous_collision: ccd,
        ..SimConfig::default()
    };
    let mut sim = Simulation::new(cloth, config).expect("sim");
    sim.add_collider(
        Collider::cuboid(Vec3::ZERO, Vec3::new(1.0, 0.005, 1.0), Quat::IDENTITY)
            .with_thickness(0.002)
            .with_friction(Friction::new(0.5, 0.4)),
    )
    .expect("plate");
    let mut lowest = f32::INFINITY;
    for _ in 0..30 {
        sim.step().unwrap_or_else(|e| panic!("{integrator:?}: {e}"));
        for p in &sim.particles().position {
            if p.x.abs() < 1.0 && p.z.abs() < 1.0 {
                lowest = lowest.min(p.y);
            }
        }
    }
    lowest
}

/// Cloth at 20 m/s toward a 1 cm plate: with continuous collision every particle ends every
/// step above the plate's top face (y ≥ 5 mm, tolerance 1e-5 m: the contact surface is at
/// 7 mm), for symplectic Euler, implicit Euler and XPBD. Without it the cloth goes through.
#[test]
fn fast_cloth_does_not_tunnel_through_a_thin_plate() {
    for integrator in INTEGRATORS {
        let lowest = plate_drop(integrator, true);
        assert!(
            lowest >= 0.005 - 1e-5,
            "{integrator:?}: a particle ended at y = {lowest} (plate top at 0.005)"
        );
        let lowest_off = plate_drop(integrator, false);
        assert!(
            lowest_off < -0.005,
            "{integrator:?}: without continuous collision the cloth should tunnel \
             (lowest {lowest_off})"
        );
    }
}

/// Counts the particles that crossed the swept board: in the board's frame a particle that
/// was in front of it (local z > 0) over its face (|x| < hx, |y| < hy) at one substep and
/// behind it (local z < 0) over its face at the next went through it (going around an edge
/// means leaving the face's footprint first), as does any particle that ends a substep
/// inside the board. Runs 0.1 s, one substep per step.
fn sweep_crossings(integrator: Integrator, ccd: bool) -> usize {
    let cloth = GridBuilder::new(24, 24)
        .size(1.0, 1.0)
        .orientation(Orientation::Vertical)
        .origin(Vec3::new(0.0, 1.0, 0.0))
        .mass(Mass::ArealDensity(3.0))
        .pin_edge(Edge::Top)
        .build()
        .expect("cloth");
    // One substep per step, so that the check below sees every substep.
    let config = SimConfig {
        integrator,
        dt: 1.0 / 720.0,
        substeps: 1,
        continuous_collision: ccd,
        strain_limit: (integrator != Integrator::Xpbd).then_some(0.1),
        ..SimConfig::default()
    };
    let mut sim = Simulation::new(cloth, config).expect("sim");
    // A board 40 cm × 40 cm × 1 cm moving at 15 m/s along +z: 20.8 mm per substep of
    // 1/720 s, more than its thickness plus both contact layers (14 mm).
    let half = Vec3::new(0.2, 0.2, 0.005);
    let start = Vec3::new(0.0, 0.9, -0.2);
    let velocity = Vec3::new(0.0, 0.0, 15.0);
    sim.add_collider(
        Collider::cuboid(start, half, Quat::IDENTITY)
            .with_thickness(0.002)
            .with_friction(Friction::new(0.3, 0.2))
            .with_velocity(velocity),
    )
    .expect("board");
    let local = |sim: &Simulation| -> Vec<Vec3> {
        let cloth_core::Shape::Box { center, .. } = sim.colliders()[0].shape else {
            unreachable!()
        };
        sim.particles()
            .position
            .iter()
            .map(|p| *p - center)
            .collect()
    };
    let over = |l: Vec3| l.x.abs() < half.x && l.y.abs() < half.y;
    let mut before = local(&sim);
    let mut crossings = 0;
    for _ in 0..72 {
        match sim.step() {
            Ok(_) => {}
            // Without continuous collision the cloth may blow up; that counts as a failure
            // of the unprotected run, not of the test.
            Err(e) if !ccd => {
                eprintln!("{integrator:?} without CCD: {e}");
                return crossings.max(1);
            }
            Err(e) => panic!("{integrator:?}: {e}"),
        }
        let after = local(&sim);
        for (b, a) in before.iter().zip(&after) {
            let inside = a.abs().cmplt(half).all();
            let crossed = over(*b) && over(*a) && b.z > 0.0 && a.z < 0.0;
            if inside || crossed {
                crossings += 1;
            }
        }
        before = after;
    }
    crossings
}

/// A thin board swept at 15 m/s through a hanging curtain never leaves a particle behind it
/// or inside it (zero crossings, exact count) with continuous collision, for symplectic Euler
/// (strain-limited), implicit Euler and XPBD; without it, particles cross.
#[test]
fn a_thin_board_swept_through_a_curtain_does_not_pass_through_it() {
    for integrator in INTEGRATORS {
        let crossings = sweep_crossings(integrator, true);
        assert_eq!(
            crossings, 0,
            "{integrator:?}: {crossings} particles crossed"
        );
        let crossings_off = sweep_crossings(integrator, false);
        assert!(
            crossings_off > 0,
            "{integrator:?}: without continuous collision particles should cross"
        );
    }
}
