//! Helpers shared by several test files (`mod common;`); each file uses a part of them.
#![allow(dead_code)]

use cloth_core::glam::{DVec3, Quat, Vec3};
use cloth_core::{
    ForceSwitches, GridBuilder, Mass, Material, SimConfig, Simulation, SpringKind, SpringParams,
};

/// Largest |(|L| − L0)/L0| over all springs (compression included), in f64.
pub fn abs_strain(sim: &Simulation) -> f64 {
    let p = &sim.particles().position;
    sim.topology()
        .springs()
        .iter()
        .map(|s| {
            let len = (p[s.b as usize].as_dvec3() - p[s.a as usize].as_dvec3()).length();
            ((len - f64::from(s.rest_length)) / f64::from(s.rest_length)).abs()
        })
        .fold(0.0, f64::max)
}

/// A tiny deterministic generator (64-bit LCG, Knuth's constants).
pub struct Lcg(pub u64);

impl Lcg {
    /// Uniform in [−1, 1).
    pub fn next_signed(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 40) as f32 / (1_u32 << 23) as f32 - 1.0
    }

    /// Each component uniform in [−1, 1).
    pub fn next_vec(&mut self) -> Vec3 {
        Vec3::new(self.next_signed(), self.next_signed(), self.next_signed())
    }
}

/// A nearly rigid patch for contact and friction laws: 3 × 3 particles of 10 g over
/// 0.1 m × 0.1 m, every spring 1000 N/m with 0.1 N·s/m dashpots (which exert nothing in a
/// rigid translation), turned by `rotation` and placed at `origin`, moving at `velocity`.
/// `config` gives the integrator and the step; global damping and air are switched off.
pub fn stiff_patch(rotation: Quat, origin: Vec3, velocity: Vec3, config: SimConfig) -> Simulation {
    let cloth = GridBuilder::new(3, 3)
        .size(0.1, 0.1)
        .rotation(rotation)
        .origin(origin)
        .velocity(velocity)
        .mass(Mass::PerParticle(0.01))
        .build()
        .unwrap();
    let stiff = SpringParams::new(1000.0, 0.1);
    let mut config = SimConfig {
        damping: 0.0,
        material: Material::isotropic(stiff, stiff, stiff),
        ..config
    };
    config.forces.air = false;
    Simulation::new(cloth, config).unwrap()
}

/// A flat 3 × 3 cloth of 1 m² (8 equal triangles) in the xz plane, of `total_mass` kg, each
/// particle's mass proportional to the number of triangles it belongs to: each triangle's air
/// force is shared equally by its corners, so in a uniform flow every particle gets the same
/// acceleration and the cloth moves as a rigid sheet.
pub fn flat_air_cloth(total_mass: f32) -> cloth_core::Cloth {
    let mut cloth = GridBuilder::new(3, 3).size(1.0, 1.0).build().unwrap();
    let mut count = vec![0_u32; cloth.particles.len()];
    for t in cloth.topology.triangles() {
        for &i in t {
            count[i as usize] += 1;
        }
    }
    let unit = total_mass / (3 * cloth.topology.triangles().len()) as f32;
    for (i, &c) in count.iter().enumerate() {
        cloth.particles.mass[i] = unit * c as f32;
        cloth.particles.inv_mass[i] = 1.0 / (unit * c as f32);
    }
    cloth
}

/// The step of [`flat_air_cloth`] in air: `substeps` per 1/60 s step, a soft fabric (40, 10
/// and 2 N/m with 0.1 N·s/m dashpots, so that even forward Euler damps the rounding noise),
/// air of 1.2 kg/m³ with C_d = 1 and no lift blowing at `wind`, no global damping, gravity
/// as `gravity` says.
pub fn air_config(
    integrator: cloth_core::Integrator,
    substeps: u32,
    wind: Vec3,
    gravity: bool,
) -> SimConfig {
    SimConfig {
        dt: 1.0 / 60.0,
        substeps,
        integrator,
        material: SOFT_FABRIC,
        air: cloth_core::Air {
            density: 1.2,
            drag_coefficient: 1.0,
            lift_coefficient: 0.0,
            wind,
            gust: None,
        },
        forces: ForceSwitches {
            gravity,
            damping: false,
            ..ForceSwitches::default()
        },
        ..SimConfig::default()
    }
}

