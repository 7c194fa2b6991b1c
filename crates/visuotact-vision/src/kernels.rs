//! Pixel kernels with runtime CPU dispatch.
//!
//! Each kernel is written once as plain safe Rust that the compiler vectorises, and compiled
//! twice: for the baseline target (SSE2 on x86-64) and with AVX2 enabled. The AVX2 copy is
//! used when the running CPU has it (checked once by `std`); nothing is pinned to the build
//! machine. Both copies compute identical results (integer code, or floating point in the same
//! order of operations, with no reassociation or fused multiply-adds); the tests run whichever
//! the machine picks and compare with scalar references. Kernels the compiler would not
//! vectorise are written with intrinsics beside a portable loop: the SSSE3 and AVX2 channel
//! shuffles, the AVX2 3-tap minimum/maximum, the SSE2/AVX2 threshold bits, the AVX2 excess sums
//! and the AVX2 background-ring plane (identical results: the ring's per-lane sums are taken in
//! the portable loop's lanes and order, tested bit for bit), and the AVX2 + FMA grey-centroid
//! window sums (floating point summed in eight lanes: equal to the portable loop within 1e-4
//! relative, tested).
//!
//! A loop that calls kernels many times a frame checks the CPU once instead: the crate-internal
//! `Avx2::detect` gives a token only on a CPU with AVX2 and FMA, and the loop, compiled with
//! those features and handed the token, calls the `_on` forms of the kernels, which then inline
//! into it (the frame's opening pass and the grey-centroid refinement do).

#![allow(
    clippy::needless_range_loop,
    reason = "fixed-width inner loops index several arrays in lockstep; the index form is what vectorises"
)]

/// Generates `pub fn $name(args)` that dispatches between an AVX2 build and a baseline build of
/// the same body.
macro_rules! dispatch {
    ($(#[$m:meta])* $vis:vis fn $name:ident($($arg:ident : $ty:ty),*) $(-> $ret:ty)? $body:block) => {
        $(#[$m])*
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            #[inline(always)]
            fn body($($arg: $ty),*) $(-> $ret)? $body
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2")]
                fn avx2($($arg: $ty),*) $(-> $ret)? {
                    body($($arg),*)
                }
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU supports AVX2, checked on the line above.
                    #[allow(unsafe_code, reason = "calling a target_feature function after the runtime check")]
                    unsafe {
                        return avx2($($arg),*);
                    }
                }
            }
            body($($arg),*)
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

/// `dst[i] = src[3 i + c]`: one channel of interleaved RGB (AVX2 or SSSE3 byte shuffles when
/// the CPU has them, else the portable loop).
pub fn pick_channel(src: &[u8], dst: &mut [u8], c: usize) {
    if let Some(cpu) = Avx2::detect() {
        pick_channel_on(Some(cpu), src, dst, c);
        return;
    }
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("ssse3") {
            // SAFETY: the CPU supports SSSE3, checked on the line above.
            #[allow(
                unsafe_code,
                reason = "calling a target_feature function after the runtime check"
            )]
            unsafe {
                pick_channel_ssse3_then_portable(src, dst, c);
            }
            return;
        }
    }
    pick_channel_portable(src, dst, c);
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
    pick_channel(src, dst, c);
}

/// The SSSE3 shuffles over whole 16-pixel steps, the portable loop over the rest.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "ssse3")]
fn pick_channel_ssse3_then_portable(src: &[u8], dst: &mut [u8], c: usize) {
    let n = dst.len().min(src.len() / 3) / 16 * 16;
    shuffle::pick_channel_ssse3(&src[..3 * n], &mut dst[..n], c);
    pick_channel_portable(&src[3 * n..], &mut dst[n..], c);
}

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
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked on the line above.
            #[allow(
                unsafe_code,
                reason = "calling a target_feature function after the runtime check"
            )]
            unsafe {
                window::above_bits_avx2(&src[..n], t, &mut bits[..n / 64]);
            }
        } else {
            // SSE2 is part of the x86-64 baseline.
            shuffle::above_bits_sse2(&src[..n], t, &mut bits[..n / 64]);
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

#[cfg(target_arch = "x86_64")]
#[allow(
    unsafe_code,
    reason = "SSE2/SSSE3/AVX2 intrinsics on bounds-checked 16/32/48/64/96-byte chunks"
)]
mod shuffle {
    use std::arch::x86_64::{
        __m128i, __m256i, _mm256_broadcastsi128_si256, _mm256_castsi128_si256,
        _mm256_inserti128_si256, _mm256_or_si256, _mm256_shuffle_epi8, _mm256_storeu_si256,
        _mm_cmpeq_epi8, _mm_loadu_si128, _mm_max_epu8, _mm_movemask_epi8, _mm_or_si128,
        _mm_set1_epi8, _mm_shuffle_epi8, _mm_storeu_si128,
    };

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
        super::for_steps_of_32(n, |i| step(i, dst));
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

dispatch! {
    /// Portable form of [`pick_channel`].
    pub fn pick_channel_portable(src: &[u8], dst: &mut [u8], c: usize) {
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
fn floor_div_10000(x: u32) -> u32 {
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

/// `dst[i] = min(a[i], b[i], c[i])` (or max): the 3-tap step of a separable filter. AVX2 when
/// the CPU has it and there are at least 32 bytes (the last 32 are taken again, overlapping, so
/// no byte takes a scalar tail), else [`extremum3_portable`].
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
                window::extremum3_avx2(&a[..n], &b[..n], &c[..n], &mut dst[..n], max);
            }
            return;
        }
    }
    let _ = cpu;
    extremum3_portable(a, b, c, dst, max);
}

