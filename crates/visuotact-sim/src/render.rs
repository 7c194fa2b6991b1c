//! Anti-aliased rasterisation of ellipses and annuli into a floating-point canvas.
//!
//! Pixel `(x, y)` covers the square `[x − ½, x + ½] × [y − ½, y + ½]` (centres at integers, as
//! the vision pipeline measures). Pixels well inside or outside a shape get coverage 1 or 0;
//! pixels near its edge are supersampled on a 16 × 16 grid, so coverage is exact to 1/256.

/// An ellipse: centre, semi-axes and rotation of the first semi-axis from the x axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ellipse {
    /// Centre column, pixels.
    pub cx_px: f64,
    /// Centre row, pixels.
    pub cy_px: f64,
    /// First semi-axis, pixels.
    pub a_px: f64,
    /// Second semi-axis, pixels.
    pub b_px: f64,
    /// Rotation of the first semi-axis from +x (towards +y), radians.
    pub angle_rad: f64,
}

impl Ellipse {
    /// A circle.
    pub fn circle(cx_px: f64, cy_px: f64, r_px: f64) -> Self {
        Self {
            cx_px,
            cy_px,
            a_px: r_px,
            b_px: r_px,
            angle_rad: 0.0,
        }
    }

    /// Area `π a b`.
    pub fn area_px(&self) -> f64 {
        std::f64::consts::PI * self.a_px * self.b_px
    }

    /// Eccentricity `sqrt(1 − (minor/major)²)`.
    pub fn eccentricity(&self) -> f64 {
        let (ma, mi) = if self.a_px >= self.b_px {
            (self.a_px, self.b_px)
        } else {
            (self.b_px, self.a_px)
        };
        if ma <= 0.0 {
            0.0
        } else {
            (1.0 - (mi / ma).powi(2)).sqrt()
        }
    }

    /// Implicit value: < 1 inside, > 1 outside.
    fn value(&self, x: f64, y: f64) -> f64 {
        let (s, c) = self.angle_rad.sin_cos();
        let (dx, dy) = (x - self.cx_px, y - self.cy_px);
        let u = (c * dx + s * dy) / self.a_px;
        let v = (-s * dx + c * dy) / self.b_px;
        u * u + v * v
    }

    /// Half-size of the axis-aligned bounding box.
    fn half_extent(&self) -> (f64, f64) {
        let (s, c) = self.angle_rad.sin_cos();
        let hx = ((self.a_px * c).powi(2) + (self.b_px * s).powi(2)).sqrt();
        let hy = ((self.a_px * s).powi(2) + (self.b_px * c).powi(2)).sqrt();
        (hx, hy)
    }
}

/// A float canvas, row-major, one value per pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct Canvas {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Values, row-major.
    pub data: Vec<f32>,
}

const SS: usize = 16;

impl Canvas {
    /// A canvas filled with `v`.
    pub fn filled(width: usize, height: usize, v: f32) -> Self {
        Self {
            width,
            height,
            data: vec![v; width * height],
        }
    }

    /// Coverage of pixel `(x, y)` by the shape `inside(x, y) -> bool`.
    fn coverage(x: usize, y: usize, inside: &impl Fn(f64, f64) -> bool) -> f64 {
        let mut k = 0;
        for j in 0..SS {
            let sy = y as f64 - 0.5 + (j as f64 + 0.5) / SS as f64;
            for i in 0..SS {
                let sx = x as f64 - 0.5 + (i as f64 + 0.5) / SS as f64;
                if inside(sx, sy) {
                    k += 1;
                }
            }
        }
        k as f64 / (SS * SS) as f64
    }

    /// Blends `value` into the canvas where the ellipse `outer` covers and `inner` (if any)
    /// does not: `pixel = pixel · (1 − c) + value · c`.
    pub fn fill(&mut self, outer: &Ellipse, inner: Option<&Ellipse>, value: f32) {
        let (hx, hy) = outer.half_extent();
        let x0 = (outer.cx_px - hx - 1.0).floor().max(0.0) as usize;
        let y0 = (outer.cy_px - hy - 1.0).floor().max(0.0) as usize;
        let x1 = ((outer.cx_px + hx + 2.0).ceil().max(0.0) as usize).min(self.width);
        let y1 = ((outer.cy_px + hy + 2.0).ceil().max(0.0) as usize).min(self.height);
        // A pixel whose centre is this far (in implicit-value terms) from the level set 1 is
        // surely fully inside or outside: the pixel's half-diagonal is 0.71 px and the implicit
        // value changes by at most 2·0.71/min_axis·(1 + 0.71/min_axis) across it.
        let margin = |e: &Ellipse| {
            let m = e.a_px.min(e.b_px).max(1e-6);
            (2.0 * 0.75 / m) * (1.0 + 0.75 / m) * 1.5
        };
        let mo = margin(outer);
        let mi = inner.map_or(0.0, margin);
        let inside =
            |x: f64, y: f64| outer.value(x, y) <= 1.0 && inner.is_none_or(|e| e.value(x, y) > 1.0);
        for y in y0..y1 {
            for x in x0..x1 {
                let vo = outer.value(x as f64, y as f64);
                let edge_o = (vo - 1.0).abs() < mo;
                let vi = inner.map(|e| e.value(x as f64, y as f64));
                let edge_i = vi.is_some_and(|v| (v - 1.0).abs() < mi);
                let c = if edge_o || edge_i {
                    Self::coverage(x, y, &inside)
                } else if vo < 1.0 && vi.is_none_or(|v| v > 1.0) {
                    1.0
                } else {
                    0.0
                };
                if c > 0.0 {
                    let p = &mut self.data[y * self.width + x];
                    *p = (f64::from(*p) * (1.0 - c) + f64::from(value) * c) as f32;
                }
            }
        }
    }
}
