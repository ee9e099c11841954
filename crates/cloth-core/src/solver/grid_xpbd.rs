//! XPBD's fast path on a regular grid: coloured Gauss–Seidel over shifted rows, in parallel,
//! with optional multi-resolution strain limits.
//!
//! The reference XPBD ([`super::xpbd`]) sweeps the springs one by one in storage order, a
//! sequential Gauss–Seidel sweep. On a cloth built by [`crate::GridBuilder`] the springs of
//! one class (warp, weft, the two shear diagonals, the two bend directions) split into two
//! **colours** whose springs share no particle:
//!
//! | class | joins | colour of the spring at slot `(r, c)` |
//! |---|---|---|
//! | warp, diagonal, anti-diagonal | `(r, ·)`–`(r + 1, ·)` | `r mod 2` |
//! | vertical bend | `(r, c)`–`(r + 2, c)` | `⌊r / 2⌋ mod 2` |
//! | weft | `(r, c)`–`(r, c + 1)` | `c mod 2` |
//! | horizontal bend | `(r, c)`–`(r, c + 2)` | `⌊c / 2⌋ mod 2` |
//!
//! Projecting the springs of one colour one after the other gives the same result in any
//! order, so a colour is projected all at once, as whole rows: a vertical class pairs row
//! `r` with row `r + d` (two disjoint slices, updated in place); a horizontal class computes
//! each spring's correction from the row (masked to the colour) and then applies it to both
//! ends (the horizontal bend, at spacing 2, with AVX-512 computes only its colour's springs:
//! the row's groups of four columns split into two vectors of ends by permutes,
//! [`crate::simd::xpbd_quads`], the same bits). One sweep (stage 2 of a substep):
//!
//! 1. warp, weft, diagonal, anti-diagonal, vertical bend, horizontal bend, each colour 0
//!    then colour 1, as compliant XPBD constraints (the reference's formula: compliance
//!    α = 1/k, dashpot as constraint damping); with `XpbdSettings::chains`, shear and bend
//!    first and then the warp and the weft as whole chains ([`super::chains`]: every column,
//!    then every row, each solved exactly by a tridiagonal solve, in blocks of 16 chains two
//!    blocks at a time, the weft taking the warp's positions straight from its blocks and,
//!    between rounds, the warp the weft's),
//!    `XpbdSettings::chain_rounds` times in turn (each round after a contact pass when there
//!    are several); with `XpbdSettings::shear_chains`, the diagonals and then the
//!    anti-diagonals as chains along the grid's diagonal lines too, in place of their pair
//!    passes ([`XpbdGrid::shear_chains`]);
//! 2. the structural strain limit, when `XpbdSettings::structural_limit` is set (after
//!    Provot 1995): every warp and weft spring at most `(1 + limit)` times its rest length,
//!    the one-sided limit of the next stage at spacing 1, run before its wider spacings; the
//!    multi-resolution strain limits, when `XpbdSettings::hierarchy_levels > 0` (after
//!    Wang, O'Brien & Ramamoorthi 2010, "Multi-resolution isotropic strain limiting"): for
//!    each spacing s = 2, 4, …, 2^levels, particles `s` apart along the warp and along the
//!    weft may be at most `(1 + hierarchy_slack)` times their rest distance apart (a
//!    one-sided, inextensible constraint, coloured by `⌊r / s⌋` or `⌊c / s⌋`). They carry a
//!    pull across `s` particles in one projection, which plain sweeps need `s` sweeps (or
//!    substeps) for;
//! 3. collider contacts with position-level Coulomb friction: the reference's routine
//!    ([`super::xpbd::contact`]), on the arrays for spheres and planes that do not turn
//!    ([`contact_soa`], every lane computed and selected, the same bits; run collider by
//!    collider on the 64-particle sub-chunks not clear of that collider,
//!    [`contacts_soa_row`]), per particle for other colliders (chunks clear of every collider
//!    skipped).
//!
//! The substep's state stays in structure-of-arrays form (x, y, z, vx, vy, vz and the start
//! positions) from the first substep of a step to its end ([`XpbdGrid::sync`], called by the
//! solver's `end_step`): the prediction, the sweeps, the velocities `(x − start)/h` and
//! continuous collision all read and write the arrays, so no substep converts between `Vec3`
//! and arrays. The last sweep's contacts, the velocities and continuous collision run as one
//! pass, row by row ([`XpbdGrid::finish`]; continuous collision takes the culls of the
//! explicit path on the arrays, then the reference's per-particle routine on the candidates).
//!
//! Every pass writes disjoint rows, so the rows are shared among the threads of the current
//! rayon pool in any way and the result is the same bits for every thread count. The
//! arithmetic is plain IEEE `f32` (no fused multiply-add, exact `sqrt` and division), so
//! every instruction set gives the same bits too. The order differs from the reference's
//! storage order, so the two agree to within the solver's convergence, not bit for bit
//! (tested in `tests/xpbd_grid.rs`).

use glam::Vec3;
use rayon::prelude::*;

use super::SubstepCtx;
use super::chains::Multipliers;
use super::grid_kernel::{CLASSES, load_rest};
use super::placed::Placed;
use crate::config::SimConfig;
use crate::topology::Topology;

/// How a pass projects its pairs.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Mode {
    /// A compliant XPBD distance constraint: α̃ = 1/(k h²), γ = c/(k h).
    Compliant { alpha: f32, gamma: f32 },
    /// A one-sided limit: the pair may be at most its `rest` entry apart.
    Limit,
}

/// Multi-resolution strain limits at one spacing.
#[derive(Debug, Clone, Default)]
struct Level {
    spacing: usize,
    /// Largest allowed distance by slot `r * cols + c`: `(r, c)`–`(r + s, c)`.
    vertical: Vec<f32>,
    /// Largest allowed distance by slot: `(r, c)`–`(r, c + s)`.
    horizontal: Vec<f32>,
    /// Whether every row of `vertical`, of `horizontal`, holds the same bits as its first
    /// row (a flat rest grid): the structural limit's pass then reads the first row for every
    /// row, a quarter of its reads fewer.
    uniform: [bool; 2],
}

/// One scratch vector per thread of a pool, each behind its own (uncontended) lock: what a
/// thread leaves there is never read by the next user, so which thread takes which does not
/// change a result. A clone starts empty.
#[derive(Debug, Default)]
struct ThreadScratch {
    /// One vector per thread, each `len` floats long, each starting on a cache line of its
    /// own ([`Placed`]: the chain solves load whole lines of it).
    each: Vec<std::sync::Mutex<Placed>>,
    len: usize,
}

impl Clone for ThreadScratch {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl ThreadScratch {
    /// One vector of at least `len` floats per thread of the current pool (allocates only
    /// when the pool or the length grew).
    fn prepare(&mut self, len: usize, slot: usize) {
        let threads = rayon::current_num_threads().max(1);
        if self.each.len() != threads || self.len < len {
            self.len = self.len.max(len);
            self.each = (0..threads)
                .map(|t| {
                    let mut v = Placed::default();
                    v.reset(self.len, slot + t);
                    std::sync::Mutex::new(v)
                })
                .collect();
        }
    }

    /// The calling thread's vector (the first one off a pool).
    fn mine(&self) -> std::sync::MutexGuard<'_, Placed> {
        let i = rayon::current_thread_index().unwrap_or(0) % self.each.len();
        // A poisoned lock only means a panic elsewhere; the scratch is rewritten before use.
        self.each[i]
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

/// Scratch of the grid XPBD path.
#[derive(Debug, Default, Clone)]
pub(crate) struct XpbdGrid {
    /// `(rows, cols, springs)` the scratch was prepared for, and whether it is the builder's
    /// grid.
    key: Option<(usize, usize, usize, bool)>,
    rows: usize,
    cols: usize,
    /// Rest length per class and slot (see [`CLASSES`]).
    rest: [Placed; 6],
    /// Whether every row of a class's `rest` holds the same bits as its first row (a flat
    /// rest grid, as the grid builder makes): its passes then read the first row for every
    /// row ([`Shared::rest_slot`]).
    uniform: [bool; 6],
    /// Lagrange multipliers per class and slot, reset every substep.
    lambda: [Placed; 6],
    /// Multipliers the strain limits are handed (they have none; never read).
    spare: Placed,
    /// Positions x, y, z (structure of arrays): the state from the first substep of a step to
    /// [`Self::sync`] at its end.
    pos: [Placed; 3],
    /// Positions at the start of the current substep.
    prev: [Placed; 3],
    /// Inverse masses.
    inv_mass: Placed,
    /// Corrections of a horizontal pass, by component.
    corr: [Placed; 3],
    /// Colour masks (1.0 in the colour, 0.0 outside) by log2 of the spacing and colour, each
    /// on cache lines of its own ([`Placed`]).
    masks: Vec<[Placed; 2]>,
    /// Whether the multipliers are kept (more than one sweep per substep).
    keep: bool,
    /// Strain-limit levels and the `(levels, slack bits)` they were built for.
    levels: Vec<Level>,
    levels_key: Option<(Option<u32>, u32, u32)>,
    /// Air force of every triangle divided by 3 (the share of each corner) of the cell rows
    /// between two bands of [`PREDICT_BAND`] rows (cell row `(k + 1)·PREDICT_BAND − 1` after
    /// band `k`), `6·(cols − 1)` floats each: first triangles' x, y, z, second triangles' x,
    /// y, z ([`air_cells`]).
    air_edges: Placed,
    /// The cell rows inside a band, two at a time (the one above the row being predicted and
    /// the one below), one ring per thread of the pool.
    air_ring: ThreadScratch,
    /// Velocities (structure of arrays), kept like `pos`.
    vel: [Placed; 3],
    /// Blocks of the chain solves (`XpbdSettings::chains`): warp (columns), weft (rows), each
    /// starting on a cache line ([`Placed`]; the allocator aligns a `Vec` to 16 bytes only, and
    /// every 16-lane load and store of a block then straddled two lines).
    chains: [Placed; 2],
    /// The chain solves' scratch, one per thread of the pool.
    chain_work: ThreadScratch,
    /// Blocks of the shear chains (`XpbdSettings::shear_chains`): diagonals, anti-diagonals
    /// (their statics and start positions flagged at `chain_statics[2 + dir]` and
    /// `chain_starts[2 + dir]`).
    shear_blocks: [Placed; 2],
    /// Whether each direction's blocks hold the current inverse masses and rest lengths.
    chain_statics: [bool; 4],
    /// Whether each direction's blocks hold this substep's start positions (reset by
    /// [`XpbdGrid::sweeps`]; later rounds and sweeps of the substep reuse them).
    chain_starts: [bool; 4],
    /// Whether `pos` and `vel` hold the state (from the first substep of a step to
    /// [`XpbdGrid::sync`] at its end) rather than the particles.
    resident: bool,
}

/// Whether the grid path runs XPBD's sweeps for these settings: a cloth built by the grid
/// builder, no self-collision and no tethers to pinned particles (which the reference path
/// handles).
pub(crate) fn applies(config: &SimConfig, topology: &Topology, pinned: bool) -> bool {
    topology.grid().is_some() && config.self_collision.is_none() && !(config.xpbd.tethers && pinned)
}

impl XpbdGrid {
    /// Checks (once per topology) that the springs are the builder's grid; returns whether
    /// the grid path can run.
    pub(crate) fn prepare(&mut self, topology: &Topology, n: usize) -> bool {
        let Some((rows, cols)) = topology.grid() else {
            return false;
        };
        let springs = topology.springs().len();
        if let Some((r, c, s, ok)) = self.key
            && (r, c, s) == (rows, cols, springs)
        {
            return ok;
        }
        let ok = rows * cols == n
            && rows >= 2
            && cols >= 2
            && load_rest(&mut self.rest, topology, rows, cols)
            && grid_triangles(topology, rows, cols);
        self.key = Some((rows, cols, springs, ok));
        self.uniform = [false; 6];
        if ok {
            for (class, uniform) in self.uniform.iter_mut().enumerate() {
                let rows_of_class = rows - CLASSES[class].0;
                *uniform = rows_equal(&self.rest[class][..rows_of_class * cols], cols);
            }
        }
        self.chain_statics = [false; 4];
        self.resident = false;
        self.levels_key = None;
        if ok {
            self.rows = rows;
            self.cols = cols;
            // Each array at its own line of a page (slots 0–5 are the rest lengths').
            let arrays = self
                .lambda
                .iter_mut()
                .chain(&mut self.pos)
                .chain(&mut self.prev)
                .chain(&mut self.corr)
                .chain([&mut self.inv_mass, &mut self.spare])
                .chain(&mut self.vel);
            let mut slot = 6;
            for a in arrays {
                a.reset(n, slot);
                slot += 1;
            }
            self.air_edges
                .reset(rows.div_ceil(PREDICT_BAND) * 6 * (cols - 1), slot);
            self.masks.clear();
            let mut slot = MASK_SLOT;
            let mut s = 1;
            while s < cols.max(rows) {
                self.masks.push([0, 1].map(|colour| {
                    let mut mask = Placed::default();
                    mask.reset(cols, slot);
                    slot += 1;
                    for (c, m) in mask.iter_mut().enumerate() {
                        *m = f32::from(u8::from((c / s) % 2 == colour));
                    }
                    mask
                }));
                s *= 2;
            }
        }
        ok
    }

    /// Rest lengths of a class by slot (after a successful [`Self::prepare`]).
    pub(crate) fn class_rest(&self, class: usize) -> &[f32] {
        &self.rest[class]
    }

    /// Builds the strain limits from the rest shape when their settings changed: the
    /// structural limit (`structural`, spacing 1) first, then the multi-resolution levels.
    fn prepare_levels(&mut self, structural: Option<f32>, levels: u32, slack: f32, rest: &[Vec3]) {
        let key = (structural.map(f32::to_bits), levels, slack.to_bits());
        if self.levels_key == Some(key) {
            return;
        }
        self.levels_key = Some(key);
        let (rows, cols) = (self.rows, self.cols);
        self.levels.clear();
        let spacings = structural
            .map(|limit| (1, limit))
            .into_iter()
            .chain((1..=levels).map(|l| (1_usize << l, slack)));
        for (s, slack) in spacings {
            if s >= rows.max(cols) {
                break;
            }
            let scale = 1.0 + slack;
            let limit = |a: usize, b: usize| scale * rest[a].distance(rest[b]);
            let mut level = Level {
                spacing: s,
                vertical: vec![0.0; rows * cols],
                horizontal: vec![0.0; rows * cols],
                uniform: [false; 2],
            };
            for r in 0..rows {
                for c in 0..cols {
                    let i = r * cols + c;
                    if r + s < rows {
                        level.vertical[i] = limit(i, i + s * cols);
                    }
                    if c + s < cols {
                        level.horizontal[i] = limit(i, i + s);
                    }
                }
            }
            level.uniform = [
                rows_equal(&level.vertical[..(rows - s.min(rows)) * cols], cols),
                rows_equal(&level.horizontal, cols),
            ];
            self.levels.push(level);
        }
    }

    /// Loads the particles' positions and velocities into the arrays at the first substep of
    /// a step (and whenever a substep left them, see [`Self::sync`]); from then on the state
    /// stays in the arrays across the step's substeps. Also refreshes the inverse masses (they
    /// change only between steps).
    fn load(&mut self, p: &crate::particles::Particles) {
        if self.resident {
            return;
        }
        scatter(&p.position, &mut self.pos, self.cols);
        scatter(&p.velocity, &mut self.vel, self.cols);
        // The chain blocks keep their copy of the inverse masses until one changes (compared
        // in one pass the compiler vectorises).
        if !self
            .inv_mass
            .iter()
            .zip(&p.inv_mass)
            .fold(true, |same, (a, b)| same & (a.to_bits() == b.to_bits()))
        {
            self.inv_mass.copy_from_slice(&p.inv_mass);
            self.chain_statics = [false; 4];
        }
        self.resident = true;
    }

    /// Writes the state kept in the arrays back to the particles (positions and velocities):
    /// at the end of a step, and before a substep that leaves the grid path.
    pub(crate) fn sync(&mut self, p: &mut crate::particles::Particles) {
        if !self.resident {
            return;
        }
        self.resident = false;
        let cols = self.cols;
        let n = p.position.len();
        let ([x, y, z], [vx, vy, vz]) = (&self.pos, &self.vel);
        fn rows(a: &[f32], n: usize, cols: usize) -> rayon::slice::Chunks<'_, f32> {
            a[..n].par_chunks(cols)
        }
        let rows = |a| rows(a, n, cols);
        p.position
            .par_chunks_mut(cols)
            .zip(p.velocity.par_chunks_mut(cols))
            .zip(rows(x).zip(rows(y)).zip(rows(z)))
            .zip(rows(vx).zip(rows(vy)).zip(rows(vz)))
            .for_each(|(((pos, vel), ((x, y), z)), ((vx, vy), vz))| {
                // Row slices zipped: no index arithmetic or bounds checks in the loops.
                for (p, ((x, y), z)) in pos.iter_mut().zip(x.iter().zip(y).zip(z)) {
                    *p = Vec3::new(*x, *y, *z);
                }
                for (v, ((x, y), z)) in vel.iter_mut().zip(vx.iter().zip(vy).zip(vz)) {
                    *v = Vec3::new(*x, *y, *z);
                }
            });
    }

