//! The explicit integrators' grid fast path against the reference path, and threads.
//!
//! Tolerance: none. The fast path evaluates every spring with the reference's operations in
//! the reference's order and sums each particle's forces in the reference's order (see the
//! `solver::grid_kernel` docs), and no kernel uses an approximation (no reciprocal square
//! root, no fused multiply-add), so positions, velocities and contact counts must be
//! **bit-identical** for every kernel this CPU runs, and for 1, 2 and 3 threads.

use cloth_core::glam::{Quat, Vec3};
use cloth_core::simd::{self, Kernel};
use cloth_core::{
    Collider, Friction, Gust, Integrator, SelfCollision, Simulation, SpringParams, presets,
};

/// Bits of every position and velocity, and the contact count of every step.
#[derive(Debug, PartialEq, Eq)]
struct Trace {
    position: Vec<[u32; 3]>,
    velocity: Vec<[u32; 3]>,
    contacts: Vec<u32>,
    ccd: Vec<u32>,
}

/// A rayon pool of `n` threads.
fn pool(n: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .expect("pool")
}

fn bits(v: &[Vec3]) -> Vec<[u32; 3]> {
    v.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
}

/// Steps `sim` `steps` times with `kernel` chosen on this thread, moving pin 0 (if pinned)
/// along a path.
fn run(mut sim: Simulation, kernel: Kernel, steps: usize) -> Trace {
    simd::set_kernel(Some(kernel)).expect("available kernel");
    let expected = if kernel == Kernel::Reference {
        Kernel::Reference
    } else {
        kernel
    };
    assert_eq!(simd::kernel_for(&sim), expected, "the fast path must apply");
    let mut contacts = Vec::new();
    let mut ccd = Vec::new();
    let pin0 = sim.particles().inv_mass[0] == 0.0;
    let start = sim.particles().position[0];
    for k in 0..steps {
        if pin0 {
            let t = k as f32 * 0.01;
            sim.set_pin_target(0, start + Vec3::new(0.05 * t, 0.02 * t, 0.0))
                .expect("pin target");
        }
        let stats = sim.step().expect("stable");
        contacts.push(stats.contacts);
        ccd.push(stats.ccd_corrections);
    }
    simd::set_kernel(None).expect("default");
    Trace {
        position: bits(&sim.particles().position),
        velocity: bits(&sim.particles().velocity),
        contacts,
        ccd,
    }
}

fn without_air(mut sim: Simulation) -> Simulation {
    let mut config = *sim.config();
    config.air.density = 0.0;
    sim.set_config(config).expect("config");
    sim
}

