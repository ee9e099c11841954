//! Particle state in structure-of-arrays form.

use glam::{DVec3, Vec3};

/// A particle mass the solvers can use: finite and `> 0` with a finite inverse; else what is
/// allowed, in words (for [`GridBuilder`](crate::GridBuilder) and
/// [`Cloth::validate`](crate::Cloth::validate)).
pub(crate) fn check_mass(m: f32) -> Result<(), String> {
    if m.is_finite() && m > 0.0 && (1.0 / m).is_finite() {
        Ok(())
    } else {
        Err(format!(
            "a finite mass > 0 with a finite inverse (at least {:e} kg)",
            1.0 / f32::MAX
        ))
    }
}

/// The particles of a cloth, one entry per particle in each array (structure of arrays).
///
/// A particle with `inv_mass == 0` is pinned: no force moves it, and it follows its
/// prescribed velocity (zero unless a pin target was set, see
/// [`Simulation::set_pin_target`](crate::Simulation::set_pin_target)). `mass` keeps the
/// particle's own mass while it is pinned so that unpinning restores it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Particles {
    /// Positions, m.
    pub position: Vec<Vec3>,
    /// Velocities, m/s.
    pub velocity: Vec<Vec3>,
    /// Mass of each particle, kg (kept while pinned).
    pub mass: Vec<f32>,
    /// Inverse mass, 1/kg; 0 for a pinned particle.
    pub inv_mass: Vec<f32>,
}

impl Particles {
    /// Number of particles.
    #[must_use]
    pub fn len(&self) -> usize {
        self.position.len()
    }

    /// `true` when there are no particles.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.position.is_empty()
    }

    /// `true` when particle `i` is pinned.
    ///
    /// # Panics
    /// When `i` is not below [`len`](Self::len).
    #[must_use]
    pub fn is_pinned(&self, i: usize) -> bool {
        self.inv_mass[i] == 0.0
    }

    /// `true` when some particle is pinned (one pass over the inverse masses, without an
    /// early exit, which the compiler vectorises).
    #[must_use]
    pub fn any_pinned(&self) -> bool {
        self.inv_mass.iter().fold(false, |any, &w| any | (w == 0.0))
    }

    /// The smallest particle mass, kg (infinite for no particles). The stiffest, lightest
    /// particle bounds the stable step of the explicit integrators.
    #[must_use]
    pub fn min_mass(&self) -> f32 {
        self.mass.iter().copied().fold(f32::INFINITY, f32::min)
    }

    /// Total mass of all particles (pinned ones included), kg.
    #[must_use]
    pub fn total_mass(&self) -> f32 {
        // Summed in f64: an f32 running sum stalls once it is 2^24 times a particle's mass
        // (a uniform 8192 × 8192 grid would report 30% of its mass).
        self.mass.iter().map(|&m| f64::from(m)).sum::<f64>() as f32
    }

    /// Total linear momentum Σ m·v, kg·m/s.
    #[must_use]
    pub fn momentum(&self) -> Vec3 {
        self.mass
            .iter()
            .zip(&self.velocity)
            .fold(DVec3::ZERO, |acc, (&m, &v)| {
                acc + f64::from(m) * v.as_dvec3()
            })
            .as_vec3()
    }

    /// Centre of mass, m (the origin when there are no particles).
    #[must_use]
    pub fn center_of_mass(&self) -> Vec3 {
        if self.is_empty() {
            return Vec3::ZERO;
        }
        let (weighted, total) = self
            .mass
            .iter()
            .zip(&self.position)
            .fold((DVec3::ZERO, 0.0_f64), |(acc, total), (&m, &x)| {
                (acc + f64::from(m) * x.as_dvec3(), total + f64::from(m))
            });
        (weighted / total).as_vec3()
    }
}