/// f32 unit roundoff, 2⁻²⁴.
pub const EPS32: f64 = 1.0 / 16_777_216.0;

/// A spring kind switched off.
pub const OFF: SpringParams = SpringParams::new(0.0, 0.0);

/// Every force term off except springs and dashpots.
pub fn internal_forces_only() -> ForceSwitches {
    ForceSwitches {
        gravity: false,
        springs: true,
        dashpots: true,
        damping: false,
        air: false,
    }
}

/// Centre of mass in f64.
pub fn com(sim: &Simulation) -> DVec3 {
    let p = sim.particles();
    let total: f64 = p.mass.iter().map(|&m| f64::from(m)).sum();
    p.mass
        .iter()
        .zip(&p.position)
        .map(|(&m, x)| f64::from(m) * x.as_dvec3())
        .sum::<DVec3>()
        / total
}

/// Extension |L| − L0 of the spring 0–1 (L0 = 1 m), in f64.
pub fn extension(sim: &Simulation) -> f64 {
    let p = &sim.particles().position;
    (p[1].as_dvec3() - p[0].as_dvec3()).length() - 1.0
}

/// Period from the zero crossings of a sampled signal (sample n at time n·h), each located by
/// linear interpolation; successive crossings are half a period apart. Returns the period and
/// the number of crossings used.
pub fn zero_crossing_period(signal: &[f64], h: f64) -> (f64, usize) {
    let crossings: Vec<f64> = signal
        .windows(2)
        .enumerate()
        .filter(|(_, w)| (w[0] > 0.0) != (w[1] > 0.0))
        .map(|(n, w)| (n as f64 + w[0] / (w[0] - w[1])) * h)
        .collect();
    assert!(
        crossings.len() >= 3,
        "too few zero crossings: {crossings:?}"
    );
    let span = crossings[crossings.len() - 1] - crossings[0];
    (2.0 * span / (crossings.len() - 1) as f64, crossings.len())
}

/// A soft fabric: structural 40 N/m, shear 10 N/m, bend 2 N/m, each with a 0.1 N·s/m
/// dashpot, so that every mode's dashpot damping beats forward Euler's (ωh)² energy gain
/// (c/k > h) and even forward Euler damps the rounding noise of the spring lengths.
pub const SOFT_FABRIC: Material = Material::isotropic(
    SpringParams::new(40.0, 0.1),
    SpringParams::new(10.0, 0.1),
    SpringParams::new(2.0, 0.1),
);

/// Free fall's cloth: 4 × 4 particles of 0.125 kg on a 1 m square at y = 1 m, thrown at `v0`,
/// stepped at 1/64 s in `substeps` under gravity only (no global damping or air; springs and
/// dashpots on but unstretched).
pub fn thrown_cloth(
    v0: Vec3,
    integrator: cloth_core::Integrator,
    substeps: u32,
    material: Material,
) -> Simulation {
    let cloth = GridBuilder::new(4, 4)
        .size(1.0, 1.0)
        .origin(Vec3::new(0.0, 1.0, 0.0))
        .velocity(v0)
        .mass(Mass::PerParticle(0.125))
        .build()
        .unwrap();
    let config = SimConfig {
        dt: 1.0 / 64.0,
        substeps,
        integrator,
        material,
        forces: ForceSwitches {
            damping: false,
            air: false,
            ..ForceSwitches::default()
        },
        ..SimConfig::default()
    };
    Simulation::new(cloth, config).unwrap()
}

/// A free fall run by [`FreeFall::run`]: what its bounds need.
pub struct FreeFall {
    /// The positions at the start.
    pub start: Vec<Vec3>,
    /// The largest |y| of any particle at the start and after every step, m.
    pub max_y: f64,
    /// Substeps taken.
    pub n: f64,
    /// The substep, s.
    pub h: f64,
    /// Gravity's magnitude, m/s².
    pub g: f64,
}