    /// Stage 1 of an XPBD substep on the grid, rows in parallel, on the arrays, with the
    /// reference's arithmetic in the reference's order (so the same bits): the external force
    /// of every particle (weight, global damping capped at m/h,
    /// [`crate::forces::capped_damping`], then its share of the air force of each adjacent
    /// triangle in triangle order), then `v ← v + h·f/m`, `start ← x`, `x ← x + h·v`,
    /// component by component as loops over the row that the compiler vectorises. One pass
    /// over bands of [`PREDICT_BAND`] rows: each row is predicted right after the air of the
    /// cell row below it (from that row and the next, neither predicted yet) is computed into
    /// a two-row ring of the thread's; the cell rows between two bands, which read a row of
    /// each, are computed in a short pass before. (Air written to whole-cloth arrays in a pass
    /// of its own and read back by the prediction took 7 % more time per frame on the 256²
    /// drape on one thread, 2 % on two.)
    pub(crate) fn predict(&mut self, ctx: &mut SubstepCtx<'_>) {
        let cfg = ctx.config;
        let (rows, cols, h) = (self.rows, self.cols, ctx.h);
        let sw = cfg.forces;
        let gravity = if sw.gravity { cfg.gravity } else { Vec3::ZERO };
        let damping = if sw.damping { cfg.damping } else { 0.0 };
        let air = super::grid_kernel::air_active(cfg);
        let p = &*ctx.particles;
        self.load(p);
        let coeff = AirCoefficients::of(cfg, ctx.wind);
        let kernel = crate::simd::kernel();
        let m = cols - 1;
        let band = PREDICT_BAND * cols;
        if air {
            // The cell rows between two bands first (each reads the last row of one band and
            // the first of the next, which the fused pass below then changes).
            let [x, y, z] = &self.pos;
            let [vx, vy, vz] = &self.vel;
            let state = [[&x[..], &y[..], &z[..]], [&vx[..], &vy[..], &vz[..]]];
            self.air_edges[..(rows - 1) / PREDICT_BAND * 6 * m]
                .par_chunks_mut(6 * m)
                .enumerate()
                .for_each(|(k, out)| {
                    let r = (k + 1) * PREDICT_BAND - 1;
                    air_cells(kernel, &coeff, state, (r, cols), out);
                });
            self.air_ring.prepare(2 * 6 * m, AIR_SLOT);
        }
        let (edges, ring) = (&self.air_edges, &self.air_ring);
        let (mass, w) = (&p.mass[..], &self.inv_mass[..]);
        let [x, y, z] = &mut self.pos;
        let [vx, vy, vz] = &mut self.vel;
        let [x0, y0, z0] = &mut self.prev;
        // Bands of rows, each row predicted right after the air of the cell row below it
        // (from the row and the next, neither predicted yet); the cell rows between bands come
        // from `edges`.
        x.par_chunks_mut(band)
            .zip(y.par_chunks_mut(band))
            .zip(z.par_chunks_mut(band))
            .zip(vx.par_chunks_mut(band))
            .zip(vy.par_chunks_mut(band))
            .zip(vz.par_chunks_mut(band))
            .zip(x0.par_chunks_mut(band))
            .zip(y0.par_chunks_mut(band))
            .zip(z0.par_chunks_mut(band))
            .enumerate()
            .for_each(|(k, ((((((((x, y), z), vx), vy), vz), x0), y0), z0))| {
                let r0 = k * PREDICT_BAND;
                let here = x.len() / cols;
                let mut ring = air.then(|| ring.mine());
                let edge = |k: usize| &edges[k * 6 * m..(k + 1) * 6 * m];
                for i in 0..here {
                    let r = r0 + i;
                    let at = i * cols..(i + 1) * cols;
                    // The cell row below row r, when there is one: computed here (inside
                    // the band) or taken from the edges (the band's last row).
                    if let Some(ring) = ring.as_deref_mut()
                        && r + 1 < rows
                        && i + 1 < here
                    {
                        let out = &mut ring[(r % 2) * 6 * m..][..6 * m];
                        let rows2 = i * cols..(i + 2) * cols;
                        let state = [
                            [&x[rows2.clone()], &y[rows2.clone()], &z[rows2.clone()]],
                            [&vx[rows2.clone()], &vy[rows2.clone()], &vz[rows2]],
                        ];
                        air_cells(kernel, &coeff, state, (0, cols), out);
                    }
                    let cells = |above: bool| -> Option<&[f32]> {
                        let rr = if above { r.checked_sub(1)? } else { r };
                        if !air || rr + 1 >= rows {
                            return None;
                        }
                        Some(if rr + 1 == r0 || rr + 1 == r0 + here {
                            edge(rr / PREDICT_BAND)
                        } else {
                            &ring.as_deref().expect("air")[(rr % 2) * 6 * m..][..6 * m]
                        })
                    };
                    let (up, down) = (cells(true), cells(false));
                    let (m_row, w_row) = (&mass[r * cols..][..cols], &w[r * cols..][..cols]);
                    let [
                        (x_row, x_next),
                        (y_row, y_next),
                        (z_row, z_next),
                        (x0_row, x0_next),
                        (y0_row, y0_next),
                        (z0_row, z0_next),
                    ] = [&mut *x, &mut *y, &mut *z, &mut *x0, &mut *y0, &mut *z0]
                        .map(|a| row_and_next(a, i, cols));
                    let lanes = [
                        (
                            x_row,
                            &mut vx[at.clone()],
                            x0_row,
                            gravity.x,
                            [x_next, x0_next],
                        ),
                        (
                            y_row,
                            &mut vy[at.clone()],
                            y0_row,
                            gravity.y,
                            [y_next, y0_next],
                        ),
                        (z_row, &mut vz[at], z0_row, gravity.z, [z_next, z0_next]),
                    ];
                    for (comp, (x, v, x0, g, next)) in lanes.into_iter().enumerate() {
                        // The next row's lines of this component (positions and start
                        // positions), taken for writing while this one runs: the chain
                        // solves' gathers read them on every thread, and stores that wait
                        // for a line held by the other core stalled this pass (at 512² on 2
                        // threads it took 7 times the CPU time of a 1-thread run).
                        for a in next {
                            crate::simd::prefetch_w(a);
                        }
                        let lane = PredictLane {
                            h,
                            g,
                            damping,
                            m: m_row,
                            w: w_row,
                        };
                        let (u, d) = (part(up, comp, m), part(down, comp, m));
                        crate::simd::xpbd_predict(kernel, &lane, x, v, x0, u, d);
                    }
                }
            });
    }

    /// Stages 2 and 3 of an XPBD substep on the grid: `iterations` sweeps (see the module
    /// docs) from the predicted positions, then the velocities `(x − start)/h`, all on the
    /// arrays, then (when `ccd`) continuous collision against the colliders
    /// ([`crate::collide::ccd`]). Writes the contact counts into `ctx.contacts`.
    pub(crate) fn sweeps(&mut self, ctx: &mut SubstepCtx<'_>, ccd: bool) {
        let cfg = ctx.config;
        let settings = cfg.xpbd;
        let h = ctx.h;
        if settings.hierarchy_levels > 0 || settings.structural_limit.is_some() {
            self.prepare_levels(
                settings.structural_limit,
                settings.hierarchy_levels,
                settings.hierarchy_slack,
                ctx.rest,
            );
        } else {
            self.levels.clear();
            self.levels_key = None;
        }
        self.keep = settings.iterations > 1;
        self.chain_starts = [false; 4];
        if self.keep {
            for l in &mut self.lambda {
                l.fill(0.0);
            }
        }

        // Per class: the mode, or None when its kind is off.
        let modes: [Option<Mode>; 6] = std::array::from_fn(|class| {
            super::xpbd::compliance(cfg, CLASSES[class].3, h)
                .map(|(alpha, gamma)| Mode::Compliant { alpha, gamma })
        });

        for sweep in 0..settings.iterations {
            // With chains the structural springs go last (after shear and bend): the stiffest
            // constraints, solved exactly per chain, end the sweep.
            let first = if settings.chains { 2 } else { 0 };
            for class in first..6 {
                let Some(mode) = modes[class] else { continue };
                if let (true, 2 | 3, Mode::Compliant { alpha, gamma }) =
                    (settings.shear_chains, class, mode)
                {
                    let params = super::chains::Params::new(alpha, gamma, &settings);
                    self.shear_chains(class - 2, (params, settings.chain_iterations));
                    continue;
                }
                // `shear_rows` (after `shear_chains`, which takes both shear classes above):
                // both shear classes in one sweep down the rows.
                if settings.shear_rows && matches!(class, 2 | 3) {
                    if class == 2 {
                        self.shear_rows([modes[2], modes[3]]);
                    }
                    continue;
                }
                let (dr, a_dc, b_dc, _) = CLASSES[class];
                for colour in 0..2 {
                    if dr == 0 {
                        self.horizontal(b_dc, colour, Rest::Class(class), mode);
                    } else {
                        self.vertical(dr, a_dc, b_dc, colour, Rest::Class(class), mode);
                    }
                }
            }
            if settings.chains {
                // `chain_rounds` rounds of warp then weft, each after a contact pass when
                // there are several.
                let rounds = settings.chain_rounds;
                // With both directions solved the weft takes the warp's positions straight from
                // its blocks (the warp's are not written into the rows in between).
                let compliant = |m: Option<Mode>| matches!(m, Some(Mode::Compliant { .. }));
                let handoff = compliant(modes[0]) && compliant(modes[1]);
                let iterations = settings.chain_iterations;
                // The contact pass before a later round runs in the weft's tasks of the round
                // before, on each block's rows right after their write-back (the same
                // per-particle operations on the same values: the same bits).
                let fused = compliant(modes[1]) && !ctx.colliders.is_empty();
                // Then between rounds the positions stay in the weft's blocks: the weft does
                // not write them back into the rows (its contacts run on its blocks) and the
                // next round's warp takes them from the weft's blocks; the last round's weft
                // writes them back.
                let in_blocks = handoff && fused;
                for round in 0..rounds {
                    if rounds > 1 && !(fused && round > 0) {
                        self.contacts(ctx.colliders, h);
                    }
                    let after = (fused && round + 1 < rounds).then_some((ctx.colliders, h));
                    let multipliers =
                        Multipliers::of(self.keep || round > 0, iterations > 1 || rounds > 1);
                    for (class, mode) in modes.into_iter().enumerate().take(2) {
                        let Some(Mode::Compliant { alpha, gamma }) = mode else {
                            continue;
                        };
                        let (after, in_blocks) = if class == 1 {
                            (after, in_blocks && round + 1 < rounds)
                        } else {
                            (None, in_blocks && round > 0)
                        };
                        let params = super::chains::Params::new(alpha, gamma, &settings);
                        let solve = (params, iterations);
                        self.chains(class, solve, multipliers, (handoff, in_blocks), after);
                    }
                }
            }
            for level in 0..self.levels.len() {
                let s = self.levels[level].spacing;
                if s == 1 {
                    self.structural_limit(level);
                    continue;
                }
                for colour in 0..2 {
                    if s < self.rows {
                        self.vertical(s, 0, 0, colour, Rest::Vertical(level), Mode::Limit);
                    }
                    if s < self.cols {
                        self.horizontal(s, colour, Rest::Horizontal(level), Mode::Limit);
                    }
                }
            }
            // The last sweep's contacts run row by row inside `finish` (one pass fewer).
            if sweep + 1 < settings.iterations {
                self.contacts(ctx.colliders, h);
            }
        }
        // The last sweep's contacts, 3. velocities from positions, and continuous collision.
        let ccd = if ccd { ctx.colliders } else { &[] };
        let (contacts, corrected) = self.finish(ctx.colliders, ccd, h);
        ctx.contacts.contacts = contacts;
        ctx.contacts.ccd += corrected;
    }

