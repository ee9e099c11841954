//! The explicit integrators' fast path on a regular grid.
//!
//! On a cloth built by [`crate::GridBuilder`] every spring kind is a shifted copy of one row
//! pattern, so a substep can run row by row over contiguous slices (no index chasing, no
//! bounds checks in the inner loops, which the compiler vectorises):
//!
//! 1. a row's particle state is six `f32` rows (x, y, z, vx, vy, vz): when nothing else
//!    reads the particles between substeps ([`Plan::persist`]) they are read in place from
//!    the row-blocked arrays the previous substep wrote ([`old_row`]; synced back to the
//!    particles at the step's end, [`sync`], and before any fallback to the reference path),
//!    else (a step's first substep, from the `Vec3` arrays, or position Verlet, whose first
//!    drift is applied here) copied into a band's ring of three row buffers;
//! 2. the six spring classes whose first end lies in row `s` (warp `(s,c)–(s+1,c)`, weft
//!    `(s,c)–(s,c+1)`, the two shear diagonals, the two bend springs) are evaluated once each
//!    from rows `s`, `s+1`, `s+2` into small per-class ring buffers (3 rows);
//! 3. row `s`'s particles then have every spring force they need (rows `s−2 ..= s`): each
//!    particle sums gravity, damping and its 12 spring contributions **in exactly the order
//!    of the reference [`crate::forces::accumulate`]** (kind by kind, springs in row-major
//!    order, `+f` at the spring's first end, `−f` at its second), integrates, and is written
//!    to the *next* state arrays; contacts (and continuous collision) run on that row at once:
//!    against spheres and planes that do not turn, the discrete contacts run vectorised on
//!    the row arrays ([`contacts_soa`], the reference's operations) and continuous
//!    collision's candidates come from its own cheap culls on the arrays
//!    ([`ccd_mask_soa`]); only candidates (and other colliders) take the per-particle code.
//!    Chunks of particles clear of every collider skip both.
//!
//! With the AVX-512 or AVX2 kernel (and no air), steps 2 and 3 run fused, chunk by chunk of
//! 16 or 8 particles ([`simd::fused_row`]): a chunk's six classes are computed from its rows' loads,
//! the row's own terms stay in registers (the shifted ones by lane rotation), only the
//! classes later rows read go to the ring, and the chunk integrates at once, in the same
//! order (the same bits). A band's two halo rows run it without integrating.
//!
//! With air on, each band also computes the air force of both triangles of every cell between
//! rows `s` and `s+1` (the reference's per-triangle operations, shared with XPBD's grid
//! path) into a ring of two cell rows, and each particle adds its (up to six) triangles'
//! shares after its spring terms, in the reference's triangle order.
//!
//! Absent neighbours (grid edges, switched-off kinds) contribute a signed zero that is an
//! exact identity: `x + (−0.0) == x` and `x − (+0.0) == x` for every `x`, so the padding of
//! the ring buffers holds −0.0 where a term is added and +0.0 where it is subtracted. Every
//! spring force uses the reference's operations in the reference's order (no fused
//! multiply-add, IEEE `sqrt` and one division per spring), so **the fast path is bit-identical to the
//! reference path**, for every kernel (portable, AVX2, AVX-512) and every number of threads.
//! The one reference case not reproduced, a spring of zero length (skipped by the reference),
//! is detected and the substep is redone by the reference path.
//!
//! Threads: the rows are cut into a fixed number of bands (one per thread of the current
//! rayon pool); each band reads only the *old* state (double buffering, the new state is
//! swapped in at the end) and recomputes the springs of the two rows above it (halo), so no
//! band waits for another and no sum depends on the partition or on scheduling.

use glam::Vec3;
use rayon::prelude::*;

use super::SubstepCtx;
use super::placed::Placed;
use super::shared_rows::SharedRows;
use crate::collide::{Collider, ccd, resolve_contacts_in};
use crate::config::{Integrator, SimConfig};
use crate::forces::{ZERO_LENGTH_SQUARED, spring_per_length};
use crate::simd::{self, Kernel};
use crate::topology::{SpringKind, Topology};

/// Spring classes of the grid, as shifted row patterns.
pub(crate) const WARP: usize = 0;
pub(crate) const WEFT: usize = 1;
pub(crate) const DIAG: usize = 2;
pub(crate) const ANTI: usize = 3;
pub(crate) const BENDV: usize = 4;
pub(crate) const BENDH: usize = 5;

/// Per class: (row offset of the second end, column offset of the first end, column
/// offset of the second end, spring kind). The spring of class `k` at slot `(r, c)` joins
/// `(r, c + a_dc)` to `(r + dr, c + b_dc)`.
pub(super) const CLASSES: [(usize, usize, usize, SpringKind); 6] = [
    (1, 0, 0, SpringKind::Warp),
    (0, 0, 1, SpringKind::Weft),
    (1, 0, 1, SpringKind::Shear),
    (1, 1, 0, SpringKind::Shear),
    (2, 0, 0, SpringKind::Bend),
    (0, 0, 2, SpringKind::Bend),
];

/// Springs (and particles) per chunk of the kernels; rows are computed in whole chunks. Two
/// AVX-512 vectors: each chunk's chain of dependent operations (square root, division, the
/// 12 ordered force terms) is latency-bound, and two independent vectors per iteration keep
/// the units busy (the peer scene ran 15 % faster than with 16 lanes, and no faster with 64;
/// the contact passes' chunk skips at 16 lanes gained nothing).
pub(crate) const LANES: usize = 32;

/// Front padding of the force rows (two slots, for the `c − 2` of horizontal bend springs).
pub(crate) const PAD: usize = 2;

/// Which explicit scheme a grid substep runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Scheme {
    /// x ← x + h·v; v ← v + h·F/m.
    Forward,
    /// v ← v + h·F/m; x ← x + h·v.
    Symplectic,
    /// x ← x + ½h·v; v ← v + h·F/m; x ← x + ½h·v.
    Verlet,
}

impl Scheme {
    fn of(integrator: Integrator) -> Option<Self> {
        match integrator {
            Integrator::ForwardEuler => Some(Self::Forward),
            Integrator::SymplecticEuler => Some(Self::Symplectic),
            Integrator::Verlet => Some(Self::Verlet),
            _ => None,
        }
    }
}

/// The decision, made before a substep, to run it on the grid fast path.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Plan {
    scheme: Scheme,
    kernel: Kernel,
    /// The fast path also runs the continuous-collision passes (per row), so the solver must
    /// not run them again.
    pub ccd: bool,
    /// Nothing else reads the particles until the step ends (no strain limiting, no
    /// self-collision, continuous collision fused): the state stays in the scratch's arrays
    /// from one substep to the next ([`GridScratch::rows`]) and goes back to the particles
    /// in [`sync`].
    persist: bool,
}

/// Scratch of the fast path: rest lengths by class, the next state, per-band ring buffers.
#[derive(Debug, Default, Clone)]
pub(crate) struct GridScratch {
    /// `(rows, cols, springs)` the scratch was prepared for, and whether the topology is a
    /// grid in the builder's order.
    key: Option<(usize, usize, usize, bool)>,
    /// Rest lengths per class, row by row, identical rows stored once ([`RestRows`]).
    rest: [RestRows; 6],
    next_position: Vec<Vec3>,
    next_velocity: Vec<Vec3>,
    /// The state kept between substeps of a step (see [`Plan::persist`]), row-blocked
    /// structure of arrays: row `s` is x, y, z, vx, vy, vz (`cols` each) from `6·cols·s`;
    /// each buffer starts on a cache line ([`Placed`]: with the allocator's 16-byte alignment
    /// every 64-byte load and store of a row straddled two lines, ≈ 5 % of the peer scene's
    /// time).
    rows: Placed,
    next_rows: Placed,
    /// `rows` holds the current state and the particles' positions and velocities are
    /// stale.
    resident: bool,
    /// Rows of +0.0 and −0.0 (`cols + 2·PAD`), the terms of absent neighbours.
    plus_zero: Vec<f32>,
    minus_zero: Vec<f32>,
    bands: Vec<Band>,
    /// Where the bands' boundaries sit.
    balance: Balance,
    /// A substep updating the state in place met a zero-length spring, which the reference
    /// skips and the fast path hands back to it. Part of the old state was already
    /// overwritten, so the substep cannot be handed back: the rest of the step does nothing
    /// and the step is run again from its start ([`GridScratch::take_redo`]).
    redo: bool,
    /// The step being run again: no update in place.
    no_in_place: bool,
}

/// The bands' boundaries, moved from substep to substep so that the bands finish together: a
/// band that finished later than its neighbour (more contacts, or started later by the thread
/// that took it) gives up a row to it. Results never depend on where the boundaries sit (every
/// row is computed the same way in any band); the balance only decides who computes what.
#[derive(Debug, Default, Clone)]
struct Balance {
    /// `(rows, bands)` the shifts are for.
    key: (usize, usize),
    /// Rows moved across each boundary from [`band_start`]'s split (positive: the band above
    /// gets more rows).
    shift: Vec<isize>,
    /// How far, in rows of work, the band below each boundary finished after the band above
    /// (smoothed over substeps).
    lead: Vec<f32>,
    /// The first row of every band, then the number of rows (`bands + 1` entries).
    starts: Vec<usize>,
}

impl Balance {
    /// Fewest rows of a band moved by the balance.
    const MIN_ROWS: usize = 4;

    /// Starts from [`band_start`]'s split when the rows or the bands changed.
    fn prepare(&mut self, rows: usize, bands: usize) {
        if self.key == (rows, bands) {
            return;
        }
        self.key = (rows, bands);
        self.shift.clear();
        self.shift.resize(bands.saturating_sub(1), 0);
        self.lead.clear();
        self.lead.resize(bands.saturating_sub(1), 0.0);
        self.place();
    }

    /// The starts from the split and the shifts (each band keeps at least `MIN_ROWS` rows
    /// where the split gave it that many, and never fewer than one).
    fn place(&mut self) {
        let (rows, bands) = self.key;
        self.starts.clear();
        self.starts
            .extend((0..=bands).map(|i| band_start(i, bands, rows)));
        for i in 1..bands {
            let base = self.starts[i];
            let lo = self.starts[i - 1] + Self::MIN_ROWS.min(base - self.starts[i - 1]);
            let next = self.starts[i + 1];
            let hi = next - Self::MIN_ROWS.min(next - base);
            let placed = base.saturating_add_signed(self.shift[i - 1]).clamp(lo, hi);
            self.shift[i - 1] = placed as isize - base as isize;
            self.starts[i] = placed;
        }
    }

    /// After a substep: `time(i)` is when band `i` started and finished (any common origin).
    /// A boundary moves by one row when the band below it has led the band above by more than
    /// a row's work (smoothed), and the other way round.
    fn update(&mut self, time: impl Fn(usize) -> [f32; 2]) {
        let bands = self.key.1;
        let mut moved = false;
        for i in 0..bands.saturating_sub(1) {
            let ([a0, a1], [b0, b1]) = (time(i), time(i + 1));
            let rows = (self.starts[i + 2] - self.starts[i]) as f32;
            let row = ((a1 - a0) + (b1 - b0)) / rows;
            if !(row > 0.0) {
                continue;
            }
            let lead = &mut self.lead[i];
            *lead = 0.75 * *lead + 0.25 * ((b1 - a1) / row);
            if lead.abs() > 1.0 {
                self.shift[i] += if *lead > 0.0 { 1 } else { -1 };
                *lead = 0.0;
                moved = true;
            }
        }
        if moved {
            self.place();
        }
    }
}

/// Ring buffers of one band.
#[derive(Debug, Default, Clone)]
pub(crate) struct Band {
    /// Row state by ring slot: x, y, z, vx, vy, vz (`cols` each).
    state: [[Vec<f32>; 6]; 3],
    /// Spring force by class, ring slot and component (`cols + 2·PAD` each).
    force: [[[Vec<f32>; 3]; 3]; 6],
    /// The new state of the current row, by component: x, y, z, vx, vy, vz, when the band
    /// writes into positions and velocities ([`Dest::Particles`]); into row-blocked arrays
    /// ([`Dest::Rows`]) it writes the row in place.
    out: [Vec<f32>; 6],
    /// Air: the force / 3 of both triangles of the cells between rows `r` and `r + 1`, by
    /// ring slot `r % 2`, triangle and component; cell `c` at `1 + c`, −0.0 in the first and
    /// last of the `cols + 1` slots (the terms of absent triangles).
    air: [[[Vec<f32>; 3]; 2]; 2],
    /// Particles of the current row the contact passes must see.
    near: Vec<bool>,
    /// The current row as `Vec3` for the per-particle contact passes: new positions and
    /// velocities, old positions.
    px: Vec<Vec3>,
    pv: Vec<Vec3>,
    start: Vec<Vec3>,
    /// When the band last started and finished, µs from its substep's start.
    time: [f32; 2],
    /// In place ([`Dest::InPlace`]): the new state of the rows other bands read (the band's
    /// first three, with a band above, and last two, with one below; see [`band`]),
    /// row-blocked like the state, by slot, and the row in each slot; written over the state
    /// after the bands join.
    defer: Vec<f32>,
    deferred: [Option<usize>; DEFERRED],
}

