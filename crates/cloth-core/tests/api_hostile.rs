//! Hostile input through the library's API: bad arguments are errors naming the field and
//! the allowed range (never a panic), and no step reports `Ok` with a non-finite or frozen
//! result. Each case was found by an audit that called every public entry point with NaN,
//! infinities, huge and tiny values and inconsistent parts.

use cloth_core::glam::Vec3;
use cloth_core::scene::Scene;
use cloth_core::topology::Spring;
use cloth_core::{
    Cloth, ClothError, Collider, GridBuilder, Integrator, Mass, Shape, SimConfig, Simulation,
    Topology, TriMesh,
};

/// An edit of a cloth's public fields.
type Edit = Box<dyn Fn(&mut Cloth)>;

fn grid(n: usize) -> Cloth {
    GridBuilder::new(n, n).build().expect("a valid grid")
}

/// The name and the allowed range of an `InvalidArgument`, else a panic naming the result.
fn invalid<T: std::fmt::Debug>(r: cloth_core::Result<T>) -> (String, String) {
    match r {
        Err(ClothError::InvalidArgument { name, allowed, .. }) => (name, allowed),
        other => panic!("expected InvalidArgument, got {other:?}"),
    }
}

/// A capsule's nearest surface direction from a point on its axis is any direction across
/// the axis: the normal must be a unit vector perpendicular to it (it was the unnormalised
/// `any_orthonormal_vector` of the axis, (0, −3, −2) for an axis of length 2), and a cloth
/// centred on a vertical capsule's axis must not turn unstable or be pushed along it.
/// Tolerance 1e-6.
#[test]
fn a_point_on_a_capsules_axis_gets_a_unit_normal_across_the_axis() {
    // (Axes along which the midpoint is exactly on the axis in f32, and a point capsule.)
    for (a, b) in [
        (Vec3::ZERO, Vec3::new(0.0, 2.0, 0.0)),
        (Vec3::new(-1.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0)),
        (Vec3::new(0.5, 1.0, -2.0), Vec3::new(0.5, 1.0, 6.0)),
        (Vec3::ONE, Vec3::ONE),
    ] {
        let capsule = Shape::Capsule { a, b, radius: 0.2 };
        let (d, n) = capsule.distance(0.5 * (a + b));
        assert!((d + 0.2).abs() < 1e-6, "{a}–{b}: distance {d}");
        assert!(
            (n.length() - 1.0).abs() < 1e-6,
            "{a}–{b}: |n| = {}",
            n.length()
        );
        if a != b {
            let axis = (b - a).normalize();
            assert!(
                n.dot(axis).abs() < 1e-6,
                "{a}–{b}: n·axis = {}",
                n.dot(axis)
            );
        }
    }
    for integrator in [Integrator::SymplecticEuler, Integrator::Xpbd] {
        let cloth = GridBuilder::new(5, 5)
            .origin(Vec3::new(0.0, 1.0, 0.0))
            .build()
            .expect("grid");
        let config = SimConfig {
            integrator,
            ..SimConfig::default()
        };
        let mut sim = Simulation::new(cloth, config).expect("sim");
        sim.add_collider(Collider::capsule(Vec3::ZERO, Vec3::new(0.0, 2.0, 0.0), 0.2))
            .expect("capsule");
        for _ in 0..10 {
            sim.step()
                .expect("a cloth pierced by a capsule stays stable");
        }
        // The centre particle sits on the axis: pushed out across it, not along it.
        let centre = sim.particles().position[12];
        assert!(centre.is_finite() && Vec3::new(centre.x, 0.0, centre.z).length() > 0.19);
    }
}