impl FreeFall {
    /// Runs `steps` steps of `sim`, calling `each` after every one.
    pub fn run(
        sim: &mut Simulation,
        steps: u32,
        mut each: impl FnMut(&Simulation, &cloth_core::StepStats),
    ) -> Self {
        let start = sim.particles().position.clone();
        let mut max_y: f64 = 1.0;
        for _ in 0..steps {
            let stats = sim.step().unwrap();
            each(sim, &stats);
            max_y = sim
                .particles()
                .position
                .iter()
                .fold(max_y, |a, p| a.max(f64::from(p.y.abs())));
        }
        Self {
            start,
            max_y,
            n: f64::from(steps * sim.config().substeps),
            h: f64::from(sim.config().substep_dt()),
            g: -f64::from(sim.config().gravity.y),
        }
    }

    /// The time fallen, s.
    pub fn t(&self) -> f64 {
        self.n * self.h
    }

    /// The f32 rounding bound n·2⁻²⁴·(2·max|y| + t·max|v|) of a fall thrown at `v0`: each of
    /// the ≤ 2n position updates rounds by at most half an ulp of |y|, each of the n velocity
    /// updates by half an ulp of |v|, which then acts for ≤ t.
    pub fn rounding_bound(&self, v0: Vec3) -> f64 {
        let t = self.t();
        let max_v = (f64::from(v0.y) - self.g * t)
            .abs()
            .max(f64::from(v0.length()));
        self.n * EPS32 * (2.0 * self.max_y + t * max_v)
    }

    /// The largest error of any particle's displacement against `expected_dy` along y and
    /// v₀t along x and z, m.
    pub fn worst_particle_error(&self, sim: &Simulation, v0: Vec3, expected_dy: f64) -> f64 {
        let t = self.t();
        let mut worst: f64 = 0.0;
        for (p, p0) in sim.particles().position.iter().zip(&self.start) {
            let d = p.as_dvec3() - p0.as_dvec3();
            worst = worst
                .max((d.y - expected_dy).abs())
                .max((d.x - f64::from(v0.x) * t).abs())
                .max((d.z - f64::from(v0.z) * t).abs());
        }
        worst
    }
}

/// A two-particle oscillator: a 2×2 grid, 1 m × 1 m, with only weft springs (stiffness `k`,
/// dashpot `c`); particle 0 has mass `m_a`, particle 1 mass `m_b`, and particle 1 is moved
/// `stretch` metres along +x (the rest length 0–1 is exactly 1 m). One substep per step of
/// length `h`. Nothing else acts.
pub fn oscillator(
    m_a: f32,
    m_b: f32,
    k: f32,
    c: f32,
    h: f32,
    integrator: cloth_core::Integrator,
    stretch: f32,
) -> Simulation {
    let mut cloth = GridBuilder::new(2, 2)
        .spacing(1.0, 1.0)
        .mass(Mass::PerParticle(1.0))
        .build()
        .unwrap();
    for (i, m) in [(0, m_a), (1, m_b)] {
        cloth.particles.mass[i] = m;
        cloth.particles.inv_mass[i] = 1.0 / m;
    }
    let rest = cloth.topology.springs_of(SpringKind::Weft)[0].rest_length;
    assert_eq!(rest, 1.0, "the 0–1 spring should be exactly 1 m long");
    let config = SimConfig {
        dt: h,
        substeps: 1,
        integrator,
        material: Material {
            warp: OFF,
            weft: SpringParams::new(k, c),
            shear: OFF,
            bend: OFF,
        },
        forces: internal_forces_only(),
        ..SimConfig::default()
    };
    let mut sim = Simulation::new(cloth, config).unwrap();
    let x1 = sim.particles().position[1];
    sim.set_position(1, x1 + Vec3::new(stretch, 0.0, 0.0))
        .unwrap();
    sim
}