    /// The chain solves of the warp (`class` 0, one chain per column) or of the weft
    /// (`class` 1, one per row), see [`super::chains`]: blocks of [`super::chains::LANES`] chains
    /// gathered, solved and scattered back, pairs of blocks ([`PAIR`], or single blocks of
    /// long chains) in parallel (each block's chains are independent of the others', so any
    /// thread count gives the same bits). A pair of weft blocks is gathered, solved and written back in one task (its rows
    /// are its own), followed there by the contacts of its rows with `contacts` (the colliders
    /// and the substep) when given; the warp's columns are written back row by row in a second
    /// pass.
    ///
    /// `handoff`: the weft takes its positions from the warp's blocks, and the warp does not
    /// write them into the rows. `in_blocks`: for the weft, its positions stay in its blocks
    /// (not written back into the rows; the contacts run on the blocks); for the warp, it
    /// takes its positions from the weft's blocks instead of the rows. The same values either
    /// way, so the same bits.
    fn chains(
        &mut self,
        class: usize,
        solve: (super::chains::Params, u32),
        multipliers: Multipliers,
        (handoff, in_blocks): (bool, bool),
        contacts: Option<(&[crate::collide::Collider], f32)>,
    ) {
        use super::chains::{self, FIELDS, LANES};
        let (rows, cols) = (self.rows, self.cols);
        let (count, len) = chains::shape(class, rows, cols);
        let size = chains::stride(len);
        let blocks = count.div_ceil(LANES);
        let kernel = crate::simd::kernel();
        let [warp, weft] = &mut self.chains;
        // With both directions solved the weft takes its positions from the warp's blocks,
        // and with `in_blocks` the warp from the weft's.
        let (scratch, from) = if class == 0 {
            (warp, in_blocks.then_some(&weft[..]))
        } else {
            (weft, handoff.then_some(&warp[..]))
        };
        if scratch.len() != blocks * FIELDS * size {
            scratch.reset(blocks * FIELDS * size, CHAIN_SLOT + class);
            self.chain_statics[class] = false;
        }
        // Blocks per task: a pair (gathered, solved one after the other, scattered) when two
        // fit in half of L2; else one (gathered, solved and scattered before the next is
        // gathered).
        let per = if chains::pair_fits(size) { PAIR } else { 1 };
        let pair = per * FIELDS * size;
        self.chain_work
            .prepare(per * chains::SCRATCH * size, SCRATCH_SLOT);
        let work = &self.chain_work;
        let (statics, starts) = chain_flags(&mut self.chain_statics, &mut self.chain_starts, class);
        let solve = |chunk: &mut [f32], ahead: Option<&chains::Ahead<'_>>| {
            iterate_chunk(
                chunk,
                work,
                (size, len),
                solve,
                (multipliers, kernel),
                ahead,
            );
        };
        if class == 1 {
            let contacts = contacts.map(|(colliders, h)| RowContacts::new(colliders, h));
            // The weft: each block gathers from, and writes back into, its own LANES rows in
            // the same task (the write-back reads the block while it is still in this core's
            // cache; rows of different blocks are disjoint).
            let (prev, w, rest) = (&self.prev, &self.inv_mass, &self.rest[class]);
            let keep = self.keep;
            let [x, y, z] = &mut self.pos;
            let lambda = &mut self.lambda[class];
            let rows_per = per * LANES * cols;
            scratch
                .par_chunks_mut(pair)
                .zip(x.par_chunks_mut(rows_per))
                .zip(y.par_chunks_mut(rows_per))
                .zip(z.par_chunks_mut(rows_per))
                .zip(lambda.par_chunks_mut(rows_per))
                .enumerate()
                .for_each(|(p, ((((chunk, x), y), z), lam))| {
                    let first_row = p * per * LANES;
                    for (h, block) in chunk.chunks_exact_mut(FIELDS * size).enumerate() {
                        let b = p * per + h;
                        let first = b * LANES;
                        let at = first * cols;
                        let mine = h * LANES * cols..;
                        if let Some(warp) = from {
                            chains::handoff::<LANES>(block, warp, b, (rows, cols), kernel);
                        }
                        // The block's rows, as chain 0 onwards.
                        chains::gather::<LANES>(
                            block,
                            len,
                            (class, cols),
                            (0, LANES.min(count - first)),
                            from.is_none().then_some([
                                &x[mine.clone()],
                                &y[mine.clone()],
                                &z[mine.clone()],
                            ]),
                            starts.then_some([&prev[0][at..], &prev[1][at..], &prev[2][at..]]),
                            &w[at..],
                            &rest[at..],
                            keep.then_some(&lam[mine]),
                            statics,
                            kernel,
                        );
                    }
                    // The tiles the next pair's hand-off reads from the warp's blocks, fetched
                    // into L2 during this pair's solve (as the warp's are).
                    let next = (p + 1) * per;
                    let ahead = from.filter(|_| next < blocks).map(|warp| {
                        // The warp's chains are `rows` long.
                        let size = chains::stride(rows);
                        let n = per.min(blocks - next);
                        chains::Ahead::tiles(chains::Tiles::new(warp, size, next, n, len))
                    });
                    solve(chunk, ahead.as_ref());
                    for (h, block) in chunk.chunks_exact(FIELDS * size).enumerate() {
                        let mine = h * LANES * cols..;
                        // Positions (fields 0, 1, 2; not `in_blocks`) and, when kept,
                        // multipliers (field 8) back.
                        if !in_blocks {
                            for (f, dst) in [&mut *x, &mut *y, &mut *z].into_iter().enumerate() {
                                let (src, dst) = (&block[f * size..], &mut dst[mine.clone()]);
                                chains::scatter_rows::<LANES>(src, len, dst, cols, kernel);
                            }
                        }
                        if keep {
                            let (src, dst) = (&block[8 * size..], &mut lam[mine]);
                            chains::scatter_rows::<LANES>(src, len, dst, cols, kernel);
                        }
                    }
                    // The next round's contacts on these rows (as `Self::contacts` does them),
                    // or on the blocks, whose fields hold the same particles' positions, start
                    // positions and inverse masses (lanes past the last row have inverse mass
                    // 0, which the contacts leave as they are).
                    let Some(contacts) = &contacts else { return };
                    if !in_blocks {
                        let prev = [&prev[0][..], &prev[1][..], &prev[2][..]];
                        contacts.rows(first_row, cols, [x, y, z], prev, w);
                        return;
                    }
                    let n = len * LANES;
                    for block in chunk.chunks_exact_mut(FIELDS * size) {
                        let (pos, rest) = block.split_at_mut(3 * size);
                        let (x, yz) = pos.split_at_mut(size);
                        let (y, z) = yz.split_at_mut(size);
                        let p0 = [&rest[..n], &rest[size..][..n], &rest[2 * size..][..n]];
                        let w = &rest[3 * size..][..n];
                        contacts.row([&mut x[..n], &mut y[..n], &mut z[..n]], p0, w);
                    }
                });
            return;
        }
        let [x, y, z] = &self.pos;
        let (prev, w, rest) = (&self.prev, &self.inv_mass, &self.rest[class]);
        let keep = self.keep;
        let lambda = keep.then_some(&self.lambda[class][..]);
        scratch
            .par_chunks_mut(pair)
            .enumerate()
            .for_each(|(p, chunk)| {
                for (h, block) in chunk.chunks_exact_mut(FIELDS * size).enumerate() {
                    let b = p * per + h;
                    let first = b * LANES;
                    if let Some(weft) = from {
                        // The grid seen transposed: the warp's block from the weft's.
                        chains::handoff::<LANES>(block, weft, b, (cols, rows), kernel);
                    }
                    chains::gather::<LANES>(
                        block,
                        len,
                        (class, cols),
                        (first, LANES.min(count - first)),
                        from.is_none().then_some([x, y, z]),
                        starts.then_some([&prev[0], &prev[1], &prev[2]]),
                        w,
                        rest,
                        lambda,
                        statics,
                        kernel,
                    );
                }
                // The next pair's columns (most often this thread's next task: rayon hands
                // each thread a contiguous range) fetched into L2 during this pair's solve,
                // those it reads from the rows and the tiles it takes from the weft's blocks.
                let next = (p + 1) * per * LANES;
                let ahead = (next < count).then(|| {
                    let pos = |f: usize| from.is_none().then_some(&[x, y, z][f][..]);
                    let start = |f: usize| starts.then_some(&prev[f][..]);
                    let tiles = from.map(|weft| {
                        let next_block = (p + 1) * per;
                        let n = per.min(blocks - next_block);
                        // The weft's chains are `cols` long.
                        chains::Tiles::new(weft, chains::stride(cols), next_block, n, len)
                    });
                    chains::Ahead {
                        fields: [pos(0), pos(1), pos(2), start(0), start(1), start(2)],
                        first: next,
                        stride: cols,
                        span: (per * LANES).min(count - next),
                        tiles,
                    }
                });
                solve(chunk, ahead.as_ref());
            });
        let scratch = &self.chains[class];
        let [x, y, z] = &mut self.pos;
        let lambda = &mut self.lambda[class];
        // The warp's fields 0, 1, 2 (positions) and 8 (multipliers) back into the rows, row by
        // row: the positions not when the weft takes them from the blocks (`handoff`), the
        // multipliers only when kept.
        let fields: &[usize] = match (handoff, keep) {
            (false, false) => &[0, 1, 2],
            (false, true) => &[0, 1, 2, 3],
            (true, true) => &[3],
            (true, false) => return,
        };
        x.par_chunks_mut(cols)
            .zip(y.par_chunks_mut(cols))
            .zip(z.par_chunks_mut(cols))
            .zip(lambda.par_chunks_mut(cols))
            .enumerate()
            .for_each(|(i, (((x, y), z), lam))| {
                let mut dst = [x, y, z, lam];
                for &f in fields {
                    let dst = &mut dst[f];
                    let field = if f == 3 { 8 } else { f };
                    for (b, block) in scratch.chunks_exact(FIELDS * size).enumerate() {
                        let first = b * LANES;
                        let lanes = LANES.min(count - first);
                        let src = &block[field * size + i * LANES..];
                        if lanes == LANES {
                            // Of known length: inlined, no `memcpy` call per step.
                            let dst = dst[first..].first_chunk_mut::<LANES>().expect("lanes");
                            *dst = *src.first_chunk::<LANES>().expect("lanes");
                        } else {
                            dst[first..first + lanes].copy_from_slice(&src[..lanes]);
                        }
                    }
                }
            });
    }

    /// The shear diagonals of one direction as chains along the grid's diagonal lines
    /// (`XpbdSettings::shear_chains`; `dir` 0: the diagonals `(r, c)–(r + 1, c + 1)`, class
    /// 2; 1: the anti-diagonals `(r, c)–(r + 1, c − 1)`, class 3), each line solved exactly by
    /// [`super::chains`]'s tridiagonal solve. Chain `j` visits column `(j ± k) mod cols` at
    /// row `k`: `cols` chains of `rows` entries, whose spring across the wrap (from the last
    /// column to the first, or back) is left out by a negative rest length; so a chain holds
    /// one line that starts at `(0, j)` and, after the wrap, the line that starts on the first
    /// or last column of the row after it (every spring of the direction in exactly one chain,
    /// the lines of a chain independent, as separate chains would be). At every row the lanes
    /// of a block read and write one contiguous run of columns (wrapped at the row's end, in
    /// one block per row). The blocks keep their inverse masses and rest lengths between
    /// substeps and their start positions through a substep, as the warp's do.
    fn shear_chains(&mut self, dir: usize, solve: (super::chains::Params, u32)) {
        use super::chains::{self, FIELDS, LANES};
        let (rows, cols) = (self.rows, self.cols);
        if rows < 2 || cols < 2 {
            return;
        }
        let (count, len) = (cols, rows);
        let size = chains::stride(len);
        let kernel = crate::simd::kernel();
        let class = 2 + dir;
        let blocks = &mut self.shear_blocks[dir];
        if blocks.len() != count.div_ceil(LANES) * FIELDS * size {
            blocks.reset(count.div_ceil(LANES) * FIELDS * size, SHEAR_SLOT + dir);
            self.chain_statics[class] = false;
        }
        let (statics, starts) = chain_flags(&mut self.chain_statics, &mut self.chain_starts, class);
        self.chain_work
            .prepare(PAIR * chains::SCRATCH * size, SCRATCH_SLOT);
        let keep = self.keep;
        let multipliers = Multipliers::of(keep, solve.1 > 1);
        // The column of block `first`'s first lane at row `k` (its lanes take the next
        // columns, wrapped), and the first slot of their springs (an anti-diagonal's slot is
        // its upper end's column minus one).
        let start = move |first: usize, k: usize| {
            if dir == 0 {
                (first + k) % cols
            } else {
                (first + cols - k % cols) % cols
            }
        };
        let slot = move |c0: usize| if dir == 0 { c0 } else { (c0 + cols - 1) % cols };
        // The lane of a run starting at column `c0` whose spring crosses the wrap (diagonal:
        // from column cols − 1; anti-diagonal: from column 0), if among the block's `lanes`.
        let wrap = if dir == 0 { cols - 1 } else { 0 };
        let cut = move |c0: usize, lanes: usize| {
            let l = (wrap + cols - c0) % cols;
            (l < lanes).then_some(l)
        };
        let work = &self.chain_work;
        let [x, y, z] = &self.pos;
        let (prev, w, rest, lambda) = (
            &self.prev,
            &self.inv_mass,
            &self.rest[class],
            &self.lambda[class],
        );
        // Entry k of the next pair's first chain is at k·cols + first ± k (a hint: past the
        // wrap it points into a neighbouring row).
        let stride = if dir == 0 { cols + 1 } else { cols - 1 };
        blocks
            .par_chunks_mut(PAIR * FIELDS * size)
            .enumerate()
            .for_each(|(p, chunk)| {
                for (h, block) in chunk.chunks_exact_mut(FIELDS * size).enumerate() {
                    let first = (p * PAIR + h) * LANES;
                    let lanes = LANES.min(count - first);
                    if statics && lanes < LANES {
                        // Lanes past the last chain: inactive (inverse mass 0), for good.
                        block.fill(0.0);
                    }
                    for k in 0..len {
                        let row = k * cols..(k + 1) * cols;
                        let (c0, at) = (start(first, k), k * LANES);
                        let mut load = |f: usize, src: &[f32], from: usize| {
                            run_load(
                                &mut block[f * size + at..][..lanes],
                                &src[row.clone()],
                                from,
                            );
                        };
                        for (f, src) in [x, y, z].into_iter().enumerate() {
                            load(f, src, c0);
                        }
                        if starts {
                            for (f, src) in prev.iter().enumerate() {
                                load(3 + f, src, c0);
                            }
                        }
                        if statics {
                            load(6, w, c0);
                            load(7, rest, slot(c0));
                        }
                        if keep {
                            load(8, lambda, slot(c0));
                        }
                        // No spring across the wrap (a static too). Past a chain's last
                        // entry the solve reads no spring; a cut spring's multiplier is never
                        // read and gains +0, and its slot, in the class's last column, holds
                        // no spring either, so the multipliers go back as they are.
                        if let (true, Some(l)) = (statics, cut(c0, lanes)) {
                            block[7 * size + at + l] = -1.0;
                        }
                    }
                }
                let next = (p + 1) * PAIR * LANES;
                let ahead = (next < count).then(|| {
                    let start = |f: usize| starts.then_some(&prev[f][..]);
                    chains::Ahead {
                        fields: [Some(x), Some(y), Some(z), start(0), start(1), start(2)],
                        first: next,
                        stride,
                        span: (PAIR * LANES).min(count - next),
                        tiles: None,
                    }
                });
                iterate_chunk(
                    chunk,
                    work,
                    (size, len),
                    solve,
                    (multipliers, kernel),
                    ahead.as_ref(),
                );
            });
        // Positions (and kept multipliers) back into the rows, row by row.
        let blocks = &self.shear_blocks[dir];
        let [x, y, z] = &mut self.pos;
        let lambda = &mut self.lambda[class];
        x.par_chunks_mut(cols)
            .zip(y.par_chunks_mut(cols))
            .zip(z.par_chunks_mut(cols))
            .zip(lambda.par_chunks_mut(cols))
            .enumerate()
            .for_each(|(k, (((x, y), z), lam))| {
                for (b, block) in blocks.chunks_exact(FIELDS * size).enumerate() {
                    let first = b * LANES;
                    let lanes = LANES.min(count - first);
                    let (c0, at) = (start(first, k), k * LANES);
                    for (f, dst) in [&mut *x, &mut *y, &mut *z].into_iter().enumerate() {
                        run_store(&block[f * size + at..][..lanes], dst, c0);
                    }
                    if keep && k + 1 < len {
                        run_store(&block[8 * size + at..][..lanes], lam, slot(c0));
                    }
                }
            });
    }

    /// The multipliers of a pass, taken out of the scratch for the pass (limits get a spare
    /// array).
    fn take_lambda(&mut self, which: Rest) -> Placed {
        match which {
            Rest::Class(c) => std::mem::take(&mut self.lambda[c]),
            _ => std::mem::take(&mut self.spare),
        }
    }

    /// Whether every row of a pass's lengths holds the same bits as the first.
    fn rest_uniform(&self, which: Rest) -> bool {
        match which {
            Rest::Class(c) => self.uniform[c],
            Rest::Vertical(l) => self.levels[l].uniform[0],
            Rest::Horizontal(l) => self.levels[l].uniform[1],
        }
    }

    fn put_lambda(&mut self, which: Rest, lambda: Placed) {
        match which {
            Rest::Class(c) => self.lambda[c] = lambda,
            _ => self.spare = lambda,
        }
    }

    /// The structural strain limit (`levels[level]`, spacing 1) in one parallel pass: the
    /// four coloured passes (warp pairs of rows `(2k, 2k + 1)`, then `(2k − 1, 2k)`, then the
    /// weft's even and odd columns of every row) as a wavefront down the rows, in bands of
    /// rows on a `rayon::join` tree ([`Limits`]). Each pair is projected from the same values
    /// as in the coloured order, so the same bits for any split of the rows.
    fn structural_limit(&mut self, level: usize) {
        let (rows, cols) = (self.rows, self.cols);
        let lv = &self.levels[level];
        let (prev, w) = (&self.prev, &self.inv_mass);
        // The wavefront reads a uniform level's first row itself (`Limits::uniform`).
        let shared = |rest| Shared {
            prev,
            w,
            rest,
            mode: Mode::Limit,
            keep: false,
            rest_cols: 0,
        };
        let [m0, m1] = &self.masks[0];
        let limits = Limits {
            warp: shared(&lv.vertical),
            weft: shared(&lv.horizontal),
            uniform: lv.uniform,
            masks: [&m0[..cols - 1], &m1[..cols - 1]],
            rows,
            cols,
            kernel: crate::simd::kernel(),
        };
        let [x, y, z] = &mut self.pos;
        let n = rows * cols;
        let bands = rayon::current_num_threads().clamp(1, rows.div_ceil(8));
        limits.run([&mut x[..n], &mut y[..n], &mut z[..n]], 0, rows, bands);
    }