dispatch! {
    /// Portable form of [`extremum3`].
    pub fn extremum3_portable(a: &[u8], b: &[u8], c: &[u8], dst: &mut [u8], max: bool) {
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
        window::excess_sums_avx2,
        excess_sums_portable,
    )
}

/// A window's pixels, row stride, columns and rows.
pub(crate) type Window<'a> = (&'a [u8], usize, usize, usize);

/// Runs `avx2` on the window (`pixels` from its first row to the image's end) when `cpu` is
/// given, else `portable` on exactly its rows; the rows are bounds-checked first either way. An
/// empty window gives `T::default()`. `avx2` may require AVX2 and FMA, nothing more.
#[inline(always)]
fn on_window<P, T: Default>(
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
pub fn excess_sums_portable(
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

/// A grey-level centroid window for [`ellipse_window_sums`]: a pixel at offset `(dx, dy)` from
/// the centroid is inside the ellipse when `q11·dx² + 2·q12·dx·dy + q22·dy² ≤ 1`, and weighs
/// `max(v − p0 − sx·dx − sy·dy, 0)` (its grey value above the background plane).
#[derive(Clone, Copy, Debug)]
pub struct EllipseWindow {
    /// `dx` of the window's first column.
    pub dx0: f32,
    /// `dy` of the window's first row.
    pub dy0: f32,
    /// The ellipse's quadratic form.
    pub q11: f32,
    /// The ellipse's quadratic form (off-diagonal).
    pub q12: f32,
    /// The ellipse's quadratic form.
    pub q22: f32,
    /// Background level at the centroid.
    pub p0: f32,
    /// Background slope along x.
    pub sx: f32,
    /// Background slope along y.
    pub sy: f32,
}

/// Sums over a window of `rows` rows of `cols` pixels (row `r` starts at `pixels[r·stride]`) of
/// the weights `w` inside the ellipse, of `w·dx` and of `w·dy`: `out = [Σ w, Σ w·dx, Σ w·dy]`.
/// AVX2 (eight lanes, each row's tail padded and masked) when the CPU has it, else a scalar
/// loop; both in `f32`, reduced in `f64`.
pub fn ellipse_window_sums(
    pixels: &[u8],
    stride: usize,
    cols: usize,
    rows: usize,
    e: EllipseWindow,
) -> [f64; 3] {
    ellipse_window_sums_on(Avx2::detect(), (pixels, stride, cols, rows), e)
}

/// [`ellipse_window_sums`] on `cpu`'s kernels.
#[inline(always)]
pub(crate) fn ellipse_window_sums_on(
    cpu: Option<Avx2>,
    window: Window<'_>,
    e: EllipseWindow,
) -> [f64; 3] {
    on_window(
        cpu,
        window,
        e,
        #[cfg(target_arch = "x86_64")]
        window::sums_avx2,
        ellipse_window_sums_portable,
    )
}

/// Portable form of [`ellipse_window_sums`] (`pixels` holds at least the window's rows).
pub fn ellipse_window_sums_portable(
    pixels: &[u8],
    stride: usize,
    cols: usize,
    rows: usize,
    e: EllipseWindow,
) -> [f64; 3] {
    let (mut sw, mut sx, mut sy) = (0.0f32, 0.0f32, 0.0f32);
    for r in 0..rows {
        let dy = e.dy0 + r as f32;
        let (bq, cq) = (2.0 * e.q12 * dy, e.q22 * dy * dy - 1.0);
        let base = e.p0 + e.sy * dy;
        for (c, &v) in pixels[r * stride..r * stride + cols].iter().enumerate() {
            let dx = e.dx0 + c as f32;
            if (e.q11 * dx + bq) * dx + cq <= 0.0 {
                let w = (f32::from(v) - base - e.sx * dx).max(0.0);
                sw += w;
                sx += w * dx;
                sy += w * dy;
            }
        }
    }
    [f64::from(sw), f64::from(sx), f64::from(sy)]
}

/// The background ring of a grey-level centroid window: its four sides in window-centred
/// coordinates (`top` at `y = −ym`, `bottom` at `ym`, both from `x = −xm`; `left` at
/// `x = −xm`, `right` at `xm`, both from `y = 1 − ym`).
pub(crate) struct RingSides<'a> {
    pub(crate) top: &'a [u8],
    pub(crate) bottom: &'a [u8],
    pub(crate) left: &'a [u8],
    pub(crate) right: &'a [u8],
    pub(crate) xm: f32,
    pub(crate) ym: f32,
}

/// One side's values and where the plane's level along it starts and how it steps.
type Side<'a> = (&'a [u8], f32, f32);

