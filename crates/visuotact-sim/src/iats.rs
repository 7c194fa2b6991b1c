//! The image-based areal touch sensor of seed 000: 117 green markers in a 13 × 9 grid over
//! 60 × 45 mm of fabric clamped in a frame, filmed from below through a wide-angle lens.
//!
//! Membrane model (physics-inspired, every parameter in [`IatsConfig`]):
//! - A spherical tip of radius `R` pressed to depth `d` makes a contact cap of radius
//!   `a = sqrt(2Rd − d²)`. Outside it the fabric follows the shape of a pre-tensioned membrane
//!   under a central load, `w(r) = d · ln(L/r) / ln(L/a)`, where `L(θ)` is the distance from the
//!   contact to the clamped frame in the direction of the point: touches near an edge make a
//!   steeper, shorter dent than central ones. `w = 0` on the frame, `w = d` under the tip.
//! - The fabric is pulled towards the dent: a point at distance `r` moves inwards by
//!   `ε (r/ρ) ∫_ρ^L (sqrt(1 + w'(s)²) − 1) ds` with `ρ = sqrt(r² + a²)`, the arc-length excess
//!   between it and the frame times a coupling `ε` (1: inextensible fabric), faded smoothly to
//!   zero at the centre. This grows with `d²`: the response is nonlinear.
//! - A sideways drag `s` moves material by `s · w/d` (all of it under the tip, none at the frame).
//! - Each marker is a circle painted on the fabric: its boundary points are moved by the field
//!   (in plane and towards the camera), so the marker shifts, grows as it comes closer to the
//!   camera and becomes an ellipse where the fabric tilts. The boundary is projected through
//!   the pinhole camera with radial distortion and filled as a polygon, whose exact area and
//!   centroid are the truth.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use visuotact_image::RgbImage;

use crate::camera::Camera;
use crate::pattern::Look;
use crate::render::{clear_crowded, ring_area_centroid, squeezed, Canvas, ConvexPolygon};

/// Every physical and optical parameter of the IATS simulator.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct IatsConfig {
    /// Marker columns.
    pub cols: usize,
    /// Marker rows.
    pub rows: usize,
    /// Distance from the first to the last marker column, mm (seed 000: 60).
    pub span_x_mm: f64,
    /// Distance from the first to the last marker row, mm (seed 000: 45).
    pub span_y_mm: f64,
    /// Marker radius, mm.
    pub marker_radius_mm: f64,
    /// Free fabric between the outer markers and the clamped frame, mm.
    pub frame_margin_mm: f64,
    /// Radius of the spherical tip, mm.
    pub tip_radius_mm: f64,
    /// Deepest allowed indentation, mm.
    pub max_depth_mm: f64,
    /// In-plane coupling ε (0: no in-plane motion, 1: inextensible fabric).
    pub stretch_coupling: f64,
    /// Distance from the camera to the fabric at rest, mm.
    pub camera_distance_mm: f64,
    /// The camera below the fabric (its optical axis through the middle of the marker grid).
    pub camera: Camera,
    /// Colours, LED vignetting and noise.
    pub look: Look,
    /// Optical blur, pixels (Gaussian σ).
    pub blur_px: f64,
}

impl IatsConfig {
    /// Seed 000's sensor: 13 × 9 markers over 60 × 45 mm, 5 mm tip, 0–5 mm deep.
    pub const SEED000: Self = Self {
        cols: 13,
        rows: 9,
        span_x_mm: 60.0,
        span_y_mm: 45.0,
        marker_radius_mm: 1.4,
        frame_margin_mm: 6.0,
        tip_radius_mm: 5.0,
        max_depth_mm: 5.0,
        stretch_coupling: 0.6,
        camera_distance_mm: 36.0,
        camera: Camera::WEBCAM_640X480,
        look: Look::GREEN_ON_DARK,
        blur_px: 0.6,
    };

