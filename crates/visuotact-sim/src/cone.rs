//! The inflatable link of seed 001: a neoprene truncated cone (230 mm long, Ø60 mm top,
//! Ø90 mm base, 4 kPa) with a webcam at the base looking up its axis at three white annuli
//! painted on the inner wall near the top, 15 mm apart.
//!
//! Load model (physics-inspired, every parameter in [`ConeConfig`]): a force at the distal end
//! of magnitude `F`, at `elevation` to the plane across the axis (seed 001: 30°) and turned by
//! `azimuth` about the axis, splits into a lateral part `F cos(elevation)` that bends the cone
//! like a cantilever fixed at the base (`δ(z) = δ_tip z²(3L − z)/(2L³)`, the wall tilting by
//! `δ'(z)`) and an axial part `F sin(elevation)` that shortens it (`Δ(z) = Δ_tip z/L`). An
//! inflated beam stiffens with pressure and saturates at large loads:
//! `δ_tip = δ_max tanh(F_lat / (k_b (p/p0) δ_max))`, likewise for `Δ_tip`. Rings shift with the
//! centreline, tilt with its slope (so they look elliptical) and come closer to the camera as
//! the cone shortens. Pressure drifts (a leak) and ripples (the compressor) over time.

use visuotact_image::RgbImage;

use crate::camera::Camera;
use crate::pattern::Look;
use crate::render::{ring_area_centroid, Canvas, ConvexPolygon};

/// Every physical and optical parameter of the cone simulator.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ConeConfig {
    /// Length from the base (camera) to the distal end, mm.
    pub length_mm: f64,
    /// Inner radius at the base, mm.
    pub base_radius_mm: f64,
    /// Inner radius at the top, mm.
    pub top_radius_mm: f64,
    /// Nominal inflation pressure, kPa.
    pub pressure_kpa: f64,
    /// Heights of the ring centres above the camera, mm (topmost first).
    pub ring_heights_mm: [f64; 3],
    /// Width of each ring along the wall, mm.
    pub ring_width_mm: f64,
    /// Lateral stiffness at the tip at nominal pressure, N/mm.
    pub bending_stiffness_n_per_mm: f64,
    /// Largest lateral tip deflection (the tanh saturation), mm.
    pub max_deflection_mm: f64,
    /// Axial stiffness at nominal pressure, N/mm.
    pub axial_stiffness_n_per_mm: f64,
    /// Largest axial shortening, mm.
    pub max_shortening_mm: f64,
    /// Bar length of the T-shaped marker painted on the distal disc, mm (0: none). The bar is
    /// `t_marker_mm × t_marker_mm/6`, the stem `t_marker_mm/6 × t_marker_mm/2.4` below its
    /// middle — longer across than along, so its second moments give its orientation.
    pub t_marker_mm: f64,
    /// Torsional stiffness of the link at nominal pressure, N·mm per radian of twist.
    pub torsional_stiffness_nmm_per_rad: f64,
    /// Largest twist of the distal disc (the tanh saturation), radians.
    pub max_twist_rad: f64,
    /// The camera at the base, looking up the axis.
    pub camera: Camera,
    /// Colours, vignetting and noise.
    pub look: Look,
    /// Optical blur, pixels.
    pub blur_px: f64,
}

impl ConeConfig {
    /// Seed 001's link: 230 mm, Ø60/Ø90 mm, 4 kPa, rings at 225/210/195 mm.
    pub const SEED001: Self = Self {
        length_mm: 230.0,
        base_radius_mm: 45.0,
        top_radius_mm: 30.0,
        pressure_kpa: 4.0,
        ring_heights_mm: [225.0, 210.0, 195.0],
        ring_width_mm: 4.0,
        bending_stiffness_n_per_mm: 4.0,
        max_deflection_mm: 4.0,
        axial_stiffness_n_per_mm: 2.5,
        max_shortening_mm: 6.0,
        t_marker_mm: 0.0,
        torsional_stiffness_nmm_per_rad: 2000.0,
        max_twist_rad: 0.6,
        camera: Camera {
            width: 640,
            height: 480,
            fx_px: 1450.0,
            fy_px: 1450.0,
            cx_px: 319.5,
            cy_px: 239.5,
            k1: -0.05,
            k2: 0.0,
        },
        look: Look::WHITE_ON_BLACK,
        blur_px: 0.8,
    };

