//! XPBD's grid path (coloured Gauss–Seidel over shifted rows, `solver::grid_xpbd`) against
//! the reference path, across threads and kernels, and the multi-resolution strain limits
//! against their definition.

use cloth_core::diagnostics::strain_quantiles;
use cloth_core::glam::Vec3;
use cloth_core::simd::{self, Kernel};
use cloth_core::{
    Cloth, Collider, Edge, Friction, GridBuilder, Integrator, Mass, Material, Orientation,
    SimConfig, Simulation, SpringClass, SpringKind, SpringParams, presets,
};

fn bits(v: &[Vec3]) -> Vec<[u32; 3]> {
    v.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
}

/// The drape with XPBD, air and wind, friction on the ball and the ground, and `levels`
/// levels of multi-resolution strain limits.
fn drape(n: usize, levels: u32) -> Simulation {
    let mut sim = presets::drape(n, Integrator::Xpbd).expect("drape");
    let mut config = *sim.config();
    config.substeps = 8;
    config.xpbd.hierarchy_levels = levels;
    config.air.wind = Vec3::new(0.5, 0.0, 0.3);
    sim.set_config(config).expect("config");
    sim
}

/// Runs `steps` steps with `kernel` chosen on this thread; every position's and velocity's
/// bits and the contact counts.
fn trace(
    mut sim: Simulation,
    kernel: Kernel,
    steps: usize,
) -> (Vec<[u32; 3]>, Vec<[u32; 3]>, Vec<u32>) {
    simd::set_kernel(Some(kernel)).expect("kernel");
    let mut contacts = Vec::new();
    for _ in 0..steps {
        contacts.push(sim.step().expect("stable").contacts);
    }
    simd::set_kernel(None).expect("default");
    (
        bits(&sim.particles().position),
        bits(&sim.particles().velocity),
        contacts,
    )
}

/// Determinism: every pass of the grid path writes disjoint rows and uses exact IEEE
/// arithmetic, so 1, 2 and 3 threads and every kernel this CPU runs give the same bits (the
/// drape with four levels of strain limits and the structural limit at 2 %, and with chain
/// solves in two rounds per sweep and the structural limit, on a square and on a strip whose
/// chains are solved one block at a time).
/// Tolerance: none.
#[test]
fn grid_path_is_bit_identical_across_threads_and_kernels() {
    let kernels: Vec<Kernel> = [Kernel::Portable, Kernel::Avx2, Kernel::Avx512]
        .into_iter()
        .filter(|k| k.is_available())
        .collect();
    let mut base = drape(40, 4);
    let mut config = *base.config();
    config.xpbd.structural_limit = Some(0.02);
    base.set_config(config).expect("config");
    assert_eq!(
        {
            simd::set_kernel(Some(Kernel::Portable)).expect("portable");
            let k = simd::kernel_for(&base);
            simd::set_kernel(None).expect("default");
            k
        },
        Kernel::Portable,
        "the grid path must apply"
    );
    // The real-time drape's setting too: chain solves with two Newton iterations and two
    // rounds per sweep, and the structural limit.
    let mut rounds = drape(40, 0);
    let mut config = *rounds.config();
    config.substeps = 5;
    config.xpbd.chains = true;
    config.xpbd.chain_iterations = 2;
    config.xpbd.chain_rounds = 2;
    config.xpbd.structural_limit = Some(0.02);
    rounds.set_config(config).expect("config");
    // Chains too long for two blocks per task (a pair would not fit `chains::PAIR_BYTES`):
    // one block per task. A strip of 24 × 320 particles, the same settings.
    let mut scene = cloth_core::scene::builtin("drape").expect("built-in");
    scene.cloth.resolution = [320, 24];
    scene.solver.kind = Integrator::Xpbd.name().into();
    scene.solver.substeps = cloth_core::scene::SubstepsDesc::default();
    let mut long = scene.build().expect("strip");
    long.set_config(config).expect("config");
    for (name, base) in [
        ("levels", base),
        ("chain rounds", rounds),
        ("long chains", long),
    ] {
        let reference = trace(base.clone(), Kernel::Portable, 40);
        assert!(
            reference.2.iter().any(|&c| c > 0),
            "{name}: the cloth must touch the ball"
        );
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool");
            for &kernel in &kernels {
                let got = pool.install(|| trace(base.clone(), kernel, 40));
                assert!(
                    got == reference,
                    "{name}, {threads} threads, {kernel:?}: different bits"
                );
            }
        }
    }
}

