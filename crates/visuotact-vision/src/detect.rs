//! The per-frame detector: preprocessing + fused blob pass + filtering, with reusable buffers.
//!
//! [`Detector::detect`] is the convenient call; [`Detector::detect_into`] writes into a caller's
//! vector and allocates nothing once its buffers have grown to the frame size (the live loop).

use serde::{Deserialize, Serialize};
use visuotact_image::{GrayImage, RgbImage};

use crate::blobs::{
    blobs_from_gray_into, blobs_weighted_from_gray_into, Blob, BlobScratch, Connectivity, Level,
    Region,
};
use crate::preprocess::{
    adaptive_levels_into, gray_from_rgb_into, histogram, morphology_in_place, open3_from_rgb_into,
    otsu_level, MorphScratch, Open3Scratch, PreprocessConfig, Threshold,
};

/// The integer level `t` with `v > t` ⟺ `v > level · 255` for 8-bit `v` (MATLAB `im2bw`):
/// `floor(level · 255)` (0.25 → 63, so 64 is foreground and 63 is not).
pub fn fixed_level(level: f64) -> u8 {
    (level * 255.0).floor().clamp(0.0, 255.0) as u8
}

/// Which blobs count as markers.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct BlobFilter {
    /// Smallest area kept, in pixels.
    pub min_area_px: u32,
    /// Largest area kept, in pixels.
    pub max_area_px: u32,
    /// Keep blobs touching the border of the processed region (excluded by default, seed 001).
    pub keep_border: bool,
    /// Pixel neighbourhood.
    pub connectivity: Connectivity,
}

impl BlobFilter {
    /// Defaults: 8-connected, border blobs dropped, areas 5..100 000 px.
    pub const DEFAULT: Self = Self {
        min_area_px: 5,
        max_area_px: 100_000,
        keep_border: false,
        connectivity: Connectivity::Eight,
    };

    /// Whether `b` passes the filter.
    pub fn keeps(&self, b: &Blob) -> bool {
        (self.keep_border || !b.touches_border)
            && b.area_px >= self.min_area_px
            && b.area_px <= self.max_area_px
    }
}

impl Default for BlobFilter {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Which centroid a blob's `x_px`, `y_px` report.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Centroid {
    /// The mean of the blob's pixels (OpenCV, scikit-image, MATLAB `regionprops`).
    #[default]
    Binary,
    /// Pixels weighted by how far their grey value exceeds the level: pixels that noise flips
    /// across the level barely count (thin rings: 5–8× less jitter). Shape moments stay binary.
    Weighted,
}

/// Preprocessing plus blob filter: everything needed to turn a frame into marker blobs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(default)]
pub struct DetectorConfig {
    /// Channel, inversion, morphology, threshold, region.
    pub preprocess: PreprocessConfig,
    /// Which blobs are markers.
    pub filter: BlobFilter,
    /// Which centroid the blobs report.
    pub centroid: Centroid,
}

/// What one detection produced besides the blobs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Detection {
    /// The global threshold level used (Fixed and Otsu), `None` for adaptive.
    pub level: Option<u8>,
    /// Blobs found before filtering.
    pub raw_count: usize,
}

/// Runs the detection pipeline with buffers kept between frames.
#[derive(Clone, Debug)]
pub struct Detector {
    cfg: DetectorConfig,
    gray: GrayImage,
    morph: MorphScratch,
    levels: Vec<f32>,
    scratch: BlobScratch,
    all: Vec<Blob>,
    centroids: Vec<(f64, f64)>,
    open3: Open3Scratch,
    /// Histogram of the preprocessed image, when the streaming path computed it.
    hist: Option<[u32; 256]>,
    /// Blobs of the last frame dropped only because they touch the border.
    cut: Vec<Blob>,
}

