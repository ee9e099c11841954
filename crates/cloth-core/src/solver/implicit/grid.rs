//! Implicit Euler's grid path: the solver of [`super`] on a cloth built by
//! [`crate::GridBuilder`], with the same arithmetic in the same order, so the same bits as the
//! reference path (tested with every kernel), but with no index lists:
//!
//! - the springs are the grid's six classes (warp, weft, the two diagonals, the two bends),
//!   each spring stored at its first end, its second end a fixed offset further; the blocks
//!   S and rest lengths are arrays per class;
//! - the vectors of the conjugate gradient are structure-of-arrays rows (x, y and z apart);
//! - a product A·p is one pass over bands of rows ([`band`]): for each row, the terms
//!   S·(p_a − p_b) of the springs whose first ends are in it go into a ring of three rows
//!   (each band recomputes the two rows above it, so bands never wait for one another), and
//!   the particle row then adds the twelve springs a particle can have, term by term over row
//!   runs, in the order of their indices in the reference path's spring list (the builder's),
//!   which is the order in which the reference path adds them ([`STENCIL`]);
//! - a dot product's terms are summed as [`super::reduce`] sums them on the reference path,
//!   task by task ([`super::task_sum`]), but in the passes that compute them where they can:
//!   the CG's update pass sums its own tasks, and each band of a product the tasks that lie
//!   within it (the few that straddle two bands are summed after the pass);
//! - the loops run in fixed-size lanes of [`L`] (the spring terms in lanes of [`T`], which
//!   keep their operands in registers) and are compiled for AVX2 and AVX-512 through
//!   [`crate::simd`] (`implicit_band`, `implicit_update`, `implicit_direction`).

use std::ops::Range;

use glam::{Mat3, Vec3};
use rayon::prelude::*;

use super::{
    CgStats, Filter, PARTICLES_PER_TASK, Sym3, assemble, constrain, gravity_term, new_contacts,
    reduce, release, spring_params, task_sum,
};
use crate::simd::{self, Kernel};
use crate::solver::SubstepCtx;
// The fixed-size chunks the vectorised loops work in: the explicit grid path's, `L` lanes.
use crate::solver::grid_kernel::{
    LANES as L, lanes as lane, lanes_mut as lane_mut, lanes_of, lanes_of_mut,
};
use crate::topology::{SpringKind, Topology};

/// The grid's spring classes, each at its first end `(r, c)`, its second end at
/// `(r + dr, c + dc)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Class {
    /// `(r, c)–(r + 1, c)`.
    Warp,
    /// `(r, c)–(r, c + 1)`.
    Weft,
    /// `(r, c)–(r + 1, c + 1)`.
    Down,
    /// `(r, c)–(r + 1, c − 1)` (the cell's other diagonal, from its top right corner).
    Up,
    /// `(r, c)–(r + 2, c)`.
    BendWarp,
    /// `(r, c)–(r, c + 2)`.
    BendWeft,
}

const CLASSES: [Class; 6] = [
    Class::Warp,
    Class::Weft,
    Class::Down,
    Class::Up,
    Class::BendWarp,
    Class::BendWeft,
];

/// The springs a particle can have, in the order of their indices in the reference path's
/// spring list (kinds in order; within a kind, by their first end's cell, row-major; within
/// a cell, the down diagonal before the up one and the warp bend before the weft bend), with
/// whether the particle is the spring's second end.
const STENCIL: [(Class, bool); 12] = [
    (Class::Warp, true),
    (Class::Warp, false),
    (Class::Weft, true),
    (Class::Weft, false),
    (Class::Down, true),
    (Class::Up, true),
    (Class::Up, false),
    (Class::Down, false),
    (Class::BendWarp, true),
    (Class::BendWeft, true),
    (Class::BendWarp, false),
    (Class::BendWeft, false),
];

impl Class {
    fn index(self) -> usize {
        self as usize
    }

    fn kind(self) -> SpringKind {
        match self {
            Class::Warp => SpringKind::Warp,
            Class::Weft => SpringKind::Weft,
            Class::Down | Class::Up => SpringKind::Shear,
            Class::BendWarp | Class::BendWeft => SpringKind::Bend,
        }
    }

    /// (dr, dc).
    fn step(self) -> (usize, isize) {
        match self {
            Class::Warp => (1, 0),
            Class::Weft => (0, 1),
            Class::Down => (1, 1),
            Class::Up => (1, -1),
            Class::BendWarp => (2, 0),
            Class::BendWeft => (0, 2),
        }
    }

    /// Index offset from the first end to the second.
    fn offset(self, cols: usize) -> usize {
        let (dr, dc) = self.step();
        (dr * cols).wrapping_add_signed(dc)
    }

    /// Rows and columns of the first ends.
    fn firsts(self, rows: usize, cols: usize) -> (Range<usize>, Range<usize>) {
        let (dr, dc) = self.step();
        let r = 0..rows.saturating_sub(dr);
        let c = match dc {
            -1 => 1.min(cols)..cols,
            d => 0..cols.saturating_sub(d.unsigned_abs()),
        };
        (r, c)
    }

    /// Rows and columns of the particles this class's springs reach as `second` ends or
    /// first ones.
    fn ends(self, rows: usize, cols: usize, second: bool) -> (Range<usize>, Range<usize>) {
        let (r, c) = self.firsts(rows, cols);
        if !second {
            return (r, c);
        }
        let (dr, dc) = self.step();
        let shift = |x: usize| x.wrapping_add_signed(dc);
        (r.start + dr..r.end + dr, shift(c.start)..shift(c.end))
    }
}

/// The chunks of [`run_terms`]: one AVX-512 register (two AVX2 ones) of `f32`, which leaves
/// a chunk's fifteen operands and three results in registers (twice as many spill with
/// [`L`]).
const T: usize = 16;

/// A copy of the [`T`] entries of `s` from `i`.
#[inline(always)]
fn copy(s: &[f32], i: usize) -> [f32; T] {
    *lanes_of(s, i)
}

