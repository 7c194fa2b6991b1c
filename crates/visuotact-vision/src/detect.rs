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
use crate::kernels::Avx2;
use crate::preprocess::{
    adaptive_levels_into, gray_from_rgb_into, histogram_of, morphology_in_place,
    open3_from_rgb_into, otsu_level, HistogramPixels, MorphScratch, Open3Scratch, PreprocessConfig,
    Threshold,
};
use crate::separate::{separate_touching, SeparateScratch};

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
    /// The grey-level centroid of the marker itself: the blob and a one-pixel ring around its
    /// moment ellipse, each pixel weighted by its grey value above a background plane fitted to
    /// the pixels 2–3 px outside the blob's box (robustly: outliers such as a neighbour's edge
    /// dropped). The partly covered edge pixels that any threshold cuts off carry the sub-pixel
    /// position: 2–4× less displacement error than `Weighted` on the sensor zoo. Blobs touching
    /// the border (or within 3 px of it) and hollow ones (annuli: under half their box) keep
    /// `Weighted`.
    Grey,
}

visuotact_image::names_from_str!(Centroid, "centroid");

impl Centroid {
    /// The names [`Centroid::from_name`] and `FromStr` read, as [`Centroid::name`] writes them.
    pub const NAMES: &'static [&'static str] = &["binary", "weighted", "grey"];

    /// `binary`, `weighted` or `grey`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Binary => "binary",
            Self::Weighted => "weighted",
            Self::Grey => "grey",
        }
    }

    /// The centroid called `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "binary" => Some(Self::Binary),
            "weighted" => Some(Self::Weighted),
            "grey" => Some(Self::Grey),
            _ => None,
        }
    }
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
    labelling: Labelling,
    /// The last frame had grey-centroid blobs that keep the weighted centroid.
    grey_needs_weights: bool,
    open3: Open3Scratch,
    /// Histogram of the preprocessed image, when the streaming path computed it.
    hist: Option<[u32; 256]>,
    /// Blobs of the last frame dropped only because they touch the border.
    cut: Vec<Blob>,
    /// Background ring columns for the grey-level centroid.
    ring: Vec<u8>,
    /// The last frame's global level (`None`: per-pixel levels, in `levels`).
    level: Option<u8>,
    /// Scratch for parting touching markers.
    separate: SeparateScratch,
}

