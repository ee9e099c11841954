//! No allocation inside a step after the first: a counting global allocator watches 20 steps
//! of every integrator (with colliders, air, self-collision and a moving pin) after two
//! warm-up steps, and sees none.
//!
//! Only the threads that run steps are counted (the test's own thread and the rayon workers,
//! marked by `TRACKED`): the test harness's own threads allocate whenever they like (printing
//! another test's result, for one), which is not the simulator's doing.

// A global allocator needs `unsafe impl`; it only forwards to the system allocator.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use cloth_core::glam::Vec3;
use cloth_core::{Integrator, SelfCollision, Simulation, presets};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// Whether this thread's allocations count.
    static TRACKED: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

fn count() {
    if TRACKED.with(std::cell::Cell::get) {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
    }
}

/// Marks this thread and the global rayon pool's workers as counted.
fn track() {
    TRACKED.with(|t| t.set(true));
    static GLOBAL_POOL: std::sync::Once = std::sync::Once::new();
    GLOBAL_POOL.call_once(|| {
        rayon::ThreadPoolBuilder::new()
            .start_handler(|_| TRACKED.with(|t| t.set(true)))
            .build_global()
            .expect("global pool");
    });
}

// SAFETY: forwards every call unchanged to `System`, only counting.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: same contract as ours.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as ours.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: same contract as ours.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// The tests of this file run one at a time: the counter is global.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Two warm-up steps, then 20 steps moving pin 0, which must not allocate. Run on a thread of
/// the pool that steps (a parallel loop started from a thread outside the pool hands rayon a
/// job through its global queue, which allocates one block per 63 jobs: rayon's amortised
/// allocation, not the step's).
fn assert_steps_do_not_allocate(sim: &mut Simulation, what: &str) {
    for _ in 0..2 {
        sim.step().expect("warm-up");
    }
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    for k in 0..20 {
        sim.set_pin_target(0, Vec3::new(-0.6, 0.55 + 0.01 * k as f32, -0.6))
            .expect("target");
        sim.step().expect("step");
    }
    let after = ALLOCATIONS.load(Ordering::Relaxed);
    assert_eq!(
        after - before,
        0,
        "{what} allocated {} times in 20 steps",
        after - before
    );
}

#[test]
fn steps_after_the_first_do_not_allocate() {
    let _serial = SERIAL
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    track();
    for integrator in Integrator::ALL {
        let mut sim = presets::drape(16, integrator).expect("drape");
        let mut config = *sim.config();
        config.self_collision = Some(SelfCollision::default());
        config.air.wind = Vec3::new(1.0, 0.0, 0.0);
        config.strain_limit = Some(0.2);
        // XPBD's reference path with its chain solves and shear chains.
        config.xpbd.chains = true;
        config.xpbd.shear_chains = true;
        sim.set_config(config).expect("config");
        sim.pin(0).expect("pin");
        // Inside the global pool, as `cloth sim` steps.
        rayon::scope(|_| assert_steps_do_not_allocate(&mut sim, &format!("{integrator:?}")));
        if integrator == Integrator::Xpbd {
            // The reference path with its shear springs in the row order (kept in its scratch).
            config.xpbd.shear_chains = false;
            config.xpbd.shear_rows = true;
            sim.set_config(config).expect("config");
            rayon::scope(|_| assert_steps_do_not_allocate(&mut sim, "Xpbd, shear rows"));
        }
    }
}

/// The explicit integrators' grid fast path and XPBD's grid path (strain limits on), with
/// the drape's air, on a pool of 2 threads, with and without XPBD's chain solves (and shear
/// chains): still no allocation after the first step (the bands' buffers, the next-state
/// arrays and the grid XPBD scratch, chain blocks included, are kept).
#[test]
fn threaded_fast_path_steps_do_not_allocate() {
    let _serial = SERIAL
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    track();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .start_handler(|_| TRACKED.with(|t| t.set(true)))
        .build()
        .expect("pool");
    let runs = Integrator::EXPLICIT
        .into_iter()
        .map(|i| (i, false))
        .chain([(Integrator::Xpbd, false), (Integrator::Xpbd, true)])
        .chain([(Integrator::ImplicitEuler, false)])
        .map(|(i, chains)| (i, chains, false))
        // XPBD's chains with the shear springs swept row by row (`xpbd.shear_rows`).
        .chain([(Integrator::Xpbd, true, true)]);
    for (integrator, chains, rows) in runs {
        let mut sim = presets::drape(32, integrator).expect("drape");
        let mut config = *sim.config();
        if integrator == Integrator::Xpbd {
            config.xpbd.hierarchy_levels = 3;
            config.xpbd.tethers = false;
            config.xpbd.chains = chains;
            // Two Newton iterations per chain solve (the multipliers zeroed in the blocks),
            // two rounds of chain solves (a contact pass before each).
            config.xpbd.chain_iterations = if chains { 2 } else { 1 };
            config.xpbd.chain_rounds = if chains { 2 } else { 1 };
            // With the structural chains, the shear chains too (their blocks are kept).
            config.xpbd.shear_chains = chains && !rows;
            config.xpbd.shear_rows = rows;
            // The structural strain limit (its screened passes) with the chains.
            config.xpbd.structural_limit = chains.then_some(0.02);
        }
        config.air.wind = Vec3::new(1.0, 0.0, 0.5);
        if integrator == Integrator::ForwardEuler {
            // Forward Euler gains energy every substep: small ones keep it stable here.
            config.substeps *= 10;
        }
        sim.set_config(config).expect("config");
        sim.pin(0).expect("pin");
        pool.install(|| {
            // Implicit Euler has one path, parallel on its own.
            if integrator != Integrator::ImplicitEuler {
                assert_ne!(
                    cloth_core::simd::kernel_for(&sim),
                    cloth_core::simd::Kernel::Reference
                );
            }
            assert_steps_do_not_allocate(
                &mut sim,
                &format!("{integrator:?} (chains {chains}, shear rows {rows}) on 2 threads"),
            );
        });
    }
}
