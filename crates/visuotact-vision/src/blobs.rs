//! Blob analysis: one fused pass of threshold + connected-component labelling + moments.
//!
//! Contract:
//! - Components are 8-connected (or 4-connected on request) sets of foreground pixels
//!   (`v > level`), numbered in raster order of their first pixel, as scikit-image's `label`.
//! - Per blob: area, centroid, normalised second central moments, bounding box, border flag.
//!   Moments are accumulated as exact integers per run of pixels, so centroids and central
//!   moments equal the pixel-by-pixel definitions (and OpenCV's `moments`) to rounding of the
//!   final division (~1e-12 px on 640×480 frames).
//! - [`Blob::shape`] gives axes, eccentricity `sqrt(1 − λ₂/λ₁)` and orientation with
//!   scikit-image's `regionprops` formulas, or MATLAB's (second moments + 1/12).
//! - [`blobs_reference`] is a plain flood fill computing the same quantities pixel by pixel in
//!   floating point; tests check the fused pass against it.
//!
//! ```
//! use visuotact_image::GrayImage;
//! use visuotact_vision::blobs::{blobs_from_gray, Connectivity, Level};
//! // Two 2×2 squares; the right one touches the image border.
//! let img = GrayImage::from_vec(6, 4, vec![
//!     0, 0, 0, 0, 0, 0,
//!     0, 9, 9, 0, 9, 9,
//!     0, 9, 9, 0, 9, 9,
//!     0, 0, 0, 0, 0, 0,
//! ]).unwrap();
//! let blobs = blobs_from_gray(&img, Level::Scalar(5), Connectivity::Eight);
//! assert_eq!(blobs.len(), 2);
//! assert_eq!((blobs[0].area_px, blobs[0].x_px, blobs[0].y_px), (4, 1.5, 1.5));
//! assert!(!blobs[0].touches_border && blobs[1].touches_border);
//! ```

use serde::{Deserialize, Serialize};
use visuotact_image::GrayImage;

use crate::preprocess::{CircleMask, Roi};

/// Pixel neighbourhood for labelling.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Connectivity {
    /// Edge and corner neighbours (OpenCV's default, scikit-image `connectivity=2`).
    #[default]
    Eight,
    /// Edge neighbours only (scikit-image `connectivity=1`).
    Four,
}

/// Axis-aligned bounding box; `x1`, `y1` are exclusive.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct BBox {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
}

/// One connected component with its moments.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Blob {
    /// Number of pixels.
    pub area_px: u32,
    /// Centroid column (pixel centres at integers).
    pub x_px: f64,
    /// Centroid row.
    pub y_px: f64,
    /// Normalised central moment μ20/μ00: the variance of x.
    pub mu20_px2: f64,
    /// Normalised central moment μ11/μ00: the covariance of x and y.
    pub mu11_px2: f64,
    /// Normalised central moment μ02/μ00: the variance of y.
    pub mu02_px2: f64,
    /// Bounding box.
    pub bbox: BBox,
    /// Whether the blob touches the edge of the processed region.
    pub touches_border: bool,
}

/// Which formula turns second moments into shape figures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum MomentConvention {
    /// Moments of the pixel centres (scikit-image, OpenCV).
    #[default]
    Pixel,
    /// MATLAB `regionprops`: each pixel a unit square, adding 1/12 to μ20 and μ02.
    Matlab,
}

visuotact_image::names_from_str!(MomentConvention, "moment convention");

impl MomentConvention {
    /// The names [`MomentConvention::from_name`] and `FromStr` read.
    pub const NAMES: &'static [&'static str] = &["pixel", "matlab"];

    /// `pixel` or `matlab`.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "pixel" => Some(Self::Pixel),
            "matlab" => Some(Self::Matlab),
            _ => None,
        }
    }
}

/// Shape figures derived from the second moments.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shape {
    /// Length of the major axis of the ellipse with the same second moments, `4·sqrt(λ₁)`.
    pub major_axis_px: f64,
    /// Length of the minor axis, `4·sqrt(λ₂)`.
    pub minor_axis_px: f64,
    /// `sqrt(1 − λ₂/λ₁)`, 0 for a circle or a single pixel.
    pub eccentricity: f64,
    /// Angle between the row axis and the major axis, in −π/2..π/2 (scikit-image convention).
    pub orientation_rad: f64,
}