/// Stage 1 (prediction with weight, global damping and per-triangle air drag and lift in
/// wind) runs in parallel on the grid path with the reference's operations in the
/// reference's order: with the springs off and no collider, the two paths give the same bits.
/// The grid path computes the air of its cell rows band by band (8 rows per band, the rows
/// between bands first), so sizes around the band: 2, 3, 9, 17 and 24 rows, with the portable
/// and the best kernel. Tolerance: none.
#[test]
fn grid_prediction_matches_the_reference_bit_for_bit() {
    for n in [2, 3, 9, 17, 24] {
        let mut sim = drape(n, 0);
        sim.clear_colliders();
        let mut config = *sim.config();
        config.forces.springs = false;
        config.forces.dashpots = false;
        config.air.wind = Vec3::new(2.0, 0.5, -1.0);
        sim.set_config(config).expect("config");
        // Some motion first, so that every triangle sees a different relative wind.
        for i in 0..sim.particles().len() {
            let v = Vec3::new(
                (i % 7) as f32 * 0.02,
                -((i % 5) as f32) * 0.03,
                (i % 3) as f32 * 0.01,
            );
            sim.set_velocity(i, v).expect("velocity");
        }
        let reference = trace(sim.clone(), Kernel::Reference, 10);
        for kernel in [Kernel::Portable, Kernel::best()] {
            let grid = trace(sim.clone(), kernel, 10);
            assert!(
                grid == reference,
                "{n}², {kernel:?}: prediction differs from the reference"
            );
        }
    }
}

/// The grid path and the reference path sweep in different orders (colour by colour, and
/// spring by spring), so they agree to within the solver's convergence: settled, the
/// hanging-curtain shape of each is the same static equilibrium, with the shear springs in
/// two colours of alternate rows (the default) and row by row (`xpbd.shear_rows`, on both
/// paths): only the order of the sweep changes, not the equilibrium. Tolerance 1 mm on a
/// 0.5 m curtain (0.2 %).
#[test]
fn grid_and_reference_paths_settle_to_the_same_shape() {
    let make = |shear_rows: bool| {
        let cloth = GridBuilder::new(16, 16)
            .size(0.5, 0.5)
            .orientation(Orientation::Vertical)
            .mass(Mass::ArealDensity(0.2))
            .pin_corner(cloth_core::Corner::TopLeft)
            .pin_corner(cloth_core::Corner::TopRight)
            .build()
            .expect("cloth");
        let mut config = SimConfig {
            integrator: Integrator::Xpbd,
            substeps: 40,
            damping: 5e-3,
            material: Material::isotropic(
                SpringParams::new(200.0, 0.02),
                SpringParams::new(40.0, 0.005),
                SpringParams::new(2.0, 0.001),
            ),
            ..SimConfig::default()
        };
        config.xpbd.shear_rows = shear_rows;
        Simulation::new(cloth, config).expect("sim")
    };
    let settle = |kernel: Kernel, shear_rows: bool| -> (Vec<Vec3>, f64) {
        simd::set_kernel(Some(kernel)).expect("kernel");
        let mut sim = make(shear_rows);
        for _ in 0..300 {
            sim.step().expect("stable");
        }
        let ke = sim.stats().kinetic_energy;
        simd::set_kernel(None).expect("default");
        (sim.particles().position.clone(), ke)
    };
    let distance = |a: &[Vec3], b: &[Vec3]| {
        a.iter()
            .zip(b)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0f32, f32::max)
    };
    let (colours, _) = settle(Kernel::Portable, false);
    for shear_rows in [false, true] {
        let (grid, ke_grid) = settle(Kernel::Portable, shear_rows);
        let (reference, ke_ref) = settle(Kernel::Reference, shear_rows);
        let worst = distance(&grid, &reference);
        let orders = distance(&grid, &colours);
        eprintln!(
            "shear_rows {shear_rows}: largest distance {worst:.2e} m (to the colours' grid \
             path {orders:.2e} m); KE grid {ke_grid:.2e} J, reference {ke_ref:.2e} J"
        );
        assert!(ke_grid < 1e-6 && ke_ref < 1e-6, "not settled");
        assert!(worst < 1e-3, "shapes differ by {worst} m");
        assert!(orders < 1e-3, "the row order settles {orders} m away");
    }
}

