//! One channel of interleaved RGB ([`pick_channel`]) and MATLAB's exact `rgb2gray`
//! ([`luma601`]): AVX2 and SSSE3 byte shuffles, the portable loops beside them.

use super::Avx2;

/// `dst[i] = src[3 i + c]`: one channel of interleaved RGB (AVX2 and SSSE3 byte shuffles when
/// the CPU has AVX2, else the portable loop).
pub fn pick_channel(src: &[u8], dst: &mut [u8], c: usize) {
    pick_channel_on(Avx2::detect(), src, dst, c);
}

/// [`pick_channel`] on `cpu`'s kernels: with AVX2, 32 pixels a step (the last step
/// overlapping the one before), SSSE3 and the portable loop for a row under 32 pixels.
#[inline(always)]
pub(crate) fn pick_channel_on(cpu: Option<Avx2>, src: &[u8], dst: &mut [u8], c: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        if cpu.is_some() {
            let n = dst.len().min(src.len() / 3);
            // SAFETY: an `Avx2` exists only on a CPU with AVX2, hence SSSE3.
            #[allow(
                unsafe_code,
                reason = "calling a target_feature function on a CPU with it"
            )]
            unsafe {
                if n >= 32 {
                    shuffle::pick_channel_avx2(&src[..3 * n], &mut dst[..n], c);
                } else {
                    pick_channel_ssse3_then_portable(src, dst, c);
                }
            }
            return;
        }
    }
    let _ = cpu;
    pick_channel_portable(src, dst, c);
}

/// The SSSE3 shuffles over whole 16-pixel steps, the portable loop over the rest.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "ssse3")]
fn pick_channel_ssse3_then_portable(src: &[u8], dst: &mut [u8], c: usize) {
    let n = dst.len().min(src.len() / 3) / 16 * 16;
    shuffle::pick_channel_ssse3(&src[..3 * n], &mut dst[..n], c);
    pick_channel_portable(&src[3 * n..], &mut dst[n..], c);
}

dispatch! {
    /// Portable form of [`pick_channel`].
    pub(crate) fn pick_channel_portable(src: &[u8], dst: &mut [u8], c: usize) {
        let n = dst.len().min(src.len() / 3);
        let (src, dst) = (&src[..3 * n], &mut dst[..n]);
        let mut d16 = dst.chunks_exact_mut(16);
        let mut s48 = src.chunks_exact(48);
        for (d, s) in (&mut d16).zip(&mut s48) {
            for i in 0..16 {
                d[i] = s[3 * i + c];
            }
        }
        for (d, s) in d16.into_remainder().iter_mut().zip(s48.remainder().chunks_exact(3)) {
            *d = s[c];
        }
    }
}

/// `dst[i] = round(0.2989 R + 0.5870 G + 0.1140 B)` exactly (MATLAB `rgb2gray`), from
/// interleaved RGB: planes of up to 1024 pixels are split out with [`pick_channel`] into
/// `planes` (caller scratch, reused between calls), then combined by [`luma601_planar`].
pub fn luma601(src: &[u8], dst: &mut [u8], planes: &mut Vec<u8>) {
    const BLOCK: usize = 1024;
    let n = dst.len().min(src.len() / 3);
    if planes.len() < 3 * BLOCK {
        planes.resize(3 * BLOCK, 0);
    }
    let (r, rest) = planes.split_at_mut(BLOCK);
    let (g, b) = rest.split_at_mut(BLOCK);
    for (d, s) in dst[..n]
        .chunks_mut(BLOCK)
        .zip(src[..3 * n].chunks(3 * BLOCK))
    {
        let k = d.len();
        pick_channel(s, &mut r[..k], 0);
        pick_channel(s, &mut g[..k], 1);
        pick_channel(s, &mut b[..k], 2);
        luma601_planar(&r[..k], &g[..k], &b[..k], d);
    }
}

/// `floor(x / 10000)` for `x < 2^22` in u32 lanes: the estimate `((x >> 4) · 6711) >> 22`
/// (products < 2^31) is within one of it, then one exact correction step each way. Checked for
/// every `x` by a test.
#[inline(always)]
pub(super) fn floor_div_10000(x: u32) -> u32 {
    let mut q = ((x >> 4) * 6711) >> 22;
    q += u32::from((q + 1) * 10000 <= x);
    q -= u32::from(q * 10000 > x);
    q
}

