//! Run-time choice of the instruction set of the explicit integrators' grid fast path.
//!
//! The fast path (see the `solver::grid_kernel` module docs) is written as plain loops over
//! equal-length `f32` slices, which the compiler vectorises. This module compiles that one
//! generic code three times: for the baseline target (SSE2 on x86-64, the portable
//! fallback), with AVX2 + FMA, and with AVX-512 (F + VL); the widest one the CPU supports
//! (checked with `is_x86_feature_detected!` at run time) runs. The compiler never contracts
//! a multiplication and an addition into a fused multiply-add on its own, and `sqrt` and
//! division are exact in every instruction set, so **all kernels give the same bits as the
//! reference path** (tested in `tests/fast_path.rs`).
//!
//! A few kernels are written with explicit intrinsics instead: the 16 × 16 tile transposes of
//! the chain solves' blocks (`transpose16`), pure data movement (AVX shuffles; loads and
//! stores through `bytemuck` casts of `[f32; 8]`, so without `unsafe`), kernels of XPBD's
//! grid path with the compiled loop's arithmetic in its order (the same bits): the horizontal
//! bend's groups of four (`xpbd_quads`, AVX-512 and AVX2), the vertical pairs with a masked
//! last vector (`xpbd_pairs`, AVX-512) and the AVX2 chain solve (`chains_lanes`), and the
//! explicit integrators' fused row (`fused_row`): a grid row's six spring classes and its
//! integration per chunk of 16 (AVX-512) or 8 (AVX2) particles in registers, one generic body
//! over the small `Lanes` trait of vector operations, the compiled path's operations in their
//! order (the same bits; about 1.5× the peer scene's throughput of the compiled AVX-512 band
//! on the Zen 4 host).
//!
//! This is the crate's only module with `unsafe`: calling a `#[target_feature]` function,
//! which is sound only on a CPU that has the features (every call is guarded), and the
//! intrinsic kernels' loads and stores (bounds asserted or taken from slices of known
//! length).
#![allow(unsafe_code)]

use std::cell::Cell;

use crate::error::{ClothError, Result};
use crate::solver::chains;
use crate::solver::grid_kernel::{self, Band, BandResult, Dest, Job};
use crate::solver::grid_xpbd::{self, AirCoefficients, Shared};
use crate::solver::implicit::grid;

/// Which code runs the substeps of the explicit integrators (forward Euler, symplectic
/// Euler, position Verlet), of implicit Euler and of XPBD on a grid cloth.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Kernel {
    /// The reference path: forces per spring through the index arrays
    /// ([`crate::forces`]), then integrate, then contacts; implicit Euler's solve through
    /// index lists; XPBD's storage-order sweeps. Also what every non-grid cloth uses.
    Reference,
    /// The grid fast path for the baseline instruction set (SSE2 on x86-64).
    Portable,
    /// The grid fast path with AVX2 and FMA (x86-64).
    Avx2,
    /// The grid fast path with AVX-512 F and VL (x86-64).
    Avx512,
}

impl Kernel {
    /// Every kernel, from the reference to the widest.
    pub const ALL: [Kernel; 4] = [Self::Reference, Self::Portable, Self::Avx2, Self::Avx512];

    /// Lower-case name (`reference`, `portable`, `avx2`, `avx512`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Reference => "reference",
            Self::Portable => "portable",
            Self::Avx2 => "avx2",
            Self::Avx512 => "avx512",
        }
    }

    /// Whether this CPU can run the kernel (inlined: every dispatch asks, and out of line its
    /// feature tests took about 1 % of a drape's samples).
    #[must_use]
    #[inline(always)]
    pub fn is_available(self) -> bool {
        match self {
            Self::Reference | Self::Portable => true,
            #[cfg(target_arch = "x86_64")]
            Self::Avx2 => avx2_fma(),
            #[cfg(target_arch = "x86_64")]
            Self::Avx512 => {
                avx2_fma()
                    && std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512vl")
            }
            #[cfg(not(target_arch = "x86_64"))]
            Self::Avx2 | Self::Avx512 => false,
        }
    }

    /// The widest kernel this CPU runs.
    #[must_use]
    pub fn best() -> Kernel {
        [Self::Avx512, Self::Avx2]
            .into_iter()
            .find(|k| k.is_available())
            .unwrap_or(Self::Portable)
    }
}

/// Whether the CPU has AVX2 and FMA, which both the AVX2 and the AVX-512 kernels need (a
/// function of its own, not a recursive `is_available`, so that every dispatch inlines it).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn avx2_fma() -> bool {
    std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
}

thread_local! {
    static CHOSEN: Cell<Option<Kernel>> = const { Cell::new(None) };
}

/// Chooses the kernel for the steps run **on this thread** (`None`: [`Kernel::best`], the
/// default). Every kernel gives the same results; this is for measuring and testing them.
///
/// # Errors
/// [`ClothError::InvalidArgument`] when this CPU cannot run `kernel`.
pub fn set_kernel(kernel: Option<Kernel>) -> Result<()> {
    if let Some(k) = kernel
        && !k.is_available()
    {
        return Err(ClothError::invalid(
            "kernel",
            k.name(),
            "a kernel this CPU supports",
        ));
    }
    choose(kernel);
    Ok(())
}

/// This thread's choice of kernel (`None`: the default).
pub(crate) fn chosen() -> Option<Kernel> {
    CHOSEN.with(Cell::get)
}

/// Makes `kernel` this thread's choice, returning the previous one (for a choice already
/// checked on the thread that made it: a step moved onto a pool thread keeps its caller's).
pub(crate) fn choose(kernel: Option<Kernel>) -> Option<Kernel> {
    CHOSEN.with(|c| c.replace(kernel))
}

/// The kernel the steps on this thread use.
#[must_use]
pub fn kernel() -> Kernel {
    chosen().unwrap_or_else(Kernel::best)
}

/// The kernel that steps `sim` on this thread: [`kernel`] when a grid fast path applies (an
/// explicit integrator or implicit Euler on a cloth built by [`crate::GridBuilder`], or XPBD
/// on such a cloth without self-collision or tethers to pins), [`Kernel::Reference`]
/// otherwise.
#[must_use]
pub fn kernel_for(sim: &crate::Simulation) -> Kernel {
    let k = kernel();
    let cfg = sim.config();
    let xpbd = cfg.integrator == crate::Integrator::Xpbd
        && k != Kernel::Reference
        && grid_xpbd::applies(cfg, sim.topology(), sim.particles().any_pinned());
    let implicit = cfg.integrator == crate::Integrator::ImplicitEuler
        && k != Kernel::Reference
        && grid::applies(sim.topology());
    if xpbd || implicit || grid_kernel::applies(k, cfg.integrator, sim.topology()) {
        k
    } else {
        Kernel::Reference
    }
}

/// A cache line's alignment, for [`align_frame`].
#[cfg(target_arch = "x86_64")]
#[repr(C, align(64))]
struct FrameAlign([u8; 64]);

/// Makes the function it is inlined into align its stack frame to 64 bytes (an over-aligned
/// local whose address escapes). The kernels spill whole vector registers, and in a frame
/// aligned to 16 bytes those slots straddle cache lines and, at some threads' stack offsets,
/// pages: on the peer scene the thread running one band spent 17 % of its kernel samples on
/// a single spill store that its twin, at another stack offset, did not (so 2 threads ran
/// 7 % under twice one). Called first in every `#[target_feature]` kernel below.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn align_frame() {
    let mut line = FrameAlign([0; 64]);
    std::hint::black_box(&mut line);
}