/// `Simulation::new` checks a cloth whose public fields were edited: each inconsistency is
/// an error naming the field, and nothing panics later in a step.
#[test]
fn a_cloth_whose_parts_do_not_fit_is_refused_by_name() {
    let cases: Vec<(&str, Edit)> = vec![
        (
            "cloth.particles.velocity",
            Box::new(|c| {
                c.particles.velocity.pop();
            }),
        ),
        (
            "cloth.rows × cloth.cols",
            Box::new(|c| c.particles = grid(3).particles),
        ),
        (
            "cloth.particles.position[4]",
            Box::new(|c| c.particles.position[4] = Vec3::NAN),
        ),
        (
            "cloth.particles.mass[0]",
            Box::new(|c| {
                c.particles.mass[0] = 1e-39;
                c.particles.inv_mass[0] = 1.0 / 1e-39;
            }),
        ),
        (
            "cloth.particles.inv_mass[2]",
            Box::new(|c| c.particles.inv_mass[2] = 7.0),
        ),
        (
            "cloth.topology.springs[0]",
            Box::new(|c| {
                c.topology = Topology::new(
                    [
                        vec![Spring {
                            a: 0,
                            b: 999,
                            rest_length: 0.1,
                        }],
                        vec![],
                        vec![],
                        vec![],
                    ],
                    vec![],
                );
            }),
        ),
        (
            "cloth.topology.springs[0].rest_length",
            Box::new(|c| {
                c.topology = Topology::new(
                    [
                        vec![Spring {
                            a: 0,
                            b: 1,
                            rest_length: 0.0,
                        }],
                        vec![],
                        vec![],
                        vec![],
                    ],
                    vec![],
                );
            }),
        ),
        (
            "cloth.topology.triangles[0]",
            Box::new(|c| c.topology = Topology::new(Default::default(), vec![[0, 1, 25]])),
        ),
    ];
    for (field, edit) in cases {
        let mut cloth = grid(5);
        edit(&mut cloth);
        let (name, allowed) = invalid(Simulation::new(cloth, SimConfig::default()));
        assert_eq!(name, field, "allowed: {allowed}");
    }
    // The same grid untouched is fine, and so is a hand-made topology that fits.
    let mut cloth = grid(5);
    cloth.topology = Topology::new(
        [
            vec![Spring {
                a: 0,
                b: 1,
                rest_length: 0.25,
            }],
            vec![],
            vec![],
            vec![],
        ],
        vec![[0, 1, 5]],
    );
    let mut sim = Simulation::new(cloth, SimConfig::default()).expect("a fitting cloth");
    sim.step().expect("steps");
}

/// A mass whose inverse overflows f32 is refused where the cloth is built (it made every
/// later step unstable, with an infinite inverse mass).
#[test]
fn a_mass_without_a_finite_inverse_is_refused() {
    for mass in [Mass::PerParticle(1e-39), Mass::ArealDensity(1e-40)] {
        let (name, allowed) = invalid(GridBuilder::new(3, 3).mass(mass).build());
        assert_eq!(name, "grid.mass");
        assert!(allowed.contains("finite inverse"), "{allowed}");
    }
    GridBuilder::new(3, 3)
        .mass(Mass::PerParticle(1e-30))
        .build()
        .expect("a tiny mass with a finite inverse is fine");
}

/// A state restored with the largest step count steps on (the count saturates) instead of
/// overflowing.
#[test]
fn the_step_count_saturates_instead_of_overflowing() {
    let mut sim = Simulation::new(grid(3), SimConfig::default()).expect("sim");
    let mut state = sim.state();
    state.steps = u64::MAX;
    sim.restore(&state).expect("restore");
    sim.step().expect("step");
    assert_eq!(sim.steps(), u64::MAX);
}

/// A scene edited in code, with a resolution `from_toml` would refuse, still gets counts and
/// a memory estimate (saturating) instead of a panic.
#[test]
fn counts_of_any_resolution_saturate() {
    let mut scene = cloth_core::scene::builtin("drape").expect("drape");
    for (resolution, particles) in [([0, 0], 0), ([1, 7], 7), ([u32::MAX, u32::MAX], u64::MAX)] {
        scene.cloth.resolution = resolution;
        let (p, _) = scene.counts();
        if particles == u64::MAX {
            assert!(p >= u64::from(u32::MAX) * u64::from(u32::MAX) - 1);
        } else {
            assert_eq!(p, particles);
        }
        let _ = scene.memory_estimate();
    }
}

