//! Capsule and box colliders: exact signed distances, cloth resting on them without
//! penetration, and kinematic turning (a spinning platform carries what sticks to it).

use cloth_core::glam::{Quat, Vec3};
use cloth_core::{Collider, Friction, GridBuilder, Integrator, Mass, Shape, SimConfig, Simulation};

/// Signed distance to a capsule is the distance to its axis segment minus the radius, and to
/// a box the Euclidean distance to its surface (negative inside: minus the distance to the
/// nearest face). Exact cases, tolerance 1e-6 m.
#[test]
fn signed_distances_are_exact() {
    let capsule = Shape::Capsule {
        a: Vec3::new(-1.0, 0.0, 0.0),
        b: Vec3::new(1.0, 0.0, 0.0),
        radius: 0.5,
    };
    for (p, d, n) in [
        (Vec3::new(0.0, 2.0, 0.0), 1.5, Vec3::Y),
        (Vec3::new(3.0, 0.0, 0.0), 1.5, Vec3::X),
        (Vec3::new(0.3, 0.0, -0.2), -0.3, -Vec3::Z),
    ] {
        let (dist, normal) = capsule.distance(p);
        assert!((dist - d).abs() < 1e-6, "{p}: {dist} vs {d}");
        assert!(normal.distance(n) < 1e-6, "{p}: {normal} vs {n}");
    }
    let turn = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
    let cuboid = Shape::Box {
        center: Vec3::new(0.0, 1.0, 0.0),
        half_extents: Vec3::new(2.0, 0.5, 0.25),
        rotation: turn,
    };
    // After the quarter turn about Y, the box's long X axis lies along world Z.
    for (p, d, n) in [
        (Vec3::new(0.0, 3.0, 0.0), 1.5, Vec3::Y),
        (Vec3::new(0.0, 1.0, 3.0), 1.0, Vec3::Z),
        (Vec3::new(1.25, 1.0, 0.0), 1.0, Vec3::X),
        (
            Vec3::new(1.25, 2.5, 0.0),
            (1.0f32 + 1.0).sqrt(),
            Vec3::new(1.0, 1.0, 0.0).normalize(),
        ),
        (Vec3::new(0.0, 1.4, 0.0), -0.1, Vec3::Y),
    ] {
        let (dist, normal) = cuboid.distance(p);
        assert!((dist - d).abs() < 1e-5, "{p}: {dist} vs {d}");
        assert!(normal.distance(n) < 1e-5, "{p}: {normal} vs {n}");
    }
}

fn cloth_over(collider: Collider, integrator: Integrator) -> Simulation {
    let cloth = GridBuilder::new(16, 16)
        .size(0.8, 0.8)
        .origin(Vec3::new(0.0, 0.45, 0.0))
        .mass(Mass::ArealDensity(0.2))
        .build()
        .expect("cloth");
    let config = SimConfig {
        integrator,
        substeps: if integrator == Integrator::Xpbd {
            20
        } else {
            40
        },
        ..SimConfig::default()
    };
    let mut sim = Simulation::new(cloth, config).expect("sim");
    sim.add_collider(collider).expect("collider");
    sim
}

/// A cloth dropped on a box and on a capsule drapes over it and never ends a step deeper than
/// 1e-5 m inside the contact surface (so never inside the solid); with friction it stays on.
#[test]
fn cloth_drapes_over_box_and_capsule_without_penetration() {
    let shapes = [
        Collider::cuboid(
            Vec3::ZERO,
            Vec3::new(0.2, 0.2, 0.2),
            Quat::from_rotation_y(0.4),
        ),
        Collider::capsule(Vec3::new(-0.3, 0.1, 0.0), Vec3::new(0.3, 0.1, 0.0), 0.1),
    ];
    for collider in shapes {
        let collider = collider
            .with_thickness(0.01)
            .with_friction(Friction::new(0.8, 0.6));
        for integrator in [
            Integrator::SymplecticEuler,
            Integrator::ImplicitEuler,
            Integrator::Xpbd,
        ] {
            let mut sim = cloth_over(collider.clone(), integrator);
            let mut worst = 0.0f32;
            for _ in 0..90 {
                let s = sim.step().unwrap_or_else(|e| panic!("{integrator:?}: {e}"));
                worst = worst.max(s.max_penetration);
            }
            let com = sim.particles().center_of_mass();
            assert!(
                worst <= 1e-5,
                "{:?} {integrator:?}: penetration {worst}",
                collider.shape
            );
            assert!(
                com.y > 0.0,
                "{:?} {integrator:?}: slid off (com {com})",
                collider.shape
            );
        }
    }
}

