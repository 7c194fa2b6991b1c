//! Marker size and spacing measured in a frame, and the detector settings they call for: a
//! 3 × 3 opening erases 2–4 px pins (a 128 × 128 TacTip image) and the 5 px smallest area
//! drops them, while 30 px markers on a 1280 × 720 image want both.
//!
//! Contract: [`MarkerSize::measure`] detects with the given settings but no opening and a
//! 1 px smallest area, takes the blobs whose area is within a factor 4 of the 90th
//! percentile's (the markers: noise specks are smaller, a rim or a shadow larger), and gives
//! their median area, the diameter of a disc of that area, and the median distance from each
//! to its nearest neighbour. [`MarkerSize::opening`] and [`MarkerSize::min_area_px`] are the
//! rules `calibrate` applies where the user set neither.
//!
//! ```
//! use visuotact_image::RgbImage;
//! use visuotact_vision::calibration::Preset;
//! use visuotact_vision::sizing::MarkerSize;
//!
//! // 2 × 2 px white pins every 6 px on black.
//! let img = RgbImage::from_fn(40, 40, |x, y| {
//!     let pin = x % 6 < 2 && y % 6 < 2 && (4..34).contains(&x) && (4..34).contains(&y);
//!     if pin { [255; 3] } else { [0; 3] }
//! });
//! let size = MarkerSize::measure(&img, &Preset::Iats.config().detector).unwrap();
//! assert_eq!((size.area_px, size.spacing_px), (4.0, 6.0));
//! assert!(!size.opening() && size.min_area_px() == 1);
//! ```

use visuotact_image::RgbImage;

use crate::detect::{BlobFilter, Detector, DetectorConfig};
use crate::layout::median;

/// The markers' typical size and spacing in a frame.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MarkerSize {
    /// Median marker area, pixels.
    pub area_px: f64,
    /// Diameter of a disc of that area, pixels.
    pub diameter_px: f64,
    /// Median distance from a marker to its nearest neighbour, pixels.
    pub spacing_px: f64,
    /// Blobs counted as markers.
    pub markers: usize,
}

impl MarkerSize {
    /// Markers narrower than this lose too much to a 3 × 3 opening, pixels.
    pub const OPENING_FROM_PX: f64 = 5.0;

    /// The markers of `frame` detected with `cfg` less its opening and area limit (see the
    /// module doc); `None` when fewer than 3 are found.
    pub fn measure(frame: &RgbImage, cfg: &DetectorConfig) -> Option<Self> {
        let mut bare = cfg.clone();
        bare.preprocess.open = false;
        bare.filter = BlobFilter {
            min_area_px: 1,
            ..cfg.filter
        };
        let blobs = Detector::new(bare).ok()?.detect(frame);
        let mut areas: Vec<u32> = blobs.iter().map(|b| b.area_px).collect();
        areas.sort_unstable();
        let p90 = f64::from(*areas.get(areas.len() * 9 / 10)?);
        let markers: Vec<(f64, f64, f64)> = blobs
            .iter()
            .map(|b| (f64::from(b.area_px), b.x_px, b.y_px))
            .filter(|&(a, _, _)| a >= p90 / 4.0 && a <= p90 * 4.0)
            .collect();
        if markers.len() < 3 {
            return None;
        }
        let mut kept: Vec<f64> = markers.iter().map(|m| m.0).collect();
        let area_px = median(&mut kept);
        let mut nearest: Vec<f64> = markers
            .iter()
            .map(|&(_, x, y)| {
                markers
                    .iter()
                    .map(|&(_, u, v)| (u - x).hypot(v - y))
                    .filter(|&d| d > 0.0)
                    .fold(f64::INFINITY, f64::min)
            })
            .collect();
        Some(Self {
            area_px,
            diameter_px: 2.0 * (area_px / std::f64::consts::PI).sqrt(),
            spacing_px: median(&mut nearest),
            markers: markers.len(),
        })
    }

    /// Whether a 3 × 3 opening leaves these markers whole (at least [`Self::OPENING_FROM_PX`]
    /// across).
    pub fn opening(&self) -> bool {
        self.diameter_px >= Self::OPENING_FROM_PX
    }

    /// The smallest blob kept: a quarter of the marker area, at least 1 px and at most the
    /// default 5 px.
    pub fn min_area_px(&self) -> u32 {
        ((self.area_px / 4.0).floor() as u32).clamp(1, BlobFilter::DEFAULT.min_area_px)
    }

    /// The size, spacing and what they decided, in words.
    pub fn in_words(&self, cfg: &DetectorConfig) -> String {
        format!(
            "markers about {:.1} px across ({:.0} px²), {:.1} px apart: {}, smallest blob {} px",
            self.diameter_px,
            self.area_px,
            self.spacing_px,
            if cfg.preprocess.open {
                "opening on"
            } else {
                "no opening"
            },
            cfg.filter.min_area_px
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::Preset;

    /// Discs of radius `r` every `pitch` px on a `w` × `h` black image.
    fn discs(w: usize, h: usize, pitch: f64, r: f64) -> RgbImage {
        RgbImage::from_fn(w, h, |x, y| {
            let (fx, fy) = (x as f64, y as f64);
            let (cx, cy) = ((fx / pitch).round() * pitch, (fy / pitch).round() * pitch);
            let inside = cx > pitch * 0.5
                && cy > pitch * 0.5
                && cx < w as f64 - pitch * 0.5
                && cy < h as f64 - pitch * 0.5;
            if inside && (fx - cx).hypot(fy - cy) <= r {
                [230; 3]
            } else {
                [0; 3]
            }
        })
    }

    #[test]
    fn big_and_tiny_markers_are_sized_from_the_frame() {
        let cfg = Preset::Iats.config().detector;
        let big = MarkerSize::measure(&discs(1280, 720, 80.0, 15.0), &cfg).unwrap();
        assert!((big.diameter_px - 30.0).abs() < 1.0, "{big:?}");
        assert!((big.spacing_px - 80.0).abs() < 1e-9, "{big:?}");
        assert!(big.opening() && big.min_area_px() == 5);
        let tiny = MarkerSize::measure(&discs(128, 128, 5.0, 1.0), &cfg).unwrap();
        assert_eq!((tiny.area_px, tiny.spacing_px), (5.0, 5.0));
        assert!(!tiny.opening() && tiny.min_area_px() == 1, "{tiny:?}");
        assert!(MarkerSize::measure(&RgbImage::new(20, 20), &cfg).is_none());
    }
}