/// y += a·x, lane by lane (a function of its own so that the references are known not to
/// overlap, which lets the compiler vectorise it).
#[inline(always)]
fn axpy(y: &mut [f32; L], a: f32, x: &[f32; L]) {
    for k in 0..L {
        y[k] += a * x[k];
    }
}

/// y −= a·x, lane by lane.
#[inline(always)]
fn axmy(y: &mut [f32; L], a: f32, x: &[f32; L]) {
    for k in 0..L {
        y[k] -= a * x[k];
    }
}

/// out = a·x + b·y + c·z, lane by lane (a row of a 3 × 3 block times a vector).
#[inline(always)]
fn row3<const N: usize>(
    out: &mut [f32; N],
    a: &[f32; N],
    b: &[f32; N],
    c: &[f32; N],
    x: &[f32; N],
    y: &[f32; N],
    z: &[f32; N],
) {
    for k in 0..N {
        out[k] = a[k] * x[k] + b[k] * y[k] + c[k] * z[k];
    }
}

/// out = p_a − p_b, lane by lane.
#[inline(always)]
fn sub(out: &mut [f32; T], a: &[f32; T], b: &[f32; T]) {
    for k in 0..T {
        out[k] = a[k] - b[k];
    }
}

/// Runs `body(j0, width)` over `0..len` in chunks: `width` is [`L`] for the whole chunks and
/// then 1 for each leftover index, so that `body` can take fixed-size lanes when it is `L`.
macro_rules! in_lanes {
    ($len:expr, |$j0:ident, $w:ident| $body:block) => {{
        let len = $len;
        let mut $j0 = 0;
        while $j0 + L <= len {
            let $w = L;
            $body
            $j0 += L;
        }
        while $j0 < len {
            let $w = 1;
            $body
            $j0 += 1;
        }
    }};
}

/// Three components in separate arrays.
type Soa = [Vec<f32>; 3];

/// Sizes the three arrays for `n` entries, as [`super::resize`] (nothing cleared).
fn resize_soa(v: &mut Soa, n: usize) {
    for a in v {
        a.resize(n, 0.0);
    }
}

/// One spring class's blocks S (diagonal x, y, z, then xy, xz, yz) and terms, per first end.
#[derive(Debug, Clone, Default)]
struct ClassArrays {
    block: [Vec<f32>; 6],
    term: Soa,
}

/// Filter kinds in [`GridScratch::kind`]: [`Filter::Free`], [`Filter::Fixed`],
/// [`Filter::Normal`] and [`Filter::Stuck`]. The kinds that fix all three directions have the
/// bit [`FIXED`] set, the contacts the bit [`NORMAL`].
const FREE: u8 = 0;
const FIXED: u8 = 1;
const NORMAL: u8 = 2;
const STUCK: u8 = 3;

/// The kind a filter is stored as.
#[inline]
fn encode(filter: Filter) -> u8 {
    match filter {
        Filter::Free => FREE,
        Filter::Fixed => FIXED,
        Filter::Stuck(_) => STUCK,
        Filter::Normal(_) => NORMAL,
    }
}

/// Scratch of the grid path, sized once per cloth.
#[derive(Debug, Clone, Default)]
pub(crate) struct GridScratch {
    class: [ClassArrays; 6],
    rhs: Soa,
    dv: Soa,
    r: Soa,
    c: Soa,
    q: Soa,
    s: Soa,
    /// The preconditioner's inverse blocks, column-major (`precond[3 * col + row]`).
    precond: [Vec<f32>; 9],
    /// [`FREE`], [`FIXED`] or [`NORMAL`].
    kind: Vec<u8>,
    normal: Soa,
    /// The kinetic friction impulse taken out of `rhs` ([`constrain`]).
    friction: Soa,
    dots: Vec<f32>,
    partial: Vec<f64>,
    /// Each band's ring of three rows of terms ([`band`]).
    ring: Vec<Vec<f32>>,
    /// Each band's sums of the tasks of [`reduce`] that lie within it ([`Self::multiply`]).
    band_sums: Vec<Vec<f64>>,
    /// Each class's rest lengths at the first ends, m (from the topology, once per cloth).
    rest: [Vec<f32>; 6],
    /// The spring count `rest` was built for.
    rest_built: usize,
}

/// Mutable chunks of the three arrays.
fn chunks3(v: &mut Soa, k: usize) -> impl IndexedParallelIterator<Item = [&mut [f32]; 3]> {
    let [x, y, z] = v;
    (
        x.par_chunks_mut(k),
        y.par_chunks_mut(k),
        z.par_chunks_mut(k),
    )
        .into_par_iter()
        .map(|(x, y, z)| [x, y, z])
}

/// Shared chunks of the three arrays.
fn chunks3_ref(v: &Soa, k: usize) -> impl IndexedParallelIterator<Item = [&[f32]; 3]> {
    let [x, y, z] = v;
    (x.par_chunks(k), y.par_chunks(k), z.par_chunks(k))
        .into_par_iter()
        .map(|(x, y, z)| [x, y, z])
}

/// Shared chunks of the nine preconditioner arrays.
fn chunks9(v: &[Vec<f32>; 9], k: usize) -> impl IndexedParallelIterator<Item = [&[f32]; 9]> {
    let [a, b, c, d, e, f, g, h, i] = v;
    (
        (a.par_chunks(k), b.par_chunks(k), c.par_chunks(k)),
        (d.par_chunks(k), e.par_chunks(k), f.par_chunks(k)),
        (g.par_chunks(k), h.par_chunks(k), i.par_chunks(k)),
    )
        .into_par_iter()
        .map(|((a, b, c), (d, e, f), (g, h, i))| [a, b, c, d, e, f, g, h, i])
}

/// P·r for particle `j` of a chunk, P's nine entries column-major: glam's `Mat3 * Vec3`, the
/// reference path's product.
#[inline]
fn precond_mul(m: &[&[f32]; 9], j: usize, r: [f32; 3]) -> [f32; 3] {
    (Mat3::from_cols_array(&m.map(|a| a[j])) * Vec3::from(r)).into()
}

