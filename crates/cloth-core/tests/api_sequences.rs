//! Sequences of API calls: random, seeded sequences of every public entry point of
//! `Simulation` (config switches mid-run, colliders added and removed between steps, pins and
//! teleports, checkpoints restored across configs and cloths, clones, steps after an unstable
//! step), checked after every call; and the regression tests of the defects such sequences
//! found.

use std::sync::Arc;

use cloth_core::glam::{Quat, Vec3};
use cloth_core::{
    ClothError, Collider, GridBuilder, Integrator, SelfCollision, SimConfig, SimState, Simulation,
    TriMesh, scene,
};

/// Uniform numbers from a xorshift64 generator: the same sequence on every run.
struct Rng(u64);

impl Rng {
    fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    /// In `0..n`.
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
    /// In [0, 1).
    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
    /// In [lo, hi).
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }
    fn chance(&mut self, p: f32) -> bool {
        self.unit() < p
    }
    fn vec(&mut self, scale: f32) -> Vec3 {
        Vec3::new(
            self.range(-scale, scale),
            self.range(-scale, scale),
            self.range(-scale, scale),
        )
    }
}

/// The simulations a sequence starts from: a 12 × 9 grid, or a built-in scene at 12 × 9.
fn start(kind: usize) -> Simulation {
    const SCENES: [&str; 8] = [
        "drape",
        "hanging",
        "flag",
        "table",
        "verlet-swing",
        "xpbd-curtain",
        "sweep",
        "mesh",
    ];
    match kind {
        0 => Simulation::new(
            GridBuilder::new(12, 9)
                .origin(Vec3::new(0.0, 0.6, 0.0))
                .build()
                .expect("a grid"),
            SimConfig::default(),
        )
        .expect("a simulation"),
        1 => {
            let cloth = GridBuilder::new(12, 9)
                .size(0.6, 0.8)
                .origin(Vec3::new(0.0, 0.6, 0.0))
                .pin_corners()
                .build()
                .expect("a grid");
            let config = SimConfig {
                integrator: Integrator::Xpbd,
                substeps: 8,
                ..SimConfig::default()
            };
            Simulation::new(cloth, config).expect("a simulation")
        }
        k => {
            let name = SCENES[(k - 2) % SCENES.len()];
            let (scene, _) = scene::load(name, &["cloth.resolution=[12, 9]".into()])
                .unwrap_or_else(|e| panic!("{name}: {e}"));
            scene.build().unwrap_or_else(|e| panic!("{name}: {e}"))
        }
    }
}

const STARTS: usize = 10;

/// A small closed box mesh.
fn box_mesh(center: Vec3, half: f32) -> Arc<TriMesh> {
    let (v, t) = cloth_core::collide::mesh::box_mesh(center, Vec3::splat(half));
    Arc::new(TriMesh::new(v, t).expect("a box mesh"))
}

fn random_collider(rng: &mut Rng) -> Collider {
    let mut c = match rng.below(6) {
        0 => Collider::sphere(rng.vec(0.5), rng.range(0.05, 0.5)),
        1 => Collider::plane(
            Vec3::new(0.0, rng.range(-0.5, 0.3), 0.0),
            Vec3::new(rng.range(-0.2, 0.2), 1.0, rng.range(-0.2, 0.2)),
        ),
        2 => Collider::capsule(rng.vec(0.5), rng.vec(0.5), rng.range(0.05, 0.3)),
        3 => Collider::cuboid(
            rng.vec(0.4),
            Vec3::new(
                rng.range(0.05, 0.4),
                rng.range(0.05, 0.4),
                rng.range(0.05, 0.4),
            ),
            Quat::from_rotation_y(rng.range(0.0, 3.0)),
        ),
        4 => Collider::mesh(
            box_mesh(Vec3::ZERO, rng.range(0.05, 0.3)),
            rng.vec(0.4),
            Quat::from_rotation_x(rng.range(0.0, 3.0)),
        ),
        // A bad collider: an error naming it.
        _ => Collider::sphere(rng.vec(0.5), -1.0),
    };
    if rng.chance(0.3) {
        c = c.with_velocity(rng.vec(1.0));
    }
    if rng.chance(0.2) {
        c = c.with_angular_velocity(rng.vec(2.0));
    }
    if rng.chance(0.2) {
        c = c.with_thickness(rng.range(0.0, 0.03));
    }
    c
}

