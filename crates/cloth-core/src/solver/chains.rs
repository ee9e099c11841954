//! XPBD's structural springs solved chain by chain (`XpbdSettings::chains`).
//!
//! On a grid cloth every warp spring belongs to one column, `(0, c)–(1, c)–…–(rows − 1, c)`,
//! and every weft spring to one row: the structural springs form `cols + rows` chains. A
//! Gauss–Seidel sweep projects the springs of a chain one at a time, so a pull travels one
//! spring per sweep (a hanging cloth of n rows needs about n sweeps, or substeps, to stop
//! stretching). Here the springs of a chain are projected **together**: XPBD's update of all
//! the chain's multipliers at once,
//!
//! ```text
//! ((1 + γ)·J W Jᵀ + α̃·I) Δλ = −C − α̃·λ − γ·J (x − x_prev),   Δx = W Jᵀ Δλ,
//! ```
//!
//! with `J` the gradients of the chain's constraints `C_k = |x_{k+1} − x_k| − L_k` at the
//! current positions, `W` the inverse masses, α̃ = 1/(k h²) and γ = c/(k h) as in the
//! reference sweep ([`super::xpbd`]). Two constraints share a particle only with their
//! neighbours in the chain, so the matrix is **tridiagonal**: diagonal
//! `(1 + γ)(w_k + w_{k+1}) + α̃`, off-diagonal `−(1 + γ)·w_k·n_{k−1}·n_k` (the unit directions
//! of the two springs at their shared particle `k`). It is symmetric positive definite
//! (α̃ > 0), and one forward elimination and one back substitution (the Thomas algorithm)
//! solve it exactly in O(length). A pull then crosses the whole chain in one projection: the
//! chains are a block Gauss–Seidel whose blocks are whole rows and columns (all warp chains,
//! then all weft chains), and a draped cloth reaches a small strain with few substeps.
//!
//! One solve linearises the chain once: it takes every direction from the positions before
//! it and applies the whole chain's tension at once, so a taut chain's sideways pull (its
//! geometric stiffness) acts explicitly, and at large substeps a zigzag across the chain
//! grows. `XpbdSettings::chain_iterations` repeats the solve from the positions the previous
//! one left, the multipliers adding up (Newton's method on the chain's constraints), which
//! approaches the chain's exact projection and keeps taut chains straight ([`iterate`]).
//! `XpbdSettings::chain_rounds` repeats the warp-then-weft block Gauss–Seidel within a sweep
//! (a contact pass before each round), the multipliers carried from round to round
//! ([`Multipliers`]), which lowers what the weft and the contacts leave of the warp's error.
//!
//! `XpbdSettings::shear_chains` solves the shear springs the same way, along the grid's
//! diagonal lines ([`solve_reference_diagonal`] on the reference path,
//! `grid_xpbd::XpbdGrid::shear_chains` on the grid path, whose chains join two lines across
//! the grid's wrap by a spring with a negative rest length, which the solve leaves out).
//!
//! A chain of two particles (one spring) gives the reference's single-spring projection, up
//! to rounding: the solve multiplies by one reciprocal where the reference divides (one
//! division per spring for its direction and one per elimination step, instead of five:
//! the divider set the pace of the solve). A spring of zero length or between two pinned particles is left out of its chain
//! (its multiplier does not change), and so is a spring whose rest length is negative.
//!
//! The chains of one direction are independent. The grid path solves them in blocks of
//! [`LANES`] chains laid out step-major (entry `(k, lane)` at `k·LANES + lane`), so every
//! operation of the sweep runs across the lanes as one vector ([`solve`]); the reference path
//! solves one chain at a time with the same function at one lane, hence the same bits. The
//! AVX2 and AVX-512 kernels run the same operations written with intrinsics
//! (`simd::chains_lanes`): with AVX2 each step of a block as two 8-lane halves (the 16-lane
//! arrays took two registers per value and spilled), with AVX-512 as one vector, each step
//! handing the next its shared particle, direction and recurrence in registers.

/// Chains per block on the grid path: the lanes of the vectorised sweeps.
pub(crate) const LANES: usize = 16;

/// Steps per tile of the transposes of the weft's blocks.
const TILE: usize = 16;

/// Floats between the starts of two arrays of a block beyond their `len · LANES` entries: one
/// cache line. Without it a block of 256-particle chains holds its arrays exactly 16 KiB
/// apart, every array's step `k` falls into the same set of the 8-way L1 cache, and the
/// streams of a sweep evict one another (a block of 256-particle chains took twice
/// the cycles per step).
const PAD: usize = 16;

/// Floats from one array of a block of chains of `len` particles to the next.
pub(crate) fn stride(len: usize) -> usize {
    len * LANES + PAD
}

/// The most bytes the two blocks of one task of the grid path may span (their [`FIELDS`] and
/// [`SCRATCH`] arrays): half of the 1 MiB L2 cache per core of the Zen 4 host. A task gathers
/// its blocks, solves them and writes them back; two blocks of 512-particle chains span
/// 0.9 MiB, and when a task's two blocks were solved interleaved they went out of L2 between
/// the forward pass and the back substitution: one block per task, each 0.45 MiB, the 512²
/// drape ran 5–10 % faster. At 256² (0.45 MiB per pair) one or two blocks per task cost the
/// same, with the blocks solved interleaved and with them solved one after the other.
pub(crate) const PAIR_BYTES: usize = 512 << 10;

