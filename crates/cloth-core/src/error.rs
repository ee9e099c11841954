//! The one error type of `cloth-core`.

use thiserror::Error;

/// Everything that can go wrong in `cloth-core`.
///
/// Argument errors name the argument (as a dotted path such as `material.shear.stiffness`),
/// the value that was given and the range that is allowed, so that a user can fix the input
/// without reading the source.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum ClothError {
    /// An argument is outside its allowed range (or not finite).
    #[error("invalid `{name}` = {value}: allowed {allowed}")]
    InvalidArgument {
        /// Dotted path of the argument, e.g. `grid.rows` or `config.dt`.
        name: String,
        /// The value that was given, formatted.
        value: String,
        /// The allowed range, in words, e.g. `2 ..= 8192`.
        allowed: String,
    },
    /// A particle index is not in the cloth.
    #[error("`{name}` index {index} is out of range: the cloth has {len} particles (allowed 0 ..= {max})", max = .len.saturating_sub(1))]
    IndexOutOfRange {
        /// Which argument held the index.
        name: String,
        /// The index that was given.
        index: usize,
        /// The number of particles.
        len: usize,
    },
    /// A scene file (or a `--set` override) is not valid.
    #[error(
        "{file}{}: {}{message}",
        if *.line > 0 { format!(":{}:{}", .line, .column) } else { String::new() },
        if .key.is_empty() { String::new() } else { format!("`{}`: ", .key) }
    )]
    Scene {
        /// The file (or `--set key=value` override) the problem is in.
        file: String,
        /// 1-based line of the problem, 0 when unknown.
        line: usize,
        /// 1-based column of the problem, 0 when unknown.
        column: usize,
        /// Dotted key path, e.g. `cloth.resolution`.
        key: String,
        /// What is wrong and what is allowed.
        message: String,
    },
    /// A step would have produced a non-finite or runaway state. The simulation kept the
    /// state it had before the step.
    #[error(
        "unstable at step {step} (t = {time:.6} s): particle {particle}: {reason}; \
         the cloth keeps its last good state. Likely cause: {hint}"
    )]
    Unstable {
        /// Index of the step that failed (the number of steps completed before it).
        step: u64,
        /// Simulated time at the start of the failed step, in seconds.
        time: f64,
        /// The first particle found in a bad state (0 when a collider's pose went bad: the
        /// reason names the collider; for an implicit solve that overflowed, the particle of
        /// largest acceleration).
        particle: u32,
        /// What was wrong with it.
        reason: String,
        /// The most likely cause and what to change.
        hint: String,
    },
}

/// `Result` with [`ClothError`].
pub type Result<T, E = ClothError> = std::result::Result<T, E>;

impl ClothError {
    /// An [`ClothError::InvalidArgument`] for `name` with the value formatted by `Debug`.
    pub(crate) fn invalid(
        name: impl Into<String>,
        value: impl std::fmt::Debug,
        allowed: impl Into<String>,
    ) -> Self {
        Self::InvalidArgument {
            name: name.into(),
            value: format!("{value:?}"),
            allowed: allowed.into(),
        }
    }
}

/// Argument checks shared by the builders and configs.
pub(crate) mod check {
    use super::{ClothError, Result};
    use glam::Vec3;

    /// `value` finite and `> 0`.
    pub fn positive(name: &str, value: f32) -> Result<()> {
        if value.is_finite() && value > 0.0 {
            Ok(())
        } else {
            Err(ClothError::invalid(name, value, "a finite number > 0"))
        }
    }

    /// `value` a length in `(0, max]` (m).
    pub fn length(name: &str, value: f32, max: f32) -> Result<()> {
        if value.is_finite() && value > 0.0 && value <= max {
            Ok(())
        } else {
            Err(ClothError::invalid(
                name,
                value,
                format!("a length in (0, {max}] m"),
            ))
        }
    }

    /// `value` finite and `>= 0`.
    pub fn non_negative(name: &str, value: f32) -> Result<()> {
        if value.is_finite() && value >= 0.0 {
            Ok(())
        } else {
            Err(ClothError::invalid(name, value, "a finite number >= 0"))
        }
    }

    /// Every component finite.
    pub fn finite_vec(name: &str, value: Vec3) -> Result<()> {
        if value.is_finite() {
            Ok(())
        } else {
            Err(ClothError::invalid(name, value, "finite components"))
        }
    }

    /// `lo <= value <= hi`, finite.
    pub fn in_range(name: &str, value: f32, lo: f32, hi: f32) -> Result<()> {
        if value.is_finite() && (lo..=hi).contains(&value) {
            Ok(())
        } else {
            Err(ClothError::invalid(name, value, format!("{lo} ..= {hi}")))
        }
    }
}
