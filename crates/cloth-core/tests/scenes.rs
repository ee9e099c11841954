//! Scene files: every built-in scene parses, round-trips and runs; every kind of bad input
//! gets one error naming the file, line and column, the key and what is allowed.

use cloth_core::scene::{self, BUILTIN, Scene};
use cloth_core::{ClothError, presets};

fn error_of(src: &str) -> (String, usize, usize, String, String) {
    match Scene::from_toml(src, "bad.toml") {
        Err(ClothError::Scene {
            file,
            line,
            column,
            key,
            message,
        }) => (file, line, column, key, message),
        other => panic!("expected a scene error for {src:?}, got {other:?}"),
    }
}

const GOOD: &str = r#"
[cloth]
resolution = [8, 8]
size = [1.0, 1.0]

[[colliders]]
type = "sphere"
center = [0.0, -1.0, 0.0]
radius = 0.5
"#;

/// Round trip: scene → TOML text → scene is identical, for every built-in scene.
#[test]
fn builtin_scenes_round_trip() {
    for (name, _) in BUILTIN {
        let scene = scene::builtin(name).expect("built-in");
        let text = scene.to_toml();
        let again = Scene::from_toml(&text, name).expect("re-parse");
        assert_eq!(scene, again, "{name}");
    }
}

/// Every built-in scene builds and runs one simulated second with no instability, no
/// non-finite value and (where it has colliders) no penetration deeper than 1e-5 m below the
/// contact surface.
#[test]
fn builtin_scenes_run_headless() {
    for (name, _) in BUILTIN {
        let scene = scene::builtin(name).expect("built-in");
        let mut sim = scene.build().expect("build");
        let frames = (1.0 / sim.config().dt).ceil() as u32;
        for frame in 0..frames {
            let stats = sim
                .step()
                .unwrap_or_else(|e| panic!("{name} frame {frame}: {e}"));
            assert!(
                stats.max_penetration <= 1e-5,
                "{name}: {}",
                stats.max_penetration
            );
        }
        assert!(sim.particles().position.iter().all(|p| p.is_finite()));
    }
}

/// The smallest cloths a scene file may ask for (2 ..= 5 particles a side, narrower than
/// the bend springs' span and the solvers' blocks) run every built-in scene, with its own
/// integrator and with XPBD in each of its sweep modes (pairs; chains with rounds, Newton
/// iterations, the strain limit and the multi-resolution limits; shear chains), on the
/// default kernel: each step either succeeds or reports an instability, never panics, and
/// the state stays finite (a failed step keeps the last good state).
#[test]
fn smallest_grids_run_every_scene_and_solver_mode() {
    let xpbd_modes: [&[&str]; 4] = [
        &[],
        &["solver.kind=\"xpbd\""],
        &[
            "solver.kind=\"xpbd\"",
            "solver.xpbd={chains=true,chain_rounds=2,chain_iterations=2,structural_limit=0.02,hierarchy_levels=3}",
        ],
        &[
            "solver.kind=\"xpbd\"",
            "solver.xpbd={chains=true,shear_chains=true,iterations=2}",
        ],
    ];
    for (name, _) in BUILTIN {
        for [rows, cols] in [[2, 2], [2, 5], [5, 2], [3, 3], [4, 4]] {
            for mode in xpbd_modes {
                let mut sets = vec![format!("cloth.resolution=[{rows}, {cols}]")];
                sets.extend(mode.iter().map(|s| (*s).to_string()));
                let (scene, _) = scene::load(name, &sets).expect("scene");
                let mut sim = scene.build().expect("build");
                for _ in 0..3 {
                    if sim.step().is_err() {
                        break;
                    }
                }
                assert!(
                    sim.particles().position.iter().all(|p| p.is_finite()),
                    "{name} {rows}x{cols} {mode:?}"
                );
            }
        }
    }
}