/// A random change of the current config: another integrator, substeps, chains, self-collision,
/// strain limits… or, now and then, an invalid field.
fn random_config(rng: &mut Rng, current: &SimConfig) -> SimConfig {
    let mut c = *current;
    for _ in 0..1 + rng.below(3) {
        match rng.below(14) {
            0 | 1 => c.integrator = Integrator::ALL[rng.below(Integrator::ALL.len())],
            2 => c.substeps = [1, 2, 4, 8, 16, 32, 48][rng.below(7)],
            3 => c.xpbd.chains = !c.xpbd.chains,
            4 => {
                c.self_collision = if c.self_collision.is_some() {
                    None
                } else {
                    Some(SelfCollision {
                        thickness: rng.range(0.005, 0.08),
                        friction: 0.3,
                    })
                }
            }
            5 => c.strain_limit = [None, Some(0.1), Some(0.02)][rng.below(3)],
            6 => {
                c.xpbd.iterations = 1 + rng.below(3) as u32;
                c.xpbd.chain_rounds = 1 + rng.below(2) as u32;
                c.xpbd.chain_iterations = 1 + rng.below(2) as u32;
            }
            7 => {
                c.xpbd.tethers = !c.xpbd.tethers;
                c.xpbd.tether_slack = [0.02, 0.0, 0.5][rng.below(3)];
                c.xpbd.hierarchy_levels = rng.below(4) as u32;
                c.xpbd.hierarchy_slack = [0.02, 0.1][rng.below(2)];
            }
            8 => {
                c.xpbd.structural_limit = [None, Some(0.02), Some(0.0)][rng.below(3)];
                c.xpbd.shear_chains = !c.xpbd.shear_chains;
            }
            9 => c.continuous_collision = !c.continuous_collision,
            10 => {
                c.air.wind = rng.vec(5.0);
                c.forces.air = rng.chance(0.7);
            }
            11 => c.dt = [1.0 / 60.0, 1.0 / 120.0, 1.0 / 30.0][rng.below(3)],
            12 => c.limits.max_speed = [1000.0, 50.0, 5.0, 0.5][rng.below(4)],
            _ => match rng.below(5) {
                0 => c.substeps = 0,
                1 => c.dt = f32::NAN,
                2 => c.xpbd.chain_rounds = 0,
                3 => {
                    c.self_collision = Some(SelfCollision {
                        thickness: 50.0,
                        friction: 0.3,
                    });
                }
                _ => c.material.shear.stiffness = -1.0,
            },
        }
    }
    c
}

/// Everything observable of a simulation's state, bit for bit.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Snapshot {
    bits: Vec<u32>,
    time: u64,
    steps: u64,
    config: String,
    colliders: String,
}

fn snapshot(sim: &Simulation) -> Snapshot {
    let p = sim.particles();
    Snapshot {
        bits: p
            .position
            .iter()
            .chain(&p.velocity)
            .flat_map(|v| v.to_array())
            .chain(p.inv_mass.iter().copied())
            .map(f32::to_bits)
            .collect(),
        time: sim.time().to_bits(),
        steps: sim.steps(),
        config: format!("{:?}", sim.config()),
        colliders: format!("{:?}", sim.colliders()),
    }
}

/// The error is one the API documents, and its message names a field or a particle.
fn check_error(e: &ClothError, what: &str) {
    match e {
        ClothError::InvalidArgument { name, allowed, .. } => {
            assert!(
                !name.is_empty() && !allowed.is_empty(),
                "{what}: unnamed error {e:?}"
            );
        }
        ClothError::IndexOutOfRange { name, .. } => {
            assert!(!name.is_empty(), "{what}: unnamed error {e:?}");
        }
        ClothError::Unstable { reason, .. } => {
            assert!(
                (what.ends_with(": step")
                    || what.ends_with(": clone")
                    || what.ends_with(": checkpoint"))
                    && !reason.is_empty()
                    && e.to_string().contains("particle"),
                "{what}: {e}"
            );
        }
        other => panic!("{what}: unexpected error {other:?}"),
    }
}