/// XPBD with a stiffness so small that its compliance α̃ = 1/(k·h²) overflows f32: the
/// spring does nothing, exactly as a spring of no stiffness (it made every step NaN). Law:
/// the correction of a spring of compliance α̃ is at most C/α̃, below f32's resolution of
/// the positions here, so the positions are the same bits as with k = 0.
#[test]
fn an_xpbd_spring_too_soft_to_act_within_a_substep_acts_as_none() {
    let run = |k: f32| {
        let mut config = SimConfig {
            integrator: Integrator::Xpbd,
            ..SimConfig::default()
        };
        config.material.bend.stiffness = k;
        let mut sim = Simulation::new(grid(6), config).expect("sim");
        for _ in 0..5 {
            sim.step().expect("a soft bend is stable");
        }
        sim.particles().position.clone()
    };
    let none = run(0.0);
    for k in [1e-38, 2e-39, 1e-40] {
        assert_eq!(run(k), none, "k = {k:e}");
    }
}

/// A step whose substeps are shorter than 1 ns is refused naming `config.dt` (h was 0 at
/// dt = 1e-44: every XPBD step NaN); "auto" substeps never exceed the maximum (implicit
/// Euler at dt = 10⁴ s asked for 600,000).
#[test]
fn substeps_stay_within_their_bounds() {
    let config = SimConfig {
        dt: 1e-44,
        ..SimConfig::default()
    };
    let (name, allowed) = invalid(config.validate());
    assert_eq!(name, "config.dt");
    assert!(allowed.contains("1e-9"), "{allowed}");
    for integrator in [Integrator::ImplicitEuler, Integrator::Xpbd] {
        let mut config = SimConfig {
            dt: 1e4,
            integrator,
            ..SimConfig::default()
        };
        cloth_core::presets::tune_for_integrator(&mut config, &grid(3));
        assert_eq!(config.substeps, cloth_core::config::MAX_SUBSTEPS);
        config.validate().expect("a valid config");
    }
}

/// A particle faster than `limits.max_speed` is refused where it is set (every step would
/// fail the instability check): at creation, by `set_velocity` and by `restore`.
#[test]
fn a_speed_over_the_limit_is_refused_where_it_is_set() {
    let fast = GridBuilder::new(3, 3)
        .velocity(Vec3::new(0.0, 0.0, 1e4))
        .build()
        .expect("grid");
    let (name, allowed) = invalid(Simulation::new(fast, SimConfig::default()));
    assert_eq!(name, "cloth.particles.velocity[0]");
    assert!(allowed.contains("1000 m/s"), "{allowed}");
    let mut sim = Simulation::new(grid(3), SimConfig::default()).expect("sim");
    let (name, _) = invalid(sim.set_velocity(0, Vec3::new(2e3, 0.0, 0.0)));
    assert_eq!(name, "set_velocity.velocity");
    let mut state = sim.state();
    state.velocity[8] = [0.0, 5e3, 0.0];
    let (name, _) = invalid(sim.restore(&state));
    assert_eq!(name, "state.velocity[8]");
}

/// A collider whose prescribed motion carries it past f32's range fails the step (which
/// keeps the last good state, colliders included) instead of returning `Ok` with a
/// non-finite pose.
#[test]
fn a_collider_that_leaves_f32s_range_fails_the_step() {
    for integrator in [Integrator::SymplecticEuler, Integrator::Xpbd] {
        let config = SimConfig {
            integrator,
            ..SimConfig::default()
        };
        let mut sim = Simulation::new(grid(3), config).expect("sim");
        // Far from the cloth, so that only the collider's own pose goes bad.
        sim.add_collider(
            Collider::capsule(Vec3::new(0.0, -5.0, 0.0), Vec3::new(1.0, -5.0, 0.0), 0.1)
                .with_angular_velocity(Vec3::splat(3e38)),
        )
        .expect("capsule");
        let before = sim.colliders()[0].clone();
        match sim.step() {
            Err(ClothError::Unstable { reason, .. }) => {
                assert!(reason.contains("collider 0"), "{reason}");
            }
            other => panic!("{}: expected Unstable, got {other:?}", integrator.name()),
        }
        assert_eq!(sim.colliders()[0], before);
    }
}