/// Whether two blocks of arrays of `size` floats fit in [`PAIR_BYTES`].
pub(crate) fn pair_fits(size: usize) -> bool {
    2 * (FIELDS + SCRATCH) * size * size_of::<f32>() <= PAIR_BYTES
}

/// Arrays per block that persist between solves: x, y, z, start x, y, z, inverse mass, rest
/// length, multiplier.
pub(crate) const FIELDS: usize = 9;

/// Scratch arrays of one solve, written before they are read (any content will do, so one
/// set per thread serves every block it solves, and stays in that core's cache): direction
/// x, y, z, the eliminated super-diagonal and right-hand side (the diagonal goes from each
/// spring's computation to its elimination step in registers).
pub(crate) const SCRATCH: usize = 5;

/// What a chain solve takes besides its chains: the springs' compliance `alpha` (α̃ = 1/(k·h²))
/// and damping `gamma` (`solver::xpbd::compliance`), and the relaxation ω of the solve's step
/// (`XpbdSettings::chain_relaxation`): every right-hand side is multiplied by ω, so every
/// multiplier's change, and the moves, are ω times the Newton step's. With ω = 1 the
/// multiplication changes no bit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Params {
    pub(crate) alpha: f32,
    pub(crate) gamma: f32,
    pub(crate) relaxation: f32,
}

impl Params {
    /// The chain solves' parameters for springs of compliance `alpha` and damping `gamma`
    /// under `settings` (their relaxation), on both paths.
    pub(crate) fn new(alpha: f32, gamma: f32, settings: &crate::config::XpbdSettings) -> Self {
        Self {
            alpha,
            gamma,
            relaxation: settings.chain_relaxation,
        }
    }

    /// The unit tests' springs: α̃ = 0.01, γ = 0.05, the plain step.
    #[cfg(test)]
    pub(crate) fn test() -> Self {
        Self {
            alpha: 0.01,
            gamma: 0.05,
            relaxation: 1.0,
        }
    }
}