fn assert_finite(sim: &Simulation, what: &str) {
    let p = sim.particles();
    assert!(
        p.position.iter().chain(&p.velocity).all(|v| v.is_finite()),
        "{what}: a non-finite particle state"
    );
    assert!(sim.time().is_finite(), "{what}: time {}", sim.time());
}

/// Runs sequence `seed`; returns its trace (one line per call: the call, its outcome and the
/// state's bits), checking the invariants after every call.
fn run_sequence(seed: u64, calls: usize) -> Vec<String> {
    let mut rng = Rng::new(seed);
    let kind = rng.below(STARTS);
    let mut sim = start(kind);
    // A simulation of another scene, for foreign checkpoints.
    let foreign = start(rng.below(STARTS)).state();
    let mut saved: Vec<SimState> = vec![sim.state()];
    let mut trace = Vec::with_capacity(calls);
    // Whether a pin target is set for the next step (a checkpoint does not hold them).
    let mut targets_pending = false;
    let mut out = Vec::new();
    for call in 0..calls {
        let n = sim.particles().len();
        let before = snapshot(&sim);
        // An index sometimes past the end.
        let index = if rng.chance(0.05) {
            n + rng.below(3)
        } else {
            rng.below(n)
        };
        let op = rng.below(25);
        let (what, result): (&str, Result<String, ClothError>) = match op {
            0..=6 => {
                let r = sim.step();
                if r.is_err() {
                    assert_eq!(
                        snapshot(&sim),
                        before,
                        "seed {seed} call {call}: a failed step changed the state"
                    );
                }
                ("step", r.map(|s| format!("{s:?}")))
            }
            7 | 8 => {
                let config = random_config(&mut rng, sim.config());
                ("set_config", sim.set_config(config).map(|()| String::new()))
            }
            9 => {
                let c = random_collider(&mut rng);
                ("add_collider", sim.add_collider(c).map(|i| i.to_string()))
            }
            10 => {
                let c = random_collider(&mut rng);
                let i = rng.below(sim.colliders().len() + 1);
                (
                    "set_collider",
                    sim.set_collider(i, c).map(|()| String::new()),
                )
            }
            11 => {
                if rng.chance(0.3) {
                    sim.clear_colliders();
                }
                out.clear();
                sim.contacts(&mut out);
                ("contacts", Ok(format!("{out:?}")))
            }
            12 => {
                let range = [None, Some(0.05), Some(0.0), Some(f32::NAN)][rng.below(4)];
                (
                    "self_contact",
                    sim.self_contact(range).map(|c| format!("{c:?}")),
                )
            }
            13 => {
                let r = sim.pin_reactions();
                let f = sim.forces().to_vec();
                assert!(
                    r.iter().all(|(_, f)| f.is_finite()) || f.iter().any(|f| !f.is_finite()),
                    "seed {seed} call {call}: non-finite pin reactions"
                );
                ("forces", Ok(format!("{r:?} {f:?} {:?}", sim.measure())))
            }
            14 => ("pin", sim.pin(index).map(|()| String::new())),
            15 => ("unpin", sim.unpin(index).map(|()| String::new())),
            16 => {
                let target = sim
                    .particles()
                    .position
                    .get(index)
                    .copied()
                    .unwrap_or_default()
                    + rng.vec(0.05);
                (
                    "set_pin_target",
                    sim.set_pin_target(index, target).map(|()| String::new()),
                )
            }
            17 => {
                let at = match rng.below(6) {
                    0 => rng.vec(0.3),
                    1 => rng.vec(3.0),
                    2 => Vec3::new(0.0, 1e4, 0.0),
                    3 => Vec3::new(1e30, -f32::MAX, 0.0),
                    4 => Vec3::splat(f32::MAX),
                    _ => sim
                        .colliders()
                        .first()
                        .map_or(Vec3::ZERO, |c| c.shape.pivot()),
                };
                (
                    "set_position",
                    sim.set_position(index, at).map(|()| String::new()),
                )
            }
            18 => {
                let v = if rng.chance(0.2) {
                    Vec3::new(2e3, 0.0, 0.0)
                } else {
                    rng.vec(3.0)
                };
                (
                    "set_velocity",
                    sim.set_velocity(index, v).map(|()| String::new()),
                )
            }
            19 => {
                saved.push(sim.state());
                ("state", Ok(String::new()))
            }
            20 | 21 => {
                let state = if rng.chance(0.2) {
                    &foreign
                } else {
                    &saved[rng.below(saved.len())]
                };
                ("restore", sim.restore(state).map(|()| String::new()))
            }
            22 => {
                // A clone diverges without touching the original, and steps like it.
                let mut copy = sim.clone();
                for _ in 0..rng.below(3) {
                    let _ = copy.step();
                    let _ = copy.set_velocity(0, Vec3::X);
                }
                assert_eq!(
                    snapshot(&sim),
                    before,
                    "seed {seed} call {call}: a clone's use changed the original"
                );
                let mut copy = sim.clone();
                let a = copy.step().map(|s| format!("{s:?}"));
                let b = sim.step().map(|s| format!("{s:?}"));
                assert_eq!(a, b, "seed {seed} call {call}: a clone stepped differently");
                assert_eq!(snapshot(&copy), snapshot(&sim), "seed {seed} call {call}");
                ("clone", b)
            }
            23 => {
                // A checkpoint continues to the same bits in a fresh simulation of the same
                // scene, config and colliders (also after a failed step), unless a pin target
                // is pending (a checkpoint does not hold it).
                if targets_pending {
                    ("checkpoint", Ok(String::new()))
                } else {
                    let mut fresh = start(kind);
                    fresh.clear_colliders();
                    for c in sim.colliders() {
                        fresh.add_collider(c.clone()).expect("a valid collider");
                    }
                    fresh.set_config(*sim.config()).expect("a valid config");
                    fresh.restore(&sim.state()).expect("the same scene's state");
                    let a = fresh.step().map(|s| format!("{:?}", s.kinetic_energy));
                    let b = sim.step().map(|s| format!("{:?}", s.kinetic_energy));
                    assert_eq!(a, b, "seed {seed} call {call}: checkpoint law");
                    assert_eq!(
                        snapshot(&fresh).bits,
                        snapshot(&sim).bits,
                        "seed {seed} call {call}: a checkpoint continued to other bits"
                    );
                    ("checkpoint", b)
                }
            }
            _ => {
                // A state saved before a config change restores after it.
                let s = sim.state();
                let config = random_config(&mut rng, sim.config());
                let _ = sim.set_config(config);
                let _ = sim.step();
                (
                    "state-config-restore",
                    sim.restore(&s).map(|()| String::new()),
                )
            }
        };
        match (what, &result) {
            ("set_pin_target", Ok(_)) => targets_pending = true,
            ("step" | "clone" | "checkpoint" | "restore" | "state-config-restore", Ok(_)) => {
                targets_pending = false;
            }
            _ => {}
        }
        let what = format!("seed {seed} call {call}: {what}");
        if let Err(e) = &result {
            check_error(e, &what);
            if (7..22).contains(&op) {
                assert_eq!(
                    snapshot(&sim),
                    before,
                    "{what}: a refused call changed the state ({e})"
                );
            }
        }
        assert_finite(&sim, &what);
        let after = snapshot(&sim);
        trace.push(format!(
            "{what} {:?} {:x}",
            result.map_err(|e| e.to_string()),
            hash(&after.bits) ^ after.time ^ after.steps
        ));
    }
    trace
}

