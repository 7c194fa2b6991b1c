//! A window's excess over a level and its first moments ([`excess_sums`]), and the window
//! runner every window kernel shares: exact integer sums, AVX2 and portable.

use super::Avx2;

/// `[Σ w, Σ w·c, Σ w·r]` over a window of `rows` rows of `cols` pixels (row `r` starts at
/// `pixels[r·stride]`), `w = max(v − t, 0)` a pixel's excess over the level `t`, `c` and `r`
/// its column and row in the window: exact integer sums (AVX2 when the CPU has it, reading
/// each row's tail in place while 32 bytes remain in `pixels`).
///
/// ```
/// use visuotact_vision::kernels::excess_sums;
/// // Two rows of three pixels, level 10: excesses 0 5 0 / 0 0 20.
/// let px = [3, 15, 10, 0, 9, 30];
/// assert_eq!(excess_sums(&px, 3, 3, 2, 10), [25, 5 + 2 * 20, 20]);
/// ```
pub fn excess_sums(pixels: &[u8], stride: usize, cols: usize, rows: usize, t: u8) -> [u64; 3] {
    excess_sums_on(Avx2::detect(), (pixels, stride, cols, rows), t)
}

/// [`excess_sums`] on `cpu`'s kernels.
#[inline(always)]
pub(crate) fn excess_sums_on(cpu: Option<Avx2>, window: Window<'_>, t: u8) -> [u64; 3] {
    on_window(
        cpu,
        window,
        t,
        #[cfg(target_arch = "x86_64")]
        simd::excess_sums_avx2,
        excess_sums_portable,
    )
}

/// A window's pixels, row stride, columns and rows.
pub(crate) type Window<'a> = (&'a [u8], usize, usize, usize);

/// Runs `avx2` on the window (`pixels` from its first row to the image's end) when `cpu` is
/// given, else `portable` on exactly its rows; the rows are bounds-checked first either way. An
/// empty window gives `T::default()`. `avx2` may require AVX2 and FMA, nothing more.
#[inline(always)]
pub(super) fn on_window<P, T: Default>(
    cpu: Option<Avx2>,
    (pixels, stride, cols, rows): Window<'_>,
    p: P,
    #[cfg(target_arch = "x86_64")] avx2: unsafe fn(&[u8], usize, usize, usize, P) -> T,
    portable: fn(&[u8], usize, usize, usize, P) -> T,
) -> T {
    if rows == 0 || cols == 0 {
        return T::default();
    }
    let rows_of = &pixels[..(rows - 1) * stride + cols];
    #[cfg(target_arch = "x86_64")]
    {
        if cpu.is_some() {
            // SAFETY: an `Avx2` exists only on a CPU with AVX2 and FMA, all `avx2` requires.
            #[allow(
                unsafe_code,
                reason = "calling a target_feature function on a CPU with it"
            )]
            return unsafe { avx2(pixels, stride, cols, rows, p) };
        }
    }
    let _ = cpu;
    portable(rows_of, stride, cols, rows, p)
}

