//! Per-step diagnostics and the instability check.

use glam::Vec3;

use crate::collide::Collider;
use crate::config::{Integrator, SimConfig};
use crate::particles::Particles;
use crate::topology::{SpringClass, SpringKind, Topology};

/// What one step did, measured at its end. Cheap enough to leave on: one pass over the
/// particles and one over the springs per step (not per substep).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepStats {
    /// Steps completed, this one included.
    pub step: u64,
    /// Simulated time at the end of the step, s.
    pub time: f64,
    /// Kinetic energy Σ ½m|v|², J (pinned particles included).
    pub kinetic_energy: f64,
    /// Gravitational potential energy −Σ m·g·x, J (zero at the origin).
    pub gravitational_energy: f64,
    /// Elastic energy of the springs Σ ½k(|L| − L0)², J.
    pub spring_energy: f64,
    /// Largest stretch strain (|L| − L0)/L0 per [`SpringClass`] (indexed by
    /// `SpringClass as usize`); 0 when no spring of the class is stretched.
    pub max_strain: [f32; 3],
    /// Deepest penetration of a free particle below any collider's contact surface (surface
    /// + thickness), m; 0 when none is inside.
    pub max_penetration: f32,
    /// Particle–collider contacts resolved in the step's last substep.
    pub contacts: u32,
    /// Particles put back on the near side of a collider by continuous collision over the
    /// whole step (paths that went through a collider within one substep).
    pub ccd_corrections: u32,
    /// What the iterative solver did, for the integrators that have one.
    pub solver: SolverStats,
}

/// Iterative-solver figures of one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverStats {
    /// Implicit Euler: the most CG iterations any substep took. XPBD: Gauss–Seidel sweeps per
    /// substep. 0 for the explicit integrators.
    pub iterations: u32,
    /// Implicit Euler: the largest final relative CG residual of any substep. 0 otherwise.
    pub residual: f32,
    /// `false` when some substep's CG stopped at the iteration cap before reaching the
    /// tolerance (a reported condition: the step is still taken, but less accurate).
    pub converged: bool,
}

impl Default for SolverStats {
    fn default() -> Self {
        Self {
            iterations: 0,
            residual: 0.0,
            converged: true,
        }
    }
}

impl StepStats {
    /// Kinetic + gravitational + spring energy, J.
    #[must_use]
    pub fn total_energy(&self) -> f64 {
        self.kinetic_energy + self.gravitational_energy + self.spring_energy
    }

    /// Largest strain of one class.
    #[must_use]
    pub fn strain(&self, class: SpringClass) -> f32 {
        self.max_strain[class as usize]
    }
}

/// A bad state found by [`measure`].
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Instability {
    pub particle: u32,
    pub reason: String,
}

/// Fewest particles (or springs) per chunk of [`measure`]'s passes, and most chunks per pass:
/// the partition depends only on the count, so the sums are the same bits for any number of
/// threads, and the partial results fit in an array on the stack (no allocation in a step).
const MEASURE_CHUNK: usize = 4096;
const MEASURE_CHUNKS: usize = 64;

/// The chunk length of a pass over `n` items.
fn chunk_len(n: usize) -> usize {
    MEASURE_CHUNK.max(n.div_ceil(MEASURE_CHUNKS))
}

/// What [`measure`] gathers from one chunk.
#[derive(Clone, Copy, Default)]
struct Partial {
    /// Energy sums of the chunk, J.
    energy: [f64; 2],
    /// Deepest penetration or largest strain of the chunk.
    max: f32,
    /// Index (within the pass) of the chunk's first bad particle or spring.
    bad: Option<usize>,
}

impl Partial {
    /// The chunks' results in chunk order: sums added in that order (from zero), maxima (from
    /// `init`), the first bad.
    fn fold(parts: impl IntoIterator<Item = Self>, init: f32) -> Self {
        parts.into_iter().fold(
            Self {
                max: init,
                ..Self::default()
            },
            |a, b| Self {
                energy: [a.energy[0] + b.energy[0], a.energy[1] + b.energy[1]],
                max: a.max.max(b.max),
                bad: a.bad.or(b.bad),
            },
        )
    }
}