/// Implicit Euler whose linear solve overflows f32 (gravity 10²⁴ m/s², or a 10¹² m/s wind)
/// reports the step unstable, naming the solve, instead of `Ok` with the cloth frozen in
/// place (a solve of zero iterations "converged" at ∞ ≤ tol·∞).
#[test]
fn an_implicit_solve_that_overflows_fails_the_step() {
    let mut windy = SimConfig {
        integrator: Integrator::ImplicitEuler,
        ..SimConfig::default()
    };
    windy.air.wind = Vec3::new(0.0, 1e12, 0.0);
    let heavy = SimConfig {
        integrator: Integrator::ImplicitEuler,
        gravity: Vec3::new(0.0, -1e24, 0.0),
        ..SimConfig::default()
    };
    for config in [heavy, windy] {
        for kernel in [None, Some(cloth_core::simd::Kernel::Reference)] {
            cloth_core::simd::set_kernel(kernel).expect("an available kernel");
            let mut sim = Simulation::new(grid(8), config).expect("sim");
            let before = sim.particles().position.clone();
            match sim.step() {
                Err(ClothError::Unstable { reason, .. }) => {
                    assert!(
                        reason.contains("linear solve overflowed")
                            || reason.contains("non-finite")
                            || reason.contains("exceeds the limit"),
                        "{reason}"
                    );
                }
                other => panic!("expected Unstable, got {other:?}"),
            }
            assert_eq!(sim.particles().position, before);
            cloth_core::simd::set_kernel(None).expect("the default kernel");
        }
    }
}

/// Energies are summed from f64 components: finite for any finite state (a speed of 10²⁰
/// m/s, allowed by a raised speed limit, overflowed |v|² in f32). Law: E_k = ½·m·|v|².
#[test]
fn energies_of_any_finite_state_are_finite() {
    let mut config = SimConfig::default();
    config.limits.max_speed = f32::MAX;
    let mut sim = Simulation::new(grid(3), config).expect("sim");
    sim.set_velocity(4, Vec3::new(1e20, 0.0, 0.0)).expect("v");
    let stats = sim.measure();
    let m = f64::from(sim.particles().mass[4]);
    let expected = 0.5 * m * 1e40;
    assert!(stats.kinetic_energy.is_finite());
    assert!((stats.kinetic_energy - expected).abs() <= 1e-6 * expected);
}

/// Colliders' coordinates and sizes are bounded by `MAX_COLLIDER_EXTENT` (a sphere of
/// radius 2·10¹⁹ m was accepted and then invisible: its squared distances overflowed), and a
/// plane's normal is normalised without overflow or underflow.
#[test]
fn collider_extents_and_plane_normals() {
    let mut sim = Simulation::new(grid(3), SimConfig::default()).expect("sim");
    let (name, _) = invalid(sim.add_collider(Collider::sphere(Vec3::new(0.0, -2e19, 0.0), 2e19)));
    assert_eq!(name, "colliders[0].center");
    let (name, allowed) = invalid(sim.add_collider(Collider::sphere(Vec3::ZERO, 2e19)));
    assert_eq!(name, "colliders[0].radius");
    assert!(allowed.contains("1e9"), "{allowed}");
    let i = sim
        .add_collider(Collider::plane(Vec3::ZERO, Vec3::new(0.0, 1e20, 1e20)))
        .expect("a huge normal is a direction");
    let Shape::Plane { normal, .. } = sim.colliders()[i].shape else {
        panic!("plane");
    };
    assert!(normal.distance(Vec3::new(0.0, 1.0, 1.0).normalize()) < 1e-6);
    let (name, _) =
        invalid(sim.add_collider(Collider::plane(Vec3::ZERO, Vec3::new(0.0, 1e-30, 0.0))));
    assert_eq!(name, "colliders[1].normal");
    // With no colliders left to replace, the error says so (it said "0 ..= -1").
    sim.clear_colliders();
    let (_, allowed) = invalid(sim.set_collider(0, Collider::sphere(Vec3::ZERO, 1.0)));
    assert!(
        !allowed.contains("-1") && allowed.contains("no colliders"),
        "{allowed}"
    );
}