/// The scenes: the peer's cloth on a ball; the drape with friction on a ball and the ground,
/// plus a moving capsule, a turning box and a pinned, moving corner; a hanging curtain with
/// shear switched off and no gravity on one side; each with every explicit integrator.
fn scenes() -> Vec<(String, Simulation)> {
    let mut out = Vec::new();
    for integrator in Integrator::EXPLICIT {
        let mut peer = presets::peer_ball(20).expect("peer");
        let mut config = *peer.config();
        config.integrator = integrator;
        config.substeps = 100;
        peer.set_config(config).expect("config");
        // The ball raised into the cloth's path, with friction, so that it touches at once.
        peer.set_collider(
            0,
            Collider::sphere(Vec3::new(0.0, 0.29, 0.0), 0.3).with_friction(Friction::new(0.5, 0.4)),
        )
        .expect("ball");
        out.push((format!("peer-20/{}", integrator.name()), peer));

        let mut drape = without_air(presets::drape(13, integrator).expect("drape"));
        drape
            .add_collider(
                Collider::capsule(Vec3::new(-0.3, 0.5, 0.0), Vec3::new(0.3, 0.5, 0.2), 0.08)
                    .with_velocity(Vec3::new(0.0, 0.3, 0.0))
                    .with_friction(Friction::new(0.7, 0.5)),
            )
            .expect("capsule");
        drape
            .add_collider(
                Collider::cuboid(
                    Vec3::new(0.4, 0.52, -0.3),
                    Vec3::new(0.1, 0.05, 0.2),
                    Quat::from_rotation_y(0.3),
                )
                .with_angular_velocity(Vec3::new(0.0, 2.0, 0.0)),
            )
            .expect("box");
        drape.pin(0).expect("pin");
        out.push((format!("drape-13/{}", integrator.name()), drape));

        let mut hanging = without_air(presets::hanging(17, integrator).expect("hanging"));
        let mut config = *hanging.config();
        config.material.shear = SpringParams::new(0.0, 0.0);
        config.material.bend.damping = 0.0;
        config.gravity = Vec3::new(0.5, -9.81, -0.0);
        config.damping = 0.3;
        hanging.set_config(config).expect("config");
        hanging
            .add_collider(Collider::sphere(Vec3::new(0.1, 1.0, 0.15), 0.2))
            .expect("sphere");
        out.push((format!("hanging-17/{}", integrator.name()), hanging));

        // Thrown at 150 m/s through small moving balls (paths of 2.5 mm or more per substep, longer
        // than a ball is wide, so continuous collision corrects particles) and onto a tilted
        // rising ground: the arrays' contact pass and candidate mask for spheres and planes,
        // with friction and thickness, against the reference.
        let mut thrown = presets::peer_ball(16).expect("peer");
        let mut config = *thrown.config();
        config.integrator = integrator;
        config.substeps = 16;
        config.dt = 0.004;
        thrown.set_config(config).expect("config");
        thrown
            .set_collider(
                0,
                Collider::plane(Vec3::new(0.0, 0.45, 0.0), Vec3::new(0.1, 1.0, 0.0))
                    .with_velocity(Vec3::new(0.0, 0.2, 0.0))
                    .with_thickness(0.002)
                    .with_friction(Friction::new(0.6, 0.5)),
            )
            .expect("ground");
        for k in 0..6 {
            // Just off a particle's line of fall.
            let p = thrown.particles().position[16 * (3 + 2 * k) + 2 + 2 * k];
            let at = Vec3::new(p.x + 0.0002, 0.52 - 0.0007 * k as f32, p.z - 0.0001);
            thrown
                .add_collider(
                    Collider::sphere(at, 0.001)
                        .with_velocity(Vec3::new(0.0, 0.5, 0.0))
                        .with_thickness(0.0002)
                        .with_friction(Friction::new(0.4, 0.3)),
                )
                .expect("ball");
        }
        for i in 0..thrown.particles().len() {
            let v = Vec3::new(0.0, -150.0, 1e-3 * (i % 7) as f32);
            thrown.set_velocity(i, v).expect("velocity");
        }
        out.push((format!("thrown-16/{}", integrator.name()), thrown));

        // The drape with its air (drag and lift per triangle) in a gusty side wind, pinned at
        // two corners so that the cloth flaps: the air's terms on the fast path against the
        // reference's per-triangle loop.
        let mut windy = presets::drape(11, integrator).expect("drape");
        let mut config = *windy.config();
        config.air.wind = Vec3::new(3.0, 0.5, -1.0);
        config.air.gust = Some(Gust::default());
        config.air.lift_coefficient = 0.4;
        windy.set_config(config).expect("config");
        windy.pin(0).expect("pin");
        windy.pin(10).expect("pin");
        out.push((format!("windy-11/{}", integrator.name()), windy));
    }
    // Forward Euler gains energy every substep: small substeps keep it stable for the test.
    for (_, sim) in &mut out {
        let mut config = *sim.config();
        if config.integrator == Integrator::ForwardEuler {
            config.substeps *= 10;
            sim.set_config(config).expect("config");
        }
    }
    out
}

