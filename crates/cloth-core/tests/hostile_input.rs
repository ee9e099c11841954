//! Hostile scene input never panics: random `--set`-style overrides of every scene key, at
//! and past their ranges (NaN, infinities, zero, negative, huge, wrong types), on every
//! built-in scene. Each case either is refused with an error, or builds and steps, where a
//! step either succeeds or reports an instability, and the state stays finite (a failed step
//! keeps the last good state). The deterministic, in-CI companion of `scripts/fuzz-cli.py`.

use cloth_core::scene::{self, BUILTIN};

/// xorshift64*: a fixed sequence, so a failure names a reproducible case.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn pick<'a>(&mut self, items: &[&'a str]) -> &'a str {
        items[(self.next() % items.len() as u64) as usize]
    }
}

const VALUES: &[&str] = &[
    "0", "1", "-1", "0.3", "1e-9", "1e9", "nan", "inf", "-inf", "1e30", "-1e-30", "2", "[]",
    "\"x\"", "true",
];

/// Plausible values, so that many cases build and step.
const PLAUSIBLE: &[&str] = &["0.01", "0.3", "1", "10", "400", "0.05"];

/// A plausible value two times in three, a hostile one otherwise.
fn value(rng: &mut Rng) -> String {
    if rng.next().is_multiple_of(3) {
        rng.pick(VALUES).to_string()
    } else {
        rng.pick(PLAUSIBLE).to_string()
    }
}

fn vec3(rng: &mut Rng) -> String {
    format!("[{},{},{}]", value(rng), value(rng), value(rng))
}

fn collider(rng: &mut Rng) -> String {
    let kind = rng.pick(&["sphere", "plane", "capsule", "box", "cone"]);
    let mut parts = vec![format!("type=\"{kind}\"")];
    for key in [
        "center",
        "point",
        "normal",
        "a",
        "b",
        "half_extents",
        "velocity",
    ] {
        if rng.next().is_multiple_of(3) {
            parts.push(format!("{key}={}", vec3(rng)));
        }
    }
    for key in ["radius", "thickness"] {
        if rng.next().is_multiple_of(3) {
            parts.push(format!("{key}={}", value(rng)));
        }
    }
    if rng.next().is_multiple_of(3) {
        parts.push(format!(
            "friction={{static={},kinetic={}}}",
            value(rng),
            value(rng)
        ));
    }
    format!("{{{}}}", parts.join(","))
}

/// One random override `key=value`.
fn override_of(rng: &mut Rng) -> String {
    match rng.next() % 16 {
        0 => format!(
            "cloth.resolution={}",
            rng.pick(&[
                "[0,0]", "[1,5]", "[2,2]", "[3,2]", "[2,3]", "[7,3]", "[2,12]", "[9,9]"
            ])
        ),
        1 => format!("cloth.size=[{},{}]", value(rng), value(rng)),
        2 => format!("cloth.origin={}", vec3(rng)),
        3 => format!("cloth.velocity={}", vec3(rng)),
        4 => format!("cloth.density={}", value(rng)),
        5 => format!(
            "material.{}={{stiffness={},damping={}}}",
            rng.pick(&["warp", "weft", "shear", "bend"]),
            value(rng),
            value(rng)
        ),
        6 => format!("forces.gravity={}", vec3(rng)),
        7 => format!("forces.damping={}", value(rng)),
        8 => format!(
            "forces.air={{density={},drag={},lift={},wind={}}}",
            value(rng),
            value(rng),
            value(rng),
            vec3(rng)
        ),
        9 => format!("colliders=[{},{}]", collider(rng), collider(rng)),
        10 => format!(
            "solver.kind={}",
            rng.pick(&[
                "xpbd",
                "implicit-euler",
                "verlet",
                "symplectic-euler",
                "forward-euler"
            ])
        ),
        11 => format!(
            "solver.substeps={}",
            rng.pick(&["0", "1", "2", "20", "\"auto\"", "2.5", "-1"])
        ),
        12 => format!(
            "solver.dt={}",
            rng.pick(&["0.001", "0.0166", "0.1", "10", "0", "nan", "-1"])
        ),
        13 => format!(
            "solver.self_collision={{thickness={},friction={}}}",
            value(rng),
            value(rng)
        ),
        14 => {
            let options = [
                "iterations=2",
                "chains=true",
                "shear_chains=true",
                "structural_limit=0.02",
                "structural_limit=nan",
                "hierarchy_levels=3",
                "hierarchy_levels=40",
                "chain_rounds=0",
                "chain_rounds=3",
                "chain_relaxation=1.3",
                "chain_relaxation=2.5",
                "chain_iterations=2",
                "tethers=true",
            ];
            let a = rng.pick(&options);
            let b = rng.pick(&options);
            if a.split('=').next() == b.split('=').next() {
                format!("solver.xpbd={{{a}}}")
            } else {
                format!("solver.xpbd={{{a},{b}}}")
            }
        }
        _ => format!(
            "solver.limits={{max_stretch_ratio={},max_speed={}}}",
            value(rng),
            value(rng)
        ),
    }
}

/// 600 random cases of one to three overrides on a small cloth (at most 12 × 12, so that the
/// whole test takes seconds): refused, or built and stepped three times, with a finite state
/// after every step and a finite, positive memory estimate.
#[test]
fn random_overrides_never_panic_or_leave_a_non_finite_state() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let (mut built, mut refused, mut unstable) = (0, 0, 0);
    for case in 0..600 {
        let (name, _) = BUILTIN[(rng.next() % BUILTIN.len() as u64) as usize];
        let side = 2 + rng.next() % 11;
        let mut sets = vec![format!("cloth.resolution=[{side},{side}]")];
        for _ in 0..1 + rng.next() % 3 {
            sets.push(override_of(&mut rng));
        }
        let what = format!("case {case}: {name} {sets:?}");
        let Ok((scene, _)) = scene::load(name, &sets) else {
            refused += 1;
            continue;
        };
        // Keep every case quick: a refused resolution is refused above; a big one is not
        // generated; a million substeps per frame would be slow, not wrong.
        let Ok(mut sim) = scene.build() else {
            refused += 1;
            continue;
        };
        assert!(scene.memory_estimate() > 0, "{what}");
        if sim.config().substeps > 2000 {
            continue;
        }
        built += 1;
        for _ in 0..3 {
            let result = sim.step();
            assert!(
                sim.particles().position.iter().all(|p| p.is_finite())
                    && sim.particles().velocity.iter().all(|v| v.is_finite()),
                "{what}: non-finite state after a step ({:?})",
                result.as_ref().err()
            );
            if result.is_err() {
                unstable += 1;
                break;
            }
        }
    }
    eprintln!("{built} built ({unstable} reported unstable), {refused} refused");
    // The generator reaches both outcomes (a test that refused everything would test little).
    assert!(
        built >= 100 && refused >= 100,
        "{built} built, {refused} refused"
    );
}