    /// Seed 001's link with the T-shaped marker its author painted on the distal disc for
    /// torque (24 mm bar), twisting 2 000 N·mm per radian at 4 kPa, at most 0.6 rad.
    pub const SEED001_T: Self = Self {
        t_marker_mm: 24.0,
        ..Self::SEED001
    };

    /// Inner radius of the wall at height `z`, mm.
    pub fn radius_at(&self, z: f64) -> f64 {
        self.base_radius_mm + (self.top_radius_mm - self.base_radius_mm) * z / self.length_mm
    }

    /// Checks the parameters.
    pub fn validate(&self) -> Result<(), crate::SimError> {
        self.camera.validate()?;
        for (name, v) in [
            ("length_mm", self.length_mm),
            ("base_radius_mm", self.base_radius_mm),
            ("top_radius_mm", self.top_radius_mm),
            ("pressure_kpa", self.pressure_kpa),
            ("ring_width_mm", self.ring_width_mm),
            (
                "bending_stiffness_n_per_mm",
                self.bending_stiffness_n_per_mm,
            ),
            ("max_deflection_mm", self.max_deflection_mm),
            ("axial_stiffness_n_per_mm", self.axial_stiffness_n_per_mm),
            ("max_shortening_mm", self.max_shortening_mm),
            (
                "torsional_stiffness_nmm_per_rad",
                self.torsional_stiffness_nmm_per_rad,
            ),
            ("max_twist_rad", self.max_twist_rad),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(crate::SimError::out_of_range(name, v, "positive"));
            }
        }
        if !(self.t_marker_mm.is_finite() && self.t_marker_mm >= 0.0) {
            return Err(crate::SimError::out_of_range(
                "t_marker_mm",
                self.t_marker_mm,
                "≥ 0 (0: no T)",
            ));
        }
        crate::check_blur_px(self.blur_px)?;
        for z in self.ring_heights_mm {
            if !(z > self.ring_width_mm && z < self.length_mm) {
                return Err(crate::SimError::Mismatch {
                    a: "ring_heights_mm",
                    b: "length_mm",
                    why: format!(
                        "a ring at {z} mm does not lie inside the cone ({} .. {} mm)",
                        self.ring_width_mm, self.length_mm
                    ),
                });
            }
        }
        Ok(())
    }
}

impl Default for ConeConfig {
    fn default() -> Self {
        Self::SEED001
    }
}

/// The load on the distal end and the pressure at that moment.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ConeLoad {
    /// Force magnitude, N.
    pub force_n: f64,
    /// Angle between the force and the plane across the axis, radians (seed 001: 30°).
    pub elevation_rad: f64,
    /// Direction of the lateral part about the axis, radians (0: towards +x of the image).
    pub azimuth_rad: f64,
    /// Inflation pressure now, kPa.
    pub pressure_kpa: f64,
    /// Torque about the link's axis at the distal end, N·mm (positive: counter-clockwise
    /// seen from the camera, i.e. from +x towards +y).
    pub torque_nmm: f64,
}

impl ConeLoad {
    /// No load at the given pressure.
    pub fn none(pressure_kpa: f64) -> Self {
        Self {
            force_n: 0.0,
            elevation_rad: 0.0,
            azimuth_rad: 0.0,
            pressure_kpa,
            torque_nmm: 0.0,
        }
    }

    /// Force components `(fx, fy, fz)` in the camera frame, N (z along the axis, away from the
    /// camera; the axial part pushes towards the base, so `fz ≤ 0`).
    pub fn components_n(&self) -> [f64; 3] {
        let lat = self.force_n * self.elevation_rad.cos();
        [
            lat * self.azimuth_rad.cos(),
            lat * self.azimuth_rad.sin(),
            -self.force_n * self.elevation_rad.sin(),
        ]
    }

    /// Checks the load.
    pub fn validate(&self) -> Result<(), crate::SimError> {
        if !(self.force_n.is_finite() && self.force_n >= 0.0) {
            return Err(crate::SimError::out_of_range(
                "force_n",
                self.force_n,
                "≥ 0 N",
            ));
        }
        if !(self.pressure_kpa.is_finite() && self.pressure_kpa > 0.0) {
            return Err(crate::SimError::out_of_range(
                "pressure_kpa",
                self.pressure_kpa,
                "positive",
            ));
        }
        if !self.torque_nmm.is_finite() {
            return Err(crate::SimError::NotFinite("torque_nmm"));
        }
        if !self.elevation_rad.is_finite() || !self.azimuth_rad.is_finite() {
            return Err(crate::SimError::NotFinite("the force direction"));
        }
        Ok(())
    }
}