/// Measures the state and checks it against the stability limits.
///
/// Two passes, each over fixed chunks ([`chunk_len`]) in parallel with the partial
/// results combined in chunk order (so the same bits for any thread count): the particles
/// (energies, non-finite state, speed limit, penetration), then the springs kind by kind
/// (elastic energy, strain, stretch limit). The instability reported is the first in that
/// order: the lowest-numbered bad particle, else the first overstretched spring.
pub(crate) fn measure(
    config: &SimConfig,
    topology: &Topology,
    particles: &Particles,
    colliders: &[Collider],
) -> (StepStats, Option<Instability>) {
    use rayon::prelude::*;
    let mut stats = StepStats::default();
    let g = if config.forces.gravity {
        config.gravity
    } else {
        Vec3::ZERO
    };
    let max_speed_sq = config.limits.max_speed * config.limits.max_speed;
    let p = particles;
    let bad_particle =
        |x: Vec3, v: Vec3| !x.is_finite() || !v.is_finite() || v.length_squared() > max_speed_sq;
    let mut parts = [Partial::default(); MEASURE_CHUNKS];
    let len = chunk_len(p.len());
    let used = p.len().div_ceil(len);
    parts[..used]
        .par_iter_mut()
        .zip(p.position.par_chunks(len))
        .zip(p.velocity.par_chunks(len))
        .zip(p.mass.par_chunks(len))
        .zip(p.inv_mass.par_chunks(len))
        .enumerate()
        .for_each(|(chunk, ((((part, x), v), m), w))| {
            for (k, ((&x, &v), &m)) in x.iter().zip(v).zip(m).enumerate() {
                if part.bad.is_none() && bad_particle(x, v) {
                    part.bad = Some(chunk * len + k);
                }
                let m = f64::from(m);
                part.energy[0] += 0.5 * m * f64::from(v.length_squared());
                part.energy[1] -= m * f64::from(g.dot(x));
            }
            for (&x, &w) in x.iter().zip(w) {
                if w == 0.0 {
                    continue;
                }
                for c in colliders {
                    let (dist, _) = c.shape.distance(x);
                    part.max = part.max.max(c.thickness - dist);
                }
            }
        });
    let total = Partial::fold(parts[..used].iter().copied(), stats.max_penetration);
    [stats.kinetic_energy, stats.gravitational_energy] = total.energy;
    stats.max_penetration = total.max;
    let mut bad = total.bad.map(|i| {
        let (x, v) = (p.position[i], p.velocity[i]);
        let reason = if !x.is_finite() {
            format!("position became non-finite ({x})")
        } else if !v.is_finite() {
            format!("velocity became non-finite ({v})")
        } else {
            format!(
                "speed {:.4e} m/s exceeds the limit of {} m/s",
                v.length(),
                config.limits.max_speed
            )
        };
        Instability {
            particle: i as u32,
            reason,
        }
    });
    let kernel = crate::simd::kernel();
    for kind in SpringKind::ALL {
        let k = f64::from(if config.forces.springs {
            config.material.params(kind).stiffness
        } else {
            0.0
        });
        let class = kind.class() as usize;
        let limit = config.limits.max_stretch_ratio;
        let springs = topology.springs_of(kind);
        let mut parts = [Partial::default(); MEASURE_CHUNKS];
        let len = chunk_len(springs.len());
        let used = springs.len().div_ceil(len);
        parts[..used]
            .par_iter_mut()
            .zip(springs.par_chunks(len))
            .enumerate()
            .for_each(|(chunk, (part, springs))| {
                let lanes = crate::simd::spring_lanes(kernel, &p.position, springs, k, limit);
                part.bad = lanes.bad.map(|j| chunk * len + j);
                part.energy[0] = lanes.energy.into_iter().sum();
                part.max = lanes.max.into_iter().fold(part.max, f32::max);
            });
        let total = Partial::fold(parts[..used].iter().copied(), stats.max_strain[class]);
        stats.spring_energy += total.energy[0];
        stats.max_strain[class] = total.max;
        if bad.is_none()
            && let Some(j) = total.bad
        {
            let s = springs[j];
            let len = p.position[s.a as usize].distance(p.position[s.b as usize]);
            bad = Some(Instability {
                particle: s.a,
                reason: format!(
                    "its {} spring to particle {} is stretched to {:.3}× its rest length \
                     (limit {}×)",
                    kind.name(),
                    s.b,
                    len / s.rest_length,
                    limit
                ),
            });
        }
    }
    (stats, bad)
}

/// Lanes of [`spring_lanes`]: spring `j` of a run adds to lane `j mod SPRING_LANES`.
pub(crate) const SPRING_LANES: usize = 8;

/// What [`spring_lanes`] measures of a run of springs.
pub(crate) struct SpringLanes {
    /// Elastic energy ½·k·(|L| − L0)² summed per lane, J.
    pub energy: [f64; SPRING_LANES],
    /// Largest strain (|L| − L0)/L0 per lane (from 0).
    pub max: [f32; SPRING_LANES],
    /// Index in the run of the first spring longer than `limit` times its rest length.
    pub bad: Option<usize>,
}