/// FNV-1a of the bits.
fn hash(bits: &[u32]) -> u64 {
    bits.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3)
    })
}

const SEQUENCES: u64 = 300;
const CALLS: usize = 30;

/// Laws, after every call of 300 random sequences of 30 calls each (12 × 9 grids and built-in
/// scenes at 12 × 9): no panic; every error is `InvalidArgument`/`IndexOutOfRange` naming a
/// field, or (from `step` only) `Unstable` naming a particle; a refused call and a failed step
/// leave the state (positions, velocities, inverse masses, time, steps, config, colliders)
/// bit for bit as it was; positions and velocities stay finite; a clone's use leaves the
/// original untouched and a clone steps to the original's bits; and replaying each sequence
/// on a fresh simulation in a 3-thread pool gives the 1-thread run's trace bit for bit.
/// Also: a checkpoint (`state`) restored into a fresh simulation of the same scene, config
/// and colliders steps to the same bits (unless a pin target is pending). Tolerance: none
/// (bit-identical). `API_SEQUENCES=N API_SEQUENCES_FROM=S` runs N sequences from seed S.
#[test]
fn random_call_sequences_keep_the_invariants_and_replay_bit_for_bit() {
    let pool = |n| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .expect("a pool")
    };
    let (one, three) = (pool(1), pool(3));
    let sequences = std::env::var("API_SEQUENCES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(SEQUENCES);
    let first_seed = std::env::var("API_SEQUENCES_FROM")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
    for seed in first_seed..first_seed + sequences {
        let first = one.install(|| run_sequence(seed, CALLS));
        let again = three.install(|| run_sequence(seed, CALLS));
        for (a, b) in first.iter().zip(&again) {
            assert_eq!(a, b, "seed {seed}: the replay on 3 threads differs");
        }
    }
}