/// A mesh's vertices are bounded the same way (at 10²⁰ m its face normal was NaN, at 10¹⁰ m
/// zero); at the bound its normals are unit vectors.
#[test]
fn mesh_vertices_are_bounded() {
    let triangle = |s: f32| vec![Vec3::ZERO, Vec3::new(s, 0.0, 0.0), Vec3::new(0.0, s, 0.0)];
    for s in [1e10, 1e20] {
        let (name, _) = invalid(TriMesh::new(triangle(s), vec![[0, 1, 2]]));
        assert_eq!(name, "mesh.vertices[1]");
    }
    let mesh = TriMesh::new(triangle(1e9), vec![[0, 1, 2]]).expect("at the bound");
    assert!(mesh.face_normals()[0].distance(Vec3::Z) < 1e-6);
}

/// A spacing too fine for f32 positions at the cloth's own size is blamed on the size, not
/// on an origin already at the world origin.
#[test]
fn a_spacing_too_fine_for_the_cloth_blames_its_size() {
    let (name, allowed) = invalid(GridBuilder::new(3, 3).size(1e-7, 1.0).build());
    assert_eq!(name, "grid.size");
    assert!(allowed.contains("spacing"), "{allowed}");
    let (name, _) = invalid(
        GridBuilder::new(3, 3)
            .size(1e-3, 1e-3)
            .origin(Vec3::new(1e5, 0.0, 0.0))
            .build(),
    );
    assert_eq!(name, "grid.origin");
}

/// The centre of mass of no particles is the origin, not NaN.
#[test]
fn the_centre_of_mass_of_nothing_is_the_origin() {
    assert_eq!(
        cloth_core::Particles::default().center_of_mass(),
        Vec3::ZERO
    );
}

/// Scene files: an array longer than its key takes is an error (the extra items were
/// dropped silently, whatever their type), a key of another kind of collider is an error
/// naming the keys that kind reads, `duration` and `description` have their documented
/// bounds, and the self-collision thickness's bound points into the file.
#[test]
fn scene_files_refuse_what_they_would_ignore() {
    let base = "[cloth]\nresolution = [8, 8]\n";
    let bad = |text: &str| match Scene::from_toml(text, "t.toml") {
        Err(ClothError::Scene {
            key, line, message, ..
        }) => (key, line, message),
        other => panic!("{text}: expected a scene error, got {other:?}"),
    };
    let (_, line, message) = bad("[cloth]\nresolution = [8, 8, 9]\n");
    assert_eq!(line, 2);
    assert!(message.contains("length 2"), "{message}");
    let (_, _, message) = bad(&format!("{base}[forces]\ngravity = [0, -9.81, 0, 5]\n"));
    assert!(message.contains("length 3"), "{message}");
    let (key, _, message) = bad(&format!(
        "{base}[[colliders]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 0.3\nhalf_extents = [1, 1, 1]\n"
    ));
    assert_eq!(key, "colliders[0].half_extents");
    assert!(message.contains("`center`, `radius`"), "{message}");
    let (key, _, _) = bad(&format!(
        "{base}[[colliders]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\nrotation = [10, 0, 0]\n"
    ));
    assert_eq!(key, "colliders[0].rotation");
    let (key, _, message) = bad(&format!("duration = 1e30\n{base}"));
    assert_eq!(key, "duration");
    assert!(message.contains("1e6"), "{message}");
    let (key, _, _) = bad(&format!("description = \"a\\nb\"\n{base}"));
    assert_eq!(key, "description");
    let (key, _, _) = bad(&format!(
        "{base}[camera]\neye = [0, 1, 0]\ntarget = [0, 1, 0]\nfov_degrees = 45\n"
    ));
    assert_eq!(key, "camera.target");
    let (key, _, message) = bad("[cloth]\nresolution = [8, 8]\norientation = 1\n");
    assert_eq!(key, "cloth.orientation");
    assert!(
        message.contains("\"horizontal\" or \"vertical\""),
        "{message}"
    );
    let (key, line, _) = bad(&format!(
        "{base}size = [1, 1]\n[solver.self_collision]\nthickness = 5.0\n"
    ));
    assert_eq!(key, "solver.self_collision.thickness");
    assert_eq!(line, 5);
    Scene::from_toml(
        &format!(
            "{base}[[colliders]]\ntype = \"box\"\ncenter = [0, 0, 0]\nhalf_extents = [1, 1, 1]\nrotation = [0, 30, 0]\n"
        ),
        "t.toml",
    )
    .expect("a box reads its rotation");
}