/// f32 positions have about 7 significant digits: a cloth far from the world origin (or
/// tiny) whose neighbours would round onto one another (springs of zero rest length, strains
/// of 0/0) is refused with the key and the distance allowed for its spacing (at least
/// `RESOLVED_ULPS` = 64 representable steps per spacing), by the builder as `grid.origin`
/// and by a scene as `cloth.origin`; a cloth well within the bound builds and steps.
#[test]
fn cloths_f32_cannot_resolve_are_refused() {
    use cloth_core::GridBuilder;
    use cloth_core::glam::Vec3;
    let err = GridBuilder::new(8, 8)
        .size(1.0, 1.0)
        .origin(Vec3::new(1e30, 0.0, 0.0))
        .build()
        .unwrap_err()
        .to_string();
    assert!(err.contains("`grid.origin`"), "{err}");
    assert!(err.contains("of the world origin"), "{err}");
    let sets = |s: &[&str]| s.iter().map(|x| (*x).to_string()).collect::<Vec<_>>();
    for bad in [
        &["cloth.origin=[1e30, 0, 0]"][..],
        &["cloth.size=[1e-9, 1e-9]"],
    ] {
        let (scene, _) = scene::load("drape", &sets(bad)).expect("parses");
        let Err(err) = scene.build() else {
            panic!("{bad:?}: built")
        };
        let err = err.to_string();
        assert!(err.contains("`cloth.origin`"), "{bad:?}: {err}");
    }
    // 1 km out (f32 steps of 6.1e-5 m there), a 2.6 cm spacing: the bound is 3.3 km.
    let (scene, _) = scene::load("drape", &sets(&["cloth.origin=[1000, 0.55, 0]"])).expect("far");
    let mut sim = scene.build().expect("builds");
    for _ in 0..10 {
        let stats = sim.step().expect("steps");
        assert!(
            stats
                .strain(cloth_core::topology::SpringClass::Structural)
                .is_finite()
        );
    }
}

/// The memory estimate `cloth sim` checks against the memory available counts the
/// self-collision pair list: without self-collision it is the particles' and springs'
/// estimate; with a thickness t it adds about π(2t)²/(2·Δx·Δy) pairs of 12 bytes per
/// particle (the candidates within twice the thickness on a flat sheet, at least 12), so the
/// 256² drape with a 2 cm layer (4.3 spacings) needs about 90 MiB more (measured: the
/// process peaked at 116 MiB against an estimate of 122 MiB for `scenes/mesh.toml`).
#[test]
fn memory_estimate_counts_the_self_collision_pairs() {
    let sets = |s: &[&str]| s.iter().map(|x| (*x).to_string()).collect::<Vec<_>>();
    let (plain, _) = scene::load("drape", &sets(&["cloth.resolution=[256, 256]"])).expect("drape");
    let (particles, springs) = plain.counts();
    assert_eq!(
        plain.memory_estimate(),
        scene::memory_estimate(particles, springs)
    );
    let (layered, _) = scene::load(
        "drape",
        &sets(&[
            "cloth.resolution=[256, 256]",
            "solver.self_collision={thickness=0.02}",
        ]),
    )
    .expect("drape with self-collision");
    let dx = 1.2_f64 / 255.0;
    let pairs = std::f64::consts::PI * 0.04 * 0.04 / (2.0 * dx * dx);
    let want = (particles as f64 * (pairs * 12.0 + 12.0)) as u64;
    let extra = layered.memory_estimate() - plain.memory_estimate();
    // The scene holds f32 lengths: the same to 10⁻⁶.
    assert!(
        extra.abs_diff(want) <= want / 1_000_000,
        "{extra} bytes against {want}"
    );
    assert!((80 << 20..100 << 20).contains(&extra), "{extra} bytes");
}

/// `scenes/peer-ball.toml` is exactly the scene `presets::peer_ball(128)` computes from the
/// peer README's formulas: same particles, masses, springs, parameters and collider.
#[test]
fn peer_ball_file_matches_the_peer_formulas() {
    let file = scene::builtin("peer-ball")
        .expect("peer-ball")
        .build()
        .expect("build");
    let formula = presets::peer_ball(128).expect("preset");
    assert_eq!(file.particles().len(), formula.particles().len());
    for (a, b) in file
        .particles()
        .position
        .iter()
        .zip(&formula.particles().position)
    {
        assert!(a.distance(*b) < 1e-6, "{a} vs {b}");
    }
    assert_eq!(file.particles().mass, formula.particles().mass);
    assert_eq!(
        file.topology().springs().len(),
        formula.topology().springs().len()
    );
    let (fc, pc) = (file.config(), formula.config());
    assert_eq!((fc.substeps, fc.integrator), (pc.substeps, pc.integrator));
    assert!((fc.dt - pc.dt).abs() < 1e-9);
    for (a, b) in [
        (fc.material.warp, pc.material.warp),
        (fc.material.shear, pc.material.shear),
        (fc.material.bend, pc.material.bend),
    ] {
        assert!(
            (a.stiffness - b.stiffness).abs() <= 1e-6 * b.stiffness,
            "{a:?} {b:?}"
        );
        assert!((a.damping - b.damping).abs() <= 1e-6 * b.damping);
    }
    assert_eq!(file.colliders(), formula.colliders());
}