/// Multi-resolution strain limits (Wang et al. 2010): with levels up to the whole height, a
/// soft curtain hanging from its top edge is at most (1 + slack) times its rest height long,
/// however soft its springs (the limits are one-sided, inextensible constraints), on both
/// paths; without them it stretches tens of percent. Tolerance 0.5 % of the height.
#[test]
fn strain_limits_bound_the_stretch_of_a_soft_curtain() {
    let rows = 33;
    let height = 0.64;
    let stretch = |levels: u32, kernel: Kernel| -> f32 {
        let (cloth, mut config) = curtain(2.0, 10);
        config.xpbd.hierarchy_levels = levels;
        config.xpbd.hierarchy_slack = 0.02;
        simd::set_kernel(Some(kernel)).expect("kernel");
        let mut sim = Simulation::new(cloth, config).expect("sim");
        for _ in 0..240 {
            sim.step().expect("stable");
        }
        simd::set_kernel(None).expect("default");
        let p = &sim.particles().position;
        (0..9)
            .map(|c| (p[c].distance(p[(rows - 1) * 9 + c]) - height) / height)
            .fold(f32::MIN, f32::max)
    };
    let free = stretch(0, Kernel::Portable);
    eprintln!("no limits: column strain {:.2}%", 100.0 * free);
    assert!(
        free > 0.2,
        "the soft curtain must stretch without limits ({free})"
    );
    for kernel in [Kernel::Portable, Kernel::Reference] {
        let limited = stretch(5, kernel);
        eprintln!(
            "limits to 32 rows, {kernel:?}: column strain {:.3}%",
            100.0 * limited
        );
        assert!(limited <= 0.02 + 0.005, "{kernel:?}: {limited}");
    }
}

/// The largest strain (|L| − L0)/L0 of the warp and weft springs of `sim`.
fn max_structural_strain(sim: &Simulation) -> f32 {
    let p = &sim.particles().position;
    let t = sim.topology();
    [SpringKind::Warp, SpringKind::Weft]
        .into_iter()
        .flat_map(|k| t.springs_of(k))
        .map(|s| (p[s.a as usize].distance(p[s.b as usize]) - s.rest_length) / s.rest_length)
        .fold(f32::MIN, f32::max)
}

/// A curtain of 33 × 9 particles (0.16 m × 0.64 m, 0.2 kg/m²) hanging from its top edge,
/// with warp and weft of stiffness `k` (N/m) and soft shear, for XPBD with `substeps`.
fn curtain(k: f32, substeps: u32) -> (Cloth, SimConfig) {
    let cloth = GridBuilder::new(33, 9)
        .size(0.16, 0.64)
        .orientation(Orientation::Vertical)
        .mass(Mass::ArealDensity(0.2))
        .pin_edge(Edge::Top)
        .build()
        .expect("cloth");
    let config = SimConfig {
        integrator: Integrator::Xpbd,
        substeps,
        damping: 0.01,
        material: Material::isotropic(
            SpringParams::new(k, 0.0),
            SpringParams::new(0.5, 0.0),
            SpringParams::new(0.0, 0.0),
        ),
        ..SimConfig::default()
    };
    (cloth, config)
}

/// [`curtain`] with 40 substeps and `limit` as the structural strain limit.
fn limited_curtain(k: f32, limit: Option<f32>) -> Simulation {
    let (cloth, mut config) = curtain(k, 40);
    config.xpbd.structural_limit = limit;
    Simulation::new(cloth, config).expect("sim")
}