/// The springs' energies, strains and stretch check in [`SPRING_LANES`] lanes: independent
/// sums and maxima (one running sum would wait for every addition before the next) whose
/// lengths, square roots and divisions the compiler can do several at once; combined by the
/// caller in lane order, so the same bits on every kernel and thread count. Each length is
/// glam's `distance` (the same operations, unfused).
#[inline(always)]
pub(crate) fn spring_lanes(
    position: &[Vec3],
    springs: &[crate::topology::Spring],
    k: f64,
    limit: f32,
) -> SpringLanes {
    const L: usize = SPRING_LANES;
    let mut out = SpringLanes {
        energy: [0.0; L],
        max: [0.0; L],
        bad: None,
    };
    // One spring's share of lane `l`.
    let add = |out: &mut SpringLanes, l: usize, length: f32, rest: f32| {
        let stretch = length - rest;
        out.energy[l] += 0.5 * k * f64::from(stretch) * f64::from(stretch);
        out.max[l] = out.max[l].max(stretch / rest);
    };
    let first_bad = |springs: &[crate::topology::Spring]| {
        springs.iter().position(|s| {
            position[s.a as usize].distance(position[s.b as usize]) > limit * s.rest_length
        })
    };
    let (groups, tail) = springs.as_chunks::<L>();
    for (g, group) in groups.iter().enumerate() {
        let (mut d, mut rest) = ([[0.0_f32; L]; 3], [0.0_f32; L]);
        for (l, s) in group.iter().enumerate() {
            let v = position[s.a as usize] - position[s.b as usize];
            [d[0][l], d[1][l], d[2][l]] = v.to_array();
            rest[l] = s.rest_length;
        }
        let mut over = false;
        for l in 0..L {
            let length = (d[0][l] * d[0][l] + d[1][l] * d[1][l] + d[2][l] * d[2][l]).sqrt();
            add(&mut out, l, length, rest[l]);
            over |= length > limit * rest[l];
        }
        if over && out.bad.is_none() {
            out.bad = first_bad(group).map(|j| g * L + j);
        }
    }
    for (l, s) in tail.iter().enumerate() {
        let length = position[s.a as usize].distance(position[s.b as usize]);
        add(&mut out, l, length, s.rest_length);
    }
    if out.bad.is_none() {
        out.bad = first_bad(tail).map(|j| groups.len() * L + j);
    }
    out
}

/// Quantiles of the stretch strain (|L| − L0)/L0 over every spring of `class` at `position`
/// (nearest rank: the smallest strain that at least a fraction `q` of the springs do not
/// exceed), one per entry of `quantiles` (each in `0 ..= 1`; 1 is the maximum). `NaN` for an
/// empty class. For reports, outside the step: it sorts a copy of the strains.
#[must_use]
pub fn strain_quantiles(
    topology: &Topology,
    position: &[Vec3],
    class: SpringClass,
    quantiles: &[f64],
) -> Vec<f32> {
    let mut strains: Vec<f32> = SpringKind::ALL
        .iter()
        .filter(|k| k.class() == class)
        .flat_map(|&k| topology.springs_of(k))
        .map(|s| {
            (position[s.a as usize].distance(position[s.b as usize]) - s.rest_length)
                / s.rest_length
        })
        .collect();
    strains.sort_by(f32::total_cmp);
    quantiles
        .iter()
        .map(|&q| {
            if strains.is_empty() {
                return f32::NAN;
            }
            let rank = (q.clamp(0.0, 1.0) * strains.len() as f64).ceil() as usize;
            strains[rank.clamp(1, strains.len()) - 1]
        })
        .collect()
}

/// A conservative estimate of the largest substep at which symplectic Euler and Verlet stay
/// stable for this material and smallest particle mass `min_mass` (kg): h < √(2m/Σk), from
/// the Gershgorin bound ω² ≤ 2Σk/m on the stiffest particle, whose springs sum to
/// Σk = 2k_warp + 2k_weft + 4k_shear + 4k_bend. Damping lowers it further.
#[must_use]
pub fn explicit_stability_limit(config: &SimConfig, min_mass: f32) -> f32 {
    let m = &config.material;
    let sum_k = 2.0 * m.warp.stiffness
        + 2.0 * m.weft.stiffness
        + 4.0 * m.shear.stiffness
        + 4.0 * m.bend.stiffness;
    if sum_k <= 0.0 {
        return f32::INFINITY;
    }
    (2.0 * min_mass / sum_k).sqrt()
}

