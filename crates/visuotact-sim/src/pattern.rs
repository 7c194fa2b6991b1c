//! Marker patterns with exact truth: a dot grid pressed and dragged, or concentric annuli.
//!
//! The press model is kinematic, not physical: a Gaussian bump of width `sigma_px` around the
//! contact pushes markers outwards by `push_px`, drags them by `(shear_x_px, shear_y_px)`,
//! scales them by `1 + grow` and stretches them radially by `1 + stretch` (all times the bump).
//! Each marker stays an exact ellipse, so its true centre, area and eccentricity are known.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use visuotact_image::RgbImage;

use crate::render::{Canvas, Ellipse};

/// Camera and colours.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Look {
    /// Background colour (R, G, B), 0..255.
    pub background: [f32; 3],
    /// Marker colour.
    pub marker: [f32; 3],
    /// Standard deviation of additive Gaussian noise, grey levels.
    pub noise_sigma: f32,
    /// Brightness fall-off towards the corners (0: none, 0.3: corners 30 % darker).
    pub vignetting: f32,
}

impl Look {
    /// Green markers on dark fabric (seed 000).
    pub const GREEN_ON_DARK: Self = Self {
        background: [30.0, 40.0, 35.0],
        marker: [60.0, 200.0, 80.0],
        noise_sigma: 3.0,
        vignetting: 0.25,
    };
    /// White annuli on black (seed 001).
    pub const WHITE_ON_BLACK: Self = Self {
        background: [15.0, 15.0, 15.0],
        marker: [230.0, 230.0, 230.0],
        noise_sigma: 3.0,
        vignetting: 0.2,
    };
}

impl Default for Look {
    fn default() -> Self {
        Self::GREEN_ON_DARK
    }
}

/// A dot grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridPattern {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Rows of markers.
    pub rows: usize,
    /// Columns of markers.
    pub cols: usize,
    /// Centre of the top-left marker, pixels.
    pub origin_px: (f64, f64),
    /// Column pitch, pixels.
    pub pitch_x_px: f64,
    /// Row pitch, pixels.
    pub pitch_y_px: f64,
    /// Marker radius at rest, pixels.
    pub radius_px: f64,
    /// Colours and noise.
    pub look: Look,
}

impl GridPattern {
    /// 640×480, 13 × 9 green markers (seed 000's layout).
    pub const IATS: Self = Self {
        width: 640,
        height: 480,
        rows: 9,
        cols: 13,
        origin_px: (44.0, 48.0),
        pitch_x_px: 46.0,
        pitch_y_px: 48.0,
        radius_px: 10.0,
        look: Look::GREEN_ON_DARK,
    };
}

/// A press on the grid, in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Press {
    /// Contact column.
    pub x_px: f64,
    /// Contact row.
    pub y_px: f64,
    /// Width of the deformed zone.
    pub sigma_px: f64,
    /// Outward push at the bump's peak.
    pub push_px: f64,
    /// Sideways drag at the peak, x.
    pub shear_x_px: f64,
    /// Sideways drag at the peak, y.
    pub shear_y_px: f64,
    /// Relative growth at the peak.
    pub grow: f64,
    /// Relative radial stretch at the peak.
    pub stretch: f64,
}

/// Truth for one rendered marker.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MarkerTruth {
    /// The ellipse as drawn.
    pub ellipse: Ellipse,
    /// Grid row.
    pub row: usize,
    /// Grid column.
    pub col: usize,
}

/// The markers of `pattern` under `press` (none: at rest).
pub fn grid_markers(pattern: &GridPattern, press: Option<&Press>) -> Vec<MarkerTruth> {
    let mut out = Vec::with_capacity(pattern.rows * pattern.cols);
    for row in 0..pattern.rows {
        for col in 0..pattern.cols {
            let x = pattern.origin_px.0 + col as f64 * pattern.pitch_x_px;
            let y = pattern.origin_px.1 + row as f64 * pattern.pitch_y_px;
            let mut e = Ellipse::circle(x, y, pattern.radius_px);
            if let Some(p) = press {
                let (dx, dy) = (x - p.x_px, y - p.y_px);
                let r = dx.hypot(dy);
                let g = (-(r * r) / (2.0 * p.sigma_px * p.sigma_px)).exp();
                let (ux, uy) = if r > 1e-9 {
                    (dx / r, dy / r)
                } else {
                    (1.0, 0.0)
                };
                // Outward push grows from 0 at the centre, peaks at r = sigma.
                let push = p.push_px * g * (r / p.sigma_px).min(1.0);
                e.cx_px += ux * push + p.shear_x_px * g;
                e.cy_px += uy * push + p.shear_y_px * g;
                let scale = 1.0 + p.grow * g;
                e.a_px =
                    pattern.radius_px * scale * (1.0 + p.stretch * g * (r / p.sigma_px).min(1.0));
                e.b_px = pattern.radius_px * scale;
                e.angle_rad = uy.atan2(ux);
            }
            out.push(MarkerTruth {
                ellipse: e,
                row,
                col,
            });
        }
    }
    out
}