/// Defines `pub(crate) fn NAME(kernel: Kernel, args…)`, which runs the generic `GENERIC(args…)`
/// as compiled with AVX-512 F + VL (the function `AVX512`) or with AVX2 + FMA (`AVX2`) when
/// `kernel` asks for that instruction set and the CPU has it, else as compiled for the
/// baseline target. Both compiled copies start with [`align_frame`]. Written
/// `dispatched! { /// docs  fn NAME / AVX2 / AVX512(args…) -> Ret = GENERIC; }`, with optional
/// const parameters after the names (`fn NAME / AVX2 / AVX512 <const N: usize>(args…)`),
/// which `GENERIC` infers from the arguments. `= GENERIC, lanes = LANES;` runs instead
/// `LANES::<V8, consts…>(args…)` in the AVX2 copy and `LANES::<V16, consts…>(args…)` in the
/// AVX-512 one: a body written with the [`Lanes`] trait's intrinsics (an `unsafe fn` whose
/// contract is to run compiled with its lanes' instruction set, which each copy is); the
/// portable kernel still runs `GENERIC`.
macro_rules! dispatched {
    (
        $(#[$attr:meta])*
        fn $name:ident / $avx2:ident / $avx512:ident
            $(<$(const $c:ident: $cty:ty),*>)? ($($arg:ident: $ty:ty),* $(,)?)
            $(-> $ret:ty)? = $generic:path;
    ) => {
        dispatched! {
            @emit [$(#[$attr])*] $name $avx2 $avx512 [$($(const $c: $cty),*)?]
            ($($arg: $ty),*) [$($ret)?] $generic { $generic($($arg),*) }
        }
    };
    (
        $(#[$attr:meta])*
        fn $name:ident / $avx2:ident / $avx512:ident
            $(<$(const $c:ident: $cty:ty),*>)? ($($arg:ident: $ty:ty),* $(,)?)
            $(-> $ret:ty)? = $generic:path, lanes = $lanes:ident;
    ) => {
        dispatched! {
            @emit [$(#[$attr])*] $name $avx2 $avx512 [$($(const $c: $cty),*)?]
            ($($arg: $ty),*) [$($ret)?] $generic {
                // SAFETY: this copy is compiled with AVX2 (the lanes' operations need no more).
                unsafe { $lanes::<V8 $($(, $c)*)?>($($arg),*) }
            } {
                // SAFETY: this copy is compiled with AVX-512 F (the lanes' operations need no
                // more).
                unsafe { $lanes::<V16 $($(, $c)*)?>($($arg),*) }
            }
        }
    };
    (
        @emit [$(#[$attr:meta])*] $name:ident $avx2:ident $avx512:ident [$($gen:tt)*]
        ($($arg:ident: $ty:ty),*) [$($ret:ty)?] $generic:path { $($avx2_body:tt)* }
    ) => {
        dispatched! {
            @emit [$(#[$attr])*] $name $avx2 $avx512 [$($gen)*] ($($arg: $ty),*) [$($ret)?]
            $generic { $($avx2_body)* } { $generic($($arg),*) }
        }
    };
    (
        @emit [$(#[$attr:meta])*] $name:ident $avx2:ident $avx512:ident [$($gen:tt)*]
        ($($arg:ident: $ty:ty),*) [$($ret:ty)?] $generic:path { $($avx2_body:tt)* }
        { $($avx512_body:tt)* }
    ) => {
        $(#[$attr])*
        pub(crate) fn $name<$($gen)*>(kernel: Kernel, $($arg: $ty),*) $(-> $ret)? {
            match kernel {
                #[cfg(target_arch = "x86_64")]
                Kernel::Avx512 if Kernel::Avx512.is_available() => {
                    // SAFETY: the CPU has every feature the AVX-512 copy is compiled with
                    // (checked on the line above).
                    unsafe { $avx512($($arg),*) }
                }
                #[cfg(target_arch = "x86_64")]
                Kernel::Avx2 if Kernel::Avx2.is_available() => {
                    // SAFETY: the CPU has every feature the AVX2 copy is compiled with
                    // (checked on the line above).
                    unsafe { $avx2($($arg),*) }
                }
                _ => $generic($($arg),*),
            }
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2,fma")]
        fn $avx2<$($gen)*>($($arg: $ty),*) $(-> $ret)? {
            align_frame();
            $($avx2_body)*
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx512f,avx512vl,avx2,fma")]
        fn $avx512<$($gen)*>($($arg: $ty),*) $(-> $ret)? {
            align_frame();
            $($avx512_body)*
        }
    };
}

dispatched! {
    /// [`grid::band`] (a band of implicit Euler's product A·p) compiled for `kernel`.
    fn implicit_band / implicit_band_avx2 / implicit_band_avx512(
        job: &grid::BandJob<'_>,
        r0: usize,
        y: [&mut [f32]; 3],
        dots: &mut [f32],
        ring: &mut [f32],
    ) = grid::band;
}

dispatched! {
    /// [`grid::update`] (implicit Euler's CG update; `out` is Δv, r and s) compiled for
    /// `kernel`.
    fn implicit_update / implicit_update_avx2 / implicit_update_avx512(
        alpha: f32,
        out: [[&mut [f32]; 3]; 3],
        c: [&[f32]; 3],
        q: [&[f32]; 3],
        m: [&[f32]; 9],
        dots: &mut [f32],
    ) = grid::update;
}

dispatched! {
    /// [`grid::direction`] (implicit Euler's next CG direction) compiled for `kernel`.
    fn implicit_direction / implicit_direction_avx2 / implicit_direction_avx512(
        beta: f32,
        c: [&mut [f32]; 3],
        s: [&[f32]; 3],
        kind: &[u8],
        normal: [&[f32]; 3],
    ) = grid::direction;
}

dispatched! {
    /// Runs one band of the grid fast path with `kernel`.
    fn run_band / band_avx2 / band_avx512(
        job: &Job<'_>,
        r0: usize,
        r1: usize,
        band: &mut Band,
        dest: Dest<'_>,
    ) -> BandResult = grid_kernel::band;
}

/// One row of the explicit grid fast path, as [`fused_row`] computes it: the old state's rows
/// and the row's parameters.
pub(crate) struct FusedRow<'a> {
    /// The row, the grid's rows and columns.
    pub s: usize,
    pub rows: usize,
    pub cols: usize,
    /// Substep (s), gravity by component (m/s²), damping coefficient (N·s/m).
    pub h: f32,
    pub gravity: [f32; 3],
    pub damping: f32,
    /// Stiffness and damping per spring class (`None`: the class contributes nothing).
    pub params: [Option<(f32, f32)>; 6],
    /// Row `s`'s rest lengths per class (whole chunks of 16 lanes; empty for a class the row
    /// does not have).
    pub rest: [&'a [f32]; 6],
    /// Row `s`'s masses and inverse masses (`cols` each).
    pub mass: &'a [f32],
    pub inv_mass: &'a [f32],
    /// Rows `s`, `s + 1`, `s + 2` of the old state (x, y, z, vx, vy, vz; another row in place
    /// of a row the grid does not have), each component readable for whole chunks of 16
    /// lanes and two lanes more.
    pub state: [[&'a [f32]; 6]; 3],
}

/// The force rings of a band, by class, ring slot and component (see `grid_kernel::Band`).
pub(crate) type ForceRing = [[[Vec<f32>; 3]; 3]; 6];

/// Proof that [`fused_row`] can run, and with which instruction set: the AVX-512 or AVX2
/// kernel was chosen and this CPU has it (made only by [`Fused::detect`], so a row needs no
/// check of its own).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Fused {
    avx512: bool,
}

impl Fused {
    /// The proof, when `kernel` is [`Kernel::Avx512`] or [`Kernel::Avx2`] and this CPU runs
    /// it.
    pub(crate) fn detect(kernel: Kernel) -> Option<Self> {
        let wide = matches!(kernel, Kernel::Avx512 | Kernel::Avx2);
        (cfg!(target_arch = "x86_64") && wide && kernel.is_available()).then_some(Self {
            avx512: kernel == Kernel::Avx512,
        })
    }
}

/// One row of the explicit grid fast path with all six spring classes per chunk of
/// particles (16 with AVX-512, 8 with AVX2): each chunk computes its springs, keeps the row's
/// own terms in registers (the shifted ones by lane rotation from the previous chunk), stores
/// only the forces later rows read (warp, both diagonals, vertical bend) into the ring, and
/// integrates at once, with the reference's operations in its order (the same bits as
/// `grid_kernel::particle_row` after `grid_kernel::springs`). With `out` `None` (a band's
/// halo rows) only the ring is written. Returns whether a spring of the row had zero length.
///
/// # Panics
/// When a row is shorter than documented in [`FusedRow`].
pub(crate) fn fused_row<const S: u8>(
    proof: Fused,
    row: &FusedRow<'_>,
    force: &mut ForceRing,
    out: Option<&mut [&mut [f32]; 6]>,
) -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: the CPU has the features of the kernel the proof names (`Fused::detect`).
        unsafe {
            if proof.avx512 {
                fused_row_avx512::<S>(row, force, out)
            } else {
                fused_row_avx2::<S>(row, force, out)
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (proof, row, force, out);
        unreachable!("`Fused::detect` gives no proof off x86-64")
    }
}

/// [`fused_row`] on AVX-512 (16 lanes).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx2,fma")]
fn fused_row_avx512<const S: u8>(
    row: &FusedRow<'_>,
    force: &mut ForceRing,
    out: Option<&mut [&mut [f32]; 6]>,
) -> bool {
    align_frame();
    // SAFETY: compiled with AVX-512 F (the lanes' operations need no more).
    unsafe { fused_lanes::<V16, S>(row, force, out) }
}

/// [`fused_row`] on AVX2 (8 lanes).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn fused_row_avx2<const S: u8>(
    row: &FusedRow<'_>,
    force: &mut ForceRing,
    out: Option<&mut [&mut [f32]; 6]>,
) -> bool {
    align_frame();
    // SAFETY: compiled with AVX2 (the lanes' operations need no more).
    unsafe { fused_lanes::<V8, S>(row, force, out) }
}

/// The vector operations [`fused_lanes`] uses, for one instruction set: IEEE operations lane
/// by lane (the same bits as the compiled scalar code), loads and stores, masks of the first
/// lanes of a chunk, and the lane rotations of the shifted terms.
///
/// # Safety
/// Every method runs that instruction set's intrinsics: call them only from code compiled
/// with its features, on a CPU that has them; the pointer methods read or write `N` floats
/// (the masked ones only the mask's lanes).
#[cfg(target_arch = "x86_64")]
unsafe trait Lanes: Copy {
    /// Lanes per vector.
    const N: usize;
    /// The first `k` lanes of a chunk.
    type Mask: Copy;
    unsafe fn splat(x: f32) -> Self;
    unsafe fn load(p: *const f32) -> Self;
    unsafe fn store(p: *mut f32, v: Self);
    /// The mask's lanes of `p`, zero elsewhere (the others are not read).
    unsafe fn load_masked(m: Self::Mask, p: *const f32) -> Self;
    /// Writes the mask's lanes only.
    unsafe fn store_masked(p: *mut f32, m: Self::Mask, v: Self);
    unsafe fn add(a: Self, b: Self) -> Self;
    unsafe fn sub(a: Self, b: Self) -> Self;
    unsafe fn mul(a: Self, b: Self) -> Self;
    unsafe fn div(a: Self, b: Self) -> Self;
    unsafe fn sqrt(a: Self) -> Self;
    /// The lanes `c0 ..` below `lim`.
    unsafe fn first(c0: usize, lim: usize) -> Self::Mask;
    /// Whether the mask holds every lane.
    unsafe fn all(m: Self::Mask) -> bool;
    /// `v` in the mask's lanes, `back` elsewhere.
    unsafe fn select(m: Self::Mask, v: Self, back: Self) -> Self;
    /// Whether some lane of the mask has a squared length `len2 < forces::ZERO_LENGTH_SQUARED` (a
    /// spring of zero length to the reference; false for NaN).
    unsafe fn short(len2: Self, m: Self::Mask) -> bool;
    /// `cur` moved up by one lane, lane 0 from `prev`'s last.
    unsafe fn shift1(prev: Self, cur: Self) -> Self;
    /// Lanes where `a > b` (false for NaN).
    unsafe fn gt(a: Self, b: Self) -> Self::Mask;
    /// Lanes where `a >= b` (false for NaN).
    unsafe fn ge(a: Self, b: Self) -> Self::Mask;
    /// Lanes in both masks.
    unsafe fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// Bitwise exclusive or (with `-0.0`: the negation).
    unsafe fn xor(a: Self, b: Self) -> Self;
    /// `cur` moved up by two lanes, lanes 0 and 1 from `prev`'s last two.
    unsafe fn shift2(prev: Self, cur: Self) -> Self;
}

/// 16 lanes of AVX-512.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct V16(std::arch::x86_64::__m512);

#[cfg(target_arch = "x86_64")]
// SAFETY: AVX-512 F intrinsics only (see the trait).
unsafe impl Lanes for V16 {
    const N: usize = 16;
    type Mask = std::arch::x86_64::__mmask16;
    #[inline(always)]
    unsafe fn splat(x: f32) -> Self {
        Self(unsafe { std::arch::x86_64::_mm512_set1_ps(x) })
    }
    #[inline(always)]
    unsafe fn load(p: *const f32) -> Self {
        Self(unsafe { std::arch::x86_64::_mm512_loadu_ps(p) })
    }
    #[inline(always)]
    unsafe fn store(p: *mut f32, v: Self) {
        unsafe { std::arch::x86_64::_mm512_storeu_ps(p, v.0) }
    }
    #[inline(always)]
    unsafe fn load_masked(m: Self::Mask, p: *const f32) -> Self {
        Self(unsafe { std::arch::x86_64::_mm512_maskz_loadu_ps(m, p) })
    }
    #[inline(always)]
    unsafe fn store_masked(p: *mut f32, m: Self::Mask, v: Self) {
        unsafe { std::arch::x86_64::_mm512_mask_storeu_ps(p, m, v.0) }
    }
    #[inline(always)]
    unsafe fn add(a: Self, b: Self) -> Self {
        Self(unsafe { std::arch::x86_64::_mm512_add_ps(a.0, b.0) })
    }
    #[inline(always)]
    unsafe fn sub(a: Self, b: Self) -> Self {
        Self(unsafe { std::arch::x86_64::_mm512_sub_ps(a.0, b.0) })
    }
    #[inline(always)]
    unsafe fn mul(a: Self, b: Self) -> Self {
        Self(unsafe { std::arch::x86_64::_mm512_mul_ps(a.0, b.0) })
    }
    #[inline(always)]
    unsafe fn div(a: Self, b: Self) -> Self {
        Self(unsafe { std::arch::x86_64::_mm512_div_ps(a.0, b.0) })
    }
    #[inline(always)]
    unsafe fn sqrt(a: Self) -> Self {
        Self(unsafe { std::arch::x86_64::_mm512_sqrt_ps(a.0) })
    }
    #[inline(always)]
    unsafe fn first(c0: usize, lim: usize) -> Self::Mask {
        if c0 + 16 <= lim {
            0xFFFF
        } else if c0 >= lim {
            0
        } else {
            (1u16 << (lim - c0)) - 1
        }
    }
    #[inline(always)]
    unsafe fn all(m: Self::Mask) -> bool {
        m == 0xFFFF
    }
    #[inline(always)]
    unsafe fn select(m: Self::Mask, v: Self, back: Self) -> Self {
        Self(unsafe { std::arch::x86_64::_mm512_mask_blend_ps(m, back.0, v.0) })
    }
    #[inline(always)]
    unsafe fn short(len2: Self, m: Self::Mask) -> bool {
        use std::arch::x86_64::{_CMP_LT_OQ, _mm512_cmp_ps_mask, _mm512_set1_ps};
        unsafe {
            _mm512_cmp_ps_mask::<_CMP_LT_OQ>(
                len2.0,
                _mm512_set1_ps(crate::forces::ZERO_LENGTH_SQUARED),
            ) & m
                != 0
        }
    }
    #[inline(always)]
    unsafe fn gt(a: Self, b: Self) -> Self::Mask {
        use std::arch::x86_64::{_CMP_GT_OQ, _mm512_cmp_ps_mask};
        unsafe { _mm512_cmp_ps_mask::<_CMP_GT_OQ>(a.0, b.0) }
    }
    #[inline(always)]
    unsafe fn ge(a: Self, b: Self) -> Self::Mask {
        use std::arch::x86_64::{_CMP_GE_OQ, _mm512_cmp_ps_mask};
        unsafe { _mm512_cmp_ps_mask::<_CMP_GE_OQ>(a.0, b.0) }
    }
    #[inline(always)]
    unsafe fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        a & b
    }
    #[inline(always)]
    unsafe fn xor(a: Self, b: Self) -> Self {
        use std::arch::x86_64::{_mm512_castps_si512, _mm512_castsi512_ps, _mm512_xor_si512};
        Self(unsafe {
            _mm512_castsi512_ps(_mm512_xor_si512(
                _mm512_castps_si512(a.0),
                _mm512_castps_si512(b.0),
            ))
        })
    }
    #[inline(always)]
    unsafe fn shift1(prev: Self, cur: Self) -> Self {
        use std::arch::x86_64::{_mm512_alignr_epi32, _mm512_castps_si512, _mm512_castsi512_ps};
        Self(unsafe {
            _mm512_castsi512_ps(_mm512_alignr_epi32::<15>(
                _mm512_castps_si512(cur.0),
                _mm512_castps_si512(prev.0),
            ))
        })
    }
    #[inline(always)]
    unsafe fn shift2(prev: Self, cur: Self) -> Self {
        use std::arch::x86_64::{_mm512_alignr_epi32, _mm512_castps_si512, _mm512_castsi512_ps};
        Self(unsafe {
            _mm512_castsi512_ps(_mm512_alignr_epi32::<14>(
                _mm512_castps_si512(cur.0),
                _mm512_castps_si512(prev.0),
            ))
        })
    }
}

/// 8 lanes of AVX2 (masks as vectors whose lanes are all ones or zero).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct V8(std::arch::x86_64::__m256);

#[cfg(target_arch = "x86_64")]
// SAFETY: AVX and AVX2 intrinsics only (see the trait).
unsafe impl Lanes for V8 {
    const N: usize = 8;
    type Mask = std::arch::x86_64::__m256i;
    #[inline(always)]
    unsafe fn splat(x: f32) -> Self {
        Self(unsafe { std::arch::x86_64::_mm256_set1_ps(x) })
    }
    #[inline(always)]
    unsafe fn load(p: *const f32) -> Self {
        Self(unsafe { std::arch::x86_64::_mm256_loadu_ps(p) })
    }
    #[inline(always)]
    unsafe fn store(p: *mut f32, v: Self) {
        unsafe { std::arch::x86_64::_mm256_storeu_ps(p, v.0) }
    }
    #[inline(always)]
    unsafe fn load_masked(m: Self::Mask, p: *const f32) -> Self {
        Self(unsafe { std::arch::x86_64::_mm256_maskload_ps(p, m) })
    }
    #[inline(always)]
    unsafe fn store_masked(p: *mut f32, m: Self::Mask, v: Self) {
        unsafe { std::arch::x86_64::_mm256_maskstore_ps(p, m, v.0) }
    }
    #[inline(always)]
    unsafe fn add(a: Self, b: Self) -> Self {
        Self(unsafe { std::arch::x86_64::_mm256_add_ps(a.0, b.0) })
    }
    #[inline(always)]
    unsafe fn sub(a: Self, b: Self) -> Self {
        Self(unsafe { std::arch::x86_64::_mm256_sub_ps(a.0, b.0) })
    }
    #[inline(always)]
    unsafe fn mul(a: Self, b: Self) -> Self {
        Self(unsafe { std::arch::x86_64::_mm256_mul_ps(a.0, b.0) })
    }
    #[inline(always)]
    unsafe fn div(a: Self, b: Self) -> Self {
        Self(unsafe { std::arch::x86_64::_mm256_div_ps(a.0, b.0) })
    }
    #[inline(always)]
    unsafe fn sqrt(a: Self) -> Self {
        Self(unsafe { std::arch::x86_64::_mm256_sqrt_ps(a.0) })
    }
    #[inline(always)]
    unsafe fn first(c0: usize, lim: usize) -> Self::Mask {
        use std::arch::x86_64::{_mm256_cmpgt_epi32, _mm256_set1_epi32, _mm256_setr_epi32};
        // Lane j is live when j < lim − c0 (clamped to 0 ..= 8).
        let live = lim.saturating_sub(c0).min(8) as i32;
        unsafe {
            _mm256_cmpgt_epi32(
                _mm256_set1_epi32(live),
                _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7),
            )
        }
    }
    #[inline(always)]
    unsafe fn all(m: Self::Mask) -> bool {
        unsafe { std::arch::x86_64::_mm256_movemask_epi8(m) == -1 }
    }
    #[inline(always)]
    unsafe fn select(m: Self::Mask, v: Self, back: Self) -> Self {
        use std::arch::x86_64::{_mm256_blendv_ps, _mm256_castsi256_ps};
        Self(unsafe { _mm256_blendv_ps(back.0, v.0, _mm256_castsi256_ps(m)) })
    }
    #[inline(always)]
    unsafe fn short(len2: Self, m: Self::Mask) -> bool {
        use std::arch::x86_64::{
            _CMP_LT_OQ, _mm256_and_ps, _mm256_castsi256_ps, _mm256_cmp_ps, _mm256_movemask_ps,
            _mm256_set1_ps,
        };
        unsafe {
            let lt = _mm256_cmp_ps::<_CMP_LT_OQ>(
                len2.0,
                _mm256_set1_ps(crate::forces::ZERO_LENGTH_SQUARED),
            );
            _mm256_movemask_ps(_mm256_and_ps(lt, _mm256_castsi256_ps(m))) != 0
        }
    }
    #[inline(always)]
    unsafe fn gt(a: Self, b: Self) -> Self::Mask {
        use std::arch::x86_64::{_CMP_GT_OQ, _mm256_castps_si256, _mm256_cmp_ps};
        unsafe { _mm256_castps_si256(_mm256_cmp_ps::<_CMP_GT_OQ>(a.0, b.0)) }
    }
    #[inline(always)]
    unsafe fn ge(a: Self, b: Self) -> Self::Mask {
        use std::arch::x86_64::{_CMP_GE_OQ, _mm256_castps_si256, _mm256_cmp_ps};
        unsafe { _mm256_castps_si256(_mm256_cmp_ps::<_CMP_GE_OQ>(a.0, b.0)) }
    }
    #[inline(always)]
    unsafe fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        unsafe { std::arch::x86_64::_mm256_and_si256(a, b) }
    }
    #[inline(always)]
    unsafe fn xor(a: Self, b: Self) -> Self {
        Self(unsafe { std::arch::x86_64::_mm256_xor_ps(a.0, b.0) })
    }
    #[inline(always)]
    unsafe fn shift1(prev: Self, cur: Self) -> Self {
        use std::arch::x86_64::{
            _mm256_alignr_epi8, _mm256_castps_si256, _mm256_castsi256_ps, _mm256_permute2f128_ps,
        };
        // [prev's high half, cur's low half], then per 128-bit half the last float of the
        // lower operand and three of the upper: [prev₇, cur₀, cur₁, cur₂ | cur₃ … cur₆].
        unsafe {
            let mid = _mm256_permute2f128_ps::<0x21>(prev.0, cur.0);
            Self(_mm256_castsi256_ps(_mm256_alignr_epi8::<12>(
                _mm256_castps_si256(cur.0),
                _mm256_castps_si256(mid),
            )))
        }
    }
    #[inline(always)]
    unsafe fn shift2(prev: Self, cur: Self) -> Self {
        use std::arch::x86_64::{
            _mm256_alignr_epi8, _mm256_castps_si256, _mm256_castsi256_ps, _mm256_permute2f128_ps,
        };
        unsafe {
            let mid = _mm256_permute2f128_ps::<0x21>(prev.0, cur.0);
            Self(_mm256_castsi256_ps(_mm256_alignr_epi8::<8>(
                _mm256_castps_si256(cur.0),
                _mm256_castps_si256(mid),
            )))
        }
    }
}

/// [`fused_row`] on the lanes `V`.
///
/// # Safety
/// Only from a function compiled with `V`'s instruction set (see [`Lanes`]).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
#[allow(clippy::too_many_lines)]
unsafe fn fused_lanes<V: Lanes, const S: u8>(
    row: &FusedRow<'_>,
    force: &mut ForceRing,
    mut out: Option<&mut [&mut [f32]; 6]>,
) -> bool {
    use grid_kernel::{ANTI, BENDH, BENDV, DIAG, PAD, WARP, WEFT};
    let FusedRow {
        s,
        rows,
        cols,
        h,
        gravity,
        damping,
        params,
        rest,
        mass,
        inv_mass,
        state,
    } = *row;
    let n = V::N;
    let full = cols.next_multiple_of(n);
    let has1 = s + 1 < rows;
    let has2 = s + 2 < rows;
    // Which classes row s has, and which terms come from the rows above.
    let on = |class: usize| params[class].is_some();
    let own = [
        on(WARP) && has1,
        on(WEFT),
        on(DIAG) && has1,
        on(ANTI) && has1,
        on(BENDV) && has2,
        on(BENDH),
    ];
    let up_warp = on(WARP) && s >= 1;
    let up_diag = on(DIAG) && s >= 1;
    let up_anti = on(ANTI) && s >= 1;
    let up_bendv = on(BENDV) && s >= 2;
    // Every read and write below stays inside these lengths (checked once per row).
    for r in &state {
        for c in r {
            assert!(c.len() >= full + 2, "a state row shorter than its chunks");
        }
    }
    for (class, &o) in own.iter().enumerate() {
        assert!(
            !o || rest[class].len() >= full,
            "a rest row shorter than its chunks"
        );
    }
    assert!(
        mass.len() >= cols && inv_mass.len() >= cols,
        "a mass row shorter than the row"
    );
    if let Some(out) = &out {
        for c in out.iter() {
            assert!(c.len() >= cols, "an output row shorter than the row");
        }
    }
    for class in [WARP, DIAG, ANTI, BENDV] {
        for slot in &force[class] {
            for c in slot {
                assert!(c.len() >= PAD + full, "a force row shorter than its chunks");
            }
        }
    }
    let slot = s % 3;
    // The ring rows this row writes (its own slot) and reads (the rows above), per component,
    // from their column 0 (the diagonal's from column −1, in the front padding).
    let write = |force: &mut ForceRing, class: usize| -> [*mut f32; 3] {
        let [x, y, z] = &mut force[class][slot];
        [
            x.as_mut_ptr().wrapping_add(PAD),
            y.as_mut_ptr().wrapping_add(PAD),
            z.as_mut_ptr().wrapping_add(PAD),
        ]
    };
    let read = |force: &ForceRing, class: usize, r: usize, back: usize| -> [*const f32; 3] {
        let [x, y, z] = &force[class][r % 3];
        [
            x.as_ptr().wrapping_add(PAD - back),
            y.as_ptr().wrapping_add(PAD - back),
            z.as_ptr().wrapping_add(PAD - back),
        ]
    };
    let (w_warp, w_diag, w_anti, w_bendv) = (
        write(force, WARP),
        write(force, DIAG),
        write(force, ANTI),
        write(force, BENDV),
    );
    let r_warp = read(force, WARP, s.wrapping_sub(1), 0);
    let r_diag = read(force, DIAG, s.wrapping_sub(1), 1);
    let r_anti = read(force, ANTI, s.wrapping_sub(1), 0);
    let r_bendv = read(force, BENDV, s.wrapping_sub(2), 0);
    // SAFETY (of every vector operation below): this function runs compiled with `V`'s
    // instruction set (its contract); the loads and stores stay inside the lengths asserted
    // above (`c0 + N <= full`; state rows read up to two lanes past that).
    unsafe {
        let param = |class: usize| params[class].unwrap_or((0.0, 0.0));
        let (p_warp, p_weft, p_diag, p_anti, p_bendv, p_bendh) = (
            splat2::<V>(param(WARP)),
            splat2::<V>(param(WEFT)),
            splat2::<V>(param(DIAG)),
            splat2::<V>(param(ANTI)),
            splat2::<V>(param(BENDV)),
            splat2::<V>(param(BENDH)),
        );
        let zero = V::splat(0.0);
        let minus = V::splat(-0.0);
        let one = V::splat(1.0);
        let (hv, half, dv) = (V::splat(h), V::splat(0.5 * h), V::splat(damping));
        let g = [
            V::splat(gravity[0]),
            V::splat(gravity[1]),
            V::splat(gravity[2]),
        ];
        let [a, b, c] = state;
        // The ring's front padding, which the shifted terms of column 0 (and 1) read.
        let mut prev_weft = [zero; 3];
        let mut prev_anti = [minus; 3];
        let mut prev_bendh = [zero; 3];
        let mut bad = false;
        let mut c0 = 0;
        while c0 < cols {
            let (live0, live1, live2) = (
                V::first(c0, cols),
                V::first(c0, cols - 1),
                V::first(c0, cols.saturating_sub(2)),
            );
            let a0 = ends::<V>(&a, c0);
            let a1 = ends::<V>(&a, c0 + 1);
            // A whole chunk (every lane below `cols`) loads and stores plainly; the row's last,
            // partial chunk masks its lanes below `cols`. AVX2's masked store (`vmaskmovps`)
            // is slow on AMD's cores: the plain stores made the AVX2 row 7 % faster on a Zen 3.
            let whole = c0 + n <= cols;
            let (m, w) = if whole {
                (
                    V::load(mass.as_ptr().add(c0)),
                    V::load(inv_mass.as_ptr().add(c0)),
                )
            } else {
                (
                    V::load_masked(live0, mass.as_ptr().add(c0)),
                    V::load_masked(live0, inv_mass.as_ptr().add(c0)),
                )
            };
            // m·g − d·v, then the 12 spring terms in the reference's order (an absent term is
            // an exact identity, so it is skipped).
            let mut f = [
                V::sub(V::mul(m, g[0]), V::mul(dv, a0[3])),
                V::sub(V::mul(m, g[1]), V::mul(dv, a0[4])),
                V::sub(V::mul(m, g[2]), V::mul(dv, a0[5])),
            ];
            if up_warp {
                f = sub3(f, ring::<V>(r_warp, c0));
            }
            let b0 = if own[WARP] || own[ANTI] {
                ends::<V>(&b, c0)
            } else {
                a0
            };
            if own[WARP] {
                let (fw, len2) = spring(&a0, &b0, p_warp, load::<V>(rest[WARP], c0), one);
                bad |= V::short(len2, live0);
                f = add3(f, fw);
                store3(w_warp, c0, fw);
            }
            if own[WEFT] {
                let (fw, len2) = spring(&a0, &a1, p_weft, load::<V>(rest[WEFT], c0), one);
                bad |= V::short(len2, live1);
                let fw = pad(fw, live1, minus);
                f = add3(sub3(f, shifted1(prev_weft, fw)), fw);
                prev_weft = fw;
            }
            if up_diag {
                f = sub3(f, ring::<V>(r_diag, c0));
            }
            if up_anti {
                f = sub3(f, ring::<V>(r_anti, c0));
            }
            if own[ANTI] {
                let (fa, len2) = spring(&a1, &b0, p_anti, load::<V>(rest[ANTI], c0), one);
                bad |= V::short(len2, live1);
                let fa = pad(fa, live1, zero);
                f = add3(f, shifted1(prev_anti, fa));
                prev_anti = fa;
                store3(w_anti, c0, fa);
            }
            if own[DIAG] {
                let b1 = ends::<V>(&b, c0 + 1);
                let (fd, len2) = spring(&a0, &b1, p_diag, load::<V>(rest[DIAG], c0), one);
                bad |= V::short(len2, live1);
                let fd = pad(fd, live1, minus);
                f = add3(f, fd);
                store3(w_diag, c0, fd);
            }
            if up_bendv {
                f = sub3(f, ring::<V>(r_bendv, c0));
            }
            let mut bendh = None;
            if own[BENDH] {
                let a2 = ends::<V>(&a, c0 + 2);
                let (fb, len2) = spring(&a0, &a2, p_bendh, load::<V>(rest[BENDH], c0), one);
                bad |= V::short(len2, live2);
                let fb = pad(fb, live2, minus);
                f = sub3(f, shifted2(prev_bendh, fb));
                prev_bendh = fb;
                bendh = Some(fb);
            }
            if own[BENDV] {
                let c2 = ends::<V>(&c, c0);
                let (fb, len2) = spring(&a0, &c2, p_bendv, load::<V>(rest[BENDV], c0), one);
                bad |= V::short(len2, live0);
                f = add3(f, fb);
                store3(w_bendv, c0, fb);
            }
            if let Some(fb) = bendh {
                f = add3(f, fb);
            }
            if let Some(out) = &mut out {
                let hw = V::mul(hv, w);
                for k in 0..3 {
                    let (x, v) = (a0[k], a0[3 + k]);
                    let (nx, nv) = match S {
                        grid_kernel::FORWARD => {
                            (V::add(x, V::mul(hv, v)), V::add(v, V::mul(hw, f[k])))
                        }
                        grid_kernel::SYMPLECTIC => {
                            let nv = V::add(v, V::mul(hw, f[k]));
                            (V::add(x, V::mul(hv, nv)), nv)
                        }
                        _ => {
                            let nv = V::add(v, V::mul(hw, f[k]));
                            (V::add(x, V::mul(half, nv)), nv)
                        }
                    };
                    // Masked in a partial chunk: lanes below `cols` only, inside the output rows.
                    if whole {
                        V::store(out[k].as_mut_ptr().add(c0), nx);
                        V::store(out[3 + k].as_mut_ptr().add(c0), nv);
                    } else {
                        V::store_masked(out[k].as_mut_ptr().add(c0), live0, nx);
                        V::store_masked(out[3 + k].as_mut_ptr().add(c0), live0, nv);
                    }
                }
            }
            c0 += n;
        }
        bad
    }
}

/// Both numbers in every lane.
///
/// # Safety
/// As [`Lanes`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn splat2<V: Lanes>((k, c): (f32, f32)) -> (V, V) {
    unsafe { (V::splat(k), V::splat(c)) }
}

/// `N` floats of `v` from `i` ([`fused_lanes`]' helpers are functions, not closures: a
/// closure in a function without the instruction set's features would not get them, and
/// every intrinsic in it would be a call).
///
/// # Safety
/// As [`Lanes`]; `i + N <= v.len()`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn load<V: Lanes>(v: &[f32], i: usize) -> V {
    unsafe { V::load(v.as_ptr().add(i)) }
}

/// A chunk's ends (x, y, z, vx, vy, vz) from column `i` of a row.
///
/// # Safety
/// As [`load`] for every component.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn ends<V: Lanes>(r: &[&[f32]; 6], i: usize) -> [V; 6] {
    unsafe {
        [
            load(r[0], i),
            load(r[1], i),
            load(r[2], i),
            load(r[3], i),
            load(r[4], i),
            load(r[5], i),
        ]
    }
}

/// Spring plus dashpot from ends `a` to `b` (stiffness and damping `k`, `c`, rest length
/// `rest`), the reference's operations in its order (`forces::spring_force`): the force on
/// the first end, and the squared length.
///
/// # Safety
/// As [`Lanes`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn spring<V: Lanes>(a: &[V; 6], b: &[V; 6], (k, c): (V, V), rest: V, one: V) -> ([V; 3], V) {
    unsafe {
        let lx = V::sub(b[0], a[0]);
        let ly = V::sub(b[1], a[1]);
        let lz = V::sub(b[2], a[2]);
        let len2 = V::add(V::add(V::mul(lx, lx), V::mul(ly, ly)), V::mul(lz, lz));
        // The square root and the division both start from the squared length: neither
        // waits for the other (the row's latency; the same operations as the reference).
        let len = V::sqrt(len2);
        let inv2 = V::div(one, len2);
        let inv = V::mul(len, inv2);
        let (wx, wy, wz) = (V::sub(b[3], a[3]), V::sub(b[4], a[4]), V::sub(b[5], a[5]));
        let along = V::add(V::add(V::mul(wx, lx), V::mul(wy, ly)), V::mul(wz, lz));
        let per_length = V::add(
            V::mul(V::mul(k, V::sub(len, rest)), inv),
            V::mul(V::mul(c, along), inv2),
        );
        (
            [
                V::mul(per_length, lx),
                V::mul(per_length, ly),
                V::mul(per_length, lz),
            ],
            len2,
        )
    }
}

/// `f` in the live lanes, the class's padding value `back` past the row's springs.
///
/// # Safety
/// As [`Lanes`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn pad<V: Lanes>(f: [V; 3], live: V::Mask, back: V) -> [V; 3] {
    unsafe {
        if V::all(live) {
            f
        } else {
            [
                V::select(live, f[0], back),
                V::select(live, f[1], back),
                V::select(live, f[2], back),
            ]
        }
    }
}

/// Stores a force chunk at column `c0` of three ring rows.
///
/// # Safety
/// As [`Lanes`]; `N` floats from `p[k] + c0` writable.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn store3<V: Lanes>(p: [*mut f32; 3], c0: usize, f: [V; 3]) {
    unsafe {
        V::store(p[0].add(c0), f[0]);
        V::store(p[1].add(c0), f[1]);
        V::store(p[2].add(c0), f[2]);
    }
}

/// A vector at entry `c0` of each of three arrays: a force chunk at column `c0` of three ring
/// rows, or a position's or a direction's components at a chain block's entry.
///
/// # Safety
/// As [`Lanes`]; `N` floats from `p[k] + c0` readable.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn ring<V: Lanes>(p: [*const f32; 3], c0: usize) -> [V; 3] {
    unsafe {
        [
            V::load(p[0].add(c0)),
            V::load(p[1].add(c0)),
            V::load(p[2].add(c0)),
        ]
    }
}

/// `f − t` by component.
///
/// # Safety
/// As [`Lanes`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn sub3<V: Lanes>(f: [V; 3], t: [V; 3]) -> [V; 3] {
    unsafe { [V::sub(f[0], t[0]), V::sub(f[1], t[1]), V::sub(f[2], t[2])] }
}

/// `f + t` by component.
///
/// # Safety
/// As [`Lanes`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn add3<V: Lanes>(f: [V; 3], t: [V; 3]) -> [V; 3] {
    unsafe { [V::add(f[0], t[0]), V::add(f[1], t[1]), V::add(f[2], t[2])] }
}

/// [`Lanes::shift1`] by component.
///
/// # Safety
/// As [`Lanes`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn shifted1<V: Lanes>(prev: [V; 3], cur: [V; 3]) -> [V; 3] {
    unsafe {
        [
            V::shift1(prev[0], cur[0]),
            V::shift1(prev[1], cur[1]),
            V::shift1(prev[2], cur[2]),
        ]
    }
}

/// [`Lanes::shift2`] by component.
///
/// # Safety
/// As [`Lanes`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn shifted2<V: Lanes>(prev: [V; 3], cur: [V; 3]) -> [V; 3] {
    unsafe {
        [
            V::shift2(prev[0], cur[0]),
            V::shift2(prev[1], cur[1]),
            V::shift2(prev[2], cur[2]),
        ]
    }
}

/// One vertical pass's two rows of the grid XPBD path (see `solver::grid_xpbd`), with
/// `kernel` (the stepping thread's choice, passed on to the pool's workers): compliant pairs
/// with AVX-512 by [`pairs_avx512`] (the same bits as the compiled loop), else
/// [`grid_xpbd::pairs`] compiled for the kernel.
pub(crate) fn xpbd_pairs(
    kernel: Kernel,
    a: [&mut [f32]; 3],
    b: [&mut [f32]; 3],
    shared: &Shared<'_>,
    g: (usize, usize, usize),
    lambda: &mut [f32],
) {
    #[cfg(target_arch = "x86_64")]
    if kernel == Kernel::Avx512
        && Kernel::Avx512.is_available()
        && let Some(input) = shared.pairs_input(g, lambda.len())
    {
        // SAFETY: the CPU has AVX-512 F (checked above).
        unsafe { pairs_avx512(a, b, input, lambda) };
        return;
    }
    xpbd_pairs_compiled(kernel, a, b, shared, g, lambda);
}

dispatched! {
    /// [`grid_xpbd::pairs`] compiled for `kernel` ([`xpbd_pairs`] without its AVX-512 kernel).
    fn xpbd_pairs_compiled / pairs_compiled_avx2 / pairs_compiled_avx512(
        a: [&mut [f32]; 3],
        b: [&mut [f32]; 3],
        shared: &Shared<'_>,
        g: (usize, usize, usize),
        lambda: &mut [f32],
    ) = grid_xpbd::pairs;
}

/// [`xpbd_pairs`]' AVX-512 kernel for compliant pairs: 16 pairs `a[i]`–`b[i]` per vector,
/// the last `m mod 16` by masked loads and stores (the compiler's loop ran those as 4-wide
/// and scalar leftovers: about 30 % of its time on rows of 255 pairs), with
/// [`grid_xpbd::pairs`]' arithmetic in its order (the same bits). Whole vectors load and store
/// plainly: with masked loads and stores for every vector, the shear rows' passes (each row
/// read right after the row above wrote it) took a third more time, 0.41–0.42 of the chain
/// solve's samples against 0.27–0.28 at 512² (a load waits on an earlier masked store).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn pairs_avx512(
    a: [&mut [f32]; 3],
    b: [&mut [f32]; 3],
    input: grid_xpbd::PairsInput<'_>,
    lambda: &mut [f32],
) {
    use std::arch::x86_64::{
        __m512, __mmask16, _mm512_add_ps, _mm512_mask_storeu_ps, _mm512_maskz_loadu_ps,
        _mm512_mul_ps, _mm512_setzero_ps, _mm512_sub_ps,
    };
    align_frame();
    let grid_xpbd::PairsInput {
        prev_a,
        prev_b,
        wa,
        wb,
        rest,
        params,
        keep,
    } = input;
    let m = lambda.len();
    let [ax, ay, az] = a;
    let [bx, by, bz] = b;
    // Every slice holds at least `m` entries (checked here once: the loads and stores below
    // read and write lanes `i .. i + 16` of them under a mask that keeps only `i .. m`).
    for v in [&ax[..], &ay[..], &az[..], &bx[..], &by[..], &bz[..]] {
        assert!(v.len() >= m, "a row shorter than its pairs");
    }
    for v in prev_a.iter().chain(&prev_b).chain([&wa, &wb, &rest]) {
        assert!(v.len() >= m, "a row shorter than its pairs");
    }
    let zero = _mm512_setzero_ps();
    let load = |k: __mmask16, v: &[f32], i: usize| -> __m512 {
        // SAFETY: `v` holds at least `m` entries (asserted above) and the mask keeps lanes
        // below `m - i` only; masked-off lanes are not read.
        unsafe {
            if k == 0xFFFF {
                std::arch::x86_64::_mm512_loadu_ps(v.as_ptr().add(i))
            } else {
                _mm512_maskz_loadu_ps(k, v.as_ptr().add(i))
            }
        }
    };
    let store = |k: __mmask16, v: &mut [f32], i: usize, x: __m512| {
        // SAFETY: as for `load`: lanes below `m - i` only, inside `v`.
        unsafe {
            if k == 0xFFFF {
                std::arch::x86_64::_mm512_storeu_ps(v.as_mut_ptr().add(i), x);
            } else {
                _mm512_mask_storeu_ps(v.as_mut_ptr().add(i), k, x);
            }
        }
    };
    for i in (0..m).step_by(16) {
        let k: __mmask16 = if m - i >= 16 {
            0xFFFF
        } else {
            (1u16 << (m - i)) - 1
        };
        let (xa, ya, za) = (load(k, ax, i), load(k, ay, i), load(k, az, i));
        let (xb, yb, zb) = (load(k, bx, i), load(k, by, i), load(k, bz, i));
        let lam = if keep { load(k, lambda, i) } else { zero };
        let (wai, wbi) = (load(k, wa, i), load(k, wb, i));
        let (l, f, len) = pair_lanes(
            ([xa, ya, za], [xb, yb, zb]),
            (prev_a.map(|p| load(k, p, i)), prev_b.map(|p| load(k, p, i))),
            _mm512_add_ps(wai, wbi),
            load(k, rest, i),
            lam,
            params,
        );
        if keep {
            store(k, lambda, i, _mm512_add_ps(lam, _mm512_mul_ps(f, len)));
        }
        let (sa, sb) = (_mm512_mul_ps(wai, f), _mm512_mul_ps(wbi, f));
        for (va, vb, (pa, pb), l) in [
            (&mut *ax, &mut *bx, (xa, xb), l[0]),
            (&mut *ay, &mut *by, (ya, yb), l[1]),
            (&mut *az, &mut *bz, (za, zb), l[2]),
        ] {
            store(k, va, i, _mm512_add_ps(pa, _mm512_mul_ps(sa, l)));
            store(k, vb, i, _mm512_sub_ps(pb, _mm512_mul_ps(sb, l)));
        }
    }
}