impl Blob {
    /// The blob of `self` and `other` together, as if one component (pieces of one marker):
    /// areas add, the centroid is their area-weighted mean and the second moments add about it
    /// (each piece's own variance plus its centroid's offset squared).
    ///
    /// ```
    /// use visuotact_vision::blobs::{BBox, Blob};
    /// // Two 1 × 2 pieces side by side make a 2 × 2 square.
    /// let piece = |x: f64| Blob {
    ///     area_px: 2,
    ///     x_px: x,
    ///     y_px: 0.5,
    ///     mu20_px2: 0.0,
    ///     mu11_px2: 0.0,
    ///     mu02_px2: 0.25,
    ///     bbox: BBox { x0: x as u32, y0: 0, x1: x as u32 + 1, y1: 2 },
    ///     touches_border: false,
    /// };
    /// let square = piece(0.0).union(&piece(1.0));
    /// assert_eq!(square.area_px, 4);
    /// assert_eq!((square.x_px, square.mu20_px2, square.mu02_px2), (0.5, 0.25, 0.25));
    /// assert_eq!(square.bbox, BBox { x0: 0, y0: 0, x1: 2, y1: 2 });
    /// ```
    pub fn union(&self, other: &Blob) -> Blob {
        let (n1, n2) = (f64::from(self.area_px), f64::from(other.area_px));
        let n = (n1 + n2).max(1.0);
        let (x, y) = (
            (n1 * self.x_px + n2 * other.x_px) / n,
            (n1 * self.y_px + n2 * other.y_px) / n,
        );
        let about = |b: &Blob, w: f64| {
            let (dx, dy) = (b.x_px - x, b.y_px - y);
            (
                w * (b.mu20_px2 + dx * dx),
                w * (b.mu11_px2 + dx * dy),
                w * (b.mu02_px2 + dy * dy),
            )
        };
        let (a, b) = (about(self, n1), about(other, n2));
        Blob {
            area_px: self.area_px + other.area_px,
            x_px: x,
            y_px: y,
            mu20_px2: (a.0 + b.0) / n,
            mu11_px2: (a.1 + b.1) / n,
            mu02_px2: (a.2 + b.2) / n,
            bbox: BBox {
                x0: self.bbox.x0.min(other.bbox.x0),
                y0: self.bbox.y0.min(other.bbox.y0),
                x1: self.bbox.x1.max(other.bbox.x1),
                y1: self.bbox.y1.max(other.bbox.y1),
            },
            touches_border: self.touches_border || other.touches_border,
        }
    }

    /// Axes, eccentricity and orientation under the given convention.
    pub fn shape(&self, convention: MomentConvention) -> Shape {
        let extra = match convention {
            MomentConvention::Pixel => 0.0,
            MomentConvention::Matlab => 1.0 / 12.0,
        };
        let (vx, vy, c) = (self.mu20_px2 + extra, self.mu02_px2 + extra, self.mu11_px2);
        let half_tr = 0.5 * (vx + vy);
        let disc = (0.25 * (vx - vy) * (vx - vy) + c * c).sqrt();
        let l1 = half_tr + disc;
        let l2 = (half_tr - disc).max(0.0);
        let eccentricity = if l1 > 0.0 {
            (1.0 - l2 / l1).max(0.0).sqrt()
        } else {
            0.0
        };
        // scikit-image: a = var(col), b = −cov, c = var(row); 0.5·atan2(−2b, c − a).
        let orientation_rad = if vx == vy {
            if c > 0.0 {
                std::f64::consts::FRAC_PI_4
            } else {
                -std::f64::consts::FRAC_PI_4
            }
        } else {
            0.5 * (2.0 * c).atan2(vy - vx)
        };
        Shape {
            major_axis_px: 4.0 * l1.sqrt(),
            minor_axis_px: 4.0 * l2.sqrt(),
            eccentricity,
            orientation_rad,
        }
    }

    /// Eccentricity with the pixel convention (scikit-image, OpenCV).
    pub fn eccentricity(&self) -> f64 {
        self.shape(MomentConvention::Pixel).eccentricity
    }

    /// The blob read as two discs of areas `a1`, `a2`: the distance between their centres and
    /// the unit vector along the line through them (the moments' major axis), or `None` when
    /// the moments allow no separation. Along that line two discs `d` apart have the variance
    /// `(a1² + a2²)/(4π(a1 + a2)) + d²·a1·a2/(a1 + a2)²`, so `d` follows from the blob's largest
    /// variance; the centroid divides it in the ratio of the areas.
    pub(crate) fn two_discs(&self, a1: f64, a2: f64) -> Option<(f64, (f64, f64))> {
        let a = a1 + a2;
        let (xx, xy, yy) = (self.mu20_px2, self.mu11_px2, self.mu02_px2);
        let half = 0.5 * (xx + yy);
        let root = (0.25 * (xx - yy) * (xx - yy) + xy * xy).sqrt();
        let l1 = half + root;
        let theta = 0.5 * (2.0 * xy).atan2(xx - yy);
        let own = (a1 * a1 + a2 * a2) / (4.0 * std::f64::consts::PI * a);
        let d2 = (l1 - own) * a * a / (a1 * a2);
        (d2 > 0.0).then(|| (d2.sqrt(), (theta.cos(), theta.sin())))
    }
}