/// One block of `L` chains of `len` particles, step-major (entry `(k, lane)` at `k·L + lane`;
/// the per-spring arrays use entries `k < len − 1`, spring `k` joining particles `k` and
/// `k + 1`).
pub(crate) struct Block<'a> {
    /// Positions, advanced in place.
    pub x: [&'a mut [f32]; 3],
    /// Positions at the start of the substep.
    pub prev: [&'a [f32]; 3],
    /// Inverse masses.
    pub w: &'a [f32],
    /// Rest lengths.
    pub rest: &'a [f32],
    /// Multipliers, advanced in place.
    pub lambda: &'a mut [f32],
    /// Scratch: unit directions.
    pub n: [&'a mut [f32]; 3],
    /// Scratch: super-diagonal after elimination.
    pub cp: &'a mut [f32],
    /// Scratch: right-hand side after elimination.
    pub dp: &'a mut [f32],
}

impl<'a> Block<'a> {
    /// Splits a block of [`FIELDS`] arrays and a scratch of [`SCRATCH`] arrays, of `size`
    /// entries each.
    pub(crate) fn split(chunk: &'a mut [f32], scratch: &'a mut [f32], size: usize) -> Self {
        let mut it = chunk.chunks_exact_mut(size);
        let mut next = || it.next().expect("a block holds FIELDS arrays");
        let x = [next(), next(), next()];
        let prev = [&*next(), &*next(), &*next()];
        let w = &*next();
        let rest = &*next();
        let lambda = next();
        let mut it = scratch.chunks_exact_mut(size);
        let mut next = || it.next().expect("a scratch holds SCRATCH arrays");
        let n = [next(), next(), next()];
        let cp = next();
        let dp = next();
        Self {
            x,
            prev,
            w,
            rest,
            lambda,
            n,
            cp,
            dp,
        }
    }
}

/// Solves the `L` chains of `len ≥ 2` particles of a block (see the module docs): one forward
/// pass (each spring's direction, constraint value and row of the tridiagonal matrix from the
/// current positions, eliminated right away), then one back substitution applying every
/// multiplier's change to the positions (and, with `keep`, adding it to the multipliers, which
/// are read as zero otherwise). Plain IEEE `f32` (no fused multiply-add), the same for every
/// lane count: each lane's operations are the same, whatever else is solved beside it.
///
/// The elimination's steps also issue `ahead`'s prefetches, one grid entry of the next blocks
/// per step: the memory system has room while the step computes (the warp's next column
/// gathers then read from L2: 9.7 → 5.5 % of a substep's samples, the 256² drape 2 %
/// faster).
#[inline(always)]
pub(crate) fn solve<const L: usize>(
    mut block: Block<'_>,
    len: usize,
    Params {
        alpha,
        gamma,
        relaxation,
    }: Params,
    keep: bool,
    ahead: Option<&Ahead<'_>>,
) {
    debug_assert!(len >= 2);
    let g1 = 1.0 + gamma;
    // 1. The forward pass down the chains: step k first computes spring k (its direction,
    // constraint value, right-hand side, diagonal and coupling with spring k − 1: no
    // dependence on the elimination's recurrence, so the processor overlaps them with it),
    // then eliminates it. What the elimination reads was
    // written a moment before and is still in L1; computed in a pass of their own, the
    // springs' diagonals, couplings and right-hand sides went out to L2 and came back.
    {
        let mut view = {
            let block = &mut block;
            (
                &block.w.as_chunks::<L>().0[..len],
                &block.rest.as_chunks::<L>().0[..len],
                block.prev.map(|a| &a.as_chunks::<L>().0[..len]),
                block.x.each_ref().map(|a| &a.as_chunks::<L>().0[..len]),
                &block.lambda.as_chunks::<L>().0[..len],
                block
                    .n
                    .each_mut()
                    .map(|a| &mut a.as_chunks_mut::<L>().0[..len]),
                &mut block.cp.as_chunks_mut::<L>().0[..len],
                &mut block.dp.as_chunks_mut::<L>().0[..len],
            )
        };
        // Spring k, from spring k − 1's direction `n_prev`: writes its direction
        // and gives its coupling with spring k − 1 (through particle k), its right-hand side
        // and its diagonal, which the elimination's step takes in registers.
        macro_rules! spring {
            ($k:expr, $n_prev:expr) => {{
                let k: usize = $k;
                let n_prev: [[f32; L]; 3] = $n_prev;
                let (w, rest, [px, py, pz], [xs, ys, zs], lam, [nx, ny, nz], ..) = &mut view;
                let (a, b) = (k, k + 1);
                // Local copies: the lane loop then reads and writes only locals and
                // vectorises without alias checks.
                let (xa, xb, ya, yb, za, zb) = (xs[a], xs[b], ys[a], ys[b], zs[a], zs[b]);
                let (pxa, pxb, pya, pyb, pza, pzb) = (px[a], px[b], py[a], py[b], pz[a], pz[b]);
                // Without kept multipliers they are zero (`−C − α̃·0 = −C`: the same bits).
                let lam_k = if keep { lam[k] } else { [0.0; L] };
                let (w_a, w_b, rest_k) = (w[a], w[b], rest[k]);
                let (mut ex, mut ey, mut ez) = ([0.0_f32; L], [0.0_f32; L], [0.0_f32; L]);
                let (mut e_k, mut rhs_k, mut diag_k) = ([0.0_f32; L], [0.0_f32; L], [0.0_f32; L]);
                for l in 0..L {
                    let (dx, dy, dz) = (xb[l] - xa[l], yb[l] - ya[l], zb[l] - za[l]);
                    let length = ((dx * dx) + (dy * dy) + (dz * dz)).sqrt();
                    let (wa, wb) = (w_a[l], w_b[l]);
                    let ws = wa + wb;
                    let active = length > 0.0 && ws > 0.0 && rest_k[l] >= 0.0;
                    // The direction in locals, stored once at the end of the lane: assigned to
                    // `ex[l]…` in both arms of the `if`, it became two masked stores to the
                    // stack and a reload, which the processor cannot forward (a fifth of the
                    // solve's samples waited on that reload).
                    let inv = 1.0 / length;
                    let (ux, uy, uz) = if active {
                        (dx * inv, dy * inv, dz * inv)
                    } else {
                        (0.0, 0.0, 0.0)
                    };
                    let (vx, vy, vz) = (
                        (xb[l] - pxb[l]) - (xa[l] - pxa[l]),
                        (yb[l] - pyb[l]) - (ya[l] - pya[l]),
                        (zb[l] - pzb[l]) - (za[l] - pza[l]),
                    );
                    let rate = (ux * vx) + (uy * vy) + (uz * vz);
                    let constraint = length - rest_k[l];
                    diag_k[l] = if active { g1 * ws + alpha } else { 1.0 };
                    // Times the relaxation ω (1: the plain Newton step, the same bits).
                    rhs_k[l] = if active {
                        (-constraint - alpha * lam_k[l] - gamma * rate) * relaxation
                    } else {
                        0.0
                    };
                    // Coupling with spring k − 1 through particle k (zero for k = 0).
                    let cos =
                        (n_prev[0][l] * ux) + (n_prev[1][l] * uy) + (n_prev[2][l] * uz);
                    e_k[l] = -(g1 * wa) * cos;
                    (ex[l], ey[l], ez[l]) = (ux, uy, uz);
                }
                (nx[k], ny[k], nz[k]) = (ex, ey, ez);
                (e_k, rhs_k, diag_k)
            }};
        }
        // The elimination's step k, from the reciprocal `m_prev` of spring k − 1's
        // eliminated diagonal and its right-hand side `dp_prev`: the eliminated right-hand
        // side replaces `dp[k]`, the coupling `c` goes into `cp[k − 1]` (k > 0) and the
        // reciprocal of the eliminated diagonal into `cp[k]` (read back as `m_prev` by step
        // k + 1, then overwritten with its coupling): one division per step. The recurrences
        // go through the block's arrays (each step reads what the step before it wrote, from
        // L1), not through arrays carried in the loop, which the compiler split into scalars
        // or spilled.
        macro_rules! eliminate {
            ($k:expr, $spring:expr, $m_prev:expr, $dp_prev:expr) => {{
                let k: usize = $k;
                let (e_k, rhs_k, diag_k): ([f32; L], [f32; L], [f32; L]) = $spring;
                let (m_prev, dp_prev): ([f32; L], [f32; L]) = ($m_prev, $dp_prev);
                let (.., cp, dp) = &mut view;
                let (mut c_k, mut m_k, mut d) = ([0.0_f32; L], [0.0_f32; L], [0.0_f32; L]);
                for l in 0..L {
                    let e = e_k[l];
                    let c = e * m_prev[l];
                    let r = 1.0 / (diag_k[l] - e * c);
                    d[l] = (rhs_k[l] - e * dp_prev[l]) * r;
                    c_k[l] = c;
                    m_k[l] = r;
                }
                dp[k] = d;
                if k > 0 {
                    cp[k - 1] = c_k;
                }
                cp[k] = m_k;
            }};
        }
        let spring = spring!(0, [[0.0; L]; 3]);
        eliminate!(0, spring, [1.0; L], [0.0; L]);
        if let Some(ahead) = ahead {
            ahead.row(0);
            ahead.row(len - 1);
        }
        for k in 1..len - 1 {
            // The elimination's steps are a chain of dependent divisions: room for the
            // next blocks' loads from memory.
            if let Some(ahead) = ahead {
                ahead.row(k);
            }
            let n = &view.5;
            let spring = spring!(k, [n[0][k - 1], n[1][k - 1], n[2][k - 1]]);
            let (.., cp, dp) = &view;
            eliminate!(k, spring, cp[k - 1], dp[k - 1]);
        }
        let (.., [nx, ny, nz], cp, dp) = &mut view;
        // Entry len − 1 (past the last spring): a zero change and direction, which the back
        // substitution's first step reads as its successor's.
        dp[len - 1] = [0.0; L];
        (nx[len - 1], ny[len - 1], nz[len - 1]) = ([0.0; L], [0.0; L], [0.0; L]);
        cp[len - 2] = [0.0; L];
    }
    // 2. The back substitution. The multipliers' changes replace the right-hand sides in place
    // (`dp[k]` becomes Δλ_k, read by step k − 1 as its successor's).
    let ([xs, ys, zs], w, lam, [nx, ny, nz], cp, dp) = {
        let Block {
            x,
            w,
            lambda,
            n,
            cp,
            dp,
            ..
        } = block;
        (
            x.map(|a| &mut a.as_chunks_mut::<L>().0[..len]),
            &w.as_chunks::<L>().0[..len],
            &mut lambda.as_chunks_mut::<L>().0[..len],
            n.map(|a| &a.as_chunks::<L>().0[..len]),
            &cp.as_chunks::<L>().0[..len],
            &mut dp.as_chunks_mut::<L>().0[..len],
        )
    };
    for k in (0..len - 1).rev() {
        let b = k + 1;
        let dl_next = dp[b];
        // Whole-lane steps (simple loops, each one vector operation per lane group).
        let mut dl = [0.0_f32; L];
        for l in 0..L {
            dl[l] = dp[k][l] - cp[k][l] * dl_next[l];
        }
        dp[k] = dl;
        let wb = w[b];
        for (x, (n_k, n_next)) in [&mut xs[b], &mut ys[b], &mut zs[b]].into_iter().zip([
            (&nx[k], &nx[b]),
            (&ny[k], &ny[b]),
            (&nz[k], &nz[b]),
        ]) {
            // Through a local copy (no alias checks in the lane loop).
            let mut v = *x;
            apply(&mut v, &wb, &dl, n_k, &dl_next, n_next);
            *x = v;
        }
        if keep {
            for l in 0..L {
                lam[k][l] += dl[l];
            }
        }
    }
    let (dl_first, n_first) = (dp[0], [nx[0], ny[0], nz[0]]);
    for l in 0..L {
        let s = w[0][l] * dl_first[l];
        xs[0][l] -= s * n_first[0][l];
        ys[0][l] -= s * n_first[1][l];
        zs[0][l] -= s * n_first[2][l];
    }
}

/// [`solve`] at [`LANES`] lanes (the grid path's blocks).
#[inline(always)]
pub(crate) fn solve_lanes(
    block: Block<'_>,
    len: usize,
    params: Params,
    keep: bool,
    ahead: Option<&Ahead<'_>>,
) {
    solve::<LANES>(block, len, params, keep, ahead);
}

/// What the next blocks of a direction will read, fetched into L2 ([`crate::simd::prefetch`])
/// during this block's elimination, a little per step: the grid entries their gather reads
/// (entry `k` of every chain at step `k`), and the other direction's tiles their
/// [`handoff`] reads ([`Tiles`]). Only a hint: it changes no result.
#[derive(Debug)]
pub(crate) struct Ahead<'a> {
    /// The grid arrays the gather will read (positions, start positions).
    pub(crate) fields: [Option<&'a [f32]>; 6],
    /// Entry `k` of the next blocks' first chain is at `first + k·stride`.
    pub(crate) first: usize,
    pub(crate) stride: usize,
    /// Floats per entry (the next blocks' chain count).
    pub(crate) span: usize,
    /// The other direction's tiles the next blocks' [`handoff`] will read, when it will.
    pub(crate) tiles: Option<Tiles<'a>>,
}

/// The tiles [`handoff`] reads for the next blocks: in every block of the other direction
/// (`from`, [`FIELDS`] arrays of `size` floats each), the positions (fields 0, 1, 2) from
/// entry `offset` on, `lines` cache lines of them; `per_step` lines of each field per step of
/// the elimination, so that the whole set arrives over its steps. Half of those blocks were solved
/// by the other thread: without it the hand-offs read them from its cache or from L3 while
/// transposing (their share of the 512² drape's samples, against the chain solve's, 0.25–0.32
/// before, 0.19–0.24 with it).
#[derive(Debug)]
pub(crate) struct Tiles<'a> {
    from: &'a [f32],
    size: usize,
    offset: usize,
    lines: usize,
    per_step: usize,
}

impl<'a> Tiles<'a> {
    /// The tiles of the `count` blocks from block `next` on (`LANES · LANES` floats of each
    /// field per block) in `from`, whose arrays are `size` floats each, spread over `steps`.
    pub(crate) fn new(
        from: &'a [f32],
        size: usize,
        next: usize,
        count: usize,
        steps: usize,
    ) -> Self {
        let lines = (count * LANES * LANES).div_ceil(16);
        let total = from.len() / (FIELDS * size) * lines;
        Self {
            from,
            size,
            offset: next * LANES * LANES,
            lines,
            per_step: total.div_ceil(steps.max(1)),
        }
    }

    /// Step `k`'s lines (each a line of the three fields).
    #[inline(always)]
    fn row(&self, k: usize) {
        for line in k * self.per_step..(k + 1) * self.per_step {
            let (block, line) = (line / self.lines, line % self.lines);
            for f in 0..3 {
                let at = (block * FIELDS + f) * self.size + self.offset + line * 16;
                if let Some(l) = self.from.get(at..at + 16) {
                    crate::simd::prefetch(l, crate::simd::Level::L2);
                }
            }
        }
    }
}

impl<'a> Ahead<'a> {
    /// Only the other direction's tiles (a task whose next blocks gather nothing from the
    /// grid).
    pub(crate) fn tiles(tiles: Tiles<'a>) -> Self {
        Self {
            fields: [None; 6],
            first: 0,
            stride: 0,
            span: 0,
            tiles: Some(tiles),
        }
    }

    #[inline(always)]
    pub(crate) fn row(&self, k: usize) {
        let at = self.first + k * self.stride;
        for field in self.fields.iter().flatten() {
            let Some(row) = field.get(at..at + self.span) else {
                continue;
            };
            crate::simd::prefetch(row, crate::simd::Level::L2);
        }
        if let Some(tiles) = &self.tiles {
            tiles.row(k);
        }
    }
}

/// What a block's multipliers (field 8) hold when its chains are solved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Multipliers {
    /// Zero, and never read: one sweep, one round and one iteration per substep (the solve
    /// then treats them as zero without reading or writing them; the same bits).
    Unused,
    /// Start from zero here and add up over the iterations and later rounds: the first round
    /// of a substep with one sweep (the block's multipliers are zeroed first).
    Fresh,
    /// Their current values (gathered from the grid with several sweeps, or left in the block
    /// by the previous round of this substep), added to.
    Kept,
}