dispatched! {
    /// One row of a horizontal pass of the grid XPBD path, with `kernel` (the stepping
    /// thread's choice, passed on to the pool's workers).
    #[allow(clippy::too_many_arguments)]
    fn xpbd_row / row_avx2 / row_avx512(
        x: [&mut [f32]; 3],
        corr: [&mut [f32]; 3],
        shared: &Shared<'_>,
        g0: usize,
        s: usize,
        lambda: &mut [f32],
        mask: &[f32],
    ) = grid_xpbd::row;
}

dispatched! {
    /// The velocities `v + (x − x_pred)/h` of one component of a row of the grid XPBD path
    /// ([`grid_xpbd::velocities`]), with `kernel`.
    fn xpbd_velocities / velocities_avx2 / velocities_avx512(
        v: &mut [f32],
        x: &[f32],
        x0: &[f32],
        w: &[f32],
        h: f32,
        inv_h: f32,
    ) = grid_xpbd::velocities;
}

dispatched! {
    /// One component of one row of the grid XPBD path's prediction
    /// ([`grid_xpbd::predict_lane`]), with `kernel`.
    fn xpbd_predict / predict_avx2 / predict_avx512(
        lane: &grid_xpbd::PredictLane<'_>,
        x: &mut [f32],
        v: &mut [f32],
        x0: &mut [f32],
        up: Option<[&[f32]; 2]>,
        down: Option<[&[f32]; 2]>,
    ) = grid_xpbd::predict_lane;
}