    /// The shear springs row by row: cell row after cell row, each row's diagonals and then
    /// its anti-diagonals (each a set of disjoint pairs, projected at once), a Gauss–Seidel
    /// sweep in the order of the rows, which carries a correction across the cloth in one
    /// sweep where the two colours carry it one row. The cell rows split into two domains
    /// that share no particle, swept at the same time (rows `[0, b)` and `(b, rows − 1)`),
    /// and then the cell row `b` between them: the same bits for any thread count.
    fn shear_rows(&mut self, modes: [Option<Mode>; 2]) {
        let (rows, cols) = (self.rows, self.cols);
        let m = cols - 1;
        let keep = self.keep;
        let mut lambdas = [
            self.take_lambda(Rest::Class(2)),
            self.take_lambda(Rest::Class(3)),
        ];
        let shared: [Option<Shared<'_>>; 2] = std::array::from_fn(|d| {
            modes[d].map(|mode| Shared {
                prev: &self.prev,
                w: &self.inv_mass,
                rest: &self.rest[2 + d],
                mode,
                keep,
                // `rest_uniform` by field (a method would borrow the whole scratch).
                rest_cols: if self.uniform[2 + d] { cols } else { 0 },
            })
        });
        let kernel = crate::simd::kernel();
        // Cell row `r` (global) of the arrays `x` that start at particle row `base`.
        let row = |x: &mut [&mut [f32]; 3], lam: &mut [&mut [f32]; 2], r: usize, base: usize| {
            for (d, sh) in shared.iter().enumerate() {
                let Some(sh) = sh else { continue };
                let (a_dc, b_dc) = if d == 0 { (0, 1) } else { (1, 0) };
                let (ga, gb) = (r * cols, (r + 1) * cols);
                let (la, lb) = (ga - base * cols, gb - base * cols);
                let [x, y, z] = x;
                let (xa, xb) = x.split_at_mut(lb);
                let (ya, yb) = y.split_at_mut(lb);
                let (za, zb) = z.split_at_mut(lb);
                pair_row(
                    kernel,
                    ([&mut xa[la..], &mut ya[la..], &mut za[la..]], [xb, yb, zb]),
                    (a_dc, b_dc, m),
                    sh,
                    (ga, gb),
                    &mut lam[d][la..],
                );
            }
        };
        let cells = rows - 1;
        let b = shear_rows_between(rows);
        {
            let [x, y, z] = &mut self.pos;
            let [l0, l1] = &mut lambdas;
            let split = (b + 1) * cols;
            let (x0, x1) = x.split_at_mut(split);
            let (y0, y1) = y.split_at_mut(split);
            let (z0, z1) = z.split_at_mut(split);
            let (l00, l01) = l0.split_at_mut(split);
            let (l10, l11) = l1.split_at_mut(split);
            rayon::join(
                || {
                    let mut xs = [x0, y0, z0];
                    let mut ls = [l00, l10];
                    for r in 0..b {
                        row(&mut xs, &mut ls, r, 0);
                    }
                },
                || {
                    let mut xs = [x1, y1, z1];
                    let mut ls = [l01, l11];
                    for r in b + 1..cells {
                        row(&mut xs, &mut ls, r, b + 1);
                    }
                },
            );
        }
        {
            let [x, y, z] = &mut self.pos;
            let [l0, l1] = &mut lambdas;
            let mut xs = [&mut x[..], &mut y[..], &mut z[..]];
            let mut ls = [&mut l0[..], &mut l1[..]];
            row(&mut xs, &mut ls, b, 0);
        }
        let [l0, l1] = lambdas;
        self.put_lambda(Rest::Class(2), l0);
        self.put_lambda(Rest::Class(3), l1);
    }

    /// One colour of a class joining row `r` to row `r + dr`: slot `(r, c)` joins
    /// `(r, c + a_dc)` to `(r + dr, c + b_dc)`; colour `⌊r / dr⌋ mod 2`. Rows are handed out
    /// in blocks of `2·dr` (rows `[0, dr)` of a block against rows `[dr, 2·dr)`).
    fn vertical(
        &mut self,
        dr: usize,
        a_dc: usize,
        b_dc: usize,
        colour: usize,
        which: Rest,
        mode: Mode,
    ) {
        let cols = self.cols;
        let first = colour * dr * cols;
        let block = 2 * dr * cols;
        let m = cols - a_dc.max(b_dc);
        let mut lambda = self.take_lambda(which);
        let rest_cols = if self.rest_uniform(which) { cols } else { 0 };
        let [x, y, z] = &mut self.pos;
        if first >= x.len() {
            self.put_lambda(which, lambda);
            return;
        }
        let rest = rest_of(&self.rest, &self.levels, which);
        let (prev, w) = (&self.prev, &self.inv_mass);
        let shared = Shared {
            prev,
            w,
            rest,
            mode,
            keep: self.keep,
            rest_cols,
        };
        let kernel = crate::simd::kernel();
        x[first..]
            .par_chunks_mut(block)
            .zip(y[first..].par_chunks_mut(block))
            .zip(z[first..].par_chunks_mut(block))
            .zip(lambda[first..].par_chunks_mut(block))
            .enumerate()
            .for_each(|(i, (((bx, by), bz), bl))| {
                let rows_here = bx.len() / cols;
                let row0 = colour * dr + i * 2 * dr;
                for r in 0..dr.min(rows_here.saturating_sub(dr)) {
                    let (ga, gb) = ((row0 + r) * cols, (row0 + r + dr) * cols);
                    let (xa, xb) = rows_pair(bx, r, dr, cols);
                    let (ya, yb) = rows_pair(by, r, dr, cols);
                    let (za, zb) = rows_pair(bz, r, dr, cols);
                    pair_row(
                        kernel,
                        ([xa, ya, za], [xb, yb, zb]),
                        (a_dc, b_dc, m),
                        &shared,
                        (ga, gb),
                        &mut bl[r * cols..],
                    );
                }
            });
        self.put_lambda(which, lambda);
    }

    /// One colour of a class joining `(r, c)` to `(r, c + s)`, colour `⌊c / s⌋ mod 2`: every
    /// row's corrections first, then applied to both ends.
    fn horizontal(&mut self, s: usize, colour: usize, which: Rest, mode: Mode) {
        let cols = self.cols;
        if s >= cols {
            // No pair `s` columns apart (a bend on a cloth two columns wide): nothing to
            // project, and no colour mask at that spacing.
            return;
        }
        let m = cols - s;
        let mut lambda = self.take_lambda(which);
        let mask = &self.masks[s.trailing_zeros() as usize][colour];
        let rest = rest_of(&self.rest, &self.levels, which);
        let rest_cols = if self.rest_uniform(which) { cols } else { 0 };
        let (prev, w) = (&self.prev, &self.inv_mass);
        let shared = Shared {
            prev,
            w,
            rest,
            mode,
            keep: self.keep,
            rest_cols,
        };
        let [x, y, z] = &mut self.pos;
        let [cx, cy, cz] = &mut self.corr;
        let kernel = crate::simd::kernel();
        x.par_chunks_mut(cols)
            .zip(y.par_chunks_mut(cols))
            .zip(z.par_chunks_mut(cols))
            .zip(lambda.par_chunks_mut(cols))
            .zip(cx.par_chunks_mut(cols))
            .zip(cy.par_chunks_mut(cols))
            .zip(cz.par_chunks_mut(cols))
            .enumerate()
            .for_each(|(r, ((((((x, y), z), lam), cx), cy), cz))| {
                if s >= BLOCK_SPACING {
                    // Blocks of 2·s columns: columns [0, s) of a block against [s, 2·s),
                    // two disjoint slices, projected in place like a vertical pass.
                    let first = colour * s;
                    for c0 in (first..m).step_by(2 * s) {
                        let len = s.min(m - c0);
                        let (xa, xb) = x.split_at_mut(c0 + s);
                        let (ya, yb) = y.split_at_mut(c0 + s);
                        let (za, zb) = z.split_at_mut(c0 + s);
                        let ga = r * cols + c0;
                        crate::simd::xpbd_pairs(
                            kernel,
                            [
                                &mut xa[c0..c0 + len],
                                &mut ya[c0..c0 + len],
                                &mut za[c0..c0 + len],
                            ],
                            [&mut xb[..len], &mut yb[..len], &mut zb[..len]],
                            &shared,
                            (ga, ga + s, ga),
                            &mut lam[c0..c0 + len],
                        );
                    }
                    return;
                }
                if matches!(shared.mode, Mode::Limit) {
                    let g = r * cols;
                    crate::simd::xpbd_limit_row(kernel, [x, y, z], &shared, (g, g), s, &mask[..m]);
                    return;
                }
                if s == 2
                    && crate::simd::xpbd_quads(kernel, [x, y, z], &shared, r * cols, colour * 2, m)
                {
                    return;
                }
                crate::simd::xpbd_row(
                    kernel,
                    [x, y, z],
                    [&mut cx[..m], &mut cy[..m], &mut cz[..m]],
                    &shared,
                    r * cols,
                    s,
                    &mut lam[..m],
                    &mask[..m],
                );
            });
        self.put_lambda(which, lambda);
    }

    /// Collider contacts of every particle, rows in parallel (every sweep but the last, whose
    /// contacts run, and are counted, in [`Self::finish`]).
    ///
    /// When every collider is a sphere or a plane that does not turn, the contacts run on the
    /// arrays ([`contacts_soa_row`]: collider by collider, [`contact_soa`] on the sub-chunks
    /// of [`NEAR_SUB`] particles not clear of it, the per-particle routine's operations in
    /// every lane, selected), else per particle ([`super::xpbd::contact`]) on the chunks of
    /// [`NEAR_CHUNK`] particles not clear of every collider ([`near_any`]); both give the
    /// same bits.
    fn contacts(&mut self, colliders: &[crate::collide::Collider], h: f32) {
        if colliders.is_empty() {
            return;
        }
        let cols = self.cols;
        let contacts = RowContacts::new(colliders, h);
        let (prev, w) = (&self.prev, &self.inv_mass);
        let prev = [&prev[0][..], &prev[1][..], &prev[2][..]];
        let [x, y, z] = &mut self.pos;
        x.par_chunks_mut(cols)
            .zip(y.par_chunks_mut(cols))
            .zip(z.par_chunks_mut(cols))
            .enumerate()
            .for_each(|(r, ((x, y), z))| {
                // Only the last sweep's count is reported (by `finish`).
                contacts.rows(r, cols, [x, y, z], prev, w);
            });
    }

    /// The end of a substep on the arrays, rows in parallel, each row on its own: the last
    /// sweep's contacts with `contact` (as [`Self::contacts`]), the velocities from the
    /// positions, `v ← (x − start)/h` for free particles (the reference's stage 3), then
    /// continuous collision against `colliders` (empty: none):
    /// [`crate::collide::ccd::resolve_in`], the reference's per-particle routine, on the
    /// particles gathered as `Vec3` in runs, so the same bits as the reference's pass over all
    /// the particles (each particle is handled on its own). When every collider is a sphere or a
    /// plane that does not turn, [`super::grid_kernel::ccd_mask`]'s culls on the arrays pick
    /// the candidates first and only they are gathered. Returns the contact count and the
    /// number of particles that continuous collision corrected.
    fn finish(
        &mut self,
        contact: &[crate::collide::Collider],
        colliders: &[crate::collide::Collider],
        h: f32,
    ) -> (u32, u32) {
        use crate::collide::ccd;
        let cols = self.cols;
        let inv_h = 1.0 / h;
        let masked = soa_colliders(colliders);
        let kernel = crate::simd::kernel();
        let contacts = RowContacts::new(contact, h);
        let (prev, w) = (&self.prev, &self.inv_mass);
        let [x, y, z] = &mut self.pos;
        let [vx, vy, vz] = &mut self.vel;
        x.par_chunks_mut(cols)
            .zip(y.par_chunks_mut(cols))
            .zip(z.par_chunks_mut(cols))
            .zip(vx.par_chunks_mut(cols))
            .zip(vy.par_chunks_mut(cols))
            .zip(vz.par_chunks_mut(cols))
            .enumerate()
            // The gather buffers of continuous collision, one set per task (written before
            // they are read; zeroed per row they took a memset of 2.3 KiB a row).
            .map_init(
                || [[Vec3::ZERO; NEAR_CHUNK]; 3],
                |[a, p, v], (r, (((((x, y), z), vx), vy), vz))| {
                    let all = r * cols..(r + 1) * cols;
                    let w = &w[all.clone()];
                    let p0 = [
                        &prev[0][all.clone()],
                        &prev[1][all.clone()],
                        &prev[2][all.clone()],
                    ];
                    let touched = if contact.is_empty() {
                        0
                    } else {
                        contacts.row([&mut *x, &mut *y, &mut *z], p0, w)
                    };
                    for (v, (x, x0)) in [
                        (&mut *vx, (&*x, &prev[0][all.clone()])),
                        (&mut *vy, (&*y, &prev[1][all.clone()])),
                        (&mut *vz, (&*z, &prev[2][all])),
                    ] {
                        crate::simd::xpbd_velocities(kernel, v, x, x0, w, h, inv_h);
                    }
                    let mut count = 0;
                    if colliders.is_empty() {
                        return (touched, count);
                    }
                    let mut near = [true; NEAR_CHUNK];
                    for c0 in (0..cols).step_by(NEAR_CHUNK) {
                        let n = NEAR_CHUNK.min(cols - c0);
                        let i0 = r * cols + c0;
                        let (row, all) = (c0..c0 + n, i0..i0 + n);
                        let any = if masked {
                            crate::simd::ccd_mask(
                                kernel,
                                colliders,
                                h,
                                &w[row.clone()],
                                [&prev[0][all.clone()], &prev[1][all.clone()], &prev[2][all]],
                                [&x[row.clone()], &y[row.clone()], &z[row]],
                                &mut near[..n],
                            )
                        } else {
                            true
                        };
                        // Runs of candidates k .. l, gathered, resolved and written back (most
                        // chunks have none: the mask says so first).
                        if !any {
                            continue;
                        }
                        for run in super::grid_kernel::runs(&near[..n]) {
                            let (k, l) = (run.start, run.end);
                            for j in k..l {
                                let (c, i) = (c0 + j, i0 + j);
                                a[j] = Vec3::new(prev[0][i], prev[1][i], prev[2][i]);
                                p[j] = Vec3::new(x[c], y[c], z[c]);
                                v[j] = Vec3::new(vx[c], vy[c], vz[c]);
                            }
                            count += ccd::resolve_in(
                                colliders,
                                &a[k..l],
                                &mut p[k..l],
                                &mut v[k..l],
                                &w[c0 + k..c0 + l],
                                h,
                            );
                            for j in k..l {
                                let c = c0 + j;
                                (x[c], y[c], z[c]) = (p[j].x, p[j].y, p[j].z);
                                (vx[c], vy[c], vz[c]) = (v[j].x, v[j].y, v[j].z);
                            }
                        }
                    }
                    (touched, count)
                },
            )
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
    }
}

/// The velocities of the free particles of a run from their positions, one component (pinned
/// ones keep their velocity): `v ← v + (x − x_pred)/h`, with `v` the predicted velocity and
/// x_pred = x₀ + h·v the predicted position recomputed with the prediction's own rounding
/// ([`PredictLane`]'s `integrate`), `inv_h` = 1/h. In exact arithmetic this is (x − x₀)/h;
/// in f32 it leaves out the rounding of x_pred, half an ulp of |x|, which (x − x₀)/h turns
/// into a velocity error of ulp(|x|)/(2h): a drift that grows with the distance from the origin
/// and the substeps (a hanging strip 5 m up, 80 substeps per 1/60 s, settled 11.7 % off
/// Hooke's extension). Computed in chunks of [`CHUNK`] lanes through local arrays, the select
/// computed in every lane, so the loop vectorises (written over the slices directly, the
/// compiler kept a branch and a scalar loop: the select's `else` reads `v`, which it could
/// not prove apart from the other slices).
#[inline(always)]
pub(crate) fn velocities(v: &mut [f32], x: &[f32], x0: &[f32], w: &[f32], h: f32, inv_h: f32) {
    let n = v.len();
    let (x, x0, w) = (&x[..n], &x0[..n], &w[..n]);
    let one = |v: &mut f32, x: f32, x0: f32, w: f32| {
        let moved = *v + (x - (x0 + h * *v)) * inv_h;
        *v = if w != 0.0 { moved } else { *v };
    };
    let (v, v_tail) = v.as_chunks_mut::<CHUNK>();
    let (x, x_tail) = x.as_chunks::<CHUNK>();
    let (x0, x0_tail) = x0.as_chunks::<CHUNK>();
    let (w, w_tail) = w.as_chunks::<CHUNK>();
    for (((v, x), x0), w) in v.iter_mut().zip(x).zip(x0).zip(w) {
        // Whole chunks copied (fixed length, inlined) into locals.
        let (mut lv, lx, lx0, lw) = (*v, *x, *x0, *w);
        for l in 0..CHUNK {
            one(&mut lv[l], lx[l], lx0[l], lw[l]);
        }
        *v = lv;
    }
    for (((v, &x), &x0), &w) in v_tail.iter_mut().zip(x_tail).zip(x0_tail).zip(w_tail) {
        one(v, x, x0, w);
    }
}

/// Blocks of chains per task of the chain solves: two, gathered together and solved one after
/// the other. One block per task where two would not stay in L2 (`chains::pair_fits`: chains
/// longer than 291 particles).
const PAIR: usize = 2;

/// Lanes per chunk of [`velocities`].
const CHUNK: usize = 32;

/// The contact pass of one row ([`XpbdGrid::contacts`], and the last sweep's inside
/// [`XpbdGrid::finish`]): chunks clear of every collider skipped, the rest on the arrays or
/// per particle.
struct RowContacts<'a> {
    colliders: &'a [crate::collide::Collider],
    h: f32,
    /// Every collider is a sphere or a plane that does not turn ([`soa_colliders`]).
    soa: bool,
    kernel: crate::simd::Kernel,
}

impl<'a> RowContacts<'a> {
    fn new(colliders: &'a [crate::collide::Collider], h: f32) -> Self {
        Self {
            colliders,
            h,
            soa: soa_colliders(colliders),
            kernel: crate::simd::kernel(),
        }
    }

    /// [`Self::row`] for each of the grid's rows from `first` held in `x, y, z` (`cols`
    /// wide), with the grid's start positions `prev` and inverse masses `w`. Returns the
    /// contact count.
    fn rows(
        &self,
        first: usize,
        cols: usize,
        [x, y, z]: [&mut [f32]; 3],
        prev: [&[f32]; 3],
        w: &[f32],
    ) -> u32 {
        let rows = x
            .chunks_mut(cols)
            .zip(y.chunks_mut(cols))
            .zip(z.chunks_mut(cols));
        let mut count = 0;
        for (r, ((x, y), z)) in rows.enumerate() {
            let all = (first + r) * cols..(first + r + 1) * cols;
            let p0 = prev.map(|p| &p[all.clone()]);
            count += self.row([x, y, z], p0, &w[all]);
        }
        count
    }