/// Portable form of [`excess_sums`].
pub(crate) fn excess_sums_portable(
    pixels: &[u8],
    stride: usize,
    cols: usize,
    rows: usize,
    t: u8,
) -> [u64; 3] {
    let mut out = [0u64; 3];
    for r in 0..rows {
        let (mut sw, mut swc) = (0u64, 0u64);
        for (c, &v) in pixels[r * stride..r * stride + cols].iter().enumerate() {
            let w = u64::from(v.saturating_sub(t));
            sw += w;
            swc += w * c as u64;
        }
        out[0] += sw;
        out[1] += swc;
        out[2] += sw * r as u64;
    }
    out
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code, reason = "AVX2 loads inside bounds-checked row slices")]
mod simd {
    #[allow(
        clippy::wildcard_imports,
        reason = "the kernels below name two dozen intrinsics"
    )]
    use std::arch::x86_64::*;

    /// [`super::excess_sums`] on AVX2, 32 columns at a time: `Σ w` by `vpsadbw`, `Σ w·c` within
    /// a block by `vpmaddubsw` (≤ 255 · 31 per byte pair, no saturation), the block's offset
    /// and the row index applied to the 64-bit `Σ w` lanes by `vpmuludq`.
    #[target_feature(enable = "avx2")]
    pub(super) fn excess_sums_avx2(
        pixels: &[u8],
        stride: usize,
        cols: usize,
        rows: usize,
        t: u8,
    ) -> [u64; 3] {
        let idx = _mm256_setr_epi8(
            0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23,
            24, 25, 26, 27, 28, 29, 30, 31,
        );
        let level = _mm256_set1_epi8(t as i8);
        let (zero, ones) = (_mm256_setzero_si256(), _mm256_set1_epi16(1));
        // 64-bit lanes: Σ w, Σ w·(block offset), Σ w·r; 32-bit lanes of Σ w·c in the block,
        // widened once per row.
        let (mut sw, mut soff, mut sr, mut sc) = (zero, zero, zero, zero);
        // The sum of four 64-bit lanes.
        let lanes = |v: __m256i| -> u64 {
            let mut a = [0u64; 4];
            // SAFETY: `a` holds 32 bytes.
            unsafe { _mm256_storeu_si256(a.as_mut_ptr().cast::<__m256i>(), v) };
            a.iter().sum()
        };
        // A window of at most 32 columns whose rows can all be read 32 bytes in place (every
        // box but those at the image's last rows): one masked block per row, no checks.
        if cols <= 32 && rows > 0 && (rows - 1) * stride + 32 <= pixels.len() {
            let valid = _mm256_cmpgt_epi8(_mm256_set1_epi8(cols as i8), idx);
            let at = pixels.as_ptr();
            for r in 0..rows {
                // SAFETY: bytes `r·stride .. + 32` lie in `pixels` (checked above).
                let v = unsafe { _mm256_loadu_si256(at.add(r * stride).cast::<__m256i>()) };
                let w = _mm256_and_si256(_mm256_subs_epu8(v, level), valid);
                let row_w = _mm256_sad_epu8(w, zero);
                sw = _mm256_add_epi64(sw, row_w);
                sr = _mm256_add_epi64(sr, _mm256_mul_epu32(row_w, _mm256_set1_epi64x(r as i64)));
                sc = _mm256_add_epi32(sc, _mm256_madd_epi16(_mm256_maddubs_epi16(w, idx), ones));
            }
            // `sc` here holds eight 32-bit lanes (each ≤ 255 · 31 · 4 · rows), widened once.
            let lanes32 = |v: __m256i| -> u64 {
                let mut a = [0u32; 8];
                // SAFETY: `a` holds 32 bytes.
                unsafe { _mm256_storeu_si256(a.as_mut_ptr().cast::<__m256i>(), v) };
                a.iter().map(|&x| u64::from(x)).sum()
            };
            return [lanes(sw), lanes32(sc), lanes(sr)];
        }
        let mut pad: [u8; 32];
        for r in 0..rows {
            let row = &pixels[r * stride..r * stride + cols];
            let (mut row_w, mut row_c) = (zero, zero);
            for at in (0..cols).step_by(32) {
                let n = (cols - at).min(32);
                let bytes: &[u8] = match pixels.get(r * stride + at..r * stride + at + 32) {
                    Some(b) => b,
                    None => {
                        pad = [0; 32];
                        pad[..n].copy_from_slice(&row[at..at + n]);
                        &pad
                    }
                };
                // SAFETY: `bytes` holds 32 readable bytes; the rest is register arithmetic.
                let v = unsafe { _mm256_loadu_si256(bytes.as_ptr().cast::<__m256i>()) };
                let valid = _mm256_cmpgt_epi8(_mm256_set1_epi8(n as i8), idx);
                let w = _mm256_and_si256(_mm256_subs_epu8(v, level), valid);
                let block_w = _mm256_sad_epu8(w, zero);
                row_w = _mm256_add_epi64(row_w, block_w);
                soff = _mm256_add_epi64(
                    soff,
                    _mm256_mul_epu32(block_w, _mm256_set1_epi64x(at as i64)),
                );
                row_c =
                    _mm256_add_epi32(row_c, _mm256_madd_epi16(_mm256_maddubs_epi16(w, idx), ones));
            }
            sw = _mm256_add_epi64(sw, row_w);
            sr = _mm256_add_epi64(sr, _mm256_mul_epu32(row_w, _mm256_set1_epi64x(r as i64)));
            // Eight 32-bit lanes (each ≤ 255 · 31 · 4 per block, summed over ≤ cols/32 blocks)
            // folded to four and widened.
            let half = _mm_add_epi32(
                _mm256_castsi256_si128(row_c),
                _mm256_extracti128_si256::<1>(row_c),
            );
            sc = _mm256_add_epi64(sc, _mm256_cvtepi32_epi64(half));
        }
        [lanes(sw), lanes(soff) + lanes(sc), lanes(sr)]
    }
}