/// The structural strain limit (Provot 1995; `xpbd.structural_limit`) is a one-sided,
/// inextensible constraint on every warp and weft spring: a soft curtain (k = 2 N/m, which
/// stretches its warp by tens of percent without it) keeps every structural spring within
/// (1 + 0.05)·L0 after every step, on the grid path with every kernel and on the reference
/// path. The limit is projected once per substep by Gauss–Seidel, and the curtain's weight
/// pulls its 32-spring columns again every substep, so what is left over the limit is the
/// sweep's residual: with 40 substeps (g·h² = 6 µm per substep) it stays within 0.5 % of
/// strain, the tolerance (with 10 substeps it is about 7 %: a long loaded chain needs the
/// chains or the multi-resolution levels to carry its load). And a cloth whose springs stay
/// within the limit is left as it is: a stiff curtain (k = 4000 N/m) gives the same bits
/// with and without a 50 % limit.
#[test]
fn structural_limit_bounds_every_warp_and_weft_spring() {
    let free = {
        let mut sim = limited_curtain(2.0, None);
        for _ in 0..120 {
            sim.step().expect("stable");
        }
        max_structural_strain(&sim)
    };
    eprintln!("no limit: largest structural strain {:.2}%", 100.0 * free);
    assert!(
        free > 0.2,
        "the soft curtain must stretch without a limit ({free})"
    );
    let kernels = [
        Kernel::Portable,
        Kernel::Avx2,
        Kernel::Avx512,
        Kernel::Reference,
    ];
    for kernel in kernels.into_iter().filter(|k| k.is_available()) {
        simd::set_kernel(Some(kernel)).expect("kernel");
        let mut sim = limited_curtain(2.0, Some(0.05));
        let mut worst = f32::MIN;
        for _ in 0..120 {
            sim.step().expect("stable");
            worst = worst.max(max_structural_strain(&sim));
        }
        simd::set_kernel(None).expect("default");
        eprintln!(
            "limit 5 %, {kernel:?}: largest structural strain {:.3}%",
            100.0 * worst
        );
        assert!(worst <= 0.05 + 0.005, "{kernel:?}: {worst}");
        assert!(
            worst > 0.04,
            "{kernel:?}: the limit must be reached ({worst})"
        );
    }
    for kernel in [Kernel::Portable, Kernel::Reference] {
        simd::set_kernel(Some(kernel)).expect("kernel");
        let run = |limit| {
            let mut sim = limited_curtain(4000.0, limit);
            for _ in 0..60 {
                sim.step().expect("stable");
            }
            assert!(max_structural_strain(&sim) < 0.5);
            bits(&sim.particles().position)
        };
        let (with, without) = (run(Some(0.5)), run(None));
        simd::set_kernel(None).expect("default");
        assert!(
            with == without,
            "{kernel:?}: a limit never reached changed the bits"
        );
    }
}

/// `strain_quantiles` is a nearest-rank quantile of (|L| − L0)/L0: at rest every spring has
/// zero strain; stretching the whole cloth uniformly by 3 % gives 3 % at every quantile.
/// Tolerance 1e-5.
#[test]
fn strain_quantiles_measure_uniform_stretch() {
    let sim = presets::drape(10, Integrator::Xpbd).expect("drape");
    let q = [0.5, 0.999, 1.0];
    let at_rest = strain_quantiles(
        sim.topology(),
        &sim.particles().position,
        SpringClass::Structural,
        &q,
    )
    .expect("structural springs");
    assert!(at_rest.iter().all(|s| s.abs() < 1e-5), "{at_rest:?}");
    let scaled: Vec<Vec3> = sim.particles().position.iter().map(|p| *p * 1.03).collect();
    let got = strain_quantiles(sim.topology(), &scaled, SpringClass::Structural, &q)
        .expect("structural springs");
    assert!(got.iter().all(|s| (s - 0.03).abs() < 1e-5), "{got:?}");
}

/// Contacts on the grid path: the drape settles on the ball with friction and never
/// penetrates deeper than the contact layer. Tolerance: the thickness (8 mm).
#[test]
fn grid_path_drapes_without_penetration() {
    let mut sim = drape(32, 3);
    sim.set_collider(
        0,
        Collider::sphere(Vec3::ZERO, 0.3)
            .with_thickness(0.008)
            .with_friction(Friction::new(0.6, 0.5)),
    )
    .expect("ball");
    let mut worst = 0.0f32;
    for _ in 0..120 {
        let s = sim.step().expect("stable");
        worst = worst.max(s.max_penetration);
    }
    eprintln!("deepest penetration {worst:.2e} m");
    assert!(worst < 0.008, "{worst}");
    assert!(sim.stats().contacts > 0);
}

/// Issue 7's real-time drape at 256² with the README's setting: XPBD with 3 substeps, chain
/// solves of 2 Newton iterations, 2 chain rounds per sweep, the shear springs swept row by row
/// (`xpbd.shear_rows`) and the 2 % structural limit, the scene's global damping
/// scaled by (48/256)² as `scripts/realtime-series.sh` does. Over 3 s the cloth falls onto the
/// ball and settles. Once draped (the second half of the run) no warp or weft spring is
/// stretched by 10 % or more; at the end the 99.9th percentile of their strain is under 5 %; no
/// particle goes deeper into a collider than its thickness.
/// Tolerances: the issue's figures (p99.9 < 5 %, max < 10 %, penetration < 8 mm).
#[test]
fn real_time_drape_setting_meets_the_strain_figures_at_256() {
    let figures = drape_figures(presets::realtime_drape(256, 3, 2, 1.0).expect("drape"));
    assert_issue_figures("256² 3 × 2 × 2", figures);
}