impl Detector {
    /// A detector for `cfg`; fails with a message when the settings are inconsistent.
    pub fn new(cfg: DetectorConfig) -> Result<Self, crate::ConfigError> {
        cfg.preprocess.validate()?;
        if cfg.filter.min_area_px > cfg.filter.max_area_px {
            return Err(crate::ConfigError::AreaRange {
                min_px: cfg.filter.min_area_px,
                max_px: cfg.filter.max_area_px,
            });
        }
        Ok(Self {
            cfg,
            gray: GrayImage::new(0, 0),
            morph: MorphScratch::default(),
            levels: Vec::new(),
            labelling: Labelling::default(),
            grey_needs_weights: false,
            open3: Open3Scratch::default(),
            hist: None,
            cut: Vec::new(),
            ring: Vec::new(),
            level: None,
            separate: SeparateScratch::default(),
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
            let want = p.threshold.histogram_pixels().map(|px| (&mut hist, px));
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

    /// Parts the blobs of the last frame (`blobs`, as it returned them) that hold touching
    /// markers where its grey image dips between them ([`crate::separate`]); `max_fill` is
    /// the least share of its moments' ellipse one of the sensor's markers fills. Returns how
    /// many blobs were parted.
    pub fn part_touching(&mut self, blobs: &mut Vec<Blob>, max_fill: f64) -> usize {
        let (w, levels, level) = (self.gray.width(), &self.levels, self.level);
        let level_at = |x: usize, y: usize| match level {
            Some(t) => f32::from(t),
            None => levels[y * w + x],
        };
        let how = (self.cfg.filter.connectivity, max_fill);
        separate_touching(blobs, &self.gray, level_at, how, &mut self.separate)
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
            Threshold::Otsu | Threshold::OtsuSampled => {
                let pixels = p.threshold.histogram_pixels();
                let of_gray = || histogram_of(&self.gray, pixels.unwrap_or(HistogramPixels::All));
                Some(otsu_level(&self.hist.unwrap_or_else(of_gray)))
            }
            Threshold::Adaptive { window_px, offset } => {
                adaptive_levels_into(&self.gray, window_px, offset, &mut self.levels);
                None
            }
        };
        let lv = match level {
            Some(t) => Level::Scalar(t),
            None => Level::PerPixel(&self.levels),
        };
        let connectivity = self.cfg.filter.connectivity;
        let grey = self.cfg.centroid == Centroid::Grey;
        // Grey centroids with a global level are refined from binary blobs (the ellipse centred
        // on the weighted centroid taken over each blob's box); only when a kept blob cannot be
        // refined (a hollow one, one at the border) does the frame need the labelling's
        // weighted centroids. Whether it did is remembered, so that a sensor of annuli is
        // labelled once per frame; the result is the same either way.
        let mut weighted = match self.cfg.centroid {
            Centroid::Binary => false,
            Centroid::Weighted => true,
            Centroid::Grey => level.is_none() || self.grey_needs_weights,
        };
        loop {
            let lab = &mut self.labelling;
            lab.label(&self.gray, lv, region, connectivity, weighted);
            out.clear();
            out.extend(lab.all.iter().filter(|b| self.cfg.filter.keeps(b)));
            if !grey {
                break;
            }
            // On the preprocessed image: a 3 × 3 opening keeps a marker's grey profile (it is
            // larger than the window and convex) and takes noise peaks off.
            let left = refine_grey(out, &self.gray, &mut self.ring, level);
            self.grey_needs_weights = left > 0;
            if left == 0 || weighted {
                break;
            }
            weighted = true;
        }
        self.level = level;
        let f = &self.cfg.filter;
        self.cut.clear();
        self.cut.extend(
            self.labelling
                .all
                .iter()
                .filter(|b| !f.keep_border && b.touches_border && b.area_px <= f.max_area_px),
        );
        Detection {
            level,
            raw_count: self.labelling.all.len(),
        }
    }
}

/// The labelling pass's scratch and its blobs (before the filter).
#[derive(Clone, Debug, Default)]
struct Labelling {
    scratch: BlobScratch,
    all: Vec<Blob>,
    centroids: Vec<(f64, f64)>,
}

impl Labelling {
    /// Labels `gray` into `all`, with grey-level weighted centroids when `weighted`.
    fn label(
        &mut self,
        gray: &GrayImage,
        lv: Level<'_>,
        region: Region,
        connectivity: Connectivity,
        weighted: bool,
    ) {
        let (s, all) = (&mut self.scratch, &mut self.all);
        if !weighted {
            blobs_from_gray_into(gray, lv, region, connectivity, s, all);
            return;
        }
        blobs_weighted_from_gray_into(gray, lv, region, connectivity, s, all, &mut self.centroids);
        for (b, &(x, y)) in all.iter_mut().zip(&self.centroids) {
            (b.x_px, b.y_px) = (x, y);
        }
    }
}

/// Replaces each blob's centroid by its grey-level centroid ([`Centroid::Grey`]) measured on
/// `gray` where it can be measured; `ring` is scratch, `level` the frame's global level if it
/// has one (else the blobs carry weighted centroids). Returns how many blobs it left as they
/// were (hollow ones, those at the border).
fn refine_grey(
    blobs: &mut [Blob],
    gray: &GrayImage,
    ring: &mut Vec<u8>,
    level: Option<u8>,
) -> usize {
    // One check of the CPU per frame; the loop is compiled with AVX2 and FMA where it runs on
    // them, its kernels inlined.
    Avx2::dispatch(
        Refinement {
            blobs,
            gray,
            ring,
            level,
        },
        #[cfg(target_arch = "x86_64")]
        refine_grey_avx2,
        refine_grey_on,
    )
}

/// The arguments of [`refine_grey`].
struct Refinement<'a> {
    blobs: &'a mut [Blob],
    gray: &'a GrayImage,
    ring: &'a mut Vec<u8>,
    level: Option<u8>,
}

/// [`refine_grey_on`] compiled with AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn refine_grey_avx2(cpu: Avx2, r: Refinement<'_>) -> usize {
    refine_grey_on(Some(cpu), r)
}