impl Detector {
    /// A detector for `cfg`; fails with a message when the settings are inconsistent.
    pub fn new(cfg: DetectorConfig) -> Result<Self, String> {
        cfg.preprocess.validate()?;
        if cfg.filter.min_area_px > cfg.filter.max_area_px {
            return Err(format!(
                "minimum area {} px exceeds maximum area {} px",
                cfg.filter.min_area_px, cfg.filter.max_area_px
            ));
        }
        Ok(Self {
            cfg,
            gray: GrayImage::new(0, 0),
            morph: MorphScratch::default(),
            levels: Vec::new(),
            scratch: BlobScratch::default(),
            all: Vec::new(),
            centroids: Vec::new(),
            open3: Open3Scratch::default(),
            hist: None,
            cut: Vec::new(),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &DetectorConfig {
        &self.cfg
    }

    /// The blobs of the last frame that passed the area filter but were dropped because they
    /// touch the border (markers cut by the edge of the image or region; empty with
    /// `keep_border`). Tracking uses them to tell a marker that left the view from one lost.
    pub fn last_cut(&self) -> &[Blob] {
        &self.cut
    }

    /// The preprocessed single-channel image of the last frame.
    pub fn last_gray(&self) -> &GrayImage {
        &self.gray
    }

    /// Preprocesses `rgb` into the detector's single-channel buffer (channel, inversion,
    /// morphology) and returns it.
    pub fn preprocess(&mut self, rgb: &RgbImage) -> &GrayImage {
        let p = &self.cfg.preprocess;
        self.hist = None;
        if p.open && !p.close && p.morph_size == 3 {
            // The common case streams channel + opening (+ histogram for Otsu) row by row.
            let mut hist = [0u32; 256];
            let want = matches!(p.threshold, Threshold::Otsu).then_some(&mut hist);
            let got = want.is_some();
            open3_from_rgb_into(
                rgb,
                p.channel,
                p.invert,
                &mut self.gray,
                want,
                &mut self.open3,
            );
            if got {
                self.hist = Some(hist);
            }
        } else {
            gray_from_rgb_into(rgb, p.channel, p.invert, &mut self.gray);
            morphology_in_place(&mut self.gray, p, &mut self.morph);
        }
        &self.gray
    }

    /// Detects marker blobs in an RGB frame into `out` (cleared first).
    pub fn detect_into(&mut self, rgb: &RgbImage, out: &mut Vec<Blob>) -> Detection {
        self.preprocess(rgb);
        self.blobs_of_gray(out)
    }

    /// Detects marker blobs in an already single-channel image (no channel selection or
    /// inversion, but morphology and threshold as configured).
    pub fn detect_gray_into(&mut self, gray: &GrayImage, out: &mut Vec<Blob>) -> Detection {
        self.gray.clone_from(gray);
        morphology_in_place(&mut self.gray, &self.cfg.preprocess, &mut self.morph);
        self.hist = None;
        self.blobs_of_gray(out)
    }

    /// Allocating form of [`Detector::detect_into`].
    pub fn detect(&mut self, rgb: &RgbImage) -> Vec<Blob> {
        let mut out = Vec::new();
        self.detect_into(rgb, &mut out);
        out
    }

    fn blobs_of_gray(&mut self, out: &mut Vec<Blob>) -> Detection {
        let p = &self.cfg.preprocess;
        let region = Region {
            roi: p.roi,
            circle: p.circle,
        };
        let level = match p.threshold {
            Threshold::Fixed { level } => Some(fixed_level(level)),
            Threshold::Otsu => Some(otsu_level(
                &self.hist.unwrap_or_else(|| histogram(self.gray.as_slice())),
            )),
            Threshold::Adaptive { window_px, offset } => {
                adaptive_levels_into(&self.gray, window_px, offset, &mut self.levels);
                None
            }
        };
        let lv = match level {
            Some(t) => Level::Scalar(t),
            None => Level::PerPixel(&self.levels),
        };
        match self.cfg.centroid {
            Centroid::Binary => blobs_from_gray_into(
                &self.gray,
                lv,
                region,
                self.cfg.filter.connectivity,
                &mut self.scratch,
                &mut self.all,
            ),
            Centroid::Weighted => {
                blobs_weighted_from_gray_into(
                    &self.gray,
                    lv,
                    region,
                    self.cfg.filter.connectivity,
                    &mut self.scratch,
                    &mut self.all,
                    &mut self.centroids,
                );
                for (b, &(x, y)) in self.all.iter_mut().zip(&self.centroids) {
                    (b.x_px, b.y_px) = (x, y);
                }
            }
        }
        out.clear();
        out.extend(self.all.iter().filter(|b| self.cfg.filter.keeps(b)));
        let f = &self.cfg.filter;
        self.cut.clear();
        self.cut.extend(
            self.all
                .iter()
                .filter(|b| !f.keep_border && b.touches_border && b.area_px <= f.max_area_px),
        );
        Detection {
            level,
            raw_count: self.all.len(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::fixed_level;

    #[test]
    fn fixed_level_is_im2bw() {
        for level in [0.0, 0.1, 0.25, 0.5, 0.99, 1.0] {
            let t = fixed_level(level);
            for v in 0..=255u8 {
                assert_eq!(v > t, f64::from(v) > level * 255.0, "level {level}, v {v}");
            }
        }
    }
}