#[test]
fn every_kernel_gives_the_reference_bits() {
    let kernels: Vec<Kernel> = Kernel::ALL
        .into_iter()
        .filter(|k| *k != Kernel::Reference && k.is_available())
        .collect();
    assert!(kernels.contains(&Kernel::Portable));
    for (name, sim) in scenes() {
        let reference = run(sim.clone(), Kernel::Reference, 12);
        assert!(
            reference.contacts.iter().any(|&c| c > 0)
                || name.starts_with("hanging")
                || name.starts_with("windy"),
            "{name}: the scene should touch a collider"
        );
        assert!(
            reference.ccd.iter().any(|&c| c > 0) || !name.starts_with("thrown"),
            "{name}: continuous collision should correct particles: {:?}",
            reference.ccd
        );
        for &k in &kernels {
            let fast = run(sim.clone(), k, 12);
            assert!(
                fast == reference,
                "{name}: kernel {} differs from the reference path",
                k.name()
            );
        }
    }
}

#[test]
fn post_passes_after_the_fast_path_match_the_reference() {
    // Strain limiting and self-collision run on the whole cloth after the fast path, and
    // continuous collision after them.
    for integrator in Integrator::EXPLICIT {
        let mut sim = without_air(presets::drape(12, integrator).expect("drape"));
        let mut config = *sim.config();
        config.strain_limit = Some(0.05);
        config.self_collision = Some(SelfCollision::default());
        sim.set_config(config).expect("config");
        let reference = run(sim.clone(), Kernel::Reference, 10);
        let fast = run(sim, Kernel::best(), 10);
        assert!(fast == reference, "{}", integrator.name());
    }
}

/// A cloth large enough (364², 132,496 particles, past the fast path's 2¹⁷) that its state is
/// updated in place from a step's second substep on, each band writing its rows over the
/// ones it has read and keeping the rows its neighbours read until the bands join: against
/// the reference for every kernel, and across 1, 2 and 3 threads (bands whose boundaries cut
/// through the contacts with the ball). Tolerance: none.
#[test]
fn a_cloth_updated_in_place_gives_the_reference_bits() {
    for integrator in [Integrator::SymplecticEuler, Integrator::Verlet] {
        let mut sim = presets::peer_ball(364).expect("peer");
        let mut config = *sim.config();
        config.integrator = integrator;
        // Five of the preset's substeps per step.
        config.dt *= 5.0 / config.substeps as f32;
        config.substeps = 5;
        sim.set_config(config).expect("config");
        // The ball's top 5 mm above the cloth, with friction: contacts in the middle rows at once.
        sim.set_collider(
            0,
            Collider::sphere(Vec3::new(0.0, 0.305, 0.0), 0.3)
                .with_friction(Friction::new(0.5, 0.4)),
        )
        .expect("ball");
        let reference = run(sim.clone(), Kernel::Reference, 2);
        assert!(
            reference.contacts.iter().all(|&c| c > 1000),
            "contacts {:?}",
            reference.contacts
        );
        for kernel in Kernel::ALL
            .into_iter()
            .filter(|k| *k != Kernel::Reference && k.is_available())
        {
            for threads in [1, 2, 3] {
                let sim = sim.clone();
                let fast = pool(threads).install(|| run(sim, kernel, 2));
                assert!(
                    fast == reference,
                    "{}: {kernel:?} on {threads} threads differs",
                    integrator.name()
                );
            }
        }
    }
}

#[test]
fn one_two_and_three_threads_give_the_same_bits() {
    for (name, sim) in scenes() {
        let traces: Vec<Trace> = [1, 2, 3]
            .into_iter()
            .map(|n| {
                let sim = sim.clone();
                pool(n).install(|| run(sim, Kernel::best(), 8))
            })
            .collect();
        assert!(traces[0] == traces[1], "{name}: 1 and 2 threads differ");
        assert!(traces[0] == traces[2], "{name}: 1 and 3 threads differ");
    }
    // A taller grid, so that 2 and 3 threads really cut it into bands.
    let sim = presets::peer_ball(48).expect("peer");
    let traces: Vec<Trace> = [1, 2, 3]
        .into_iter()
        .map(|n| {
            let sim = sim.clone();
            pool(n).install(|| run(sim, Kernel::best(), 3))
        })
        .collect();
    assert!(traces[0] == traces[1] && traces[0] == traces[2]);
}