/// [`refine_grey`] on `cpu`'s kernels.
#[inline(always)]
fn refine_grey_on(cpu: Option<Avx2>, r: Refinement<'_>) -> usize {
    let mut left = 0;
    for b in r.blobs.iter_mut() {
        match grey_centroid(cpu, b, r.gray, r.ring, r.level) {
            Some(c) => (b.x_px, b.y_px) = c,
            None => left += 1,
        }
    }
    left
}

/// The grey-level centroid of blob `b` ([`Centroid::Grey`]), `None` where it has none.
#[inline(always)]
fn grey_centroid(
    cpu: Option<Avx2>,
    b: &Blob,
    gray: &GrayImage,
    ring: &mut Vec<u8>,
    level: Option<u8>,
) -> Option<(f64, f64)> {
    let (width, height) = (gray.width(), gray.height());
    // Annuli and other hollow shapes (under half their box) keep the weighted centroid.
    let box_area = (b.bbox.x1 - b.bbox.x0) * (b.bbox.y1 - b.bbox.y0);
    if b.touches_border || 2 * b.area_px < box_area {
        return None;
    }
    // Window: the box grown by 3 px; background ring: its outer 1-px frame.
    let (bx0, by0, bx1, by1) = (
        b.bbox.x0 as usize,
        b.bbox.y0 as usize,
        b.bbox.x1 as usize,
        b.bbox.y1 as usize,
    );
    if bx0 < 3 || by0 < 3 || bx1 + 3 > width || by1 + 3 > height {
        return None;
    }
    let (x0, y0, x1, y1) = (bx0 - 3, by0 - 3, bx1 + 3, by1 + 3);
    let (nw, nh) = (x1 - x0, y1 - y0);
    // The ring: top row, bottom row, left column, right column (between the rows).
    let (xm, ym) = (0.5 * (nw - 1) as f32, 0.5 * (nh - 1) as f32);
    let data = gray.as_slice();
    ring.clear();
    ring.extend((y0 + 1..y1 - 1).map(|y| data[y * width + x0]));
    ring.extend((y0 + 1..y1 - 1).map(|y| data[y * width + x1 - 1]));
    let (left, right) = ring.split_at(nh - 2);
    let sides = crate::kernels::RingSides {
        top: &data[y0 * width + x0..y0 * width + x1],
        bottom: &data[(y1 - 1) * width + x0..(y1 - 1) * width + x1],
        left,
        right,
        xm,
        ym,
    };
    let (mid, sxp, syp) = crate::kernels::ring_plane_on(cpu, &sides)?;
    // Weights inside the blob's moment ellipse (semi-axes 2·sqrt(λ)) grown by one pixel,
    // q(dx, dy) ≤ 1 for its quadratic form q; coordinates relative to its centre. The centre
    // is the weighted centroid (pixels weighted by their excess over the level; centred on the
    // binary centroid, the zoo's displacement errors were 7–13 % larger), taken over the box,
    // where it equals the labelling's unless another blob reaches into the box.
    let (cx, cy) = match level {
        Some(t) => {
            let (cols, rows) = (bx1 - bx0, by1 - by0);
            let window = (&data[by0 * width + bx0..], width, cols, rows);
            let e = crate::kernels::excess_sums_on(cpu, window, t);
            if e[0] > 0 {
                let sw = e[0] as f64;
                (bx0 as f64 + e[1] as f64 / sw, by0 as f64 + e[2] as f64 / sw)
            } else {
                (b.x_px, b.y_px)
            }
        }
        None => (b.x_px, b.y_px),
    };
    let [q11, q12, q22] = ellipse_form(b.mu20_px2, b.mu11_px2, b.mu02_px2);
    // The plane about the centroid: level = p0 + sxp·dx + syp·dy.
    let (wx0, wy0) = (x0 as f32 + xm, y0 as f32 + ym);
    let p0 = mid + sxp * (cx as f32 - wx0) + syp * (cy as f32 - wy0);
    let (xa, ya) = (bx0 - 1, by0 - 1);
    let [sw, sx, sy] = crate::kernels::ellipse_window_sums_on(
        cpu,
        (&data[ya * width + xa..], width, bx1 + 1 - xa, by1 + 1 - ya),
        crate::kernels::EllipseWindow {
            dx0: (xa as f64 - cx) as f32,
            dy0: (ya as f64 - cy) as f32,
            q11,
            q12,
            q22,
            p0,
            sx: sxp,
            sy: syp,
        },
    );
    (sw > 0.0).then(|| (cx + sx / sw, cy + sy / sw))
}