/// Most rows of a band written after the bands join when the state is updated in place: its
/// first three and its last two.
const DEFERRED: usize = 5;

impl Band {
    fn prepare(&mut self, cols: usize) {
        if self.out[0].len() == cols {
            return;
        }
        for slot in &mut self.state {
            for a in slot {
                // NaN padding past the row, up to whole chunks and two lanes more: the spring
                // lanes that do not exist read them.
                a.clear();
                a.resize(cols.next_multiple_of(LANES) + 2, f32::NAN);
            }
        }
        for a in &mut self.out {
            a.clear();
            a.resize(cols, 0.0);
        }
        for a in self.air.iter_mut().flatten().flatten() {
            a.clear();
            a.resize(cols + 1, -0.0);
        }
        self.near.clear();
        self.near.resize(cols, true);
        for a in [&mut self.px, &mut self.pv, &mut self.start] {
            a.clear();
            a.resize(cols, Vec3::ZERO);
        }
        self.defer.clear();
        self.defer.resize(DEFERRED * 6 * cols, 0.0);
        for (class, rows) in self.force.iter_mut().enumerate() {
            // Padding: −0.0 where the term is added, +0.0 where it is subtracted (see the
            // module docs); the anti-diagonal is read as `+A[c − 1]` and `−A[c]`, the other
            // horizontal classes as `−F[c − 1 or 2]` and `+F[c]`.
            let (front, back) = if class == ANTI {
                (-0.0, 0.0)
            } else {
                (0.0, -0.0)
            };
            for slot in rows {
                for a in slot {
                    a.clear();
                    a.resize(cols.next_multiple_of(LANES) + 2 * PAD, back);
                    a[..PAD].fill(front);
                }
            }
        }
    }
}

/// Whether a force kind contributes at all (the reference skips a kind whose stiffness and
/// damping are both zero, or all springs when both switches are off).
pub(super) fn kind_params(config: &SimConfig, kind: SpringKind) -> Option<(f32, f32)> {
    let sw = config.forces;
    if !(sw.springs || sw.dashpots) {
        return None;
    }
    let p = config.material.params(kind);
    let k = if sw.springs { p.stiffness } else { 0.0 };
    let c = if sw.dashpots { p.damping } else { 0.0 };
    if k == 0.0 && c == 0.0 {
        None
    } else {
        Some((k, c))
    }
}

/// Whether the air force is on (with a non-zero density and some coefficient).
pub(super) fn air_active(config: &SimConfig) -> bool {
    let air = &config.air;
    config.forces.air
        && !(air.density == 0.0 || (air.drag_coefficient == 0.0 && air.lift_coefficient == 0.0))
}

impl GridScratch {
    /// After a step: whether it must be run again from its start (see [`GridScratch::redo`]);
    /// the next step then runs without updating the state in place.
    pub(crate) fn take_redo(&mut self) -> bool {
        let redo = std::mem::take(&mut self.redo);
        self.no_in_place = redo;
        redo
    }

    /// A step is to be run again: its remaining substeps do nothing.
    pub(crate) fn redo_pending(&self) -> bool {
        self.redo
    }

    /// Checks (once per topology) that the springs are the builder's grid and records the
    /// rest lengths by class. Returns whether the fast path can run.
    fn prepare(&mut self, topology: &Topology, n: usize) -> bool {
        let Some((rows, cols)) = topology.grid() else {
            return false;
        };
        let springs = topology.springs().len();
        if let Some((r, c, s, ok)) = self.key
            && (r, c, s) == (rows, cols, springs)
        {
            return ok;
        }
        let mut full: [Placed; 6] = Default::default();
        let ok = rows * cols == n
            && rows >= 2
            && cols >= 2
            && load_rest(&mut full, topology, rows, cols);
        self.key = Some((rows, cols, springs, ok));
        if ok {
            for (slot, (rows_of, table)) in self.rest.iter_mut().zip(full).enumerate() {
                rows_of.build(table, rows, cols, slot);
            }
            let padded = cols + 2 * PAD;
            self.plus_zero.clear();
            self.plus_zero.resize(padded, 0.0);
            self.minus_zero.clear();
            self.minus_zero.resize(padded, -0.0);
        }
        ok
    }
}

/// One class's rest lengths by row, each distinct row stored once.
///
/// On a flat regular grid a class's rows repeat: a row's rest lengths depend only on the
/// coordinate differences along it and across it, and those take a handful of values with
/// the rounding. Storing each distinct row once (compared bit by bit, so every spring reads
/// exactly the value it had) takes the rest lengths out of the substep's memory traffic: at
/// 512² the full tables are 6 MiB, a quarter of what a substep streams. A cloth whose rows do
/// not repeat (a curved or irregular start) keeps the full table.
#[derive(Debug, Default, Clone)]
pub(crate) struct RestRows {
    /// The distinct rows, `cols` entries each in order of first use, then `LANES` entries of
    /// slack (the kernels read whole chunks past a row's end); or the full table.
    table: Placed,
    /// Where each row starts in `table`.
    at: Vec<usize>,
}

impl RestRows {
    /// Most distinct rows kept: past that, the full table (the search per row is linear).
    const MAX_DISTINCT: usize = 32;

    /// Builds from `full` (`rows · cols` entries, row-major, then `LANES` of slack), the table
    /// placed on page slot `slot` (`full` itself when its rows do not repeat).
    fn build(&mut self, full: Placed, rows: usize, cols: usize, slot: usize) {
        let row = |s: usize| &full[s * cols..][..cols];
        let same = |a: &[f32], b: &[f32]| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
        // Distinct rows (their first row), and each row's index among them.
        let mut distinct: Vec<usize> = Vec::new();
        self.at.clear();
        for s in 0..rows {
            let found = distinct.iter().position(|&d| same(row(d), row(s)));
            let k = match found {
                Some(k) => k,
                None if distinct.len() < Self::MAX_DISTINCT => {
                    distinct.push(s);
                    distinct.len() - 1
                }
                None => {
                    // Too many: the full table, every row where it was.
                    self.table = full;
                    self.at.clear();
                    self.at.extend((0..rows).map(|s| s * cols));
                    return;
                }
            };
            self.at.push(k * cols);
        }
        self.table.reset(distinct.len() * cols + LANES, slot);
        for (k, &d) in distinct.iter().enumerate() {
            self.table[k * cols..][..cols].copy_from_slice(row(d));
        }
    }

    /// The first `len` rest lengths of row `s` (entries past the row's `cols` belong to other
    /// rows or the slack: the kernels read them into lanes whose springs do not exist).
    #[inline]
    pub(crate) fn row(&self, s: usize, len: usize) -> &[f32] {
        &self.table[self.at[s]..][..len]
    }

    /// How many rows the table holds.
    #[cfg(test)]
    fn stored_rows(&self, cols: usize) -> usize {
        (self.table.len() - LANES) / cols
    }
}

/// Replays the builder's spring order, checks every spring against it and records the rest
/// lengths by class and slot `r * cols + c` (see [`CLASSES`]) into `rest`. Returns whether the
/// springs are exactly the grid's.
pub(super) fn load_rest(
    rest: &mut [Placed; 6],
    topology: &Topology,
    rows: usize,
    cols: usize,
) -> bool {
    for (slot, r) in rest.iter_mut().enumerate() {
        // LANES slack: the spring kernel reads whole chunks past the last row's end.
        r.reset(rows * cols + LANES, slot);
    }
    let idx = |r: usize, c: usize| (r * cols + c) as u32;
    let mut next = [0_usize; 4];
    let mut take = |rest: &mut [Placed; 6], class: usize, r: usize, c: usize| -> bool {
        let (dr, a_dc, b_dc, kind) = CLASSES[class];
        let list = topology.springs_of(kind);
        let Some(s) = list.get(next[kind as usize]) else {
            return false;
        };
        next[kind as usize] += 1;
        if s.a != idx(r, c + a_dc) || s.b != idx(r + dr, c + b_dc) {
            return false;
        }
        rest[class][r * cols + c] = s.rest_length;
        true
    };
    for r in 0..rows {
        for c in 0..cols {
            let ok = (r + 1 >= rows || take(rest, WARP, r, c))
                && (c + 1 >= cols || take(rest, WEFT, r, c))
                && (r + 1 >= rows
                    || c + 1 >= cols
                    || (take(rest, DIAG, r, c) && take(rest, ANTI, r, c)))
                && (r + 2 >= rows || take(rest, BENDV, r, c))
                && (c + 2 >= cols || take(rest, BENDH, r, c));
            if !ok {
                return false;
            }
        }
    }
    SpringKind::ALL
        .iter()
        .all(|&k| next[k as usize] == topology.springs_of(k).len())
}

/// Whether the fast path runs for these settings (the topology's springs are checked
/// against the grid pattern once more before the first substep).
pub(crate) fn applies(kernel: Kernel, integrator: Integrator, topology: &Topology) -> bool {
    kernel != Kernel::Reference && Scheme::of(integrator).is_some() && topology.grid().is_some()
}

/// Decides whether this substep runs on the grid fast path (and prepares the scratch).
pub(crate) fn plan(
    integrator: Integrator,
    ctx: &SubstepCtx<'_>,
    scratch: &mut GridScratch,
) -> Option<Plan> {
    let scheme = Scheme::of(integrator)?;
    let kernel = simd::kernel();
    if !applies(kernel, integrator, ctx.topology) {
        return None;
    }
    if !scratch.prepare(ctx.topology, ctx.particles.len()) {
        return None;
    }
    // The continuous-collision passes come after strain limiting and self-collision, which
    // run on the whole cloth after the integrator: fuse them only when neither is on.
    let ccd = ctx.config.continuous_collision
        && !ctx.colliders.is_empty()
        && ctx.config.strain_limit.is_none()
        && ctx.config.self_collision.is_none();
    let persist = ctx.config.strain_limit.is_none() && ctx.config.self_collision.is_none();
    Some(Plan {
        scheme,
        kernel,
        ccd,
        persist,
    })
}

/// Everything a band reads (shared by all bands).
pub(crate) struct Job<'a> {
    rows: usize,
    cols: usize,
    scheme: Scheme,
    h: f32,
    gravity: Vec3,
    damping: f32,
    /// Stiffness and damping per class, `None` when its kind contributes nothing.
    params: [Option<(f32, f32)>; 6],
    /// The air's coefficients when the air is on.
    air: Option<super::grid_xpbd::AirCoefficients>,
    /// The rows run on the fused kernel ([`simd::fused_row`]: AVX-512 or AVX2 chosen and
    /// available, no air), else on [`springs`] and [`particle_row`].
    fused: Option<simd::Fused>,
    /// The old state.
    src: Source<'a>,
    mass: &'a [f32],
    inv_mass: &'a [f32],
    rest: &'a [RestRows; 6],
    plus_zero: &'a [f32],
    minus_zero: &'a [f32],
    colliders: &'a [Collider],
    /// Every collider is a sphere or a plane that does not turn: the discrete contact pass
    /// runs vectorised on the structure-of-arrays row ([`contacts_soa`]).
    soa_contacts: bool,
    ccd: bool,
    /// Continuous collision cannot change a particle whose path over the substep is shorter
    /// than every collider's [`ccd::tolerance`] (halved, for rounding): this is that length
    /// when every collider is still (then the path relative to each collider is the particle's
    /// own), else 0 (no particle skipped).
    ccd_min_path: f32,
}

/// Where the bands read the old state.
#[derive(Clone, Copy)]
enum Source<'a> {
    /// The particles' positions and velocities.
    Particles(&'a [Vec3], &'a [Vec3]),
    /// The scratch's row-blocked arrays ([`GridScratch::rows`]), which the bands may be
    /// updating in place ([`Dest::InPlace`]).
    Rows(SharedRows<'a>),
}

