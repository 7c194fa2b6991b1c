//! The grey-level centroid's window sums inside an ellipse over a background plane
//! ([`ellipse_window_sums`]): AVX2 and FMA in eight lanes, the portable loop beside them.

use super::excess::{on_window, Window};
use super::Avx2;

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
        simd::sums_avx2,
        ellipse_window_sums_portable,
    )
}

/// Portable form of [`ellipse_window_sums`] (`pixels` holds at least the window's rows).
pub(crate) fn ellipse_window_sums_portable(
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

#[cfg(target_arch = "x86_64")]
#[allow(
    unsafe_code,
    reason = "AVX2 loads of 8 bytes inside bounds-checked row slices"
)]
mod simd {
    use super::EllipseWindow;
    #[allow(
        clippy::wildcard_imports,
        reason = "the kernels below name two dozen intrinsics"
    )]
    use std::arch::x86_64::*;

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

    /// The sum of the eight lanes, pairwise.
    #[target_feature(enable = "avx2")]
    fn lanes_sum(v: __m256) -> f64 {
        let mut a = [0.0f32; 8];
        // SAFETY: `a` holds eight floats.
        unsafe { _mm256_storeu_ps(a.as_mut_ptr(), v) };
        f64::from(((a[0] + a[1]) + (a[2] + a[3])) + ((a[4] + a[5]) + (a[6] + a[7])))
    }
}