    /// A membrane sensor like seed 000's with every parameter drawn from a range by `seed`
    /// (seed 0: [`IatsConfig::SEED000`]), uniform: 8–14 columns × 6–10 rows spanning at most
    /// 62 × 46 mm (pitches 3.5–6 mm, row pitch 0.8–1.2 × column pitch), marker radius 0.2–0.35
    /// pitch, frame margin 3–8 mm, tip radius 3–8 mm, presses to 4–5.5 mm, in-plane coupling
    /// 0.3–1, camera 36–42 mm away with k1 −0.12…−0.04, markers pale (40–90 grey levels above
    /// the fabric) or bright in a random colour on fabric 15–60, noise σ 2–5, vignetting
    /// 0.1–0.35, blur 0.4–1 px.
    pub fn variant(seed: u64) -> Self {
        let mut c = Self::SEED000;
        if seed == 0 {
            return c;
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x1A75_0000);
        let mut u = |lo: f64, hi: f64| rng.random_range(lo..=hi);
        c.cols = u(8.0, 14.99).floor() as usize;
        c.rows = u(6.0, 10.99).floor() as usize;
        let px = u(3.5, 6.0).min(62.0 / (c.cols - 1) as f64);
        let py = (px * u(0.8, 1.2)).min(46.0 / (c.rows - 1) as f64);
        c.span_x_mm = px * (c.cols - 1) as f64;
        c.span_y_mm = py * (c.rows - 1) as f64;
        c.marker_radius_mm = u(0.2, 0.35) * px.min(py);
        c.frame_margin_mm = u(3.0, 8.0);
        c.tip_radius_mm = u(3.0, 8.0);
        c.max_depth_mm = u(4.0, 5.5);
        c.stretch_coupling = u(0.3, 1.0);
        c.camera_distance_mm = u(36.0, 42.0);
        c.camera.k1 = u(-0.12, -0.04);
        let fabric = u(15.0, 60.0) as f32;
        let tint = [u(0.8, 1.2) as f32, u(0.8, 1.2) as f32, u(0.8, 1.2) as f32];
        let marker = if u(0.0, 1.0) < 0.5 {
            // Pale: little contrast over the fabric, in the green channel too.
            let lift = u(40.0, 90.0) as f32;
            tint.map(|t| t * (fabric + lift))
        } else {
            [
                u(40.0, 120.0) as f32,
                u(150.0, 240.0) as f32,
                u(40.0, 140.0) as f32,
            ]
        };
        c.look = Look {
            background: tint.map(|t| t * fabric),
            marker,
            noise_sigma: u(2.0, 5.0) as f32,
            vignetting: u(0.1, 0.35) as f32,
        };
        c.blur_px = u(0.4, 1.0);
        c
    }

    /// Column pitch, mm.
    pub fn pitch_x_mm(&self) -> f64 {
        self.span_x_mm / (self.cols.max(2) - 1) as f64
    }

    /// Row pitch, mm.
    pub fn pitch_y_mm(&self) -> f64 {
        self.span_y_mm / (self.rows.max(2) - 1) as f64
    }

    /// Checks the parameters; the message names the bad one.
    pub fn validate(&self) -> Result<(), crate::SimError> {
        self.camera.validate()?;
        if self.cols < 2 || self.rows < 2 {
            return Err(crate::SimError::Size {
                what: "marker grid",
                width: self.cols,
                height: self.rows,
                limit: "at least 2 × 2 markers".to_string(),
            });
        }
        if self.cols > 200 || self.rows > 200 {
            return Err(crate::SimError::Size {
                what: "marker grid",
                width: self.cols,
                height: self.rows,
                limit: "at most 200 × 200 markers".to_string(),
            });
        }
        crate::check_blur_px(self.blur_px)?;
        for (name, v) in [
            ("span_x_mm", self.span_x_mm),
            ("span_y_mm", self.span_y_mm),
            ("marker_radius_mm", self.marker_radius_mm),
            ("tip_radius_mm", self.tip_radius_mm),
            ("max_depth_mm", self.max_depth_mm),
            ("camera_distance_mm", self.camera_distance_mm),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(crate::SimError::out_of_range(name, v, "positive"));
            }
        }
        if !(self.frame_margin_mm.is_finite() && self.frame_margin_mm >= 0.0) {
            return Err(crate::SimError::out_of_range(
                "frame_margin_mm",
                self.frame_margin_mm,
                "≥ 0",
            ));
        }
        if !(0.0..=1.0).contains(&self.stretch_coupling) {
            return Err(crate::SimError::out_of_range(
                "stretch_coupling",
                self.stretch_coupling,
                "in 0..1",
            ));
        }
        if self.max_depth_mm >= self.camera_distance_mm {
            return Err(crate::SimError::Mismatch {
                a: "max_depth_mm",
                b: "camera_distance_mm",
                why: "a press would reach the camera".to_string(),
            });
        }
        Ok(())
    }
}