/// Where a band writes its rows of the new state.
pub(crate) enum Dest<'a> {
    /// Positions and velocities (the band's rows).
    Particles(&'a mut [Vec3], &'a mut [Vec3]),
    /// Row-blocked arrays (the band's rows).
    Rows(&'a mut [f32]),
    /// The old state's own row-blocked arrays, updated in place (row `s` at `6·cols·s`; every
    /// band holds the whole array and writes only its rows, see [`band`]).
    InPlace(SharedRows<'a>),
}

impl<'a> Dest<'a> {
    /// The first `particles` particles' rows and the rest (`particles` a whole number of rows).
    fn split(self, particles: usize) -> (Dest<'a>, Dest<'a>) {
        match self {
            Dest::Particles(x, v) => {
                let ((x0, x1), (v0, v1)) = (x.split_at_mut(particles), v.split_at_mut(particles));
                (Dest::Particles(x0, v0), Dest::Particles(x1, v1))
            }
            Dest::Rows(r) => {
                let (r0, r1) = r.split_at_mut(6 * particles);
                (Dest::Rows(r0), Dest::Rows(r1))
            }
            Dest::InPlace(all) => (Dest::InPlace(all), Dest::InPlace(all)),
        }
    }
}

/// What a band reports.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct BandResult {
    contacts: u32,
    ccd: u32,
    degenerate: bool,
}

impl BandResult {
    fn merge(self, o: Self) -> Self {
        Self {
            contacts: self.contacts + o.contacts,
            ccd: self.ccd + o.ccd,
            degenerate: self.degenerate || o.degenerate,
        }
    }
}

/// Runs one substep on the fast path. Returns `false` (with the particles untouched) when the
/// reference path must run instead (a zero-length spring).
pub(crate) fn substep(ctx: &mut SubstepCtx<'_>, scratch: &mut GridScratch, plan: Plan) -> bool {
    let (rows, cols) = ctx.topology.grid().expect("planned on a grid");
    let n = rows * cols;
    let config = ctx.config;
    let sw = config.forces;
    let mut params = [None; 6];
    for (p, &(_, _, _, kind)) in params.iter_mut().zip(&CLASSES) {
        *p = kind_params(config, kind);
    }
    let threads = rayon::current_num_threads().max(1);
    let bands = threads.min(rows.div_ceil(8)).max(1);
    if scratch.bands.len() < bands {
        scratch.bands.resize_with(bands, Band::default);
    }
    for b in &mut scratch.bands[..bands] {
        b.prepare(cols);
    }
    if plan.persist {
        let len = 6 * n + ROW_SLACK;
        if scratch.next_rows.len() != len {
            // Both state buffers start on a cache line (a row's arrays then load and store
            // whole lines, none split across two), half a page apart from each other.
            let slot = if scratch.rows.len() == len { 32 } else { 0 };
            scratch.next_rows.reset(len, slot);
        }
    } else {
        scratch.next_position.resize(n, Vec3::ZERO);
        scratch.next_velocity.resize(n, Vec3::ZERO);
    }
    let p = &*ctx.particles;
    // A large cloth's resident state is updated in place ([`IN_PLACE_MIN`]).
    let in_place = plan.persist
        && scratch.resident
        && !scratch.no_in_place
        && n >= IN_PLACE_MIN
        && cols >= 2 * LANES;
    let src = if in_place {
        Source::Rows(SharedRows::writer(&mut scratch.rows))
    } else if scratch.resident {
        Source::Rows(SharedRows::reader(&scratch.rows))
    } else {
        Source::Particles(&p.position, &p.velocity)
    };
    let air = air_active(config).then(|| super::grid_xpbd::AirCoefficients::of(config, ctx.wind));
    let job = Job {
        rows,
        cols,
        scheme: plan.scheme,
        h: ctx.h,
        gravity: if sw.gravity {
            config.gravity
        } else {
            Vec3::ZERO
        },
        damping: if sw.damping { config.damping } else { 0.0 },
        params,
        fused: simd::Fused::detect(plan.kernel).filter(|_| air.is_none()),
        air,
        src,
        mass: &p.mass,
        inv_mass: &p.inv_mass,
        rest: &scratch.rest,
        plus_zero: &scratch.plus_zero,
        minus_zero: &scratch.minus_zero,
        colliders: ctx.colliders,
        soa_contacts: ctx.colliders.iter().all(|c| {
            c.angular_velocity == Vec3::ZERO
                && matches!(
                    c.shape,
                    crate::collide::Shape::Sphere { .. } | crate::collide::Shape::Plane { .. }
                )
        }),
        ccd: plan.ccd,
        ccd_min_path: if ctx
            .colliders
            .iter()
            .all(|c| c.velocity == Vec3::ZERO && c.angular_velocity == Vec3::ZERO)
        {
            0.5 * ctx
                .colliders
                .iter()
                .map(ccd::tolerance)
                .fold(f32::INFINITY, f32::min)
        } else {
            0.0
        },
    };
    scratch.balance.prepare(rows, bands);
    // The bands' times, for the balance (only with several bands: one band has nothing to
    // balance, and needs no clock).
    let clock = (bands > 1).then(std::time::Instant::now);
    let run = |r0: usize, r1: usize, band: &mut Band, dest: Dest<'_>| {
        let Some(clock) = clock else {
            return simd::run_band(plan.kernel, &job, r0, r1, band, dest);
        };
        let begin = clock.elapsed();
        let result = simd::run_band(plan.kernel, &job, r0, r1, band, dest);
        band.time = [begin, clock.elapsed()].map(|t| t.as_secs_f32() * 1e6);
        result
    };
    let dest = if let (true, Source::Rows(all)) = (in_place, job.src) {
        Dest::InPlace(all)
    } else if plan.persist {
        Dest::Rows(&mut scratch.next_rows)
    } else {
        Dest::Particles(&mut scratch.next_position, &mut scratch.next_velocity)
    };
    let result = run_bands(
        &run,
        &mut scratch.bands[..bands],
        &scratch.balance.starts,
        cols,
        dest,
    );
    if bands > 1 {
        let band = &scratch.bands;
        scratch.balance.update(|i| band[i].time);
    }
    if result.degenerate {
        if in_place {
            scratch.redo = true;
            return true;
        }
        return false;
    }
    if in_place {
        // The rows the bands' neighbours read, kept aside by the bands until now.
        let row = 6 * cols;
        for band in &scratch.bands[..bands] {
            for (slot, r) in band.deferred.iter().enumerate() {
                if let Some(r) = *r {
                    scratch.rows[row * r..][..row]
                        .copy_from_slice(&band.defer[row * slot..][..row]);
                }
            }
        }
    } else if plan.persist {
        std::mem::swap(&mut scratch.rows, &mut scratch.next_rows);
        scratch.resident = true;
    } else {
        let p = &mut *ctx.particles;
        std::mem::swap(&mut p.position, &mut scratch.next_position);
        std::mem::swap(&mut p.velocity, &mut scratch.next_velocity);
        scratch.resident = false;
    }
    ctx.contacts.contacts = result.contacts;
    if plan.ccd {
        ctx.contacts.ccd += result.ccd;
    }
    true
}

/// First row of band `i` of `bands` over `rows` rows. Every band but the first also
/// computes the springs of the two rows above it (its halo), so the first band gets about
/// one row more than the others and the rest share what is left: the bands then take about
/// the same time (with two bands on the peer scene, a split at 65/63 rows instead of 64/64
/// ran ≈ 2 % faster). Bands never change results, only who computes which rows.
fn band_start(i: usize, bands: usize, rows: usize) -> usize {
    if i == 0 {
        return 0;
    }
    if i >= bands {
        return rows;
    }
    // Bands of `b₀` rows, each after the first `HALO` rows shorter: b₀ + (bands − 1)(b₀ − HALO)
    // = rows; band i starts at i·b₀ − (i − 1)·HALO, rounded to the nearest row. (At most one
    // band per 8 rows: every band keeps at least one row, which a test checks.)
    const HALO: usize = 2;
    let total = rows + (bands - 1) * HALO;
    ((i * total + bands / 2 - (i - 1) * HALO * bands) / bands).min(rows)
}