/// A kinematic collider turning with angular velocity ω carries a sticking contact along: a
/// small cloth lying on a wide box spinning about the vertical axis at 1 rad/s with high
/// friction moves with the surface, v = ω × r, and stays on its circle of radius 0.5 m, after
/// 1 s. For symplectic Euler (40 substeps per 1/60 s), implicit Euler (4: its sticking
/// contacts are fixed at the collider's velocity at the particle inside the solve) and XPBD
/// (10). Tolerance 2·ω·h, relative, for both (the sticking particle follows the surface's
/// velocity ω × r taken at its position once per substep, a first-order discretisation of the
/// rotation: an error of order ωh; measured 10⁻⁷ for symplectic Euler, 0.42 % for implicit
/// Euler, whose ωh is 0.42 %, and 10⁻⁴ for XPBD), so a collider velocity off by 1 % fails for
/// every integrator with ωh ≤ 0.5 %.
#[test]
fn a_spinning_platform_carries_the_cloth() {
    for (integrator, substeps) in [
        (Integrator::SymplecticEuler, 40),
        (Integrator::ImplicitEuler, 4),
        (Integrator::Xpbd, 10),
    ] {
        let platform = Collider::cuboid(Vec3::ZERO, Vec3::new(1.0, 0.1, 1.0), Quat::IDENTITY)
            .with_thickness(0.005)
            .with_friction(Friction::new(2.0, 1.5))
            .with_angular_velocity(Vec3::new(0.0, 1.0, 0.0));
        let cloth = GridBuilder::new(3, 3)
            .size(0.05, 0.05)
            .origin(Vec3::new(0.5, 0.105, 0.0))
            .mass(Mass::ArealDensity(0.2))
            .build()
            .expect("cloth");
        // No global damping: −d·v acts in the world frame and would drag the cloth against the
        // platform (with these 3e-5 kg particles, d/m would be 64 /s).
        let config = SimConfig {
            integrator,
            substeps,
            damping: 0.0,
            air: cloth_core::Air {
                density: 0.0,
                ..cloth_core::Air::default()
            },
            ..SimConfig::default()
        };
        let mut sim = Simulation::new(cloth, config).expect("sim");
        sim.add_collider(platform).expect("platform");
        for _ in 0..60 {
            sim.step().expect("step");
        }
        let com = sim.particles().center_of_mass();
        let v = sim.particles().momentum() / sim.particles().total_mass();
        let expected = Vec3::Y.cross(Vec3::new(com.x, 0.0, com.z));
        let radius = Vec3::new(com.x, 0.0, com.z).length();
        eprintln!("{integrator:?}: r = {radius}, v = {v}, ω × r = {expected}");
        let tolerance = 2.0 * sim.config().substep_dt();
        assert!(
            (radius - 0.5).abs() < tolerance * 0.5,
            "{integrator:?}: the cloth left its circle: r = {radius}"
        );
        assert!(
            (v - expected).length() < tolerance * expected.length(),
            "{integrator:?}: velocity {v} vs ω × r = {expected}"
        );
    }
}

/// A triangle-mesh collider is a real kinematic collider: a closed box mesh moving up at
/// 0.5 m/s and turning at 1 rad/s carries a cloth exactly like the analytic box with the
/// same motion (same signed distance, so the same contacts): positions agree within 1e-4 m
/// after 1 s, and the cloth rose with the box.
#[test]
fn a_moving_mesh_box_matches_the_analytic_box() {
    use cloth_core::collide::mesh::box_mesh;
    use std::sync::Arc;
    let half = Vec3::new(0.4, 0.05, 0.4);
    let (v, t) = box_mesh(Vec3::ZERO, half);
    let mesh = Arc::new(cloth_core::TriMesh::new(v, t).expect("mesh"));
    let run = |collider: Collider| {
        let cloth = GridBuilder::new(12, 12)
            .size(0.5, 0.5)
            .origin(Vec3::new(0.0, 0.1, 0.0))
            .mass(Mass::ArealDensity(0.2))
            .build()
            .expect("cloth");
        let config = SimConfig {
            substeps: 40,
            ..SimConfig::default()
        };
        let mut sim = Simulation::new(cloth, config).expect("sim");
        sim.add_collider(
            collider
                .with_thickness(0.005)
                .with_friction(Friction::new(1.0, 0.8))
                .with_velocity(Vec3::new(0.0, 0.5, 0.0))
                .with_angular_velocity(Vec3::new(0.0, 1.0, 0.0)),
        )
        .expect("collider");
        for _ in 0..60 {
            sim.step().expect("step");
        }
        sim.particles().position.clone()
    };
    let analytic = run(Collider::cuboid(Vec3::ZERO, half, Quat::IDENTITY));
    let meshed = run(Collider::mesh(mesh, Vec3::ZERO, Quat::IDENTITY));
    let worst = analytic
        .iter()
        .zip(&meshed)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0f32, f32::max);
    assert!(worst < 1e-4, "mesh and analytic box differ by {worst} m");
    let mean_y = meshed.iter().map(|p| p.y).sum::<f32>() / meshed.len() as f32;
    assert!(
        mean_y > 0.5,
        "the cloth rode up with the box: mean y {mean_y}"
    );
}