/// A spring that reaches zero length in the middle of a step, on a cloth large enough to be
/// updated in place (364²): the reference skips it; the fast path has already written part
/// of the substep's state over the old one when it meets the spring, so the step is redone
/// from its start without the in-place update. Two neighbours pinned, one still and one
/// driven onto it in exactly one substep (dyadic dt and substep, a difference that is exact).
/// Tolerance: none.
#[test]
fn a_spring_reaching_zero_length_in_place_gives_the_reference_bits() {
    let n = 364;
    let mut sim = presets::peer_ball(n).expect("peer");
    let mut config = *sim.config();
    config.substeps = 4;
    config.dt = 1.0 / 4096.0;
    sim.set_config(config).expect("config");
    let h = config.dt / config.substeps as f32;
    let (a, b) = (200 * n + 5, 200 * n + 6);
    // b moved to 1 µm from a first (its other springs stretched by a spacing), so that it
    // needs only a slow drive onto a.
    let xa = sim.particles().position[a];
    let xb = xa + Vec3::new(1.0 / 1_048_576.0, 0.0, 0.0);
    sim.set_position(b, xb).expect("position");
    let tb = xb + 4.0 * (xa - xb);
    // The precondition, as the step computes it: b's pinned velocity, one substep, on a.
    let vb = (tb - xb) / config.dt;
    assert_eq!(
        bits(&[xb + vb * h]),
        bits(&[xa]),
        "b lands on a after one substep"
    );
    for threads in [1, 2] {
        let mut sim = sim.clone();
        sim.pin(a).expect("pin");
        sim.pin(b).expect("pin");
        sim.set_pin_target(b, tb).expect("target");
        let pool = pool(threads);
        let reference = pool.install(|| run(sim.clone(), Kernel::Reference, 2));
        let fast = pool.install(|| run(sim, Kernel::best(), 2));
        assert!(fast == reference, "{threads} threads");
    }
}

/// The arrays' contact pass leaves a chunk of 32 particles alone when every one has φ =
/// |x − c| − r − t ≥ 0. A 64-column cloth (whole chunks) laid onto a sphere's contact
/// surface, each particle at (r + t)·(1 + δ) along its direction from the centre, rows
/// alternating between δ all just outside (0 < δ < 0.001: no contact) and δ mixing contacts
/// 1–4 µm deep with particles outside; a substep of 10⁻⁷ s, so that the springs, far from
/// rest, move nothing by more than a rounding. Every explicit integrator on every kernel
/// gives the reference's bits and contact count (tolerance: none), and the count is the
/// number of particles placed inside (δ < 0). (A chunk test with a margin of −0.1 % instead
/// of the exact one fails it.)
#[test]
fn contacts_just_inside_a_sphere_in_whole_chunks_give_the_reference_bits() {
    let n = 64;
    for integrator in Integrator::EXPLICIT {
        let mut sim = presets::peer_ball(n).expect("peer");
        let mut config = *sim.config();
        config.integrator = integrator;
        config.substeps = 1;
        config.dt = 1e-7;
        config.gravity = Vec3::ZERO;
        sim.set_config(config).expect("config");
        let (c, r, t) = (Vec3::new(0.0, 0.1, 0.0), 0.3, 0.004);
        sim.set_collider(0, Collider::sphere(c, r).with_thickness(t))
            .expect("ball");
        let margin = [1e-7, 4e-4, 9.9e-4];
        let mixed = [-4e-6, 2e-3, -1e-6, 5e-3];
        let mut inside = 0;
        for i in 0..n * n {
            let (row, col) = (i / n, i % n);
            let d = if row % 2 == 0 {
                margin[col % margin.len()]
            } else {
                mixed[col % mixed.len()]
            };
            inside += u32::from(d < 0.0);
            let dir = (sim.particles().position[i] - c).normalize();
            sim.set_position(i, c + dir * ((r + t) * (1.0 + d)))
                .expect("position");
        }
        let reference = run(sim.clone(), Kernel::Reference, 1);
        assert_eq!(reference.contacts, [inside], "{}", integrator.name());
        for kernel in Kernel::ALL
            .into_iter()
            .filter(|k| *k != Kernel::Reference && k.is_available())
        {
            let fast = run(sim.clone(), kernel, 1);
            assert!(fast == reference, "{}: {kernel:?}", integrator.name());
        }
    }
}