/// The threshold level(s) the fused pass compares against: foreground is `v > level`.
#[derive(Clone, Copy, Debug)]
pub enum Level<'a> {
    /// One level for every pixel.
    Scalar(u8),
    /// One level per pixel, row-major, same size as the image.
    PerPixel(&'a [f32]),
}

/// Where in the image to look. Blobs touching the rectangle's edge are flagged as border blobs.
#[derive(Clone, Copy, Debug, Default)]
pub struct Region {
    /// Rectangle to process (whole image when `None`).
    pub roi: Option<Roi>,
    /// Circle outside which pixels are background.
    pub circle: Option<CircleMask>,
}

#[derive(Clone, Copy, Debug)]
struct Run {
    x0: u32,
    x1: u32, // inclusive
    label: u32,
}

#[derive(Clone, Copy, Debug, Default)]
struct Acc {
    n: u64,
    sx: u64,
    sy: u64,
    sxx: u64,
    syy: u64,
    sxy: u64,
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
    /// A pixel of the blob neighbours a pixel outside the circular mask.
    edge: bool,
}

impl Acc {
    /// Adds the run of pixels `a..=b` on row `y`; `sq[x]` is `Σ_{i<x} i²`.
    #[inline]
    fn add_run(&mut self, y: u32, a: u32, b: u32, sq: &[u64]) {
        let (a64, b64, y64) = (u64::from(a), u64::from(b), u64::from(y));
        let n = b64 - a64 + 1;
        let sx = ((a64 + b64) * n) >> 1;
        let sxx = sq[b as usize + 1] - sq[a as usize];
        self.n += n;
        self.sx += sx;
        self.sy += n * y64;
        self.sxx += sxx;
        self.syy += n * y64 * y64;
        self.sxy += sx * y64;
        self.x0 = self.x0.min(a);
        self.x1 = self.x1.max(b + 1);
        self.y0 = self.y0.min(y);
        self.y1 = self.y1.max(y + 1);
    }

    fn fresh() -> Self {
        Self {
            x0: u32::MAX,
            y0: u32::MAX,
            ..Self::default()
        }
    }

    fn merge(&mut self, o: &Acc) {
        self.n += o.n;
        self.sx += o.sx;
        self.sy += o.sy;
        self.sxx += o.sxx;
        self.syy += o.syy;
        self.sxy += o.sxy;
        self.x0 = self.x0.min(o.x0);
        self.y0 = self.y0.min(o.y0);
        self.x1 = self.x1.max(o.x1);
        self.y1 = self.y1.max(o.y1);
        self.edge |= o.edge;
    }

    fn blob(&self, rect: (u32, u32, u32, u32)) -> Blob {
        let n = i128::from(self.n);
        let (sx, sy) = (i128::from(self.sx), i128::from(self.sy));
        let nf = self.n as f64;
        let n2 = nf * nf;
        // Exact integer numerators, one rounding each.
        let mu20 = (n * i128::from(self.sxx) - sx * sx) as f64 / n2;
        let mu02 = (n * i128::from(self.syy) - sy * sy) as f64 / n2;
        let mu11 = (n * i128::from(self.sxy) - sx * sy) as f64 / n2;
        let (rx0, ry0, rx1, ry1) = rect;
        Blob {
            area_px: self.n as u32,
            x_px: self.sx as f64 / nf,
            y_px: self.sy as f64 / nf,
            mu20_px2: mu20,
            mu11_px2: mu11,
            mu02_px2: mu02,
            bbox: BBox {
                x0: self.x0,
                y0: self.y0,
                x1: self.x1,
                y1: self.y1,
            },
            touches_border: self.edge
                || self.x0 == rx0
                || self.y0 == ry0
                || self.x1 == rx1
                || self.y1 == ry1,
        }
    }
}

