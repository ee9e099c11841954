//! The built-in scenes the viewer and the `cloth` binary know by name.

use cloth_core::glam::Vec3;
use cloth_core::{
    Edge, GridBuilder, Gust, Integrator, Mass, Material, Orientation, SimConfig, Simulation,
    SpringParams, presets,
};

/// A built-in scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SceneKind {
    /// The seed's scene: a square cloth dropped onto a ball resting on the ground.
    #[default]
    Drape,
    /// A curtain hanging from its two top corners.
    Hanging,
    /// The peer benchmark's cloth on a frictionless ball (Taichi's `mass_spring_3d_ggui`).
    PeerBall,
    /// A flag pinned along its left edge, in gusty wind.
    Flag,
}

impl SceneKind {
    /// Every scene, in menu order.
    pub const ALL: [SceneKind; 4] = [Self::Drape, Self::Hanging, Self::PeerBall, Self::Flag];

    /// The scene's command-line name.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Drape => "drape",
            Self::Hanging => "hanging",
            Self::PeerBall => "peer-ball",
            Self::Flag => "flag",
        }
    }

    /// The scene called `name`, if any.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }

    /// The names of all scenes, comma separated (for messages).
    #[must_use]
    pub fn names() -> String {
        Self::ALL.map(Self::name).join(", ")
    }

    /// One line describing the scene.
    #[must_use]
    pub fn description(self) -> &'static str {
        match self {
            Self::Drape => "a 1.2 m cloth dropped onto a ball on the ground",
            Self::Hanging => "a 1 m curtain hanging from its two top corners",
            Self::PeerBall => "the peer benchmark: a stiff cloth on a frictionless ball",
            Self::Flag => "a flag pinned along its left edge in gusty wind",
        }
    }

    /// Height of a floor drawn for looks when the scene has no plane collider, m.
    #[must_use]
    pub fn display_floor(self) -> f32 {
        match self {
            Self::Drape => -0.3,
            Self::Hanging | Self::Flag => 0.0,
            Self::PeerBall => -0.8,
        }
    }

    /// A good point for the camera to look at, and the distance to look from.
    #[must_use]
    pub fn focus(self) -> (Vec3, f32) {
        match self {
            Self::Drape => (Vec3::new(0.0, -0.05, 0.0), 1.9),
            Self::Hanging => (Vec3::new(0.0, 0.95, 0.0), 2.4),
            Self::PeerBall => (Vec3::new(0.0, 0.0, 0.0), 2.4),
            Self::Flag => (Vec3::new(0.3, 1.2, 0.0), 3.0),
        }
    }

    /// Builds the scene with an `n × n` grid.
    ///
    /// # Errors
    /// The simulator's error for an invalid resolution or configuration.
    pub fn build(self, n: usize, integrator: Integrator) -> cloth_core::Result<Simulation> {
        match self {
            Self::Drape => presets::drape(n, integrator),
            Self::Hanging => presets::hanging(n, integrator),
            Self::PeerBall => presets::peer_ball(n),
            Self::Flag => flag(n, integrator),
        }
    }
}

impl std::fmt::Display for SceneKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A 1.6 m × 1 m flag (`n` rows, proportionally more columns), 0.15 kg/m², pinned along its left
/// edge with its top at 1.7 m, in a 4 m/s wind along +x (slightly towards +z) with default
/// gusts. Substeps come from [`presets::stable_substeps`].
///
/// # Errors
/// The simulator's error for an invalid resolution.
pub fn flag(n: usize, integrator: Integrator) -> cloth_core::Result<Simulation> {
    let cols = (n * 8).div_ceil(5).max(2);
    let cloth = GridBuilder::new(n, cols)
        .size(1.6, 1.0)
        .orientation(Orientation::Vertical)
        .origin(Vec3::new(0.0, 1.2, 0.0))
        .mass(Mass::ArealDensity(0.15))
        .pin_edge(Edge::Left)
        .build()?;
    let mut config = SimConfig {
        integrator,
        damping: 5e-4,
        material: Material::isotropic(
            SpringParams::new(400.0, 0.02),
            SpringParams::new(80.0, 0.01),
            SpringParams::new(8.0, 0.004),
        ),
        ..SimConfig::default()
    };
    config.air.wind = Vec3::new(4.0, 0.0, 1.0);
    config.air.gust = Some(Gust::default());
    let min_mass = cloth.particles.min_mass();
    config.substeps = presets::stable_substeps(&config, min_mass);
    Simulation::new(cloth, config)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for s in SceneKind::ALL {
            assert_eq!(SceneKind::from_name(s.name()), Some(s));
        }
        assert_eq!(SceneKind::from_name("nope"), None);
        assert_eq!(SceneKind::names(), "drape, hanging, peer-ball, flag");
    }

    #[test]
    fn flag_is_pinned_on_the_left_and_flies_downwind() {
        let mut sim = flag(10, Integrator::SymplecticEuler).unwrap();
        let (rows, cols) = sim.grid_size();
        for r in 0..rows {
            assert!(sim.particles().is_pinned(r * cols));
            assert!(!sim.particles().is_pinned(r * cols + cols - 1));
        }
        let x0 = sim.particles().center_of_mass().x;
        for _ in 0..60 {
            sim.step().unwrap();
        }
        assert!(sim.particles().position.iter().all(|p| p.is_finite()));
        // the free edge never gets upwind of the pole
        assert!(
            sim.particles().center_of_mass().x > x0 - 0.8,
            "flag blew upwind"
        );
    }
}