impl Default for IatsConfig {
    fn default() -> Self {
        Self::SEED000
    }
}

/// A touch: where, how deep, and how far the tip drags the fabric sideways.
#[derive(Clone, Copy, Debug, PartialEq, Default, serde::Serialize)]
pub struct Touch {
    /// Contact x in marker coordinates (0 at the first column), mm.
    pub x_mm: f64,
    /// Contact y (0 at the first row, growing down the image), mm.
    pub y_mm: f64,
    /// Indentation depth, mm (0: no contact).
    pub depth_mm: f64,
    /// Sideways drag along x, mm.
    pub shear_x_mm: f64,
    /// Sideways drag along y, mm.
    pub shear_y_mm: f64,
}

impl Touch {
    /// The touch part of the way there, as a video shows it being made: the depth scaled by
    /// `press`, the drag by `drag` (each 0..1; 1 and 1: the touch itself).
    pub fn partway(&self, press: f64, drag: f64) -> Self {
        Self {
            depth_mm: self.depth_mm * press,
            shear_x_mm: self.shear_x_mm * drag,
            shear_y_mm: self.shear_y_mm * drag,
            ..*self
        }
    }

    /// Checks the touch against the sensor: inside the marker area, depth in range, a drag only
    /// with contact and at most two pitches.
    pub fn validate(&self, cfg: &IatsConfig) -> Result<(), crate::SimError> {
        let finite = [
            self.x_mm,
            self.y_mm,
            self.depth_mm,
            self.shear_x_mm,
            self.shear_y_mm,
        ];
        if !finite.iter().all(|v| v.is_finite()) {
            return Err(crate::SimError::NotFinite("every value of a touch"));
        }
        if self.depth_mm < 0.0 || self.depth_mm > cfg.max_depth_mm {
            return Err(crate::SimError::out_of_range(
                "depth_mm",
                self.depth_mm,
                format!("in 0..{} mm", cfg.max_depth_mm),
            ));
        }
        if !(0.0..=cfg.span_x_mm).contains(&self.x_mm)
            || !(0.0..=cfg.span_y_mm).contains(&self.y_mm)
        {
            return Err(crate::SimError::OffField {
                x_mm: self.x_mm,
                y_mm: self.y_mm,
            });
        }
        let drag = self.shear_x_mm.hypot(self.shear_y_mm);
        if drag > 0.0 && self.depth_mm <= 0.0 {
            return Err(crate::SimError::DragWithoutContact);
        }
        let limit_mm = 2.0 * cfg.pitch_x_mm().max(cfg.pitch_y_mm());
        if drag > limit_mm {
            return Err(crate::SimError::out_of_range(
                "drag (mm)",
                drag,
                format!("at most two marker pitches ({limit_mm} mm)"),
            ));
        }
        Ok(())
    }
}

/// Distance from `(cx, cy)` along the unit direction `(ux, uy)` to the rectangle's edge.
fn distance_to_frame(cfg: &IatsConfig, cx: f64, cy: f64, ux: f64, uy: f64) -> f64 {
    let m = cfg.frame_margin_mm;
    let (x0, x1, y0, y1) = (-m, cfg.span_x_mm + m, -m, cfg.span_y_mm + m);
    let tx = if ux > 1e-12 {
        (x1 - cx) / ux
    } else if ux < -1e-12 {
        (x0 - cx) / ux
    } else {
        f64::INFINITY
    };
    let ty = if uy > 1e-12 {
        (y1 - cy) / uy
    } else if uy < -1e-12 {
        (y0 - cy) / uy
    } else {
        f64::INFINITY
    };
    tx.min(ty)
}