/// Reusable buffers for [`blobs_from_gray_into`]; keep one per live loop.
#[derive(Default, Debug, Clone)]
pub struct BlobScratch {
    bytes: Vec<u8>,
    bits: Vec<u64>,
    prev: Vec<Run>,
    cur: Vec<Run>,
    parent: Vec<u32>,
    acc: Vec<Acc>,
    /// `sq[x] = Σ_{i<x} i²` for every column (exact integers; no divisions per run).
    sq: Vec<u64>,
    /// Grey-weighted sums per provisional label: Σw, Σw·x, Σw·y.
    wacc: Vec<[f64; 3]>,
}

fn find(parent: &mut [u32], mut x: u32) -> u32 {
    let mut r = x;
    while parent[r as usize] != r {
        r = parent[r as usize];
    }
    while parent[x as usize] != r {
        let next = parent[x as usize];
        parent[x as usize] = r;
        x = next;
    }
    r
}

fn union(parent: &mut [u32], a: u32, b: u32) -> u32 {
    let ra = find(parent, a);
    let rb = find(parent, b);
    let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
    parent[hi as usize] = lo;
    lo
}

/// Clears every bit outside `[lo, hi)`.
fn clear_bits_outside(bits: &mut [u64], lo: usize, hi: usize) {
    for (k, w) in bits.iter_mut().enumerate() {
        let (a, b) = (k * 64, k * 64 + 64);
        let keep_lo = if lo <= a {
            u64::MAX
        } else if lo >= b {
            0
        } else {
            u64::MAX << (lo - a)
        };
        let keep_hi = if hi >= b {
            u64::MAX
        } else if hi <= a {
            0
        } else {
            u64::MAX >> (b - hi)
        };
        *w &= keep_lo & keep_hi;
    }
}

/// Fused threshold + labelling + moments. Appends every blob (border ones flagged, none
/// filtered) to `out` after clearing it.
pub fn blobs_from_gray_into(
    img: &GrayImage,
    level: Level<'_>,
    region: Region,
    connectivity: Connectivity,
    s: &mut BlobScratch,
    out: &mut Vec<Blob>,
) {
    label_pass(img, level, region, connectivity, s, out, None);
}

/// [`blobs_from_gray_into`] that also gives each blob's grey-weighted centroid, in `out`'s
/// order: every pixel of the blob weighted by how far its grey value exceeds the level. A pixel
/// at the level weighs nothing, so noise that flips pixels near the level in or out of the
/// blob barely moves it — on thin rings 5–8× less jitter than the binary centroid.
///
/// ```
/// use visuotact_image::GrayImage;
/// use visuotact_vision::blobs::{blobs_weighted_from_gray_into, BlobScratch, Connectivity, Level, Region};
/// // A 1×3 blob with grey values 110, 150, 250 above level 100: weights 10, 50, 150.
/// let img = GrayImage::from_fn(5, 1, |x, _| [0, 110, 150, 250, 0][x]);
/// let (mut blobs, mut c) = (Vec::new(), Vec::new());
/// blobs_weighted_from_gray_into(&img, Level::Scalar(100), Region::default(),
///     Connectivity::Eight, &mut BlobScratch::default(), &mut blobs, &mut c);
/// assert_eq!(blobs[0].x_px, 2.0);
/// assert!((c[0].0 - (10.0 * 1.0 + 50.0 * 2.0 + 150.0 * 3.0) / 210.0).abs() < 1e-12);
/// ```
pub fn blobs_weighted_from_gray_into(
    img: &GrayImage,
    level: Level<'_>,
    region: Region,
    connectivity: Connectivity,
    s: &mut BlobScratch,
    out: &mut Vec<Blob>,
    centroids: &mut Vec<(f64, f64)>,
) {
    label_pass(img, level, region, connectivity, s, out, Some(centroids));
}

/// Columns `[xa, xb)` of a row inside the processed region.
type Chord = (usize, usize);

/// One row's geometry for labelling: the row, the processed rectangle's columns, the
/// circle's chord on it and on its neighbours, and the neighbourhood's reach.
struct RowSpan {
    y: usize,
    /// Where the row's first processed pixel sits in the image (per-pixel levels).
    at: usize,
    /// The processed rectangle's first and past-the-last columns.
    rx: (usize, usize),
    /// The circle's chord `[xa, xb)` on this row (the rectangle without a circle).
    chord: (usize, usize),
    /// The chords of the rows above and below, with a circular mask.
    around: [Option<Chord>; 2],
    /// 1 for 8-connectivity (diagonal runs touch), 0 for 4.
    gap: u32,
}