/// Runs `bands` (band `i` from row `starts[i]` to `starts[i + 1]`) over a grid of `cols`
/// columns, writing into `dest` (those bands' rows only): halves on both sides of a
/// `rayon::join`, one band per leaf. (A `join` tree, not a parallel iterator over the bands:
/// the iterator's splitting and reduction cost ≈ 6 % of the peer scene's time on 2 threads,
/// for the same work.)
fn run_bands(
    run: &(impl Fn(usize, usize, &mut Band, Dest<'_>) -> BandResult + Sync),
    bands: &mut [Band],
    starts: &[usize],
    cols: usize,
    dest: Dest<'_>,
) -> BandResult {
    if let [band] = bands {
        return run(starts[0], starts[1], band, dest);
    }
    let half = bands.len() / 2;
    let (lo, hi) = bands.split_at_mut(half);
    let (d_lo, d_hi) = dest.split((starts[half] - starts[0]) * cols);
    let (a, b) = rayon::join(
        || run_bands(run, lo, &starts[..=half], cols, d_lo),
        || run_bands(run, hi, &starts[half..], cols, d_hi),
    );
    a.merge(b)
}

/// Writes the state kept in the scratch's arrays (if any) back to the particles: at the end
/// of a step, and before a substep that falls back to the reference path.
pub(crate) fn sync(scratch: &mut GridScratch, position: &mut [Vec3], velocity: &mut [Vec3]) {
    if !scratch.resident {
        return;
    }
    scratch.resident = false;
    let cols = scratch.key.map_or(0, |(_, c, _, _)| c);
    if cols == 0 {
        return;
    }
    // Rows in parallel (a copy: the same bits however they are shared out).
    scratch
        .rows
        .par_chunks_exact(6 * cols)
        .zip(position.par_chunks_exact_mut(cols))
        .zip(velocity.par_chunks_exact_mut(cols))
        .for_each(|((row, x), v)| {
            let [px, py, pz, vx, vy, vz] = row_parts(row, cols);
            for c in 0..cols {
                x[c] = Vec3::new(px[c], py[c], pz[c]);
                v[c] = Vec3::new(vx[c], vy[c], vz[c]);
            }
        });
}

/// After a substep that fell back to the reference path, the continuous-collision passes the
/// plan promised (with the old positions kept in the scratch).
pub(crate) fn keep_start(scratch: &mut GridScratch, position: &[Vec3]) {
    scratch.next_position.clear();
    scratch.next_position.extend_from_slice(position);
}

/// The continuous-collision passes over the whole cloth from the positions saved by
/// [`keep_start`] (used when a planned fast substep fell back to the reference path).
pub(crate) fn ccd_after_fallback(ctx: &mut SubstepCtx<'_>, scratch: &GridScratch) {
    ctx.contacts.ccd += ccd::resolve(ctx.colliders, &scratch.next_position, ctx.particles, ctx.h);
}

/// One band of rows `r0 .. r1`: writes their new state into `dest` (the band's rows only).
/// Generic code, compiled once per instruction set by [`crate::simd`].
///
/// In place ([`Dest::InPlace`], the old state's arrays shared by every band): the band reads
/// old rows `r0 − 2 ..= r1 + 1` (and, past the end of row `r1 + 1`'s last component, fewer
/// than `LANES + 2` floats of row `r1 + 2`), and row `s` for the last time at row `s`. So row
/// `s`'s new state is written over it once row `s` is done, except for the rows another band
/// reads: the band's first three when a band runs above it (that band reads down to `r0 + 1`,
/// and into `r0 + 2`) and its last two when one runs below (that band recomputes their
/// springs), which wait in [`Band::defer`] until the bands have joined ([`substep`] writes
/// them).
#[inline(always)]
pub(crate) fn band(
    job: &Job<'_>,
    r0: usize,
    r1: usize,
    band: &mut Band,
    mut dest: Dest<'_>,
) -> BandResult {
    let (rows, cols) = (job.rows, job.cols);
    let mut result = BandResult::default();
    let first = r0.saturating_sub(2);
    let half = 0.5 * job.h;
    let drift = job.scheme == Scheme::Verlet;
    // The old state's rows are read in place from the row-blocked arrays when they hold it
    // as the springs need it (no Verlet drift); else copied into the ring, rows
    // first ..= first + 2 first.
    let in_place = match job.src {
        Source::Rows(all) if !drift => Some(all),
        _ => None,
    };
    band.deferred = [None; DEFERRED];
    // Whole chunks of springs per row, read up to two columns past them (the offsets).
    let full = cols.next_multiple_of(LANES);
    let width = full + 2;
    if in_place.is_none() {
        for s in first..(first + 3).min(rows) {
            load_row(job, s, drift, half, &mut band.state[s % 3]);
        }
    }
    for s in first..r1 {
        let old = |r: usize| old_row(&band.state, in_place, cols, width, r);
        // Springs whose first end is in row s (the fused kernel computes them with the row).
        let classes = if job.fused.is_some() {
            &[][..]
        } else {
            &CLASSES[..]
        };
        for (class, &(dr, a_dc, b_dc, _)) in classes.iter().enumerate() {
            let Some((k, c)) = job.params[class] else {
                continue;
            };
            if s + dr >= rows {
                continue;
            }
            // All `cols` lanes are computed (whole vectors, no scalar remainder); the lanes
            // past the row's `m` springs read the ring's NaN padding or, in place, the next
            // component's values ([`old_row`]), are not checked for a zero length, and are
            // reset to the class's padding value afterwards.
            let m = cols - a_dc.max(b_dc);
            let rest = job.rest[class].row(s, full);
            let (a, b) = (old(s), old(s + dr));
            let [fx, fy, fz] = &mut band.force[class][s % 3];
            result.degenerate |= springs(
                k,
                c,
                m,
                [
                    &a[0][a_dc..][..full],
                    &a[1][a_dc..][..full],
                    &a[2][a_dc..][..full],
                    &a[3][a_dc..][..full],
                    &a[4][a_dc..][..full],
                    &a[5][a_dc..][..full],
                ],
                [
                    &b[0][b_dc..][..full],
                    &b[1][b_dc..][..full],
                    &b[2][b_dc..][..full],
                    &b[3][b_dc..][..full],
                    &b[4][b_dc..][..full],
                    &b[5][b_dc..][..full],
                ],
                rest,
                [
                    &mut fx[PAD..][..full],
                    &mut fy[PAD..][..full],
                    &mut fz[PAD..][..full],
                ],
            );
            let back = if class == ANTI { 0.0 } else { -0.0 };
            for f in [fx, fy, fz] {
                f[PAD + m..PAD + full].fill(back);
            }
        }
        // Air: the cells between rows s and s + 1, from the ring (drifted for Verlet, as the
        // reference evaluates its forces there); the band's rows need cell rows r0 − 1 on.
        if let Some(coeff) = &job.air
            && s + 1 >= r0
            && s + 1 < rows
        {
            let [[ax, ay, az], [bx, by, bz]] = &mut band.air[s % 2];
            super::grid_xpbd::air_row(
                old(s),
                old(s + 1),
                cols,
                coeff,
                [
                    [&mut ax[1..cols], &mut ay[1..cols], &mut az[1..cols]],
                    [&mut bx[1..cols], &mut by[1..cols], &mut bz[1..cols]],
                ],
            );
        }
        if let Some(proof) = job.fused
            && s < r0
        {
            // A row above the band: only its springs, for the band's first rows.
            let rows3 = (&band.state, in_place, width);
            result.degenerate |= fused_row(proof, job, s, rows3, &mut band.force, None);
        }
        if s >= r0 {
            // The new row: straight into the row-blocked arrays, or into the band's row
            // buffers (then converted into `Vec3`s).
            let (mut out, particles) = match &mut dest {
                Dest::InPlace(_) => {
                    let [x, y, z, vx, vy, vz] = &mut band.out;
                    ([x, y, z, vx, vy, vz].map(Vec::as_mut_slice), None)
                }
                Dest::Rows(rows) => (
                    split_row(&mut rows[6 * cols * (s - r0)..][..6 * cols], cols),
                    None,
                ),
                Dest::Particles(px, pv) => {
                    // (`prepare` sizes the buffers to `cols`.)
                    let [x, y, z, vx, vy, vz] = &mut band.out;
                    let out = [x, y, z, vx, vy, vz].map(Vec::as_mut_slice);
                    (out, Some((px, pv)))
                }
            };
            let state = old(s);
            if let Some(proof) = job.fused {
                let rows3 = (&band.state, in_place, width);
                result.degenerate |=
                    fused_row(proof, job, s, rows3, &mut band.force, Some(&mut out));
            } else {
                particle_row(job, s, state, &band.force, &band.air, &mut out);
            }
            // With the discrete contacts done on the arrays, the rows that also run continuous
            // collision get their candidates there too (old positions = the ring's row, which
            // Verlet's drift has changed: it keeps the per-particle mask).
            let premasked = job.soa_contacts && job.ccd && job.scheme != Scheme::Verlet;
            if job.soa_contacts {
                result.contacts += contacts_soa(job, s, &mut out);
            }
            let candidates = premasked && ccd_mask_soa(job, s, state, &out, &mut band.near);
            // The per-particle passes (other colliders, continuous-collision candidates) on
            // the row as `Vec3`.
            let per_particle = if job.colliders.is_empty() {
                false
            } else if premasked {
                candidates
            } else {
                !job.soa_contacts || job.ccd
            };
            if per_particle {
                let [x, y, z, vx, vy, vz] = &out;
                for c in 0..cols {
                    band.px[c] = Vec3::new(x[c], y[c], z[c]);
                    band.pv[c] = Vec3::new(vx[c], vy[c], vz[c]);
                }
                old_positions(job, s, &mut band.start);
                let (px, pv, start) = (&mut band.px, &mut band.pv, &band.start);
                contacts_row(
                    job,
                    s,
                    px,
                    pv,
                    start,
                    &mut band.near,
                    premasked,
                    &mut result,
                );
                let [x, y, z, vx, vy, vz] = &mut out;
                for c in 0..cols {
                    [x[c], y[c], z[c]] = band.px[c].to_array();
                    [vx[c], vy[c], vz[c]] = band.pv[c].to_array();
                }
            }
            if let Some((px, pv)) = particles {
                write_particles(&out, s - r0, cols, px, pv);
            }
            if let Dest::InPlace(all) = &dest {
                let row = 6 * cols;
                // (Only where there is a band above, or below.)
                let slot = if r0 > 0 && s < r0 + 3 {
                    Some(s - r0)
                } else {
                    (r1 < rows && s + 2 >= r1).then(|| s + 5 - r1)
                };
                if let Some(slot) = slot {
                    band.deferred[slot] = Some(s);
                    for (k, o) in band.out.iter().enumerate() {
                        band.defer[row * slot + k * cols..][..cols].copy_from_slice(o);
                    }
                } else {
                    for (k, o) in band.out.iter().enumerate() {
                        // SAFETY: this band has read row s for the last time (see above); no
                        // other band reads it (not one of the band's first three or last two).
                        #[allow(unsafe_code)]
                        unsafe {
                            all.put(row * s + k * cols, o);
                        }
                    }
                }
            }
        }
        // Row s + 3 replaces row s in the ring (needed by the springs of row s + 1).
        if in_place.is_none() && s + 3 < rows && s + 1 < r1 {
            load_row(job, s + 3, drift, half, &mut band.state[s % 3]);
        }
    }
    result
}

/// Where [`old_row`] reads a band's old rows: the ring, the row-blocked arrays when read in
/// place, and the width of a row's components.
type OldRows<'a> = (&'a [[Vec<f32>; 6]; 3], Option<SharedRows<'a>>, usize);

/// Row `s` (its springs, and with `out` its new state) on [`simd::fused_row`], from the old
/// state's rows `s`, `s + 1`, `s + 2` as [`old_row`] reads them from `(ring, all, width)`
/// (the last row in place of rows past it: only read for springs the row does not have,
/// which are not used).
#[inline(always)]
fn fused_row(
    proof: simd::Fused,
    job: &Job<'_>,
    s: usize,
    (ring, all, width): OldRows<'_>,
    force: &mut simd::ForceRing,
    out: Option<&mut [&mut [f32]; 6]>,
) -> bool {
    let (rows, cols) = (job.rows, job.cols);
    let old = |r: usize| old_row(ring, all, cols, width, r.min(rows - 1));
    let state = [old(s), old(s + 1), old(s + 2)];
    let lo = s * cols;
    let full = cols.next_multiple_of(LANES);
    let mut rest: [&[f32]; 6] = [&[]; 6];
    for (class, &(dr, _, _, _)) in CLASSES.iter().enumerate() {
        if job.params[class].is_some() && s + dr < rows {
            rest[class] = job.rest[class].row(s, full);
        }
    }
    let row = simd::FusedRow {
        s,
        rows,
        cols,
        h: job.h,
        gravity: job.gravity.to_array(),
        damping: job.damping,
        params: job.params,
        rest,
        mass: &job.mass[lo..][..cols],
        inv_mass: &job.inv_mass[lo..][..cols],
        state,
    };
    match job.scheme {
        Scheme::Forward => simd::fused_row::<FORWARD>(proof, &row, force, out),
        Scheme::Symplectic => simd::fused_row::<SYMPLECTIC>(proof, &row, force, out),
        Scheme::Verlet => simd::fused_row::<VERLET>(proof, &row, force, out),
    }
}

/// Distance to the contact surface below which a particle always goes through the exact
/// contact passes, m (far above the rounding of the distances compared).
const CULL_MARGIN: f32 = 1e-4;

/// Contacts (and, when planned, continuous collision) of one new row, as the reference runs
/// them on the whole cloth after integrating: each particle on its own, so they run on the
/// runs of particles that [`near_mask`] does not rule out.
#[allow(clippy::too_many_arguments)]
fn contacts_row(
    job: &Job<'_>,
    s: usize,
    px: &mut [Vec3],
    pv: &mut [Vec3],
    start: &[Vec3],
    near: &mut [bool],
    premasked: bool,
    result: &mut BandResult,
) {
    if job.colliders.is_empty() || (job.soa_contacts && !job.ccd) {
        return;
    }
    if premasked {
        // `near` already holds the continuous-collision candidates ([`ccd_mask_soa`]).
        let range = s * job.cols..(s + 1) * job.cols;
        let (w, a) = (&job.inv_mass[range], start);
        for run in runs(&near[..px.len()]) {
            let (i, j) = (run.start, run.end);
            result.ccd += ccd::resolve_in(
                job.colliders,
                &a[i..j],
                &mut px[i..j],
                &mut pv[i..j],
                &w[i..j],
                job.h,
            );
        }
        return;
    }
    let range = s * job.cols..(s + 1) * job.cols;
    let w = &job.inv_mass[range];
    let pos_weight = match job.scheme {
        Scheme::Forward => 0.0,
        Scheme::Symplectic => job.h,
        Scheme::Verlet => 0.5 * job.h,
    };
    near_mask(job, start, px, near);
    for run in runs(&near[..px.len()]) {
        let (i, j) = (run.start, run.end);
        let (x, v, w, a) = (&mut px[i..j], &mut pv[i..j], &w[i..j], &start[i..j]);
        if !job.soa_contacts {
            result.contacts += resolve_contacts_in(job.colliders, x, v, w, pos_weight);
        }
        if job.ccd {
            // Continuous collision only on the particles whose path is long enough for it to
            // change anything (see `Job::ccd_min_path`); each particle is on its own.
            let mut k = 0;
            while k < x.len() {
                if (x[k] - a[k]).length() < job.ccd_min_path {
                    k += 1;
                    continue;
                }
                let mut l = k + 1;
                while l < x.len() && (x[l] - a[l]).length() >= job.ccd_min_path {
                    l += 1;
                }
                result.ccd += ccd::resolve_in(
                    job.colliders,
                    &a[k..l],
                    &mut x[k..l],
                    &mut v[k..l],
                    &w[k..l],
                    job.h,
                );
                k = l;
            }
            // (No projection pass: the solver runs it only after strain limiting or
            // self-collision, and the plan fuses continuous collision only without them.)
        }
    }
}

/// The maximal runs `i..j` of `true` entries of `mask`, in order (the candidates of a chunk,
/// resolved a run at a time).
pub(super) fn runs(mask: &[bool]) -> impl Iterator<Item = std::ops::Range<usize>> + '_ {
    let mut i = 0;
    std::iter::from_fn(move || {
        while i < mask.len() && !mask[i] {
            i += 1;
        }
        if i == mask.len() {
            return None;
        }
        let start = i;
        while i < mask.len() && mask[i] {
            i += 1;
        }
        Some(start..i)
    })
}

/// The discrete contact pass ([`crate::collide::resolve_contacts`]) on row `s`'s new state in
/// structure of arrays (x, y, z, vx, vy, vz), for spheres and planes that do not turn: the
/// same operations in the same order as the reference's per-particle code (`Shape::distance`,
/// `respond`, `coulomb`), computed in every lane and selected, so the bits are the
/// reference's. Returns the number of contacts.
#[inline(always)]
fn contacts_soa(job: &Job<'_>, s: usize, out: &mut [&mut [f32]; 6]) -> u32 {
    use crate::collide::Shape;
    let cols = job.cols;
    let w = &job.inv_mass[s * cols..][..cols];
    let pw = match job.scheme {
        Scheme::Forward => 0.0,
        Scheme::Symplectic => job.h,
        Scheme::Verlet => 0.5 * job.h,
    };
    let [x, y, z, vx, vy, vz] = out;
    let (x, y, z) = (&mut x[..cols], &mut y[..cols], &mut z[..cols]);
    let (vx, vy, vz) = (&mut vx[..cols], &mut vy[..cols], &mut vz[..cols]);
    let mut contacts = 0;
    for col in job.colliders {
        let (mu_s, mu_k, t) = (
            col.friction.static_coefficient,
            col.friction.kinetic_coefficient,
            col.thickness,
        );
        let vc = col.velocity;
        let (sphere, a, r, norm) = match col.shape {
            Shape::Sphere { center, radius } => (true, center, radius, Vec3::Y),
            Shape::Plane { point, normal } => (false, point, 0.0, normal),
            _ => unreachable!("soa_contacts holds only spheres and planes"),
        };
        // One particle (a macro, so that it inlines into the vector loop): the distance and
        // normal of `$shape`, then the contact response, every branch computed and selected.
        macro_rules! one {
            ($sphere:expr, $a:expr, $r:expr, $p:expr, $v:expr, $w:expr) => {{
                let (sphere, a, r): (bool, Vec3, f32) = ($sphere, $a, $r);
                let ([px, py, pz], [qx, qy, qz], w): ([f32; 3], [f32; 3], f32) = ($p, $v, $w);
                let (dist, [nx, ny, nz]) = lane_distance(sphere, a, r, norm, [px, py, pz]);
                let phi = dist - t;
                let hit = w != 0.0 && !(phi >= 0.0);
                // x ← x − φ·n
                let (hx, hy, hz) = (px - phi * nx, py - phi * ny, pz - phi * nz);
                // respond: relative velocity, its normal part, Coulomb friction.
                let (rx, ry, rz) = (qx - vc.x, qy - vc.y, qz - vc.z);
                let vn = rx * nx + ry * ny + rz * nz;
                let approach = !(vn >= 0.0);
                let dvn = -vn;
                let (tx, ty, tz) = (rx - vn * nx, ry - vn * ny, rz - vn * nz);
                let vt_len = (tx * tx + ty * ty + tz * tz).sqrt();
                let stick = vt_len <= mu_s * dvn;
                let scale = (1.0 - mu_k * dvn / vt_len).max(0.0);
                let (ux, uy, uz) = if stick {
                    (0.0, 0.0, 0.0)
                } else {
                    (tx * scale, ty * scale, tz * scale)
                };
                let (ex, ey, ez) = if approach {
                    (
                        hx + pw * (ux - tx),
                        hy + pw * (uy - ty),
                        hz + pw * (uz - tz),
                    )
                } else {
                    (hx, hy, hz)
                };
                let (fx, fy, fz) = if approach {
                    (vc.x + ux, vc.y + uy, vc.z + uz)
                } else {
                    (qx, qy, qz)
                };
                if hit {
                    ([ex, ey, ez], [fx, fy, fz], 1_u32)
                } else {
                    ([px, py, pz], [qx, qy, qz], 0_u32)
                }
            }};
        }
        let mut c0 = 0;
        while c0 + LANES <= cols {
            let (lx, ly, lz) = (lanes(x, c0), lanes(y, c0), lanes(z, c0));
            // A chunk whose particles are all outside the contact surface (φ ≥ 0, computed
            // as `Shape::distance` does) is left as it is.
            let mut clear = true;
            for j in 0..LANES {
                let dist = if sphere {
                    let (dx, dy, dz) = (lx[j] - a.x, ly[j] - a.y, lz[j] - a.z);
                    (dx * dx + dy * dy + dz * dz).sqrt() - r
                } else {
                    (lx[j] - a.x) * norm.x + (ly[j] - a.y) * norm.y + (lz[j] - a.z) * norm.z
                };
                clear &= dist - t >= 0.0;
            }
            if clear {
                c0 += LANES;
                continue;
            }
            let (lvx, lvy, lvz) = (lanes(vx, c0), lanes(vy, c0), lanes(vz, c0));
            let lw = lanes(w, c0);
            let mut o = [[0.0_f32; LANES]; 6];
            let mut hits = [0_u32; LANES];
            for j in 0..LANES {
                let (p, v, h) = one!(
                    sphere,
                    a,
                    r,
                    [lx[j], ly[j], lz[j]],
                    [lvx[j], lvy[j], lvz[j]],
                    lw[j]
                );
                [o[0][j], o[1][j], o[2][j]] = p;
                [o[3][j], o[4][j], o[5][j]] = v;
                hits[j] = h;
            }
            for (dst, src) in [&mut *x, &mut *y, &mut *z, &mut *vx, &mut *vy, &mut *vz]
                .into_iter()
                .zip(&o)
            {
                dst[c0..c0 + LANES].copy_from_slice(src);
            }
            contacts += hits.iter().sum::<u32>();
            c0 += LANES;
        }
        for c in c0..cols {
            let (p, v, h) = one!(
                sphere,
                a,
                r,
                [x[c], y[c], z[c]],
                [vx[c], vy[c], vz[c]],
                w[c]
            );
            [x[c], y[c], z[c]] = p;
            [vx[c], vy[c], vz[c]] = v;
            contacts += h;
        }
    }
    contacts
}

/// Marks the particles of a row that the contact passes could touch. A particle is ruled out
/// only against still spheres and planes (exact distances), when its new position is more
/// than the thickness and half its path from every collider, and (with continuous
/// collision) its old position more than half its path, each with [`CULL_MARGIN`]: then the
/// discrete pass finds φ > 0, the continuous pass's own cull `φ(a) + φ(b) ≥ |b − a|` holds
/// and the projection finds nothing, so skipping it changes no bit. Any other collider
/// keeps every particle.
#[inline(always)]
fn near_mask(job: &Job<'_>, start: &[Vec3], px: &[Vec3], near: &mut [bool]) {
    let n = px.len();
    let (start, near) = (&start[..n], &mut near[..n]);
    near.fill(false);
    for col in job.colliders {
        let still = col.velocity == Vec3::ZERO && col.angular_velocity == Vec3::ZERO;
        let t = col.thickness;
        match col.shape {
            crate::collide::Shape::Sphere { center, radius } if still => {
                mark(start, px, near, t, job.ccd, |p| {
                    (p - center).length() - radius
                });
            }
            crate::collide::Shape::Plane { point, normal } if still => {
                mark(start, px, near, t, job.ccd, |p| (p - point).dot(normal));
            }
            _ => near.fill(true),
        }
    }
}

/// The continuous-collision candidates of a row, on the arrays (old positions `a`, new
/// positions after the discrete contacts `b`): `near` is cleared for exactly the particles
/// that [`ccd::resolve_in`] would leave alone at every collider without marching, by its own
/// tests with its own operations (pinned; path under ½τ; `φ(b) ≥ |b − a|`; `φ(a) < 0` or
/// `φ(a) + φ(b) ≥ |b − a|`; touching at the start with `(b − a)·n ≥ −τ`). The colliders are
/// spheres and planes that do not turn ([`Job::soa_contacts`]).
#[inline(always)]
fn ccd_mask_soa(
    job: &Job<'_>,
    s: usize,
    a: [&[f32]; 6],
    b: &[&mut [f32]; 6],
    near: &mut [bool],
) -> bool {
    let cols = job.cols;
    ccd_mask::<false>(
        job.colliders,
        job.h,
        &job.inv_mass[s * cols..][..cols],
        [&a[0][..cols], &a[1][..cols], &a[2][..cols]],
        [&b[0][..cols], &b[1][..cols], &b[2][..cols]],
        &mut near[..cols],
    )
}

/// [`ccd_mask_soa`] on any run of particles: `near[k]` is cleared exactly for the particles
/// `k` (inverse mass `w[k]`, start `a`, end `b`, by component) that [`ccd::resolve_in`] with
/// substep `h` would leave alone at every collider without marching. Every collider must be
/// a sphere or a plane that does not turn. Returns whether any `near[k]` is set (so callers
/// need not scan the mask for a run with none).
///
/// With `SCREEN`, a chunk of particles that all moved less than the tolerance (or are pinned)
/// skips the other tests' square roots, with the same mask: for a cloth that settles (XPBD's
/// finishing pass, [`ccd_mask_screened`]). The explicit band runs without it: its peer
/// scene's chunks never pass the screen, which cost it 1–2 %.
#[inline(always)]
pub(crate) fn ccd_mask<const SCREEN: bool>(
    colliders: &[Collider],
    h: f32,
    w: &[f32],
    [ax, ay, az]: [&[f32]; 3],
    [bx, by, bz]: [&[f32]; 3],
    near: &mut [bool],
) -> bool {
    use crate::collide::Shape;
    let cols = near.len();
    let w = &w[..cols];
    let (ax, ay, az) = (&ax[..cols], &ay[..cols], &az[..cols]);
    let (bx, by, bz) = (&bx[..cols], &by[..cols], &bz[..cols]);
    near.fill(false);
    let mut any = false;
    for col in colliders {
        let (sphere, p, r, n) = match col.shape {
            Shape::Sphere { center, radius } => (true, center, radius, Vec3::Y),
            Shape::Plane { point, normal } => (false, point, 0.0, normal),
            _ => unreachable!("soa_contacts holds only spheres and planes"),
        };
        let tau = ccd::tolerance(col);
        let radius = ccd::curvature_radius(&col.shape).expect("a sphere or a plane");
        // `resolve_in`'s start point in the collider's end pose (no turn): a + (p₁ − p₀).
        let pivot_end = col.shape.pivot();
        let shift = pivot_end - (pivot_end - col.velocity * h);
        // The start point, the path and its squared length.
        let path = |[ax, ay, az]: [f32; 3], [bx, by, bz]: [f32; 3]| {
            let (sx, sy, sz) = (ax + shift.x, ay + shift.y, az + shift.z);
            let (qx, qy, qz) = (bx - sx, by - sy, bz - sz);
            ([sx, sy, sz], [qx, qy, qz], qx * qx + qy * qy + qz * qz)
        };
        // Pinned, or a path under the tolerance: the two cheap tests without a square root.
        let short = 0.2 * tau * tau;
        let still = |w: f32, l2: f32| (w == 0.0) | (l2 < short);
        // `resolve_in`'s cheap tests of one particle (pinned, path under ½τ, `φ(b) ≥ |b − a|`,
        // ending too shallow to be corrected: [`ccd::shallow`]), with `|` (no short-circuit,
        // no branch), and what the others need: the start point, the path, its length and
        // `φ(b)`.
        let cheap = |w: f32, a: [f32; 3], b: [f32; 3]| {
            let (s, q, l2) = path(a, b);
            let [bx, by, bz] = b;
            let len = l2.sqrt();
            // The signed distance alone (the unused normal's divisions are dead code).
            let db = lane_distance(sphere, p, r, n, [bx, by, bz]).0;
            let skip = still(w, l2)
                | len.is_nan()
                | (len < 0.5 * tau)
                | (db >= len)
                | ccd::shallow(radius, tau, len, db);
            (skip, s, q, len, db, l2)
        };
        // The other tests: `φ(a) < 0`, `φ(a) + φ(b) ≥ |b − a|`, touching at the start and
        // leaving (`(b − a)·n ≥ −τ`).
        let rest = |[sx, sy, sz]: [f32; 3], [qx, qy, qz]: [f32; 3], len: f32, db: f32| {
            let (da, [nx, ny, nz]) = lane_distance(sphere, p, r, n, [sx, sy, sz]);
            (da < 0.0)
                | (da + db >= len)
                | ((da <= ccd::HIT_EPSILON) & (qx * nx + qy * ny + qz * nz >= -tau))
        };
        // Whole chunks of LANES particles read in place, every test in every lane (the lane
        // loops vectorise); the tests that need the start point's distance and normal only
        // for chunks where a cheap test fails. Then the last particles one by one.
        let (nc, nt) = near.as_chunks_mut::<LANES>();
        let (wc, wt) = w.as_chunks::<LANES>();
        let [(axc, axt), (ayc, ayt), (azc, azt)] = [ax, ay, az].map(|a| a.as_chunks::<LANES>());
        let [(bxc, bxt), (byc, byt), (bzc, bzt)] = [bx, by, bz].map(|b| b.as_chunks::<LANES>());
        // With SCREEN, a chunk whose every particle is pinned or moved less than the tolerance
        // (two of the cheap tests) is left alone (`near` stays clear: the same result) after a
        // screen without the other tests' square roots: a settled cloth's every chunk. The
        // screen runs on the first chunk and after chunks that would have passed it: a run of
        // falling particles pays for it once.
        let mut screen = SCREEN;
        for (i, near) in nc.iter_mut().enumerate() {
            let (w, ax, ay, az) = (&wc[i], &axc[i], &ayc[i], &azc[i]);
            let (bx, by, bz) = (&bxc[i], &byc[i], &bzc[i]);
            if screen {
                let mut moved = false;
                for l in 0..LANES {
                    let (_, _, l2) = path([ax[l], ay[l], az[l]], [bx[l], by[l], bz[l]]);
                    moved |= !still(w[l], l2);
                }
                if !moved {
                    continue;
                }
            }
            // A sphere's chunk whose every particle ends farther from the centre than the
            // radius plus the chunk's longest path (with a margin far above rounding) has
            // `φ(b) ≥ |b − s|` in every lane, a cheap test that skips it: left alone after
            // one square root per chunk instead of two per particle.
            if sphere && far_chunk(p, r, [ax, ay, az], [bx, by, bz], shift) {
                continue;
            }
            let mut skip = [false; LANES];
            let ([mut sx, mut sy, mut sz], [mut qx, mut qy, mut qz]) =
                ([[0.0_f32; LANES]; 3], [[0.0_f32; LANES]; 3]);
            let (mut len, mut db) = ([0.0_f32; LANES], [0.0_f32; LANES]);
            // Whether any lane is left, reduced in the loop (a scan of `skip` after it read
            // the bytes just stored: a stalled load, 4 % of the peer scene's time).
            let mut live = false;
            let mut moved = false;
            for l in 0..LANES {
                let (k, s, q, length, d, l2) =
                    cheap(w[l], [ax[l], ay[l], az[l]], [bx[l], by[l], bz[l]]);
                (skip[l], len[l], db[l]) = (k, length, d);
                live |= !k;
                moved |= !still(w[l], l2);
                [sx[l], sy[l], sz[l]] = s;
                [qx[l], qy[l], qz[l]] = q;
            }
            screen = SCREEN && !moved;
            if !live {
                continue;
            }
            for l in 0..LANES {
                let other = rest([sx[l], sy[l], sz[l]], [qx[l], qy[l], qz[l]], len[l], db[l]);
                let candidate = !(skip[l] | other);
                near[l] |= candidate;
                any |= candidate;
            }
        }
        for (k, near) in nt.iter_mut().enumerate() {
            let (skip, s, q, len, db, _) =
                cheap(wt[k], [axt[k], ayt[k], azt[k]], [bxt[k], byt[k], bzt[k]]);
            if !skip && !rest(s, q, len, db) {
                *near = true;
                any = true;
            }
        }
    }
    any
}

/// Relative margin of [`far_chunk`]'s test.
const FAR_MARGIN: f32 = 1.001;

/// Whether every particle of a chunk (start `a` shifted by the sphere's motion `shift`, end
/// `b`) ends at least `FAR_MARGIN · (r + L)` from the centre `p` of a sphere of radius `r`,
/// `L` the chunk's longest path. Then `|b − p| − r ≥ L + 0.001·(r + L)` exactly, so the
/// rounded `φ(b) ≥ |b − s|` of [`ccd_mask`]'s cheap test holds in every lane too (its
/// rounding is ~1e-7 of `|b − p|`; a particle so far that this exceeds the margin has
/// `φ(b)` hundreds of times its path). A lane ending at NaN does not count (its cheap test
/// skips it anyway); a NaN path fails the test.
#[inline(always)]
fn far_chunk(
    p: Vec3,
    r: f32,
    [ax, ay, az]: [&[f32; LANES]; 3],
    [bx, by, bz]: [&[f32; LANES]; 3],
    shift: Vec3,
) -> bool {
    // The extremes of squares (never negative, never −0.0) by their bits, whose integer order
    // is theirs: reductions that vectorise (`f32::max` does not). A NaN square is the
    // largest: a NaN path fails the test, a NaN distance drops out of the minimum.
    let (mut path2, mut dist2) = (0_u32, u32::MAX);
    for l in 0..LANES {
        let (qx, qy, qz) = (
            bx[l] - (ax[l] + shift.x),
            by[l] - (ay[l] + shift.y),
            bz[l] - (az[l] + shift.z),
        );
        let (dx, dy, dz) = (bx[l] - p.x, by[l] - p.y, bz[l] - p.z);
        path2 = path2.max((qx * qx + qy * qy + qz * qz).to_bits());
        dist2 = dist2.min((dx * dx + dy * dy + dz * dz).to_bits());
    }
    let (path2, dist2) = (f32::from_bits(path2), f32::from_bits(dist2));
    let reach = FAR_MARGIN * (r + path2.sqrt());
    dist2 >= reach * reach
}

/// [`ccd_mask`] with its screen, as a plain function for `simd`'s dispatcher (which infers no
/// `bool` parameter).
#[inline(always)]
pub(crate) fn ccd_mask_screened(
    colliders: &[Collider],
    h: f32,
    w: &[f32],
    a: [&[f32]; 3],
    b: [&[f32]; 3],
    near: &mut [bool],
) -> bool {
    ccd_mask::<true>(colliders, h, w, a, b, near)
}

/// `Shape::distance` of a sphere (`sphere`: centre `p`, radius `r`) or a plane (point `p`,
/// unit normal `n`) at `x`, with the shape's own operations in the same order (so the same
/// bits), written for lanes of a loop: the signed distance and the outward normal (a sphere's
/// is `Y` at its centre). Shared by the passes on the arrays of both grid paths.
#[inline(always)]
pub(crate) fn lane_distance(
    sphere: bool,
    p: Vec3,
    r: f32,
    n: Vec3,
    [x, y, z]: [f32; 3],
) -> (f32, [f32; 3]) {
    if sphere {
        let (dx, dy, dz) = (x - p.x, y - p.y, z - p.z);
        let len = (dx * dx + dy * dy + dz * dz).sqrt();
        let pos = len > 0.0;
        (
            len - r,
            [
                if pos { dx / len } else { 0.0 },
                if pos { dy / len } else { 1.0 },
                if pos { dz / len } else { 0.0 },
            ],
        )
    } else {
        (
            (x - p.x) * n.x + (y - p.y) * n.y + (z - p.z) * n.z,
            n.to_array(),
        )
    }
}

/// [`near_mask`] for one collider with distance function `dist`.
#[inline(always)]
fn mark(
    start: &[Vec3],
    px: &[Vec3],
    near: &mut [bool],
    t: f32,
    ccd: bool,
    dist: impl Fn(Vec3) -> f32,
) {
    for ((&a, &b), near) in start.iter().zip(px).zip(near) {
        let half_path = 0.5 * (b - a).length();
        let db = dist(b);
        let far = db - t > CULL_MARGIN
            && (!ccd || (db - half_path > CULL_MARGIN && dist(a) - half_path > CULL_MARGIN));
        *near |= !far;
    }
}

/// Row `r` of the old state (x, y, z, vx, vy, vz), each component `width` floats
/// (`cols` rounded up to whole chunks, plus the two a spring class's column offset reads past
/// them): in place in the row-blocked arrays `all` when given, else the ring's copy. In place,
/// the floats past a component's `cols` are the next component's (and, past the last row,
/// [`ROW_SLACK`]): the spring lanes past a row's springs compute garbage there, which
/// [`springs`] neither reports nor keeps. (Not inlined: inlined into the band, its slices
/// made the band's contact passes about 60 % slower on the peer scene.)
#[inline(never)]
#[allow(unsafe_code)]
fn old_row<'b>(
    ring: &'b [[Vec<f32>; 6]; 3],
    all: Option<SharedRows<'b>>,
    cols: usize,
    width: usize,
    r: usize,
) -> [&'b [f32]; 6] {
    match all {
        Some(all) => {
            let at = 6 * cols * r;
            // SAFETY: the bands read a row only before it is written in place and read no
            // row another band writes during the substep ([`band`]).
            let get = |k: usize| unsafe { all.get(at + k * cols, width) };
            [get(0), get(1), get(2), get(3), get(4), get(5)]
        }
        None => {
            let [x, y, z, vx, vy, vz] = &ring[r % 3];
            [x, y, z, vx, vy, vz]
        }
    }
}