/// [`Filter::apply`] on one particle, written with selects so that a loop of it vectorises
/// (the projection is computed for every particle, and kept only for a contact).
#[inline(always)]
fn apply(kind: u8, n: [f32; 3], p: [f32; 3]) -> [f32; 3] {
    let d = n[0] * p[0] + n[1] * p[1] + n[2] * p[2];
    let w = [p[0] - d * n[0], p[1] - d * n[1], p[2] - d * n[2]];
    let pick = |pv: f32, wv: f32| {
        if kind == FREE {
            pv
        } else if kind & FIXED != 0 {
            0.0
        } else {
            wv
        }
    };
    [pick(p[0], w[0]), pick(p[1], w[1]), pick(p[2], w[2])]
}

#[inline]
fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Particle `j` of three component slices, shared or mutable.
#[inline]
fn get<S: std::ops::Deref<Target = [f32]>>(v: &[S; 3], j: usize) -> [f32; 3] {
    [v[0][j], v[1][j], v[2][j]]
}

#[inline]
fn put(v: &mut [&mut [f32]; 3], j: usize, x: [f32; 3]) {
    v[0][j] = x[0];
    v[1][j] = x[1];
    v[2][j] = x[2];
}

/// Adds or subtracts the terms of the stencil to rows `r0..` of `y` (their
/// starting values already there): for each stencil entry in order, over the run of each row
/// that has that spring.
#[inline(always)]
fn stencil(rows: usize, cols: usize, r0: usize, y: &mut [&mut [f32]; 3], terms: &[&Soa; 6]) {
    let band_rows = y[0].len() / cols;
    for r in r0..r0 + band_rows {
        let row = (r - r0) * cols;
        let i0 = r * cols;
        for &(class, second) in &STENCIL {
            let (rr, cr) = class.ends(rows, cols, second);
            if !rr.contains(&r) || cr.is_empty() {
                continue;
            }
            let shift = if second { class.offset(cols) } else { 0 };
            let term = terms[class.index()];
            for (dst, src) in y.iter_mut().zip(term) {
                let dst = &mut dst[row + cr.start..row + cr.end];
                let src = &src[i0 + cr.start - shift..i0 + cr.end - shift];
                if second {
                    for (d, s) in dst.iter_mut().zip(src) {
                        *d -= *s;
                    }
                } else {
                    for (d, s) in dst.iter_mut().zip(src) {
                        *d += *s;
                    }
                }
            }
        }
    }
}

impl GridScratch {
    /// Each class's rest lengths, placed at the first ends from the topology's springs (the
    /// builder's, whose kinds and offsets tell their class).
    fn rest_lengths(&mut self, topology: &Topology, cols: usize) {
        let n = self.kind.len();
        if self.rest_built == topology.springs().len() && self.rest[0].len() == n {
            return;
        }
        for r in &mut self.rest {
            r.clear();
            r.resize(n, 0.0);
        }
        for kind in SpringKind::ALL {
            for s in topology.springs_of(kind) {
                let (a, b) = (s.a as usize, s.b as usize);
                let class = match kind {
                    SpringKind::Warp => Class::Warp,
                    SpringKind::Weft => Class::Weft,
                    SpringKind::Shear if b - a == cols + 1 => Class::Down,
                    SpringKind::Shear => Class::Up,
                    SpringKind::Bend if b - a == 2 * cols => Class::BendWarp,
                    SpringKind::Bend => Class::BendWeft,
                };
                self.rest[class.index()][a] = s.rest_length;
            }
        }
        self.rest_built = topology.springs().len();
    }

    /// Sizes the scratch for `n` particles. Nothing is cleared: every pass writes the entries
    /// it later reads (a class's entries outside its first ends are never read), so a substep
    /// on the same cloth neither allocates nor fills its scratch again.
    fn size(&mut self, n: usize) {
        for class in &mut self.class {
            for b in &mut class.block {
                b.resize(n, 0.0);
            }
            resize_soa(&mut class.term, n);
        }
        for v in [
            &mut self.rhs,
            &mut self.dv,
            &mut self.r,
            &mut self.c,
            &mut self.q,
            &mut self.s,
            &mut self.normal,
            &mut self.friction,
        ] {
            resize_soa(v, n);
        }
        for p in &mut self.precond {
            p.resize(n, 0.0);
        }
        self.kind.resize(n, FREE);
        self.dots.resize(n, 0.0);
        self.partial.resize(n.div_ceil(PARTICLES_PER_TASK), 0.0);
    }

    /// One ring per band of a product A·p (a row of the ring is written before it is read).
    fn size_rings(&mut self, rows: usize, cols: usize) {
        let bands = rows.div_ceil(band_rows(rows, cols));
        self.ring.resize_with(bands, Vec::new);
        for ring in &mut self.ring {
            ring.resize(3 * ring_row_len(cols), 0.0);
        }
        self.band_sums.resize_with(bands, Vec::new);
        let tasks = (band_rows(rows, cols) * cols).div_ceil(PARTICLES_PER_TASK);
        for sums in &mut self.band_sums {
            sums.resize(tasks, 0.0);
        }
    }

    /// `self.q = A·Δv` (unfiltered) for the Δv in `self.dv`.
    fn product_of_dv(&mut self, kernel: Kernel, rows: usize, cols: usize, mass: &[f32], diag: f32) {
        let mut q = std::mem::take(&mut self.q);
        let dv = std::mem::take(&mut self.dv);
        self.multiply(kernel, rows, cols, mass, diag, &dv, &mut q, false);
        (self.q, self.dv) = (q, dv);
    }