/// The fused threshold + labelling + moments pass (one pass over the rows, union–find on
/// runs, moments accumulated per run); with `centroids`, also the grey-weighted ones.
fn label_pass(
    img: &GrayImage,
    level: Level<'_>,
    region: Region,
    connectivity: Connectivity,
    s: &mut BlobScratch,
    out: &mut Vec<Blob>,
    mut centroids: Option<&mut Vec<(f64, f64)>>,
) {
    out.clear();
    if let Some(c) = centroids.as_mut() {
        c.clear();
    }
    let weighted = centroids.is_some();
    let (w, h) = (img.width(), img.height());
    let roi = region.roi.unwrap_or(Roi {
        x: 0,
        y: 0,
        width: w,
        height: h,
    });
    let (rx0, ry0) = (roi.x.min(w), roi.y.min(h));
    let (rx1, ry1) = ((roi.x + roi.width).min(w), (roi.y + roi.height).min(h));
    if rx1 <= rx0 || ry1 <= ry0 {
        s.wacc.clear();
        return;
    }
    if let Level::PerPixel(l) = level {
        assert_eq!(l.len(), w * h, "per-pixel levels must match the image size");
    }
    s.reset(rx1 - rx0, w);
    let gap = match connectivity {
        Connectivity::Eight => 1u32,
        Connectivity::Four => 0u32,
    };
    // Columns `[xa, xb)` inside the region on row `y` (empty when the circle misses it).
    let chord = |y: usize| -> (usize, usize) {
        let (mut xa, mut xb) = (rx0, rx1);
        if let Some(c) = region.circle {
            let dy = y as f64 - c.cy_px;
            let r2 = c.radius_px * c.radius_px - dy * dy;
            if r2 < 0.0 {
                return (rx0, rx0);
            }
            let half = r2.sqrt();
            xa = xa.max((c.cx_px - half).ceil().max(0.0) as usize);
            xb = xb.min(((c.cx_px + half).floor() + 1.0).max(0.0) as usize);
        }
        (xa, xb.max(xa))
    };
    for y in ry0..ry1 {
        let (xa, xb) = chord(y);
        if xb <= xa {
            s.prev.clear();
            continue;
        }
        // With a circular mask, a run whose end or 8-neighbours in the rows above and below
        // fall outside the chords touches the mask's edge.
        let around = match region.circle {
            Some(_) => [
                (y > ry0).then(|| chord(y - 1)),
                (y + 1 < ry1).then(|| chord(y + 1)),
            ],
            None => [None, None],
        };
        let row = &img.row(y)[rx0..rx1];
        s.threshold_row(row, level, (y * w + rx0, y * w + rx1));
        if xa > rx0 || xb < rx1 {
            clear_bits_outside(&mut s.bits, xa - rx0, xb - rx0);
        }
        s.runs_from_bits(rx1 - rx0);
        let span = RowSpan {
            y,
            at: y * w + rx0,
            rx: (rx0, rx1),
            chord: (xa, xb),
            around,
            gap,
        };
        s.label_row(&span, row, level, weighted, region.circle.is_some());
        std::mem::swap(&mut s.prev, &mut s.cur);
    }
    s.fold_labels(weighted);
    s.emit(
        (rx0 as u32, ry0 as u32, rx1 as u32, ry1 as u32),
        out,
        centroids,
    );
}

impl BlobScratch {
    /// Empties the per-image state for a rectangle `span` columns wide in an image `w` wide.
    fn reset(&mut self, span: usize, w: usize) {
        self.wacc.clear();
        self.bytes.resize(span, 0);
        self.bits.resize(span.div_ceil(64), 0);
        self.prev.clear();
        self.cur.clear();
        self.parent.clear();
        self.acc.clear();
        if self.sq.len() != w + 1 {
            self.sq.clear();
            self.sq.push(0);
            for x in 0..w as u64 {
                let last = self.sq[x as usize];
                self.sq.push(last + x * x);
            }
        }
    }

    /// The row's foreground as bits: above the level (`at`: the row's range in per-pixel
    /// levels).
    #[inline]
    fn threshold_row(&mut self, row: &[u8], level: Level<'_>, at: (usize, usize)) {
        match level {
            Level::Scalar(t) => crate::kernels::above_bits(row, t, &mut self.bits),
            Level::PerPixel(l) => {
                let lrow = &l[at.0..at.1];
                for ((o, &v), &t) in self.bytes.iter_mut().zip(row).zip(lrow) {
                    *o = u8::from(f32::from(v) > t);
                }
                crate::kernels::pack_bits(&self.bytes, &mut self.bits);
            }
        }
    }