/// Renders markers onto the look's background with vignetting, noise and 8-bit quantisation.
pub fn render_markers(
    width: usize,
    height: usize,
    shapes: &[(Ellipse, Option<Ellipse>)],
    look: &Look,
    seed: u64,
) -> RgbImage {
    // Coverage canvas: 0 background, 1 marker.
    let mut cov = Canvas::filled(width, height, 0.0);
    for (outer, inner) in shapes {
        cov.fill(outer, inner.as_ref(), 1.0);
    }
    frame_from_coverage(&cov, look, seed)
}

/// Colours a coverage canvas (0 background, 1 marker) with the look's colours, vignetting,
/// Gaussian noise and 8-bit rounding. The noise sequence is fixed by `seed`.
pub fn frame_from_coverage(cov: &Canvas, look: &Look, seed: u64) -> RgbImage {
    let (cx, cy) = (cov.width as f32 / 2.0, cov.height as f32 / 2.0);
    let rmax2 = cx * cx + cy * cy;
    frame_from_coverage_lit(cov, look.noise_sigma, seed, |x, y| {
        let r2 = ((x as f32 - cx).powi(2) + (y as f32 - cy).powi(2)) / rmax2;
        let light = 1.0 - look.vignetting * r2;
        (look.background, look.marker, light)
    })
}

/// Colours a coverage canvas with per-pixel colours: `colours(x, y)` gives the background and
/// marker colours there and the light falling on them; the pixel is their blend by coverage
/// times the light, plus Gaussian noise of `noise_sigma` grey levels (sequence fixed by
/// `seed`), rounded to 8 bits.
pub fn frame_from_coverage_lit(
    cov: &Canvas,
    noise_sigma: f32,
    seed: u64,
    colours: impl Fn(usize, usize) -> ([f32; 3], [f32; 3], f32),
) -> RgbImage {
    let width = cov.width;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0f32, noise_sigma.max(0.0))
        .unwrap_or_else(|_| Normal::new(0.0, 0.0).unwrap());
    RgbImage::from_fn(width, cov.height, |x, y| {
        let c = cov.data[y * width + x];
        let (bg, mk, light) = colours(x, y);
        let mut px = [0u8; 3];
        for (o, (b, m)) in px.iter_mut().zip(bg.iter().zip(&mk)) {
            let v = (b * (1.0 - c) + m * c) * light + noise.sample(&mut rng);
            *o = u8_from_level(v);
        }
        px
    })
}

/// `v.round().clamp(0.0, 255.0) as u8` (half away from zero; NaN to 0) without the libm call
/// that `round` is on baseline x86-64 — the same bits, a few times faster per pixel.
fn u8_from_level(v: f32) -> u8 {
    if v.is_nan() || v < 0.5 {
        return 0;
    }
    if v >= 254.5 {
        return 255;
    }
    // 0.5 ≤ v < 254.5: truncation and the fraction are exact.
    let t = v as u8;
    t + u8::from(v - f32::from(t) >= 0.5)
}

/// Renders a grid pattern; returns the frame and the truth per marker in grid order.
pub fn render_grid(
    pattern: &GridPattern,
    press: Option<&Press>,
    seed: u64,
) -> (RgbImage, Vec<MarkerTruth>) {
    let markers = grid_markers(pattern, press);
    let shapes: Vec<(Ellipse, Option<Ellipse>)> =
        markers.iter().map(|m| (m.ellipse, None)).collect();
    (
        render_markers(pattern.width, pattern.height, &shapes, &pattern.look, seed),
        markers,
    )
}

#[cfg(test)]
mod tests {
    use super::u8_from_level;

    #[test]
    fn levels_round_as_the_standard_library_does() {
        let mut values: Vec<f32> = (-2_000..=260_000).map(|i| i as f32 / 1000.0).collect();
        // Both neighbours of every half and whole level, where rounding changes.
        for i in -4..=520 {
            let v = i as f32 * 0.5;
            values.extend([v, v.next_up(), v.next_down()]);
        }
        values.extend([
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            -0.0,
            1e30,
            -1e30,
        ]);
        for v in values {
            let want = v.round().clamp(0.0, 255.0) as u8;
            assert_eq!(u8_from_level(v), want, "{v} ({:#x})", v.to_bits());
        }
    }
}