/// Issue 7's real-time drape at 512² with the README's setting: as at 256² above, with 4
/// substeps of 4 chain rounds whose solves are over-relaxed by ω = 1.3
/// (`xpbd.chain_relaxation`; the damping scaled by (48/512)²). With fewer substeps the 512²
/// cloth needs more chain rounds in each to hold its strain where it lands on the ball; the
/// over-relaxed rounds hold it with one round fewer (measured 7.4 %, p99.9 1.6 %).
/// Tolerances: the issue's figures (p99.9 < 5 %, max < 10 %, penetration < 8 mm).
#[test]
fn real_time_drape_setting_meets_the_strain_figures_at_512() {
    let figures = drape_figures(presets::realtime_drape(512, 4, 4, 1.3).expect("drape"));
    assert_issue_figures("512² 4 × 4 × 2, relaxation 1.3", figures);
}

/// Over-relaxation is what lets four rounds hold the 512² drape: the setting above with the
/// plain Newton step (ω = 1) leaves the settled maximum far past 10 % (measured 270 %, the cap
/// on the ball stretched where the cloth landed), and needs a fifth round (measured 6.3 %,
/// p99.9 1.1 %), which still meets the figures.
/// Tolerances: 10 % (the plain step's miss at four rounds); the issue's figures at five.
#[test]
fn plain_chain_steps_need_five_rounds_at_512_where_relaxed_need_four() {
    let (_, at_four, _) = drape_figures(presets::realtime_drape(512, 4, 4, 1.0).expect("drape"));
    assert!(
        at_four > 0.10,
        "512² 4 × 4 × 2, plain step: settled structural maximum {at_four}"
    );
    let figures = drape_figures(presets::realtime_drape(512, 4, 5, 1.0).expect("drape"));
    assert_issue_figures("512² 4 × 5 × 2, plain step", figures);
}

/// The order of the shear sweep is what lets the setting above meet the figures: the same
/// drape (3 substeps of two chain rounds of two Newton iterations, the 2 % limit) with the
/// shear springs swept in two colours of alternate rows (`xpbd.shear_rows = false`, the
/// default) leaves the shear pass and the chain solves undoing one another on the
/// ball, and the settled maximum far past 10 % (measured 182 % against 8.8 % row by row). The
/// colours needed 5 substeps (measured 7.0 %), which still meet the figures.
/// Tolerances: 10 % (the colours' miss at 3 substeps); the issue's figures at 5.
#[test]
fn shear_colours_need_five_substeps_at_256_where_rows_need_three() {
    let colours = |substeps: u32| {
        let mut sim = presets::realtime_drape(256, substeps, 2, 1.0).expect("drape");
        let mut config = *sim.config();
        config.xpbd.shear_rows = false;
        sim.set_config(config).expect("config");
        drape_figures(sim)
    };
    let (_, at_three, _) = colours(3);
    assert!(
        at_three > 0.10,
        "colours at 3 substeps: settled structural maximum {at_three}"
    );
    assert_issue_figures("colours at 5", colours(5));
}

/// Issue 7's figures for [`drape_figures`]' `(p99.9, settled maximum, deepest penetration)`:
/// the structural strain's 99.9th percentile under 5 %, its settled maximum under 10 %, no
/// penetration as deep as the contact layer (8 mm).
fn assert_issue_figures(what: &str, (p999, late_max, deepest): (f32, f32, f32)) {
    assert!(p999 < 0.05, "{what}: p99.9 structural strain {p999}");
    assert!(
        late_max < 0.10,
        "{what}: settled structural maximum {late_max}"
    );
    assert!(deepest < 0.008, "{what}: penetration {deepest}");
}

/// 3 s (180 frames) of a drape: the 99.9th percentile of the structural strain at the end,
/// the largest structural strain over the second half, and the deepest penetration.
fn drape_figures(mut sim: Simulation) -> (f32, f32, f32) {
    let frames = 180;
    let (mut late_max, mut deepest) = (0.0_f32, 0.0_f32);
    for frame in 0..frames {
        let s = sim.step().expect("stable");
        if frame >= frames / 2 {
            late_max = late_max.max(s.strain(SpringClass::Structural));
        }
        deepest = deepest.max(s.max_penetration);
    }
    let p999 = strain_quantiles(
        sim.topology(),
        &sim.particles().position,
        SpringClass::Structural,
        &[0.999],
    )
    .expect("structural springs")[0];
    eprintln!("p99.9 {p999:.4}, settled max {late_max:.4}, deepest {deepest:.2e} m");
    (p999, late_max, deepest)
}