impl RingSides<'_> {
    /// See [`ring_plane_on`]: the portable form.
    #[inline(always)]
    fn plane(&self) -> Option<(f32, f32, f32)> {
        self.plane_by(
            |v| v.iter().map(|&x| u32::from(x)).sum(),
            residual_sq_max,
            kept_mean,
        )
    }

    /// See [`ring_plane_on`], with `sum(side)` the sum of a side's values, `residuals(side, start,
    /// step)` its `Σ r²` (lanes `i mod 8` summed pairwise) and `max |r|`, and `kept(side, start,
    /// step, cut)` as [`kept_mean`].
    #[inline(always)]
    fn plane_by(
        &self,
        sum: impl Fn(&[u8]) -> u32,
        residuals: impl Fn(&[u8], f32, f32) -> (f32, f32),
        kept: impl Fn(&[u8], f32, f32, f32) -> Option<f32>,
    ) -> Option<(f32, f32, f32)> {
        let mean =
            |v: &[u8]| -> Option<f32> { (!v.is_empty()).then(|| sum(v) as f32 / v.len() as f32) };
        let first = self.plane_of_means([
            mean(self.top)?,
            mean(self.bottom)?,
            mean(self.left)?,
            mean(self.right)?,
        ]);
        let sides = self.sides(first);
        // Residuals against the plane: RMS and the worst.
        let (mut sq, mut worst, mut n) = (0.0f32, 0.0f32, 0usize);
        for &(vals, start, step) in &sides {
            let (s, w) = residuals(vals, start, step);
            sq += s;
            worst = worst.max(w);
            n += vals.len();
        }
        let cut = 3.0 * (sq / n as f32).sqrt().max(0.5);
        if worst <= cut {
            return Some(first);
        }
        let kept = |&(vals, start, step): &Side<'_>| kept(vals, start, step, cut);
        Some(self.plane_of_means([
            kept(&sides[0])?,
            kept(&sides[1])?,
            kept(&sides[2])?,
            kept(&sides[3])?,
        ]))
    }

    /// The fewest values on a side.
    fn shortest(&self) -> usize {
        self.top
            .len()
            .min(self.bottom.len())
            .min(self.left.len())
            .min(self.right.len())
    }

    /// The plane from the means of the top, bottom, left and right sides.
    fn plane_of_means(&self, [t, bo, l, r]: [f32; 4]) -> (f32, f32, f32) {
        (
            0.25 * (t + bo + l + r),
            (r - l) / (2.0 * self.xm),
            (bo - t) / (2.0 * self.ym),
        )
    }

    /// Each side with the plane's level at its first pixel and its step per pixel.
    fn sides(&self, (mid, sx, sy): (f32, f32, f32)) -> [Side<'_>; 4] {
        let (xm, ym) = (self.xm, self.ym);
        [
            (self.top, mid - sx * xm - sy * ym, sx),
            (self.bottom, mid - sx * xm + sy * ym, sx),
            (self.left, mid - sx * xm + sy * (1.0 - ym), sy),
            (self.right, mid + sx * xm + sy * (1.0 - ym), sy),
        ]
    }
}

/// Lanes of the ring's residual loops.
const LANES: usize = 8;

/// Calls `f(lane, v_i, |r_i|)` for the residuals `r_i = v_i − start − step·i` of `vals`, the
/// lane being `i mod LANES`. Inlined into fixed-width loops over per-lane state, which the
/// compiler vectorises (a running sum or maximum over one scalar is a chain it cannot).
#[inline(always)]
fn for_residuals(vals: &[u8], start: f32, step: f32, mut f: impl FnMut(usize, u8, f32)) {
    let (chunks, rest) = vals.as_chunks::<LANES>();
    let mut i0 = 0.0f32;
    for c in chunks {
        for (k, &v) in c.iter().enumerate() {
            f(k, v, (f32::from(v) - start - step * (i0 + k as f32)).abs());
        }
        i0 += LANES as f32;
    }
    for (k, &v) in rest.iter().enumerate() {
        f(k, v, (f32::from(v) - start - step * (i0 + k as f32)).abs());
    }
}

/// The mean of the values whose residuals `|v_i − start − step·i|` are at most `cut`, `None`
/// when none is.
#[inline(always)]
fn kept_mean(vals: &[u8], start: f32, step: f32, cut: f32) -> Option<f32> {
    // Integer sums: exact, so the order of the lanes does not matter.
    let (mut sum, mut kept) = ([0u32; LANES], [0u32; LANES]);
    for_residuals(vals, start, step, |k, v, r| {
        let keep = u32::from(r <= cut);
        sum[k] += keep * u32::from(v);
        kept[k] += keep;
    });
    let (sum, kept) = (sum.iter().sum::<u32>(), kept.iter().sum::<u32>());
    (kept > 0).then(|| sum as f32 / kept as f32)
}