impl Multipliers {
    /// What a solve's multipliers hold: `kept` when they carry values from before it (several
    /// sweeps, or a later round), else `Fresh` when it adds them up (several Newton
    /// iterations or rounds), else `Unused`.
    pub(crate) fn of(kept: bool, add_up: bool) -> Self {
        if kept {
            Self::Kept
        } else if add_up {
            Self::Fresh
        } else {
            Self::Unused
        }
    }
}

/// `iterations` Newton iterations of the chain solves of a block (`XpbdSettings::
/// chain_iterations`): [`solve`] again from the positions the previous iteration left, the
/// multipliers adding up over the iterations (and over the rounds, `multipliers`).
///
/// `chunk` holds one or two blocks ([`FIELDS`] arrays of `size` each, one after the other),
/// solved one after the other, each iteration in turn; `scratch` holds [`SCRATCH`] arrays per
/// block. `ahead`: the grid entries the next blocks will gather, fetched into L2 during the
/// first block's first iteration ([`Ahead`]).
#[allow(clippy::too_many_arguments)]
pub(crate) fn iterate(
    chunk: &mut [f32],
    scratch: &mut [f32],
    size: usize,
    len: usize,
    (params, iterations): (Params, u32),
    multipliers: Multipliers,
    kernel: crate::simd::Kernel,
    ahead: Option<&Ahead<'_>>,
) {
    debug_assert!(chunk.len() == FIELDS * size || chunk.len() == 2 * FIELDS * size);
    if multipliers == Multipliers::Fresh {
        for block in chunk.chunks_exact_mut(FIELDS * size) {
            block[8 * size..9 * size].fill(0.0);
        }
    }
    let keep = multipliers != Multipliers::Unused;
    for iteration in 0..iterations {
        let blocks = chunk.chunks_exact_mut(FIELDS * size);
        let works = scratch.chunks_exact_mut(SCRATCH * size);
        for (b, (block, work)) in blocks.zip(works).enumerate() {
            // The next blocks' entries fetched during the first block's first iteration only.
            let ahead = ahead.filter(|_| iteration == 0 && b == 0);
            let block = Block::split(block, work, size);
            crate::simd::xpbd_chains(kernel, block, len, params, keep, ahead);
        }
    }
}