/// Fewest particles for which the resident state is updated in place ([`Dest::InPlace`])
/// rather than into a second array. In place, a row's new state goes to the band's row
/// buffers and is copied over the old row once nothing reads it any more: on a large cloth
/// that halves the arrays a substep streams and writes into lines already in cache (peer-ball
/// 512², 1 thread: +6 %, 8 interleaved rounds), on a smaller one the copy costs more than it
/// saves (256²: −1 % on 1 thread, −4 % on 2). Between the two sizes measured, 2¹⁷ particles
/// (a 362² cloth).
const IN_PLACE_MIN: usize = 1 << 17;

/// Floats past the last row of the row-blocked state arrays, so that [`old_row`]'s components
/// stay inside them.
const ROW_SLACK: usize = LANES + 2;

/// Copies row `s` of the old state into `dst` (x, y, z, vx, vy, vz), with Verlet's first
/// drift x + ½h·v applied.
#[inline(always)]
fn load_row(job: &Job<'_>, s: usize, drift: bool, half: f32, dst: &mut [Vec<f32>; 6]) {
    let cols = job.cols;
    let [x, y, z, vx, vy, vz] = dst;
    let (x, y, z) = (&mut x[..cols], &mut y[..cols], &mut z[..cols]);
    let (vx, vy, vz) = (&mut vx[..cols], &mut vy[..cols], &mut vz[..cols]);
    let (xs, vs) = match job.src {
        Source::Particles(position, velocity) => {
            (&position[s * cols..][..cols], &velocity[s * cols..][..cols])
        }
        Source::Rows(all) => {
            // SAFETY: as in [`old_row`] (row `s` is loaded before it is written).
            #[allow(unsafe_code)]
            let row = unsafe { all.get(6 * cols * s, 6 * cols) };
            let [px, py, pz, pvx, pvy, pvz] = row_parts(row, cols);
            // `p + ½h·v` per component, as glam computes it for `Vec3`.
            for c in 0..cols {
                let (p, v) = ([px[c], py[c], pz[c]], [pvx[c], pvy[c], pvz[c]]);
                let p = if drift {
                    [p[0] + half * v[0], p[1] + half * v[1], p[2] + half * v[2]]
                } else {
                    p
                };
                [x[c], y[c], z[c]] = p;
                [vx[c], vy[c], vz[c]] = v;
            }
            return;
        }
    };
    for c in 0..cols {
        let (p, v) = (xs[c], vs[c]);
        let p = if drift { p + half * v } else { p };
        x[c] = p.x;
        y[c] = p.y;
        z[c] = p.z;
        vx[c] = v.x;
        vy[c] = v.y;
        vz[c] = v.z;
    }
}