/// A hanging 12 × 9 cloth pinned at its top corners, on XPBD with tethers of `slack`.
fn tethered(slack: f32) -> Simulation {
    let cloth = GridBuilder::new(12, 9)
        .origin(Vec3::new(0.0, 0.6, 0.0))
        .orientation(cloth_core::Orientation::Vertical)
        .pin_corners()
        .build()
        .expect("a grid");
    let mut config = SimConfig {
        integrator: Integrator::Xpbd,
        substeps: 4,
        ..SimConfig::default()
    };
    config.xpbd.tethers = true;
    config.xpbd.tether_slack = slack;
    Simulation::new(cloth, config).expect("a simulation")
}

/// Law: a config takes effect at the next step whatever ran before it, so a simulation whose
/// `xpbd.tether_slack` was changed mid-run continues like a fresh one built with that slack
/// and restored to the same state (the checkpoint contract). The tethers were built once per
/// pinned set and kept the old slack's lengths. Tolerance: none (bit for bit, 20 steps).
#[test]
fn a_tether_slack_changed_mid_run_takes_effect_at_the_next_step() {
    let mut changed = tethered(0.5);
    changed.step().expect("a stable step");
    let mut config = *changed.config();
    config.xpbd.tether_slack = 0.0;
    changed.set_config(config).expect("a valid config");
    let mut fresh = tethered(0.0);
    fresh
        .restore(&changed.state())
        .expect("the same scene's state");
    for _ in 0..20 {
        changed.step().expect("a stable step");
        fresh.step().expect("a stable step");
    }
    assert_eq!(changed.particles().position, fresh.particles().position);
    assert_eq!(changed.particles().velocity, fresh.particles().velocity);
}

/// Law: `set_config` refuses, like `Simulation::new` and `restore`, a `limits.max_speed`
/// below the speed of a particle now (every later step would fail the instability check and
/// the simulation could not go on), naming `config.limits.max_speed` and the particle; the
/// config is unchanged and stepping goes on. A limit at least the fastest speed is accepted.
/// Tolerance: none.
#[test]
fn set_config_refuses_a_speed_limit_below_a_particles_speed() {
    let cloth = GridBuilder::new(12, 9)
        .origin(Vec3::new(0.0, 0.6, 0.0))
        .build()
        .expect("a grid");
    let mut sim = Simulation::new(cloth, SimConfig::default()).expect("a simulation");
    sim.set_velocity(7, Vec3::new(0.0, 0.0, 3.0))
        .expect("a valid velocity");
    let mut config = *sim.config();
    config.limits.max_speed = 0.5;
    match sim.set_config(config) {
        Err(ClothError::InvalidArgument { name, allowed, .. }) => {
            assert_eq!(name, "config.limits.max_speed");
            assert!(allowed.contains("particle 7"), "{allowed}");
        }
        other => panic!("expected InvalidArgument, got {other:?}"),
    }
    assert_eq!(sim.config().limits.max_speed, 1000.0);
    sim.step().expect("a stable step");
    config.limits.max_speed = 10.0;
    sim.set_config(config).expect("a limit above every speed");
    sim.step().expect("a stable step");
}