dispatched! {
    /// One-sided strain limits of pairs `a[i]`–`b[i]` of the grid XPBD path
    /// ([`grid_xpbd::limit_pairs`]), with `kernel`.
    fn xpbd_limit_pairs / limit_pairs_avx2 / limit_pairs_avx512(
        a: [&mut [f32]; 3],
        b: [&mut [f32]; 3],
        shared: &Shared<'_>,
        g: (usize, usize, usize),
        m: usize,
    ) = grid_xpbd::limit_pairs;
}

dispatched! {
    /// Both colours of a row of the structural limit's weft ([`grid_xpbd::limit_row_both`]),
    /// with `kernel`.
    fn xpbd_limit_row_both / limit_row_both_avx2 / limit_row_both_avx512(
        x: [&mut [f32]; 3],
        shared: &Shared<'_>,
        g: (usize, usize),
        masks: [&[f32]; 2],
    ) = grid_xpbd::limit_row_both;
}

dispatched! {
    /// One row of a horizontal pass of strain limits of the grid XPBD path
    /// ([`grid_xpbd::limit_row`]), with `kernel`.
    fn xpbd_limit_row / limit_row_avx2 / limit_row_avx512(
        x: [&mut [f32]; 3],
        shared: &Shared<'_>,
        g: (usize, usize),
        s: usize,
        mask: &[f32],
    ) = grid_xpbd::limit_row;
}