/// Row `s`'s old positions as `Vec3` (for the per-particle contact passes).
#[inline(always)]
fn old_positions(job: &Job<'_>, s: usize, dst: &mut [Vec3]) {
    let cols = job.cols;
    match job.src {
        Source::Particles(position, _) => {
            dst[..cols].copy_from_slice(&position[s * cols..][..cols]);
        }
        Source::Rows(all) => {
            // SAFETY: as in [`old_row`] (row `s`'s contacts run before it is written).
            #[allow(unsafe_code)]
            let row = unsafe { all.get(6 * cols * s, 3 * cols) };
            let (px, rest) = row.split_at(cols);
            let (py, pz) = rest.split_at(cols);
            for c in 0..cols {
                dst[c] = Vec3::new(px[c], py[c], pz[c]);
            }
        }
    }
}

/// Row `i` of a band's new state (x, y, z, vx, vy, vz) into its positions and velocities.
#[inline(always)]
fn write_particles(out: &[&mut [f32]; 6], i: usize, cols: usize, px: &mut [Vec3], pv: &mut [Vec3]) {
    let (px, pv) = (&mut px[i * cols..][..cols], &mut pv[i * cols..][..cols]);
    let [x, y, z, vx, vy, vz] = out;
    for c in 0..cols {
        px[c] = Vec3::new(x[c], y[c], z[c]);
        pv[c] = Vec3::new(vx[c], vy[c], vz[c]);
    }
}

/// A row of the row-blocked arrays (`6 · cols` floats) as its six components, read-only.
#[inline(always)]
fn row_parts(row: &[f32], cols: usize) -> [&[f32]; 6] {
    let (x, rest) = row.split_at(cols);
    let (y, rest) = rest.split_at(cols);
    let (z, rest) = rest.split_at(cols);
    let (vx, rest) = rest.split_at(cols);
    let (vy, vz) = rest.split_at(cols);
    [x, y, z, vx, vy, &vz[..cols]]
}

/// A row of the row-blocked arrays (`6 · cols` floats) as its six components.
#[inline(always)]
fn split_row(row: &mut [f32], cols: usize) -> [&mut [f32]; 6] {
    let (x, rest) = row.split_at_mut(cols);
    let (y, rest) = rest.split_at_mut(cols);
    let (z, rest) = rest.split_at_mut(cols);
    let (vx, rest) = rest.split_at_mut(cols);
    let (vy, vz) = rest.split_at_mut(cols);
    [x, y, z, vx, vy, &mut vz[..cols]]
}