/// `Σ r²` and `max |r|` of the residuals `r_i = v_i − start − step·i`.
#[inline(always)]
fn residual_sq_max(vals: &[u8], start: f32, step: f32) -> (f32, f32) {
    let (mut sq, mut worst) = ([0.0f32; LANES], [0.0f32; LANES]);
    for_residuals(vals, start, step, |k, _, r| {
        sq[k] += r * r;
        // Not `f32::max`: residuals are finite, and its NaN handling blocks vectorising.
        worst[k] = if r > worst[k] { r } else { worst[k] };
    });
    let total = ((sq[0] + sq[1]) + (sq[2] + sq[3])) + ((sq[4] + sq[5]) + (sq[6] + sq[7]));
    (total, worst.into_iter().fold(0.0, f32::max))
}

/// The background plane `v = mid + sx·x + sy·y` of a grey-level centroid window's ring: the
/// mean level and the slopes from the means of opposite sides. Ring pixels over 3 RMS (at least
/// 1.5 grey levels) from it, such as a neighbour's edge, are dropped and the plane taken again;
/// `None` when a side is empty. Explicit AVX2 when the CPU has it and every side has at least
/// eight values, else the portable loops; the same arithmetic either way (per-lane sums in the
/// same lanes and order, no fused multiply-adds), so the same plane. On `cpu`'s kernels.
#[inline(always)]
pub(crate) fn ring_plane_on(cpu: Option<Avx2>, sides: &RingSides<'_>) -> Option<(f32, f32, f32)> {
    #[cfg(target_arch = "x86_64")]
    {
        if cpu.is_some() && sides.shortest() >= LANES {
            // SAFETY: an `Avx2` exists only on a CPU with AVX2.
            #[allow(
                unsafe_code,
                reason = "calling a target_feature function on a CPU with it"
            )]
            return unsafe { window::ring_plane_avx2(sides) };
        }
    }
    let _ = cpu;
    sides.plane()
}

#[cfg(target_arch = "x86_64")]
#[allow(
    unsafe_code,
    reason = "AVX2 intrinsics on 8- and 32-byte loads inside bounds-checked row slices"
)]
mod window {
    use std::arch::x86_64::{
        __m256, __m256i, _mm256_add_epi32, _mm256_add_epi64, _mm256_add_ps, _mm256_and_ps,
        _mm256_and_si256, _mm256_castps_si256, _mm256_castsi256_ps, _mm256_castsi256_si128,
        _mm256_cmp_ps, _mm256_cmpgt_epi32, _mm256_cmpgt_epi8, _mm256_cvtepi32_epi64,
        _mm256_cvtepi32_ps, _mm256_cvtepu8_epi32, _mm256_extracti128_si256, _mm256_fmadd_ps,
        _mm256_fnmadd_ps, _mm256_loadu_si256, _mm256_madd_epi16, _mm256_maddubs_epi16,
        _mm256_max_ps, _mm256_mul_epu32, _mm256_mul_ps, _mm256_permutevar8x32_epi32,
        _mm256_sad_epu8, _mm256_set1_epi16, _mm256_set1_epi32, _mm256_set1_epi64x,
        _mm256_set1_epi8, _mm256_set1_ps, _mm256_setr_epi32, _mm256_setr_epi8, _mm256_setzero_ps,
        _mm256_setzero_si256, _mm256_storeu_ps, _mm256_storeu_si256, _mm256_sub_epi32,
        _mm256_sub_ps, _mm256_subs_epu8, _mm_add_epi32, _mm_loadl_epi64, _CMP_LE_OQ,
    };
    use std::arch::x86_64::{
        _mm256_cmpeq_epi8, _mm256_max_epu8, _mm256_min_epu8, _mm256_movemask_epi8,
    };

    use super::{EllipseWindow, RingSides};