    /// The runs of set bits of a row `span` columns wide into `cur`.
    #[inline]
    fn runs_from_bits(&mut self, span: usize) {
        self.cur.clear();
        let mut open: Option<u32> = None;
        for (wi, &word) in self.bits.iter().enumerate() {
            let base = (wi * 64) as u32;
            let mut wv = word;
            let mut pos = 0u32;
            while pos < 64 {
                if let Some(start) = open {
                    // Inside a run: find its end (first zero bit).
                    let zeros = (!wv).trailing_zeros();
                    if zeros >= 64 - pos {
                        break; // run continues into the next word
                    }
                    let end = base + pos + zeros; // exclusive
                    self.cur.push(Run {
                        x0: start,
                        x1: end - 1,
                        label: 0,
                    });
                    open = None;
                    wv >>= zeros;
                    pos += zeros;
                } else {
                    if wv == 0 {
                        break;
                    }
                    let tz = wv.trailing_zeros();
                    open = Some(base + pos + tz);
                    wv >>= tz;
                    pos += tz;
                }
            }
        }
        if let Some(start) = open {
            self.cur.push(Run {
                x0: start,
                x1: span as u32 - 1,
                label: 0,
            });
        }
    }

    /// Labels the row's runs against the previous row's (union–find) and adds each run to its
    /// label's moments (and grey-weighted sums when `weighted`).
    #[inline]
    fn label_row(
        &mut self,
        span: &RowSpan,
        row: &[u8],
        level: Level<'_>,
        weighted: bool,
        circle: bool,
    ) {
        let (rx0, rx1) = span.rx;
        let (xa, xb) = span.chord;
        let yy = span.y as u32;
        let mut j = 0usize;
        for r in self.cur.iter_mut() {
            while j < self.prev.len() && self.prev[j].x1 + span.gap < r.x0 {
                j += 1;
            }
            let mut label = u32::MAX;
            let mut k = j;
            while k < self.prev.len() && self.prev[k].x0 <= r.x1 + span.gap {
                let pl = self.prev[k].label;
                label = if label == u32::MAX {
                    find(&mut self.parent, pl)
                } else {
                    union(&mut self.parent, label, pl)
                };
                k += 1;
            }
            if label == u32::MAX {
                label = self.parent.len() as u32;
                self.parent.push(label);
                self.acc.push(Acc::fresh());
                if weighted {
                    self.wacc.push([0.0; 3]);
                }
            }
            r.label = label;
            let (a, b) = (r.x0 as usize + rx0, r.x1 as usize + rx0);
            let acc = &mut self.acc[label as usize];
            acc.add_run(yy, a as u32, b as u32, &self.sq);
            if circle {
                let outside = |c: Option<(usize, usize)>| {
                    c.is_some_and(|(ca, cb)| cb <= ca || a < ca + 1 || b + 2 > cb)
                };
                acc.edge |= (a == xa && xa > rx0)
                    || (b + 1 == xb && xb < rx1)
                    || outside(span.around[0])
                    || outside(span.around[1]);
            }
            if weighted {
                let (a, b) = (r.x0 as usize, r.x1 as usize);
                // Every pixel of a run exceeds its level, so the weights v − t are positive.
                let (sw, swx) = match level {
                    Level::Scalar(t) => run_weights_scalar(&row[a..=b], t, (rx0 + a) as f64),
                    Level::PerPixel(l) => {
                        let at = span.at;
                        run_weights_levels(&row[a..=b], &l[at + a..=at + b], (rx0 + a) as f64)
                    }
                };
                let acc = &mut self.wacc[label as usize];
                acc[0] += sw;
                acc[1] += swx;
                acc[2] += sw * span.y as f64;
            }
        }
    }

    /// One blob per root label, in label order (and its grey-weighted centroid when asked).
    fn emit(
        &self,
        rect: (u32, u32, u32, u32),
        out: &mut Vec<Blob>,
        mut centroids: Option<&mut Vec<(f64, f64)>>,
    ) {
        for l in 0..self.parent.len() {
            if self.parent[l] == l as u32 {
                let b = self.acc[l].blob(rect);
                if let Some(c) = centroids.as_mut() {
                    let [sw, sx, sy] = self.wacc[l];
                    c.push(if sw > 0.0 {
                        (sx / sw, sy / sw)
                    } else {
                        (b.x_px, b.y_px)
                    });
                }
                out.push(b);
            }
        }
    }