    /// Modified PCG (Baraff & Witkin 1998, §5.3) on the filters in `self.kind` and
    /// `self.normal`, from the Δv in `self.dv` with its product A·Δv in `self.q`
    /// ([`Self::product_of_dv`]), as on the reference path; returns the iterations, δ and δ0.
    #[allow(clippy::too_many_arguments)]
    fn pcg(
        &mut self,
        kernel: Kernel,
        rows: usize,
        cols: usize,
        mass: &[f32],
        diag: f32,
        floor: f64,
        tolerance: f32,
        cap: u32,
    ) -> (u32, f64, f64) {
        let k = PARTICLES_PER_TASK;
        // s = filter(b), c = P·s, δ0 = s·c.
        {
            let (kind, normal) = (&self.kind, &self.normal);
            chunks3(&mut self.s, k)
                .zip(chunks3(&mut self.c, k))
                .zip(chunks3_ref(&self.rhs, k))
                .zip(chunks9(&self.precond, k))
                .zip(self.dots.par_chunks_mut(k))
                .enumerate()
                .for_each(|(task, ((((mut s, mut c), b), m), dots))| {
                    let base = task * k;
                    for (j, dot_j) in dots.iter_mut().enumerate() {
                        let i = base + j;
                        let sv = apply(kind[i], nrm(normal, i), get(&b, j));
                        let cv = precond_mul(&m, j, sv);
                        put(&mut s, j, sv);
                        put(&mut c, j, cv);
                        *dot_j = dot(sv, cv);
                    }
                });
        }
        let delta0 = reduce(&self.dots, &mut self.partial).max(floor);
        // r = filter(b − A·Δv), c = filter(P·r), δ = r·c.
        let mut q = std::mem::take(&mut self.q);
        {
            let (kind, normal) = (&self.kind, &self.normal);
            chunks3(&mut self.r, k)
                .zip(chunks3(&mut self.c, k))
                .zip(chunks3_ref(&self.rhs, k))
                .zip(chunks3_ref(&q, k))
                .zip(chunks9(&self.precond, k))
                .zip(self.dots.par_chunks_mut(k))
                .enumerate()
                .for_each(|(task, (((((mut r, mut c), b), aq), m), dots))| {
                    let base = task * k;
                    for (j, dot_j) in dots.iter_mut().enumerate() {
                        let i = base + j;
                        let (bv, qv) = (get(&b, j), get(&aq, j));
                        let rv = apply(
                            kind[i],
                            nrm(normal, i),
                            [bv[0] - qv[0], bv[1] - qv[1], bv[2] - qv[2]],
                        );
                        let cv = apply(kind[i], nrm(normal, i), precond_mul(&m, j, rv));
                        put(&mut r, j, rv);
                        put(&mut c, j, cv);
                        *dot_j = dot(rv, cv);
                    }
                });
        }
        let mut delta = reduce(&self.dots, &mut self.partial);
        let tol2 = f64::from(tolerance) * f64::from(tolerance);
        let mut iterations = 0;
        while delta > tol2 * delta0 && iterations < cap {
            // q = filter(A·c), c·q.
            let c = std::mem::take(&mut self.c);
            let cq = self.multiply(kernel, rows, cols, mass, diag, &c, &mut q, true);
            self.c = c;
            if cq <= 0.0 {
                break;
            }
            let alpha = (delta / cq) as f32;
            // Δv += α·c, r −= α·q, s = P·r, r·s.
            chunks3(&mut self.dv, k)
                .zip(chunks3(&mut self.r, k))
                .zip(chunks3(&mut self.s, k))
                .zip(chunks3_ref(&self.c, k))
                .zip(chunks3_ref(&q, k))
                .zip(chunks9(&self.precond, k))
                .zip(self.dots.par_chunks_mut(k))
                .zip(self.partial.par_iter_mut())
                .for_each(|(((((((dv, r), s), c), q), m), dots), partial)| {
                    simd::implicit_update(kernel, alpha, [dv, r, s], c, q, m, dots);
                    // The task's share of `reduce`, in the same pass.
                    *partial = task_sum(dots);
                });
            let delta_old = delta;
            delta = self.partial.iter().sum();
            let beta = (delta / delta_old) as f32;
            // c = filter(s + β·c).
            chunks3(&mut self.c, k)
                .zip(chunks3_ref(&self.s, k))
                .zip(self.kind.par_chunks(k))
                .zip(chunks3_ref(&self.normal, k))
                .for_each(|(((c, s), kind), normal)| {
                    simd::implicit_direction(kernel, beta, c, s, kind, normal);
                });
            iterations += 1;
        }
        self.q = q;
        (iterations, delta, delta0)
    }

    /// y = A·p (`filtered`: then y is filtered too); returns p·y, the sum of [`reduce`]: each
    /// band sums the tasks that lie within it in the same pass, and the tasks that straddle
    /// two bands are summed after them.
    #[allow(clippy::too_many_arguments)]
    fn multiply(
        &mut self,
        kernel: Kernel,
        rows: usize,
        cols: usize,
        mass: &[f32],
        diag: f32,
        p: &Soa,
        y: &mut Soa,
        filtered: bool,
    ) -> f64 {
        let band_rows = band_rows(rows, cols);
        let job = BandJob {
            rows,
            cols,
            mass,
            diag,
            p,
            blocks: std::array::from_fn(|k| &self.class[k].block),
            kind: &self.kind,
            normal: &self.normal,
            filtered,
        };
        let per_band = band_rows * cols;
        let n = self.dots.len();
        // The tasks of `reduce` wholly within the particles `start..end`.
        let within = |start: usize, end: usize| {
            (start.div_ceil(PARTICLES_PER_TASK)..n.div_ceil(PARTICLES_PER_TASK))
                .take_while(move |t| ((t + 1) * PARTICLES_PER_TASK).min(n) <= end)
        };
        chunks3(y, per_band)
            .zip(self.dots.par_chunks_mut(per_band))
            .zip(self.ring.par_iter_mut())
            .zip(self.band_sums.par_iter_mut())
            .enumerate()
            .for_each(|(band, (((y, dots), ring), sums))| {
                simd::implicit_band(kernel, &job, band * band_rows, y, dots, ring);
                let start = band * per_band;
                for (t, sum) in within(start, start + dots.len()).zip(sums.iter_mut()) {
                    let a = t * PARTICLES_PER_TASK - start;
                    *sum = task_sum(&dots[a..(a + PARTICLES_PER_TASK).min(dots.len())]);
                }
            });
        for (t, partial) in self.partial.iter_mut().enumerate() {
            let (a, b) = (
                t * PARTICLES_PER_TASK,
                ((t + 1) * PARTICLES_PER_TASK).min(n),
            );
            let band = a / per_band;
            *partial = if (b - 1) / per_band == band {
                self.band_sums[band][t - (band * per_band).div_ceil(PARTICLES_PER_TASK)]
            } else {
                task_sum(&self.dots[a..b])
            };
        }
        self.partial.iter().sum()
    }
}