/// One component of the back substitution's update of particle `k + 1`:
/// `x += (w·Δλ_k)·n_k − (w·Δλ_{k+1})·n_{k+1}` (separate arrays, so it vectorises).
#[inline(always)]
fn apply<const L: usize>(
    x: &mut [f32; L],
    w: &[f32; L],
    dl: &[f32; L],
    n: &[f32; L],
    dl_next: &[f32; L],
    n_next: &[f32; L],
) {
    for ((x, &w), ((&dl, &n), (&dl_next, &n_next))) in x
        .iter_mut()
        .zip(w)
        .zip(dl.iter().zip(n).zip(dl_next.iter().zip(n_next)))
    {
        let (s, t) = (w * dl, w * dl_next);
        *x += s * n - t * n_next;
    }
}

/// Where entry `k` of chain `chain` lives in a row-major grid of `cols` columns: warp chains
/// (class 0) are columns, weft chains (class 1) rows.
#[inline(always)]
fn at(class: usize, cols: usize, chain: usize, k: usize) -> usize {
    if class == 0 {
        k * cols + chain
    } else {
        chain * cols + k
    }
}

/// `(chains, particles per chain)` of a direction.
pub(crate) fn shape(class: usize, rows: usize, cols: usize) -> (usize, usize) {
    if class == 0 {
        (cols, rows)
    } else {
        (rows, cols)
    }
}