/// Displacement `(ux, uy, w)` in mm of the fabric point at rest position `(x, y)` (marker
/// coordinates): in plane, and towards the camera.
pub fn displacement_mm(cfg: &IatsConfig, touch: &Touch, x: f64, y: f64) -> [f64; 3] {
    let d = touch.depth_mm;
    if d <= 0.0 {
        return [0.0, 0.0, 0.0];
    }
    let (dx, dy) = (x - touch.x_mm, y - touch.y_mm);
    let r = dx.hypot(dy);
    let (ux, uy) = if r > 1e-9 {
        (dx / r, dy / r)
    } else {
        (1.0, 0.0)
    };
    let l = distance_to_frame(cfg, touch.x_mm, touch.y_mm, ux, uy);
    let rt = cfg.tip_radius_mm;
    let a = (2.0 * rt * d - d * d).max(0.0).sqrt().clamp(0.3, 0.9 * l);
    let lambda = (l / a).ln();
    // Deflection profile and its shape factor ψ = w / d.
    let psi = |s: f64| -> f64 {
        if s <= a {
            1.0
        } else if s >= l {
            0.0
        } else {
            (l / s).ln() / lambda
        }
    };
    let p = psi(r);
    // Arc-length excess from ρ = sqrt(r² + a²) (a smooth stand-in for max(r, a): no kink at the
    // contact edge) to the frame: ∫ sqrt(1 + w'²) − 1, w' = −d/(s Λ), integrated on a log scale
    // (Simpson, 32 intervals).
    let rho = r.hypot(a);
    let s0 = rho;
    let excess = if s0 >= l {
        0.0
    } else {
        let n = 32;
        let (t0, t1) = (s0.ln(), l.ln());
        let h = (t1 - t0) / n as f64;
        let f = |t: f64| {
            let s = t.exp();
            let slope = d / (s * lambda);
            ((1.0 + slope * slope).sqrt() - 1.0) * s
        };
        let mut acc = f(t0) + f(t1);
        for k in 1..n {
            acc += f(t0 + k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
        }
        acc * h / 3.0
    };
    // The pull fades smoothly to zero at the centre of the contact (r / ρ).
    let inward = cfg.stretch_coupling * excess * r / rho;
    [
        -ux * inward + touch.shear_x_mm * p,
        -uy * inward + touch.shear_y_mm * p,
        d * p,
    ]
}

/// Truth for one marker in one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IatsMarker {
    /// Grid row (0 = top).
    pub row: usize,
    /// Grid column.
    pub col: usize,
    /// Projected centroid column, pixels (exact centroid of the drawn polygon).
    pub x_px: f64,
    /// Projected centroid row, pixels.
    pub y_px: f64,
    /// Projected area, pixels.
    pub area_px: f64,
    /// Whether the whole marker lies inside the image with a pixel to spare.
    pub fully_in_view: bool,
    /// In view, clear of every other marker by `2 px + 2 × blur`, and not squeezed to a sliver
    /// (its minor axis at least 2.5 px and 35 % of its rest value): a blob of its own.
    pub visible: bool,
}

/// Boundary points of a marker per polygon.
const MARKER_VERTICES: usize = 48;

/// Camera-frame position (mm) of the fabric point at rest position `(x, y)` under `touch`.
fn camera_point(cfg: &IatsConfig, touch: &Touch, x: f64, y: f64) -> [f64; 3] {
    let u = displacement_mm(cfg, touch, x, y);
    [
        x + u[0] - 0.5 * cfg.span_x_mm,
        y + u[1] - 0.5 * cfg.span_y_mm,
        cfg.camera_distance_mm - u[2],
    ]
}

