//! Determinism across thread counts, scene by scene: every built-in scene (contacts with
//! spheres, planes, capsules, boxes and meshes, moving colliders, pins, air with gusts,
//! self-collision, strain limits), with every integrator and XPBD's sweep modes, gives the same
//! bits on 1, 2 and 3 threads.
//!
//! The parallel passes split the cloth by the pool's size (bands of rows for the explicit grid
//! path and XPBD, fixed tasks for implicit Euler and the diagnostics), so each thread count
//! here runs a different partition. The cloth is 40 × 33 particles: 5 bands of 8 rows at most,
//! and two implicit-Euler tasks of 1024 particles.

use cloth_core::scene::{self, BUILTIN};
use cloth_core::{Integrator, Simulation};

/// Steps run with the scene's own integrator (long enough for the cloths that fall to reach
/// their colliders, the drape's ball after 14 frames); and with each other mode.
const OWN_STEPS: usize = 24;
const OTHER_STEPS: usize = 6;

/// Everything a step leaves: the state's bits, and the step's diagnostics (their `Debug` text
/// prints each float's shortest round-trip digits, so equal text is equal bits).
fn trace(mut sim: Simulation, steps: usize) -> Vec<String> {
    let mut out = Vec::with_capacity(steps);
    for _ in 0..steps {
        let stats = match sim.step() {
            Ok(s) => format!("{s:?}"),
            Err(e) => format!("error: {e}"),
        };
        let p = sim.particles();
        let bits: Vec<u32> = p
            .position
            .iter()
            .chain(&p.velocity)
            .flat_map(|v| v.to_array())
            .map(f32::to_bits)
            .collect();
        out.push(format!("{stats} {bits:?}"));
    }
    out
}

/// Law: a parallel pass writes disjoint data and sums in a fixed order, so the partition a pool
/// size gives never changes a bit. Tolerance: none (bit for bit, every step's state and
/// diagnostics, or the same error at the same step).
#[test]
fn every_scene_and_integrator_gives_the_same_bits_on_1_2_and_3_threads() {
    let pools: Vec<rayon::ThreadPool> = [1, 2, 3]
        .iter()
        .map(|&n| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .expect("pool")
        })
        .collect();
    let mut modes: Vec<(String, Vec<String>)> = Integrator::ALL
        .iter()
        .map(|i| {
            (
                i.name().to_owned(),
                vec![format!("solver.kind={:?}", i.name())],
            )
        })
        .collect();
    modes.push((
        "xpbd chains, rounds, limit, levels".into(),
        vec![
            "solver.kind=\"xpbd\"".into(),
            "solver.xpbd={chains=true,chain_rounds=2,chain_iterations=2,structural_limit=0.02,hierarchy_levels=3}".into(),
        ],
    ));
    modes.push((
        "xpbd shear chains, two sweeps".into(),
        vec![
            "solver.kind=\"xpbd\"".into(),
            "solver.xpbd={chains=true,shear_chains=true,iterations=2}".into(),
        ],
    ));
    let mut runs = 0;
    for (name, _) in BUILTIN {
        let own = scene::builtin(name).expect("built-in").integrator();
        let mut cases = vec![("own integrator".to_owned(), Vec::new(), OWN_STEPS)];
        for (mode, sets) in &modes {
            if sets.len() > 1 || Integrator::from_name(mode) != Some(own) {
                cases.push((mode.clone(), sets.clone(), OTHER_STEPS));
            }
        }
        for (mode, sets, steps) in cases {
            let mut sets = sets;
            sets.push("cloth.resolution=[40, 33]".into());
            let (scene, _) = scene::load(name, &sets).expect("scene");
            let sim = scene.build().expect("build");
            let first = pools[0].install(|| trace(sim.clone(), steps));
            for (pool, threads) in pools.iter().zip([1, 2, 3]).skip(1) {
                let got = pool.install(|| trace(sim.clone(), steps));
                let step = got.iter().zip(&first).position(|(a, b)| a != b);
                assert!(
                    step.is_none(),
                    "{name}, {mode}: {threads} threads differ from 1 at step {step:?}"
                );
            }
            runs += 1;
        }
    }
    // Every scene ran with its own integrator and each other mode.
    assert_eq!(runs, BUILTIN.len() * (Integrator::ALL.len() + 2));
}