#[test]
fn a_good_scene_parses_and_builds() {
    let scene = Scene::from_toml(GOOD, "good.toml").expect("parse");
    let sim = scene.build().expect("build");
    assert_eq!(sim.particles().len(), 64);
    assert_eq!(scene.counts(), (64, sim.topology().springs().len() as u64));
}

#[test]
fn syntax_errors_give_line_and_column() {
    let (file, line, column, _, message) = error_of("[cloth]\nresolution = [8, 8\nsize = 1");
    assert_eq!(file, "bad.toml");
    // The missing comma is found where the next token starts: the end of line 2 or line 3.
    assert!((2..=3).contains(&line), "{line}: {message}");
    assert!(column > 0);
}

#[test]
fn unknown_keys_suggest_the_closest_known_key() {
    let src = GOOD.replace("size = [1.0, 1.0]", "sise = [1.0, 1.0]");
    let (_, line, _, _, message) = error_of(&src);
    assert_eq!(line, 4, "{message}");
    assert!(message.contains("unknown field `sise`"), "{message}");
    assert!(message.contains("did you mean `size`?"), "{message}");
}

#[test]
fn wrong_types_are_errors() {
    let src = GOOD.replace("radius = 0.5", "radius = \"big\"");
    let (_, line, _, _, message) = error_of(&src);
    assert_eq!(line, 9, "{message}");
}

/// Out-of-range and non-finite values name the key, its line and the allowed range.
#[test]
fn out_of_range_values_name_key_line_and_range() {
    let cases: [(&str, &str, &str, usize, &str); 15] = [
        (
            "resolution = [8, 8]",
            "resolution = [0, 8]",
            "cloth.resolution",
            3,
            "2 ..= 8192",
        ),
        (
            "size = [1.0, 1.0]",
            "size = [1e30, 1.0]",
            "cloth.size",
            4,
            "(0, 10000] m",
        ),
        (
            "size = [1.0, 1.0]",
            "spacing = [2000.0, 0.1]",
            "cloth.spacing",
            4,
            "at most [1428.5714, 1428.5714] m",
        ),
        (
            "size = [1.0, 1.0]",
            "size = [1.0, 1.0]\ndensity = -2.0",
            "cloth.density",
            5,
            "> 0",
        ),
        (
            "radius = 0.5",
            "radius = 0.5\nfriction = { static = -1.0 }",
            "colliders[0].friction.static",
            10,
            ">= 0",
        ),
        (
            "radius = 0.5",
            "radius = nan",
            "colliders[0].radius",
            9,
            "> 0",
        ),
        (
            "size = [1.0, 1.0]",
            "size = [1.0, 1.0]\npins = { indices = [64] }",
            "cloth.pins.indices",
            5,
            "0 ..= 63",
        ),
        (
            "radius = 0.5",
            "radius = 0.5\n[solver]\ndt = 0.0",
            "solver.dt",
            11,
            "> 0",
        ),
        (
            "radius = 0.5",
            "radius = 0.5\n[solver]\nkind = \"rk4\"",
            "solver.kind",
            11,
            "xpbd",
        ),
        (
            "radius = 0.5",
            "radius = 0.5\n[solver]\nsubsteps = 0",
            "solver.substeps",
            11,
            "auto",
        ),
        (
            "radius = 0.5",
            "radius = 0.5\n[solver.xpbd]\nchains = true\nchain_iterations = 0",
            "solver.xpbd.chain_iterations",
            12,
            "1 ..= 16",
        ),
        (
            "radius = 0.5",
            "radius = 0.5\n[solver.xpbd]\nchains = true\nchain_rounds = 17",
            "solver.xpbd.chain_rounds",
            12,
            "1 ..= 16",
        ),
        (
            "radius = 0.5",
            "radius = 0.5\n[solver.xpbd]\nchains = true\nchain_relaxation = 2.0",
            "solver.xpbd.chain_relaxation",
            12,
            "greater than 0 and less than 2",
        ),
        (
            "radius = 0.5",
            "radius = 0.5\n[solver.xpbd]\nstructural_limit = -0.02",
            "solver.xpbd.structural_limit",
            11,
            "0 ..= 1",
        ),
        (
            "radius = 0.5",
            "radius = 0.5\n[solver.xpbd]\nstructural_limit = 2.0",
            "solver.xpbd.structural_limit",
            11,
            "0 ..= 1",
        ),
    ];
    for (from, to, key, line, allowed) in cases {
        let src = GOOD.replace(from, to);
        let (_, l, c, k, message) = error_of(&src);
        assert_eq!(k, key, "{to}: {message}");
        assert_eq!(l, line, "{to}: {message} (line {l})");
        assert!(c > 0);
        assert!(message.contains(allowed), "{to}: {message}");
        let shown = Scene::from_toml(&src, "bad.toml").unwrap_err().to_string();
        assert!(shown.starts_with(&format!("bad.toml:{line}:")), "{shown}");
    }
}