/// Copies the chains `first .. first + lanes` of a direction into a block of `L` lanes
/// (fields x, y, z, start x, y, z, inverse mass, rest length, multiplier). The inverse masses
/// and rest lengths only when `statics` (they stay in the block between substeps); the
/// multipliers only when `lambda` is given (else [`solve`] runs with `keep = false` and never
/// reads them); the positions only when `pos` is given (else [`handoff`] copies them from the
/// warp's blocks); the start positions only when `prev` is given (they stay in the block for
/// the substep's later rounds and sweeps). Lanes past `lanes` are left as they are (zero:
/// inactive).
#[allow(clippy::too_many_arguments)]
pub(crate) fn gather<const L: usize>(
    chunk: &mut [f32],
    len: usize,
    (class, cols): (usize, usize),
    (first, lanes): (usize, usize),
    pos: Option<[&[f32]; 3]>,
    prev: Option<[&[f32]; 3]>,
    w: &[f32],
    rest: &[f32],
    lambda: Option<&[f32]>,
    statics: bool,
    kernel: crate::simd::Kernel,
) {
    let size = chunk.len() / FIELDS;
    debug_assert!(size >= len * L);
    let pos = pos.map_or([None; 3], |p| p.map(Some));
    let prev = prev.map_or([None; 3], |p| p.map(Some));
    let fields = pos
        .into_iter()
        .chain(prev)
        .chain([Some(w), Some(rest)])
        .chain([lambda])
        .enumerate()
        .filter(|&(f, _)| statics || !(6..=7).contains(&f));
    for (f, src) in fields {
        let Some(src) = src else { continue };
        let dst = &mut chunk[f * size..(f + 1) * size];
        if class == 0 {
            for (k, dst) in dst.as_chunks_mut::<L>().0[..len].iter_mut().enumerate() {
                let i = at(class, cols, first, k);
                if lanes == L {
                    // A whole block: a copy of known length, inlined (no `memcpy` call per step).
                    *dst = *src[i..].first_chunk::<L>().expect("L entries");
                } else {
                    dst[..lanes].copy_from_slice(&src[i..i + lanes]);
                }
            }
        } else {
            // A transpose, in tiles of TILE steps (each tile's rows stay in L1); whole 16 × 16
            // tiles with the kernel's transpose.
            let dst = &mut dst.as_chunks_mut::<L>().0[..len];
            for k0 in (0..len).step_by(TILE) {
                let tile = &mut dst[k0..(k0 + TILE).min(len)];
                let n = tile.len();
                if L == 16 && TILE == 16 && lanes == L && n == TILE {
                    let src = &src[at(class, cols, first, k0)..];
                    crate::simd::transpose16(kernel, src, cols, tile.as_flattened_mut(), L);
                    continue;
                }
                for lane in 0..lanes {
                    let i = at(class, cols, first + lane, k0);
                    for (d, &v) in tile.iter_mut().zip(&src[i..i + n]) {
                        d[lane] = v;
                    }
                }
            }
        }
    }
}

/// The positions of weft block `block` (rows `block·L ..`, fields 0, 1, 2) copied straight
/// from the warp's blocks (`from`: every column's chain just solved, `stride(rows)` per field),
/// instead of scattering the warp into the rows and gathering the weft from them: tile `(b,
/// block)` of 16 columns × 16 rows is a transpose of one contiguous tile into another. The
/// same values as the round trip through the rows (the warp's lanes past `cols` and steps
/// past `rows` are not read; the weft's lanes past `rows` are left as they are).
///
/// With `(rows, cols)` given as `(cols, rows)` it is the other way round: the positions of
/// warp block `block` (columns `block·L ..`) from the weft's blocks (`stride(cols)` per field),
/// the grid seen transposed.
pub(crate) fn handoff<const L: usize>(
    chunk: &mut [f32],
    from: &[f32],
    block: usize,
    (rows, cols): (usize, usize),
    kernel: crate::simd::Kernel,
) {
    let size = chunk.len() / FIELDS;
    let from_size = stride(rows);
    let lanes = L.min(rows - block * L);
    for f in 0..3 {
        let dst = &mut chunk[f * size..][..cols * L];
        for (b, dst) in dst.chunks_mut(L * L).enumerate() {
            // Warp block b: steps block·L + lane (the weft's lanes), lanes k (its steps).
            let src = &from[(b * FIELDS + f) * from_size..][block * L * L..][..lanes * L];
            // The tile two blocks on, read into L1 while this one is transposed: the other
            // thread solved about half of the blocks, so their lines come from its cache,
            // and they are a block's stride apart, which the hardware prefetcher does not
            // follow (the transposes' share of a 2-thread 512² drape: 12 → 7 %).
            if let Some(ahead) = from.get(((b + 2) * FIELDS + f) * from_size + block * L * L..) {
                let ahead = &ahead[..ahead.len().min(lanes * L)];
                crate::simd::prefetch(ahead, crate::simd::Level::L1);
            }
            if L == 16 && lanes == L && dst.len() == L * L {
                crate::simd::transpose16(kernel, src, L, dst, L);
                continue;
            }
            for (k, d) in dst.as_chunks_mut::<L>().0.iter_mut().enumerate() {
                for (lane, d) in d[..lanes].iter_mut().enumerate() {
                    *d = src[lane * L + k];
                }
            }
        }
    }
}