/// One row of a horizontal pass at spacing 2 of the grid XPBD path (pairs `(c, c + 2)`,
/// colour `⌊c / 2⌋ mod 2`, from column `first` = 2·colour; `m` slots), projected in place
/// with only the colour's pairs computed, when `kernel` is AVX-512 (and the CPU has it) and
/// the pass is compliant without kept multipliers; returns whether it ran (else the caller
/// runs the masked [`xpbd_row`], which computes every slot and keeps half). The same
/// arithmetic as the masked row, so the same bits.
pub(crate) fn xpbd_quads(
    kernel: Kernel,
    x: [&mut [f32]; 3],
    shared: &Shared<'_>,
    g0: usize,
    first: usize,
    m: usize,
) -> bool {
    #[cfg(target_arch = "x86_64")]
    if matches!(kernel, Kernel::Avx512 | Kernel::Avx2) && kernel.is_available() {
        let Some(grid_xpbd::QuadsInput {
            prev,
            w,
            rest,
            params,
        }) = shared.quads_input()
        else {
            return false;
        };
        if first < m {
            let g = g0 + first;
            let n = m + 2 - first;
            let [x, y, z] = x;
            let pos = [
                &mut x[first..][..n],
                &mut y[first..][..n],
                &mut z[first..][..n],
            ];
            let prev = prev.map(|p| &p[g..][..n]);
            let (w, rest, m) = (&w[g..][..n], &rest[shared.rest_slot(g)..][..n], m - first);
            if kernel == Kernel::Avx512 {
                // SAFETY: the CPU has AVX-512 F (checked above).
                unsafe { quads_avx512(pos, prev, w, rest, m, params) };
            } else {
                // SAFETY: the CPU has AVX2 and FMA (checked above).
                unsafe { quads_avx2(pos, prev, w, rest, m, params) };
            }
        }
        return true;
    }
    let _ = (kernel, x, shared, g0, first, m);
    false
}

/// `grid_xpbd::pair_correction` for 16 compliant pairs in AVX-512 lanes, its operations in its
/// order (the same bits): from the ends' positions `(a, b)` and start positions, `wsum =
/// w_a + w_b`, the rest lengths and the multipliers, the pairs' `l = a − b`, the factor
/// `f = s` (zero where a pair does not move) and `|l|`. Shared by [`pairs_avx512`] and
/// [`quads_avx512`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
fn pair_lanes(
    (a, b): (
        [std::arch::x86_64::__m512; 3],
        [std::arch::x86_64::__m512; 3],
    ),
    (pa, pb): (
        [std::arch::x86_64::__m512; 3],
        [std::arch::x86_64::__m512; 3],
    ),
    wsum: std::arch::x86_64::__m512,
    rest: std::arch::x86_64::__m512,
    lambda: std::arch::x86_64::__m512,
    (alpha, gamma): (f32, f32),
) -> (
    [std::arch::x86_64::__m512; 3],
    std::arch::x86_64::__m512,
    std::arch::x86_64::__m512,
) {
    use std::arch::x86_64::{
        _CMP_GT_OQ, _mm512_add_ps, _mm512_cmp_ps_mask, _mm512_mask_cmp_ps_mask,
        _mm512_maskz_div_ps, _mm512_mul_ps, _mm512_set1_ps, _mm512_setzero_ps, _mm512_sqrt_ps,
        _mm512_sub_ps,
    };
    let (alpha, gamma) = (_mm512_set1_ps(alpha), _mm512_set1_ps(gamma));
    let zero = _mm512_setzero_ps();
    let l: [_; 3] = std::array::from_fn(|c| _mm512_sub_ps(a[c], b[c]));
    let d: [_; 3] = std::array::from_fn(|c| {
        _mm512_sub_ps(_mm512_sub_ps(a[c], pa[c]), _mm512_sub_ps(b[c], pb[c]))
    });
    let len2 = _mm512_add_ps(
        _mm512_add_ps(_mm512_mul_ps(l[0], l[0]), _mm512_mul_ps(l[1], l[1])),
        _mm512_mul_ps(l[2], l[2]),
    );
    let len = _mm512_sqrt_ps(len2);
    let ok = _mm512_mask_cmp_ps_mask::<_CMP_GT_OQ>(
        _mm512_cmp_ps_mask::<_CMP_GT_OQ>(wsum, zero),
        len,
        zero,
    );
    let constraint = _mm512_sub_ps(len, rest);
    let ld = _mm512_add_ps(
        _mm512_add_ps(_mm512_mul_ps(l[0], d[0]), _mm512_mul_ps(l[1], d[1])),
        _mm512_mul_ps(l[2], d[2]),
    );
    // s = ((−C − α̃·λ)·|l| − γ·(l·d)) / (((1 + γ)·wsum + α̃)·|l|²), zero where not `ok`;
    // −C is computed as −0 − C, the same bits as a negation for every C.
    let num = _mm512_sub_ps(
        _mm512_mul_ps(
            _mm512_sub_ps(
                _mm512_sub_ps(_mm512_set1_ps(-0.0), constraint),
                _mm512_mul_ps(alpha, lambda),
            ),
            len,
        ),
        _mm512_mul_ps(gamma, ld),
    );
    let one_gamma = _mm512_add_ps(_mm512_set1_ps(1.0), gamma);
    let den = _mm512_mul_ps(_mm512_add_ps(_mm512_mul_ps(one_gamma, wsum), alpha), len2);
    (l, _mm512_maskz_div_ps(ok, num, den), len)
}

/// [`xpbd_quads`]' AVX-512 kernel: spans of 32 columns (eight groups of four) as two vectors
/// per field, the groups' columns 0, 1 and 2, 3 split into 16 lanes `a` and 16 lanes `b` by
/// two-source permutes, one pair per lane; the last span by masked loads and stores (only the
/// row's columns), its lanes past the row's pairs computed on zeros and left as they were.
/// Every row slice starts at the colour's first column and holds `m + 2` entries.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn quads_avx512(
    [x, y, z]: [&mut [f32]; 3],
    [px, py, pz]: [&[f32]; 3],
    w: &[f32],
    rest: &[f32],
    m: usize,
    params: (f32, f32),
) {
    use std::arch::x86_64::{
        __m512, __m512i, __mmask16, _mm512_add_ps, _mm512_mask_blend_ps, _mm512_mask_storeu_ps,
        _mm512_maskz_loadu_ps, _mm512_mul_ps, _mm512_permutex2var_ps, _mm512_setr_epi32,
        _mm512_setzero_ps, _mm512_sub_ps,
    };
    const SPAN: usize = 32;
    align_frame();
    let n = m + 2;
    // Lanes `a`: columns 4g, 4g + 1 of the span's eight groups; lanes `b`: 4g + 2, 4g + 3.
    let ia: __m512i = _mm512_setr_epi32(0, 1, 4, 5, 8, 9, 12, 13, 16, 17, 20, 21, 24, 25, 28, 29);
    let ib: __m512i = _mm512_setr_epi32(2, 3, 6, 7, 10, 11, 14, 15, 18, 19, 22, 23, 26, 27, 30, 31);
    // Back: the span's first 16 columns from lanes a 0..8 and b 0..8, the last from 8..16.
    let lo: __m512i = _mm512_setr_epi32(0, 1, 16, 17, 2, 3, 18, 19, 4, 5, 20, 21, 6, 7, 22, 23);
    let hi: __m512i =
        _mm512_setr_epi32(8, 9, 24, 25, 10, 11, 26, 27, 12, 13, 28, 29, 14, 15, 30, 31);
    // Every slice holds at least `n` entries (checked here once: the loads and stores below
    // touch the span's columns below `n` only, by their masks).
    for v in [&x[..], &y[..], &z[..], px, py, pz, w, rest] {
        assert!(v.len() >= n, "a row shorter than its span");
    }
    // The span at `at`'s columns below `n`: masks of its two halves.
    let columns = |at: usize| -> (__mmask16, __mmask16) {
        let keep = |from: usize| match n.saturating_sub(at + from) {
            0 => 0,
            r if r >= 16 => 0xFFFF,
            r => (1u16 << r) - 1,
        };
        (keep(0), keep(16))
    };
    let load = |v: &[f32], at: usize, (k0, k1): (__mmask16, __mmask16)| -> (__m512, __m512) {
        // SAFETY: the masks keep the columns below `n` only, inside `v` (asserted above).
        let (v0, v1) = unsafe {
            (
                _mm512_maskz_loadu_ps(k0, v.as_ptr().add(at)),
                _mm512_maskz_loadu_ps(k1, v.as_ptr().add(at + 16)),
            )
        };
        (
            _mm512_permutex2var_ps(v0, ia, v1),
            _mm512_permutex2var_ps(v0, ib, v1),
        )
    };
    let store =
        |v: &mut [f32], at: usize, (k0, k1): (__mmask16, __mmask16), a: __m512, b: __m512| {
            let (v0, v1) = (
                _mm512_permutex2var_ps(a, lo, b),
                _mm512_permutex2var_ps(a, hi, b),
            );
            // SAFETY: as for `load`: the columns below `n` only, inside `v`.
            unsafe {
                _mm512_mask_storeu_ps(v.as_mut_ptr().add(at), k0, v0);
                _mm512_mask_storeu_ps(v.as_mut_ptr().add(at + 16), k1, v1);
            }
        };
    let zero = _mm512_setzero_ps();
    for q in 0..n.div_ceil(SPAN) {
        let at = q * SPAN;
        let k = columns(at);
        // The span's pairs `(i, i + 2)` with `i < m` (every pair of a whole span; the last
        // span's lanes past them are computed on zeros and left unwritten).
        let pairs: __mmask16 = if at + SPAN <= n {
            0xFFFF
        } else {
            (0..16).fold(0, |mask, lane| {
                let i = at + 4 * (lane / 2) + lane % 2;
                if i < m { mask | (1 << lane) } else { mask }
            })
        };
        let (xa, xb) = load(x, at, k);
        let (ya, yb) = load(y, at, k);
        let (za, zb) = load(z, at, k);
        let (pxa, pxb) = load(px, at, k);
        let (pya, pyb) = load(py, at, k);
        let (pza, pzb) = load(pz, at, k);
        let (wa, wb) = load(w, at, k);
        // Rest lengths by slot: the first ends' lanes only.
        let (ra, _) = load(rest, at, k);
        let (l, f, _) = pair_lanes(
            ([xa, ya, za], [xb, yb, zb]),
            ([pxa, pya, pza], [pxb, pyb, pzb]),
            _mm512_add_ps(wa, wb),
            ra,
            zero,
            params,
        );
        for (v, (a, b), l) in [
            (&mut *x, (xa, xb), l[0]),
            (&mut *y, (ya, yb), l[1]),
            (&mut *z, (za, zb), l[2]),
        ] {
            let c = _mm512_mul_ps(f, l);
            // Ends of the span's pairs past `m` keep their values (bit for bit: adding a zero
            // correction would turn −0 into +0).
            let a = _mm512_mask_blend_ps(pairs, a, _mm512_add_ps(a, _mm512_mul_ps(wa, c)));
            let b = _mm512_mask_blend_ps(pairs, b, _mm512_sub_ps(b, _mm512_mul_ps(wb, c)));
            store(v, at, k, a, b);
        }
    }
}

/// `grid_xpbd::pair_correction` for compliant pairs without kept multipliers (`λ = 0`, as
/// the quads run) on the lanes `V`, its operations in its order (the same bits): from the
/// ends' positions `(a, b)` and start positions `(pa, pb)`, `wsum = w_a + w_b` and the rest
/// lengths, the pairs' `l = a − b` and the factor `s` (zero where a pair does not move: both
/// ends pinned, or zero length). Used by [`quads_avx2`] (the AVX-512 kernels have
/// [`pair_lanes`]).
///
/// # Safety
/// As [`Lanes`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn pair_factor<V: Lanes>(
    (a, b): ([V; 3], [V; 3]),
    (pa, pb): ([V; 3], [V; 3]),
    wsum: V,
    rest: V,
    (alpha, gamma): (f32, f32),
) -> ([V; 3], V) {
    unsafe {
        let zero = V::splat(0.0);
        let (alpha_v, gamma_v) = (V::splat(alpha), V::splat(gamma));
        let l = [V::sub(a[0], b[0]), V::sub(a[1], b[1]), V::sub(a[2], b[2])];
        let d = [
            V::sub(V::sub(a[0], pa[0]), V::sub(b[0], pb[0])),
            V::sub(V::sub(a[1], pa[1]), V::sub(b[1], pb[1])),
            V::sub(V::sub(a[2], pa[2]), V::sub(b[2], pb[2])),
        ];
        let len2 = V::add(
            V::add(V::mul(l[0], l[0]), V::mul(l[1], l[1])),
            V::mul(l[2], l[2]),
        );
        let len = V::sqrt(len2);
        let ok = V::and(V::gt(wsum, zero), V::gt(len, zero));
        let constraint = V::sub(len, rest);
        let ld = V::add(
            V::add(V::mul(l[0], d[0]), V::mul(l[1], d[1])),
            V::mul(l[2], d[2]),
        );
        // s = ((−C − α̃·λ)·|l| − γ·(l·d)) / (((1 + γ)·wsum + α̃)·|l|²) with λ = 0; +0 where
        // not `ok` (the scalar code's mask of the bits); −C as a flip of the sign bit, as `-x`
        // is. The product α̃·0 is not dead: a positive stiffness so small that k·h² is 0 gives
        // α̃ = ∞, and ∞·0 is NaN in the scalar code too, so it stays for the same bits.
        let num = V::sub(
            V::mul(
                V::sub(V::xor(constraint, V::splat(-0.0)), V::mul(alpha_v, zero)),
                len,
            ),
            V::mul(gamma_v, ld),
        );
        let den = V::mul(V::add(V::mul(V::splat(1.0 + gamma), wsum), alpha_v), len2);
        (l, V::select(ok, V::div(num, den), zero))
    }
}

