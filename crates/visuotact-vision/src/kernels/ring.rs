//! The background plane of a grey-level centroid window, fitted to the ring around it with
//! outliers dropped ([`ring_plane_on`]): AVX2 and the portable loops, identical results.

use super::Avx2;

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
    pub(super) fn plane(&self) -> Option<(f32, f32, f32)> {
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
    pub(super) fn plane_of_means(&self, [t, bo, l, r]: [f32; 4]) -> (f32, f32, f32) {
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
            return unsafe { simd::ring_plane_avx2(sides) };
        }
    }
    let _ = cpu;
    sides.plane()
}

#[cfg(target_arch = "x86_64")]
#[allow(
    unsafe_code,
    reason = "AVX2 loads of 8 bytes inside bounds-checked side slices"
)]
mod simd {
    use super::RingSides;
    #[allow(
        clippy::wildcard_imports,
        reason = "the kernels below name two dozen intrinsics"
    )]
    use std::arch::x86_64::*;

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
}