/// Copies one field of a weft block (`src`: `len` steps of `L` lanes, step-major) back into
/// the rows `dst` (`cols` entries each, one row per lane): the transpose of [`gather`]'s, in
/// tiles.
pub(crate) fn scatter_rows<const L: usize>(
    src: &[f32],
    len: usize,
    dst: &mut [f32],
    cols: usize,
    kernel: crate::simd::Kernel,
) {
    let src = &src.as_chunks::<L>().0[..len];
    let full_rows = dst.len() >= L * cols;
    for k0 in (0..len).step_by(TILE) {
        let tile = &src[k0..(k0 + TILE).min(len)];
        if L == 16 && TILE == 16 && full_rows && tile.len() == TILE {
            crate::simd::transpose16(kernel, tile.as_flattened(), L, &mut dst[k0..], cols);
            continue;
        }
        for (lane, row) in dst.chunks_exact_mut(cols).enumerate().take(L) {
            for (d, s) in row[k0..k0 + tile.len()].iter_mut().zip(tile) {
                *d = s[lane];
            }
        }
    }
}

/// The reference path's chain solves: every chain of one direction (`class` 0: the warp
/// columns, 1: the weft rows), one after the other, each at one lane in `scratch`, with
/// `iterations` Newton iterations (see [`iterate`]).
pub(crate) fn solve_reference(
    particles: &mut crate::particles::Particles,
    start: &[glam::Vec3],
    rest: &[f32],
    lambda: &mut [f32],
    (rows, cols, class): (usize, usize, usize),
    solve: (Params, u32),
    scratch: &mut Vec<f32>,
) {
    let (count, len) = shape(class, rows, cols);
    for chain in 0..count {
        let entry = |k: usize| at(class, cols, chain, k);
        // Every entry's rest length and multiplier are gathered (the last one's is not read).
        let line = (len, entry, |k: usize| Some(entry(k)));
        solve_line(particles, start, (rest, &mut *lambda), line, solve, scratch);
    }
}

/// The reference path's shear chains (`XpbdSettings::shear_chains`): every diagonal line of
/// one direction (`dir` 0: the springs `(r, c)–(r + 1, c + 1)`, rest lengths and multipliers
/// at slot `(r, c)`; 1: `(r, c)–(r + 1, c − 1)`, at slot `(r, c − 1)`), one line after the
/// other, each at one lane in `scratch` with `iterations` Newton iterations: the lines that
/// start on row 0, from column 0 on, then those that start on the first (diagonals) or last
/// (anti-diagonals) column, from row 1 on. A line of one particle has no spring.
pub(crate) fn solve_reference_diagonal(
    particles: &mut crate::particles::Particles,
    start: &[glam::Vec3],
    rest: &[f32],
    lambda: &mut [f32],
    (rows, cols, dir): (usize, usize, usize),
    solve: (Params, u32),
    scratch: &mut Vec<f32>,
) {
    let edge = if dir == 0 { 0 } else { cols - 1 };
    let starts = (0..cols)
        .map(|c| (0, c))
        .chain((1..rows).map(|r| (r, edge)));
    for (r0, c0) in starts {
        let len = if dir == 0 {
            (rows - r0).min(cols - c0)
        } else {
            (rows - r0).min(c0 + 1)
        };
        if len < 2 {
            continue;
        }
        // Entry k of the line: row r0 + k, column c0 ± k; its spring to entry k + 1 has its
        // rest length and multiplier at slot `entry(k) − dir`.
        let entry = |k: usize| (r0 + k) * cols + if dir == 0 { c0 + k } else { c0 - k };
        let line = (len, entry, |k: usize| (k + 1 < len).then(|| entry(k) - dir));
        solve_line(particles, start, (rest, &mut *lambda), line, solve, scratch);
    }
}