#[test]
fn empty_binary_and_missing_files_are_errors() {
    assert!(error_of("").4.contains("empty"));
    assert!(error_of("  \n\n").4.contains("empty"));
    assert!(error_of("a\0b").4.contains("binary"));
    let err = scene::load("/no/such/scene.toml", &[])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("/no/such/scene.toml") && err.contains("drape"),
        "{err}"
    );
}

/// `--set key.path=value` overrides are applied and validated like the file; a bare word is a
/// string.
#[test]
fn overrides_apply_and_are_validated() {
    let sets = |s: &[&str]| s.iter().map(|x| (*x).to_string()).collect::<Vec<_>>();
    let (scene, _) = scene::load(
        "drape",
        &sets(&[
            "cloth.resolution=[10, 12]",
            "solver.kind=\"xpbd\"",
            "colliders[0].radius=0.25",
        ]),
    )
    .expect("overrides");
    assert_eq!(scene.cloth.resolution, [10, 12]);
    assert_eq!(scene.solver.kind, "xpbd");
    assert_eq!(scene.colliders[0].radius, Some(0.25));
    // A bare word is a string: what a shell leaves of `solver.kind="symplectic-euler"`.
    let (bare, _) = scene::load("drape", &sets(&["solver.kind=symplectic-euler"])).expect("bare");
    assert_eq!(bare.solver.kind, "symplectic-euler");
    for (bad, needle) in [
        ("cloth.resolution=[1, 8]", "2 ..= 8192"),
        ("name=my drape", "needs quotes"),
        ("solver.kind=xpdb", "solver.kind"),
        ("solver.knd=\"xpbd\"", "did you mean `kind`?"),
        ("colliders[7].radius=1.0", "out of range"),
        ("no-equals-sign", "key.path=value"),
    ] {
        let err = scene::load("drape", &sets(&[bad])).unwrap_err().to_string();
        assert!(err.contains(&format!("--set {bad}")), "{bad}: {err}");
        assert!(err.contains(needle), "{bad}: {err}");
    }
}

/// What the viewer saves reproduces what was on screen: a simulation whose settings were
/// changed while running (material, damping, wind, friction, integrator, substeps, a pin),
/// saved with `Scene::with_settings_of`, written as TOML and read back, restarts to the same
/// state, bit for bit, as the modified simulation restarted by hand.
#[test]
fn saved_settings_rerun_to_the_same_state() {
    let base = scene::builtin("drape").expect("drape");
    let mut base = base;
    base.cloth.resolution = [12, 12];
    let mut live = base.build().expect("build");
    let mut config = *live.config();
    config.material.warp.stiffness = 321.0;
    config.damping = 0.01;
    config.air.wind = glam::Vec3::new(1.0, 0.0, 0.5);
    config.integrator = cloth_core::Integrator::Verlet;
    config.substeps = 77;
    live.set_config(config).expect("config");
    let mut col = live.colliders()[0].clone();
    col.friction = cloth_core::Friction::new(0.9, 0.7);
    live.set_collider(0, col.clone()).expect("collider");
    live.pin(5).expect("pin");

    let saved = base.with_settings_of(&live);
    let text = saved.to_toml();
    let reloaded = Scene::from_toml(&text, "saved.toml").expect("saved scene parses");
    assert_eq!(reloaded, saved);

    // The same settings applied by hand to a fresh build of the original scene.
    let mut by_hand = base.build().expect("build");
    by_hand.set_config(config).expect("config");
    by_hand.set_collider(0, col).expect("collider");
    by_hand.pin(5).expect("pin");
    let mut from_file = reloaded.build().expect("build");
    for _ in 0..30 {
        by_hand.step().expect("step");
        from_file.step().expect("step");
    }
    assert_eq!(by_hand.particles().position, from_file.particles().position);
    assert_eq!(by_hand.config(), from_file.config());
}