/// Rows per band of a product A·p: a band recomputes the terms of the two rows above it, so
/// bands of at least 16 rows (about 4096 particles).
fn band_rows(rows: usize, cols: usize) -> usize {
    (4096 / cols).max(16).min(rows.max(1))
}

/// The terms S·(p_a − p_b) of the springs whose first ends are `run` (indices), the second
/// ends `off` further, into `t` (the run's length).
#[inline(always)]
fn run_terms(block: &[Vec<f32>; 6], p: &Soa, run: Range<usize>, off: usize, t: [&mut [f32]; 3]) {
    let [a0, a1, a2, u0, u1, u2] = block;
    let [t0, t1, t2] = t;
    let [px, py, pz] = p;
    let len = run.len();
    let far = run.start + off..run.end + off;
    let (px_a, py_a, pz_a) = (&px[run.clone()], &py[run.clone()], &pz[run.clone()]);
    let (px_b, py_b, pz_b) = (&px[far.clone()], &py[far.clone()], &pz[far]);
    let (a0, a1, a2) = (&a0[run.clone()], &a1[run.clone()], &a2[run.clone()]);
    let (u0, u1, u2) = (&u0[run.clone()], &u1[run.clone()], &u2[run]);
    let (t0, t1, t2) = (&mut t0[..len], &mut t1[..len], &mut t2[..len]);
    let spring = |t: [&mut f32; 3], a: [f32; 3], u: [f32; 3], pa: [f32; 3], pb: [f32; 3]| {
        let (dx, dy, dz) = (pa[0] - pb[0], pa[1] - pb[1], pa[2] - pb[2]);
        *t[0] = a[0] * dx + u[0] * dy + u[1] * dz;
        *t[1] = u[0] * dx + a[1] * dy + u[2] * dz;
        *t[2] = u[1] * dx + u[2] * dy + a[2] * dz;
    };
    // Whole lanes; a run that is not a multiple of L ends with one more whole lane that
    // overlaps the one before (each term depends only on its own spring, so the overlap
    // writes the same values again) instead of scalar leftovers.
    let lanes = if len >= T { len.div_ceil(T) } else { 0 };
    let scalar_from = if len >= T { len } else { 0 };
    for l in 0..lanes {
        let j = (l * T).min(len - T);
        {
            let (t0, t1, t2) = (
                lanes_of_mut(t0, j),
                lanes_of_mut(t1, j),
                lanes_of_mut(t2, j),
            );
            // Copies of the operands (values, which the compiler keeps in registers).
            let (a0, a1, a2) = (&copy(a0, j), &copy(a1, j), &copy(a2, j));
            let (u0, u1, u2) = (&copy(u0, j), &copy(u1, j), &copy(u2, j));
            let (xa, ya, za) = (&copy(px_a, j), &copy(py_a, j), &copy(pz_a, j));
            let (xb, yb, zb) = (&copy(px_b, j), &copy(py_b, j), &copy(pz_b, j));
            let (mut dx, mut dy, mut dz) = ([0.0; T], [0.0; T], [0.0; T]);
            sub(&mut dx, xa, xb);
            sub(&mut dy, ya, yb);
            sub(&mut dz, za, zb);
            row3(t0, a0, u0, u1, &dx, &dy, &dz);
            row3(t1, u0, a1, u2, &dx, &dy, &dz);
            row3(t2, u1, u2, a2, &dx, &dy, &dz);
        }
    }
    for j in scalar_from..len {
        spring(
            [&mut t0[j], &mut t1[j], &mut t2[j]],
            [a0[j], a1[j], a2[j]],
            [u0[j], u1[j], u2[j]],
            [px_a[j], py_a[j], pz_a[j]],
            [px_b[j], py_b[j], pz_b[j]],
        );
    }
}

/// What a band of a product A·p reads.
pub(crate) struct BandJob<'a> {
    rows: usize,
    cols: usize,
    mass: &'a [f32],
    diag: f32,
    p: &'a Soa,
    blocks: [&'a [Vec<f32>; 6]; 6],
    kind: &'a [u8],
    normal: &'a Soa,
    filtered: bool,
}

/// Floats of one row of a band's ring: every class's three components of a row's terms.
fn ring_row_len(cols: usize) -> usize {
    CLASSES.len() * 3 * cols
}