/// 8 floats of `v` from `i`: plainly for a whole vector, else the `live` lanes (zero in the
/// others, which are not read).
///
/// # Safety
/// As [`Lanes`]; `i + 8 <= v.len()` when `whole`, else `live` keeps only lanes inside `v`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn lanes_at(v: &[f32], i: usize, whole: bool, live: <V8 as Lanes>::Mask) -> V8 {
    unsafe {
        if whole {
            V8::load(v.as_ptr().add(i))
        } else {
            // (A span's second half may start past `v`: no lane of it is read then.)
            V8::load_masked(live, v.as_ptr().wrapping_add(i))
        }
    }
}

/// Writes 8 floats of `v` from `i`: plainly for a whole vector, else the `live` lanes only.
///
/// # Safety
/// As [`lanes_at`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn put_lanes(v: &mut [f32], i: usize, whole: bool, live: <V8 as Lanes>::Mask, x: V8) {
    unsafe {
        if whole {
            V8::store(v.as_mut_ptr().add(i), x);
        } else {
            V8::store_masked(v.as_mut_ptr().wrapping_add(i), live, x);
        }
    }
}

/// [`xpbd_quads`]' AVX2 kernel: spans of 16 columns (four groups of four) as two vectors per
/// field, the groups' columns 0, 1 (lanes `a`) and 2, 3 (lanes `b`) split apart by one
/// in-lane shuffle each (`vshufps`: lanes `a` hold columns 0, 1, 8, 9, 4, 5, 12, 13 of the
/// span, lanes `b` two further), one pair per lane; the last span by masked loads and stores
/// (only the row's columns), its lanes past the row's pairs computed on zeros and left as they
/// were. Every row slice starts at the colour's first column and holds `m + 2` entries. The
/// masked row it replaces computes every slot and keeps half.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn quads_avx2(
    [x, y, z]: [&mut [f32]; 3],
    [px, py, pz]: [&[f32]; 3],
    w: &[f32],
    rest: &[f32],
    m: usize,
    params: (f32, f32),
) {
    use std::arch::x86_64::{_mm256_cmpgt_epi32, _mm256_set1_epi32, _mm256_setr_epi32};
    const SPAN: usize = 16;
    align_frame();
    let n = m + 2;
    // Every slice holds at least `n` entries (checked here once: the loads and stores below
    // touch the span's columns below `n` only, plainly for a whole span, else by masks).
    for v in [&x[..], &y[..], &z[..], px, py, pz, w, rest] {
        assert!(v.len() >= n, "a row shorter than its span");
    }
    // SAFETY: compiled with AVX2 (`V8`'s operations need no more); every access stays below
    // `n` (asserted above).
    unsafe {
        // The span's columns of lanes `a` (the pairs' first ends).
        let columns_a = _mm256_setr_epi32(0, 1, 8, 9, 4, 5, 12, 13);
        let mut at = 0;
        while at < n {
            let whole = at + SPAN <= n;
            let k = (V8::first(at, n), V8::first(at + 8, n));
            // The span's pairs `(i, i + 2)` with `i < m` (every pair of a whole span).
            let ahead = i32::try_from(m.saturating_sub(at).min(SPAN)).unwrap_or(0);
            let pairs = _mm256_cmpgt_epi32(_mm256_set1_epi32(ahead), columns_a);
            let (xa, xb) = span_at(x, at, whole, k);
            let (ya, yb) = span_at(y, at, whole, k);
            let (za, zb) = span_at(z, at, whole, k);
            let (pxa, pxb) = span_at(px, at, whole, k);
            let (pya, pyb) = span_at(py, at, whole, k);
            let (pza, pzb) = span_at(pz, at, whole, k);
            let (wa, wb) = span_at(w, at, whole, k);
            // Rest lengths by slot: the first ends' lanes only.
            let (ra, _) = span_at(rest, at, whole, k);
            let (l, f) = pair_factor(
                ([xa, ya, za], [xb, yb, zb]),
                ([pxa, pya, pza], [pxb, pyb, pzb]),
                V8::add(wa, wb),
                ra,
                params,
            );
            for (v, (a, b), l) in [
                (&mut *x, (xa, xb), l[0]),
                (&mut *y, (ya, yb), l[1]),
                (&mut *z, (za, zb), l[2]),
            ] {
                let c = V8::mul(f, l);
                // Ends of the span's pairs past `m` keep their values (bit for bit: adding a
                // zero correction would turn −0 into +0).
                let a = V8::select(pairs, V8::add(a, V8::mul(wa, c)), a);
                let b = V8::select(pairs, V8::sub(b, V8::mul(wb, c)), b);
                put_span(v, at, whole, k, (a, b));
            }
            at += SPAN;
        }
    }
}

/// The span of 16 columns of `v` from `at`, split into the groups' columns 0, 1 (lanes `a`)
/// and 2, 3 (lanes `b`) as [`quads_avx2`] lays them out: plainly for a whole span, else the
/// halves' `k` lanes (zero elsewhere, not read).
///
/// # Safety
/// As [`Lanes`]; `at + 16 <= v.len()` when `whole`, else `k` keeps only lanes inside `v`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn span_at(
    v: &[f32],
    at: usize,
    whole: bool,
    (k0, k1): (<V8 as Lanes>::Mask, <V8 as Lanes>::Mask),
) -> (V8, V8) {
    use std::arch::x86_64::_mm256_shuffle_ps;
    unsafe {
        let (v0, v1) = (lanes_at(v, at, whole, k0), lanes_at(v, at + 8, whole, k1));
        // Per 128-bit half: two floats of `v0`, then the same two of `v1`.
        (
            V8(_mm256_shuffle_ps::<0x44>(v0.0, v1.0)),
            V8(_mm256_shuffle_ps::<0xEE>(v0.0, v1.0)),
        )
    }
}

/// Writes back a span that [`span_at`] split: its columns below `n` only (the masks `k`).
///
/// # Safety
/// As [`span_at`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn put_span(
    v: &mut [f32],
    at: usize,
    whole: bool,
    (k0, k1): (<V8 as Lanes>::Mask, <V8 as Lanes>::Mask),
    (a, b): (V8, V8),
) {
    use std::arch::x86_64::_mm256_shuffle_ps;
    unsafe {
        let v0 = V8(_mm256_shuffle_ps::<0x44>(a.0, b.0));
        let v1 = V8(_mm256_shuffle_ps::<0xEE>(a.0, b.0));
        put_lanes(v, at, whole, k0, v0);
        put_lanes(v, at + 8, whole, k1, v1);
    }
}

dispatched! {
    /// The air forces of one cell row of XPBD's grid path, with `kernel` (the stepping thread's
    /// choice, passed on to the pool's workers). (The explicit integrators' bands call
    /// [`grid_xpbd::air_row`] inside their own kernel.)
    fn xpbd_air / air_avx2 / air_avx512(
        top: [&[f32]; 6],
        bottom: [&[f32]; 6],
        cols: usize,
        k: &AirCoefficients,
        out: [[&mut [f32]; 3]; 2],
    ) = grid_xpbd::air_row;
}

/// Whether this CPU runs `PREFETCHW` (CPUID leaf 8000_0001h, ECX bit 8, which Linux calls
/// `3dnowprefetch`: every AMD processor of the last fifteen years and Intel's since
/// Broadwell). Asked once.
#[cfg(target_arch = "x86_64")]
fn has_prefetchw() -> bool {
    static HAS: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *HAS.get_or_init(|| {
        use std::arch::x86_64::__cpuid;
        // SAFETY: CPUID exists on every x86_64 processor; leaf 8000_0000h gives the highest
        // extended leaf, asked before leaf 8000_0001h.
        #[allow(unused_unsafe)]
        let (max, ecx) = unsafe {
            let max = __cpuid(0x8000_0000).eax;
            (
                max,
                if max >= 0x8000_0001 {
                    __cpuid(0x8000_0001).ecx
                } else {
                    0
                },
            )
        };
        max >= 0x8000_0001 && ecx & (1 << 8) != 0
    })
}

/// Asks for every cache line of `v` in a state this core may write (`PREFETCHW`), ahead of
/// writing them: a line the other threads have read since this one last wrote it must first
/// be taken from their caches, and a loop whose stores wait for that stalls (a hint only: it
/// changes no value; nothing on a processor without the instruction).
#[inline(always)]
pub(crate) fn prefetch_w(v: &[f32]) {
    #[cfg(target_arch = "x86_64")]
    if has_prefetchw() {
        for line in v.chunks(16) {
            // SAFETY: a prefetch reads and writes nothing architecturally and never faults;
            // the pointer is the slice's own, and the processor runs the instruction (above).
            unsafe {
                std::arch::asm!(
                    "prefetchw [{0}]",
                    in(reg) line.as_ptr(),
                    options(nostack, preserves_flags, readonly)
                );
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = v;
}

/// The cache level a read prefetch ([`prefetch`]) brings lines into.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Level {
    /// L1 (`prefetcht0`): read in a moment.
    L1,
    /// L2 (`prefetcht1`): read a little later (the next blocks' entries).
    L2,
}

/// Asks for every cache line of `v` to be brought into `level` (nothing on other targets): a
/// hint for reads the hardware prefetcher would not see coming (a jump to another array, or
/// lines another core has just written). It changes no result and never faults.
#[inline(always)]
pub(crate) fn prefetch(v: &[f32], level: Level) {
    #[cfg(target_arch = "x86_64")]
    for line in v.chunks(16) {
        use std::arch::x86_64::{_MM_HINT_T0, _MM_HINT_T1, _mm_prefetch};
        let p = line.as_ptr().cast();
        // SAFETY: a prefetch reads nothing architecturally and never faults; the pointer is
        // the slice's own.
        unsafe {
            match level {
                Level::L1 => _mm_prefetch::<_MM_HINT_T0>(p),
                Level::L2 => _mm_prefetch::<_MM_HINT_T1>(p),
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (v, level);
}

dispatched! {
    /// A block of XPBD's chain solves ([`chains::solve`] at [`chains::LANES`] lanes), with
    /// `kernel` (the stepping thread's choice, passed on to the pool's workers). AVX2 and
    /// AVX-512 run [`chains_lanes`] (written with intrinsics: with AVX2 each step of a block
    /// as two 8-lane halves, with AVX-512 as one vector); the portable kernel the generic
    /// solve. The same bits on every kernel.
    fn xpbd_chains / chains_avx2 / chains_avx512(
        block: chains::Block<'_>,
        len: usize,
        params: chains::Params,
        keep: bool,
        ahead: Option<&chains::Ahead<'_>>,
    ) = chains::solve_lanes, lanes = chains_lanes;
}

/// Raw pointers to a block's arrays of chains ([`chains_lanes`]).
#[cfg(target_arch = "x86_64")]
struct ChainPtrs {
    x: [*mut f32; 3],
    prev: [*const f32; 3],
    w: *const f32,
    rest: *const f32,
    lambda: *mut f32,
    n: [*mut f32; 3],
    cp: *mut f32,
    dp: *mut f32,
}

/// The numbers every step of [`chains_lanes`] reads, in every lane.
#[cfg(target_arch = "x86_64")]
struct ChainConsts<V> {
    g1: V,
    alpha: V,
    gamma: V,
    relaxation: V,
    zero: V,
    one: V,
    minus: V,
    keep: bool,
}

/// What a step of the forward pass takes from one end of its spring: the particle's position,
/// its move since the substep's start (`x − x_prev`, per component) and its inverse mass.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct ChainEnd<V> {
    x: [V; 3],
    moved: [V; 3],
    w: V,
}

/// The particle at entry `e` as a [`ChainEnd`].
///
/// # Safety
/// As [`chain_spring`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn chain_end<V: Lanes>(p: &ChainPtrs, e: usize) -> ChainEnd<V> {
    unsafe {
        let x = ring::<V>(p.x.map(<*mut f32>::cast_const), e);
        let prev = ring::<V>(p.prev, e);
        let moved = [
            V::sub(x[0], prev[0]),
            V::sub(x[1], prev[1]),
            V::sub(x[2], prev[2]),
        ];
        ChainEnd {
            x,
            moved,
            w: V::load(p.w.add(e)),
        }
    }
}

/// Spring k (entry `e`, its particles `e` and `e + LANES`, the first given as `a`) from its
/// predecessor's direction: writes its direction and gives its coupling, right-hand side and
/// diagonal (the generic solve's `spring!`), its second particle (the next step's first) and
/// its direction.
///
/// # Safety
/// As [`Lanes`]; entries `e ..= e + LANES + N − 1` inside the block's arrays.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn chain_spring<V: Lanes>(
    p: &ChainPtrs,
    k: &ChainConsts<V>,
    e: usize,
    a: ChainEnd<V>,
    n_prev: [V; 3],
) -> ((V, V, V), ChainEnd<V>, [V; 3]) {
    const L: usize = chains::LANES;
    unsafe {
        let b = chain_end::<V>(p, e + L);
        let ([xa, ya, za], [xb, yb, zb]) = (a.x, b.x);
        let (dx, dy, dz) = (V::sub(xb, xa), V::sub(yb, ya), V::sub(zb, za));
        let length = V::sqrt(V::add(
            V::add(V::mul(dx, dx), V::mul(dy, dy)),
            V::mul(dz, dz),
        ));
        let (wa, wb) = (a.w, b.w);
        let ws = V::add(wa, wb);
        let rest = V::load(p.rest.add(e));
        let active = V::and(
            V::and(V::gt(length, k.zero), V::gt(ws, k.zero)),
            V::ge(rest, k.zero),
        );
        let inv = V::div(k.one, length);
        let (ux, uy, uz) = (
            V::select(active, V::mul(dx, inv), k.zero),
            V::select(active, V::mul(dy, inv), k.zero),
            V::select(active, V::mul(dz, inv), k.zero),
        );
        // (x_b − x_b,prev) − (x_a − x_a,prev), per component.
        let (vx, vy, vz) = (
            V::sub(b.moved[0], a.moved[0]),
            V::sub(b.moved[1], a.moved[1]),
            V::sub(b.moved[2], a.moved[2]),
        );
        let rate = V::add(V::add(V::mul(ux, vx), V::mul(uy, vy)), V::mul(uz, vz));
        let constraint = V::sub(length, rest);
        let diag = V::select(active, V::add(V::mul(k.g1, ws), k.alpha), k.one);
        let lam = if k.keep {
            V::load(p.lambda.add(e))
        } else {
            k.zero
        };
        let rhs = V::select(
            active,
            V::mul(
                V::sub(
                    V::sub(V::xor(constraint, k.minus), V::mul(k.alpha, lam)),
                    V::mul(k.gamma, rate),
                ),
                k.relaxation,
            ),
            k.zero,
        );
        let cos = V::add(
            V::add(V::mul(n_prev[0], ux), V::mul(n_prev[1], uy)),
            V::mul(n_prev[2], uz),
        );
        let coupling = V::mul(V::xor(V::mul(k.g1, wa), k.minus), cos);
        V::store(p.n[0].add(e), ux);
        V::store(p.n[1].add(e), uy);
        V::store(p.n[2].add(e), uz);
        ((coupling, rhs, diag), b, [ux, uy, uz])
    }
}

/// The elimination's step at entry `e` (the generic solve's `eliminate!`): gives the
/// reciprocal of the eliminated diagonal and the eliminated right-hand side, which it stores
/// (the reciprocal only with `store_m`: a next step that takes it in a register does not read
/// it back).
///
/// # Safety
/// As [`chain_spring`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn chain_eliminate<V: Lanes>(
    p: &ChainPtrs,
    k: &ChainConsts<V>,
    e: usize,
    (ek, rhs, diag): (V, V, V),
    (m_prev, dp_prev): (V, V),
    store_m: bool,
) -> (V, V) {
    const L: usize = chains::LANES;
    unsafe {
        let c = V::mul(ek, m_prev);
        let r = V::div(k.one, V::sub(diag, V::mul(ek, c)));
        let d = V::mul(V::sub(rhs, V::mul(ek, dp_prev)), r);
        V::store(p.dp.add(e), d);
        if e >= L {
            V::store(p.cp.add(e - L), c);
        }
        if store_m {
            V::store(p.cp.add(e), r);
        }
        (r, d)
    }
}

/// What one step of the forward pass hands the next (in registers when a block's step is one
/// vector): its spring's second particle, direction, eliminated diagonal's reciprocal and
/// right-hand side.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct ChainCarry<V> {
    end: ChainEnd<V>,
    n: [V; 3],
    m: V,
    dp: V,
}