/// The quadratic form `[q11, q12, q22]` of the ellipse with the axes of the covariance
/// `[[a, b], [b, c]]` and semi-axes `2·sqrt(λ) + 1` for its eigenvalues `λ` (negative ones
/// taken as 0). Without angles: with `P` the projector onto the major axis, `(C − λ₂ I)/(λ₁ −
/// λ₂)`, the form is `i₂ I + (i₁ − i₂) P` for `iₖ = 1/rₖ²`, and `(i₁ − i₂)/(λ₁ − λ₂)` has a
/// closed form free of the difference `λ₁ − λ₂` (finite for a circle).
fn ellipse_form(a: f64, b: f64, c: f64) -> [f32; 3] {
    let half = 0.5 * (a + c);
    let root = (0.25 * (a - c) * (a - c) + b * b).sqrt();
    let l2_exact = half - root;
    let (s1, s2) = ((half + root).sqrt(), l2_exact.max(0.0).sqrt());
    let (ra, rb) = (2.0 * s1 + 1.0, 2.0 * s2 + 1.0);
    let (ia, ib) = (1.0 / (ra * ra), 1.0 / (rb * rb));
    // k = (ia − ib)/(λ₁ − λ₂): with ra − rb = 2(λ₁ − λ₂)/(s1 + s2) where λ₂ ≥ 0.
    let k = if l2_exact < 0.0 {
        (ia - ib) / (2.0 * root)
    } else if s1 + s2 > 0.0 {
        -2.0 * (ra + rb) * ia * ib / (s1 + s2)
    } else {
        0.0
    };
    [
        (ib + k * (a - l2_exact)) as f32,
        (k * b) as f32,
        (ib + k * (c - l2_exact)) as f32,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A dark frame with bright anti-aliased discs `(cx, cy, r)` and annuli `(cx, cy, r_in,
    /// r_out)` (4 × 4 supersampled coverage).
    fn frame(discs: &[(f64, f64, f64)], annuli: &[(f64, f64, f64, f64)]) -> RgbImage {
        RgbImage::from_fn(120, 80, |x, y| {
            let mut cover = 0.0;
            for sy in 0..4 {
                for sx in 0..4 {
                    let (px, py) = (
                        x as f64 + (sx as f64 - 1.5) / 4.0,
                        y as f64 + (sy as f64 - 1.5) / 4.0,
                    );
                    let inside = discs
                        .iter()
                        .any(|&(cx, cy, r)| (px - cx).hypot(py - cy) <= r)
                        || annuli.iter().any(|&(cx, cy, ri, ro)| {
                            let d = (px - cx).hypot(py - cy);
                            ri <= d && d <= ro
                        });
                    cover += f64::from(u8::from(inside)) / 16.0;
                }
            }
            let g = (20.0 + 200.0 * cover).round() as u8;
            [g, g, g]
        })
    }

    fn detector(centroid: Centroid) -> Detector {
        Detector::new(DetectorConfig {
            centroid,
            ..Default::default()
        })
        .unwrap()
    }

    #[test]
    fn grey_centroids_do_not_depend_on_the_frame_before() {
        let discs = [(20.3, 20.6, 6.0), (50.1, 22.4, 5.5), (90.7, 60.2, 7.0)];
        let with_annulus = frame(&discs, &[(40.4, 58.3, 8.0, 12.0)]);
        let moved = frame(
            &[(21.0, 20.1, 6.0), (49.6, 23.0, 5.5), (90.2, 60.9, 7.0)],
            &[],
        );
        // The frame with an annulus needs the labelling's weighted centroids, and the detector
        // remembers it; the next frame's blobs equal a fresh detector's.
        let (mut warm, mut out) = (detector(Centroid::Grey), Vec::new());
        warm.detect_into(&with_annulus, &mut out);
        assert_eq!(out.len(), 4);
        let annulus = out.iter().find(|b| b.bbox.x1 - b.bbox.x0 > 20).unwrap();
        let weighted = detector(Centroid::Weighted).detect(&with_annulus);
        let same = weighted
            .iter()
            .find(|b| b.bbox.x1 - b.bbox.x0 > 20)
            .unwrap();
        assert_eq!((annulus.x_px, annulus.y_px), (same.x_px, same.y_px));
        warm.detect_into(&moved, &mut out);
        assert_eq!(out, detector(Centroid::Grey).detect(&moved));
        // And the discs' grey centroids are where the discs are.
        for (b, &(cx, cy, _)) in
            out.iter()
                .zip(&[(21.0, 20.1, 6.0), (49.6, 23.0, 5.5), (90.2, 60.9, 7.0)])
        {
            assert!(
                (b.x_px - cx).abs() < 0.02 && (b.y_px - cy).abs() < 0.02,
                "{b:?} vs {cx} {cy}"
            );
        }
        // Back to the frame with the annulus: the same blobs as the first time.
        let mut again = Vec::new();
        warm.detect_into(&with_annulus, &mut again);
        assert_eq!(again, detector(Centroid::Grey).detect(&with_annulus));
    }

    #[test]
    fn ellipse_form_matches_the_rotated_axes() {
        // Against the form built from the angle of the major axis, over shapes from a circle
        // to a needle at many angles.
        for (a, b, c) in [
            (4.0f64, 0.0f64, 4.0f64),
            (9.0, 0.0, 1.0),
            (1.0, 0.0, 9.0),
            (5.0, 2.0, 3.0),
            (3.0, -2.5, 3.0),
            (2.0, 1.9999, 2.0),
            (0.0, 0.0, 0.0),
            (6.25, 0.5, 6.2500001),
            (1.0, 2.0, 1.0),
        ] {
            let half = 0.5 * (a + c);
            let root = (0.25 * (a - c) * (a - c) + b * b).sqrt();
            let (l1, l2): (f64, f64) = (half + root, (half - root).max(0.0));
            let theta = 0.5 * (2.0 * b).atan2(a - c);
            let (ra, rb) = (2.0 * l1.sqrt() + 1.0, 2.0 * l2.sqrt() + 1.0);
            let (st, ct) = theta.sin_cos();
            let (ia, ib) = (1.0 / (ra * ra), 1.0 / (rb * rb));
            let want = [
                ct * ct * ia + st * st * ib,
                ct * st * (ia - ib),
                st * st * ia + ct * ct * ib,
            ];
            let got = ellipse_form(a, b, c);
            for (g, w) in got.iter().zip(want) {
                assert!(
                    (f64::from(*g) - w).abs() < 1e-6,
                    "{a} {b} {c}: {got:?} vs {want:?}"
                );
            }
        }
    }

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
