//! A fixed-timestep accumulator: the simulation always advances in whole steps of its own
//! `dt`, however long the frames take. Forces are never scaled by frame time.

use std::time::Duration;

/// Turns wall-clock frame times into a whole number of fixed simulation steps.
///
/// Each frame adds its duration to an accumulator; [`steps`](Self::steps) takes out as many
/// whole steps of `dt` as fit, at most `max_steps` per frame. When the simulation cannot keep
/// up, the extra time is dropped (it runs slower than real time, [`behind`](Self::behind) says
/// so) instead of piling up into ever longer frames (the "spiral of death").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixedStep {
    dt: f64,
    max_steps: u32,
    accumulator: f64,
    behind: bool,
}

impl FixedStep {
    /// Steps of `dt` seconds, at most `max_steps` (≥ 1) per frame.
    #[must_use]
    pub fn new(dt: f32, max_steps: u32) -> Self {
        Self {
            dt: f64::from(dt).max(1e-6),
            max_steps: max_steps.max(1),
            accumulator: 0.0,
            behind: false,
        }
    }

    /// The step length, s.
    #[must_use]
    pub fn dt(&self) -> f32 {
        self.dt as f32
    }

    /// Changes the step length (keeps the accumulated time).
    pub fn set_dt(&mut self, dt: f32) {
        self.dt = f64::from(dt).max(1e-6);
    }

    /// Adds a frame of `elapsed` wall time and returns how many steps to run now.
    pub fn steps(&mut self, elapsed: Duration) -> u32 {
        // a frame longer than a quarter second (a stall, a dragged window) counts as one
        self.accumulator += elapsed.as_secs_f64().min(0.25);
        let due = (self.accumulator / self.dt).floor();
        let n = due.min(f64::from(self.max_steps)) as u32;
        self.accumulator -= f64::from(n) * self.dt;
        self.behind = due > f64::from(self.max_steps);
        if self.behind {
            // drop what cannot be caught up: run slower than real time
            self.accumulator = self.accumulator.min(self.dt);
        }
        n
    }

    /// Whether the last frame had more steps due than allowed (running slower than real time).
    #[must_use]
    pub fn behind(&self) -> bool {
        self.behind
    }

    /// Forgets accumulated time (after a pause or reset).
    pub fn reset(&mut self) {
        self.accumulator = 0.0;
        self.behind = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_steps_only_and_the_remainder_carries_over() {
        let mut f = FixedStep::new(0.01, 10);
        assert_eq!(f.steps(Duration::from_millis(25)), 2);
        assert_eq!(f.steps(Duration::from_millis(5)), 1);
        assert_eq!(f.steps(Duration::from_millis(9)), 0);
        assert!(!f.behind());
    }

    #[test]
    fn slow_frames_are_capped_and_never_spiral() {
        let mut f = FixedStep::new(0.01, 4);
        for _ in 0..100 {
            assert!(f.steps(Duration::from_millis(200)) <= 4);
            assert!(f.behind());
        }
        // once frames are fast again, it catches up at once
        assert!(f.steps(Duration::from_millis(10)) <= 2);
        assert!(!f.behind());
    }

    #[test]
    fn total_steps_match_real_time_when_it_keeps_up() {
        let mut f = FixedStep::new(1.0 / 60.0, 8);
        let total: u32 = (0..600)
            .map(|_| f.steps(Duration::from_micros(16_667)))
            .sum();
        assert!((599..=601).contains(&total), "{total}");
    }
}