    /// The contacts of one row: positions `x, y, z` (updated), start positions `p0`, inverse
    /// masses `w`: on the arrays ([`contacts_soa_row`]) when every collider is a sphere or a
    /// plane that does not turn, else per particle in chunks of [`NEAR_CHUNK`]. Returns the
    /// contact count.
    fn row(&self, [x, y, z]: [&mut [f32]; 3], p0: [&[f32]; 3], w: &[f32]) -> u32 {
        let (colliders, h) = (self.colliders, self.h);
        if self.soa {
            return crate::simd::xpbd_contacts(self.kernel, colliders, h, w, [x, y, z], p0);
        }
        let mut count = 0;
        let mut near = [false; NEAR_CHUNK];
        for c0 in (0..x.len()).step_by(NEAR_CHUNK) {
            let n = NEAR_CHUNK.min(x.len() - c0);
            let run = c0..c0 + n;
            near_any(
                colliders,
                [&x[run.clone()], &y[run.clone()], &z[run.clone()]],
                &mut near[..n],
            );
            for (k, &near) in near[..n].iter().enumerate() {
                let c = c0 + k;
                if !near || w[c] == 0.0 {
                    continue;
                }
                let mut p = Vec3::new(x[c], y[c], z[c]);
                let start = Vec3::new(p0[0][c], p0[1][c], p0[2][c]);
                let mut touched = false;
                for col in colliders {
                    if surely_clear(col, p) {
                        continue;
                    }
                    if super::xpbd::contact(col, &mut p, start, h) {
                        touched = true;
                        count += 1;
                    }
                }
                if touched {
                    (x[c], y[c], z[c]) = (p.x, p.y, p.z);
                }
            }
        }
        count
    }
}

/// One component of [`XpbdGrid::predict`] on one row of particles.
pub(crate) struct PredictLane<'a> {
    /// Substep, s.
    h: f32,
    /// This component of gravity, m/s².
    g: f32,
    /// Global damping, kg/s.
    damping: f32,
    /// Masses and inverse masses of the row.
    m: &'a [f32],
    w: &'a [f32],
}

/// Row `i` of `a` (rows of `cols` entries), writable, and the row after it (empty after the
/// last row).
fn row_and_next(a: &mut [f32], i: usize, cols: usize) -> (&mut [f32], &[f32]) {
    let (row, rest) = a[i * cols..].split_at_mut(cols);
    let n = rest.len().min(cols);
    (row, &rest[..n])
}

/// [`PredictLane::run`] with the air shares of the cell rows above (`up`) and below (`down`)
/// when there are any, for [`crate::simd::xpbd_predict`] to compile for each kernel (the loop
/// is element-wise IEEE arithmetic: the same bits at any vector width).
#[inline(always)]
pub(crate) fn predict_lane(
    lane: &PredictLane<'_>,
    x: &mut [f32],
    v: &mut [f32],
    x0: &mut [f32],
    up: Option<[&[f32]; 2]>,
    down: Option<[&[f32]; 2]>,
) {
    let none: [&[f32]; 2] = [&[], &[]];
    match (up, down) {
        (Some(u), Some(d)) => lane.run::<true, true>(x, v, x0, u, d),
        (Some(u), None) => lane.run::<true, false>(x, v, x0, u, none),
        (None, Some(d)) => lane.run::<false, true>(x, v, x0, none, d),
        (None, None) => lane.run::<false, false>(x, v, x0, none, none),
    }
}

impl PredictLane<'_> {
    /// Predicts one component `x`, `v` of the row (and saves the old `x` in `x0`): the weight
    /// and damping, then when `UP` the air shares of the cell row above (`u0`, `u1`: its first
    /// and second triangles, `cols − 1` each) and when `DOWN` those of the cell row below, in
    /// the reference's triangle order. The edge columns, which have fewer triangles, are done
    /// apart, so the loop over the inner columns has no branch and vectorises.
    #[inline(always)]
    fn run<const UP: bool, const DOWN: bool>(
        &self,
        x: &mut [f32],
        v: &mut [f32],
        x0: &mut [f32],
        [u0, u1]: [&[f32]; 2],
        [d0, d1]: [&[f32]; 2],
    ) {
        let n = x.len();
        let (h, g, d) = (self.h, self.g, self.damping);
        let inv_h = 1.0 / h;
        let cap = |m: f32| crate::forces::capped_damping(d, m, inv_h);
        let (m, w, v, x0) = (&self.m[..n], &self.w[..n], &mut v[..n], &mut x0[..n]);
        let integrate = |f: f32, w: f32, x: &mut f32, v: &mut f32, x0: &mut f32| {
            *v += (h * w) * f;
            *x0 = *x;
            *x += h * *v;
        };
        // Column 0: the cells to its right only.
        let mut f = m[0] * g - cap(m[0]) * v[0];
        if UP {
            f += u0[0];
            f += u1[0];
        }
        if DOWN {
            f += d0[0];
        }
        integrate(f, w[0], &mut x[0], &mut v[0], &mut x0[0]);
        // Last column: the cells to its left only.
        let l = n - 1;
        let mut f = m[l] * g - cap(m[l]) * v[l];
        if UP {
            f += u1[l - 1];
        }
        if DOWN {
            f += d0[l - 1];
            f += d1[l - 1];
        }
        integrate(f, w[l], &mut x[l], &mut v[l], &mut x0[l]);
        // Inner columns c = 1 ..= n − 2, at index i = c − 1 of slices starting at column 1.
        let k = n - 2;
        let (m, w) = (&m[1..][..k], &w[1..][..k]);
        let (x, v, x0) = (&mut x[1..][..k], &mut v[1..][..k], &mut x0[1..][..k]);
        let empty: &[f32] = &[];
        let (ul1, ur0, ur1) = if UP {
            (&u1[..k], &u0[1..][..k], &u1[1..][..k])
        } else {
            (empty, empty, empty)
        };
        let (dl0, dl1, dr0) = if DOWN {
            (&d0[..k], &d1[..k], &d0[1..][..k])
        } else {
            (empty, empty, empty)
        };
        for i in 0..k {
            let mut f = m[i] * g - cap(m[i]) * v[i];
            if UP {
                f += ul1[i];
                f += ur0[i];
                f += ur1[i];
            }
            if DOWN {
                f += dl0[i];
                f += dl1[i];
                f += dr0[i];
            }
            v[i] += (h * w[i]) * f;
            x0[i] = x[i];
            x[i] += h * v[i];
        }
    }
}

/// Whether every collider is a sphere or a plane that does not turn (the shapes the passes
/// on the arrays handle: [`contact_soa`], [`super::grid_kernel::ccd_mask`]).
fn soa_colliders(colliders: &[crate::collide::Collider]) -> bool {
    use crate::collide::Shape;
    colliders.iter().all(|c| {
        c.angular_velocity == Vec3::ZERO
            && matches!(c.shape, Shape::Sphere { .. } | Shape::Plane { .. })
    })
}

/// The contacts of a run of particles (positions `x`, `y`, `z` updated in place, start
/// positions `p0`, inverse masses `w`) with `colliders`, every one a sphere or a plane that
/// does not turn ([`soa_colliders`]): in sub-chunks of [`NEAR_SUB`] particles, collider by
/// collider in order, [`contact_soa`] on each sub-chunk that holds a particle not
/// [`surely_clear`] of that collider at that point. A skipped sub-chunk is one the exact
/// routine leaves as it is (every particle clear of the contact layer), so the same bits as
/// [`contact_soa`] on the whole run, collider after collider. Returns the contact count.
#[inline(always)]
pub(crate) fn contacts_soa_row(
    colliders: &[crate::collide::Collider],
    h: f32,
    w: &[f32],
    [x, y, z]: [&mut [f32]; 3],
    p0: [&[f32]; 3],
) -> u32 {
    let n = w.len();
    let mut count = 0;
    let mut s0 = 0;
    while s0 < n {
        let m = NEAR_SUB.min(n - s0);
        let sub = s0..s0 + m;
        for col in colliders {
            // Whole sub-chunks as fixed-length loops (vectorised), the tail as it is.
            let near = if m == NEAR_SUB {
                near_one(
                    col,
                    [
                        &x[s0..s0 + NEAR_SUB],
                        &y[s0..s0 + NEAR_SUB],
                        &z[s0..s0 + NEAR_SUB],
                    ],
                )
            } else {
                near_one(col, [&x[sub.clone()], &y[sub.clone()], &z[sub.clone()]])
            };
            if near {
                count += contact_soa(
                    col,
                    h,
                    &w[sub.clone()],
                    [
                        &mut x[sub.clone()],
                        &mut y[sub.clone()],
                        &mut z[sub.clone()],
                    ],
                    [
                        &p0[0][sub.clone()],
                        &p0[1][sub.clone()],
                        &p0[2][sub.clone()],
                    ],
                );
            }
        }
        s0 += m;
    }
    count
}

/// Whether a particle of the run `x, y, z` is not [`surely_clear`] of `col` (a sphere or a
/// plane; `true` for every other shape), as one reduction over the run.
#[inline(always)]
fn near_one(col: &crate::collide::Collider, [x, y, z]: [&[f32]; 3]) -> bool {
    let Some(layer) = Layer::of(col) else {
        return true;
    };
    let n = x.len();
    let (y, z) = (&y[..n], &z[..n]);
    let mut near = false;
    for k in 0..n {
        near |= layer.near(x[k], y[k], z[k]);
    }
    near
}

/// A sphere's or a plane's contact layer widened by [`CLEAR_MARGIN`]: the negation of
/// [`surely_clear`] as a per-particle test that loops over runs vectorise.
#[derive(Clone, Copy)]
enum Layer {
    Sphere {
        center: Vec3,
        reach_sq: f32,
    },
    Plane {
        point: Vec3,
        normal: Vec3,
        limit: f32,
    },
}

impl Layer {
    /// `None` for shapes other than spheres and planes.
    #[inline(always)]
    fn of(col: &crate::collide::Collider) -> Option<Self> {
        use crate::collide::Shape;
        match col.shape {
            Shape::Sphere { center, radius } => {
                let reach = radius + col.thickness + CLEAR_MARGIN;
                Some(Self::Sphere {
                    center,
                    reach_sq: reach * reach,
                })
            }
            Shape::Plane { point, normal } => Some(Self::Plane {
                point,
                normal,
                limit: col.thickness + CLEAR_MARGIN,
            }),
            _ => None,
        }
    }

    /// Whether the particle at `(x, y, z)` is within the widened layer.
    #[inline(always)]
    fn near(self, x: f32, y: f32, z: f32) -> bool {
        match self {
            Self::Sphere { center, reach_sq } => {
                (Vec3::new(x, y, z) - center).length_squared() <= reach_sq
            }
            Self::Plane {
                point,
                normal,
                limit,
            } => (Vec3::new(x, y, z) - point).dot(normal) <= limit,
        }
    }
}

/// [`super::xpbd::contact`] with collider `col` (a sphere or a plane that does not turn) for
/// every free particle of a run (positions `x`, `y`, `z` updated in place, start positions
/// `p0`, inverse masses `w`): the same operations in the same order (`Shape::distance`, the
/// push, Coulomb friction on the tangential displacement), computed in every lane and
/// selected, so the bits are the per-particle routine's. Returns the number of contacts.
#[inline(always)]
pub(crate) fn contact_soa(
    col: &crate::collide::Collider,
    h: f32,
    w: &[f32],
    x: [&mut [f32]; 3],
    x0: [&[f32]; 3],
) -> u32 {
    use crate::collide::Shape;
    match col.shape {
        Shape::Sphere { center, radius } => {
            contact_lanes::<true>(col, center, radius, Vec3::Y, h, w, x, x0)
        }
        Shape::Plane { point, normal } => {
            contact_lanes::<false>(col, point, 0.0, normal, h, w, x, x0)
        }
        _ => unreachable!("soa_colliders holds only spheres and planes"),
    }
}

/// [`contact_soa`] for a sphere (`SPHERE`: centre `p`, radius `r`) or a plane (point `p`,
/// unit normal `nrm`), as one branch-free loop.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn contact_lanes<const SPHERE: bool>(
    col: &crate::collide::Collider,
    p: Vec3,
    r: f32,
    nrm: Vec3,
    h: f32,
    w: &[f32],
    [x, y, z]: [&mut [f32]; 3],
    [x0, y0, z0]: [&[f32]; 3],
) -> u32 {
    let n = w.len();
    let (x, y, z) = (&mut x[..n], &mut y[..n], &mut z[..n]);
    let (x0, y0, z0) = (&x0[..n], &y0[..n], &z0[..n]);
    let (th, mu_s, mu_k) = (
        col.thickness,
        col.friction.static_coefficient,
        col.friction.kinetic_coefficient,
    );
    // `velocity_at(x) * h` of a collider that does not turn.
    let vh = col.velocity * h;
    let mut count = 0;
    for i in 0..n {
        let (px, py, pz) = (x[i], y[i], z[i]);
        let (dist, [nx, ny, nz]) =
            super::grid_kernel::lane_distance(SPHERE, p, r, nrm, [px, py, pz]);
        let phi = dist - th;
        let touch = !(phi >= 0.0) && w[i] != 0.0;
        let push = -phi;
        let (qx, qy, qz) = (px + push * nx, py + push * ny, pz + push * nz);
        let (rx, ry, rz) = (
            (qx - x0[i]) - vh.x,
            (qy - y0[i]) - vh.y,
            (qz - z0[i]) - vh.z,
        );
        let rn = rx * nx + ry * ny + rz * nz;
        let (tx, ty, tz) = (rx - rn * nx, ry - rn * ny, rz - rn * nz);
        let t_len = (tx * tx + ty * ty + tz * tz).sqrt();
        // Static: the whole tangential displacement goes (`x − t`, computed as `x − t·1`,
        // the same bits); kinetic: `x − t·min(μk·push/|t|, 1)`; nothing when `|t|` is 0 (or
        // NaN), as in the per-particle routine.
        let stat = t_len <= mu_s * push;
        let s = if stat {
            1.0
        } else {
            (mu_k * push / t_len).min(1.0)
        };
        let slide = stat || t_len > 0.0;
        let (fx, fy, fz) = if slide {
            (qx - tx * s, qy - ty * s, qz - tz * s)
        } else {
            (qx, qy, qz)
        };
        // Stored in every lane (a select, not a branch), so the loop vectorises.
        (x[i], y[i], z[i]) = if touch { (fx, fy, fz) } else { (px, py, pz) };
        count += u32::from(touch);
    }
    count
}

/// A cheap test that `p` is clear of a sphere's or a plane's contact layer by more than
/// [`CLEAR_MARGIN`] (far more than the rounding of the exact test), so the exact contact
/// routine would do nothing; `false` (run the exact routine) for every other shape.
#[inline(always)]
fn surely_clear(col: &crate::collide::Collider, p: Vec3) -> bool {
    use crate::collide::Shape;
    match col.shape {
        Shape::Sphere { center, radius } => {
            let reach = radius + col.thickness + CLEAR_MARGIN;
            (p - center).length_squared() > reach * reach
        }
        Shape::Plane { point, normal } => (p - point).dot(normal) > col.thickness + CLEAR_MARGIN,
        _ => false,
    }
}

/// From this spacing on, a horizontal pass runs as blocks of two disjoint runs of `s`
/// columns (no masked lanes, in place) instead of the masked two-phase row kernel.
const BLOCK_SPACING: usize = 16;

/// [`Placed`] slots of the chain blocks (warp, weft) and of the first thread's chain scratch
/// (past the grid's arrays, slots 0–37), and of the first colour mask.
const CHAIN_SLOT: usize = 40;
const SCRATCH_SLOT: usize = 42;
/// [`Placed`] slots of the shear chains' blocks (diagonals, anti-diagonals).
const SHEAR_SLOT: usize = 38;
/// [`Placed`] slot of the first thread's ring of air cell rows.
const AIR_SLOT: usize = 46;

/// Rows per band of [`XpbdGrid::predict`]'s fused pass (air and prediction): the cell rows
/// between bands are computed first, one per band, so fewer bands compute fewer apart.
const PREDICT_BAND: usize = 8;
const MASK_SLOT: usize = 50;

/// Particles per chunk of the vectorised contact pre-test.
const NEAR_CHUNK: usize = 64;

/// Particles per sub-chunk of a chunk that the contact kernel runs on (or skips) as a whole,
/// collider by collider. The kernel's chain of square roots and divisions per particle is
/// long, so longer runs per call overlap more of them: 64 ran the 256² drape 4–5 % faster
/// than 16 (fifteenth round), though fewer sub-chunks are skipped.
const NEAR_SUB: usize = 64;