/// [`chains::solve`] with explicit vectors of `V::N` lanes: each step of a block of
/// [`chains::LANES`] chains runs as `LANES / V::N` parts of `V::N` lanes, one after the other.
/// The generic solve's 16-lane arrays took two AVX2 registers per value, and its steps
/// spilled to the stack; here a part's spring and elimination stay in registers (the 256²
/// drape 7 % faster on one thread of a Zen 3, `docs/performance.md`). With AVX-512 (one
/// vector per step, `V::N = LANES`) each step also hands the next, in registers, what both
/// read ([`ChainCarry`]: the shared particle, the direction, the elimination's recurrence)
/// instead of reloading it, and the back substitution its change and direction: the generic
/// solve, with its bounds checks and reloads, took a third more time per step. Every lane runs
/// the generic solve's IEEE operations in its order (no fused multiply-add, the same selects),
/// so the same bits (`tests/xpbd_chains.rs` compares every kernel with the reference path).
///
/// # Safety
/// Only from a function compiled with `V`'s instruction set (see [`Lanes`]).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
#[allow(clippy::too_many_lines)]
unsafe fn chains_lanes<V: Lanes>(
    block: chains::Block<'_>,
    len: usize,
    chains::Params {
        alpha,
        gamma,
        relaxation,
    }: chains::Params,
    keep: bool,
    ahead: Option<&chains::Ahead<'_>>,
) {
    const L: usize = chains::LANES;
    assert!(len >= 2 && L.is_multiple_of(V::N));
    let parts = L / V::N;
    // One vector per step: the steps hand on their values in registers.
    let carry = parts == 1;
    let size = len * L;
    // Raw pointers to the block's arrays (checked to hold `len` steps of `L` lanes).
    let p = &{
        let b = block;
        for a in b.x.iter().map(|a| &**a).chain(b.prev).chain([b.w, b.rest]) {
            assert!(
                a.len() >= size,
                "a chain block array shorter than its chains"
            );
        }
        for a in b.n.iter().chain([&b.cp, &b.dp]) {
            assert!(
                a.len() >= size,
                "a chain scratch array shorter than its chains"
            );
        }
        assert!(!keep || b.lambda.len() >= size);
        let [x0, x1, x2] = b.x;
        let [n0, n1, n2] = b.n;
        ChainPtrs {
            x: [x0.as_mut_ptr(), x1.as_mut_ptr(), x2.as_mut_ptr()],
            prev: b.prev.map(<[f32]>::as_ptr),
            w: b.w.as_ptr(),
            rest: b.rest.as_ptr(),
            lambda: b.lambda.as_mut_ptr(),
            n: [n0.as_mut_ptr(), n1.as_mut_ptr(), n2.as_mut_ptr()],
            cp: b.cp.as_mut_ptr(),
            dp: b.dp.as_mut_ptr(),
        }
    };
    // SAFETY (of every vector operation below): compiled with `V`'s instruction set (the
    // contract); every entry read or written is below `len · L` (asserted above).
    unsafe {
        let (zero, one) = (V::splat(0.0), V::splat(1.0));
        let c = ChainConsts {
            g1: V::splat(1.0 + gamma),
            alpha: V::splat(alpha),
            gamma: V::splat(gamma),
            relaxation: V::splat(relaxation),
            zero,
            one,
            minus: V::splat(-0.0),
            keep,
        };
        // The forward pass. Step 0 of every part; with `carry`, what it hands on.
        let mut next = ChainCarry {
            end: ChainEnd {
                x: [zero; 3],
                moved: [zero; 3],
                w: zero,
            },
            n: [zero; 3],
            m: one,
            dp: zero,
        };
        for h in 0..parts {
            let e = h * V::N;
            let a = chain_end::<V>(p, e);
            let (s, end, n) = chain_spring::<V>(p, &c, e, a, [zero; 3]);
            let (m, dp) = chain_eliminate::<V>(p, &c, e, s, (one, zero), !carry);
            next = ChainCarry { end, n, m, dp };
        }
        if let Some(ahead) = ahead {
            ahead.row(0);
            ahead.row(len - 1);
        }
        for k in 1..len - 1 {
            if let Some(ahead) = ahead {
                ahead.row(k);
            }
            for h in 0..parts {
                let e = k * L + h * V::N;
                let from = if carry {
                    next
                } else {
                    let q = e - L;
                    ChainCarry {
                        end: chain_end::<V>(p, e),
                        n: ring::<V>(p.n.map(<*mut f32>::cast_const), q),
                        m: V::load(p.cp.add(q)),
                        dp: V::load(p.dp.add(q)),
                    }
                };
                let (s, end, n) = chain_spring::<V>(p, &c, e, from.end, from.n);
                let (m, dp) = chain_eliminate::<V>(p, &c, e, s, (from.m, from.dp), !carry);
                next = ChainCarry { end, n, m, dp };
            }
        }
        for h in 0..parts {
            let (last, before) = ((len - 1) * L + h * V::N, (len - 2) * L + h * V::N);
            if !carry {
                // Entry len − 1 (past the last spring): a zero change and direction, which the
                // back substitution's first step reads as its successor's (with `carry` it
                // starts from zeros in registers).
                V::store(p.dp.add(last), zero);
                for n in p.n {
                    V::store(n.add(last), zero);
                }
            }
            // The last spring's coupling with the one past it: zero (the scratch may hold
            // anything, and the back substitution multiplies it by a zero change).
            V::store(p.cp.add(before), zero);
        }
        // The back substitution, from the last spring (its successor's change and direction
        // zero); with `carry` each step hands its change and direction to the next in
        // registers.
        let mut after = (zero, [zero; 3]);
        for step in (0..len - 1).rev() {
            for h in 0..parts {
                let k = step * L + h * V::N;
                let b = k + L;
                let (dl_next, n_next) = if carry {
                    after
                } else {
                    (
                        V::load(p.dp.add(b)),
                        ring::<V>(p.n.map(<*mut f32>::cast_const), b),
                    )
                };
                let dl = V::sub(V::load(p.dp.add(k)), V::mul(V::load(p.cp.add(k)), dl_next));
                if !carry {
                    V::store(p.dp.add(k), dl);
                }
                let n_k = ring::<V>(p.n.map(<*mut f32>::cast_const), k);
                let wb = V::load(p.w.add(b));
                let (s, t) = (V::mul(wb, dl), V::mul(wb, dl_next));
                for c in 0..3 {
                    let x = V::load(p.x[c].add(b));
                    let moved = V::sub(V::mul(s, n_k[c]), V::mul(t, n_next[c]));
                    V::store(p.x[c].add(b), V::add(x, moved));
                }
                if keep {
                    let lam = V::load(p.lambda.add(k));
                    V::store(p.lambda.add(k), V::add(lam, dl));
                }
                after = (dl, n_k);
            }
        }
        for h in 0..parts {
            let e = h * V::N;
            let (dl, n) = if carry {
                after
            } else {
                (
                    V::load(p.dp.add(e)),
                    ring::<V>(p.n.map(<*mut f32>::cast_const), e),
                )
            };
            let t = V::mul(V::load(p.w.add(e)), dl);
            for (x, n) in p.x.into_iter().zip(n) {
                V::store(x.add(e), V::sub(V::load(x.add(e)), V::mul(t, n)));
            }
        }
    }
}

dispatched! {
    /// Continuous collision's candidates of a run of particles against spheres and planes that
    /// do not turn ([`grid_kernel::ccd_mask_screened`]; the same mask on every kernel), for
    /// callers outside a dispatched kernel (XPBD's finishing pass; the explicit band inlines
    /// [`grid_kernel::ccd_mask`]).
    fn ccd_mask / ccd_mask_avx2 / ccd_mask_avx512(
        colliders: &[crate::collide::Collider],
        h: f32,
        w: &[f32],
        a: [&[f32]; 3],
        b: [&[f32]; 3],
        near: &mut [bool],
    ) -> bool = grid_kernel::ccd_mask_screened;
}

dispatched! {
    /// The diagnostics' energies, strains and stretch check of a run of springs
    /// ([`crate::diagnostics::spring_lanes`]; the same bits on every kernel).
    fn spring_lanes / spring_lanes_avx2 / spring_lanes_avx512(
        position: &[glam::Vec3],
        springs: &[crate::topology::Spring],
        rest: &[f32],
        k: f64,
        limit: f32,
    ) -> crate::diagnostics::SpringLanes = crate::diagnostics::spring_lanes;
}

dispatched! {
    /// The diagnostics' spring pass with the lengths already measured
    /// ([`crate::diagnostics::length_lanes`]; the same bits on every kernel).
    fn length_lanes / length_lanes_avx2 / length_lanes_avx512(
        lengths: &[f32],
        springs: &[crate::topology::Spring],
        rest: &[f32],
        k: f64,
        limit: f32,
    ) -> crate::diagnostics::SpringLanes = crate::diagnostics::length_lanes;
}

dispatched! {
    /// The diagnostics' spring lengths of some rows of a grid cloth
    /// ([`crate::diagnostics::grid_row_lengths`]; the same bits on every kernel).
    fn grid_row_lengths / grid_row_lengths_avx2 / grid_row_lengths_avx512(
        position: &[glam::Vec3],
        shape: [usize; 2],
        rows: std::ops::Range<usize>,
        out: [&mut [f32]; 4],
    ) = crate::diagnostics::grid_row_lengths;
}

dispatched! {
    /// One chunk of the diagnostics' particle pass ([`crate::diagnostics::particle_chunk`]; the
    /// same bits on every kernel).
    fn particle_chunk / particle_chunk_avx2 / particle_chunk_avx512(
        state: [&[glam::Vec3]; 2],
        mass: [&[f32]; 2],
        colliders: &[crate::collide::Collider],
        g: glam::Vec3,
        max_speed_sq: f32,
    ) -> crate::diagnostics::Partial = crate::diagnostics::particle_chunk;
}

dispatched! {
    /// XPBD's contacts of a run of particles with colliders that are all spheres or planes that
    /// do not turn, on the arrays ([`grid_xpbd::contacts_soa_row`]: the pre-test and the exact
    /// kernel; the same bits on every kernel). Returns the contact count.
    fn xpbd_contacts / contacts_avx2 / contacts_avx512(
        colliders: &[crate::collide::Collider],
        h: f32,
        w: &[f32],
        x: [&mut [f32]; 3],
        x0: [&[f32]; 3],
    ) -> u32 = grid_xpbd::contacts_soa_row;
}