    /// [`super::ellipse_window_sums`] on AVX2 and FMA; `pixels` holds at least the window's
    /// rows. A row is taken eight pixels a step; where its length is not a multiple of eight,
    /// the last step reads the row's last eight pixels in place, the lanes already summed
    /// masked off (a window under eight columns wide: each row copied into a zeroed step).
    /// `Σ w·dy` is taken per row, as `dy · Σ_row w`.
    #[target_feature(enable = "avx2,fma")]
    pub(super) fn sums_avx2(
        pixels: &[u8],
        stride: usize,
        cols: usize,
        rows: usize,
        e: EllipseWindow,
    ) -> [f64; 3] {
        if rows == 0 || cols == 0 {
            return [0.0; 3];
        }
        let lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        let lane_f = _mm256_cvtepi32_ps(lane);
        let (q11, sxv) = (_mm256_set1_ps(e.q11), _mm256_set1_ps(e.sx));
        let (zero, eight) = (_mm256_setzero_ps(), _mm256_set1_ps(8.0));
        let (mut sw, mut sx, mut sy) = (zero, zero, zero);
        // Whole steps at 0, 8, …; then the step at `last`, whose first `seen` lanes the whole
        // steps took (none where `seen` is 8).
        let whole = cols / 8;
        let last = cols.max(8) - 8;
        let seen = (8 * whole).saturating_sub(last) as i32;
        let last_valid = _mm256_castsi256_ps(_mm256_cmpgt_epi32(lane, _mm256_set1_epi32(seen - 1)));
        let narrow_valid =
            _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(cols as i32), lane));
        let dx_first = _mm256_add_ps(_mm256_set1_ps(e.dx0), lane_f);
        let dx_last = _mm256_add_ps(_mm256_set1_ps(e.dx0 + last as f32), lane_f);
        // Every row's `cols` bytes (so every eight-byte step at `c ≤ cols − 8` of a row) lie
        // inside `pixels`.
        let window = &pixels[..(rows - 1) * stride + cols];
        let at = window.as_ptr();
        for r in 0..rows {
            let dyf = e.dy0 + r as f32;
            let bq = _mm256_set1_ps(2.0 * e.q12 * dyf);
            let cq = _mm256_set1_ps(e.q22 * dyf * dyf - 1.0);
            let base = _mm256_set1_ps(e.p0 + e.sy * dyf);
            // The weights of the eight pixels at `ptr` (columns `dx`), 0 outside the ellipse.
            macro_rules! weights {
                ($ptr:expr, $dx:expr) => {{
                    let dx = $dx;
                    let v = _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_loadl_epi64($ptr.cast())));
                    // v − (p0 + sy·dy) − sx·dx, not below 0.
                    let w = _mm256_max_ps(_mm256_fnmadd_ps(sxv, dx, _mm256_sub_ps(v, base)), zero);
                    let q = _mm256_fmadd_ps(_mm256_fmadd_ps(q11, dx, bq), dx, cq);
                    _mm256_and_ps(w, _mm256_cmp_ps::<_CMP_LE_OQ>(q, zero))
                }};
            }
            // The row's own sums, added to the totals once per row: each row's chain of adds
            // is a few steps long and rows overlap, where one running total over every step
            // would wait on each fused multiply-add's latency.
            let (mut row_w, mut row_x) = (zero, zero);
            if cols >= 8 {
                let mut dx = dx_first;
                for c in 0..whole {
                    // SAFETY: bytes `r·stride + 8c .. + 8` with `8c + 8 ≤ cols` lie in `window`.
                    let w = unsafe { weights!(at.add(r * stride + 8 * c), dx) };
                    row_w = _mm256_add_ps(row_w, w);
                    row_x = _mm256_fmadd_ps(w, dx, row_x);
                    dx = _mm256_add_ps(dx, eight);
                }
                if seen < 8 {
                    // SAFETY: bytes `r·stride + cols − 8 .. + 8` lie in `window`.
                    let w = unsafe { weights!(at.add(r * stride + last), dx_last) };
                    let w = _mm256_and_ps(w, last_valid);
                    row_w = _mm256_add_ps(row_w, w);
                    row_x = _mm256_fmadd_ps(w, dx_last, row_x);
                }
            } else {
                let mut v = [0u8; 8];
                v[..cols].copy_from_slice(&window[r * stride..r * stride + cols]);
                // SAFETY: `v` is 8 bytes.
                let w = unsafe { weights!(v.as_ptr(), dx_first) };
                let w = _mm256_and_ps(w, narrow_valid);
                row_w = w;
                row_x = _mm256_mul_ps(w, dx_first);
            }
            sw = _mm256_add_ps(sw, row_w);
            sx = _mm256_add_ps(sx, row_x);
            sy = _mm256_fmadd_ps(row_w, _mm256_set1_ps(dyf), sy);
        }
        [lanes_sum(sw), lanes_sum(sx), lanes_sum(sy)]
    }

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
        super::for_steps_of_32(n, |i| step(i, dst));
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

    /// The values of `vals` (at least eight) eight at a time as `i32` lanes, with their
    /// indices as `f32` lanes and a mask of the lanes to use: whole steps at `0, 8, …`, then,
    /// where the length is not a multiple of eight, the last eight values loaded in place and
    /// rotated so that lane `k` holds index `k` mod 8 (the portable loop's lane), the lanes
    /// already seen masked off.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn for_eights(vals: &[u8], mut f: impl FnMut(__m256i, __m256, __m256i)) {
        let n = vals.len();
        let lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        let load = |eight: &[u8]| {
            let eight: &[u8; 8] = eight.try_into().unwrap_or(&[0; 8]);
            // SAFETY: `eight` is 8 readable bytes.
            _mm256_cvtepu8_epi32(unsafe { _mm_loadl_epi64(eight.as_ptr().cast()) })
        };
        let mut at = 0;
        while at + 8 <= n {
            let index = _mm256_cvtepi32_ps(_mm256_add_epi32(_mm256_set1_epi32(at as i32), lane));
            f(load(&vals[at..at + 8]), index, _mm256_set1_epi32(-1));
            at += 8;
        }
        let rest = (n - at) as i32;
        if rest > 0 {
            // Loaded lane j is index n − 8 + j; lane k wants index at + k = n − rest + k.
            let from = _mm256_and_si256(
                _mm256_add_epi32(lane, _mm256_set1_epi32(8 - rest)),
                _mm256_set1_epi32(7),
            );
            let v = _mm256_permutevar8x32_epi32(load(&vals[n - 8..]), from);
            let index = _mm256_cvtepi32_ps(_mm256_add_epi32(_mm256_set1_epi32(at as i32), lane));
            f(v, index, _mm256_cmpgt_epi32(_mm256_set1_epi32(rest), lane));
        }
    }

    /// [`super::ring_plane_on`] on AVX2, every side at least eight values long.
    #[target_feature(enable = "avx2")]
    pub(super) fn ring_plane_avx2(s: &RingSides<'_>) -> Option<(f32, f32, f32)> {
        let sum = |vals: &[u8]| {
            let mut acc = _mm256_setzero_si256();
            for_eights(vals, |v, _, valid| {
                acc = _mm256_add_epi32(acc, _mm256_and_si256(v, valid));
            });
            lanes_u32(acc)
        };
        // |(v − start) − step·i|, 0 in the lanes not to use.
        let magnitude = _mm256_castsi256_ps(_mm256_set1_epi32(i32::MAX));
        let residual = |v: __m256i, index: __m256, valid: __m256i, start: __m256, step: __m256| {
            let r = _mm256_sub_ps(
                _mm256_sub_ps(_mm256_cvtepi32_ps(v), start),
                _mm256_mul_ps(step, index),
            );
            _mm256_and_ps(r, _mm256_and_ps(magnitude, _mm256_castsi256_ps(valid)))
        };
        let residuals = |vals: &[u8], start: f32, step: f32| {
            let (start, step) = (_mm256_set1_ps(start), _mm256_set1_ps(step));
            let (mut sq, mut worst) = (_mm256_setzero_ps(), _mm256_setzero_ps());
            for_eights(vals, |v, index, valid| {
                let r = residual(v, index, valid, start, step);
                sq = _mm256_add_ps(sq, _mm256_mul_ps(r, r));
                worst = _mm256_max_ps(r, worst);
            });
            let (mut q, mut w) = ([0.0f32; 8], [0.0f32; 8]);
            // SAFETY: `q` and `w` hold eight floats each.
            unsafe {
                _mm256_storeu_ps(q.as_mut_ptr(), sq);
                _mm256_storeu_ps(w.as_mut_ptr(), worst);
            }
            let total = ((q[0] + q[1]) + (q[2] + q[3])) + ((q[4] + q[5]) + (q[6] + q[7]));
            (total, w.into_iter().fold(0.0, f32::max))
        };
        // Integer sums of the values within the cut and their count: exact in any order.
        let kept = |vals: &[u8], start: f32, step: f32, cut: f32| {
            let (start, step, cut) = (
                _mm256_set1_ps(start),
                _mm256_set1_ps(step),
                _mm256_set1_ps(cut),
            );
            let (mut sum, mut count) = (_mm256_setzero_si256(), _mm256_setzero_si256());
            for_eights(vals, |v, index, valid| {
                let r = residual(v, index, valid, start, step);
                let keep = _mm256_and_si256(
                    _mm256_castps_si256(_mm256_cmp_ps::<_CMP_LE_OQ>(r, cut)),
                    valid,
                );
                sum = _mm256_add_epi32(sum, _mm256_and_si256(v, keep));
                count = _mm256_sub_epi32(count, keep);
            });
            let (sum, count) = (lanes_u32(sum), lanes_u32(count));
            (count > 0).then(|| sum as f32 / count as f32)
        };
        s.plane_by(sum, residuals, kept)
    }

    /// The sum of the eight `u32` lanes.
    #[target_feature(enable = "avx2")]
    fn lanes_u32(v: __m256i) -> u32 {
        let mut a = [0u32; 8];
        // SAFETY: `a` holds 32 bytes.
        unsafe { _mm256_storeu_si256(a.as_mut_ptr().cast::<__m256i>(), v) };
        a.iter().sum()
    }

    /// The sum of the eight lanes, pairwise.
    #[target_feature(enable = "avx2")]
    fn lanes_sum(v: __m256) -> f64 {
        let mut a = [0.0f32; 8];
        // SAFETY: `a` holds eight floats.
        unsafe { _mm256_storeu_ps(a.as_mut_ptr(), v) };
        f64::from(((a[0] + a[1]) + (a[2] + a[3])) + ((a[4] + a[5]) + (a[6] + a[7])))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn division_is_exact_for_every_luma_sum() {
        for x in 0..=255 * 9999 + 5000u32 {
            assert_eq!(floor_div_10000(x), x / 10000, "x = {x}");
        }
    }

    #[test]
    fn luma_is_exact_for_every_colour() {
        // Every (r, g, b) on a coarse lattice plus the extremes, against integer division.
        let mut r = Vec::new();
        let mut g = Vec::new();
        let mut b = Vec::new();
        for rv in (0..=255u32).step_by(3).chain([254, 255]) {
            for gv in (0..=255u32).step_by(5).chain([254, 255]) {
                for bv in (0..=255u32).step_by(7).chain([254, 255]) {
                    r.push(rv as u8);
                    g.push(gv as u8);
                    b.push(bv as u8);
                }
            }
        }
        let mut out = vec![0u8; r.len()];
        luma601_planar(&r, &g, &b, &mut out);
        for i in 0..out.len() {
            let x = 2989 * u32::from(r[i]) + 5870 * u32::from(g[i]) + 1140 * u32::from(b[i]) + 5000;
            assert_eq!(
                u32::from(out[i]),
                x / 10000,
                "rgb {} {} {}",
                r[i],
                g[i],
                b[i]
            );
        }
    }

    #[test]
    fn excess_sums_match_a_brute_force_count() {
        let stride = 101;
        let pixels: Vec<u8> = (0..stride * 9)
            .map(|i| ((i * 89 + 13) % 256) as u8)
            .collect();
        for cols in [1, 5, 31, 32, 33, 64, 70, 101] {
            for rows in [1, 2, 9] {
                for t in [0, 90, 200, 255] {
                    let mut want = [0u64; 3];
                    for r in 0..rows {
                        for c in 0..cols {
                            let w = u64::from(pixels[r * stride + c].saturating_sub(t));
                            want[0] += w;
                            want[1] += w * c as u64;
                            want[2] += w * r as u64;
                        }
                    }
                    let what = format!("{cols} x {rows}, level {t}");
                    assert_eq!(excess_sums(&pixels, stride, cols, rows, t), want, "{what}");
                    assert_eq!(excess_sums_portable(&pixels, stride, cols, rows, t), want);
                    // The last row's tail copied instead of read in place.
                    let exact = &pixels[..(rows - 1) * stride + cols];
                    assert_eq!(excess_sums(exact, stride, cols, rows, t), want, "{what}");
                }
            }
        }
    }

    #[test]
    fn ring_plane_equals_the_portable_loops() {
        // Sides of 5 to 40 values on a sloped background with noise, some with a neighbour's
        // bright edge (the outlier pass) and some flat: the dispatched plane (AVX2 where the
        // CPU has it) equals the portable one exactly.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = |m: u64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state % m
        };
        let mut outliers = 0;
        for case in 0..3000 {
            let (nw, nh) = (5 + next(36) as usize, 7 + next(36) as usize);
            let (gx, gy) = (next(7) as f32 - 3.0, next(7) as f32 - 3.0);
            let noise = next(4);
            let mut px = |x: usize, y: usize| {
                let v =
                    120.0 + gx * x as f32 * 0.3 + gy * y as f32 * 0.3 + next(2 * noise + 1) as f32;
                v as u8
            };
            let top: Vec<u8> = (0..nw).map(|x| px(x, 0)).collect();
            let mut bottom: Vec<u8> = (0..nw).map(|x| px(x, nh - 1)).collect();
            let left: Vec<u8> = (1..nh - 1).map(|y| px(0, y)).collect();
            let right: Vec<u8> = (1..nh - 1).map(|y| px(nw - 1, y)).collect();
            if case % 3 == 0 {
                let at = next(nw as u64) as usize;
                for v in &mut bottom[at..(at + 4).min(nw)] {
                    *v = 250;
                }
            }
            let sides = RingSides {
                top: &top,
                bottom: &bottom,
                left: &left,
                right: &right,
                xm: 0.5 * (nw - 1) as f32,
                ym: 0.5 * (nh - 1) as f32,
            };
            let (got, want) = (ring_plane_on(Avx2::detect(), &sides), sides.plane());
            let bits = |p: Option<(f32, f32, f32)>| {
                p.map(|(a, b, c)| (a.to_bits(), b.to_bits(), c.to_bits()))
            };
            assert_eq!(bits(got), bits(want), "case {case}: {nw} x {nh}");
            let first = sides.plane_of_means([
                top.iter().map(|&v| f32::from(v)).sum::<f32>() / nw as f32,
                bottom.iter().map(|&v| f32::from(v)).sum::<f32>() / nw as f32,
                left.iter().map(|&v| f32::from(v)).sum::<f32>() / left.len() as f32,
                right.iter().map(|&v| f32::from(v)).sum::<f32>() / right.len() as f32,
            ]);
            outliers += usize::from((first.0 - want.unwrap().0).abs() > 1e-3);
        }
        assert!(outliers > 300, "the outlier pass ran {outliers} times");
    }

    #[test]
    fn ellipse_window_sums_match_scalar() {
        let stride = 31;
        let pixels: Vec<u8> = (0..stride * 12)
            .map(|i| ((i * 53 + 7) % 256) as u8)
            .collect();
        let e = EllipseWindow {
            dx0: -11.5,
            dy0: -5.25,
            q11: 0.01,
            q12: 0.004,
            q22: 0.03,
            p0: 60.0,
            sx: 0.7,
            sy: -0.4,
        };
        for cols in [0, 1, 7, 8, 9, 16, 23, 29] {
            for rows in [0, 1, 5, 12] {
                let mut want = [0.0f64; 3];
                for r in 0..rows {
                    for c in 0..cols {
                        let (dx, dy) = (f64::from(e.dx0) + c as f64, f64::from(e.dy0) + r as f64);
                        let q = f64::from(e.q11) * dx * dx
                            + 2.0 * f64::from(e.q12) * dx * dy
                            + f64::from(e.q22) * dy * dy;
                        let v = f64::from(pixels[r * stride + c]);
                        let bg = f64::from(e.p0) + f64::from(e.sx) * dx + f64::from(e.sy) * dy;
                        if q <= 1.0 {
                            let w = (v - bg).max(0.0);
                            want[0] += w;
                            want[1] += w * dx;
                            want[2] += w * dy;
                        }
                    }
                }
                let out = ellipse_window_sums(&pixels, stride, cols, rows, e);
                // Tails read in place (bytes past the window masked) and copied agree.
                if rows > 0 {
                    let exact = &pixels[..(rows - 1) * stride + cols];
                    assert_eq!(ellipse_window_sums(exact, stride, cols, rows, e), out);
                }
                let portable = ellipse_window_sums_portable(&pixels, stride, cols, rows, e);
                for k in 0..3 {
                    assert!(
                        (portable[k] - want[k]).abs() <= 1e-4 * want[k].abs().max(10.0),
                        "portable {cols} x {rows}, sum {k}: {portable:?} vs {want:?}"
                    );
                    assert!(
                        (out[k] - want[k]).abs() <= 1e-4 * want[k].abs().max(10.0),
                        "{cols} x {rows}, sum {k}: {out:?} vs {want:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn kernels_match_scalar() {
        let src: Vec<u8> = (0..3 * 131).map(|i| ((i * 37 + 11) % 251) as u8).collect();
        for c in 0..3 {
            // Under, at and past one or two 32-pixel steps (the overlapping last step).
            for n in [0, 1, 15, 16, 31, 32, 33, 47, 64, 65, 95, 131] {
                let mut d = vec![0; n];
                pick_channel(&src[..3 * n], &mut d, c);
                assert!(
                    d.iter().enumerate().all(|(i, &v)| v == src[3 * i + c]),
                    "{n}"
                );
                let mut e = vec![0; n];
                pick_channel_portable(&src[..3 * n], &mut e, c);
                assert_eq!(d, e);
            }
        }
        let mut l = vec![0; 131];
        luma601(&src, &mut l, &mut Vec::new());
        for (i, &v) in l.iter().enumerate() {
            let x = 2989 * u32::from(src[3 * i])
                + 5870 * u32::from(src[3 * i + 1])
                + 1140 * u32::from(src[3 * i + 2]);
            assert_eq!(u32::from(v), (x + 5000) / 10000);
        }
        // Lengths below, at and past one 32-byte step, with and without an overlapping tail.
        for n in [0, 1, 31, 32, 33, 63, 64, 65, 100] {
            let (a, b, c) = (&src[..n], &src[1..n + 1], &src[2..n + 2]);
            let mut d = vec![0; n];
            extremum3(a, b, c, &mut d, false);
            assert!((0..n).all(|i| d[i] == a[i].min(b[i]).min(c[i])), "min, {n}");
            extremum3(a, b, c, &mut d, true);
            assert!((0..n).all(|i| d[i] == a[i].max(b[i]).max(c[i])), "max, {n}");
        }
        let mut bytes = vec![0u8; 150];
        above(&src[..150], 120, &mut bytes);
        let mut bits = vec![0u64; 3];
        pack_bits(&bytes, &mut bits);
        for i in 0..150 {
            assert_eq!((bits[i / 64] >> (i % 64)) & 1 == 1, src[i] > 120, "bit {i}");
        }
        for t in [0u8, 1, 120, 200, 254, 255] {
            let mut direct = vec![0u64; 3];
            above_bits(&src[..150], t, &mut direct);
            for i in 0..150 {
                assert_eq!(
                    (direct[i / 64] >> (i % 64)) & 1 == 1,
                    src[i] > t,
                    "t {t} bit {i}"
                );
            }
        }
    }
}
