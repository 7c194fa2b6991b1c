//! Thresholds as bytes ([`above`]) and as bits ([`above_bits`], [`pack_bits`]): SSE2 (the
//! x86-64 baseline) and AVX2 compares, the portable loops beside them.

use super::Avx2;

/// Bit `i` of the result words is `src[i] > t` (little-endian words, as [`pack_bits`]).
pub fn above_bits(src: &[u8], t: u8, bits: &mut [u64]) {
    assert!(bits.len() >= src.len().div_ceil(64), "bit buffer too short");
    if t == 255 {
        bits.iter_mut().for_each(|w| *w = 0);
        return;
    }
    #[cfg(target_arch = "x86_64")]
    {
        let n = src.len() / 64 * 64;
        if Avx2::detect().is_some() {
            // SAFETY: an `Avx2` exists only on a CPU with AVX2.
            #[allow(
                unsafe_code,
                reason = "calling a target_feature function on a CPU with it"
            )]
            unsafe {
                simd::above_bits_avx2(&src[..n], t, &mut bits[..n / 64]);
            }
        } else {
            // SSE2 is part of the x86-64 baseline.
            simd::above_bits_sse2(&src[..n], t, &mut bits[..n / 64]);
        }
        let rest = &src[n..];
        if !rest.is_empty() {
            let mut bytes = [0u8; 64];
            above(rest, t, &mut bytes[..rest.len()]);
            pack_bits(&bytes[..rest.len()], &mut bits[n / 64..n / 64 + 1]);
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let mut bytes = vec![0u8; src.len()];
        above(src, t, &mut bytes);
        pack_bits(&bytes, bits);
    }
}

dispatch! {
    /// `dst[i] = (src[i] > t) as u8`.
    pub fn above(src: &[u8], t: u8, dst: &mut [u8]) {
        for (o, &v) in dst.iter_mut().zip(src) {
            *o = u8::from(v > t);
        }
    }
}

dispatch! {
    /// Packs bytes that are 0 or 1 into little-endian 64-bit words (bit `i` of word `k` is
    /// byte `64 k + i`).
    pub fn pack_bits(bytes: &[u8], bits: &mut [u64]) {
        for (w, chunk) in bits.iter_mut().zip(bytes.chunks(64)) {
            let mut word = 0u64;
            let mut eights = chunk.chunks_exact(8);
            for (k, c8) in (&mut eights).enumerate() {
                let v = u64::from_le_bytes([c8[0], c8[1], c8[2], c8[3], c8[4], c8[5], c8[6], c8[7]]);
                // The multiplier has bits at 56 − 7i, so byte i's bit lands on bit 56 + i and no
                // two partial products share a bit (no carries).
                word |= (v.wrapping_mul(0x0102_0408_1020_4080) >> 56) << (8 * k);
            }
            let base = chunk.len() / 8 * 8;
            for (i, &b) in eights.remainder().iter().enumerate() {
                word |= u64::from(b) << (base + i);
            }
            *w = word;
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[allow(
    unsafe_code,
    reason = "SSE2 and AVX2 compares on bounds-checked 16- and 32-byte chunks"
)]
mod simd {
    #[allow(
        clippy::wildcard_imports,
        reason = "the kernels below name two dozen intrinsics"
    )]
    use std::arch::x86_64::*;

    /// `src.len()` a multiple of 64, `bits.len() == src.len() / 64`, `t < 255`.
    pub(super) fn above_bits_sse2(src: &[u8], t: u8, bits: &mut [u64]) {
        // SAFETY: SSE2 is always present on x86-64; every load reads 16 bytes inside a
        // 64-byte chunk from chunks_exact.
        unsafe {
            // v > t  ⟺  max(v, t + 1) == v (unsigned bytes, t < 255).
            let t1 = _mm_set1_epi8((t + 1) as i8);
            for (w, c) in bits.iter_mut().zip(src.chunks_exact(64)) {
                let mut word = 0u64;
                for k in 0..4 {
                    let v = _mm_loadu_si128(c[16 * k..].as_ptr().cast::<__m128i>());
                    let m = _mm_movemask_epi8(_mm_cmpeq_epi8(_mm_max_epu8(v, t1), v)) as u32 as u64;
                    word |= m << (16 * k);
                }
                *w = word;
            }
        }
    }

    /// [`super::above_bits`] on AVX2: `src.len()` a multiple of 64, `bits.len() == src.len() /
    /// 64`, `t < 255`.
    #[target_feature(enable = "avx2")]
    pub(super) fn above_bits_avx2(src: &[u8], t: u8, bits: &mut [u64]) {
        // v > t  ⟺  max(v, t + 1) == v (unsigned bytes, t < 255).
        let t1 = _mm256_set1_epi8((t + 1) as i8);
        for (w, c) in bits.iter_mut().zip(src.chunks_exact(64)) {
            let (lo, hi) = c.split_at(32);
            // SAFETY: `lo` and `hi` are 32 bytes each (a 64-byte chunk split in two).
            let (a, b) = unsafe {
                (
                    _mm256_loadu_si256(lo.as_ptr().cast::<__m256i>()),
                    _mm256_loadu_si256(hi.as_ptr().cast::<__m256i>()),
                )
            };
            let above = |v: __m256i| {
                _mm256_movemask_epi8(_mm256_cmpeq_epi8(_mm256_max_epu8(v, t1), v)) as u32 as u64
            };
            *w = above(a) | (above(b) << 32);
        }
    }
}
