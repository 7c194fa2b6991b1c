//! Pixel kernels with runtime CPU dispatch.
//!
//! Each kernel is written once as plain safe Rust that the compiler vectorises, and compiled twice:
//! for the baseline target (SSE2 on x86-64) and with AVX2 and FMA enabled. One mechanism chooses
//! between them: the crate-internal `Avx2` token, which exists only after `std`'s runtime check
//! found both on the running CPU; nothing is pinned to the build machine. The portable forms are
//! crate-private (the tests compare the two). Both copies compute identical results (integer code,
//! or floating point in the same order of operations, with no reassociation or fused
//! multiply-adds); the tests run whichever the machine picks and compare with scalar references.
//! Kernels the compiler would not vectorise are written with intrinsics beside a portable loop: the
//! AVX2 (and, for short rows, SSSE3) channel shuffles, the AVX2 3-tap minimum/maximum, the
//! SSE2/AVX2 threshold bits, the AVX2 excess sums and the AVX2 background-ring plane (identical
//! results: the ring's per-lane sums are taken in the portable loop's lanes and order, tested bit
//! for bit), and the AVX2 + FMA grey-centroid window sums (floating point summed in eight lanes:
//! equal to the portable loop within 1e-4 relative, tested).
//!
//! One file per operation: `channel` (one channel of RGB, exact luma), `threshold` (bytes and
//! bits above a level), `extremum` (3-tap minimum or maximum), `excess` (a window's excess
//! sums, and the window runner), `ellipse` (the grey-centroid window sums), `ring` (the
//! background plane of the ring around a window); each holds its portable loop and, in a
//! `simd` module, its intrinsics.
//!
//! A loop that calls kernels many times a frame checks the CPU once instead: the crate-internal
//! `Avx2::detect` gives a token only on a CPU with AVX2 and FMA, and the loop, compiled with
//! those features and handed the token, calls the `_on` forms of the kernels, which then inline
//! into it (the frame's opening pass and the grey-centroid refinement do).

#![allow(
    clippy::needless_range_loop,
    reason = "fixed-width inner loops index several arrays in lockstep; the index form is what vectorises"
)]

/// Generates `$vis fn $name(args)` that runs one body compiled twice — with AVX2 and FMA and
/// for the baseline — through [`Avx2::dispatch`], the one CPU check every kernel uses.
macro_rules! dispatch {
    ($(#[$m:meta])* $vis:vis fn $name:ident($($arg:ident : $ty:ty),*) $(-> $ret:ty)? $body:block) => {
        $(#[$m])*
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            #[inline(always)]
            fn body(($($arg),*,): ($($ty),*,)) $(-> $ret)? $body
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2,fma")]
            fn avx2(_: Avx2, args: ($($ty),*,)) $(-> $ret)? {
                body(args)
            }
            Avx2::dispatch(
                ($($arg),*,),
                #[cfg(target_arch = "x86_64")]
                avx2,
                |_, args| body(args),
            )
        }
    };
}

/// A CPU with AVX2 and FMA, made by [`Avx2::detect`] only after the runtime check: a kernel
/// handed one runs its AVX2 (and FMA) code without checking again. A row loop compiled with
/// AVX2 that passes one down to its kernels has them inlined, with no check or call per row.
#[derive(Clone, Copy, Debug)]
#[cfg_attr(
    not(target_arch = "x86_64"),
    allow(dead_code, reason = "only x86-64 has the AVX2 kernels")
)]
pub(crate) struct Avx2(());

impl Avx2 {
    /// `Some` when the running CPU has AVX2 and FMA (every x86-64 CPU with AVX2 but a few
    /// early VIA ones has FMA; those take the portable kernels).
    #[inline]
    pub(crate) fn detect() -> Option<Self> {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                return Some(Avx2(()));
            }
        }
        None
    }

    /// The one CPU check of a loop that hands its kernels the token: `avx2(cpu, args)` (a
    /// function compiled with AVX2 and FMA, nothing more) where the CPU has them, else
    /// `portable(None, args)`.
    #[inline(always)]
    pub(crate) fn dispatch<A, R>(
        args: A,
        #[cfg(target_arch = "x86_64")] avx2: unsafe fn(Avx2, A) -> R,
        portable: fn(Option<Avx2>, A) -> R,
    ) -> R {
        match Self::detect() {
            #[cfg(target_arch = "x86_64")]
            Some(cpu) => {
                // SAFETY: `cpu` exists only on a CPU with AVX2 and FMA, all `avx2` requires.
                #[allow(
                    unsafe_code,
                    reason = "calling a target_feature function on a CPU with it"
                )]
                unsafe {
                    avx2(cpu, args)
                }
            }
            cpu => portable(cpu, args),
        }
    }
}

/// Calls `step` at the starts of 32-byte steps over `n ≥ 32` bytes: `0, 32, …` while a whole
/// step fits, then `n − 32` where bytes remain (that step overlaps the one before; kernels that
/// write each byte from their inputs alone write the same values twice).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn for_steps_of_32(n: usize, mut step: impl FnMut(usize)) {
    let mut i = 0;
    while i + 32 <= n {
        step(i);
        i += 32;
    }
    if i < n {
        step(n - 32);
    }
}

mod channel;
mod ellipse;
mod excess;
mod extremum;
mod ring;
#[cfg(test)]
mod tests;
mod threshold;

pub(crate) use channel::pick_channel_on;
pub use channel::{luma601, luma601_planar, pick_channel};
pub(crate) use ellipse::ellipse_window_sums_on;
pub use ellipse::{ellipse_window_sums, EllipseWindow};
pub use excess::excess_sums;
pub(crate) use excess::excess_sums_on;
pub(crate) use extremum::extremum3_on;
pub use extremum::{extremum3, extremum_acc};
// The portable forms, for the tests that compare them with the AVX2 ones.
pub(crate) use ring::{ring_plane_on, RingSides};
pub use threshold::{above, above_bits, pack_bits};
#[cfg(test)]
use {
    channel::{floor_div_10000, pick_channel_portable},
    ellipse::ellipse_window_sums_portable,
    excess::excess_sums_portable,
};