    /// Folds provisional labels into their roots (roots are the smallest label of each set, so
    /// blobs come out in raster order of their first pixel).
    fn fold_labels(&mut self, weighted: bool) {
        for l in 0..self.parent.len() as u32 {
            let r = find(&mut self.parent, l);
            if r != l {
                let a = self.acc[l as usize];
                self.acc[r as usize].merge(&a);
                if weighted {
                    let wa = self.wacc[l as usize];
                    for (d, v) in self.wacc[r as usize].iter_mut().zip(wa) {
                        *d += v;
                    }
                }
            }
        }
    }
}

/// `(Σ (v − t), Σ (v − t)·x)` over one run of pixels `v > t` starting at column `x0`: exact
/// integer sums of `v` and `v·i` (`i` the offset in the run), combined once.
fn run_weights_scalar(run: &[u8], t: u8, x0: f64) -> (f64, f64) {
    let (mut sv, mut svi) = (0u64, 0u64);
    // Blocks of 4 096 keep the per-block sums within u32 (255 · 4 096² / 2 < 2³²).
    for (k, block) in run.chunks(4096).enumerate() {
        let (mut bv, mut bvi) = (0u32, 0u32);
        for (i, &v) in block.iter().enumerate() {
            bv += u32::from(v);
            bvi += u32::from(v) * i as u32;
        }
        sv += u64::from(bv);
        svi += u64::from(bvi) + u64::from(bv) * (4096 * k) as u64;
    }
    let n = run.len() as f64;
    let (t, sv, svi) = (f64::from(t), sv as f64, svi as f64);
    let sw = sv - n * t;
    // Σ (v − t)·(x0 + i) = x0·Σ(v − t) + Σ v·i − t·Σ i.
    let sum_i = n * (n - 1.0) / 2.0;
    (sw, x0 * sw + svi - t * sum_i)
}

/// [`run_weights_scalar`] with a level per pixel (`levels[i]` for `run[i]`).
fn run_weights_levels(run: &[u8], levels: &[f32], x0: f64) -> (f64, f64) {
    let (mut sw, mut swi) = (0.0f64, 0.0f64);
    for (i, (&v, &t)) in run.iter().zip(levels).enumerate() {
        let wt = f64::from((f32::from(v) - t).max(0.0));
        sw += wt;
        swi += wt * i as f64;
    }
    (sw, x0 * sw + swi)
}

/// Allocating form of [`blobs_from_gray_into`] on the whole image.
pub fn blobs_from_gray(img: &GrayImage, level: Level<'_>, connectivity: Connectivity) -> Vec<Blob> {
    let mut out = Vec::new();
    blobs_from_gray_into(
        img,
        level,
        Region::default(),
        connectivity,
        &mut BlobScratch::default(),
        &mut out,
    );
    out
}