/// `near[k]`: whether particle `k` of a chunk is not [`surely_clear`] of some collider (at
/// its current position), as plain loops over the chunk that the compiler vectorises. A
/// particle clear of every collider is untouched by the contact pass (the first collider
/// does not move it, so the test holds for the next), so only `near` particles need it.
#[inline(always)]
fn near_any(colliders: &[crate::collide::Collider], [x, y, z]: [&[f32]; 3], near: &mut [bool]) {
    let n = near.len();
    let (x, y, z) = (&x[..n], &y[..n], &z[..n]);
    near.fill(false);
    for col in colliders {
        let Some(layer) = Layer::of(col) else {
            near.fill(true);
            continue;
        };
        for k in 0..n {
            near[k] |= layer.near(x[k], y[k], z[k]);
        }
    }
}

/// See [`surely_clear`], m.
const CLEAR_MARGIN: f32 = 1e-4;

/// Whether the triangles are the builder's: two per cell, in row-major cell order.
fn grid_triangles(topology: &Topology, rows: usize, cols: usize) -> bool {
    let t = topology.triangles();
    t.len() == 2 * (rows - 1) * (cols - 1)
        && (0..rows - 1).all(|r| {
            (0..cols - 1).all(|c| {
                let i = (r * cols + c) as u32;
                let n = cols as u32;
                let k = 2 * (r * (cols - 1) + c);
                t[k] == [i, i + n, i + 1] && t[k + 1] == [i + 1, i + n, i + n + 1]
            })
        })
}

/// Whether every row of `v` (rows of `cols`) holds the same bits as its first row.
fn rows_equal(v: &[f32], cols: usize) -> bool {
    let Some(first) = v.get(..cols) else {
        return true;
    };
    v.chunks_exact(cols).all(|row| {
        row.iter()
            .zip(first)
            .all(|(a, b)| a.to_bits() == b.to_bits())
    })
}

/// The rest (or limit) lengths a pass reads.
fn rest_of<'a>(rest: &'a [Placed; 6], levels: &'a [Level], which: Rest) -> &'a [f32] {
    match which {
        Rest::Class(c) => &rest[c],
        Rest::Vertical(l) => &levels[l].vertical,
        Rest::Horizontal(l) => &levels[l].horizontal,
    }
}

/// Which lengths a pass reads.
#[derive(Debug, Clone, Copy)]
enum Rest {
    Class(usize),
    Vertical(usize),
    Horizontal(usize),
}

/// What every row of a pass reads.
pub(crate) struct Shared<'a> {
    prev: &'a [Placed; 3],
    w: &'a [f32],
    rest: &'a [f32],
    mode: Mode,
    /// Whether the multipliers are read and written: with one sweep per substep they are
    /// zero whenever read (then skipping them gives the same bits: `−C − α·0 = −C`).
    keep: bool,
    /// `cols` when every row of `rest` holds the same bits as its first row (a flat rest
    /// grid: [`XpbdGrid::uniform`]), else 0: slot `g` is then read at `g mod cols`, so a pass
    /// streams one row of lengths instead of a whole array of them (the same values).
    rest_cols: usize,
}

/// The cell row that [`XpbdGrid::shear_rows`] sweeps last, between the two halves of cell
/// rows it sweeps at the same time (`[0, b)` and `(b, rows − 1)`); the reference path sorts
/// its shear springs into the same order with it.
pub(crate) fn shear_rows_between(rows: usize) -> usize {
    (rows - 1) / 2
}

/// One row of a vertical pass: the `m` pairs `(c + a_dc)` of row `a` against `(c + b_dc)` of
/// row `b` (`rows`: each row's x, y, z from its first column; `(ga, gb)`: the rows' first
/// slots, the pairs' slots from `ga`), projected in place with `kernel`; `lambda` from the
/// row's first slot. [`XpbdGrid::vertical`]'s colours and [`XpbdGrid::shear_rows`]' rows both
/// project through it.
fn pair_row(
    kernel: crate::simd::Kernel,
    rows: ([&mut [f32]; 3], [&mut [f32]; 3]),
    (a_dc, b_dc, m): (usize, usize, usize),
    sh: &Shared<'_>,
    (ga, gb): (usize, usize),
    lambda: &mut [f32],
) {
    let ([xa, ya, za], [xb, yb, zb]) = rows;
    crate::simd::xpbd_pairs(
        kernel,
        [
            &mut xa[a_dc..a_dc + m],
            &mut ya[a_dc..a_dc + m],
            &mut za[a_dc..a_dc + m],
        ],
        [
            &mut xb[b_dc..b_dc + m],
            &mut yb[b_dc..b_dc + m],
            &mut zb[b_dc..b_dc + m],
        ],
        sh,
        (ga + a_dc, gb + b_dc, ga),
        &mut lambda[..m],
    );
}

/// Rows `r` and `r + dr` of a block, as two disjoint slices.
fn rows_pair(block: &mut [f32], r: usize, dr: usize, cols: usize) -> (&mut [f32], &mut [f32]) {
    let (a, b) = block.split_at_mut((r + dr) * cols);
    (&mut a[r * cols..(r + 1) * cols], &mut b[..cols])
}

/// `Vec3`s into three arrays (x, y, z), rows of `cols` in parallel (a copy: the same values
/// however the rows are shared out).
fn scatter(v: &[Vec3], out: &mut [Placed; 3], cols: usize) {
    let [x, y, z] = out;
    x.par_chunks_mut(cols)
        .zip(y.par_chunks_mut(cols))
        .zip(z.par_chunks_mut(cols))
        .zip(v.par_chunks(cols))
        .for_each(|(((x, y), z), v)| {
            for (((p, x), y), z) in v.iter().zip(x).zip(y).zip(z) {
                (*x, *y, *z) = (p.x, p.y, p.z);
            }
        });
}

/// The air's parameters for [`air_row`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct AirCoefficients {
    density: f32,
    drag: f32,
    lift: f32,
    wind: Vec3,
}

impl AirCoefficients {
    /// The coefficients of `config`'s air with the current `wind`.
    pub(crate) fn of(config: &SimConfig, wind: Vec3) -> Self {
        let a = &config.air;
        Self {
            density: a.density,
            drag: a.drag_coefficient,
            lift: a.lift_coefficient,
            wind,
        }
    }
}

/// Component `comp` of a cell row's two triangles (`m` cells each, laid out as by
/// [`air_cells`]).
fn part(c: Option<&[f32]>, comp: usize, m: usize) -> Option<[&[f32]; 2]> {
    c.map(|c| [&c[comp * m..][..m], &c[(3 + comp) * m..][..m]])
}

/// The air forces of cell row `r` (between particle rows `r` and `r + 1`) of the state
/// `[x, v]` (rows of `cols` particles from row 0 of the slices) into `out` (`6·(cols − 1)`
/// floats: the first triangles' x, y, z, then the second's), with `kernel`.
fn air_cells(
    kernel: crate::simd::Kernel,
    coeff: &AirCoefficients,
    [x, v]: [[&[f32]; 3]; 2],
    (r, cols): (usize, usize),
    out: &mut [f32],
) {
    let m = cols - 1;
    let at = |r: usize| {
        let i = r * cols..(r + 1) * cols;
        [
            &x[0][i.clone()],
            &x[1][i.clone()],
            &x[2][i.clone()],
            &v[0][i.clone()],
            &v[1][i.clone()],
            &v[2][i],
        ]
    };
    let (t0, t1) = out.split_at_mut(3 * m);
    let (ax, rest) = t0.split_at_mut(m);
    let (ay, az) = rest.split_at_mut(m);
    let (bx, rest) = t1.split_at_mut(m);
    let (by, bz) = rest.split_at_mut(m);
    crate::simd::xpbd_air(
        kernel,
        at(r),
        at(r + 1),
        cols,
        coeff,
        [[ax, ay, az], [bx, by, bz]],
    );
}

/// The air force (divided by 3) of both triangles of every cell between particle rows `top`
/// and `bottom` (x, y, z, vx, vy, vz, at least `cols` each):
/// [`crate::forces::triangle_air_force`] with the same operations in the same order (so the
/// same bits), as a loop over shifted rows that the compiler vectorises.
#[inline(always)]
pub(crate) fn air_row(
    top: [&[f32]; 6],
    bottom: [&[f32]; 6],
    cols: usize,
    k: &AirCoefficients,
    out: [[&mut [f32]; 3]; 2],
) {
    let m = cols - 1;
    fn row<'a>(a: &[&'a [f32]; 6], first: usize, start: usize, m: usize) -> [&'a [f32]; 3] {
        [
            &a[first][start..start + m],
            &a[first + 1][start..start + m],
            &a[first + 2][start..start + m],
        ]
    }
    // Corners: p = (r, c), q = (r, c + 1), s = (r + 1, c), t = (r + 1, c + 1).
    let (xp, xq) = (row(&top, 0, 0, m), row(&top, 0, 1, m));
    let (xs, xt) = (row(&bottom, 0, 0, m), row(&bottom, 0, 1, m));
    let (vp, vq) = (row(&top, 3, 0, m), row(&top, 3, 1, m));
    let (vs, vt) = (row(&bottom, 3, 0, m), row(&bottom, 3, 1, m));
    let [[ax, ay, az], [bx, by, bz]] = out;
    let (ax, ay, az, bx, by, bz) = (
        &mut ax[..m],
        &mut ay[..m],
        &mut az[..m],
        &mut bx[..m],
        &mut by[..m],
        &mut bz[..m],
    );
    for c in 0..m {
        // First triangle (p, s, q), second (q, s, t), as the builder lists them.
        let p = (xp[0][c], xp[1][c], xp[2][c]);
        let q = (xq[0][c], xq[1][c], xq[2][c]);
        let sx = (xs[0][c], xs[1][c], xs[2][c]);
        let t = (xt[0][c], xt[1][c], xt[2][c]);
        let vp = (vp[0][c], vp[1][c], vp[2][c]);
        let vq = (vq[0][c], vq[1][c], vq[2][c]);
        let vs = (vs[0][c], vs[1][c], vs[2][c]);
        let vt = (vt[0][c], vt[1][c], vt[2][c]);
        (ax[c], ay[c], az[c]) = air_force(k, p, sx, q, vp, vs, vq);
        (bx[c], by[c], bz[c]) = air_force(k, q, sx, t, vq, vs, vt);
    }
}

type V3 = (f32, f32, f32);

/// [`crate::forces::triangle_air_force`]`(…) / 3` for corners `x0, x1, x2` with velocities
/// `v0, v1, v2`, operation for operation (glam's `Vec3` is scalar: `dot` is
/// `x·x' + y·y' + z·z'` left to right, `cross` as written below), in plain scalars so that the
/// loop around it vectorises.
#[inline(always)]
fn air_force(k: &AirCoefficients, x0: V3, x1: V3, x2: V3, v0: V3, v1: V3, v2: V3) -> V3 {
    let (e1x, e1y, e1z) = (x1.0 - x0.0, x1.1 - x0.1, x1.2 - x0.2);
    let (e2x, e2y, e2z) = (x2.0 - x0.0, x2.1 - x0.1, x2.2 - x0.2);
    let cx = e1y * e2z - e2y * e1z;
    let cy = e1z * e2x - e2z * e1x;
    let cz = e1x * e2y - e2x * e1y;
    let third = crate::forces::THIRD;
    let tx = (v0.0 + v1.0 + v2.0) * third;
    let ty = (v0.1 + v1.1 + v2.1) * third;
    let tz = (v0.2 + v1.2 + v2.2) * third;
    let (rx, ry, rz) = (k.wind.x - tx, k.wind.y - ty, k.wind.z - tz);
    let cc = cx * cx + cy * cy + cz * cz;
    let ss = rx * rx + ry * ry + rz * rz;
    let p = cc * ss;
    let live = (f32::MIN_POSITIVE..f32::INFINITY).contains(&p);
    let t = 1.0 / p.sqrt();
    let cr = cx * rx + cy * ry + cz * rz;
    let q = 0.25 * k.density * cr * t;
    let (a, b) = ((k.drag + k.lift) * ss, k.lift * cr);
    let fx = q * (a * cx - b * rx);
    let fy = q * (a * cy - b * ry);
    let fz = q * (a * cz - b * rz);
    if live {
        (fx * third, fy * third, fz * third)
    } else {
        (0.0, 0.0, 0.0)
    }
}

/// The correction of one compliant pair: `(dl, s)`, its multiplier's change `Δλ` and the
/// factor `s = Δλ / |l|` that moves its ends along `l` (the first end by `w_a·s·l`, the second
/// by `−w_b·s·l`): one division per pair instead of two (`1 / |l|` and `Δλ`). Both are zero
/// for a pair that does not move (both ends pinned, zero length).
#[inline(always)]
fn pair_correction(
    l: [f32; 3],
    rate_d: [f32; 3],
    wsum: f32,
    rest: f32,
    lambda: f32,
    (alpha, gamma): (f32, f32),
) -> (f32, f32) {
    let len2 = l[0] * l[0] + l[1] * l[1] + l[2] * l[2];
    let len = len2.sqrt();
    let ok = wsum > 0.0 && len > 0.0;
    // Δλ = (−C − α̃·λ − γ·(l·d)/|l|) / ((1 + γ)·wsum + α̃), times |l| / |l| so that s =
    // Δλ / |l| takes one division.
    let constraint = len - rest;
    let ld = l[0] * rate_d[0] + l[1] * rate_d[1] + l[2] * rate_d[2];
    let num = (-constraint - alpha * lambda) * len - gamma * ld;
    let den = ((1.0 + gamma) * wsum + alpha) * len2;
    // Zero where not `ok`, by a mask of the bits rather than a branch: with a branch the
    // compiler loads the pair's rate inputs under the mask (`vmaskmovps`), after the test.
    let s = f32::from_bits((num / den).to_bits() & 0_u32.wrapping_sub(u32::from(ok)));
    (s * len, s)
}

/// The factor `s` that puts a pair `l` longer than its `limit` back onto it (its ends move
/// by `w_a·s·l` and `−w_b·s·l`), or `None` when the limit leaves the pair where it is: within
/// the limit ([`past_limit`]'s screen, then exactly), zero length, or both ends pinned.
#[inline(always)]
fn limit_factor(l: [f32; 3], wsum: f32, limit: f32) -> Option<f32> {
    let len2 = l[0] * l[0] + l[1] * l[1] + l[2] * l[2];
    if !past_limit(len2, limit) {
        return None;
    }
    let len = len2.sqrt();
    (wsum > 0.0 && len > 0.0 && len > limit).then(|| (limit - len) / (wsum * len))
}

/// Projects the pairs `a[i]`–`b[i]` in place (a vertical pass's two rows). `g = (a0, b0,
/// slot0)`: the particle indices of `a[0]`, `b[0]` and the first slot.
#[inline(always)]
pub(crate) fn pairs(
    a: [&mut [f32]; 3],
    b: [&mut [f32]; 3],
    sh: &Shared<'_>,
    g: (usize, usize, usize),
    lambda: &mut [f32],
) {
    match sh.mode {
        Mode::Compliant { alpha, gamma } if sh.keep => {
            pairs_in::<true>(a, b, sh, g, lambda, (alpha, gamma));
        }
        Mode::Compliant { alpha, gamma } => {
            pairs_in::<false>(a, b, sh, g, lambda, (alpha, gamma));
        }
        Mode::Limit => limit_pairs(a, b, sh, g, lambda.len()),
    }
}

/// The structural strain limit's wavefront ([`XpbdGrid::structural_limit`]). Step `k` projects
/// the warp pair of rows `(2k, 2k + 1)` (colour 0), then `(2k − 1, 2k)` (colour 1), then the
/// weft of rows `2k − 1` and `2k` (their even columns, then their odd ones): a row's weft
/// runs once both of its warp pairs have, and a colour-1 pair once both of its colour-0
/// neighbours have, so every pair reads what it reads in the coloured order. A band of rows
/// `[a, c)` leaves the colour-1 pair `(a − 1, a)` and the weft of rows `a − 1` and `a` to the
/// join above it, which runs them once both bands are done.
struct Limits<'a> {
    warp: Shared<'a>,
    weft: Shared<'a>,
    /// [`Level::uniform`]: every row's limits read from the first row.
    uniform: [bool; 2],
    /// The weft's colour masks (even, odd columns), `cols − 1` slots each.
    masks: [&'a [f32]; 2],
    rows: usize,
    cols: usize,
    kernel: crate::simd::Kernel,
}