/// `solver.xpbd.shear_chains` reaches the simulation's settings (off by default), survives a
/// round trip through TOML, and a wrong type is an error naming the key.
#[test]
fn shear_chains_key_reaches_the_config() {
    let off = Scene::from_toml(GOOD, "good.toml").expect("parses");
    assert!(!off.build().expect("build").config().xpbd.shear_chains);
    let src = GOOD.replace(
        "radius = 0.5",
        "radius = 0.5\n[solver]\nkind = \"xpbd\"\n[solver.xpbd]\nchains = true\nshear_chains = true",
    );
    let on = Scene::from_toml(&src, "good.toml").expect("parses");
    let config = *on.build().expect("build").config();
    assert!(config.xpbd.shear_chains && config.xpbd.chains);
    let again = Scene::from_toml(&on.to_toml(), "again.toml").expect("re-parse");
    assert_eq!(again, on);
    assert!(on.to_toml().contains("shear_chains = true"));
    let (_, line, _, key, message) =
        error_of(&src.replace("shear_chains = true", "shear_chains = 2"));
    assert_eq!(key, "solver.xpbd.shear_chains", "{message}");
    assert_eq!(line, 14, "{message}");
}

/// `substeps = "auto"` gives implicit Euler one substep and XPBD 20 per 1/60 s step, as
/// docs/scenes.md says, at the f32 nearest 1/60 (`dt = 0.016666668`, a little above 1/60: its
/// 20 substeps per frame once rounded up to 21) and in proportion at other steps.
#[test]
fn auto_substeps_per_frame_of_implicit_euler_and_xpbd() {
    let substeps = |kind: &str, dt: &str| {
        let src = GOOD.replace(
            "radius = 0.5",
            &format!("radius = 0.5\n[solver]\nkind = \"{kind}\"\ndt = {dt}\nsubsteps = \"auto\""),
        );
        let scene = Scene::from_toml(&src, "auto.toml").expect("parses");
        scene.build().expect("build").config().substeps
    };
    for dt in ["0.016666668", "0.016666666"] {
        assert_eq!(substeps("xpbd", dt), 20, "dt = {dt}");
        assert_eq!(substeps("implicit-euler", dt), 1, "dt = {dt}");
    }
    assert_eq!(substeps("xpbd", "0.033333335"), 40);
    assert_eq!(substeps("implicit-euler", "0.033333335"), 2);
    // Not a whole number of frames: rounded up.
    assert_eq!(substeps("xpbd", "0.0165625"), 20);
    assert_eq!(substeps("xpbd", "0.02"), 24);
    assert_eq!(substeps("implicit-euler", "0.02"), 2);
}

/// A step too short for the substeps "auto" chooses (at most `MAX_SUBSTEPS`, each at least
/// `MIN_SUBSTEP_DT`), found only when the scene is built, is blamed on the scene's
/// `solver.dt`, not on the library's `config.dt`.
#[test]
fn a_step_too_short_for_auto_substeps_names_solver_dt() {
    let sets = [
        "solver.dt=5e-5".to_string(),
        "material.warp={stiffness=1e30}".to_string(),
    ];
    let (scene, _) = scene::load("drape", &sets).expect("the file's checks pass");
    match scene.build() {
        Err(ClothError::InvalidArgument { name, allowed, .. }) => {
            assert_eq!(name, "solver.dt");
            assert!(allowed.contains("at least 1e-9 s"), "{allowed}");
        }
        other => panic!("expected solver.dt to be refused, got {:?}", other.err()),
    }
}

/// Which overrides set a key (what the viewer keeps when it adjusts a scene): the key, one
/// under it, or the key inside a table value; not a key that merely starts with the same
/// letters, nor another key of the same table.
#[test]
fn which_overrides_set_a_key() {
    use cloth_core::scene::overrides_set;
    let o = |v: &[&str]| v.iter().map(|s| (*s).to_string()).collect::<Vec<_>>();
    assert!(overrides_set(&o(&["camera.eye=[1,2,3]"]), "camera"));
    assert!(overrides_set(
        &o(&["camera={eye=[1,2,3],target=[0,0,0]}"]),
        "camera"
    ));
    assert!(!overrides_set(&o(&["cloth.resolution=[4,4]"]), "camera"));
    assert!(overrides_set(
        &o(&[" solver.substeps = 3"]),
        "solver.substeps"
    ));
    assert!(!overrides_set(
        &o(&["solver.substeps_x=3"]),
        "solver.substeps"
    ));
    assert!(!overrides_set(&o(&["solver.dt=0.01"]), "solver.substeps"));
    // Through a table value: the field itself, not a string that mentions it.
    assert!(overrides_set(
        &o(&[r#"solver={kind="xpbd",substeps=8}"#]),
        "solver.substeps"
    ));
    assert!(!overrides_set(
        &o(&[r#"solver={kind="substeps"}"#]),
        "solver.substeps"
    ));
}