/// Centreline state of the bent, shortened cone.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConeShape {
    /// Lateral tip deflection, mm, along `(cos azimuth, sin azimuth)`.
    pub tip_deflection_mm: f64,
    /// Axial shortening at the tip, mm.
    pub tip_shortening_mm: f64,
    /// Direction of the deflection, radians.
    pub azimuth_rad: f64,
    /// Twist of the distal disc about the axis, radians (same sense as the torque).
    pub twist_rad: f64,
}

/// How the load deforms the cone.
pub fn shape(cfg: &ConeConfig, load: &ConeLoad) -> ConeShape {
    let stiff = load.pressure_kpa / cfg.pressure_kpa;
    let [fx, fy, fz] = load.components_n();
    let lat = fx.hypot(fy);
    let kb = cfg.bending_stiffness_n_per_mm * stiff;
    let ka = cfg.axial_stiffness_n_per_mm * stiff;
    ConeShape {
        tip_deflection_mm: cfg.max_deflection_mm * (lat / (kb * cfg.max_deflection_mm)).tanh(),
        tip_shortening_mm: cfg.max_shortening_mm
            * ((-fz).max(0.0) / (ka * cfg.max_shortening_mm)).tanh(),
        azimuth_rad: fy.atan2(fx),
        twist_rad: cfg.max_twist_rad
            * (load.torque_nmm / (cfg.torsional_stiffness_nmm_per_rad * stiff * cfg.max_twist_rad))
                .tanh(),
    }
}

/// The T-shaped marker on the distal disc, projected: its bar and its stem, or nothing when
/// the sensor has none. The disc moves with the tip (deflection, shortening) and turns by the
/// twist; its tilt is neglected (at most a few degrees). At rest the bar lies along the image
/// rows (+x) and the stem points to +y.
pub fn t_marker(cfg: &ConeConfig, s: &ConeShape) -> Vec<ConvexPolygon> {
    if cfg.t_marker_mm <= 0.0 {
        return Vec::new();
    }
    let (w, t) = (cfg.t_marker_mm, cfg.t_marker_mm / 6.0);
    let stem = cfg.t_marker_mm / 2.4;
    let z = cfg.length_mm - s.tip_shortening_mm;
    let (cx, cy) = (
        s.tip_deflection_mm * s.azimuth_rad.cos(),
        s.tip_deflection_mm * s.azimuth_rad.sin(),
    );
    let (c, sn) = (s.twist_rad.cos(), s.twist_rad.sin());
    // Rectangles in the disc's own frame (x along the bar), the bar's middle at the centre.
    let rects = [
        (-0.5 * w, 0.5 * w, -0.5 * t, 0.5 * t),
        (-0.5 * t, 0.5 * t, 0.5 * t, 0.5 * t + stem),
    ];
    rects
        .iter()
        .filter_map(|&(x0, x1, y0, y1)| {
            let corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)];
            let verts: Vec<(f64, f64)> = corners
                .iter()
                .filter_map(|&(x, y)| {
                    cfg.camera
                        .px_from_mm([cx + c * x - sn * y, cy + sn * x + c * y, z])
                })
                .collect();
            ConvexPolygon::new(verts)
        })
        .collect()
}

/// Truth for one ring in one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RingTruth {
    /// Ring index, topmost (smallest in the image) first.
    pub index: usize,
    /// Projected centroid column, pixels.
    pub x_px: f64,
    /// Projected centroid row, pixels.
    pub y_px: f64,
    /// Projected area, pixels.
    pub area_px: f64,
    /// Whether the whole ring is inside the image.
    pub fully_in_view: bool,
}

const RING_VERTICES: usize = 96;