impl Limits<'_> {
    /// Rows `[a, c)` (`x`: their x, y, z) in `bands` bands, split at even rows.
    fn run(&self, x: [&mut [f32]; 3], a: usize, c: usize, bands: usize) {
        let b = (a + (c - a) * (bands / 2) / bands.max(1)) & !1;
        if bands <= 1 || b <= a || b >= c {
            self.band(x, a, c);
            return;
        }
        let cut = (b - a) * self.cols;
        let [x, y, z] = x;
        {
            let (x0, x1) = x.split_at_mut(cut);
            let (y0, y1) = y.split_at_mut(cut);
            let (z0, z1) = z.split_at_mut(cut);
            rayon::join(
                || self.run([x0, y0, z0], a, b, bands / 2),
                || self.run([x1, y1, z1], b, c, bands - bands / 2),
            );
        }
        let mut x = [x, y, z];
        self.pair(&mut x, a, b - 1);
        self.row(&mut x, a, b - 1);
        self.row(&mut x, a, b);
    }

    /// The wavefront's steps on rows `[a, c)` (`a` even), but for what the join above does.
    fn band(&self, x: [&mut [f32]; 3], a: usize, c: usize) {
        let mut x = x;
        let last = if c == self.rows { c / 2 } else { c / 2 - 1 };
        for k in a / 2..=last {
            let r = 2 * k;
            if r + 1 < c {
                self.pair(&mut x, a, r);
            }
            if k == a / 2 && a > 0 {
                continue;
            }
            if r >= 1 && r < c {
                self.pair(&mut x, a, r - 1);
            }
            if r >= 1 {
                self.row(&mut x, a, r - 1);
            }
            if r < c {
                self.row(&mut x, a, r);
            }
        }
    }

    /// The warp's limits between rows `r` and `r + 1` (`x` holds rows from `a` on).
    fn pair(&self, x: &mut [&mut [f32]; 3], a: usize, r: usize) {
        let cols = self.cols;
        let at = (r - a) * cols;
        let [x, y, z] = x;
        let (xa, xb) = x[at..at + 2 * cols].split_at_mut(cols);
        let (ya, yb) = y[at..at + 2 * cols].split_at_mut(cols);
        let (za, zb) = z[at..at + 2 * cols].split_at_mut(cols);
        let g = r * cols;
        let slots = if self.uniform[0] { 0 } else { g };
        crate::simd::xpbd_limit_pairs(
            self.kernel,
            [xa, ya, za],
            [xb, yb, zb],
            &self.warp,
            (g, g + cols, slots),
            cols,
        );
    }

    /// The weft's limits of row `r`, even columns then odd ones (`x` holds rows from `a` on).
    fn row(&self, x: &mut [&mut [f32]; 3], a: usize, r: usize) {
        let cols = self.cols;
        let at = (r - a) * cols;
        let [x, y, z] = x;
        let row = [
            &mut x[at..at + cols],
            &mut y[at..at + cols],
            &mut z[at..at + cols],
        ];
        let g = r * cols;
        let slots = if self.uniform[1] { 0 } else { g };
        crate::simd::xpbd_limit_row_both(self.kernel, row, &self.weft, (g, slots), self.masks);
    }
}

/// Pairs a strain limit's screen takes at a time ([`limit_pairs`], [`limit_row`]).
const SCREEN_LANES: usize = 16;

/// Whether a pair of squared length `len2` may be longer than its `limit`: `len2 >
/// limit²·(1 − 2⁻²⁰)`. The margin is past the rounding of `|l| = √len2` and of `limit²`, so a
/// pair this is false for has `|l| ≤ limit`, which the limit leaves where it is.
#[inline(always)]
fn past_limit(len2: f32, limit: f32) -> bool {
    const SCREEN: f32 = 1.0 - 1.0 / (1 << 20) as f32;
    len2 > limit * limit * SCREEN
}

/// Whether any of the [`SCREEN_LANES`] pairs `a[j]`–`b[j]` with `mask[j]` non-zero may be
/// past its limit `limit[j]` ([`past_limit`]); a loop the compiler vectorises.
#[inline(always)]
fn chunk_past_limit(a: [&[f32]; 3], b: [&[f32]; 3], limit: &[f32], mask: &[f32]) -> bool {
    let k = SCREEN_LANES;
    let [xa, ya, za] = a.map(|v| &v[..k]);
    let [xb, yb, zb] = b.map(|v| &v[..k]);
    let (limit, mask) = (&limit[..k], &mask[..k]);
    let mut over = 0_u32;
    for j in 0..k {
        let (dx, dy, dz) = (xa[j] - xb[j], ya[j] - yb[j], za[j] - zb[j]);
        let past = past_limit(dx * dx + dy * dy + dz * dz, limit[j]);
        over |= u32::from(past && mask[j] != 0.0);
    }
    over != 0
}

/// One-sided strain limits of the pairs `a[i]`–`b[i]`, `i < m` (a vertical pass's two rows,
/// or a block of a wide horizontal pass), projected in place. Screened: the squared lengths of
/// [`SCREEN_LANES`] pairs at a time against their limits, and only the pairs
/// [`past_limit`] projected, one by one ([`limit_factor`]). Most pairs of a cloth
/// are within their limits, so the pass costs about one read of the two rows.
#[inline(always)]
pub(crate) fn limit_pairs(
    a: [&mut [f32]; 3],
    b: [&mut [f32]; 3],
    sh: &Shared<'_>,
    (ga, gb, gs): (usize, usize, usize),
    m: usize,
) {
    let [ax, ay, az] = a;
    let [bx, by, bz] = b;
    let (ax, ay, az) = (&mut ax[..m], &mut ay[..m], &mut az[..m]);
    let (bx, by, bz) = (&mut bx[..m], &mut by[..m], &mut bz[..m]);
    let (wa, wb) = (&sh.w[ga..ga + m], &sh.w[gb..gb + m]);
    let rest = sh.rest_from(gs, m);
    let mut i0 = 0;
    while i0 < m {
        let n = SCREEN_LANES.min(m - i0);
        if n == SCREEN_LANES
            && !chunk_past_limit(
                [&ax[i0..], &ay[i0..], &az[i0..]],
                [&bx[i0..], &by[i0..], &bz[i0..]],
                &rest[i0..],
                &[1.0; SCREEN_LANES],
            )
        {
            i0 += n;
            continue;
        }
        for i in i0..i0 + n {
            let l = [ax[i] - bx[i], ay[i] - by[i], az[i] - bz[i]];
            let Some(f) = limit_factor(l, wa[i] + wb[i], rest[i]) else {
                continue;
            };
            let (sa, sb) = (wa[i] * f, wb[i] * f);
            ax[i] += sa * l[0];
            ay[i] += sa * l[1];
            az[i] += sa * l[2];
            bx[i] -= sb * l[0];
            by[i] -= sb * l[1];
            bz[i] -= sb * l[2];
        }
        i0 += n;
    }
}

/// One row of a horizontal pass of one-sided strain limits at spacing `s` below
/// [`BLOCK_SPACING`]: pairs `(c, c + s)` for the `m = mask.len()` slots with `mask[c]` 1 (the
/// colour; its pairs share no particle), projected in place, screened as in [`limit_pairs`].
/// `g0`: the particle index of the row's first column; `gs`: the slot of its first limit.
#[inline(always)]
pub(crate) fn limit_row(
    x: [&mut [f32]; 3],
    sh: &Shared<'_>,
    (g0, gs): (usize, usize),
    s: usize,
    mask: &[f32],
) {
    let m = mask.len();
    let [x, y, z] = x;
    let mut x = [&mut x[..m + s], &mut y[..m + s], &mut z[..m + s]];
    let w = &sh.w[g0..g0 + m + s];
    let rest = sh.rest_from(gs, m);
    let mut i0 = 0;
    while i0 < m {
        let n = SCREEN_LANES.min(m - i0);
        let [xs, ys, zs] = &x;
        if n == SCREEN_LANES
            && !chunk_past_limit(
                [&xs[i0..], &ys[i0..], &zs[i0..]],
                [&xs[i0 + s..], &ys[i0 + s..], &zs[i0 + s..]],
                &rest[i0..],
                &mask[i0..],
            )
        {
            i0 += n;
            continue;
        }
        project_span(&mut x, (w, rest, mask), s, i0..i0 + n);
        i0 += n;
    }
}

/// The pairs `(i, i + s)` of a row for `i` in `span` with `mask[i]` non-zero and
/// [`past_limit`], projected one by one onto their limits (`w`, `rest`: the row's inverse
/// masses and limits); returns whether it projected any.
#[inline(always)]
fn project_span(
    [x, y, z]: &mut [&mut [f32]; 3],
    (w, rest, mask): (&[f32], &[f32], &[f32]),
    s: usize,
    span: std::ops::Range<usize>,
) -> bool {
    let mut any = false;
    for i in span {
        let k = i + s;
        let l = [x[i] - x[k], y[i] - y[k], z[i] - z[k]];
        if mask[i] == 0.0 {
            continue;
        }
        let Some(f) = limit_factor(l, w[i] + w[k], rest[i]) else {
            continue;
        };
        move_ends([&mut **x, &mut **y, &mut **z], (i, k), (w[i], w[k]), f, l);
        any = true;
    }
    any
}

/// Moves the ends `i` and `k` of a pair `l = x_i − x_k` of a row by the factor `f` (a
/// correction `c = f·l`): `x_i += w_i·c`, `x_k −= w_k·c`, component by component.
#[inline(always)]
fn move_ends(
    [x, y, z]: [&mut [f32]; 3],
    (i, k): (usize, usize),
    (wi, wk): (f32, f32),
    f: f32,
    l: [f32; 3],
) {
    let c = [f * l[0], f * l[1], f * l[2]];
    x[i] += wi * c[0];
    x[k] -= wk * c[0];
    y[i] += wi * c[1];
    y[k] -= wk * c[1];
    z[i] += wi * c[2];
    z[k] -= wk * c[2];
}

/// Chunks of [`SCREEN_LANES`] pairs a row of [`limit_row_both`] may hold (its two bit sets).
const ROW_CHUNKS: usize = crate::grid::MAX_GRID_SIDE / SCREEN_LANES + 2;

/// Bit `c` of a bit set of chunks.
#[inline(always)]
fn chunk_bit(set: &[u64], c: usize) -> bool {
    (set[c / 64] >> (c % 64)) & 1 != 0
}

/// [`limit_row`] at spacing 1 for both colours of a row, `masks[0]` and then `masks[1]`, with
/// one screen of every pair instead of one per colour: a chunk of [`SCREEN_LANES`] pairs is
/// projected in colour 0 when one of its pairs was past its limit, and in colour 1 also when
/// colour 0 moved a particle of its pairs (a projection in the chunk or in the next chunk's
/// first pair). Any other chunk's pairs were within their limits and have not moved, which
/// [`limit_row`]'s screen would find too: the same projections, the same bits.
#[inline(always)]
pub(crate) fn limit_row_both(
    x: [&mut [f32]; 3],
    sh: &Shared<'_>,
    (g0, gs): (usize, usize),
    masks: [&[f32]; 2],
) {
    let m = masks[0].len();
    let chunks = m / SCREEN_LANES;
    let [x, y, z] = x;
    let mut x = [&mut x[..m + 1], &mut y[..m + 1], &mut z[..m + 1]];
    let w = &sh.w[g0..g0 + m + 1];
    let rest = sh.rest_from(gs, m);
    let mut flagged = [0_u64; ROW_CHUNKS.div_ceil(64)];
    let mut moved = flagged;
    debug_assert!(chunks + 2 <= 64 * flagged.len());
    for c in 0..chunks {
        let i0 = c * SCREEN_LANES;
        let [xs, ys, zs] = &x;
        if chunk_past_limit(
            [&xs[i0..], &ys[i0..], &zs[i0..]],
            [&xs[i0 + 1..], &ys[i0 + 1..], &zs[i0 + 1..]],
            &rest[i0..],
            &[1.0; SCREEN_LANES],
        ) {
            flagged[c / 64] |= 1 << (c % 64);
        }
    }
    // The last, partial chunk (index `chunks`) is never screened: always projected.
    let span = |c: usize| c * SCREEN_LANES..((c + 1) * SCREEN_LANES).min(m);
    for c in 0..=chunks {
        if (c == chunks || chunk_bit(&flagged, c))
            && project_span(&mut x, (w, rest, masks[0]), 1, span(c))
        {
            moved[c / 64] |= 1 << (c % 64);
        }
    }
    for c in 0..=chunks {
        let touched = c == chunks
            || chunk_bit(&flagged, c)
            || chunk_bit(&moved, c)
            || chunk_bit(&moved, c + 1);
        if touched {
            project_span(&mut x, (w, rest, masks[1]), 1, span(c));
        }
    }
}

#[inline(always)]
fn pairs_in<const KEEP: bool>(
    a: [&mut [f32]; 3],
    b: [&mut [f32]; 3],
    sh: &Shared<'_>,
    g: (usize, usize, usize),
    lambda: &mut [f32],
    params: (f32, f32),
) {
    let m = lambda.len();
    let [ax, ay, az] = a;
    let [bx, by, bz] = b;
    let (ax, ay, az) = (&mut ax[..m], &mut ay[..m], &mut az[..m]);
    let (bx, by, bz) = (&mut bx[..m], &mut by[..m], &mut bz[..m]);
    let (ga, gb, gs) = g;
    let (pax, pay, paz) = (
        &sh.prev[0][ga..ga + m],
        &sh.prev[1][ga..ga + m],
        &sh.prev[2][ga..ga + m],
    );
    let (pbx, pby, pbz) = (
        &sh.prev[0][gb..gb + m],
        &sh.prev[1][gb..gb + m],
        &sh.prev[2][gb..gb + m],
    );
    let (wa, wb) = (&sh.w[ga..ga + m], &sh.w[gb..gb + m]);
    let rest = sh.rest_from(gs, m);
    for i in 0..m {
        let l = [ax[i] - bx[i], ay[i] - by[i], az[i] - bz[i]];
        let d = [
            (ax[i] - pax[i]) - (bx[i] - pbx[i]),
            (ay[i] - pay[i]) - (by[i] - pby[i]),
            (az[i] - paz[i]) - (bz[i] - pbz[i]),
        ];
        let lam = if KEEP { lambda[i] } else { 0.0 };
        let (dl, f) = pair_correction(l, d, wa[i] + wb[i], rest[i], lam, params);
        if KEEP {
            lambda[i] += dl;
        }
        let (sa, sb) = (wa[i] * f, wb[i] * f);
        ax[i] += sa * l[0];
        ay[i] += sa * l[1];
        az[i] += sa * l[2];
        bx[i] -= sb * l[0];
        by[i] -= sb * l[1];
        bz[i] -= sb * l[2];
    }
}

/// What a pass at spacing 2 in groups of four ([`crate::simd::xpbd_quads`]) reads besides
/// the positions.
pub(crate) struct QuadsInput<'a> {
    /// Start positions of the substep (x, y, z).
    pub(crate) prev: [&'a [f32]; 3],
    /// Inverse masses.
    pub(crate) w: &'a [f32],
    /// Rest lengths by slot.
    pub(crate) rest: &'a [f32],
    /// The compliance `(α̃, γ)`.
    pub(crate) params: (f32, f32),
}

/// What [`crate::simd::xpbd_pairs`]' AVX-512 kernel reads besides the two rows and the
/// multipliers: the pairs' own entries (each slice from the pair's first, `m` long).
pub(crate) struct PairsInput<'a> {
    /// Start positions of the substep (x, y, z) of the first ends.
    pub(crate) prev_a: [&'a [f32]; 3],
    /// Start positions of the second ends.
    pub(crate) prev_b: [&'a [f32]; 3],
    /// Inverse masses of the first ends.
    pub(crate) wa: &'a [f32],
    /// Inverse masses of the second ends.
    pub(crate) wb: &'a [f32],
    /// Rest lengths by slot.
    pub(crate) rest: &'a [f32],
    /// The compliance `(α̃, γ)`.
    pub(crate) params: (f32, f32),
    /// Whether the multipliers are read and written.
    pub(crate) keep: bool,
}

impl Shared<'_> {
    /// Where slot `g`'s rest length is read: `g`, or its column in the first row when every
    /// row holds the same lengths.
    pub(crate) fn rest_slot(&self, g: usize) -> usize {
        if self.rest_cols > 0 {
            g % self.rest_cols
        } else {
            g
        }
    }

    /// The `m` rest lengths from slot `g` ([`Self::rest_slot`]).
    fn rest_from(&self, g: usize, m: usize) -> &[f32] {
        let s = self.rest_slot(g);
        &self.rest[s..s + m]
    }

    /// The input of [`crate::simd::xpbd_pairs`]' AVX-512 kernel for the `m` pairs of
    /// [`pairs`] at `g = (a0, b0, slot0)`; `None` for a limit (those take [`pairs`]).
    pub(crate) fn pairs_input(
        &self,
        (ga, gb, gs): (usize, usize, usize),
        m: usize,
    ) -> Option<PairsInput<'_>> {
        match self.mode {
            Mode::Compliant { alpha, gamma } => Some(PairsInput {
                prev_a: std::array::from_fn(|k| &self.prev[k][ga..ga + m]),
                prev_b: std::array::from_fn(|k| &self.prev[k][gb..gb + m]),
                wa: &self.w[ga..ga + m],
                wb: &self.w[gb..gb + m],
                rest: self.rest_from(gs, m),
                params: (alpha, gamma),
                keep: self.keep,
            }),
            Mode::Limit => None,
        }
    }

    /// The pass's input for [`crate::simd::xpbd_quads`]; `None` for a limit or with kept
    /// multipliers (those passes take the masked [`row`]).
    pub(crate) fn quads_input(&self) -> Option<QuadsInput<'_>> {
        match self.mode {
            Mode::Compliant { alpha, gamma } if !self.keep => Some(QuadsInput {
                prev: [&self.prev[0][..], &self.prev[1][..], &self.prev[2][..]],
                w: self.w,
                rest: self.rest,
                params: (alpha, gamma),
            }),
            _ => None,
        }
    }
}