/// Hooke spring plus dashpot for `m` springs from ends `a` to ends `b` (x, y, z, vx, vy, vz
/// each), the reference's operations in its order. Writes the force on the first end
/// (`+f` there, `−f` on the second); returns whether one of the first `count` springs (the
/// real ones; the lanes past them compute whatever their ends hold) had zero length.
#[inline(always)]
fn springs(
    k: f32,
    c: f32,
    count: usize,
    a: [&[f32]; 6],
    b: [&[f32]; 6],
    rest: &[f32],
    out: [&mut [f32]; 3],
) -> bool {
    let m = rest.len();
    let [ax, ay, az, avx, avy, avz] = heads(a, m);
    let [bx, by, bz, bvx, bvy, bvz] = heads(b, m);
    let [fx, fy, fz] = out;
    let (fx, fy, fz) = (&mut fx[..m], &mut fy[..m], &mut fz[..m]);
    debug_assert_eq!(m % LANES, 0);
    let mut degenerate = false;
    // Chunks of LANES springs: fixed-length loops on local arrays, which the compiler turns
    // into whole vectors (two zmm with AVX-512) with no run-time alias checks.
    let mut i = 0;
    while i < m {
        // Lanes past the row's springs (`live` of this chunk are real) compute garbage: only
        // the real ones may report a zero length.
        let live = count.saturating_sub(i);
        let (mut ox, mut oy, mut oz) = ([0.0; LANES], [0.0; LANES], [0.0; LANES]);
        let [ax, ay, az, avx, avy, avz] = chunks([ax, ay, az, avx, avy, avz], i);
        let [bx, by, bz, bvx, bvy, bvz] = chunks([bx, by, bz, bvx, bvy, bvz], i);
        let rest = lanes(rest, i);
        let mut bad = false;
        for j in 0..LANES {
            let lx = bx[j] - ax[j];
            let ly = by[j] - ay[j];
            let lz = bz[j] - az[j];
            // The reference's operations (`forces::spring_force`).
            let len2 = lx * lx + ly * ly + lz * lz;
            let (wx, wy, wz) = (bvx[j] - avx[j], bvy[j] - avy[j], bvz[j] - avz[j]);
            let along = wx * lx + wy * ly + wz * lz;
            let per_length = spring_per_length(len2, along, rest[j], k, c);
            // A zero-length spring's lanes hold NaN or infinities: the substep is then
            // discarded and run on the reference path (`bad`), so no select is needed here.
            bad |= (j < live) & (len2 < ZERO_LENGTH_SQUARED);
            ox[j] = per_length * lx;
            oy[j] = per_length * ly;
            oz[j] = per_length * lz;
        }
        degenerate |= bad;
        fx[i..i + LANES].copy_from_slice(&ox);
        fy[i..i + LANES].copy_from_slice(&oy);
        fz[i..i + LANES].copy_from_slice(&oz);
        i += LANES;
    }
    degenerate
}

/// The first `m` elements of every slice. (Element by element: `array::map` is a call that
/// does not inline into the `#[target_feature]` kernels.)
#[inline(always)]
fn heads<const K: usize>(s: [&[f32]; K], m: usize) -> [&[f32]; K] {
    let mut out = s;
    let mut k = 0;
    while k < K {
        out[k] = &s[k][..m];
        k += 1;
    }
    out
}

/// [`lanes`] of every slice.
#[inline(always)]
fn chunks<const K: usize>(s: [&[f32]; K], i: usize) -> [&[f32; LANES]; K] {
    let mut out = [&[0.0; LANES]; K];
    let mut k = 0;
    while k < K {
        out[k] = lanes(s[k], i);
        k += 1;
    }
    out
}

/// `LANES` elements of `s` from `i`, as an array.
#[inline(always)]
pub(crate) fn lanes(s: &[f32], i: usize) -> &[f32; LANES] {
    lanes_of(s, i)
}

/// `LANES` elements of `s` from `i`, as a mutable array.
#[inline(always)]
pub(crate) fn lanes_mut(s: &mut [f32], i: usize) -> &mut [f32; LANES] {
    lanes_of_mut(s, i)
}

/// `N` elements of `s` from `i`, as an array.
#[inline(always)]
pub(crate) fn lanes_of<const N: usize>(s: &[f32], i: usize) -> &[f32; N] {
    s[i..i + N].try_into().expect("N elements")
}

/// `N` elements of `s` from `i`, as a mutable array.
#[inline(always)]
pub(crate) fn lanes_of_mut<const N: usize>(s: &mut [f32], i: usize) -> &mut [f32; N] {
    (&mut s[i..i + N]).try_into().expect("N elements")
}

/// Sums the forces on row `s` in the reference's order and integrates it into `out` (x, y, z,
/// vx, vy, vz of the new row), reading the ring's state, force and air rows.
#[inline(always)]
fn particle_row(
    job: &Job<'_>,
    s: usize,
    state: [&[f32]; 6],
    force: &[[[Vec<f32>; 3]; 3]; 6],
    air: &[[[Vec<f32>; 3]; 2]; 2],
    out: &mut [&mut [f32]; 6],
) {
    let (rows, cols) = (job.rows, job.cols);
    let slot = |r: usize| r % 3;
    let on = |class: usize| job.params[class].is_some();
    let up1 = s.checked_sub(1);
    let up2 = s.checked_sub(2);
    let lo = s * cols;
    let mass = &job.mass[lo..][..cols];
    let w = &job.inv_mass[lo..][..cols];
    let g = job.gravity.to_array();
    let (out_x, out_v) = out.split_at_mut(3);
    for comp in 0..3 {
        let pick = |class: usize, r: Option<usize>, added: bool| -> &[f32] {
            let (dr, _, _, _) = CLASSES[class];
            match r {
                Some(r) if on(class) && r + dr < rows => &force[class][slot(r)][comp],
                _ if added => job.minus_zero,
                _ => job.plus_zero,
            }
        };
        // Terms in the reference's order; offsets index the padded rows at column c.
        let t = [
            &pick(WARP, up1, false)[PAD..],          // − warp (s−1, c)
            &pick(WARP, Some(s), true)[PAD..],       // + warp (s, c)
            &pick(WEFT, Some(s), false)[PAD - 1..],  // − weft (s, c−1)
            &pick(WEFT, Some(s), true)[PAD..],       // + weft (s, c)
            &pick(DIAG, up1, false)[PAD - 1..],      // − diagonal (s−1, c−1)
            &pick(ANTI, up1, false)[PAD..],          // − anti-diagonal (s−1, c)
            &pick(ANTI, Some(s), true)[PAD - 1..],   // + anti-diagonal (s, c−1)
            &pick(DIAG, Some(s), true)[PAD..],       // + diagonal (s, c)
            &pick(BENDV, up2, false)[PAD..],         // − vertical bend (s−2, c)
            &pick(BENDH, Some(s), false)[PAD - 2..], // − horizontal bend (s, c−2)
            &pick(BENDV, Some(s), true)[PAD..],      // + vertical bend (s, c)
            &pick(BENDH, Some(s), true)[PAD..],      // + horizontal bend (s, c)
        ];
        // The air's terms in the reference's triangle order: cell (s−1, c−1)'s second
        // triangle, cell (s−1, c)'s two, cell (s, c−1)'s two, cell (s, c)'s first (a cell row
        // holds cell c at 1 + c, −0.0 at both ends; absent cell rows are −0.0).
        let air = job.air.is_some().then(|| {
            let cells = |r: Option<usize>, k: usize| -> &[f32] {
                match r {
                    Some(r) if r + 1 < rows => &air[r % 2][k][comp],
                    _ => job.minus_zero,
                }
            };
            [
                cells(up1, 1),
                &cells(up1, 0)[1..],
                &cells(up1, 1)[1..],
                cells(Some(s), 0),
                cells(Some(s), 1),
                &cells(Some(s), 0)[1..],
            ]
        });
        integrate_component(
            job.scheme,
            job.h,
            g[comp],
            job.damping,
            mass,
            w,
            &state[comp][..cols],
            &state[3 + comp][..cols],
            t,
            air,
            &mut out_x[comp][..cols],
            &mut out_v[comp][..cols],
        );
    }
}

/// One component of one row: force m·g − d·v, the 12 spring terms in order, then the
/// scheme's update, as the reference computes it.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn integrate_component(
    scheme: Scheme,
    h: f32,
    g: f32,
    damping: f32,
    mass: &[f32],
    w: &[f32],
    x: &[f32],
    v: &[f32],
    t: [&[f32]; 12],
    air: Option<[&[f32]; 6]>,
    out_x: &mut [f32],
    out_v: &mut [f32],
) {
    let n = x.len();
    let (mass, w, v) = (&mass[..n], &w[..n], &v[..n]);
    let t = heads(t, n);
    match air {
        None => {
            // (The air slot is unused without air.)
            let args = (h, g, damping, mass, w, x, v, t, [x; 6]);
            match scheme {
                Scheme::Forward => integrate_lanes::<FORWARD, false>(args, out_x, out_v),
                Scheme::Symplectic => integrate_lanes::<SYMPLECTIC, false>(args, out_x, out_v),
                Scheme::Verlet => integrate_lanes::<VERLET, false>(args, out_x, out_v),
            }
        }
        Some(air) => {
            let args = (h, g, damping, mass, w, x, v, t, heads(air, n));
            match scheme {
                Scheme::Forward => integrate_lanes::<FORWARD, true>(args, out_x, out_v),
                Scheme::Symplectic => integrate_lanes::<SYMPLECTIC, true>(args, out_x, out_v),
                Scheme::Verlet => integrate_lanes::<VERLET, true>(args, out_x, out_v),
            }
        }
    }
}

pub(crate) const FORWARD: u8 = 0;
pub(crate) const SYMPLECTIC: u8 = 1;
pub(crate) const VERLET: u8 = 2;

