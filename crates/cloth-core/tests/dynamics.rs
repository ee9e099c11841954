//! Dynamics tests: each checks a physical law (or the exact discrete law an integrator is
//! documented to follow) against an analytic value, with a stated tolerance.
//!
//! Two-particle systems are built as a 2×2 grid with only the weft springs active: particles
//! 0–1 (row 0) and 2–3 (row 1) then form two independent oscillators along x. Row 1 is left
//! unstretched and at rest, so it contributes nothing; particle 1 is displaced along +x, so
//! the spring 0–1 stays on the x axis and its force is exactly linear in the extension.
//!
//! Run with `--nocapture` to see the measured numbers.

mod common;
use common::*;

use std::f64::consts::TAU;

use cloth_core::glam::Vec3;
use cloth_core::{
    GridBuilder, Integrator, Mass, Material, SimConfig, Simulation, SpringClass, SpringKind,
    StepStats,
};

/// The three explicit integrators, named one by one: the laws below are theirs, and
/// `Integrator` is `#[non_exhaustive]`, so `Integrator::ALL` may grow to solvers these exact
/// discretisation formulas do not describe.
const EXPLICIT: [Integrator; 3] = [
    Integrator::ForwardEuler,
    Integrator::SymplecticEuler,
    Integrator::Verlet,
];

/// Kinetic + elastic energy from a step's diagnostics, J.
fn mech_energy(s: &StepStats) -> f64 {
    s.kinetic_energy + s.spring_energy
}

/// Kinetic + elastic energy of the current state, J, computed exactly as `StepStats` does
/// (f32 spring lengths, f64 sums). Needed for the initial state: `Simulation::stats()` is
/// only refreshed by `new`, `set_config`, collider changes and `step`, not by
/// `set_position`/`set_velocity`, so after those it still describes the built cloth.
fn energy_now(sim: &Simulation) -> f64 {
    let p = sim.particles();
    let kinetic: f64 = p
        .mass
        .iter()
        .zip(&p.velocity)
        .map(|(&m, v)| 0.5 * f64::from(m) * f64::from(v.length_squared()))
        .sum();
    let mut elastic = 0.0;
    for kind in SpringKind::ALL {
        let k = f64::from(sim.config().material.params(kind).stiffness);
        for s in sim.topology().springs_of(kind) {
            let len = p.position[s.a as usize].distance(p.position[s.b as usize]);
            elastic += 0.5 * k * f64::from(len - s.rest_length).powi(2);
        }
    }
    kinetic + elastic
}

/// Period of the sampled linear oscillator produced by symplectic Euler and by position
/// Verlet: both have an amplification matrix of determinant 1 and trace 2 − (ωh)², so their
/// samples are exact sinusoids of frequency Ω with cos(Ωh) = 1 − (ωh)²/2.
fn discrete_period(omega: f64, h: f64) -> f64 {
    let wh = omega * h;
    TAU * h / (1.0 - 0.5 * wh * wh).acos()
}

// ---------------------------------------------------------------------------------------
// 1. Harmonic oscillator period
// ---------------------------------------------------------------------------------------

