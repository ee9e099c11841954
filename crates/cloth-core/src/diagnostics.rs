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
pub(crate) struct Partial {
    /// Energy sums of the chunk, J.
    pub energy: [f64; 2],
    /// Deepest penetration or largest strain of the chunk.
    pub max: f32,
    /// Index (within the pass) of the chunk's first bad particle or spring.
    pub bad: Option<usize>,
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
/// (energies, non-finite state, speed limit, penetration), then the springs of every kind
/// (elastic energy, strain, stretch limit; one parallel pass over the chunks of all kinds,
/// folded kind by kind). On a grid cloth the springs' lengths are first computed row by row
/// from contiguous slices into `lengths` ([`grid_lengths`]; the same bits as measuring them
/// spring by spring); `lengths` is reused from call to call. The instability reported is the
/// first in that order: the lowest-numbered bad particle, else the first overstretched
/// spring.
pub(crate) fn measure(
    config: &SimConfig,
    topology: &Topology,
    particles: &Particles,
    colliders: &[Collider],
    lengths: &mut Vec<f32>,
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
    let kernel = crate::simd::kernel();
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
            *part = crate::simd::particle_chunk(kernel, [x, v], [m, w], colliders, g, max_speed_sq);
            part.bad = part.bad.map(|k| chunk * len + k);
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
                v.as_dvec3().length(),
                config.limits.max_speed
            )
        };
        Instability {
            particle: i as u32,
            reason,
        }
    });

    // The springs: the lengths of a grid first (else measured spring by spring), then the
    // chunks of every kind in one parallel pass (kind after kind, chunk after chunk).
    let all = topology.springs();
    let measured = grid_lengths(kernel, topology, &p.position, lengths);
    let limit = config.limits.max_stretch_ratio;
    let stiffness = |kind: SpringKind| {
        f64::from(if config.forces.springs {
            config.material.params(kind).stiffness
        } else {
            0.0
        })
    };
    // Per kind: its first spring in `all`, its spring count and chunk length, its first part.
    let mut first_part = [0_usize; 5];
    let mut spans = [(0_usize, 0_usize, 0_usize); 4];
    let mut offset = 0;
    for kind in SpringKind::ALL {
        let count = topology.springs_of(kind).len();
        let len = chunk_len(count);
        spans[kind as usize] = (offset, count, len);
        offset += count;
        first_part[kind as usize + 1] = first_part[kind as usize] + count.div_ceil(len);
    }
    let mut parts = [Partial::default(); 4 * MEASURE_CHUNKS];
    parts[..first_part[4]]
        .par_iter_mut()
        .enumerate()
        .for_each(|(t, part)| {
            let kind = (0..4).rfind(|&k| first_part[k] <= t).unwrap_or(0);
            let kind = SpringKind::ALL[kind];
            let (start, count, len) = spans[kind as usize];
            let chunk = t - first_part[kind as usize];
            let range = start + chunk * len..start + ((chunk + 1) * len).min(count);
            let (springs, k) = (&all[range.clone()], stiffness(kind));
            let lanes = match measured {
                true => {
                    let rest = &topology.rest_lengths()[range.clone()];
                    crate::simd::length_lanes(kernel, &lengths[range], springs, rest, k, limit)
                }
                false => {
                    let rest = &topology.rest_lengths()[range];
                    crate::simd::spring_lanes(kernel, &p.position, springs, rest, k, limit)
                }
            };
            part.bad = lanes.bad.map(|j| chunk * len + j);
            part.energy[0] = lanes.energy.into_iter().sum();
            part.max = lanes.max.into_iter().fold(part.max, f32::max);
        });
    for kind in SpringKind::ALL {
        let class = kind.class() as usize;
        let parts = &parts[first_part[kind as usize]..first_part[kind as usize + 1]];
        let total = Partial::fold(parts.iter().copied(), stats.max_strain[class]);
        stats.spring_energy += total.energy[0];
        stats.max_strain[class] = total.max;
        if bad.is_none()
            && let Some(j) = total.bad
        {
            let springs = topology.springs_of(kind);
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

/// One chunk of [`measure`]'s particle pass: the energies Σ ½m|v|² and −Σ m·g·x (in f64,
/// in eight lanes, particle `i` of the chunk adding to lane `i mod 8`, combined in lane order),
/// the first particle with a non-finite state or a speed above the limit,
/// and the deepest penetration of a free particle into any collider (from 0; spheres and
/// planes computed vectorised with the shapes' own operations, so the same values).
#[inline(always)]
pub(crate) fn particle_chunk(
    [x, v]: [&[Vec3]; 2],
    [m, w]: [&[f32]; 2],
    colliders: &[Collider],
    g: Vec3,
    max_speed_sq: f32,
) -> Partial {
    use crate::collide::Shape;
    let n = x.len();
    let (v, m, w) = (&v[..n], &m[..n], &w[..n]);
    let mut part = Partial::default();
    // (Without short-circuits, so that the lanes below vectorise.)
    let bad_particle =
        |x: Vec3, v: Vec3| !x.is_finite() | !v.is_finite() | (v.length_squared() > max_speed_sq);
    // Energies in lanes (particle i of the chunk adds to lane i mod E: independent sums,
    // which the compiler computes several at once), added in lane order at the end.
    const E: usize = 8;
    let (mut kinetic, mut potential) = ([0.0_f64; E], [0.0_f64; E]);
    let mut any_bad = false;
    let mut one = |l: usize, x: Vec3, v: Vec3, m: f32| {
        any_bad |= bad_particle(x, v);
        // In f64 from the components on: finite for any finite state (|v|² and g·x in f32
        // overflow past about 10¹⁹ m/s and 10³⁷ m²/s²).
        let m = f64::from(m);
        kinetic[l] += 0.5 * m * v.as_dvec3().length_squared();
        potential[l] -= m * g.as_dvec3().dot(x.as_dvec3());
    };
    let ((xc, xt), (vc, vt), (mc, mt)) =
        (x.as_chunks::<E>(), v.as_chunks::<E>(), m.as_chunks::<E>());
    for ((xs, vs), ms) in xc.iter().zip(vc).zip(mc) {
        for l in 0..E {
            one(l, xs[l], vs[l], ms[l]);
        }
    }
    for (l, ((&x, &v), &m)) in xt.iter().zip(vt).zip(mt).enumerate() {
        one(l, x, v, m);
    }
    part.energy = [kinetic.into_iter().sum(), potential.into_iter().sum()];
    if any_bad {
        part.bad = (0..n).position(|i| bad_particle(x[i], v[i]));
    }
    // Penetration, collider by collider: lanes of maxima over chunks of particles.
    const L: usize = 16;
    let (xc, xt) = x.as_chunks::<L>();
    let (wc, wt) = w.as_chunks::<L>();
    for c in colliders {
        let t = c.thickness;
        let (sphere, a, r, normal) = match c.shape {
            Shape::Sphere { center, radius } => (true, center, radius, Vec3::Y),
            Shape::Plane { point, normal } => (false, point, 0.0, normal),
            _ => {
                for (&x, &w) in x.iter().zip(w) {
                    if w != 0.0 {
                        part.max = part.max.max(t - c.shape.distance(x).0);
                    }
                }
                continue;
            }
        };
        let depth = |x: Vec3, w: f32| {
            let (dist, _) =
                crate::solver::grid_kernel::lane_distance(sphere, a, r, normal, x.to_array());
            if w != 0.0 {
                t - dist
            } else {
                f32::NEG_INFINITY
            }
        };
        let mut lanes = [f32::NEG_INFINITY; L];
        for (xs, ws) in xc.iter().zip(wc) {
            for j in 0..L {
                lanes[j] = lanes[j].max(depth(xs[j], ws[j]));
            }
        }
        for (&x, &w) in xt.iter().zip(wt) {
            part.max = part.max.max(depth(x, w));
        }
        part.max = lanes.into_iter().fold(part.max, f32::max);
    }
    part
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
    rest: &[f32],
    k: f64,
    limit: f32,
) -> SpringLanes {
    lanes_of(
        springs,
        rest,
        k,
        limit,
        |_, group| {
            let mut d = [[0.0_f32; SPRING_LANES]; 3];
            for (l, s) in group.iter().enumerate() {
                let v = position[s.a as usize] - position[s.b as usize];
                [d[0][l], d[1][l], d[2][l]] = v.to_array();
            }
            std::array::from_fn(|l| {
                (d[0][l] * d[0][l] + d[1][l] * d[1][l] + d[2][l] * d[2][l]).sqrt()
            })
        },
        |_, s| position[s.a as usize].distance(position[s.b as usize]),
    )
}

/// [`spring_lanes`] with the lengths already measured (`lengths[j]` of `springs[j]`, by
/// [`grid_lengths`]): the same bits.
#[inline(always)]
pub(crate) fn length_lanes(
    lengths: &[f32],
    springs: &[crate::topology::Spring],
    rest: &[f32],
    k: f64,
    limit: f32,
) -> SpringLanes {
    let lengths = &lengths[..springs.len()];
    lanes_of(
        springs,
        rest,
        k,
        limit,
        |g, _| {
            *lengths[g * SPRING_LANES..]
                .first_chunk::<SPRING_LANES>()
                .expect("a whole group")
        },
        |j, _| lengths[j],
    )
}

/// The lanes of a run of springs whose lengths come from `group` (the lengths of group `g`,
/// the springs `8g .. 8g + 8`) and `one` (the length of spring `j`).
#[inline(always)]
fn lanes_of(
    springs: &[crate::topology::Spring],
    rest: &[f32],
    k: f64,
    limit: f32,
    group: impl Fn(usize, &[crate::topology::Spring; SPRING_LANES]) -> [f32; SPRING_LANES],
    one: impl Fn(usize, &crate::topology::Spring) -> f32,
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
    let first_bad = |from: usize, springs: &[crate::topology::Spring]| {
        springs
            .iter()
            .enumerate()
            .position(|(j, s)| one(from + j, s) > limit * s.rest_length)
    };
    // The rest lengths from their own array: gathered from the springs (a vector gather),
    // they took most of this pass's time on the peer scene.
    let rest = &rest[..springs.len()];
    let (groups, tail) = springs.as_chunks::<L>();
    for (g, springs) in groups.iter().enumerate() {
        let length = group(g, springs);
        let rest: &[f32; L] = rest[g * L..].first_chunk().expect("a whole group");
        let mut over = false;
        for l in 0..L {
            add(&mut out, l, length[l], rest[l]);
            over |= length[l] > limit * rest[l];
        }
        if over && out.bad.is_none() {
            out.bad = first_bad(g * L, springs).map(|j| g * L + j);
        }
    }
    let from = groups.len() * L;
    for (l, s) in tail.iter().enumerate() {
        add(&mut out, l, one(from + l, s), s.rest_length);
    }
    if out.bad.is_none() {
        out.bad = first_bad(from, tail).map(|j| from + j);
    }
    out
}

/// Per kind (in [`SpringKind::ALL`] order), the index of the first spring whose first end
/// lies in grid row `r` (`0 ..= rows`), for the builder's order ([`crate::GridBuilder`]):
/// row by row, and in a row slot by slot, warp `(r, c)–(r+1, c)`, weft `(r, c)–(r, c+1)`, the
/// two shear diagonals `(r, c)–(r+1, c+1)` and `(r, c+1)–(r+1, c)`, the bends
/// `(r, c)–(r+2, c)` and `(r, c)–(r, c+2)`, each where it exists.
fn grid_row_starts(rows: usize, cols: usize, r: usize) -> [usize; 4] {
    let h = cols.saturating_sub(2);
    let below = r.min(rows.saturating_sub(2));
    [
        r.min(rows - 1) * cols,
        r * (cols - 1),
        r.min(rows - 1) * 2 * (cols - 1),
        below * (cols + h) + (r - below) * h,
    ]
}

/// Rows of a grid cloth per task of [`grid_lengths`]: about 4096 springs.
fn grid_rows_per_task(cols: usize) -> usize {
    (MEASURE_CHUNK / (6 * cols)).max(1)
}

/// The lengths of every spring of a grid cloth (built by [`crate::GridBuilder`], see
/// [`Topology::grid`]) into `lengths`, in the topology's order, computed row by row from
/// contiguous slices of the positions (tasks of [`grid_rows_per_task`] rows in parallel;
/// each length is glam's `distance`, as when measuring spring by spring: the same bits).
/// Returns `false` (and leaves `lengths` alone) for any other topology.
fn grid_lengths(
    kernel: crate::simd::Kernel,
    topology: &Topology,
    position: &[Vec3],
    lengths: &mut Vec<f32>,
) -> bool {
    let Some((rows, cols)) = topology.grid() else {
        return false;
    };
    if rows < 2 || cols < 2 || rows * cols != position.len() {
        return false;
    }
    let ends = grid_row_starts(rows, cols, rows);
    if SpringKind::ALL
        .iter()
        .any(|&k| topology.springs_of(k).len() != ends[k as usize])
    {
        return false;
    }
    lengths.resize(topology.springs().len(), 0.0);
    let (warp, rest) = lengths.split_at_mut(ends[0]);
    let (weft, rest) = rest.split_at_mut(ends[1]);
    let (shear, bend) = rest.split_at_mut(ends[2]);
    grid_length_rows(
        kernel,
        position,
        [rows, cols],
        0..rows,
        [warp, weft, shear, bend],
    );
    true
}

/// Rows `rows.start .. rows.end` of [`grid_lengths`] into `out` (those rows' springs of each
/// kind): halves on both sides of a `rayon::join` down to tasks of [`grid_rows_per_task`].
fn grid_length_rows(
    kernel: crate::simd::Kernel,
    position: &[Vec3],
    [rows, cols]: [usize; 2],
    range: std::ops::Range<usize>,
    out: [&mut [f32]; 4],
) {
    if range.len() <= grid_rows_per_task(cols) {
        crate::simd::grid_row_lengths(kernel, position, [rows, cols], range, out);
        return;
    }
    let mid = range.start + range.len() / 2;
    let (a, b) = (
        grid_row_starts(rows, cols, range.start),
        grid_row_starts(rows, cols, mid),
    );
    let [w, f, s, b_] = out;
    let (w0, w1) = w.split_at_mut(b[0] - a[0]);
    let (f0, f1) = f.split_at_mut(b[1] - a[1]);
    let (s0, s1) = s.split_at_mut(b[2] - a[2]);
    let (b0, b1) = b_.split_at_mut(b[3] - a[3]);
    rayon::join(
        || {
            grid_length_rows(
                kernel,
                position,
                [rows, cols],
                range.start..mid,
                [w0, f0, s0, b0],
            );
        },
        || {
            grid_length_rows(
                kernel,
                position,
                [rows, cols],
                mid..range.end,
                [w1, f1, s1, b1],
            );
        },
    );
}

/// The springs of grid rows `range` (see [`grid_row_starts`]) measured into `out` (those
/// rows' springs of each kind, in order). Generic code, compiled once per instruction set by
/// [`crate::simd`].
#[inline(always)]
pub(crate) fn grid_row_lengths(
    position: &[Vec3],
    [rows, cols]: [usize; 2],
    range: std::ops::Range<usize>,
    out: [&mut [f32]; 4],
) {
    let [mut warp, mut weft, mut shear, mut bend] = out;
    let h = cols - 2;
    for r in range {
        let row = &position[r * cols..][..cols];
        if r + 1 < rows {
            let next = &position[(r + 1) * cols..][..cols];
            let (w, rest) = warp.split_at_mut(cols);
            for c in 0..cols {
                w[c] = row[c].distance(next[c]);
            }
            warp = rest;
            let (s, rest) = shear.split_at_mut(2 * (cols - 1));
            for c in 0..cols - 1 {
                s[2 * c] = row[c].distance(next[c + 1]);
                s[2 * c + 1] = row[c + 1].distance(next[c]);
            }
            shear = rest;
        }
        let (f, rest) = weft.split_at_mut(cols - 1);
        for c in 0..cols - 1 {
            f[c] = row[c].distance(row[c + 1]);
        }
        weft = rest;
        if r + 2 < rows {
            let next2 = &position[(r + 2) * cols..][..cols];
            let (b, rest) = bend.split_at_mut(cols + h);
            for c in 0..h {
                b[2 * c] = row[c].distance(next2[c]);
                b[2 * c + 1] = row[c].distance(row[c + 2]);
            }
            for c in h..cols {
                b[h + c] = row[c].distance(next2[c]);
            }
            bend = rest;
        } else {
            let (b, rest) = bend.split_at_mut(h);
            for c in 0..h {
                b[c] = row[c].distance(row[c + 2]);
            }
            bend = rest;
        }
    }
}

/// Quantiles of the stretch strain (|L| − L0)/L0 over every spring of `class` at `position`
/// (nearest rank: the smallest strain that at least a fraction `q` of the springs do not
/// exceed), one per entry of `quantiles` (each in `0 ..= 1`; 1 is the maximum). `None` when
/// the cloth has no spring of that class. For reports, outside the step: it sorts a copy of the
/// strains.
///
/// # Panics
/// When a spring of `class` joins a particle that is not below `position.len()` (the
/// positions must be those of the cloth whose `topology` this is).
#[must_use]
pub fn strain_quantiles(
    topology: &Topology,
    position: &[Vec3],
    class: SpringClass,
    quantiles: &[f64],
) -> Option<Vec<f32>> {
    let mut strains: Vec<f32> = SpringKind::ALL
        .iter()
        .filter(|k| k.class() == class)
        .flat_map(|&k| topology.springs_of(k))
        .map(|s| {
            (position[s.a as usize].distance(position[s.b as usize]) - s.rest_length)
                / s.rest_length
        })
        .collect();
    if strains.is_empty() {
        return None;
    }
    strains.sort_by(f32::total_cmp);
    let quantile = |q: f64| {
        let rank = (q.clamp(0.0, 1.0) * strains.len() as f64).ceil() as usize;
        strains[rank.clamp(1, strains.len()) - 1]
    };
    Some(quantiles.iter().map(|&q| quantile(q)).collect())
}

/// A conservative estimate of the largest substep at which symplectic Euler and Verlet stay
/// stable for this material and smallest particle mass `min_mass` (kg): h < √(2m/Σk), from
/// the Gershgorin bound ω² ≤ 2Σk/m on the stiffest particle, whose springs sum to
/// Σk = 2k_warp + 2k_weft + 4k_shear + 4k_bend. Damping lowers it further:
/// [`explicit_stability_limit_of`] counts it.
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

/// The largest substep at which symplectic Euler and Verlet stay stable for this cloth, its
/// dashpots and global damping included: [`explicit_stability_limit`] (stiffness only), or
/// lower where damping binds. A damped mode of stiffness κ and damping γ per unit mass is
/// stable under symplectic Euler when h²κ + 2hγ < 4; per free particle `i`, Gershgorin bounds
/// give κᵢ ≤ 2Σk/mᵢ and γᵢ ≤ (2Σc + d)/mᵢ over the springs at `i` (k and c of their kind,
/// each counted when its force is on), so h < 4 / (γᵢ + √(γᵢ² + 4κᵢ)) for every `i`.
/// Dashpots set the bound at high resolutions: c/m grows with 1/Δx² where √(k/m) grows with
/// 1/Δx (the drape's corners at 512²: 4.4·10⁻⁶ s, against 1.7·10⁻⁵ s from the stiffness).
#[must_use]
pub fn explicit_stability_limit_of(config: &SimConfig, topology: &Topology, p: &Particles) -> f32 {
    let stiffness_only = explicit_stability_limit(config, p.min_mass());
    let n = p.mass.len();
    let (mut sum_k, mut sum_c) = (vec![0.0_f64; n], vec![0.0_f64; n]);
    let sw = config.forces;
    for kind in SpringKind::ALL {
        let params = config.material.params(kind);
        let k = if sw.springs {
            f64::from(params.stiffness)
        } else {
            0.0
        };
        let c = if sw.dashpots {
            f64::from(params.damping)
        } else {
            0.0
        };
        for s in topology.springs_of(kind) {
            for i in [s.a as usize, s.b as usize] {
                sum_k[i] += k;
                sum_c[i] += c;
            }
        }
    }
    let d = if sw.damping {
        f64::from(config.damping)
    } else {
        0.0
    };
    let mut limit = f64::from(stiffness_only);
    for i in 0..n {
        let m = f64::from(p.mass[i]);
        if p.inv_mass[i] == 0.0 || m <= 0.0 {
            continue;
        }
        let kappa = 2.0 * sum_k[i] / m;
        let gamma = (2.0 * sum_c[i] + d) / m;
        let root = gamma + (gamma * gamma + 4.0 * kappa).sqrt();
        if root > 0.0 {
            limit = limit.min(4.0 / root);
        }
    }
    limit as f32
}

/// The most likely cause of an instability, in words, with what to change; `limit` is the
/// explicit integrators' stable substep ([`explicit_stability_limit_of`]).
pub(crate) fn instability_hint(config: &SimConfig, limit: f32) -> String {
    let h = config.substep_dt();
    // Gravity alone past the speed limit within a few steps: no step size helps.
    let g = config.gravity.as_dvec3().length();
    let per_step = g * f64::from(config.dt);
    if config.forces.gravity && per_step * 10.0 > f64::from(config.limits.max_speed) {
        return format!(
            "gravity of {g:.3e} m/s² alone adds {per_step:.3e} m/s per step, past the speed \
             limit of {} m/s within ten steps; lower `forces.gravity`",
            config.limits.max_speed
        );
    }
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
    if limit <= 0.0 {
        // The estimate underflowed f32: no substep count comes near.
        return format!(
            "the stiffness is so far beyond the particles' masses that no substep resolves \
             it (the stable substep is {}, f32's smallest); lower the stiffness or the damping, \
             make the particles heavier (the cloth's density), or use xpbd or implicit-euler, \
             which are stable at large steps",
            stable_substep_text(limit)
        );
    }
    let needed = f64::from(config.dt) / f64::from(limit);
    let most = crate::config::MAX_SUBSTEPS;
    let count = substeps_text(needed);
    if h > limit && needed > f64::from(most) {
        format!(
            "the time step is too large for the stiffness, and no allowed `substeps` is \
             enough: substep h = {h:.3e} s, but this material needs h < ~{limit:.3e} s, about \
             {count} substeps per step where at most {most} are allowed; lower the stiffness \
             or the damping, make the particles heavier (the cloth's density), shorten `dt`, \
             or use xpbd or implicit-euler, which are stable at large steps"
        )
    } else if h > limit {
        format!(
            "the time step is too large for the stiffness: substep h = {h:.3e} s, but this \
             material needs h < ~{limit:.3e} s; raise `substeps` to at least {count}, or lower \
             the stiffness or the damping"
        )
    } else {
        format!(
            "the time step is likely too large for the stiffness or a collider moves too fast \
             (substep h = {h:.3e} s, estimated limit {limit:.3e} s); raise `substeps` or lower \
             the stiffness or the damping"
        )
    }
}

/// An estimated stable substep for messages: `1.824e-4 s`, or `below 1.2e-38 s` when the
/// estimate underflowed f32 to zero (an absurd stiffness or a feather-light cloth).
#[must_use]
pub fn stable_substep_text(limit: f32) -> String {
    if limit > 0.0 {
        format!("{limit:.3e} s")
    } else {
        format!("below {:.1e} s", f32::MIN_POSITIVE)
    }
}

/// A number of substeps per step for messages: `92`, or `1.4e29` past a billion. `needed` is
/// finite (the caller handles a stable substep that underflowed to zero).
#[must_use]
pub fn substeps_text(needed: f64) -> String {
    let needed = needed.ceil();
    if needed < 1e9 {
        format!("{needed}")
    } else {
        format!("{needed:.1e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::topology::Spring;

    /// Law: a spring's length is |a − b| whoever measures it. The grid pass (row by row,
    /// from contiguous slices) gives exactly the bits of measuring each spring through its
    /// indices (`Spring::a`, `Spring::b`), on every kernel, for grids from 2 × 2 up (the
    /// edges: no bends across 2 rows or 2 columns, one row of bends at the far side), and
    /// the whole measure then gives the same stats, bit for bit, as the spring-by-spring
    /// pass. Tolerance: 0 (bit-identical).
    #[test]
    fn grid_lengths_are_the_spring_by_spring_lengths() {
        use crate::GridBuilder;
        for (rows, cols) in [(2, 2), (2, 5), (5, 2), (3, 3), (3, 4), (7, 13), (40, 33)] {
            let cloth = GridBuilder::new(rows, cols)
                .spacing(0.1, 0.07)
                .build()
                .expect("a valid grid");
            let topology = &cloth.topology;
            // A wrinkled state: every spring a different length.
            let position: Vec<Vec3> = cloth
                .particles
                .position
                .iter()
                .enumerate()
                .map(|(i, &p)| {
                    let t = i as f32;
                    p + 0.01 * Vec3::new((t * 1.3).sin(), (t * 0.7).cos(), (t * 2.9).sin())
                })
                .collect();
            let expected: Vec<u32> = topology
                .springs()
                .iter()
                .map(|s| {
                    position[s.a as usize]
                        .distance(position[s.b as usize])
                        .to_bits()
                })
                .collect();
            for kernel in crate::simd::Kernel::ALL {
                if !kernel.is_available() {
                    continue;
                }
                let mut lengths = vec![f32::NAN; 3];
                assert!(grid_lengths(kernel, topology, &position, &mut lengths));
                let got: Vec<u32> = lengths.iter().map(|l| l.to_bits()).collect();
                assert_eq!(got, expected, "{rows} x {cols}, {kernel:?}");
            }
            // The whole measure: the grid pass against the same springs without the grid.
            let config = SimConfig::default();
            let mut particles = cloth.particles.clone();
            particles.position = position;
            let plain = Topology::new(
                SpringKind::ALL.map(|k| topology.springs_of(k).to_vec()),
                topology.triangles().to_vec(),
            );
            let (a, _) = measure(&config, topology, &particles, &[], &mut Vec::new());
            let (b, _) = measure(&config, &plain, &particles, &[], &mut Vec::new());
            assert_eq!(a, b, "{rows} x {cols}");
            assert_eq!(a.spring_energy.to_bits(), b.spring_energy.to_bits());
        }
    }

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
                let rest: Vec<f32> = run.iter().map(|s| s.rest_length).collect();
                let lanes = crate::simd::spring_lanes(kernel, &position, run, &rest, k, limit);
                let seq_bad = run.iter().position(|s| {
                    position[s.a as usize].distance(position[s.b as usize]) > limit * s.rest_length
                });
                assert_eq!(lanes.bad, seq_bad, "{kernel:?}, {} springs", run.len());
            }
            let rest: Vec<f32> = springs.iter().map(|s| s.rest_length).collect();
            let lanes = crate::simd::spring_lanes(kernel, &position, &springs, &rest, k, limit);
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