/// The arguments of [`integrate_component`] past the scheme: h, g, d, mass, 1/m, x, v, the
/// 12 spring terms and the 6 air terms.
type IntegrateArgs<'a> = (
    f32,
    f32,
    f32,
    &'a [f32],
    &'a [f32],
    &'a [f32],
    &'a [f32],
    [&'a [f32]; 12],
    [&'a [f32]; 6],
);

/// [`integrate_component`] for scheme `S`: whole chunks of LANES particles on local arrays
/// (vectorised without run-time alias checks), then the remainder one by one, with the same
/// operations.
#[inline(always)]
fn integrate_lanes<const S: u8, const AIR: bool>(
    args: IntegrateArgs<'_>,
    out_x: &mut [f32],
    out_v: &mut [f32],
) {
    let (h, g, damping, mass, w, x, v, t, air) = args;
    let n = x.len();
    let half = 0.5 * h;
    // Particle c: m·g − d·v, the spring terms in the reference's order, the air's terms (with
    // `AIR`), then the update. (A macro, not a closure: always inlined into the vector loop.)
    macro_rules! one {
        ($mass:expr, $w:expr, $x:expr, $v:expr, $t:expr, $a:expr) => {{
            let (mass, w, x, v, t, a): (f32, f32, f32, f32, [f32; 12], [f32; 6]) =
                ($mass, $w, $x, $v, $t, $a);
            let mut f = mass * g - damping * v;
            f -= t[0];
            f += t[1];
            f -= t[2];
            f += t[3];
            f -= t[4];
            f -= t[5];
            f += t[6];
            f += t[7];
            f -= t[8];
            f -= t[9];
            f += t[10];
            f += t[11];
            if AIR {
                f += a[0];
                f += a[1];
                f += a[2];
                f += a[3];
                f += a[4];
                f += a[5];
            }
            let hw = h * w;
            match S {
                FORWARD => (x + h * v, v + hw * f),
                SYMPLECTIC => {
                    let nv = v + hw * f;
                    (x + h * nv, nv)
                }
                _ => {
                    let nv = v + hw * f;
                    (x + half * nv, nv)
                }
            }
        }};
    }
    let mut c0 = 0;
    while c0 + LANES <= n {
        let (m, wl, xl, vl) = (lanes(mass, c0), lanes(w, c0), lanes(x, c0), lanes(v, c0));
        let tl = chunks(t, c0);
        let al = if AIR { chunks(air, c0) } else { [xl; 6] };
        // Written straight into the output rows: through local arrays the results took a
        // round trip through the stack (zeroed, written, read back, copied).
        let (ox, ov) = (lanes_mut(out_x, c0), lanes_mut(out_v, c0));
        for j in 0..LANES {
            let terms = [
                tl[0][j], tl[1][j], tl[2][j], tl[3][j], tl[4][j], tl[5][j], tl[6][j], tl[7][j],
                tl[8][j], tl[9][j], tl[10][j], tl[11][j],
            ];
            let a = [al[0][j], al[1][j], al[2][j], al[3][j], al[4][j], al[5][j]];
            (ox[j], ov[j]) = one!(m[j], wl[j], xl[j], vl[j], terms, a);
        }
        c0 += LANES;
    }
    for c in c0..n {
        let terms = [
            t[0][c], t[1][c], t[2][c], t[3][c], t[4][c], t[5][c], t[6][c], t[7][c], t[8][c],
            t[9][c], t[10][c], t[11][c],
        ];
        let a = if AIR {
            [
                air[0][c], air[1][c], air[2][c], air[3][c], air[4][c], air[5][c],
            ]
        } else {
            [0.0; 6]
        };
        (out_x[c], out_v[c]) = one!(mass[c], w[c], x[c], v[c], terms, a);
    }
}

/// The explicit substep on the fast path, or (for a substep the fast path declines) the
/// reference path followed by the continuous-collision passes the plan took over.
pub(crate) fn run(
    ctx: &mut SubstepCtx<'_>,
    scratch: &mut GridScratch,
    plan: Option<Plan>,
    force: &mut [Vec3],
) {
    let Some(plan) = plan else { return };
    if substep(ctx, scratch, plan) {
        return;
    }
    let p = &mut *ctx.particles;
    sync(scratch, &mut p.position, &mut p.velocity);
    if plan.ccd {
        keep_start(scratch, &ctx.particles.position);
    }
    match plan.scheme {
        Scheme::Forward => super::explicit::forward_euler(ctx, force),
        Scheme::Symplectic => super::explicit::symplectic_euler(ctx, force),
        Scheme::Verlet => super::explicit::position_verlet(ctx, force),
    }
    if plan.ccd {
        ccd_after_fallback(ctx, scratch);
    }
}

#[cfg(test)]
mod tests {
    use super::{
        Balance, IN_PLACE_MIN, LANES, Placed, RestRows, SharedRows, band_start, far_chunk,
        lane_distance, old_row, springs,
    };
    use crate::test_rng::uniform;
    use glam::Vec3;

    // The integration test of the in-place update (`fast_path.rs`) runs a 364² cloth: past
    // the threshold, with rows wide enough.
    const _: () = assert!(364 * 364 >= IN_PLACE_MIN && 364 >= 2 * LANES);

    /// [`RestRows`] gives every row exactly (bit for bit) the rest lengths of the full table:
    /// on a flat grid placed off the origin (shear diagonals' lengths √(Δx² + Δz²) from f32
    /// coordinates, whose differences round to a few values) it stores a handful of rows; on
    /// random lengths it keeps the full table. Tolerance: none.
    #[test]
    fn rest_rows_store_each_distinct_row_once_and_give_every_row_its_own() {
        let (rows, cols) = (300, 77);
        let (ox, oz, dx, dz) = (
            0.036_176_89_f32,
            0.026_585_01_f32,
            0.003_1_f32,
            0.001_953_125,
        );
        let at = |r: usize, c: usize| Vec3::new(ox + c as f32 * dx, 0.6, oz + r as f32 * dz);
        let mut flat = vec![0.0; rows * cols + LANES];
        for r in 0..rows - 1 {
            for c in 0..cols - 1 {
                flat[r * cols + c] = at(r, c).distance(at(r + 1, c + 1));
            }
        }
        let mut random = uniform(7);
        let noisy: Vec<f32> = (0..rows * cols + LANES).map(|_| random()).collect();
        let placed = |v: &[f32]| {
            let mut p = Placed::default();
            p.reset(v.len(), 3);
            p.copy_from_slice(v);
            p
        };
        let mut table = RestRows::default();
        for (full, most) in [(&flat, RestRows::MAX_DISTINCT), (&noisy, rows)] {
            table.build(placed(full), rows, cols, 3);
            let stored = table.stored_rows(cols);
            assert!(stored <= most, "{stored} rows stored");
            for s in 0..rows {
                let want = &full[s * cols..][..cols];
                let got = table.row(s, cols);
                assert!(
                    want.iter()
                        .zip(got)
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    "row {s}"
                );
                // Whole chunks past the row's end stay readable.
                assert_eq!(
                    table.row(s, cols.next_multiple_of(LANES)).len(),
                    cols.next_multiple_of(LANES)
                );
            }
        }
        table.build(placed(&flat), rows, cols, 3);
        assert!(
            table.stored_rows(cols) < 10,
            "{} rows",
            table.stored_rows(cols)
        );
    }

    /// Continuous collision's chunk screen for spheres ([`far_chunk`]) only passes a chunk
    /// whose every particle passes the cheap per-particle test it stands for, `φ(b) ≥ |b − s|`
    /// in f32 as [`super::ccd_mask`] rounds it: chunks of random paths ending at 0.4–1.6 times
    /// the reach `r + L` from spheres of radius 1 mm – 10 m, centred up to 100 m away
    /// (seeded; tolerance: none, every passed lane must pass).
    #[test]
    fn the_far_chunk_screen_passes_only_chunks_every_lane_passes() {
        let mut rand = uniform(0x2545_f491_4f6c_dd1d);
        let (mut passed, mut failed) = (0, 0);
        for _ in 0..20_000 {
            let r = 1e-3 * 1e4_f32.powf(rand());
            let centre = Vec3::new(rand() - 0.5, rand() - 0.5, rand() - 0.5) * 200.0 * rand();
            let path = r * 1e-4 * 1e4_f32.powf(rand());
            let shift = Vec3::new(rand() - 0.5, rand(), 0.0) * 1e-3 * rand();
            let ring = 0.4 + 1.2 * rand();
            let (mut a, mut b) = ([[0.0_f32; LANES]; 3], [[0.0_f32; LANES]; 3]);
            for l in 0..LANES {
                let dir = Vec3::new(rand() - 0.5, rand() - 0.5, rand() - 0.5).normalize_or(Vec3::Y);
                let end = centre + dir * (r + path) * (ring + 0.002 * rand());
                let step =
                    Vec3::new(rand() - 0.5, rand() - 0.5, rand() - 0.5).normalize_or(Vec3::X);
                let start = end - step * path * rand() - shift;
                [a[0][l], a[1][l], a[2][l]] = start.to_array();
                [b[0][l], b[1][l], b[2][l]] = end.to_array();
            }
            let far = far_chunk(
                centre,
                r,
                [&a[0], &a[1], &a[2]],
                [&b[0], &b[1], &b[2]],
                shift,
            );
            if !far {
                failed += 1;
                continue;
            }
            passed += 1;
            for l in 0..LANES {
                let s = [a[0][l] + shift.x, a[1][l] + shift.y, a[2][l] + shift.z];
                let (qx, qy, qz) = (b[0][l] - s[0], b[1][l] - s[1], b[2][l] - s[2]);
                let len = (qx * qx + qy * qy + qz * qz).sqrt();
                let db = lane_distance(true, centre, r, Vec3::Y, [b[0][l], b[1][l], b[2][l]]).0;
                assert!(
                    db >= len,
                    "lane {l}: φ(b) = {db} < path {len} (r = {r}, L = {path})"
                );
            }
        }
        // Both outcomes occur (the test is not vacuous).
        assert!(
            passed > 1000 && failed > 1000,
            "{passed} passed, {failed} failed"
        );
    }

    /// Read in place ([`old_row`]), the lanes past a row's springs see the next component's
    /// values: on a flat cloth at rest along a row (y, z and vx constant) a lane's two ends
    /// there are the same point. Only the row's real springs may report a zero length, else
    /// every such substep would go to the reference path; a real zero-length spring still
    /// reports it, and so does one too short for its squared length to be a normal float.
    #[test]
    fn only_a_rows_real_springs_report_a_zero_length() {
        let cols: usize = 40; // 39 weft springs (c, c + 1), computed as two chunks of LANES
        let full = cols.next_multiple_of(LANES);
        let width = full + 2;
        // One row-blocked row: x rising along the row, y, z, vx, vy, vz constant, then slack.
        let mut all = vec![0.0_f32; 6 * cols + width];
        for c in 0..cols {
            all[c] = 0.1 * c as f32;
            all[cols + c] = 0.6;
            all[2 * cols + c] = -0.2;
        }
        let ring = Default::default();
        let weft = |all: &[f32]| {
            let a = old_row(&ring, Some(SharedRows::reader(all)), cols, width, 0);
            let ends = |dc: usize| a.map(|comp| &comp[dc..][..full]);
            let (mut fx, mut fy, mut fz) = (vec![0.0; full], vec![0.0; full], vec![0.0; full]);
            let rest = vec![0.1; full];
            springs(
                1.0,
                0.0,
                cols - 1,
                ends(0),
                ends(1),
                &rest,
                [&mut fx, &mut fy, &mut fz],
            )
        };
        // Lane 40 joins x[40] = y[0] … to x[41] = y[1] …: the same values, length zero.
        assert_eq!(
            (all[cols], all[2 * cols]),
            (all[cols + 1], all[2 * cols + 1])
        );
        assert!(
            !weft(&all),
            "a lane past the row's springs reported a zero length"
        );
        let mut touching = all.clone();
        touching[5] = touching[6];
        assert!(weft(&touching), "spring (5, 6) has zero length");
        // Zero length as the reference sees it (`forces::spring_force`): a squared length
        // below `f32::MIN_POSITIVE`, whose reciprocal would overflow; just above it, a spring.
        let mut near = all.clone();
        (near[5], near[6]) = (0.0, 1e-20);
        assert!(
            weft(&near),
            "spring (5, 6) of 1e-20 m counts as zero length"
        );
        (near[5], near[6]) = (0.0, 1.2e-19);
        assert!(!weft(&near), "spring (5, 6) of 1.2e-19 m is a spring");
    }

    /// The balance moves a boundary towards the band that finished first until the bands
    /// finish within a row's work of each other (a lower band whose rows cost 10 % more and
    /// that starts 0.6 µs late ends up with fewer rows), never leaves a band with fewer than
    /// `MIN_ROWS` rows, and starts over from the plain split for a new size. (Results do not
    /// depend on the boundaries: the thread-count tests compare the bits.)
    #[test]
    fn the_balance_moves_rows_to_the_band_that_finishes_first() {
        // Two bands over 128 rows; rows of the lower band cost 1.1 µs, of the upper 1.0 µs,
        // and the lower band starts 0.6 µs late (the thread that steals it).
        let mut b = Balance::default();
        b.prepare(128, 2);
        assert_eq!(b.starts, [0, 65, 128]);
        let ends = |starts: &[usize]| {
            let (r0, r1) = (starts[1] as f32, (starts[2] - starts[1]) as f32);
            [[0.0, r0], [0.6, 0.6 + 1.1 * r1]]
        };
        for _ in 0..200 {
            let t = ends(&b.starts);
            b.update(|i| t[i]);
            assert!(b.starts[1] > Balance::MIN_ROWS && b.starts[1] < 128 - Balance::MIN_ROWS);
        }
        // Balanced: 1.0·r0 = 0.6 + 1.1·(128 − r0) at r0 ≈ 67.3; within a row of the work.
        let t = ends(&b.starts);
        assert!((t[1][1] - t[0][1]).abs() <= 1.1, "{:?} {t:?}", b.starts);
        // Extreme costs keep every band at least MIN_ROWS rows; new sizes start over.
        for _ in 0..500 {
            b.update(|i| [[0.0, 1.0], [0.0, 1000.0]][i]);
        }
        assert_eq!(b.starts, [0, 128 - Balance::MIN_ROWS, 128]);
        b.prepare(40, 3);
        assert_eq!(
            b.starts,
            (0..=3).map(|i| band_start(i, 3, 40)).collect::<Vec<_>>()
        );
    }

    /// The bands tile the rows: starts from 0 to `rows`, strictly increasing (every band at
    /// least one row), the first band at most a few rows longer than the others, for every
    /// band count the fast path uses (at most one band per 8 rows).
    #[test]
    fn bands_tile_the_rows_first_band_slightly_longer() {
        for rows in 1_usize..300 {
            for bands in 1..=rows.div_ceil(8).min(64) {
                let starts: Vec<usize> = (0..=bands).map(|i| band_start(i, bands, rows)).collect();
                assert_eq!(
                    (starts[0], starts[bands]),
                    (0, rows),
                    "{rows} rows, {bands} bands"
                );
                assert!(starts.windows(2).all(|w| w[0] < w[1]), "{starts:?}");
                let len = |i: usize| starts[i + 1] - starts[i];
                for i in 1..bands {
                    assert!(len(0) + 1 >= len(i) && len(0) <= len(i) + 4, "{starts:?}");
                }
            }
        }
    }
}