/// A circle of the wall at height `z` on the deformed cone, projected.
fn wall_circle(cfg: &ConeConfig, s: &ConeShape, z: f64) -> Option<ConvexPolygon> {
    let l = cfg.length_mm;
    let (c, sn) = (s.azimuth_rad.cos(), s.azimuth_rad.sin());
    let defl = s.tip_deflection_mm * z * z * (3.0 * l - z) / (2.0 * l * l * l);
    let slope = s.tip_deflection_mm * (6.0 * l * z - 3.0 * z * z) / (2.0 * l * l * l);
    let zc = z - s.tip_shortening_mm * z / l;
    // Compression bulges the wall a little (volume kept roughly constant).
    let r = cfg.radius_at(z) * (1.0 + 0.5 * s.tip_shortening_mm / l);
    let tilt = slope.atan();
    let verts: Vec<(f64, f64)> = (0..RING_VERTICES)
        .filter_map(|k| {
            let t = k as f64 / RING_VERTICES as f64 * std::f64::consts::TAU;
            // Circle in the tilted plane: along the bending direction the radius vector gains
            // an axial component (rotation by `tilt` about the axis across the bend).
            let (along, across) = (r * t.cos(), r * t.sin());
            let lat_along = along * tilt.cos();
            let axial = -along * tilt.sin();
            let x = defl * c + lat_along * c - across * sn;
            let y = defl * sn + lat_along * sn + across * c;
            cfg.camera.px_from_mm([x, y, zc + axial])
        })
        .collect();
    ConvexPolygon::new(verts)
}

/// Projected rings (topmost first) with their truth.
pub fn rings(
    cfg: &ConeConfig,
    load: &ConeLoad,
) -> Vec<(Option<(ConvexPolygon, ConvexPolygon)>, RingTruth)> {
    let s = shape(cfg, load);
    let cam = &cfg.camera;
    cfg.ring_heights_mm
        .iter()
        .enumerate()
        .map(|(index, &z)| {
            let half = 0.5 * cfg.ring_width_mm;
            // The lower edge is nearer the camera and looks larger: it is the outer outline.
            let pair = wall_circle(cfg, &s, z - half).zip(wall_circle(cfg, &s, z + half));
            let truth = match &pair {
                Some((outer, hole)) => {
                    let (area_px, (x_px, y_px)) = ring_area_centroid(outer, Some(hole));
                    let (x0, y0, x1, y1) = outer.bounds();
                    let fully_in_view = x0 > 1.0
                        && y0 > 1.0
                        && x1 < cam.width as f64 - 2.0
                        && y1 < cam.height as f64 - 2.0;
                    RingTruth {
                        index,
                        x_px,
                        y_px,
                        area_px,
                        fully_in_view,
                    }
                }
                None => RingTruth {
                    index,
                    x_px: f64::NAN,
                    y_px: f64::NAN,
                    area_px: 0.0,
                    fully_in_view: false,
                },
            };
            (pair, truth)
        })
        .collect()
}