/// The projected polygon of every marker (grid order) and its truth.
pub fn markers(cfg: &IatsConfig, touch: &Touch) -> Vec<(Option<ConvexPolygon>, IatsMarker)> {
    let (px, py) = (cfg.pitch_x_mm(), cfg.pitch_y_mm());
    let cam = &cfg.camera;
    let mut out = Vec::with_capacity(cfg.rows * cfg.cols);
    for row in 0..cfg.rows {
        for col in 0..cfg.cols {
            let (mx, my) = (col as f64 * px, row as f64 * py);
            let outline = |t: &Touch| {
                let verts: Vec<(f64, f64)> = (0..MARKER_VERTICES)
                    .filter_map(|k| {
                        let a = k as f64 / MARKER_VERTICES as f64 * std::f64::consts::TAU;
                        let (x, y) = (
                            mx + cfg.marker_radius_mm * a.cos(),
                            my + cfg.marker_radius_mm * a.sin(),
                        );
                        cam.px_from_mm(camera_point(cfg, t, x, y))
                    })
                    .collect();
                ConvexPolygon::new(verts)
            };
            let poly = outline(touch);
            let collapsed = squeezed(poly.as_ref(), outline(&Touch::default()).as_ref());
            let (area_px, (x_px, y_px)) = poly
                .as_ref()
                .map_or((0.0, (f64::NAN, f64::NAN)), |p| ring_area_centroid(p, None));
            let fully_in_view = poly.as_ref().is_some_and(|p| {
                let (x0, y0, x1, y1) = p.bounds();
                x0 > 1.0 && y0 > 1.0 && x1 < cam.width as f64 - 2.0 && y1 < cam.height as f64 - 2.0
            });
            out.push((
                poly,
                IatsMarker {
                    row,
                    col,
                    x_px,
                    y_px,
                    area_px,
                    fully_in_view,
                    visible: fully_in_view && !collapsed,
                },
            ));
        }
    }
    clear_crowded(
        &mut out,
        2.0 + 2.0 * cfg.blur_px,
        |m| (m.x_px, m.y_px),
        |m| &mut m.visible,
    );
    out
}