/// Two particles (m₁ = 0.1 kg, m₂ = 0.3 kg) on a spring k = 100 N/m oscillate with period
/// T = 2π√(μ/k), μ = m₁m₂/(m₁+m₂) (reduced mass); with particle 0 pinned the period is
/// 2π√(m₂/k). Checked for symplectic Euler and Verlet, period measured from the zero
/// crossings of |L| − L0 over 10 periods.
///
/// Tolerances:
/// - at h = T/200 the measured period is within 0.1 % of T (tighter than the usual 1 %):
///   both integrators' period error is (ωh)²/24 ≈ 4·10⁻⁵, the interpolation error over 20
///   crossings is far below that, and f32 rounding of a 5 cm extension is ~10⁻⁶;
/// - at a coarse h = T/20 the period must equal the *discrete* period
///   2πh / arccos(1 − (ωh)²/2) within 2·10⁻⁴, while the continuous T is ≈ 0.4 % away: the test
///   resolves the integrators' exact dispersion, not just "roughly T".
#[test]
fn oscillator_period_matches_reduced_mass_formula() {
    let k = 100.0_f32;
    let cases: [(&str, f32, f32, bool); 2] =
        [("free pair", 0.1, 0.3, false), ("pinned", 0.1, 0.3, true)];
    for integrator in [Integrator::SymplecticEuler, Integrator::Verlet] {
        for (label, m_a, m_b, pinned) in cases {
            let mu = if pinned {
                f64::from(m_b)
            } else {
                f64::from(m_a) * f64::from(m_b) / f64::from(m_a + m_b)
            };
            let omega = (f64::from(k) / mu).sqrt();
            let period = TAU / omega;
            for (steps_per_period, periods) in [(200_usize, 10_usize), (20, 40)] {
                let h = (period / steps_per_period as f64) as f32;
                let hd = f64::from(h);
                let mut sim = oscillator(m_a, m_b, k, 0.0, h, integrator, 0.05);
                if pinned {
                    sim.pin(0).unwrap();
                }
                let mut ext = vec![extension(&sim)];
                for _ in 0..steps_per_period * periods {
                    sim.step().unwrap();
                    ext.push(extension(&sim));
                }
                let (measured, crossings) = zero_crossing_period(&ext, hd);
                let discrete = discrete_period(omega, hd);
                let rel_cont = measured / period - 1.0;
                let rel_disc = measured / discrete - 1.0;
                eprintln!(
                    "{:>16} {label:>9} h=T/{steps_per_period:<3}: T = {period:.6} s, \
                     discrete {discrete:.6} s, measured {measured:.6} s ({crossings} crossings); \
                     rel. err vs T {rel_cont:+.2e}, vs discrete {rel_disc:+.2e}",
                    integrator.name()
                );
                if steps_per_period == 200 {
                    assert!(
                        rel_cont.abs() < 1e-3,
                        "{} {label}: period {measured} vs 2π√(μ/k) = {period}",
                        integrator.name()
                    );
                } else {
                    assert!(
                        rel_disc.abs() < 2e-4,
                        "{} {label}: period {measured} vs discrete {discrete}",
                        integrator.name()
                    );
                    assert!(
                        rel_cont.abs() > 3e-3,
                        "{} {label}: coarse-step period {measured} should show the \
                         discrete dispersion vs {period}",
                        integrator.name()
                    );
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// 2. Energy behaviour of the integrators on the undamped oscillator
// ---------------------------------------------------------------------------------------

/// Forward Euler on the undamped oscillator: the energy ½μv² + ½ke² is multiplied by exactly
/// 1 + (ωh)² every step (the amplification matrix [[1, h], [−ω²h, 1]] scales the energy norm
/// by that factor for every state). Here ωh = 2π/200, so (ωh)² ≈ 9.9·10⁻⁴; the oscillator
/// starts at rest stretched by A = 0.3 m (the force stays exactly linear: the spring lies on
/// the x axis and never reaches zero length).
///
/// Asserts: the energy strictly increases at every one of 1000 steps; each per-step growth
/// E_{n+1}/E_n − 1 is within 2 % of (ωh)² (f32 rounding of |L| ≈ 1.3 m is ~10⁻⁷ m, i.e.
/// ~10⁻⁶ of the energy per step, 0.1 % of the growth); the growth rate averaged over the run,
/// (E_N/E_0)^{1/N} − 1, is within 10⁻³ of (ωh)² (the rounding errors of the two end values
/// are divided by N·(ωh)² ≈ 1).
#[test]
fn forward_euler_energy_grows_by_one_plus_omega_h_squared() {
    let (m_a, m_b, k) = (0.1_f32, 0.3_f32, 100.0_f32);
    let mu = f64::from(m_a) * f64::from(m_b) / f64::from(m_a + m_b);
    let omega = (f64::from(k) / mu).sqrt();
    let h = (TAU / omega / 200.0) as f32;
    let wh2 = (omega * f64::from(h)).powi(2);
    let mut sim = oscillator(m_a, m_b, k, 0.0, h, Integrator::ForwardEuler, 0.3);
    let e0 = energy_now(&sim);
    // ½kA², up to the f32 rounding of the stretched position (≤ ulp(0.8)/A ≈ 2·10⁻⁷ of A).
    assert!((e0 - 0.5 * f64::from(k) * 0.09).abs() < 1e-5 * e0);
    let steps = 1000;
    let mut prev = e0;
    let mut worst_step_dev: f64 = 0.0;
    for n in 0..steps {
        let e = mech_energy(&sim.step().unwrap());
        assert!(
            e > prev,
            "step {n}: energy {e} did not increase from {prev}"
        );
        let growth = e / prev - 1.0;
        worst_step_dev = worst_step_dev.max((growth / wh2 - 1.0).abs());
        prev = e;
    }
    let mean_growth = (prev / e0).powf(1.0 / f64::from(steps)) - 1.0;
    eprintln!(
        "forward Euler: (ωh)² = {wh2:.6e}, mean growth/step = {mean_growth:.6e} \
         (rel. dev {:+.2e}), worst single-step rel. dev {worst_step_dev:.2e}, \
         E_N/E_0 = {:.4}",
        mean_growth / wh2 - 1.0,
        prev / e0
    );
    assert!(
        worst_step_dev < 0.02,
        "per-step growth off by {worst_step_dev}"
    );
    assert!(
        (mean_growth / wh2 - 1.0).abs() < 1e-3,
        "mean growth {mean_growth} vs (ωh)² = {wh2}"
    );
}

/// Symplectic Euler and Verlet do not drift: on the undamped oscillator each conserves an
/// exact quadratic invariant, so the true energy stays in a fixed band for ever.
/// - Symplectic Euler conserves Q = ½μv² + ½ke² − ½hk·e·v; started at rest (v = 0) the energy
///   E = E₀ + ½hk·e·v stays in [E₀/(1 + ωh/2), E₀/(1 − ωh/2)], and reaches both ends every
///   period: max |E/E₀ − 1| = (ωh/2)/(1 − ωh/2).
/// - Position Verlet conserves ½k e² + ½μ(1 − (ωh)²/4)v²; started at rest the energy is
///   E = E₀ + (μ(ωh)²/8)v², whose largest value is E₀(1 + (ωh)²/(4 − (ωh)²)).
///
/// Same oscillator as the forward-Euler test (ωh = 2π/200, A = 0.3 m), N = 4000 steps (20
/// periods). In f32 the invariants themselves random-walk: each step rounds positions of
/// magnitude ≤ 1 + A by half an ulp, ≈ 2⁻²⁴(1 + A)/A of the amplitude, so the energy wanders
/// by about `noise` = 2√N·2⁻²⁴(1 + A)/A ≈ 3·10⁻⁵ (measured: ~10⁻⁵). Asserts:
/// - the largest |E/E₀ − 1| equals the predicted band edge within 2 % + `noise` (the band is
///   sampled 200 times a period, so its edge is hit to ~10⁻³ of its width). For symplectic
///   Euler (band 1.6 %) this is a 2 % check; for Verlet (band 2.5·10⁻⁴) ≈ 15 %, still enough
///   to tell (ωh)²/4 from ωh/2 or from 0;
/// - no drift: the band's upper edge over the last period equals that over the first within
///   `noise` (forward Euler's energy grows e⁴-fold over the same run).
#[test]
fn symplectic_integrators_keep_energy_in_exact_band_without_drift() {
    let (m_a, m_b, k) = (0.1_f32, 0.3_f32, 100.0_f32);
    let mu = f64::from(m_a) * f64::from(m_b) / f64::from(m_a + m_b);
    let omega = (f64::from(k) / mu).sqrt();
    let steps_per_period = 200;
    let h = (TAU / omega / steps_per_period as f64) as f32;
    let wh = omega * f64::from(h);
    let amp = 0.3;
    for integrator in [Integrator::SymplecticEuler, Integrator::Verlet] {
        let band = match integrator {
            Integrator::SymplecticEuler => 0.5 * wh / (1.0 - 0.5 * wh),
            Integrator::Verlet => wh * wh / (4.0 - wh * wh),
            other => unreachable!("{other:?}"),
        };
        let mut sim = oscillator(m_a, m_b, k, 0.0, h, integrator, amp as f32);
        let e0 = energy_now(&sim);
        let rel: Vec<f64> = (0..20 * steps_per_period)
            .map(|_| mech_energy(&sim.step().unwrap()) / e0 - 1.0)
            .collect();
        let max_dev = rel.iter().fold(0.0_f64, |a, &r| a.max(r.abs()));
        let noise = 2.0 * (rel.len() as f64).sqrt() * EPS32 * (1.0 + amp) / amp;
        let upper = |s: &[f64]| s.iter().copied().fold(f64::MIN, f64::max);
        let first = upper(&rel[..steps_per_period]);
        let last = upper(&rel[rel.len() - steps_per_period..]);
        eprintln!(
            "{:>16}: ωh = {wh:.4e}, predicted band {band:.4e}, measured max |E/E0−1| = \
             {max_dev:.4e} (ratio {:.4}); band top first period {first:.4e}, last {last:.4e}; \
             noise allowance {noise:.2e}",
            integrator.name(),
            max_dev / band
        );
        assert!(
            (max_dev - band).abs() <= 0.02 * band + noise,
            "{}: energy band {max_dev} vs predicted {band}",
            integrator.name()
        );
        assert!(
            (last - first).abs() <= noise,
            "{}: energy drifted: band top {first} → {last}",
            integrator.name()
        );
    }
}

// ---------------------------------------------------------------------------------------
// 3. Free fall
// ---------------------------------------------------------------------------------------

/// A 4×4 cloth thrown with one velocity v₀ = (0.3, 2, −0.5) m/s under gravity only (no
/// damping or air; springs and dashpots on but unstretched — the default material, a softer
/// one for forward Euler, see below) falls as a rigid body. After n
/// substeps of h = 1/512 s (t = nh = 1 s), every particle's and the centre of mass's
/// displacement along y is the integrator's exact discretisation of y₀ + v₀t − ½gt²:
/// - Verlet (drift–kick–drift): exactly v₀t − ½gt² (exact for constant acceleration);
/// - symplectic Euler: v₀t − gh²·n(n+1)/2;
/// - forward Euler: v₀t − gh²·n(n−1)/2;
///
/// and x, z move by exactly v₀t. Tolerance: a bound on f32 rounding,
/// n·2⁻²⁴·(2·max|y| + t·max|v|) ≈ 3·10⁻⁴ m (each of the ≤ 2n position updates rounds by at most
/// half an ulp of |y|, each of the n velocity updates by half an ulp of |v|, which then acts
/// for ≤ t); the three formulas differ by ½ght ≈ 10⁻² m, 30× more, so the test tells them apart.
/// Also asserts the deviation from the continuous ½gt² is at most ½ght (+ the same rounding)
/// and that no spring's strain exceeds 10⁻⁵ (a translating cloth has no strain; the bound is
/// ~10 ulps of the coordinates relative to the 1/3 m rest length).
#[test]
fn free_fall_follows_each_integrators_exact_discretisation() {
    let v0 = Vec3::new(0.3, 2.0, -0.5);
    let substeps = 8_u32;
    let steps = 64_u32;
    for integrator in EXPLICIT {
        // Forward Euler amplifies the rounding noise of the spring lengths unless every mode's
        // dashpot damping beats its (ωh)² energy gain, which needs c/k > h for each kind: the
        // default 500 N/m with 0.1 N·s/m does not (strains grow to ~2·10⁻⁴ within 1 s), a
        // 40 N/m fabric does. The symplectic integrators keep the stiff default material.
        let material = if integrator == Integrator::ForwardEuler {
            SOFT_FABRIC
        } else {
            Material::default()
        };
        let mut sim = thrown_cloth(v0, integrator, substeps, material);
        assert_eq!(sim.config().substep_dt(), 1.0 / 512.0);
        let com0 = com(&sim);
        let mut max_strain: f64 = 0.0;
        let mut max_stat_strain: f32 = 0.0;
        let fall = FreeFall::run(&mut sim, steps, |sim, s| {
            max_stat_strain = max_stat_strain.max(s.strain(SpringClass::Structural));
            max_strain = max_strain.max(abs_strain(sim));
        });
        let (n, h, g, t) = (fall.n, fall.h, fall.g, fall.t());
        let continuous = f64::from(v0.y) * t - 0.5 * g * t * t;
        let expected = match integrator {
            Integrator::Verlet => continuous,
            Integrator::SymplecticEuler => f64::from(v0.y) * t - g * h * h * n * (n + 1.0) / 2.0,
            Integrator::ForwardEuler => f64::from(v0.y) * t - g * h * h * n * (n - 1.0) / 2.0,
            other => unreachable!("{other:?}"),
        };
        let tol = fall.rounding_bound(v0);
        let dcom = com(&sim) - com0;
        let worst = fall.worst_particle_error(&sim, v0, expected);
        eprintln!(
            "{:>16}: Δy_com = {:.9} m, expected {expected:.9} m (continuous {continuous:.9}, \
             ½ght = {:.3e}); com err {:.2e}, worst particle err {worst:.2e}, tol {tol:.2e}; \
             max |strain| {max_strain:.2e} (StepStats structural {max_stat_strain:.2e})",
            integrator.name(),
            dcom.y,
            0.5 * g * h * t,
            (dcom.y - expected).abs()
        );
        assert!(
            (dcom.y - expected).abs() <= tol,
            "{}: com Δy {} vs {expected}",
            integrator.name(),
            dcom.y
        );
        assert!((dcom.x - f64::from(v0.x) * t).abs() <= tol);
        assert!((dcom.z - f64::from(v0.z) * t).abs() <= tol);
        assert!(
            worst <= tol,
            "{}: worst particle error {worst}",
            integrator.name()
        );
        assert!(
            (dcom.y - continuous).abs() <= 0.5 * g * h * t + tol,
            "{}: deviation from ½gt² exceeds ½ght",
            integrator.name()
        );
        assert!(
            max_strain < 1e-5,
            "{}: strain {max_strain}",
            integrator.name()
        );
        assert!(
            max_stat_strain < 1e-5,
            "{}: StepStats strain {max_stat_strain}",
            integrator.name()
        );
    }
}

// ---------------------------------------------------------------------------------------
// 4. Momentum conservation
// ---------------------------------------------------------------------------------------

/// Newton's third law makes the springs and dashpots internal forces: with no gravity,
/// global damping, air or colliders, total momentum Σmv is conserved exactly. An 8×8 cloth
/// (0.05 kg per particle, default material) with random velocities (|vᵢ| components ≤ 1 m/s)
/// and random position perturbations (≤ 1 cm, so springs are stretched and compressed) is
/// run for 500 substeps of 1/6000 s with each explicit integrator.
///
/// Tolerance: |P − P₀| ≤ 2N·2⁻²⁴·max Σm|v| (N = 500 substeps): each substep's velocity
/// update rounds every particle's momentum by ~half an ulp, and the per-spring ±f pairs cancel
/// only up to the rounding of their accumulation; ≈ 6·10⁻⁵ of Σm|v|. (A lost momentum of
/// one part in 10⁴ — any one-sided force — would fail it.)
#[test]
fn internal_forces_conserve_momentum() {
    for integrator in EXPLICIT {
        let cloth = GridBuilder::new(8, 8)
            .size(1.0, 1.0)
            .mass(Mass::PerParticle(0.05))
            .build()
            .unwrap();
        let config = SimConfig {
            dt: 1.0 / 600.0,
            substeps: 10,
            integrator,
            forces: internal_forces_only(),
            ..SimConfig::default()
        };
        let mut sim = Simulation::new(cloth, config).unwrap();
        let mut rng = Lcg(0x5EED_C10E);
        for i in 0..sim.particles().len() {
            let x = sim.particles().position[i];
            sim.set_position(i, x + 0.01 * rng.next_vec()).unwrap();
            sim.set_velocity(i, rng.next_vec()).unwrap();
        }
        let p0 = sim.particles().momentum().as_dvec3();
        let scale = |sim: &Simulation| -> f64 {
            let p = sim.particles();
            p.mass
                .iter()
                .zip(&p.velocity)
                .map(|(&m, v)| f64::from(m) * f64::from(v.length()))
                .sum()
        };
        let mut max_scale = scale(&sim);
        let mut worst: f64 = 0.0;
        for _ in 0..50 {
            sim.step().unwrap();
            max_scale = max_scale.max(scale(&sim));
            worst = worst.max((sim.particles().momentum().as_dvec3() - p0).length());
        }
        let n = 500.0;
        let tol = 2.0 * n * EPS32 * max_scale;
        eprintln!(
            "{:>16}: P0 = {p0:.6}, max |P − P0| = {worst:.3e} kg·m/s, Σm|v| ≤ {max_scale:.4}, \
             rel {:.2e}, tol {tol:.2e}; max strain after {:.3}",
            integrator.name(),
            worst / max_scale,
            abs_strain(&sim)
        );
        assert!(
            p0.length() > 0.05 * max_scale,
            "initial momentum too small to test"
        );
        assert!(abs_strain(&sim) > 1e-3, "springs should be working");
        assert!(
            worst <= tol,
            "{}: momentum changed by {worst} (tol {tol})",
            integrator.name()
        );
    }
}

// ---------------------------------------------------------------------------------------
// 5. Air drag
// ---------------------------------------------------------------------------------------

/// A flat horizontal 3×3 cloth (1 m², 8 equal triangles) falls in still air (ρ = 1.2 kg/m³,
/// C_d = 1, C_l = 0) under gravity. Terminal velocity: weight = drag,
/// Mg = ½ρC_dAv_t² ⇒ v_t = √(2Mg/(ρC_dA)) (M = 0.24 kg ⇒ v_t ≈ 1.98 m/s, time constant
/// τ = v_t/g ≈ 0.2 s). Each triangle's force is shared equally by its corners, so the
/// masses are set proportional to the number of triangles a particle belongs to: then every
/// particle has the same acceleration and the cloth falls exactly flat. The springs (a soft
/// 40 N/m fabric with 0.1 N·s/m dashpots, so that even forward Euler damps the rounding noise:
/// c/k > h) carry no load.
///
/// Started at rest and at 3v_t (so approached from both sides), run 3 s = 15τ with each
/// integrator. Tolerance 10⁻⁴ relative (much tighter than the 2 % one might expect): a steady
/// state of any of these explicit integrators has a(v) = 0 exactly, so the discrete terminal
/// velocity is the analytic one; what remains is the tanh convergence (2e⁻³⁰) and f32
/// stagnation: v stops changing once h·a is below half an ulp of v, which leaves
/// |v/v_t − 1| ≤ ulp(v)/(4hg) ≈ 6·10⁻⁶. Also asserts the cloth stays flat (y spread < 10⁻⁵ m).
#[test]
fn flat_cloth_reaches_drag_terminal_velocity() {
    let total_mass = 0.24_f32;
    for integrator in EXPLICIT {
        for start_factor in [0.0_f32, 3.0] {
            let cloth = flat_air_cloth(total_mass);
            let tris = cloth.topology.triangles().to_vec();
            let area: f64 = tris
                .iter()
                .map(|t| {
                    let x = |j: usize| cloth.particles.position[t[j] as usize].as_dvec3();
                    0.5 * (x(1) - x(0)).cross(x(2) - x(0)).length()
                })
                .sum();
            let config = air_config(integrator, 16, Vec3::ZERO, true);
            let (rho, cd) = (config.air.density, config.air.drag_coefficient);
            let g = -f64::from(config.gravity.y);
            let m = f64::from(cloth.particles.total_mass());
            let vt = (2.0 * m * g / (f64::from(rho) * f64::from(cd) * area)).sqrt();
            let mut sim = Simulation::new(cloth, config).unwrap();
            for i in 0..sim.particles().len() {
                sim.set_velocity(i, Vec3::new(0.0, -start_factor * vt as f32, 0.0))
                    .unwrap();
            }
            for _ in 0..180 {
                sim.step().unwrap();
            }
            let p = sim.particles();
            let v = -f64::from(p.momentum().y) / m;
            let ys = p.position.iter().map(|x| f64::from(x.y));
            let spread = ys.clone().fold(f64::MIN, f64::max) - ys.fold(f64::MAX, f64::min);
            eprintln!(
                "{:>16} from {start_factor}·v_t: A = {area:.6} m², v_t = {vt:.6} m/s, measured \
                 {v:.6} m/s (rel {:+.2e}), y spread {spread:.1e} m",
                integrator.name(),
                v / vt - 1.0
            );
            assert!(
                (v / vt - 1.0).abs() < 1e-4,
                "{}: terminal velocity {v} vs {vt}",
                integrator.name()
            );
            assert!(spread < 1e-5, "cloth did not stay flat: {spread}");
        }
    }
}

/// `triangle_air_force` against the formulas of `Air`'s docs, for a right triangle of area
/// 0.5 m² in the XZ plane with normal +Y, ρ = 1.2, C_d = 0.8, C_l = 0.3, |v_rel| = 3 m/s
/// (q = ½ρ|v|²A = 2.7 N). Tolerance 10⁻⁶ relative (a handful of f32 operations):
/// - wind along ±n: force = ±q·C_d·n exactly (lift vanishes at normal incidence);
/// - wind in the plane: zero;
/// - wind at 45°: drag part (C_l = 0) = q·C_d·cos45°·n; lift part (C_d = 0) is perpendicular
///   to the wind with magnitude q·C_l·|cos θ|·sin θ = q·C_l/2; with both coefficients the
///   force is their sum;
/// - only the relative velocity matters: a triangle moving at −w in still air feels the same
///   force as a still triangle in wind w.
#[test]
fn triangle_air_force_matches_drag_and_lift_formulas() {
    use cloth_core::forces::triangle_air_force;
    let x = [
        Vec3::ZERO,
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::new(1.0, 0.0, 0.0),
    ];
    let n = Vec3::Y;
    let (rho, cd, cl) = (1.2_f32, 0.8_f32, 0.3_f32);
    let speed = 3.0_f32;
    let q = 0.5 * rho * speed * speed * 0.5;
    let close = |a: Vec3, b: Vec3, what: &str| {
        let err = (a - b).length();
        eprintln!("{what}: got {a}, expected {b}, |err| {err:.1e}");
        assert!(err <= 1e-6 * q, "{what}: {a} vs {b}");
    };

    let up = triangle_air_force(rho, cd, cl, x, Vec3::ZERO, speed * n);
    close(up, q * cd * n, "normal wind from below");
    let down = triangle_air_force(rho, cd, cl, x, Vec3::ZERO, -speed * n);
    close(down, -q * cd * n, "normal wind from above");
    let parallel = triangle_air_force(rho, cd, cl, x, Vec3::ZERO, speed * Vec3::X);
    close(parallel, Vec3::ZERO, "wind in the plane");

    let w45 = speed * Vec3::new(1.0, 1.0, 0.0).normalize();
    let c45 = std::f32::consts::FRAC_1_SQRT_2;
    let drag = triangle_air_force(rho, cd, 0.0, x, Vec3::ZERO, w45);
    close(drag, q * cd * c45 * n, "45° drag only");
    let lift = triangle_air_force(rho, 0.0, cl, x, Vec3::ZERO, w45);
    let along_wind = lift.dot(w45.normalize());
    eprintln!("45° lift: {lift}, component along the wind {along_wind:.1e}");
    assert!(
        along_wind.abs() <= 1e-6 * q,
        "lift not perpendicular to wind"
    );
    assert!(
        (lift.length() - q * cl * 0.5).abs() <= 1e-6 * q,
        "lift magnitude {} vs q·C_l·cosθ·sinθ = {}",
        lift.length(),
        q * cl * 0.5
    );
    let both = triangle_air_force(rho, cd, cl, x, Vec3::ZERO, w45);
    close(both, drag + lift, "drag + lift superpose");
    let moving = triangle_air_force(rho, cd, cl, x, -w45, Vec3::ZERO);
    close(moving, both, "Galilean invariance");
}

// ---------------------------------------------------------------------------------------
// 6. Dashpot dissipation
// ---------------------------------------------------------------------------------------

/// Two particles (0.1 and 0.3 kg) on a spring k = 100 N/m with a dashpot c set for damping
/// ratio ζ = c/(2μω) = 0.05, nothing else acting, symplectic Euler at h = T/200, started at
/// rest stretched by 5 cm, 1300 steps (6.5 periods).
///
/// 1. The dashpot only dissipates: the energy ½m₁v₁² + ½m₂v₂² + ½ke² strictly decreases at
///    every step. Symplectic Euler's own energy wobble adds ½hω²(v² − ω²e²) per unit time
///    (per unit reduced mass), which the dashpot's −(c/μ)v² outweighs when c/μ > ½hω², i.e.
///    ζ > ωh/4 ≈ 0.008; ζ = 0.05 leaves a 6× margin. The slowest decrease, at the turning
///    points, is then ≈ (ωh)² ≈ 10⁻³ of E per step; asserted > ½(ωh)² (f32 rounding of the
///    energy is ~10⁻⁵ of E).
/// 2. It decays at the analytic rate: successive maxima of the extension shrink by the
///    logarithmic decrement δ = 2πζ/√(1 − ζ²) per period. Measured from the first to the last
///    maximum (peaks refined by a parabola through the three samples around each), within 1 %
///    of the continuous δ (symplectic Euler's own decrement is 7.6·10⁻⁴ above it at this h;
///    its bias is of order ζωh ≈ 1.6·10⁻³) and within 10⁻³ of
///    symplectic Euler's exact discrete decrement (left: parabola refinement, ~10⁻⁵ of a
///    peak, and rounding).
#[test]
fn dashpot_dissipates_energy_with_analytic_log_decrement() {
    let (m_a, m_b, k) = (0.1_f32, 0.3_f32, 100.0_f32);
    let mu = f64::from(m_a) * f64::from(m_b) / f64::from(m_a + m_b);
    let omega = (f64::from(k) / mu).sqrt();
    let zeta = 0.05;
    let c = (2.0 * zeta * mu * omega) as f32;
    let h = (TAU / omega / 200.0) as f32;
    let mut sim = oscillator(m_a, m_b, k, c, h, Integrator::SymplecticEuler, 0.05);
    let e0 = energy_now(&sim);
    let mut prev = e0;
    let mut ext = vec![extension(&sim)];
    let mut min_drop = f64::MAX;
    for n in 0..1300 {
        let e = mech_energy(&sim.step().unwrap());
        assert!(e < prev, "step {n}: energy rose from {prev} to {e}");
        min_drop = min_drop.min(1.0 - e / prev);
        prev = e;
        ext.push(extension(&sim));
    }
    // Maxima of the extension, refined by a parabola through three samples.
    let peaks: Vec<f64> = ext
        .windows(3)
        .filter(|w| w[1] > 0.0 && w[1] > w[0] && w[1] >= w[2])
        .map(|w| {
            let curv = w[0] - 2.0 * w[1] + w[2];
            w[1] - (w[2] - w[0]).powi(2) / (8.0 * curv)
        })
        .collect();
    // The first "peak" is the initial displacement at n = 0, which `windows` cannot see.
    let mut amplitudes = vec![ext[0]];
    amplitudes.extend(&peaks);
    let periods = amplitudes.len() - 1;
    let delta = (amplitudes[0] / amplitudes[periods]).ln() / periods as f64;
    let expected = TAU * zeta / (1.0 - zeta * zeta).sqrt();
    // Symplectic Euler's own decrement: its amplification matrix for e'' = −ω²e − γe' has
    // trace 2 − (ωh)² − hγ and determinant 1 − hγ (γ = c/μ = 2ζω); with eigenvalues r·e^{±iθ}
    // the sampled peaks shrink by r^{2π/θ} per period.
    let (hd, gamma) = (f64::from(h), f64::from(c) / mu);
    let r = (1.0 - hd * gamma).sqrt();
    let theta = ((2.0 - (omega * hd).powi(2) - hd * gamma) / (2.0 * r)).acos();
    let discrete = TAU * (1.0 / r).ln() / theta;
    let wh2 = (omega * hd).powi(2);
    eprintln!(
        "dashpot: c = {c:.4} N·s/m, E_N/E_0 = {:.4e}, smallest per-step drop {min_drop:.2e}; \
         (ωh)² = {wh2:.2e}; peaks {amplitudes:.5?}; δ = {delta:.5} vs 2πζ/√(1−ζ²) = \
         {expected:.5} (rel {:+.2e}), vs discrete {discrete:.5} (rel {:+.2e})",
        prev / e0,
        delta / expected - 1.0,
        delta / discrete - 1.0
    );
    assert!(
        min_drop > 0.5 * wh2,
        "smallest per-step energy drop {min_drop} vs predicted ≈ (ωh)² = {wh2}"
    );
    assert!(periods >= 5, "too few peaks: {amplitudes:?}");
    assert!(
        (delta / expected - 1.0).abs() < 0.01,
        "log decrement {delta} vs {expected}"
    );
    assert!(
        (delta / discrete - 1.0).abs() < 1e-3,
        "log decrement {delta} vs symplectic Euler's {discrete}"
    );
}