/// Law: a checkpoint whose plane normal or box rotation is off unit length (an edited or
/// hand-written `SimState`) is normalised when restored, as `add_collider` normalises it, so
/// the cloth meets the same plane: a cloth falling on a plane restored with normal (0, 4, 0)
/// steps to the bits of one restored with (0, 1, 0); the collider's normal has unit length
/// (tolerance 1e-6). A checkpoint's own unit shapes keep their bits.
#[test]
fn a_restored_plane_normal_is_normalised_like_add_collider() {
    let make = || {
        let cloth = GridBuilder::new(12, 9)
            .origin(Vec3::new(0.0, 0.05, 0.0))
            .build()
            .expect("a grid");
        let mut sim = Simulation::new(cloth, SimConfig::default()).expect("a simulation");
        sim.add_collider(Collider::plane(Vec3::ZERO, Vec3::Y))
            .expect("a plane");
        sim.add_collider(Collider::cuboid(
            Vec3::new(3.0, 0.0, 0.0),
            Vec3::splat(0.2),
            Quat::IDENTITY,
        ))
        .expect("a box");
        sim
    };
    let mut edited = make();
    let mut state = edited.state();
    let unit = state.clone();
    state.collider_shapes[0] = cloth_core::Shape::Plane {
        point: Vec3::ZERO,
        normal: Vec3::new(0.0, 4.0, 0.0),
    };
    state.collider_shapes[1] = cloth_core::Shape::Box {
        center: Vec3::new(3.0, 0.0, 0.0),
        half_extents: Vec3::splat(0.2),
        rotation: Quat::from_xyzw(0.0, 0.0, 0.0, 1.0005),
    };
    edited.restore(&state).expect("a valid state");
    let mut reference = make();
    reference.restore(&unit).expect("a valid state");
    assert_eq!(reference.colliders(), make().colliders());
    match &edited.colliders()[0].shape {
        cloth_core::Shape::Plane { normal, .. } => {
            assert!((normal.length() - 1.0).abs() <= 1e-6, "{normal}");
        }
        other => panic!("a plane, not {other:?}"),
    }
    assert_eq!(edited.colliders(), reference.colliders());
    for _ in 0..20 {
        edited.step().expect("a stable step");
        reference.step().expect("a stable step");
    }
    assert_eq!(edited.particles().position, reference.particles().position);
}

/// Law: `stats()` before the first step describes the state when the colliders last changed
/// (its documentation): replacing a collider by one the cloth lies inside shows the
/// penetration at once, as adding it does. Tolerance: the penetration is that of `measure()`
/// exactly.
#[test]
fn set_collider_refreshes_the_stats_like_add_collider() {
    let cloth = GridBuilder::new(12, 9)
        .origin(Vec3::new(0.0, 0.0, 0.0))
        .build()
        .expect("a grid");
    let mut sim = Simulation::new(cloth, SimConfig::default()).expect("a simulation");
    sim.add_collider(Collider::sphere(Vec3::new(0.0, 5.0, 0.0), 0.3))
        .expect("a sphere");
    assert_eq!(sim.stats().max_penetration, 0.0);
    sim.set_collider(0, Collider::sphere(Vec3::new(0.0, -0.1, 0.0), 0.3))
        .expect("a sphere");
    assert!(sim.stats().max_penetration > 0.1);
    assert_eq!(sim.stats().max_penetration, sim.measure().max_penetration);
}