/// One chain of the reference path, `line = (len, entry, slot)`: entry `k` is particle
/// `entry(k)`, its spring to entry `k + 1` has its rest length and multiplier at `slot(k)`
/// (`None`: none, read as zero and not written back). Gathered into `scratch` at one lane,
/// solved `iterations` times ([`solve`], multipliers kept), scattered back.
fn solve_line(
    particles: &mut crate::particles::Particles,
    start: &[glam::Vec3],
    (rest, lambda): (&[f32], &mut [f32]),
    (len, entry, slot): (
        usize,
        impl Fn(usize) -> usize,
        impl Fn(usize) -> Option<usize>,
    ),
    (params, iterations): (Params, u32),
    scratch: &mut Vec<f32>,
) {
    // Every field the solve reads is gathered below; only the length matters.
    scratch.resize((FIELDS + SCRATCH) * len, 0.0);
    {
        let (fields, _) = scratch.split_at_mut(FIELDS * len);
        for k in 0..len {
            let i = entry(k);
            let (x, x0) = (particles.position[i], start[i]);
            let (r, l) = slot(k).map_or((0.0, 0.0), |s| (rest[s], lambda[s]));
            for (f, v) in [x.x, x.y, x.z, x0.x, x0.y, x0.z, particles.inv_mass[i], r, l]
                .into_iter()
                .enumerate()
            {
                fields[f * len + k] = v;
            }
        }
    }
    for _ in 0..iterations {
        let (fields, work) = scratch.split_at_mut(FIELDS * len);
        solve::<1>(Block::split(fields, work, len), len, params, true, None);
    }
    for k in 0..len {
        let i = entry(k);
        particles.position[i] = glam::Vec3::new(scratch[k], scratch[len + k], scratch[2 * len + k]);
        if let Some(s) = slot(k) {
            lambda[s] = scratch[8 * len + k];
        }
    }
}

/// One tile of 16 × 16 floats transposed element by element: `dst[k·dst_stride + l] =
/// src[l·src_stride + k]` for `k, l < 16` (the portable version of
/// [`crate::simd::transpose16`]).
pub(crate) fn transpose16(src: &[f32], src_stride: usize, dst: &mut [f32], dst_stride: usize) {
    for l in 0..16 {
        let row = &src[l * src_stride..][..16];
        for (k, &v) in row.iter().enumerate() {
            dst[k * dst_stride + l] = v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A task of the grid path takes two blocks up to chains of 291 particles (the docs' and
    /// the long-chain bit test's threshold: the 320-particle strip takes single blocks, 256²
    /// pairs). Exact arithmetic on the sizes, no tolerance.
    #[test]
    fn pairs_stop_past_291_particles() {
        assert!(pair_fits(stride(256)));
        assert!(pair_fits(stride(291)));
        assert!(!pair_fits(stride(292)));
        assert!(!pair_fits(stride(320)));
        assert!(!pair_fits(stride(512)));
    }

    /// Solves one chain at one lane (`iterations` Newton iterations, multipliers kept) from
    /// positions `x`, start positions `x0`, inverse masses `w` and rest lengths `rest` (entry
    /// `k` for the spring `k`–`k + 1`); returns the positions and multipliers.
    fn solve_one(
        x: &[[f32; 3]],
        x0: &[[f32; 3]],
        w: &[f32],
        rest: &[f32],
        iterations: u32,
    ) -> (Vec<[f32; 3]>, Vec<f32>) {
        let len = x.len();
        let mut fields = vec![0.0_f32; FIELDS * len];
        let mut work = vec![0.0_f32; SCRATCH * len];
        for k in 0..len {
            let values = [
                x[k][0], x[k][1], x[k][2], x0[k][0], x0[k][1], x0[k][2], w[k], rest[k], 0.0,
            ];
            for (f, v) in values.into_iter().enumerate() {
                fields[f * len + k] = v;
            }
        }
        for _ in 0..iterations {
            solve::<1>(
                Block::split(&mut fields, &mut work, len),
                len,
                Params::test(),
                true,
                None,
            );
        }
        let x = (0..len)
            .map(|k| [fields[k], fields[len + k], fields[2 * len + k]])
            .collect();
        (x, fields[8 * len..9 * len].to_vec())
    }

    /// A negative rest length leaves its spring out of the chain (`XpbdSettings::shear_chains`
    /// joins two diagonal lines into one chain across the grid's wrap that way): a chain of
    /// two lines joined by such a spring gives the same positions and multipliers as the two
    /// lines solved on their own, with one Newton iteration and with three. Tolerance: none
    /// (compared as values, so that a zero's sign does not count).
    #[test]
    fn a_negative_rest_length_cuts_the_chain() {
        let (a, b) = (5, 7);
        let n = a + b;
        let x: Vec<[f32; 3]> = (0..n)
            .map(|k| {
                let t = k as f32;
                [0.11 * t, 0.02 * (t * 1.3).sin(), 0.015 * (t * 0.7).cos()]
            })
            .collect();
        let x0: Vec<[f32; 3]> = x
            .iter()
            .enumerate()
            .map(|(k, p)| [p[0] - 0.001 * k as f32, p[1] + 0.002, p[2]])
            .collect();
        let mut w = vec![2.0_f32; n];
        w[0] = 0.0;
        w[n - 1] = 0.5;
        let mut rest = vec![0.1_f32; n];
        rest[a - 1] = -1.0;
        rest[n - 1] = 0.0;
        for iterations in [1, 3] {
            let (whole, whole_lambda) = solve_one(&x, &x0, &w, &rest, iterations);
            let (first, first_lambda) =
                solve_one(&x[..a], &x0[..a], &w[..a], &rest[..a], iterations);
            let (second, second_lambda) =
                solve_one(&x[a..], &x0[a..], &w[a..], &rest[a..], iterations);
            assert!(whole[..a] == first[..], "{iterations}: the first line");
            assert!(whole[a..] == second[..], "{iterations}: the second line");
            assert!(whole_lambda[..a - 1] == first_lambda[..a - 1]);
            assert!(whole_lambda[a..n - 1] == second_lambda[..b - 1]);
            assert!(whole.iter().flatten().all(|v| v.is_finite()));
            // The solve did move the particles.
            assert!(whole != x, "{iterations}: nothing moved");
        }
    }
}