/// Renders one camera frame of the sensor under `touch` (depth 0: the no-contact reference),
/// with noise fixed by `seed`. Returns the frame and the markers' truth in grid order.
pub fn render(
    cfg: &IatsConfig,
    touch: &Touch,
    seed: u64,
) -> Result<(RgbImage, Vec<IatsMarker>), crate::SimError> {
    cfg.validate()?;
    touch.validate(cfg)?;
    let ms = markers(cfg, touch);
    let mut cov = Canvas::filled(cfg.camera.width, cfg.camera.height, 0.0);
    for (poly, _) in &ms {
        if let Some(p) = poly {
            cov.fill_polygon(p, None, 1.0);
        }
    }
    cov.blur(cfg.blur_px);
    // The LED sits beside the camera: a soft hot spot on top of the lens vignetting.
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x1ED);
    let led = Normal::new(0.0f64, 1.0)
        .map(|n| n.sample(&mut rng) * 0.02)
        .unwrap_or(0.0);
    let img = crate::pattern::frame_from_coverage(
        &cov,
        &Look {
            vignetting: cfg.look.vignetting + led as f32,
            ..cfg.look
        },
        seed,
    );
    Ok((img, ms.into_iter().map(|(_, m)| m).collect()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> IatsConfig {
        IatsConfig::SEED000
    }

    #[test]
    fn no_contact_no_displacement() {
        let t = Touch {
            x_mm: 30.0,
            y_mm: 20.0,
            ..Touch::default()
        };
        for &(x, y) in &[(0.0, 0.0), (30.0, 20.0), (55.0, 41.0)] {
            assert_eq!(displacement_mm(&cfg(), &t, x, y), [0.0, 0.0, 0.0]);
        }
    }

    #[test]
    fn central_touch_gives_a_symmetric_field() {
        let c = cfg();
        let t = Touch {
            x_mm: 30.0,
            y_mm: 22.5,
            depth_mm: 3.0,
            ..Touch::default()
        };
        for &(dx, dy) in &[(5.0, 0.0), (10.0, 4.0), (20.0, 15.0)] {
            let a = displacement_mm(&c, &t, 30.0 + dx, 22.5 + dy);
            let b = displacement_mm(&c, &t, 30.0 - dx, 22.5 - dy);
            let m = displacement_mm(&c, &t, 30.0 - dx, 22.5 + dy);
            assert!(
                (a[0] + b[0]).abs() < 1e-12
                    && (a[1] + b[1]).abs() < 1e-12
                    && (a[2] - b[2]).abs() < 1e-12
            );
            assert!(
                (a[0] + m[0]).abs() < 1e-12
                    && (a[1] - m[1]).abs() < 1e-12
                    && (a[2] - m[2]).abs() < 1e-12
            );
            // Pulled towards the contact.
            assert!(a[0] * dx + a[1] * dy < 0.0);
        }
    }

    #[test]
    fn deflection_and_pull_grow_with_depth() {
        let c = cfg();
        let mut last = [0.0f64; 3];
        for k in 1..=10 {
            let t = Touch {
                x_mm: 24.0,
                y_mm: 18.0,
                depth_mm: 0.5 * f64::from(k),
                ..Touch::default()
            };
            let u = displacement_mm(&c, &t, 32.0, 18.0);
            assert!(
                u[2] > last[2] && u[0].abs() > last[0].abs(),
                "depth {}: {u:?}",
                t.depth_mm
            );
            last = u;
        }
        // Nonlinear: the in-plane pull grows faster than the depth.
        let u1 = displacement_mm(
            &c,
            &Touch {
                x_mm: 24.0,
                y_mm: 18.0,
                depth_mm: 1.0,
                ..Touch::default()
            },
            32.0,
            18.0,
        );
        let u4 = displacement_mm(
            &c,
            &Touch {
                x_mm: 24.0,
                y_mm: 18.0,
                depth_mm: 4.0,
                ..Touch::default()
            },
            32.0,
            18.0,
        );
        assert!(u4[0].abs() > 8.0 * u1[0].abs());
    }

    #[test]
    fn clamped_frame_holds_the_fabric() {
        let c = cfg();
        let m = c.frame_margin_mm;
        let t = Touch {
            x_mm: 55.0,
            y_mm: 40.0,
            depth_mm: 5.0,
            shear_x_mm: 3.0,
            shear_y_mm: 0.0,
        };
        for &(x, y) in &[(60.0 + m, 20.0), (30.0, 45.0 + m), (-m, 10.0)] {
            let u = displacement_mm(&c, &t, x, y);
            assert!(u.iter().all(|v| v.abs() < 1e-9), "at ({x}, {y}): {u:?}");
        }
        // A touch near the edge dents the fabric towards that edge more steeply than a central one.
        let central = Touch {
            x_mm: 30.0,
            y_mm: 22.5,
            depth_mm: 4.0,
            ..Touch::default()
        };
        let near_edge = Touch {
            x_mm: 56.0,
            y_mm: 22.5,
            depth_mm: 4.0,
            ..Touch::default()
        };
        let wc = displacement_mm(&c, &central, 30.0 + 7.0, 22.5)[2];
        let we = displacement_mm(&c, &near_edge, 56.0 + 7.0, 22.5)[2];
        assert!(we < wc);
    }

    #[test]
    fn impossible_touches_are_errors() {
        let c = cfg();
        for t in [
            Touch {
                x_mm: 10.0,
                y_mm: 10.0,
                depth_mm: -1.0,
                ..Touch::default()
            },
            Touch {
                x_mm: 70.0,
                y_mm: 10.0,
                depth_mm: 1.0,
                ..Touch::default()
            },
            Touch {
                x_mm: 10.0,
                y_mm: 10.0,
                depth_mm: 6.0,
                ..Touch::default()
            },
            Touch {
                x_mm: 10.0,
                y_mm: 10.0,
                depth_mm: 0.0,
                shear_x_mm: 1.0,
                shear_y_mm: 0.0,
            },
            Touch {
                x_mm: f64::NAN,
                y_mm: 10.0,
                depth_mm: 1.0,
                ..Touch::default()
            },
        ] {
            assert!(render(&c, &t, 0).is_err(), "{t:?}");
        }
    }

    #[test]
    fn variants_are_valid_and_in_view() {
        for seed in 0..20 {
            let c = IatsConfig::variant(seed);
            c.validate().unwrap();
            let rest = markers(&c, &Touch::default());
            assert!(
                rest.iter().all(|(_, m)| m.fully_in_view),
                "variant {seed}: {c:?}"
            );
        }
    }

    #[test]
    fn markers_grow_and_stretch_under_the_tip() {
        let c = cfg();
        let rest = markers(&c, &Touch::default());
        let t = Touch {
            x_mm: 30.0,
            y_mm: 22.5,
            depth_mm: 4.0,
            ..Touch::default()
        };
        let pressed = markers(&c, &t);
        let centre = 4 * 13 + 6;
        assert!(pressed[centre].1.area_px > 1.1 * rest[centre].1.area_px);
        assert!(rest.iter().all(|(_, m)| m.fully_in_view));
    }
}
