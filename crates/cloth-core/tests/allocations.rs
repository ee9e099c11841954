//! No allocation inside a step after the first: a counting global allocator watches 20 steps
//! of every integrator (with colliders, air, self-collision and a moving pin) after two
//! warm-up steps, and sees none.

// A global allocator needs `unsafe impl`; it only forwards to the system allocator.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use cloth_core::glam::Vec3;
use cloth_core::{Integrator, SelfCollision, presets};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards every call unchanged to `System`, only counting.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: same contract as ours.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as ours.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: same contract as ours.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn steps_after_the_first_do_not_allocate() {
    for integrator in Integrator::ALL {
        let mut sim = presets::drape(16, integrator).expect("drape");
        let mut config = *sim.config();
        config.self_collision = Some(SelfCollision::default());
        config.air.wind = Vec3::new(1.0, 0.0, 0.0);
        config.strain_limit = Some(0.2);
        sim.set_config(config).expect("config");
        sim.pin(0).expect("pin");
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
            "{integrator:?} allocated {} times in 20 steps",
            after - before
        );
    }
}