dispatch! {
    /// [`luma601`] on separate R, G, B planes.
    pub fn luma601_planar(r: &[u8], g: &[u8], b: &[u8], dst: &mut [u8]) {
        for (((o, &r), &g), &b) in dst.iter_mut().zip(r).zip(g).zip(b) {
            // 2989 + 5870 + 1140 = 9999: x = weighted sum + 5000 < 2^22 (adding 5000 rounds
            // half up, as MATLAB's round does).
            let x = 2989 * u32::from(r) + 5870 * u32::from(g) + 1140 * u32::from(b) + 5000;
            *o = floor_div_10000(x) as u8;
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[allow(
    unsafe_code,
    reason = "SSE2/SSSE3/AVX2 intrinsics on bounds-checked 16/32/48/64/96-byte chunks"
)]
mod shuffle {
    #[allow(
        clippy::wildcard_imports,
        reason = "the kernels below name a dozen intrinsics"
    )]
    use std::arch::x86_64::*;

    /// Shuffle masks taking bytes `3 i + c` (i = 0..16) from three consecutive 16-byte loads,
    /// for each channel `c`.
    const MASKS: [[[u8; 16]; 3]; 3] = {
        let mut m = [[[0x80u8; 16]; 3]; 3];
        let mut c = 0;
        while c < 3 {
            let mut i = 0;
            while i < 16 {
                let k = 3 * i + c;
                m[c][k / 16][i] = (k % 16) as u8;
                i += 1;
            }
            c += 1;
        }
        m
    };

    /// The shuffle masks of channel `c` (0, 1 or 2).
    fn masks(c: usize) -> &'static [[u8; 16]; 3] {
        &MASKS[c]
    }

    /// `dst[i] = src[3 i + c]` for `dst.len() ≥ 32` and `src.len() == 3 dst.len()`: 32 pixels
    /// a step, each 128-bit lane shuffling one 48-byte group with the SSSE3 masks; the last
    /// step at `dst.len() − 32` (overlapping the one before: it writes the same values).
    #[target_feature(enable = "avx2")]
    pub(super) fn pick_channel_avx2(src: &[u8], dst: &mut [u8], c: usize) {
        let n = dst.len();
        assert!(n >= 32 && src.len() == 3 * n);
        let m = masks(c);
        let mask = |k: usize| {
            // SAFETY: `m[k]` is 16 bytes.
            let v = unsafe { _mm_loadu_si128(m[k].as_ptr().cast::<__m128i>()) };
            _mm256_broadcastsi128_si256(v)
        };
        let (ma, mb, mc) = (mask(0), mask(1), mask(2));
        let step = |i: usize, dst: &mut [u8]| {
            let s = &src[3 * i..3 * i + 96];
            // Lane 0 from bytes 16k.., lane 1 from bytes 48 + 16k.. of the 96.
            let pair = |k: usize| {
                let (lo, hi) = (&s[16 * k..16 * k + 16], &s[48 + 16 * k..64 + 16 * k]);
                // SAFETY: `lo` and `hi` are 16 bytes each (bounds-checked slices).
                unsafe {
                    _mm256_inserti128_si256::<1>(
                        _mm256_castsi128_si256(_mm_loadu_si128(lo.as_ptr().cast::<__m128i>())),
                        _mm_loadu_si128(hi.as_ptr().cast::<__m128i>()),
                    )
                }
            };
            let a = _mm256_shuffle_epi8(pair(0), ma);
            let b = _mm256_shuffle_epi8(pair(1), mb);
            let cc = _mm256_shuffle_epi8(pair(2), mc);
            let d = &mut dst[i..i + 32];
            // SAFETY: `d` is 32 bytes (a bounds-checked slice).
            unsafe {
                _mm256_storeu_si256(
                    d.as_mut_ptr().cast::<__m256i>(),
                    _mm256_or_si256(_mm256_or_si256(a, b), cc),
                );
            }
        };
        super::super::for_steps_of_32(n, |i| step(i, dst));
    }

    /// `dst[i] = src[3 i + c]` for `dst.len()` a multiple of 16 and `src.len() == 3 dst.len()`.
    #[target_feature(enable = "ssse3")]
    pub(super) fn pick_channel_ssse3(src: &[u8], dst: &mut [u8], c: usize) {
        let m = masks(c);
        // SAFETY: each pointer comes from a chunk of exactly 16 bytes (chunks_exact), so the
        // unaligned 16-byte loads and stores stay inside the slices.
        unsafe {
            let ma = _mm_loadu_si128(m[0].as_ptr().cast::<__m128i>());
            let mb = _mm_loadu_si128(m[1].as_ptr().cast::<__m128i>());
            let mc = _mm_loadu_si128(m[2].as_ptr().cast::<__m128i>());
            for (d, s) in dst.chunks_exact_mut(16).zip(src.chunks_exact(48)) {
                let (s0, rest) = s.split_at(16);
                let (s1, s2) = rest.split_at(16);
                let a = _mm_shuffle_epi8(_mm_loadu_si128(s0.as_ptr().cast::<__m128i>()), ma);
                let b = _mm_shuffle_epi8(_mm_loadu_si128(s1.as_ptr().cast::<__m128i>()), mb);
                let cc = _mm_shuffle_epi8(_mm_loadu_si128(s2.as_ptr().cast::<__m128i>()), mc);
                _mm_storeu_si128(
                    d.as_mut_ptr().cast::<__m128i>(),
                    _mm_or_si128(_mm_or_si128(a, b), cc),
                );
            }
        }
    }
}