/// Reference implementation: flood fill over a boolean mask, moments summed pixel by pixel in
/// two passes. Slow and simple; the fused pass is tested against it.
pub fn blobs_reference(
    mask: &[bool],
    width: usize,
    height: usize,
    connectivity: Connectivity,
) -> Vec<Blob> {
    assert_eq!(mask.len(), width * height);
    let mut seen = vec![false; mask.len()];
    let mut out = Vec::new();
    let mut stack = Vec::new();
    let mut pixels: Vec<(usize, usize)> = Vec::new();
    for start in 0..mask.len() {
        if !mask[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        pixels.clear();
        while let Some(p) = stack.pop() {
            let (x, y) = (p % width, p / width);
            pixels.push((x, y));
            for dy in -1i64..=1 {
                for dx in -1i64..=1 {
                    if (dx == 0 && dy == 0)
                        || (connectivity == Connectivity::Four && dx != 0 && dy != 0)
                    {
                        continue;
                    }
                    let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                    if nx < 0 || ny < 0 || nx >= width as i64 || ny >= height as i64 {
                        continue;
                    }
                    let q = ny as usize * width + nx as usize;
                    if mask[q] && !seen[q] {
                        seen[q] = true;
                        stack.push(q);
                    }
                }
            }
        }
        let mut b = blob_of_pixels(pixels.iter().copied());
        let BBox { x0, y0, x1, y1 } = b.bbox;
        b.touches_border = x0 == 0 || y0 == 0 || x1 as usize == width || y1 as usize == height;
        out.push(b);
    }
    out
}

/// The blob of the pixels `(column, row)` (any source that can be walked more than once: a
/// slice's `iter().copied()`, or a map over pixel indices), its moments computed pixel by
/// pixel in floating point (not flagged as touching the border).
pub fn blob_of_pixels<I>(pixels: I) -> Blob
where
    I: Iterator<Item = (usize, usize)> + Clone,
{
    let n = pixels.clone().count() as f64;
    let cx = pixels.clone().map(|p| p.0 as f64).sum::<f64>() / n;
    let cy = pixels.clone().map(|p| p.1 as f64).sum::<f64>() / n;
    let (mut m20, mut m02, mut m11) = (0.0, 0.0, 0.0);
    let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
    for (x, y) in pixels {
        let (dx, dy) = (x as f64 - cx, y as f64 - cy);
        m20 += dx * dx;
        m02 += dy * dy;
        m11 += dx * dy;
        (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
    }
    if n == 0.0 {
        (x0, y0, x1, y1) = (0, 0, 1, 1);
    }
    Blob {
        area_px: n as u32,
        x_px: cx,
        y_px: cy,
        mu20_px2: m20 / n,
        mu11_px2: m11 / n,
        mu02_px2: m02 / n,
        bbox: BBox {
            x0: x0 as u32,
            y0: y0 as u32,
            x1: x1 as u32,
            y1: y1 as u32,
        },
        touches_border: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn run_weights_equal_the_pixel_sums() {
        // Runs longer than one 4 096-pixel block included.
        for len in [1usize, 5, 64, 4095, 4096, 4097, 9000] {
            let run: Vec<u8> = (0..len).map(|i| 101 + (i * 37 % 155) as u8).collect();
            let x0 = 17.0;
            let (mut sw, mut swx) = (0.0f64, 0.0f64);
            for (i, &v) in run.iter().enumerate() {
                let w = f64::from(v) - 100.0;
                sw += w;
                swx += w * (x0 + i as f64);
            }
            let (a, b) = super::run_weights_scalar(&run, 100, x0);
            assert_eq!(a, sw, "len {len}");
            assert!((b - swx).abs() <= 1e-9 * swx, "len {len}: {b} vs {swx}");
            let levels = vec![100.0f32; len];
            let (c, d) = super::run_weights_levels(&run, &levels, x0);
            assert_eq!(c, sw, "len {len}");
            assert!((d - swx).abs() <= 1e-9 * swx, "len {len}: {d} vs {swx}");
        }
    }

    fn blobs_in(img: &GrayImage, region: Region) -> Vec<Blob> {
        let mut out = Vec::new();
        let mut scratch = BlobScratch::default();
        blobs_from_gray_into(
            img,
            Level::Scalar(100),
            region,
            Connectivity::Eight,
            &mut scratch,
            &mut out,
        );
        out
    }

    fn squares() -> GrayImage {
        // Three 3×3 squares at columns 1, 8, 15 on a 20×7 image, rows 2..5.
        GrayImage::from_fn(20, 7, |x, y| {
            u8::from((2..5).contains(&y) && [1, 8, 15].iter().any(|&c| (c..c + 3).contains(&x)))
                * 200
        })
    }

    #[test]
    fn roi_limits_blobs_and_defines_the_border() {
        let img = squares();
        let region = Region {
            roi: Some(Roi {
                x: 8,
                y: 0,
                width: 12,
                height: 7,
            }),
            circle: None,
        };
        let out = blobs_in(&img, region);
        assert_eq!(out.len(), 2);
        assert!(
            out[0].touches_border,
            "the square at column 8 starts on the ROI edge"
        );
        assert_eq!(out[0].x_px, 9.0);
        assert!(!out[1].touches_border);
    }

    #[test]
    fn circle_mask_removes_pixels_outside() {
        let img = squares();
        let region = Region {
            roi: None,
            circle: Some(CircleMask {
                cx_px: 9.0,
                cy_px: 3.0,
                radius_px: 2.0,
            }),
        };
        let out = blobs_in(&img, region);
        assert_eq!(out.len(), 1);
        assert_eq!((out[0].x_px, out[0].y_px, out[0].area_px), (9.0, 3.0, 9));
        let region = Region {
            roi: None,
            circle: Some(CircleMask {
                cx_px: 9.0,
                cy_px: 3.0,
                radius_px: 1.0,
            }),
        };
        let out = blobs_in(&img, region);
        assert_eq!(
            out[0].area_px, 5,
            "a radius-1 disc keeps the centre and its 4 neighbours"
        );
        // Cut by the circle: it touches the border of the processed region.
        assert!(out[0].touches_border);
        let region = Region {
            roi: None,
            circle: Some(CircleMask {
                cx_px: 9.0,
                cy_px: 3.0,
                radius_px: 20.0,
            }),
        };
        let out = blobs_in(&img, region);
        assert!(out.iter().all(|b| !b.touches_border), "{out:?}");
    }
}