/// Transposes one tile of 16 × 16 floats: `dst[k·dst_stride + l] = src[l·src_stride + k]`
/// for `k, l < 16` (rows `l` of `src`, `src_stride` apart, become columns of `dst`). With
/// AVX-512 in 16 registers ([`transpose16_avx512`]), with AVX (the AVX2 kernel, or AVX-512's
/// on a CPU without it) as four 8 × 8 transposes in registers, else element by element
/// ([`chains::transpose16`]); the same values either way.
pub(crate) fn transpose16(
    kernel: Kernel,
    src: &[f32],
    src_stride: usize,
    dst: &mut [f32],
    dst_stride: usize,
) {
    match kernel {
        #[cfg(target_arch = "x86_64")]
        Kernel::Avx512 if Kernel::Avx512.is_available() => {
            // SAFETY: the CPU has AVX-512 F (checked on the line above).
            unsafe { transpose16_avx512(src, src_stride, dst, dst_stride) }
        }
        #[cfg(target_arch = "x86_64")]
        Kernel::Avx2 | Kernel::Avx512 if Kernel::Avx2.is_available() => {
            // SAFETY: the CPU has AVX2 (checked on the line above), which includes AVX.
            unsafe { transpose16_avx(src, src_stride, dst, dst_stride) }
        }
        _ => chains::transpose16(src, src_stride, dst, dst_stride),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
fn transpose16_avx(src: &[f32], src_stride: usize, dst: &mut [f32], dst_stride: usize) {
    use std::arch::x86_64::__m256;
    for bi in 0..2 {
        for bj in 0..2 {
            // The 8 × 8 block of source rows 8·bi.. and columns 8·bj...
            let mut r = [bytemuck::Zeroable::zeroed(); 8];
            for (i, r) in r.iter_mut().enumerate() {
                let row: [f32; 8] = *src[(8 * bi + i) * src_stride + 8 * bj..]
                    .first_chunk()
                    .expect("16 floats per source row");
                *r = bytemuck::cast::<[f32; 8], __m256>(row);
            }
            let o = transpose8(r);
            for (i, o) in o.into_iter().enumerate() {
                let out: &mut [f32; 8] = dst[(8 * bj + i) * dst_stride + 8 * bi..]
                    .first_chunk_mut()
                    .expect("16 floats per destination row");
                *out = bytemuck::cast::<__m256, [f32; 8]>(o);
            }
        }
    }
}

/// [`transpose16`] with AVX-512: the 16 rows in 16 registers, transposed in four rounds of 16
/// shuffles (pairs of rows interleaved, then quadruples, within each 128-bit lane; then the
/// lanes, twice), where the AVX copy takes four 8 × 8 transposes (96 shuffles, and 64 loads
/// and 64 stores of half rows).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn transpose16_avx512(src: &[f32], src_stride: usize, dst: &mut [f32], dst_stride: usize) {
    use std::arch::x86_64::{
        __m512, _mm512_loadu_ps, _mm512_setzero_ps, _mm512_shuffle_f32x4, _mm512_shuffle_ps,
        _mm512_storeu_ps, _mm512_unpackhi_ps, _mm512_unpacklo_ps,
    };
    assert!(
        src.len() >= 15 * src_stride + 16 && dst.len() >= 15 * dst_stride + 16,
        "a tile of 16 rows of 16 floats"
    );
    let mut r: [__m512; 16] = [_mm512_setzero_ps(); 16];
    let mut t = r;
    // SAFETY: every row read or written lies inside its slice (asserted above).
    unsafe {
        for (i, r) in r.iter_mut().enumerate() {
            *r = _mm512_loadu_ps(src.as_ptr().add(i * src_stride));
        }
    }
    // Pairs of rows interleaved within each 128-bit lane.
    for i in (0..16).step_by(2) {
        t[i] = _mm512_unpacklo_ps(r[i], r[i + 1]);
        t[i + 1] = _mm512_unpackhi_ps(r[i], r[i + 1]);
    }
    // Quadruples: register 4g + q holds, in its lane j, column 4j + q of rows 4g .. 4g + 3.
    for g in (0..16).step_by(4) {
        r[g] = _mm512_shuffle_ps::<0x44>(t[g], t[g + 2]);
        r[g + 1] = _mm512_shuffle_ps::<0xEE>(t[g], t[g + 2]);
        r[g + 2] = _mm512_shuffle_ps::<0x44>(t[g + 1], t[g + 3]);
        r[g + 3] = _mm512_shuffle_ps::<0xEE>(t[g + 1], t[g + 3]);
    }
    // Lanes 0 and 2 (0x88) and lanes 1 and 3 (0xDD) of the quadruples of rows 8h .. 8h + 3
    // and 8h + 4 .. 8h + 7.
    for h in [0, 8] {
        for q in 0..4 {
            t[h + q] = _mm512_shuffle_f32x4::<0x88>(r[h + q], r[h + 4 + q]);
            t[h + 4 + q] = _mm512_shuffle_f32x4::<0xDD>(r[h + q], r[h + 4 + q]);
        }
    }
    // Column c < 8 from lanes 0 and 2 of t[c] and t[8 + c], column 8 + c from lanes 1 and 3.
    for c in 0..8 {
        r[c] = _mm512_shuffle_f32x4::<0x88>(t[c], t[8 + c]);
        r[8 + c] = _mm512_shuffle_f32x4::<0xDD>(t[c], t[8 + c]);
    }
    // SAFETY: as above.
    unsafe {
        for (c, col) in r.into_iter().enumerate() {
            _mm512_storeu_ps(dst.as_mut_ptr().add(c * dst_stride), col);
        }
    }
}

/// The transpose of 8 rows of 8 floats in AVX registers (unpack, shuffle, swap of halves).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
#[inline]
fn transpose8(r: [std::arch::x86_64::__m256; 8]) -> [std::arch::x86_64::__m256; 8] {
    use std::arch::x86_64::{
        _mm256_permute2f128_ps, _mm256_shuffle_ps, _mm256_unpackhi_ps, _mm256_unpacklo_ps,
    };
    // t: pairs of rows interleaved; s: quadruples; then the 128-bit halves exchanged.
    let t = [
        _mm256_unpacklo_ps(r[0], r[1]),
        _mm256_unpackhi_ps(r[0], r[1]),
        _mm256_unpacklo_ps(r[2], r[3]),
        _mm256_unpackhi_ps(r[2], r[3]),
        _mm256_unpacklo_ps(r[4], r[5]),
        _mm256_unpackhi_ps(r[4], r[5]),
        _mm256_unpacklo_ps(r[6], r[7]),
        _mm256_unpackhi_ps(r[6], r[7]),
    ];
    let s = [
        _mm256_shuffle_ps::<0x44>(t[0], t[2]),
        _mm256_shuffle_ps::<0xEE>(t[0], t[2]),
        _mm256_shuffle_ps::<0x44>(t[1], t[3]),
        _mm256_shuffle_ps::<0xEE>(t[1], t[3]),
        _mm256_shuffle_ps::<0x44>(t[4], t[6]),
        _mm256_shuffle_ps::<0xEE>(t[4], t[6]),
        _mm256_shuffle_ps::<0x44>(t[5], t[7]),
        _mm256_shuffle_ps::<0xEE>(t[5], t[7]),
    ];
    [
        _mm256_permute2f128_ps::<0x20>(s[0], s[4]),
        _mm256_permute2f128_ps::<0x20>(s[1], s[5]),
        _mm256_permute2f128_ps::<0x20>(s[2], s[6]),
        _mm256_permute2f128_ps::<0x20>(s[3], s[7]),
        _mm256_permute2f128_ps::<0x31>(s[0], s[4]),
        _mm256_permute2f128_ps::<0x31>(s[1], s[5]),
        _mm256_permute2f128_ps::<0x31>(s[2], s[6]),
        _mm256_permute2f128_ps::<0x31>(s[3], s[7]),
    ]
}

/// Under CI on x86-64, fails unless the CPU has AVX2: a test of an AVX2 kernel (`what`) must
/// not pass there by skipping it (elsewhere a CPU without AVX2 has only the other kernels to
/// run).
#[cfg(test)]
pub(crate) fn require_avx2_under_ci(what: &str) {
    if cfg!(target_arch = "x86_64") && std::env::var_os("CI").is_some() {
        assert!(
            Kernel::Avx2.is_available(),
            "CI: no AVX2 on this CPU, {what} would go untested"
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fused row's zero-length test ([`Lanes::short`]) flags a live lane whose squared
    /// length is below `forces::ZERO_LENGTH_SQUARED` (±0, subnormal), as the reference skips it, and no
    /// other: not the smallest normal, not a real length, not NaN (a NaN spring is left to the
    /// step's instability check), and not a lane outside the mask. On 8 lanes of AVX2 and,
    /// where the CPU has it, 16 of AVX-512. Tolerance: none.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn short_flags_the_squared_lengths_the_reference_skips() {
        require_avx2_under_ci("the fused row's zero-length test");
        let tiny = crate::forces::ZERO_LENGTH_SQUARED;
        let cases = [
            (0.0, true),
            (-0.0, true),
            (tiny / 4.0, true),
            (tiny, false),
            (1e-3, false),
            (f32::NAN, false),
        ];
        fn check<V: Lanes>(cases: &[(f32, bool)]) {
            for &(len2, short) in cases {
                for lane in 0..V::N {
                    let mut v = vec![1.0_f32; V::N];
                    v[lane] = len2;
                    // SAFETY: the caller checked the CPU has `V`'s instruction set; `v`
                    // holds `V::N` floats.
                    let (all, below) = unsafe {
                        let x = V::load(v.as_ptr());
                        (
                            V::short(x, V::first(0, V::N)),
                            V::short(x, V::first(0, lane)),
                        )
                    };
                    assert_eq!(all, short, "{len2:e} in lane {lane} of {}", V::N);
                    assert!(!below, "{len2:e} in lane {lane}, outside the mask");
                }
            }
        }
        if Kernel::Avx2.is_available() {
            check::<V8>(&cases);
        }
        if Kernel::Avx512.is_available() {
            check::<V16>(&cases);
        }
    }

    /// Every kernel's tile transpose moves each value to its transposed place (distinct values,
    /// source and destination strides of 16 and of a row width; nothing else is written).
    #[test]
    fn transpose16_moves_every_value_to_its_transposed_place() {
        for (src_stride, dst_stride) in [(16, 16), (37, 16), (16, 41)] {
            let src: Vec<f32> = (0..16 * src_stride).map(|i| i as f32 + 0.5).collect();
            for kernel in Kernel::ALL.into_iter().filter(|k| k.is_available()) {
                let mut dst = vec![-1.0_f32; 16 * dst_stride];
                transpose16(kernel, &src, src_stride, &mut dst, dst_stride);
                // dst[r·dst_stride + c] = src[c·src_stride + r] for c < 16; the rest untouched.
                for r in 0..16 {
                    for c in 0..dst_stride {
                        let want = if c < 16 {
                            src[c * src_stride + r]
                        } else {
                            -1.0
                        };
                        let got = dst[r * dst_stride + c];
                        assert_eq!(got, want, "{kernel:?} {src_stride}/{dst_stride} ({r}, {c})");
                    }
                }
            }
        }
    }

    /// Every kernel's chain solve ([`xpbd_chains`]: the AVX2 and AVX-512 kernels' intrinsics,
    /// the portable kernel's generic code) writes the generic solve's bits into every array of
    /// a block (its fields; the scratch is not a result): 16 chains
    /// of 2 and of 37 particles, with the lanes the solve leaves out (a zero-length spring,
    /// a spring between two pinned particles, one pinned end, a negative rest length), kept
    /// and unused multipliers, one and three iterations, and two over-relaxed ones
    /// (`XpbdSettings::chain_relaxation` 1.3). Tolerance: none (bits). Under CI on
    /// x86-64 the AVX2 kernel must be available, so that its intrinsics are what is compared
    /// (elsewhere a CPU without it has only the generic solve to run).
    #[test]
    fn every_kernels_chain_solve_gives_the_generic_bits() {
        use crate::solver::chains::{self, Block, FIELDS, LANES, SCRATCH};
        require_avx2_under_ci("the AVX2 chain solve");
        for len in [2, 37] {
            let size = chains::stride(len);
            let mut fields = vec![0.0_f32; FIELDS * size];
            for k in 0..len {
                for l in 0..LANES {
                    let (t, c) = (k as f32, l as f32);
                    let e = k * LANES + l;
                    let x = [
                        0.1 * t + 0.003 * c,
                        0.02 * (t * 1.3 + c).sin(),
                        0.015 * (t * 0.7 - c).cos(),
                    ];
                    for d in 0..3 {
                        fields[d * size + e] = x[d];
                        fields[(3 + d) * size + e] = x[d] - 0.001 * (t + c).sin();
                    }
                    fields[6 * size + e] = 1.0 + 0.1 * c;
                    fields[7 * size + e] = 0.098 + 0.0005 * c;
                    fields[8 * size + e] = 0.01 * (t - c).sin();
                }
            }
            // Lane 1: a zero-length spring (particles 0 and 1 at the same place); lane 2: a
            // spring between two pinned particles; lane 3: a pinned end; lane 4: a negative
            // rest length (cut out of the chain).
            for d in 0..3 {
                fields[d * size + LANES + 1] = fields[d * size + 1];
            }
            fields[6 * size + 2] = 0.0;
            fields[6 * size + LANES + 2] = 0.0;
            fields[6 * size + 3] = 0.0;
            fields[7 * size + 4] = -1.0;
            for (keep, iterations, relaxation) in [
                (false, 1, 1.0),
                (true, 1, 1.0),
                (true, 3, 1.0),
                (true, 2, 1.3),
            ] {
                let params = chains::Params {
                    relaxation,
                    ..chains::Params::test()
                };
                let solve = |kernel: Option<Kernel>| {
                    let (mut f, mut work) = (fields.clone(), vec![0.0_f32; SCRATCH * size]);
                    for _ in 0..iterations {
                        let block = Block::split(&mut f, &mut work, size);
                        match kernel {
                            Some(kernel) => xpbd_chains(kernel, block, len, params, keep, None),
                            None => chains::solve_lanes(block, len, params, keep, None),
                        }
                    }
                    // The block's fields only: the scratch is not a result (the AVX-512
                    // kernel hands some of its values on in registers and never stores them).
                    f.iter().map(|v| v.to_bits()).collect::<Vec<u32>>()
                };
                let generic = solve(None);
                for kernel in Kernel::ALL.into_iter().filter(|k| k.is_available()) {
                    assert!(
                        solve(Some(kernel)) == generic,
                        "{kernel:?}: chains of {len}, keep {keep}, {iterations} iterations, \
                         relaxation {relaxation}"
                    );
                }
            }
        }
    }
}
