//! The 3-tap minimum or maximum of a separable filter ([`extremum3`]) and the running one
//! ([`extremum_acc`]): AVX2 and the portable loops.

use super::Avx2;

/// `dst[i] = min(a[i], b[i], c[i])` (or max): the 3-tap step of a separable filter. AVX2 when
/// the CPU has it and there are at least 32 bytes (the last 32 are taken again, overlapping, so
/// no byte takes a scalar tail), else the portable loop.
pub fn extremum3(a: &[u8], b: &[u8], c: &[u8], dst: &mut [u8], max: bool) {
    extremum3_on(Avx2::detect(), a, b, c, dst, max);
}

/// [`extremum3`] on `cpu`'s kernels.
#[inline(always)]
pub(crate) fn extremum3_on(
    cpu: Option<Avx2>,
    a: &[u8],
    b: &[u8],
    c: &[u8],
    dst: &mut [u8],
    max: bool,
) {
    #[cfg(target_arch = "x86_64")]
    {
        let n = dst.len().min(a.len()).min(b.len()).min(c.len());
        if n >= 32 && cpu.is_some() {
            // SAFETY: an `Avx2` exists only on a CPU with AVX2.
            #[allow(
                unsafe_code,
                reason = "calling a target_feature function on a CPU with it"
            )]
            unsafe {
                simd::extremum3_avx2(&a[..n], &b[..n], &c[..n], &mut dst[..n], max);
            }
            return;
        }
    }
    let _ = cpu;
    extremum3_portable(a, b, c, dst, max);
}

dispatch! {
    /// Portable form of [`extremum3`].
    pub(crate) fn extremum3_portable(a: &[u8], b: &[u8], c: &[u8], dst: &mut [u8], max: bool) {
        if max {
            for (((o, &x), &y), &z) in dst.iter_mut().zip(a).zip(b).zip(c) {
                *o = x.max(y).max(z);
            }
        } else {
            for (((o, &x), &y), &z) in dst.iter_mut().zip(a).zip(b).zip(c) {
                *o = x.min(y).min(z);
            }
        }
    }
}

dispatch! {
    /// `dst[i] = min(dst[i], src[i])` (or max).
    pub fn extremum_acc(src: &[u8], dst: &mut [u8], max: bool) {
        if max {
            dst.iter_mut().zip(src).for_each(|(o, &v)| *o = (*o).max(v));
        } else {
            dst.iter_mut().zip(src).for_each(|(o, &v)| *o = (*o).min(v));
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[allow(
    unsafe_code,
    reason = "AVX2 loads and stores of bounds-checked 32-byte slices"
)]
mod simd {
    #[allow(
        clippy::wildcard_imports,
        reason = "the kernels below name two dozen intrinsics"
    )]
    use std::arch::x86_64::*;

    /// [`super::extremum3`] on AVX2: all four slices of one length `n ≥ 32`; 32 bytes a step,
    /// the last step at `n − 32` (overlapping the one before: `dst` is written from `a`, `b`,
    /// `c` only, so writing a byte twice writes the same value).
    #[target_feature(enable = "avx2")]
    pub(super) fn extremum3_avx2(a: &[u8], b: &[u8], c: &[u8], dst: &mut [u8], max: bool) {
        let n = dst.len();
        assert!(n >= 32 && a.len() == n && b.len() == n && c.len() == n);
        let step = |i: usize, dst: &mut [u8]| {
            let v = |s: &[u8]| {
                let s = &s[i..i + 32];
                // SAFETY: `s` is 32 bytes (a bounds-checked slice).
                unsafe { _mm256_loadu_si256(s.as_ptr().cast::<__m256i>()) }
            };
            let (x, y, z) = (v(a), v(b), v(c));
            let r = if max {
                _mm256_max_epu8(_mm256_max_epu8(x, y), z)
            } else {
                _mm256_min_epu8(_mm256_min_epu8(x, y), z)
            };
            let d = &mut dst[i..i + 32];
            // SAFETY: `d` is 32 bytes (a bounds-checked slice).
            unsafe { _mm256_storeu_si256(d.as_mut_ptr().cast::<__m256i>(), r) };
        };
        super::super::for_steps_of_32(n, |i| step(i, dst));
    }
}
