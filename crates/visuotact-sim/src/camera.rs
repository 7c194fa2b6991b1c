//! Pinhole camera with radial distortion.
//!
//! Camera coordinates in millimetres: the camera looks along +z, x to the right of the image,
//! y down the image. A point `(X, Y, Z)` with `Z > 0` has normalised coordinates
//! `(X/Z, Y/Z)`, distorted by `1 + k1 r² + k2 r⁴` (Brown's radial model, as OpenCV's first two
//! coefficients), then mapped to pixels by the focal lengths and principal point.
//!
//! ```
//! use visuotact_sim::camera::Camera;
//! let cam = Camera::WEBCAM_640X480;
//! let (u, v) = cam.px_from_mm([0.0, 0.0, 50.0]).unwrap();
//! assert_eq!((u, v), (cam.cx_px, cam.cy_px));
//! ```

/// Intrinsics and distortion.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Camera {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Focal length along x, pixels.
    pub fx_px: f64,
    /// Focal length along y, pixels.
    pub fy_px: f64,
    /// Principal point column, pixels.
    pub cx_px: f64,
    /// Principal point row, pixels.
    pub cy_px: f64,
    /// First radial coefficient (negative: barrel, as wide-angle lenses).
    pub k1: f64,
    /// Second radial coefficient.
    pub k2: f64,
}

impl Camera {
    /// A 640×480 wide-angle webcam (about 90° across the diagonal), mild barrel distortion.
    pub const WEBCAM_640X480: Self = Self {
        width: 640,
        height: 480,
        fx_px: 330.0,
        fy_px: 330.0,
        cx_px: 319.5,
        cy_px: 239.5,
        k1: -0.08,
        k2: 0.01,
    };

    /// Checks the parameters.
    pub fn validate(&self) -> Result<(), crate::SimError> {
        if self.width == 0 || self.height == 0 {
            return Err(crate::SimError::Size {
                what: "camera size",
                width: self.width,
                height: self.height,
                limit: "must be positive".to_string(),
            });
        }
        if self.width > crate::MAX_CAMERA_SIDE_PX || self.height > crate::MAX_CAMERA_SIDE_PX {
            return Err(crate::SimError::Size {
                what: "camera size",
                width: self.width,
                height: self.height,
                limit: format!(
                    "exceeds the simulator's limit of {} px a side",
                    crate::MAX_CAMERA_SIDE_PX
                ),
            });
        }
        if !(self.fx_px > 0.0 && self.fy_px > 0.0) {
            let (name, v) = if self.fx_px > 0.0 {
                ("camera fy_px", self.fy_px)
            } else {
                ("camera fx_px", self.fx_px)
            };
            return Err(crate::SimError::out_of_range(name, v, "positive"));
        }
        if ![self.cx_px, self.cy_px, self.k1, self.k2]
            .iter()
            .all(|v| v.is_finite())
        {
            return Err(crate::SimError::NotFinite(
                "the camera's principal point and distortion",
            ));
        }
        Ok(())
    }

    fn distortion(&self, r2: f64) -> f64 {
        1.0 + self.k1 * r2 + self.k2 * r2 * r2
    }

    /// Pixel position of a camera-frame point in millimetres; `None` behind the camera.
    pub fn px_from_mm(&self, p: [f64; 3]) -> Option<(f64, f64)> {
        if p[2] <= 1e-9 {
            return None;
        }
        let (x, y) = (p[0] / p[2], p[1] / p[2]);
        let d = self.distortion(x * x + y * y);
        Some((
            self.cx_px + self.fx_px * x * d,
            self.cy_px + self.fy_px * y * d,
        ))
    }

    /// The undistorted normalised ray `(X/Z, Y/Z)` through a pixel (Newton iterations on the
    /// radial model; exact to 1e-12 inside the image for the presets).
    pub fn ray_from_px(&self, u: f64, v: f64) -> (f64, f64) {
        let xd = (u - self.cx_px) / self.fx_px;
        let yd = (v - self.cy_px) / self.fy_px;
        let rd = xd.hypot(yd);
        if rd == 0.0 {
            return (0.0, 0.0);
        }
        // Solve r · (1 + k1 r² + k2 r⁴) = rd for r.
        let mut r = rd;
        for _ in 0..30 {
            let r2 = r * r;
            let f = r * self.distortion(r2) - rd;
            let df = 1.0 + 3.0 * self.k1 * r2 + 5.0 * self.k2 * r2 * r2;
            let step = f / df;
            r -= step;
            if step.abs() < 1e-15 {
                break;
            }
        }
        (xd * r / rd, yd * r / rd)
    }

    /// The camera-frame point at depth `z_mm` seen at a pixel.
    pub fn mm_from_px(&self, u: f64, v: f64, z_mm: f64) -> [f64; 3] {
        let (x, y) = self.ray_from_px(u, v);
        [x * z_mm, y * z_mm, z_mm]
    }
}

impl Default for Camera {
    fn default() -> Self {
        Self::WEBCAM_640X480
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn projection_round_trips() {
        let cam = Camera::WEBCAM_640X480;
        for &(x, y, z) in &[
            (0.0, 0.0, 30.0),
            (20.0, -15.0, 35.0),
            (-31.0, 22.0, 36.0),
            (5.0, 40.0, 200.0),
        ] {
            let (u, v) = cam.px_from_mm([x, y, z]).unwrap();
            let p = cam.mm_from_px(u, v, z);
            assert!(
                (p[0] - x).abs() < 1e-9 && (p[1] - y).abs() < 1e-9,
                "{x} {y} {z} → {p:?}"
            );
        }
        assert!(cam.px_from_mm([1.0, 1.0, -1.0]).is_none());
    }

    #[test]
    fn barrel_distortion_pulls_points_inwards() {
        let cam = Camera::WEBCAM_640X480;
        let ideal = Camera {
            k1: 0.0,
            k2: 0.0,
            ..cam
        };
        let (u, _) = cam.px_from_mm([30.0, 0.0, 35.0]).unwrap();
        let (ui, _) = ideal.px_from_mm([30.0, 0.0, 35.0]).unwrap();
        assert!(u < ui);
    }
}