#[test]
fn a_degenerate_spring_falls_back_to_the_reference() {
    // Two neighbours at the same point: the reference skips that spring; the fast path
    // hands the substep back to it.
    let mut sim = presets::peer_ball(10).expect("peer");
    let mut config = *sim.config();
    config.substeps = 400;
    sim.set_config(config).expect("config");
    let p = sim.particles().position[1];
    sim.set_position(0, p).expect("position");
    let reference = run(sim.clone(), Kernel::Reference, 1);
    let fast = run(sim, Kernel::best(), 1);
    assert!(fast == reference);
}

#[test]
fn air_runs_on_the_fast_path() {
    // Air drag and lift (per triangle) run on the fast path too; `every_kernel_gives_the_
    // reference_bits` compares its bits with the reference path's (the `windy` scenes).
    let sim = presets::drape(8, Integrator::SymplecticEuler).expect("drape");
    assert!(sim.config().air.density > 0.0, "the drape has air");
    simd::set_kernel(None).expect("default");
    assert_eq!(simd::kernel_for(&sim), simd::kernel());
}

/// The step's diagnostics are computed over fixed chunks in parallel and combined in chunk
/// order: on a cloth of several chunks (100² = 10,000 particles: 3 chunks of particles and of
/// each spring kind) the energies, strains and penetration are the same bits at 1, 2 and 3
/// threads (tolerance: none), and the kinetic energy is Σ ½m|v|² (in f64 from the
/// components) summed one particle at a time to within 10⁻¹² relative (the order of the
/// additions is all that differs).
#[test]
fn diagnostics_are_bit_identical_across_threads() {
    let sim = presets::drape(100, Integrator::Xpbd).expect("drape");
    let measure = |threads: usize| {
        let pool = pool(threads);
        let mut sim = sim.clone();
        pool.install(|| {
            (0..20)
                .map(|_| {
                    let s = sim.step().expect("stable");
                    let direct: f64 = sim
                        .particles()
                        .velocity
                        .iter()
                        .zip(&sim.particles().mass)
                        .map(|(v, &m)| 0.5 * f64::from(m) * v.as_dvec3().length_squared())
                        .sum();
                    assert!(
                        (s.kinetic_energy - direct).abs() <= 1e-12 * direct,
                        "kinetic energy {} vs {direct}",
                        s.kinetic_energy
                    );
                    let floats = [
                        s.max_penetration,
                        s.max_strain[0],
                        s.max_strain[1],
                        s.max_strain[2],
                    ];
                    (
                        [s.kinetic_energy, s.gravitational_energy, s.spring_energy]
                            .map(f64::to_bits),
                        floats.map(f32::to_bits),
                    )
                })
                .collect::<Vec<_>>()
        })
    };
    let one = measure(1);
    assert!(one.iter().any(|(e, _)| e[0] != 0), "the cloth moves");
    assert_eq!(measure(2), one, "2 threads");
    assert_eq!(measure(3), one, "3 threads");
}