/// The rows of y = A·p from row `r0` on (whole rows, `y`'s length), in one pass: the terms
/// of each row's springs (by their first ends, the two rows above the band's first recomputed)
/// go into `ring`, three rows of terms that stay in the cache, and each particle row then
/// takes (m + h·d)·p, the stencil's terms from the ring, the filter when asked; `dots` gets
/// p·y per particle.
#[inline(always)]
pub(crate) fn band(
    job: &BandJob<'_>,
    r0: usize,
    mut y: [&mut [f32]; 3],
    dots: &mut [f32],
    ring: &mut [f32],
) {
    let (rows, cols) = (job.rows, job.cols);
    let p = job.p;
    let row_len = ring_row_len(cols);
    let band_rows = dots.len() / cols;
    for r in r0.saturating_sub(2)..r0 + band_rows {
        // The terms of the springs whose first ends are in row r, into slot r mod 3.
        let slot = &mut ring[(r % 3) * row_len..(r % 3 + 1) * row_len];
        for (class, out) in CLASSES.iter().zip(slot.chunks_exact_mut(3 * cols)) {
            let (rr, cr) = class.firsts(rows, cols);
            if !rr.contains(&r) || cr.is_empty() {
                continue;
            }
            let (t0, rest) = out.split_at_mut(cols);
            let (t1, t2) = rest.split_at_mut(cols);
            let t = [
                &mut t0[cr.clone()],
                &mut t1[cr.clone()],
                &mut t2[cr.clone()],
            ];
            let run = r * cols + cr.start..r * cols + cr.end;
            run_terms(job.blocks[class.index()], p, run, class.offset(cols), t);
        }
        if r < r0 {
            continue;
        }
        // Particle row r.
        let row = (r - r0) * cols;
        let at = r * cols..(r + 1) * cols;
        let (px, py, pz) = (&p[0][at.clone()], &p[1][at.clone()], &p[2][at.clone()]);
        let [yx, yy, yz] = &mut y;
        let (yx, yy, yz) = (
            &mut yx[row..row + cols],
            &mut yy[row..row + cols],
            &mut yz[row..row + cols],
        );
        let m = &job.mass[at.clone()];
        for j in 0..cols {
            let s = m[j] + job.diag;
            (yx[j], yy[j], yz[j]) = (s * px[j], s * py[j], s * pz[j]);
        }
        for &(class, second) in &STENCIL {
            let (rr, cr) = class.ends(rows, cols, second);
            if !rr.contains(&r) || cr.is_empty() {
                continue;
            }
            // The spring's first end: this particle, or (r − dr, c − dc).
            let (dr, dc) = if second { class.step() } else { (0, 0) };
            let slot = (r - dr) % 3;
            let base = slot * row_len + class.index() * 3 * cols;
            let from = cr.start.wrapping_add_signed(-dc)..cr.end.wrapping_add_signed(-dc);
            for (k, dst) in [&mut *yx, &mut *yy, &mut *yz].into_iter().enumerate() {
                let src = &ring[base + k * cols..base + (k + 1) * cols][from.clone()];
                let dst = &mut dst[cr.clone()];
                if second {
                    for (d, s) in dst.iter_mut().zip(src) {
                        *d -= *s;
                    }
                } else {
                    for (d, s) in dst.iter_mut().zip(src) {
                        *d += *s;
                    }
                }
            }
        }
        let dots = &mut dots[row..row + cols];
        if job.filtered {
            let k = &job.kind[at.clone()];
            let n = job.normal;
            let (nx, ny, nz) = (&n[0][at.clone()], &n[1][at.clone()], &n[2][at]);
            for j in 0..cols {
                let v = apply(k[j], [nx[j], ny[j], nz[j]], [yx[j], yy[j], yz[j]]);
                [yx[j], yy[j], yz[j]] = v;
                dots[j] = dot([px[j], py[j], pz[j]], v);
            }
        } else {
            for j in 0..cols {
                dots[j] = dot([px[j], py[j], pz[j]], [yx[j], yy[j], yz[j]]);
            }
        }
    }
}

/// Δv += α·c, r −= α·q, s = P·r (P column-major, as glam's `Mat3 * Vec3`), `dots` = r·s.
#[inline(always)]
pub(crate) fn update(
    alpha: f32,
    [dv, r, s]: [[&mut [f32]; 3]; 3],
    c: [&[f32]; 3],
    q: [&[f32]; 3],
    m: [&[f32]; 9],
    dots: &mut [f32],
) {
    let len = dots.len();
    let [dvx, dvy, dvz] = dv;
    let (dvx, dvy, dvz) = (&mut dvx[..len], &mut dvy[..len], &mut dvz[..len]);
    let [rx, ry, rz] = r;
    let (rx, ry, rz) = (&mut rx[..len], &mut ry[..len], &mut rz[..len]);
    let [sx, sy, sz] = s;
    let (sx, sy, sz) = (&mut sx[..len], &mut sy[..len], &mut sz[..len]);
    let (cx, cy, cz) = (&c[0][..len], &c[1][..len], &c[2][..len]);
    let (qx, qy, qz) = (&q[0][..len], &q[1][..len], &q[2][..len]);
    let [m0, m1, m2, m3, m4, m5, m6, m7, m8] = m.map(|m| &m[..len]);
    // One particle: its nine preconditioner entries, c and q in, Δv, r and s updated; r·s.
    let one = |dv: [&mut f32; 3],
               r: [&mut f32; 3],
               s: [&mut f32; 3],
               c: [f32; 3],
               q: [f32; 3],
               m: [f32; 9]|
     -> f32 {
        for a in 0..3 {
            *dv[a] += alpha * c[a];
            *r[a] -= alpha * q[a];
        }
        let (a, b, c) = (*r[0], *r[1], *r[2]);
        let sv = [
            m[0] * a + m[3] * b + m[6] * c,
            m[1] * a + m[4] * b + m[7] * c,
            m[2] * a + m[5] * b + m[8] * c,
        ];
        (*s[0], *s[1], *s[2]) = (sv[0], sv[1], sv[2]);
        dot([a, b, c], sv)
    };
    in_lanes!(len, |j, w| {
        if w == L {
            let (dvx, dvy, dvz) = (lane_mut(dvx, j), lane_mut(dvy, j), lane_mut(dvz, j));
            let (rx, ry, rz) = (lane_mut(rx, j), lane_mut(ry, j), lane_mut(rz, j));
            let (sx, sy, sz) = (lane_mut(sx, j), lane_mut(sy, j), lane_mut(sz, j));
            let (cx, cy, cz) = (lane(cx, j), lane(cy, j), lane(cz, j));
            let (qx, qy, qz) = (lane(qx, j), lane(qy, j), lane(qz, j));
            let mm = [
                lane(m0, j),
                lane(m1, j),
                lane(m2, j),
                lane(m3, j),
                lane(m4, j),
                lane(m5, j),
                lane(m6, j),
                lane(m7, j),
                lane(m8, j),
            ];
            let d = lane_mut(dots, j);
            let [m0, m1, m2, m3, m4, m5, m6, m7, m8] = mm;
            axpy(dvx, alpha, cx);
            axpy(dvy, alpha, cy);
            axpy(dvz, alpha, cz);
            axmy(rx, alpha, qx);
            axmy(ry, alpha, qy);
            axmy(rz, alpha, qz);
            // s = P·r as glam's Mat3 * Vec3 (column-major); then r·s.
            row3(sx, m0, m3, m6, rx, ry, rz);
            row3(sy, m1, m4, m7, rx, ry, rz);
            row3(sz, m2, m5, m8, rx, ry, rz);
            row3(d, rx, ry, rz, sx, sy, sz);
        } else {
            dots[j] = one(
                [&mut dvx[j], &mut dvy[j], &mut dvz[j]],
                [&mut rx[j], &mut ry[j], &mut rz[j]],
                [&mut sx[j], &mut sy[j], &mut sz[j]],
                [cx[j], cy[j], cz[j]],
                [qx[j], qy[j], qz[j]],
                [
                    m0[j], m1[j], m2[j], m3[j], m4[j], m5[j], m6[j], m7[j], m8[j],
                ],
            );
        }
    });
}