/// A mesh file that cannot be read, named by a `--set` override, is blamed on that override
/// (its error pointed at a line of the file that does not exist).
#[test]
fn a_mesh_error_from_an_override_names_the_override() {
    let item = "colliders=[{type=\"mesh\",file=\"nope.obj\"}]".to_string();
    match Scene::from_toml_with_overrides(
        "[cloth]\nresolution = [8, 8]\n",
        "min.toml",
        std::slice::from_ref(&item),
    ) {
        Err(ClothError::Scene {
            file, line, key, ..
        }) => {
            assert_eq!(file, format!("--set {item}"));
            assert_eq!(line, 0);
            assert_eq!(key, "colliders[0].file");
        }
        other => panic!("expected a scene error, got {other:?}"),
    }
}

/// A scene's enum-valued key given a number is told every name it takes, and only those: the
/// hint's names are each accepted at that key, and there is one per variant (the exhaustive
/// matches below stop compiling when a variant is added).
#[test]
fn enum_hints_list_exactly_the_names_each_key_takes() {
    use cloth_core::scene::{ColliderKind, CornerDesc, EdgeDesc, OrientationDesc};
    let orientation = |o: OrientationDesc| match o {
        OrientationDesc::Horizontal | OrientationDesc::Vertical => (),
    };
    let corner = |c: CornerDesc| match c {
        CornerDesc::TopLeft
        | CornerDesc::TopRight
        | CornerDesc::BottomLeft
        | CornerDesc::BottomRight => (),
    };
    let edge = |e: EdgeDesc| match e {
        EdgeDesc::Top | EdgeDesc::Bottom | EdgeDesc::Left | EdgeDesc::Right => (),
    };
    let kind = |k: ColliderKind| match k {
        ColliderKind::Sphere
        | ColliderKind::Plane
        | ColliderKind::Capsule
        | ColliderKind::Box
        | ColliderKind::Mesh => (),
    };
    OrientationDesc::ALL.into_iter().for_each(orientation);
    CornerDesc::ALL.into_iter().for_each(corner);
    EdgeDesc::ALL.into_iter().for_each(edge);
    ColliderKind::ALL.into_iter().for_each(kind);

    let base = "[cloth]\nresolution = [8, 8]\n";
    // (scene with NAME where the name goes, its key, variants)
    let cases = [
        (
            format!("{base}orientation = NAME\n"),
            "cloth.orientation",
            OrientationDesc::ALL.len(),
        ),
        (
            format!("{base}[cloth.pins]\ncorners = [NAME]\n"),
            "cloth.pins.corners",
            CornerDesc::ALL.len(),
        ),
        (
            format!("{base}[cloth.pins]\nedges = [NAME]\n"),
            "cloth.pins.edges",
            EdgeDesc::ALL.len(),
        ),
        (
            format!("{base}[[colliders]]\ntype = NAME\n"),
            "colliders[0].type",
            ColliderKind::ALL.len(),
        ),
    ];
    for (template, key, variants) in cases {
        let message = match Scene::from_toml(&template.replace("NAME", "1"), "t.toml") {
            Err(ClothError::Scene {
                key: k, message, ..
            }) => {
                assert!(k.starts_with(key), "{k} for {key}");
                message
            }
            other => panic!("{key}: expected a scene error, got {other:?}"),
        };
        let mut names: Vec<&str> = message.split('"').skip(1).step_by(2).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), variants, "{key}: {message}");
        for name in names {
            let text = template.replace("NAME", &format!("\"{name}\""));
            if let Err(ClothError::Scene {
                key: k, message, ..
            }) = Scene::from_toml(&text, "t.toml")
            {
                // A collider of a valid type may still miss its fields; the type was read.
                assert!(!k.ends_with(".type"), "{key} = {name:?} refused: {message}");
            }
        }
    }
}