/// The pairs `(i, i + 2)` for `i` in `4·q .. 4·q + 2`, `q` in `groups`, of a row seen from
/// its colour's first column (`x`, `prev`, `w` from there, `rest` by slot from there; `m`
/// slots): a horizontal pass at spacing 2 (colour `⌊c / 2⌋ mod 2`) on groups of four
/// columns, with the masked [`row`]'s arithmetic (the same bits), in place. Compliant pairs,
/// multipliers not kept. The scalar form of [`crate::simd::xpbd_quads`]' kernel, which the
/// tests hold to the masked row's bits on every CPU.
#[cfg(test)]
pub(crate) fn quads_scalar(
    [x, y, z]: [&mut [f32]; 3],
    [px, py, pz]: [&[f32]; 3],
    w: &[f32],
    rest: &[f32],
    m: usize,
    groups: std::ops::Range<usize>,
    params: (f32, f32),
) {
    for q in groups {
        for i in [4 * q, 4 * q + 1] {
            if i >= m {
                return;
            }
            let k = i + 2;
            let l = [x[i] - x[k], y[i] - y[k], z[i] - z[k]];
            let d = [
                (x[i] - px[i]) - (x[k] - px[k]),
                (y[i] - py[i]) - (y[k] - py[k]),
                (z[i] - pz[i]) - (z[k] - pz[k]),
            ];
            let (_, f) = pair_correction(l, d, w[i] + w[k], rest[i], 0.0, params);
            move_ends([&mut *x, &mut *y, &mut *z], (i, k), (w[i], w[k]), f, l);
        }
    }
}

/// One row of a horizontal pass: pairs `(c, c + s)` for the `m = corr.len()` slots,
/// `mask[c]` 1 in the colour and 0 outside; corrections into `corr`, then applied.
#[inline(always)]
pub(crate) fn row(
    x: [&mut [f32]; 3],
    corr: [&mut [f32]; 3],
    sh: &Shared<'_>,
    g0: usize,
    s: usize,
    lambda: &mut [f32],
    mask: &[f32],
) {
    match sh.mode {
        Mode::Compliant { alpha, gamma } if sh.keep => {
            row_in::<true>(x, corr, sh, g0, s, lambda, mask, (alpha, gamma));
        }
        Mode::Compliant { alpha, gamma } => {
            row_in::<false>(x, corr, sh, g0, s, lambda, mask, (alpha, gamma));
        }
        Mode::Limit => limit_row(x, sh, (g0, g0), s, &mask[..lambda.len()]),
    }
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn row_in<const KEEP: bool>(
    x: [&mut [f32]; 3],
    corr: [&mut [f32]; 3],
    sh: &Shared<'_>,
    g0: usize,
    s: usize,
    lambda: &mut [f32],
    mask: &[f32],
    params: (f32, f32),
) {
    let m = lambda.len();
    let [x, y, z] = x;
    let [cx, cy, cz] = corr;
    let (cx, cy, cz, mask) = (&mut cx[..m], &mut cy[..m], &mut cz[..m], &mask[..m]);
    let (px, py, pz) = (
        &sh.prev[0][g0..g0 + m + s],
        &sh.prev[1][g0..g0 + m + s],
        &sh.prev[2][g0..g0 + m + s],
    );
    let w = &sh.w[g0..g0 + m + s];
    let rest = sh.rest_from(g0, m);
    {
        let (xa, xb) = (&x[..m], &x[s..s + m]);
        let (ya, yb) = (&y[..m], &y[s..s + m]);
        let (za, zb) = (&z[..m], &z[s..s + m]);
        let (pxa, pxb) = (&px[..m], &px[s..s + m]);
        let (pya, pyb) = (&py[..m], &py[s..s + m]);
        let (pza, pzb) = (&pz[..m], &pz[s..s + m]);
        let (wa, wb) = (&w[..m], &w[s..s + m]);
        for i in 0..m {
            let l = [xa[i] - xb[i], ya[i] - yb[i], za[i] - zb[i]];
            let d = [
                (xa[i] - pxa[i]) - (xb[i] - pxb[i]),
                (ya[i] - pya[i]) - (yb[i] - pyb[i]),
                (za[i] - pza[i]) - (zb[i] - pzb[i]),
            ];
            let lam = if KEEP { lambda[i] } else { 0.0 };
            let (dl, f) = pair_correction(l, d, wa[i] + wb[i], rest[i], lam, params);
            if KEEP {
                lambda[i] += dl * mask[i];
            }
            let f = f * mask[i];
            cx[i] = f * l[0];
            cy[i] = f * l[1];
            cz[i] = f * l[2];
        }
    }
    for (v, c) in [(&mut *x, &*cx), (&mut *y, &*cy), (&mut *z, &*cz)] {
        let (head, wh) = (&mut v[..m], &w[..m]);
        for i in 0..m {
            head[i] += wh[i] * c[i];
        }
        let (tail, wt) = (&mut v[s..s + m], &w[s..s + m]);
        for i in 0..m {
            tail[i] -= wt[i] * c[i];
        }
    }
}

/// Whether the blocks of `class` (0, 1: warp, weft; 2, 3: shear chains) must gather their
/// inverse masses and rest lengths (`statics`) and their start positions (`starts`) this time
/// (flags `XpbdGrid::chain_statics` and `chain_starts`); from then on they hold them (until
/// the inverse masses change, and for the substep).
fn chain_flags(statics: &mut [bool; 4], starts: &mut [bool; 4], class: usize) -> (bool, bool) {
    let gather_statics = !statics[class];
    statics[class] = true;
    let gather_starts = gather_statics || !starts[class];
    starts[class] = true;
    (gather_statics, gather_starts)
}

/// [`super::chains::iterate`] on a chunk of one or two blocks of `size`-float fields, with this
/// thread's scratch from `work` and the stepping thread's `kernel`.
fn iterate_chunk(
    chunk: &mut [f32],
    work: &ThreadScratch,
    (size, len): (usize, usize),
    solve: (super::chains::Params, u32),
    (multipliers, kernel): (Multipliers, crate::simd::Kernel),
    ahead: Option<&super::chains::Ahead<'_>>,
) {
    use super::chains::{FIELDS, SCRATCH};
    let in_chunk = chunk.len() / (FIELDS * size);
    super::chains::iterate(
        chunk,
        &mut work.mine()[..in_chunk * SCRATCH * size],
        size,
        len,
        solve,
        multipliers,
        kernel,
        ahead,
    );
}

/// Copies `dst.len()` entries of a row from column `start` on, wrapping at the row's end.
#[inline(always)]
fn run_load(dst: &mut [f32], row: &[f32], start: usize) {
    use super::chains::LANES;
    if dst.len() == LANES && start + LANES <= row.len() {
        // A whole run within the row (all but one block per row): no `memcpy` call.
        let d = dst.first_chunk_mut::<LANES>().expect("a whole run");
        *d = *row[start..].first_chunk::<LANES>().expect("a whole run");
        return;
    }
    let n = dst.len();
    let head = (row.len() - start).min(n);
    dst[..head].copy_from_slice(&row[start..start + head]);
    dst[head..].copy_from_slice(&row[..n - head]);
}

/// The inverse of [`run_load`]: `src` into a row from column `start` on, wrapping.
#[inline(always)]
fn run_store(src: &[f32], row: &mut [f32], start: usize) {
    use super::chains::LANES;
    if src.len() == LANES && start + LANES <= row.len() {
        let d = row[start..]
            .first_chunk_mut::<LANES>()
            .expect("a whole run");
        *d = *src.first_chunk::<LANES>().expect("a whole run");
        return;
    }
    let n = src.len();
    let head = (row.len() - start).min(n);
    row[start..start + head].copy_from_slice(&src[..head]);
    row[..n - head].copy_from_slice(&src[head..]);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::Kernel;

    /// A pass at spacing 2 computed only on its colour's pairs ([`crate::simd::xpbd_quads`],
    /// AVX-512 and AVX2) gives the masked row's bits ([`row`], every slot computed, half
    /// kept), on rows of every length around the kernels' 32- and 16-column spans (the last
    /// span masked), both colours, with pinned particles (zero inverse mass) and coincident
    /// ends (zero length) among them; so does the same arithmetic in scalar form
    /// ([`quads_scalar`], on every CPU). Tolerance: none. On a CPU without the kernel's
    /// instruction set the quads must decline (the caller then takes the row); under CI on
    /// x86-64 the AVX2 kernel must be available, so that it is not skipped.
    #[test]
    fn quads_give_the_masked_rows_bits() {
        crate::simd::require_avx2_under_ci("the AVX2 quads");
        let mut seed = 0x2545_f491_u32;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            f32::from_bits(0x3f80_0000 | (seed >> 9)) - 1.5
        };
        for cols in [
            3, 4, 5, 15, 16, 17, 18, 19, 20, 25, 31, 32, 33, 34, 35, 36, 63, 66, 67, 97, 130,
        ] {
            let placed = |v: Vec<f32>| {
                let mut p = Placed::default();
                p.reset(v.len(), 0);
                p.copy_from_slice(&v);
                p
            };
            let mut field = |scale: f32| placed((0..cols).map(|_| scale * next()).collect());
            let mut pos = [field(1.0), field(1.0), field(1.0)];
            let prev = [field(1.0), field(1.0), field(1.0)];
            let mut w = field(1.0);
            for (c, w) in w.iter_mut().enumerate() {
                *w = if c % 7 == 3 { 0.0 } else { w.abs() + 0.1 };
            }
            let rest = field(0.2);
            // Two coincident ends: columns 5 and 7 (a pair of colour 0), where they exist.
            if cols > 7 {
                for p in &mut pos {
                    p[7] = p[5];
                }
            }
            let mode = Mode::Compliant {
                alpha: 0.37,
                gamma: 0.011,
            };
            let shared = Shared {
                prev: &prev,
                w: &w,
                rest: &rest,
                mode,
                keep: false,
                rest_cols: 0,
            };
            let m = cols - 2;
            for colour in 0..2 {
                let mask: Vec<f32> = (0..cols)
                    .map(|c| f32::from(u8::from((c / 2) % 2 == colour)))
                    .collect();
                let mut masked = pos.clone().map(|p| p.to_vec());
                let mut corr = [vec![0.0; m], vec![0.0; m], vec![0.0; m]];
                let [cx, cy, cz] = &mut corr;
                let [x, y, z] = &mut masked;
                row(
                    [x, y, z],
                    [cx, cy, cz],
                    &shared,
                    0,
                    2,
                    &mut vec![0.0; m],
                    &mask,
                );
                let bits = |v: &[Vec<f32>; 3]| {
                    v.clone()
                        .map(|a| a.iter().map(|f| f.to_bits()).collect::<Vec<_>>())
                };
                let mut scalar = pos.clone().map(|p| p.to_vec());
                let [x, y, z] = &mut scalar;
                let first = 2 * colour;
                if first < m {
                    let Some(input) = shared.quads_input() else {
                        panic!("a compliant pass without kept multipliers has quads input");
                    };
                    let n = cols - first;
                    quads_scalar(
                        [&mut x[first..], &mut y[first..], &mut z[first..]],
                        input.prev.map(|p| &p[first..]),
                        &input.w[first..],
                        &input.rest[first..],
                        m - first,
                        0..n.div_ceil(4),
                        input.params,
                    );
                }
                assert_eq!(
                    bits(&scalar),
                    bits(&masked),
                    "{cols} columns, colour {colour}, scalar"
                );
                if first < m {
                    let before = pos.clone().map(|p| p.to_vec());
                    assert_ne!(
                        bits(&scalar),
                        bits(&before),
                        "{cols} columns: nothing moved"
                    );
                }
                for kernel in [Kernel::Avx512, Kernel::Avx2] {
                    let mut quads = pos.clone().map(|p| p.to_vec());
                    let [x, y, z] = &mut quads;
                    let ran = crate::simd::xpbd_quads(kernel, [x, y, z], &shared, 0, 2 * colour, m);
                    assert_eq!(ran, kernel.is_available(), "{kernel:?}, {cols} columns");
                    if !ran {
                        continue;
                    }
                    assert_eq!(
                        bits(&quads),
                        bits(&masked),
                        "{kernel:?}, {cols} columns, colour {colour}"
                    );
                    if 2 * colour < m {
                        let before = pos.clone().map(|p| p.to_vec());
                        assert_ne!(
                            bits(&quads),
                            bits(&before),
                            "{kernel:?}, {cols} columns: nothing moved"
                        );
                    }
                }
            }
        }
    }

    /// A pass reads a class's rest lengths from the first row only when every row of that
    /// class holds the first row's bits ([`XpbdGrid::uniform`], [`Shared::rest_slot`]): the
    /// flag is checked here against the topology's springs, compared independently (each
    /// spring against the spring of its class at the same column of row 0), on a flat grid
    /// (every class uniform, so the one-row reads are taken) and on grids whose rest shape
    /// is rotated or bent, where some rows differ in their last bits or more (the flag must
    /// then be false and every row read). Tolerance: none (bit equality).
    #[test]
    fn rest_lengths_are_read_from_one_row_only_when_every_row_is_the_same() {
        use crate::grid::GridBuilder;
        let (rows, cols) = (9, 7);
        let flat = GridBuilder::new(rows, cols).build().expect("flat");
        let rotated = GridBuilder::new(rows, cols)
            .rotation(glam::Quat::from_rotation_y(0.3) * glam::Quat::from_rotation_x(0.7))
            .origin(Vec3::new(0.37, 1.3, -2.1))
            .build()
            .expect("rotated");
        // The flat grid's springs with rest lengths from a shape with one row lifted: row 4
        // (its vertical springs to rows 3 and 5 change, and the bend's to rows 2 and 6), or
        // the last row (only the last row of each vertical class changes).
        let lifted = |row: usize| {
            let mut shape = flat.particles.position.clone();
            for p in &mut shape[row * cols..(row + 1) * cols] {
                p.y += 0.05;
            }
            let per_kind = std::array::from_fn(|i| {
                let kind = crate::topology::SpringKind::ALL[i];
                assert_eq!(kind as usize, i);
                let springs = flat.topology.springs_of(kind).iter();
                springs
                    .map(|s| crate::topology::Spring {
                        rest_length: shape[s.a as usize].distance(shape[s.b as usize]),
                        ..*s
                    })
                    .collect()
            });
            Topology::new(per_kind, flat.topology.triangles().to_vec()).with_grid(rows, cols)
        };
        let (bent, bent_last) = (lifted(4), lifted(rows - 1));
        let mut any_non_uniform = false;
        for (name, topology) in [
            ("flat", &flat.topology),
            ("rotated", &rotated.topology),
            ("bent", &bent),
            ("bent at the last row", &bent_last),
        ] {
            let mut grid = XpbdGrid::default();
            assert!(grid.prepare(topology, rows * cols), "{name}: not a grid");
            for (class, &(dr, a_dc, b_dc, kind)) in CLASSES.iter().enumerate() {
                // The rest length of every spring of this class by its slot (first end's row
                // and column, less the class's column offset).
                let mut by_slot = std::collections::BTreeMap::new();
                for sp in topology.springs_of(kind) {
                    let (a, b) = (sp.a as usize, sp.b as usize);
                    let (ra, ca, rb, cb) = (a / cols, a % cols, b / cols, b % cols);
                    if rb == ra + dr && cb + a_dc == ca + b_dc && ca >= a_dc {
                        by_slot.insert((ra, ca - a_dc), sp.rest_length.to_bits());
                    }
                }
                let expected = by_slot
                    .iter()
                    .all(|(&(_, c), &bits)| by_slot.get(&(0, c)) == Some(&bits));
                assert_eq!(grid.uniform[class], expected, "{name}: class {class}");
                if name == "flat" {
                    assert!(
                        grid.uniform[class],
                        "flat: class {class} not read from one row"
                    );
                }
                any_non_uniform |= !expected;
            }
        }
        assert!(any_non_uniform, "no grid with differing rows was tried");
    }
}