/// Renders one frame of the cone under `load`, noise fixed by `seed`.
pub fn render(
    cfg: &ConeConfig,
    load: &ConeLoad,
    seed: u64,
) -> Result<(RgbImage, Vec<RingTruth>), crate::SimError> {
    cfg.validate()?;
    load.validate()?;
    let rs = rings(cfg, load);
    let mut cov = Canvas::filled(cfg.camera.width, cfg.camera.height, 0.0);
    for (pair, _) in &rs {
        if let Some((outer, hole)) = pair {
            cov.fill_polygon(outer, Some(hole), 1.0);
        }
    }
    for part in t_marker(cfg, &shape(cfg, load)) {
        cov.fill_polygon(&part, None, 1.0);
    }
    cov.blur(cfg.blur_px);
    let img = crate::pattern::frame_from_coverage(&cov, &cfg.look, seed);
    Ok((img, rs.into_iter().map(|(_, t)| t).collect()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(f: f64, az: f64) -> ConeLoad {
        ConeLoad {
            force_n: f,
            elevation_rad: 30f64.to_radians(),
            azimuth_rad: az,
            pressure_kpa: 4.0,
            torque_nmm: 0.0,
        }
    }

    #[test]
    fn zero_force_zero_deformation() {
        let s = shape(&ConeConfig::SEED001, &load(0.0, 1.0));
        assert_eq!((s.tip_deflection_mm, s.tip_shortening_mm), (0.0, 0.0));
        let rest = rings(&ConeConfig::SEED001, &load(0.0, 0.0));
        let cam = ConeConfig::SEED001.camera;
        for (_, r) in &rest {
            assert!((r.x_px - cam.cx_px).abs() < 1e-9 && (r.y_px - cam.cy_px).abs() < 1e-9);
        }
        // Two inner rings in view, the outermost cut by the image border.
        assert!(rest[0].1.fully_in_view && rest[1].1.fully_in_view && !rest[2].1.fully_in_view);
    }

    #[test]
    fn deflection_grows_monotonically_and_saturates() {
        let c = ConeConfig::SEED001;
        let mut last = 0.0;
        let mut steps = Vec::new();
        for k in 1..=20 {
            let s = shape(&c, &load(f64::from(k), 0.0));
            assert!(s.tip_deflection_mm > last);
            steps.push(s.tip_deflection_mm - last);
            last = s.tip_deflection_mm;
        }
        assert!(steps[19] < steps[0], "stiffens at large loads");
        assert!(last < c.max_deflection_mm);
    }

    #[test]
    fn rings_move_with_the_force_direction_and_lower_pressure_softens() {
        let c = ConeConfig::SEED001;
        for az in [0.0, 1.0, 2.5, -2.0] {
            let r = rings(&c, &load(6.0, az));
            let (dx, dy) = (r[0].1.x_px - c.camera.cx_px, r[0].1.y_px - c.camera.cy_px);
            let ang = dy.atan2(dx);
            assert!(
                (ang - az).sin().abs() < 1e-6 && (ang - az).cos() > 0.0,
                "az {az}: {ang}"
            );
        }
        let soft = shape(
            &c,
            &ConeLoad {
                pressure_kpa: 3.0,
                ..load(6.0, 0.0)
            },
        );
        let firm = shape(&c, &load(6.0, 0.0));
        assert!(soft.tip_deflection_mm > firm.tip_deflection_mm);
    }

    #[test]
    fn symmetric_loads_give_mirrored_rings() {
        let c = ConeConfig::SEED001;
        let a = rings(&c, &load(5.0, 0.3));
        let b = rings(&c, &load(5.0, -0.3));
        for (p, q) in a.iter().zip(&b) {
            assert!((p.1.x_px - q.1.x_px).abs() < 1e-9);
            assert!(((p.1.y_px - c.camera.cy_px) + (q.1.y_px - c.camera.cy_px)).abs() < 1e-9);
        }
    }

    #[test]
    fn the_t_twists_with_the_torque_and_only_where_painted() {
        let c = ConeConfig::SEED001_T;
        let twisted = |torque: f64, pressure_kpa: f64| {
            let l = ConeLoad {
                torque_nmm: torque,
                pressure_kpa,
                ..load(0.0, 0.0)
            };
            shape(&c, &l).twist_rad
        };
        assert_eq!(twisted(0.0, 4.0), 0.0);
        // Small torques: τ / k_t; opposite torques, opposite twists; saturating below the
        // largest twist; a softer link twists more.
        assert!((twisted(20.0, 4.0) - 20.0 / c.torsional_stiffness_nmm_per_rad).abs() < 1e-5);
        assert!((twisted(-300.0, 4.0) + twisted(300.0, 4.0)).abs() < 1e-12);
        let most = twisted(1e6, 4.0);
        assert!(most <= c.max_twist_rad && most > 0.99 * c.max_twist_rad);
        assert!(twisted(300.0, 3.0) > twisted(300.0, 4.0));
        // The T: bar and stem, turned by the twist about the disc's centre; none by default.
        let s = shape(
            &c,
            &ConeLoad {
                torque_nmm: 300.0,
                ..load(0.0, 0.0)
            },
        );
        let height = |s: &ConeShape| {
            let parts = t_marker(&c, s);
            assert_eq!(parts.len(), 2);
            let (_, y0, _, y1) = parts[0].bounds();
            y1 - y0
        };
        let rest = shape(&c, &load(0.0, 0.0));
        // The bar (6:1) turned by 0.15 rad spans more rows than lying along them.
        assert!(
            height(&s) > 1.5 * height(&rest),
            "{} vs {}",
            height(&s),
            height(&rest)
        );
        assert!(t_marker(&ConeConfig::SEED001, &s).is_empty());
    }

    #[test]
    fn bad_loads_are_errors() {
        let c = ConeConfig::SEED001;
        assert!(render(&c, &load(-1.0, 0.0), 0).is_err());
        assert!(render(
            &c,
            &ConeLoad {
                pressure_kpa: 0.0,
                ..load(1.0, 0.0)
            },
            0
        )
        .is_err());
    }
}