/// c = filter(s + β·c).
#[inline(always)]
pub(crate) fn direction(
    beta: f32,
    c: [&mut [f32]; 3],
    s: [&[f32]; 3],
    kind: &[u8],
    normal: [&[f32]; 3],
) {
    let len = kind.len();
    let [cx, cy, cz] = c;
    let (cx, cy, cz) = (&mut cx[..len], &mut cy[..len], &mut cz[..len]);
    let (sx, sy, sz) = (&s[0][..len], &s[1][..len], &s[2][..len]);
    let (nx, ny, nz) = (&normal[0][..len], &normal[1][..len], &normal[2][..len]);
    let one = |c: [&mut f32; 3], s: [f32; 3], kind: u8, n: [f32; 3]| {
        let v = [
            s[0] + beta * *c[0],
            s[1] + beta * *c[1],
            s[2] + beta * *c[2],
        ];
        let out = apply(kind, n, v);
        (*c[0], *c[1], *c[2]) = (out[0], out[1], out[2]);
    };
    in_lanes!(len, |j, w| {
        if w == L {
            let (cx, cy, cz) = (lane_mut(cx, j), lane_mut(cy, j), lane_mut(cz, j));
            let (sx, sy, sz) = (lane(sx, j), lane(sy, j), lane(sz, j));
            let (nx, ny, nz) = (lane(nx, j), lane(ny, j), lane(nz, j));
            let kind: &[u8; L] = kind[j..j + L].try_into().expect("L entries");
            for k in 0..L {
                let v = [
                    sx[k] + beta * cx[k],
                    sy[k] + beta * cy[k],
                    sz[k] + beta * cz[k],
                ];
                [cx[k], cy[k], cz[k]] = apply(kind[k], [nx[k], ny[k], nz[k]], v);
            }
        } else {
            one(
                [&mut cx[j], &mut cy[j], &mut cz[j]],
                [sx[j], sy[j], sz[j]],
                kind[j],
                [nx[j], ny[j], nz[j]],
            );
        }
    });
}

/// Whether the grid path runs `ctx`'s cloth: one built by [`crate::GridBuilder`] (its springs
/// in the builder's order).
pub(crate) fn applies(topology: &Topology) -> bool {
    topology
        .grid()
        .is_some_and(|(rows, cols)| rows >= 2 && cols >= 2)
}

