//! Cloth–cloth contact: a towel folded in half onto itself. With self-collision on, no two
//! particles that are not neighbours in the rest shape ever come closer than half the thickness
//! (the particle–particle form of the "no particle closer to a non-neighbour than half the
//! thickness" criterion); with it off, the layers pass through each other. Checked for a
//! force-based integrator and for XPBD.

use cloth_core::glam::Vec3;
use cloth_core::{
    Collider, Edge, Friction, GridBuilder, Integrator, Mass, Material, SelfCollision, SimConfig,
    Simulation, SpringParams,
};

const SPACING: f32 = 0.02;
const THICKNESS: f32 = 0.015;
const ROWS: usize = 10;
const COLS: usize = 30;

/// A towel lying on the ground, folded in half by carrying its right edge (pinned, animated
/// along a half circle) over onto its left half.
fn towel(integrator: Integrator, self_collision: bool) -> Simulation {
    let cloth = GridBuilder::new(ROWS, COLS)
        .spacing(SPACING, SPACING)
        .origin(Vec3::new(0.0, 0.005, 0.0))
        .mass(Mass::ArealDensity(0.2))
        .pin_edge(Edge::Right)
        .build()
        .expect("towel");
    let config = SimConfig {
        integrator,
        substeps: if integrator == Integrator::Xpbd {
            20
        } else {
            80
        },
        damping: 1e-3,
        material: Material::isotropic(
            SpringParams::new(200.0, 0.01),
            SpringParams::new(50.0, 0.005),
            SpringParams::new(0.05, 0.0),
        ),
        self_collision: self_collision.then_some(SelfCollision {
            thickness: THICKNESS,
            friction: 0.3,
        }),
        ..SimConfig::default()
    };
    let mut sim = Simulation::new(cloth, config).expect("sim");
    sim.add_collider(
        Collider::plane(Vec3::ZERO, Vec3::Y)
            .with_thickness(0.005)
            .with_friction(Friction::new(0.6, 0.5)),
    )
    .expect("ground");
    sim
}

/// Moves the pinned right edge along a half circle about the towel's middle over `steps`
/// steps, ending just above the left half (one thickness above the bottom layer).
fn fold_step(sim: &mut Simulation, rest: &[Vec3], step: usize, steps: usize) {
    let s = (step as f32 / steps as f32).min(1.0);
    let angle = std::f32::consts::PI * s;
    for r in 0..ROWS {
        let i = r * COLS + COLS - 1;
        let x0 = rest[i].x;
        let lift = 0.005 + 1.5 * THICKNESS * s;
        let target = Vec3::new(x0 * angle.cos(), lift + x0 * angle.sin(), rest[i].z);
        sim.set_pin_target(i, target).expect("pin target");
    }
}
/// Smallest distance between two particles whose rest distance is at least the thickness
/// (non-neighbours at this thickness), relative to the thickness.
fn closest_non_neighbours(sim: &Simulation, rest: &[Vec3]) -> f32 {
    let p = &sim.particles().position;
    let mut closest = f32::INFINITY;
    for i in 0..p.len() {
        for j in i + 1..p.len() {
            if rest[i].distance(rest[j]) >= THICKNESS {
                closest = closest.min(p[i].distance(p[j]) / THICKNESS);
            }
        }
    }
    closest
}

/// Folding a towel in half: with self-collision on, no two particles that are not
/// neighbours at rest come within half the thickness; with it off, the folded layer sinks into
/// the bottom one (both rest on the ground) and they do.
#[test]
fn a_folded_towel_keeps_its_thickness() {
    for integrator in [Integrator::SymplecticEuler, Integrator::Xpbd] {
        let mut on = towel(integrator, true);
        let mut off = towel(integrator, false);
        let rest = on.particles().position.clone();
        let (mut worst_on, mut worst_off) = (f32::INFINITY, f32::INFINITY);
        for step in 0..150 {
            fold_step(&mut on, &rest, step, 60);
            fold_step(&mut off, &rest, step, 60);
            on.step()
                .unwrap_or_else(|e| panic!("{integrator:?} step {step}: {e}"));
            off.step().expect("step");
            worst_on = worst_on.min(closest_non_neighbours(&on, &rest));
            worst_off = worst_off.min(closest_non_neighbours(&off, &rest));
        }
        let folded = on
            .particles()
            .position
            .iter()
            .filter(|p| p.y > 0.5 * THICKNESS + 0.005)
            .count();
        eprintln!(
            "{}: closest non-neighbours / thickness: on {worst_on:.3}, off {worst_off:.3}; {folded} particles on the top layer",
            integrator.name()
        );
        assert!(folded >= ROWS * COLS / 3, "the towel must have folded");
        assert!(
            worst_on >= 0.5,
            "{integrator:?}: layers came within {worst_on} thickness"
        );
        assert!(
            worst_off < 0.5,
            "{integrator:?}: without self-collision the layers should overlap"
        );
    }
}