/// The most likely cause of an instability, in words, with what to change.
pub(crate) fn instability_hint(config: &SimConfig, min_mass: f32) -> String {
    let h = config.substep_dt();
    if config.integrator == Integrator::Xpbd {
        let chains = if config.xpbd.chains {
            format!(
                ", or `xpbd.chain_iterations` (now {}; 2–3 keep taut chains straight at large \
                 substeps)",
                config.xpbd.chain_iterations
            )
        } else {
            String::new()
        };
        return format!(
            "xpbd gains no energy from its step, but at large substeps a sweep leaves stiff, \
             taut springs tangled and overstretched (the lighter the particles, the more \
             substeps they need); raise `substeps`{chains}, or check the scene: a collider or \
             pin moving too fast, an extreme stiffness or wind (substep h = {h:.3e} s)"
        );
    }
    if !config.integrator.is_explicit() {
        return format!(
            "{} is stable at large steps, so the state itself is extreme: a collider or pin \
             moving too fast, or an extreme stiffness or wind; raise `substeps` or check the \
             scene (substep h = {h:.3e} s)",
            config.integrator.name()
        );
    }
    if config.integrator == Integrator::ForwardEuler {
        return format!(
            "forward Euler gains energy every step (by 1 + (ωh)² for a spring of frequency ω), \
             so it always blows up in the end; use symplectic Euler or Verlet, or a smaller \
             substep than h = {h:.3e} s"
        );
    }
    let limit = explicit_stability_limit(config, min_mass);
    if h > limit {
        format!(
            "the time step is too large for the stiffness: substep h = {h:.3e} s, but this \
             material needs h < ~{limit:.3e} s; raise `substeps` to at least {}, or lower \
             the stiffness",
            (config.dt / limit).ceil()
        )
    } else {
        format!(
            "the time step is likely too large for the stiffness or a collider moves too fast \
             (substep h = {h:.3e} s, estimated limit {limit:.3e} s); raise `substeps` or \
             lower the stiffness"
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::topology::Spring;

    /// `spring_lanes` against the plain sequential loop it replaced, on 8·5 + 3 springs (a
    /// tail): the same maximum strain and first overstretched spring (exact), the same energy
    /// to 1e-12 relative (only the order of the additions differs), on every kernel.
    #[test]
    fn spring_lanes_match_the_sequential_measure() {
        let position: Vec<Vec3> = (0..50)
            .map(|i| {
                let t = i as f32;
                Vec3::new((t * 0.37).sin(), (t * 0.11).cos(), t * 0.01)
            })
            .collect();
        let springs: Vec<Spring> = (0..43u32)
            .map(|j| Spring {
                a: j,
                b: (j * 7 + 3) % 50,
                rest_length: 0.2 + 0.01 * j as f32,
            })
            .collect();
        let (k, limit) = (400.0, 6.0);
        let mut energy = 0.0_f64;
        let mut max = 0.0_f32;
        let mut bad = None;
        for (j, s) in springs.iter().enumerate() {
            let length = position[s.a as usize].distance(position[s.b as usize]);
            let stretch = length - s.rest_length;
            energy += 0.5 * k * f64::from(stretch) * f64::from(stretch);
            max = max.max(stretch / s.rest_length);
            if bad.is_none() && length > limit * s.rest_length {
                bad = Some(j);
            }
        }
        assert!(bad.is_some(), "the case has an overstretched spring");
        for kernel in crate::simd::Kernel::ALL {
            if !kernel.is_available() {
                continue;
            }
            for run in [&springs[..], &springs[..40], &springs[..5]] {
                let lanes = crate::simd::spring_lanes(kernel, &position, run, k, limit);
                let seq_bad = run.iter().position(|s| {
                    position[s.a as usize].distance(position[s.b as usize]) > limit * s.rest_length
                });
                assert_eq!(lanes.bad, seq_bad, "{kernel:?}, {} springs", run.len());
            }
            let lanes = crate::simd::spring_lanes(kernel, &position, &springs, k, limit);
            let sum: f64 = lanes.energy.into_iter().sum();
            assert!((sum - energy).abs() <= 1e-12 * energy, "{sum} vs {energy}");
            assert_eq!(
                lanes.max.into_iter().fold(0.0, f32::max).to_bits(),
                max.to_bits()
            );
            assert_eq!(lanes.bad, bad);
        }
    }
}