/// One linearised backward-Euler substep on the grid path (the stages of [`super::substep`]).
pub(super) fn substep(
    ctx: &mut SubstepCtx<'_>,
    force: &[Vec3],
    sc: &mut GridScratch,
    cg: &mut CgStats,
) {
    let Some((rows, cols)) = ctx.topology.grid() else {
        return;
    };
    let n = ctx.particles.len();
    let h = ctx.h;
    let cfg = ctx.config;
    let settings = cfg.implicit;
    let kernel = simd::kernel();
    sc.size(n);
    sc.size_rings(rows, cols);
    let diag = if cfg.forces.damping {
        h * cfg.damping
    } else {
        0.0
    };
    let gravity = if cfg.forces.gravity {
        cfg.gravity
    } else {
        Vec3::ZERO
    };
    let g_h = gravity.length() * h;

    sc.rest_lengths(ctx.topology, cols);

    // 1. Each class's blocks and right-hand-side terms h²·K·(v_b − v_a), at the first ends.
    {
        let (x, v) = (&ctx.particles.position, &ctx.particles.velocity);
        let rest = &sc.rest;
        sc.class
            .par_iter_mut()
            .zip(CLASSES.par_iter())
            .for_each(|(arrays, &class)| {
                let (k, c) = spring_params(cfg, class.kind());
                let off = class.offset(cols);
                let (rr, cr) = class.firsts(rows, cols);
                let rest = &rest[class.index()];
                let [a0, a1, a2, u0, u1, u2] = &mut arrays.block;
                let [t0, t1, t2] = &mut arrays.term;
                for r in rr {
                    for a in r * cols + cr.start..r * cols + cr.end {
                        let b = a + off;
                        let (block, term) = assemble(x[a], x[b], v[a], v[b], rest[a], k, c, h);
                        (a0[a], a1[a], a2[a]) = block.diag.into();
                        (u0[a], u1[a], u2[a]) = block.upper.into();
                        (t0[a], t1[a], t2[a]) = term.into();
                    }
                }
            });
    }

    // 2. Per particle: b = h·f + the terms, the preconditioner, the filter and the start of
    // Δv (as on the reference path).
    {
        let terms: [&Soa; 6] = std::array::from_fn(|k| &sc.class[k].term);
        let blocks: [&[Vec<f32>; 6]; 6] = std::array::from_fn(|k| &sc.class[k].block);
        let p = &*ctx.particles;
        let colliders = ctx.colliders;
        let band = (PARTICLES_PER_TASK / cols).max(1) * cols;
        let [px0, px1, px2, px3, px4, px5, px6, px7, px8] = &mut sc.precond;
        let precond = (
            (
                px0.par_chunks_mut(band),
                px1.par_chunks_mut(band),
                px2.par_chunks_mut(band),
            ),
            (
                px3.par_chunks_mut(band),
                px4.par_chunks_mut(band),
                px5.par_chunks_mut(band),
            ),
            (
                px6.par_chunks_mut(band),
                px7.par_chunks_mut(band),
                px8.par_chunks_mut(band),
            ),
        )
            .into_par_iter();
        chunks3(&mut sc.rhs, band)
            .zip(chunks3(&mut sc.dv, band))
            .zip(chunks3(&mut sc.normal, band))
            .zip(chunks3(&mut sc.friction, band))
            .zip(sc.kind.par_chunks_mut(band))
            .zip(precond)
            .zip(sc.dots.par_chunks_mut(band))
            .enumerate()
            .for_each(
                |(task, ((((((mut rhs, mut dv), mut normal), mut friction), kind), pre), dots))| {
                    let ((m0, m1, m2), (m3, m4, m5), (m6, m7, m8)) = pre;
                    let mut m = [m0, m1, m2, m3, m4, m5, m6, m7, m8];
                    let base = task * band;
                    for j in 0..kind.len() {
                        let i = base + j;
                        put(&mut rhs, j, (h * force[i]).into());
                    }
                    stencil(rows, cols, base / cols, &mut rhs, &terms);
                    for j in 0..kind.len() {
                        let i = base + j;
                        let (r, c) = (i / cols, i % cols);
                        let mut sum = Sym3 {
                            diag: Vec3::splat(p.mass[i] + diag),
                            upper: Vec3::ZERO,
                        };
                        for &(class, second) in &STENCIL {
                            let (rr, cr) = class.ends(rows, cols, second);
                            if rr.contains(&r) && cr.contains(&c) {
                                let at = if second { i - class.offset(cols) } else { i };
                                let b = blocks[class.index()];
                                sum = sum
                                    + Sym3 {
                                        diag: Vec3::new(b[0][at], b[1][at], b[2][at]),
                                        upper: Vec3::new(b[3][at], b[4][at], b[5][at]),
                                    };
                            }
                        }
                        let inverse = sum.to_mat3().inverse();
                        dots[j] = gravity_term(gravity, h, p.mass[i], p.inv_mass[i], inverse);
                        let inverse = inverse.to_cols_array();
                        for (dst, value) in m.iter_mut().zip(inverse) {
                            dst[j] = value;
                        }
                        let mut b = Vec3::from(get(&rhs, j));
                        let mut fr = Vec3::ZERO;
                        let (filter, start) = constrain(
                            p.position[i],
                            p.velocity[i],
                            p.mass[i] + diag,
                            p.inv_mass[i],
                            &mut b,
                            &mut fr,
                            colliders,
                            h,
                            g_h,
                        );
                        put(&mut rhs, j, b.into());
                        put(&mut friction, j, fr.into());
                        put(&mut dv, j, start.into());
                        kind[j] = encode(filter);
                        put(&mut normal, j, filter.normal().unwrap_or(Vec3::ZERO).into());
                    }
                },
            );
    }

    let floor = reduce(&sc.dots, &mut sc.partial);

    // 3. Modified PCG (Baraff & Witkin 1998, §5.3), as on the reference path.
    let mass = &ctx.particles.mass;
    sc.product_of_dv(kernel, rows, cols, mass, diag);
    let (mut iterations, mut delta, mut delta0) = sc.pcg(
        kernel,
        rows,
        cols,
        mass,
        diag,
        floor,
        settings.tolerance,
        settings.max_iterations,
    );

    // 4. The contacts that pull their particle in are released and the solve runs again, once
    // (as on the reference path), from this product: Δv and A are unchanged.
    let k = PARTICLES_PER_TASK;
    sc.product_of_dv(kernel, rows, cols, mass, diag);
    let released: u32 = sc
        .kind
        .par_chunks_mut(k)
        .zip(chunks3(&mut sc.normal, k))
        .zip(chunks3(&mut sc.rhs, k))
        .zip(chunks3_ref(&sc.friction, k))
        .zip(chunks3_ref(&sc.q, k))
        .map(|((((kind, mut normal), mut rhs), friction), aq)| {
            let mut count = 0;
            for (j, kind) in kind.iter_mut().enumerate() {
                if *kind & NORMAL == 0 {
                    continue;
                }
                let n = Vec3::from(get(&normal, j));
                let mut filter = if *kind == STUCK {
                    Filter::Stuck(n)
                } else {
                    Filter::Normal(n)
                };
                let mut b = Vec3::from(get(&rhs, j));
                let (fr, aqv) = (get(&friction, j).into(), get(&aq, j).into());
                if release(&mut filter, &mut b, fr, aqv) {
                    *kind = encode(filter);
                    put(&mut normal, j, [0.0; 3]);
                    put(&mut rhs, j, b.into());
                    count += 1;
                }
            }
            count
        })
        .sum();
    if released > 0 && iterations < settings.max_iterations {
        let cap = settings.max_iterations - iterations;
        let (more, d, d0) = sc.pcg(
            kernel,
            rows,
            cols,
            mass,
            diag,
            floor,
            settings.tolerance,
            cap,
        );
        iterations += more;
        (delta, delta0) = (d, d0);
    }
    let tol2 = f64::from(settings.tolerance) * f64::from(settings.tolerance);
    *cg = CgStats::new(iterations, delta, delta0, tol2);
    // 5. The new velocities and positions (friction was in the solve), then the contacts the
    // substep reached.
    let p = &mut *ctx.particles;
    p.position
        .par_chunks_mut(k)
        .zip(p.velocity.par_chunks_mut(k))
        .zip(chunks3_ref(&sc.dv, k))
        .for_each(|((x, v), dv)| {
            for (j, (x, v)) in x.iter_mut().zip(v).enumerate() {
                *v += Vec3::from(get(&dv, j));
                *x += h * *v;
            }
        });
    let colliders = ctx.colliders;
    let kind = &sc.kind;
    ctx.contacts.contacts = new_contacts(p, colliders, h, |i| kind[i] & NORMAL != 0);
}

#[inline]
fn nrm(normal: &Soa, i: usize) -> [f32; 3] {
    [normal[0][i], normal[1][i], normal[2][i]]
}
