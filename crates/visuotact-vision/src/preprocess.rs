//! Preprocessing: RGB → one channel, inversion, morphology and the threshold level.
//!
//! Contract:
//! - [`Channel::Luma601`] is `round(0.2989 R + 0.5870 G + 0.1140 B)` computed exactly in integers
//!   (MATLAB `rgb2gray`), not the `image` crate's Rec. 709 luma.
//! - Grey-level erosion / dilation use a square `k × k` window clipped at the image edge (pixels
//!   outside the image are ignored), which equals OpenCV's `erode`/`dilate` with its default
//!   border. Opening is erosion then dilation; closing the reverse.
//! - [`otsu_level`] returns the level `t` that maximises the between-class variance with the
//!   foreground `v > t`; on every image of `shared/reference/golden/otsu_cc_regionprops.json` it
//!   equals both scikit-image's `threshold_otsu` and OpenCV's `THRESH_OTSU`.
//! - Adaptive thresholding marks `v > mean − offset`, the mean taken over the part of a
//!   `window × window` square inside the image (OpenCV's `ADAPTIVE_THRESH_MEAN_C` convention for
//!   the sign of the offset: a negative offset asks pixels to be brighter than their surroundings).

use serde::{Deserialize, Serialize};
use visuotact_image::{GrayImage, RgbImage};

use crate::kernels::{extremum3_on, pick_channel_on, Avx2};

/// Which pixels a threshold histogram counts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HistogramPixels {
    /// Every pixel.
    All,
    /// Every fourth pixel of every second row, starting at `(0, 0)`: an eighth of the image.
    Eighth,
}

impl Threshold {
    /// The histogram the threshold's level comes from, if it comes from one.
    pub fn histogram_pixels(self) -> Option<HistogramPixels> {
        match self {
            Threshold::Otsu => Some(HistogramPixels::All),
            Threshold::OtsuSampled => Some(HistogramPixels::Eighth),
            Threshold::Fixed { .. } | Threshold::Adaptive { .. } => None,
        }
    }
}

/// Which single channel the pipeline works on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Channel {
    /// Green only: best contrast for green markers (seed 000).
    #[default]
    Green,
    /// ITU-R BT.601 luma with MATLAB's weights 0.2989 / 0.5870 / 0.1140 (seed 001).
    Luma601,
    /// Mean of R, G and B, rounded.
    Mean,
    /// Red only.
    Red,
    /// Blue only.
    Blue,
}

visuotact_image::names_from_str!(Channel, "channel");

impl Channel {
    /// The names [`Channel::from_name`] and `FromStr` read (each is also what `name` writes,
    /// where the type has one).
    pub const NAMES: &'static [&'static str] = &["green", "luma601", "mean", "red", "blue"];

    /// All channels, for listing in help texts.
    pub const ALL: [Channel; 5] = [
        Channel::Green,
        Channel::Luma601,
        Channel::Mean,
        Channel::Red,
        Channel::Blue,
    ];

    /// The name used in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Channel::Green => "green",
            Channel::Luma601 => "luma601",
            Channel::Mean => "mean",
            Channel::Red => "red",
            Channel::Blue => "blue",
        }
    }

    /// Parses a name written by [`Channel::name`] (also accepts `luma`, `gray`, `grey`).
    pub fn from_name(s: &str) -> Option<Self> {
        match s {
            "green" | "g" => Some(Channel::Green),
            "luma601" | "luma" | "gray" | "grey" => Some(Channel::Luma601),
            "mean" => Some(Channel::Mean),
            "red" | "r" => Some(Channel::Red),
            "blue" | "b" => Some(Channel::Blue),
            _ => None,
        }
    }
}

/// How the foreground is separated from the background.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum Threshold {
    /// A fixed level as a fraction of full scale (0..1): foreground `v > level · 255`
    /// (MATLAB `im2bw`; seed 001 used 0.25).
    Fixed {
        /// Level in 0..1 of full scale.
        level: f64,
    },
    /// Otsu's level computed on every frame from all its pixels (seed 000; MATLAB
    /// `graythresh`, OpenCV `THRESH_OTSU`).
    #[default]
    Otsu,
    /// Otsu's level computed on every frame from every fourth pixel of every second row: the
    /// histogram, the costliest step of a 640 × 480 frame, in an eighth of the time. Its level
    /// is Otsu's criterion on a 38 400-pixel sample of the frame, not `graythresh`'s exact
    /// level (on the simulator's sensors and the OpenCV peer's frames it lies within a grey
    /// level of it).
    OtsuSampled,
    /// Local mean minus an offset, for uneven lighting.
    Adaptive {
        /// Side of the square window in pixels (odd, ≥ 3).
        window_px: usize,
        /// Offset in 0..1 of full scale, subtracted from the local mean (negative: stricter).
        offset: f64,
    },
}

/// A circle outside which every pixel is background (e.g. the round window of a cone camera).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CircleMask {
    /// Centre column in pixels.
    pub cx_px: f64,
    /// Centre row in pixels.
    pub cy_px: f64,
    /// Radius in pixels.
    pub radius_px: f64,
}

/// A rectangular region of interest; blobs touching its edge count as touching the border.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Roi {
    /// Left column.
    pub x: usize,
    /// Top row.
    pub y: usize,
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
}

/// Largest morphology window, pixels: wider than any marker a camera resolves.
pub const MAX_MORPH_SIZE: usize = 255;

/// Every preprocessing setting; stored in the sensor calibration file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct PreprocessConfig {
    /// Channel to work on.
    pub channel: Channel,
    /// Invert the channel (dark markers on a bright gel, as GelSight).
    pub invert: bool,
    /// Grey-level opening (removes bright specks smaller than the window).
    pub open: bool,
    /// Grey-level closing (fills dark specks smaller than the window), applied after opening.
    pub close: bool,
    /// Side of the square morphology window in pixels (odd; 3 by default).
    pub morph_size: usize,
    /// Threshold rule.
    pub threshold: Threshold,
    /// Optional rectangular region of interest.
    pub roi: Option<Roi>,
    /// Optional circular mask.
    pub circle: Option<CircleMask>,
}

impl PreprocessConfig {
    /// Seed 000 (IATS): green channel, 3×3 opening, Otsu.
    pub const IATS: Self = Self {
        channel: Channel::Green,
        invert: false,
        open: true,
        close: false,
        morph_size: 3,
        threshold: Threshold::Otsu,
        roi: None,
        circle: None,
    };

    /// Seed 001 (inflatable cone): BT.601 luma, fixed level 0.25.
    pub const CONE: Self = Self {
        channel: Channel::Luma601,
        invert: false,
        open: true,
        close: false,
        morph_size: 3,
        threshold: Threshold::Fixed { level: 0.25 },
        roi: None,
        circle: None,
    };

    /// Dark markers on a bright, unevenly lit gel (GelSight, 9DTact).
    pub const DARK_MARKERS: Self = Self {
        channel: Channel::Luma601,
        invert: true,
        open: true,
        close: false,
        morph_size: 3,
        threshold: Threshold::Adaptive {
            window_px: 31,
            offset: -0.06,
        },
        roi: None,
        circle: None,
    };

    /// Checks the settings; the message says which one is wrong.
    pub fn validate(&self) -> Result<(), crate::ConfigError> {
        if (self.open || self.close) && (self.morph_size == 0 || self.morph_size.is_multiple_of(2))
        {
            return Err(crate::ConfigError::out_of_range(
                "morphology size",
                self.morph_size as f64,
                "odd and ≥ 1",
            ));
        }
        match self.threshold {
            Threshold::Fixed { level } if !(0.0..=1.0).contains(&level) => {
                return Err(crate::ConfigError::out_of_range(
                    "fixed threshold",
                    level,
                    "in 0..1 of full scale",
                ))
            }
            Threshold::Adaptive { window_px, offset } => {
                if window_px < 3 || window_px % 2 == 0 {
                    return Err(crate::ConfigError::out_of_range(
                        "adaptive window",
                        window_px as f64,
                        "odd and ≥ 3",
                    ));
                }
                if !(-1.0..=1.0).contains(&offset) {
                    return Err(crate::ConfigError::out_of_range(
                        "adaptive offset",
                        offset,
                        "in −1..1",
                    ));
                }
            }
            _ => {}
        }
        if self.morph_size > MAX_MORPH_SIZE {
            return Err(crate::ConfigError::out_of_range(
                "morphology size",
                self.morph_size as f64,
                format!("at most {MAX_MORPH_SIZE} px"),
            ));
        }
        if let Some(r) = self.roi {
            if r.width == 0 || r.height == 0 {
                return Err(crate::ConfigError::EmptyRegion {
                    width: r.width,
                    height: r.height,
                });
            }
        }
        if let Some(c) = self.circle {
            if c.radius_px.is_nan()
                || c.radius_px <= 0.0
                || !c.cx_px.is_finite()
                || !c.cy_px.is_finite()
            {
                return Err(crate::ConfigError::BadCircle);
            }
        }
        Ok(())
    }
}

impl Default for PreprocessConfig {
    fn default() -> Self {
        Self::IATS
    }
}

/// Writes the chosen channel of `src` into `dst` (resized to match), inverted if asked.
pub fn gray_from_rgb_into(src: &RgbImage, channel: Channel, invert: bool, dst: &mut GrayImage) {
    dst.resize(src.width(), src.height());
    channel_from_rgb(
        src.as_slice(),
        channel,
        invert,
        dst.as_mut_slice(),
        &mut Vec::new(),
    );
}

/// One channel of a short run of interleaved RGB `s` into `d` (same formulas as
/// [`gray_from_rgb_into`], per pixel: for small windows).
pub fn channel_of_rgb(s: &[u8], channel: Channel, invert: bool, d: &mut [u8]) {
    for (o, p) in d.iter_mut().zip(s.chunks_exact(3)) {
        let (r, g, b) = (u32::from(p[0]), u32::from(p[1]), u32::from(p[2]));
        let v = match channel {
            Channel::Red => r,
            Channel::Green => g,
            Channel::Blue => b,
            Channel::Luma601 => (2989 * r + 5870 * g + 1140 * b + 5000) / 10000,
            Channel::Mean => (2 * (r + g + b) + 3) / 6,
        } as u8;
        *o = if invert { 255 - v } else { v };
    }
}

/// One channel of interleaved RGB `s` into `d` (any length: whole images or single rows);
/// `planes` is scratch for the luma conversion.
fn channel_from_rgb(s: &[u8], channel: Channel, invert: bool, d: &mut [u8], planes: &mut Vec<u8>) {
    match channel {
        Channel::Red => crate::kernels::pick_channel(s, d, 0),
        Channel::Green => crate::kernels::pick_channel(s, d, 1),
        Channel::Blue => crate::kernels::pick_channel(s, d, 2),
        // Adding 5000 before dividing by 10000 rounds half up, as MATLAB's round does.
        Channel::Luma601 => crate::kernels::luma601(s, d, planes),
        Channel::Mean => {
            for (o, p) in d.iter_mut().zip(s.chunks_exact(3)) {
                let acc = u32::from(p[0]) + u32::from(p[1]) + u32::from(p[2]);
                *o = ((2 * acc + 3) / 6) as u8;
            }
        }
    }
    if invert {
        for v in d.iter_mut() {
            *v = 255 - *v;
        }
    }
}

/// Ring buffers for [`open3_from_rgb_into`].
#[derive(Debug, Clone)]
pub struct Open3Scratch {
    g: Vec<u8>,
    he: Vec<u8>,
    e: Vec<u8>,
    hd: Vec<u8>,
    planes: Vec<u8>,
    tables: Box<Tables>,
}

/// Channel selection, inversion and a 3×3 grey opening in one streaming pass over rows (three
/// rows of each intermediate kept, in L1 cache), accumulating the histogram of the result's
/// chosen pixels when `hist` is given. Equals [`gray_from_rgb_into`] followed by
/// [`morphology_in_place`] with `open` and size 3, and [`histogram_of`] of the result. Images
/// narrower or shorter than 3 pixels take that general path.
pub fn open3_from_rgb_into(
    src: &RgbImage,
    channel: Channel,
    invert: bool,
    dst: &mut GrayImage,
    hist: Option<(&mut [u32; 256], HistogramPixels)>,
    s: &mut Open3Scratch,
) {
    let (w, h) = (src.width(), src.height());
    if w < 3 || h < 3 {
        gray_from_rgb_into(src, channel, invert, dst);
        let cfg = PreprocessConfig {
            open: true,
            close: false,
            morph_size: 3,
            ..PreprocessConfig::IATS
        };
        morphology_in_place(dst, &cfg, &mut MorphScratch::default());
        if let Some((hh, pixels)) = hist {
            *hh = histogram_of(dst, pixels);
        }
        return;
    }
    dst.resize(w, h);
    s.g.resize(w, 0);
    s.he.resize(3 * w, 0);
    s.e.resize(w, 0);
    s.hd.resize(3 * w, 0);
    let want_hist = hist.as_ref().map(|&(_, pixels)| pixels);
    if want_hist.is_some() {
        *s.tables = [[0; 256]; 8];
    }
    let pass = Open3Pass {
        src,
        channel,
        invert,
        dst,
        want_hist,
        s,
    };
    // One check of the CPU per frame; the row loop is compiled with AVX2 where it runs on it.
    Avx2::dispatch(
        pass,
        #[cfg(target_arch = "x86_64")]
        open3_rows_avx2,
        open3_rows,
    );
    if let Some((hh, _)) = hist {
        *hh = merged(&s.tables);
    }
}

/// The inputs, output and scratch of [`open3_rows`].
struct Open3Pass<'a> {
    src: &'a RgbImage,
    channel: Channel,
    invert: bool,
    dst: &'a mut GrayImage,
    want_hist: Option<HistogramPixels>,
    s: &'a mut Open3Scratch,
}

/// [`open3_rows`] compiled with AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn open3_rows_avx2(cpu: Avx2, pass: Open3Pass<'_>) {
    open3_rows(Some(cpu), pass);
}

/// The rows of [`open3_from_rgb_into`] (scratch sized, `w, h ≥ 3`) on `cpu`'s kernels.
#[inline(always)]
fn open3_rows(cpu: Option<Avx2>, pass: Open3Pass<'_>) {
    let Open3Pass {
        src,
        channel,
        invert,
        dst,
        want_hist,
        s,
    } = pass;
    let (w, h) = (src.width(), src.height());
    let rgb = src.as_slice();
    let slot = |y: usize| (y % 3) * w..(y % 3) * w + w;
    for y_in in 0..h + 2 {
        // Stage A: channel row y_in, eroded horizontally.
        if y_in < h {
            let row = &rgb[3 * w * y_in..3 * w * (y_in + 1)];
            match (channel, invert) {
                (Channel::Red, false) => pick_channel_on(cpu, row, &mut s.g, 0),
                (Channel::Green, false) => pick_channel_on(cpu, row, &mut s.g, 1),
                (Channel::Blue, false) => pick_channel_on(cpu, row, &mut s.g, 2),
                _ => channel_from_rgb(row, channel, invert, &mut s.g, &mut s.planes),
            }
            row_extremum(cpu, &s.g, &mut s.he[slot(y_in)], 1, Extremum::Min);
        }
        // Stage B: row y_in − 1 eroded vertically, then dilated horizontally.
        if (1..=h).contains(&y_in) {
            let y = y_in - 1;
            vertical3(cpu, &s.he, w, y, h, &mut s.e, false);
            row_extremum(cpu, &s.e, &mut s.hd[slot(y)], 1, Extremum::Max);
        }
        // Stage C: row y_in − 2 dilated vertically: the opened row.
        if y_in >= 2 {
            let y = y_in - 2;
            let out = dst.row_mut(y);
            vertical3(cpu, &s.hd, w, y, h, out, true);
            if let Some(pixels) = want_hist {
                count_pixels_of_row(out, y, pixels, &mut s.tables);
            }
        }
    }
}

/// Adds the chosen pixels of row `y` to `tables`.
#[inline]
fn count_pixels_of_row(row: &[u8], y: usize, pixels: HistogramPixels, tables: &mut Tables) {
    match pixels {
        HistogramPixels::All => count_row(row, tables),
        HistogramPixels::Eighth if y.is_multiple_of(2) => count_fourth_of_row(row, tables),
        HistogramPixels::Eighth => {}
    }
}

/// Eight interleaved histograms, summed by [`merged`].
type Tables = [[u32; 256]; 8];

/// Adds every byte of `row` to the eight interleaved `tables` (each sees every eighth byte,
/// which breaks the store-to-load chain when neighbouring pixels are equal, the common case on
/// a flat background).
#[inline]
fn count_row(row: &[u8], tables: &mut Tables) {
    let mut chunks = row.chunks_exact(8);
    for c in &mut chunks {
        let v = u64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]);
        for (k, table) in tables.iter_mut().enumerate() {
            table[((v >> (8 * k)) & 0xff) as usize] += 1;
        }
    }
    for &v in chunks.remainder() {
        tables[0][v as usize] += 1;
    }
}

/// Adds the bytes at offsets `0, 4, 8, …` of `row` to `tables` (all eight in turn, so that
/// equal neighbours on a flat background do not chain one counter's increments).
#[inline]
fn count_fourth_of_row(row: &[u8], tables: &mut Tables) {
    let (chunks, rest) = row.as_chunks::<32>();
    for c in chunks {
        for (k, table) in tables.iter_mut().enumerate() {
            table[c[4 * k] as usize] += 1;
        }
    }
    for (&v, table) in rest.iter().step_by(4).zip(tables.iter_mut()) {
        table[v as usize] += 1;
    }
}

/// The sum of the interleaved tables.
fn merged(tables: &Tables) -> [u32; 256] {
    let mut out = [0u32; 256];
    for (i, o) in out.iter_mut().enumerate() {
        *o = tables.iter().map(|t| t[i]).sum();
    }
    out
}

impl Default for Open3Scratch {
    fn default() -> Self {
        Self {
            g: Vec::new(),
            he: Vec::new(),
            e: Vec::new(),
            hd: Vec::new(),
            planes: Vec::new(),
            tables: Box::new([[0; 256]; 8]),
        }
    }
}

/// Min (or max) of ring-buffer rows `y − 1, y, y + 1` (clipped to `0..h`) into `out`.
#[inline(always)]
fn vertical3(
    cpu: Option<Avx2>,
    ring: &[u8],
    w: usize,
    y: usize,
    h: usize,
    out: &mut [u8],
    max: bool,
) {
    let row = |yy: usize| &ring[(yy % 3) * w..(yy % 3) * w + w];
    match (y > 0, y + 1 < h) {
        (true, true) => extremum3_on(cpu, row(y - 1), row(y), row(y + 1), out, max),
        (lo, _) => {
            let other = if lo { y - 1 } else { y + 1 };
            out.copy_from_slice(row(y));
            crate::kernels::extremum_acc(row(other), out, max);
        }
    }
}

/// Allocating form of [`gray_from_rgb_into`].
pub fn gray_from_rgb(src: &RgbImage, channel: Channel, invert: bool) -> GrayImage {
    let mut dst = GrayImage::new(0, 0);
    gray_from_rgb_into(src, channel, invert, &mut dst);
    dst
}

#[derive(Clone, Copy)]
enum Extremum {
    Min,
    Max,
}

impl Extremum {
    #[inline(always)]
    fn pick(self, a: u8, b: u8) -> u8 {
        match self {
            Extremum::Min => a.min(b),
            Extremum::Max => a.max(b),
        }
    }
}

/// Horizontal running min/max of radius `r` over one row, clipped at the ends.
#[inline(always)]
fn row_extremum(cpu: Option<Avx2>, src: &[u8], dst: &mut [u8], r: usize, op: Extremum) {
    let n = src.len();
    if n == 0 {
        return;
    }
    if r == 1 && n >= 3 {
        // The 3-wide case is the hot one: three shifted slices so the loop vectorises.
        let (a, b, c) = (&src[..n - 2], &src[1..n - 1], &src[2..]);
        extremum3_on(
            cpu,
            a,
            b,
            c,
            &mut dst[1..n - 1],
            matches!(op, Extremum::Max),
        );
        dst[0] = op.pick(src[0], src[1]);
        dst[n - 1] = op.pick(src[n - 2], src[n - 1]);
        return;
    }
    for (x, o) in dst.iter_mut().enumerate().take(n) {
        let lo = x.saturating_sub(r);
        let hi = (x + r).min(n - 1);
        *o = src[lo + 1..=hi].iter().fold(src[lo], |v, &s| op.pick(v, s));
    }
}

/// Separable `k × k` min/max filter, `src` → `dst`, with `tmp` as scratch.
fn extremum_filter(
    src: &GrayImage,
    dst: &mut GrayImage,
    tmp: &mut GrayImage,
    k: usize,
    op: Extremum,
) {
    let (w, h) = (src.width(), src.height());
    let r = k / 2;
    tmp.resize(w, h);
    dst.resize(w, h);
    let cpu = Avx2::detect();
    for y in 0..h {
        row_extremum(cpu, src.row(y), tmp.row_mut(y), r, op);
    }
    let t = tmp.as_slice();
    let d = dst.as_mut_slice();
    for y in 0..h {
        let lo = y.saturating_sub(r);
        let hi = (y + r).min(h - 1);
        let out = &mut d[y * w..(y + 1) * w];
        let max = matches!(op, Extremum::Max);
        if hi - lo == 2 {
            let (a, b, c) = (
                &t[lo * w..(lo + 1) * w],
                &t[(lo + 1) * w..(lo + 2) * w],
                &t[hi * w..(hi + 1) * w],
            );
            extremum3_on(cpu, a, b, c, out, max);
            continue;
        }
        out.copy_from_slice(&t[lo * w..(lo + 1) * w]);
        for yy in lo + 1..=hi {
            crate::kernels::extremum_acc(&t[yy * w..(yy + 1) * w], out, max);
        }
    }
}

/// Grey-level erosion with a `k × k` square (OpenCV `erode`, default border).
pub fn erode(src: &GrayImage, dst: &mut GrayImage, tmp: &mut GrayImage, k: usize) {
    extremum_filter(src, dst, tmp, k, Extremum::Min);
}

/// Grey-level dilation with a `k × k` square (OpenCV `dilate`, default border).
pub fn dilate(src: &GrayImage, dst: &mut GrayImage, tmp: &mut GrayImage, k: usize) {
    extremum_filter(src, dst, tmp, k, Extremum::Max);
}

/// Reusable buffers for [`morphology_in_place`].
#[derive(Default, Debug, Clone)]
pub struct MorphScratch {
    a: GrayImage,
    b: GrayImage,
}

/// Applies the opening and/or closing asked for in `cfg` to `img` in place.
pub fn morphology_in_place(img: &mut GrayImage, cfg: &PreprocessConfig, s: &mut MorphScratch) {
    let k = cfg.morph_size;
    if cfg.open {
        erode(img, &mut s.a, &mut s.b, k);
        dilate(&s.a, img, &mut s.b, k);
    }
    if cfg.close {
        dilate(img, &mut s.a, &mut s.b, k);
        erode(&s.a, img, &mut s.b, k);
    }
}

/// 256-bin histogram of an 8-bit buffer.
pub fn histogram(data: &[u8]) -> [u32; 256] {
    let mut tables = [[0u32; 256]; 8];
    count_row(data, &mut tables);
    merged(&tables)
}

/// 256-bin histogram of the chosen pixels of `img`.
///
/// ```
/// use visuotact_image::GrayImage;
/// use visuotact_vision::preprocess::{histogram_of, HistogramPixels};
/// // 5 × 3: only (0, 0), (4, 0), (0, 2) and (4, 2) are in the eighth.
/// let img = GrayImage::from_vec(5, 3, vec![1, 9, 9, 9, 2, 9, 9, 9, 9, 9, 3, 9, 9, 9, 1]).unwrap();
/// let h = histogram_of(&img, HistogramPixels::Eighth);
/// assert_eq!((h[1], h[2], h[3], h[9]), (2, 1, 1, 0));
/// assert_eq!(histogram_of(&img, HistogramPixels::All)[9], 11);
/// ```
pub fn histogram_of(img: &GrayImage, pixels: HistogramPixels) -> [u32; 256] {
    let mut tables = [[0u32; 256]; 8];
    for y in 0..img.height() {
        count_pixels_of_row(img.row(y), y, pixels, &mut tables);
    }
    merged(&tables)
}

/// Otsu's level from a 256-bin histogram: the `t` maximising the between-class variance of
/// `{v ≤ t}` and `{v > t}` (first maximum on ties). A histogram with one occupied bin gives that
/// value.
///
/// ```
/// use visuotact_vision::preprocess::otsu_level;
/// let mut h = [0u32; 256];
/// h[10] = 50;
/// h[200] = 50;
/// assert_eq!(otsu_level(&h), 10);
/// ```
pub fn otsu_level(hist: &[u32; 256]) -> u8 {
    let total: f64 = hist.iter().map(|&c| f64::from(c)).sum();
    if total == 0.0 {
        return 0;
    }
    let sum_all: f64 = hist
        .iter()
        .enumerate()
        .map(|(i, &c)| i as f64 * f64::from(c))
        .sum();
    let (mut w0, mut sum0) = (0.0f64, 0.0f64);
    let (mut best, mut best_t) = (-1.0f64, 0usize);
    for (t, &c) in hist.iter().enumerate().take(255) {
        // An empty bin leaves both classes as they were: its variance equals the last bin's,
        // which cannot be a new (strictly greater) maximum.
        if c == 0 {
            continue;
        }
        w0 += f64::from(c);
        sum0 += t as f64 * f64::from(c);
        let w1 = total - w0;
        if w0 == 0.0 || w1 == 0.0 {
            continue;
        }
        let m0 = sum0 / w0;
        let m1 = (sum_all - sum0) / w1;
        let between = w0 * w1 * (m0 - m1) * (m0 - m1);
        if between > best {
            best = between;
            best_t = t;
        }
    }
    if best < 0.0 {
        // A single occupied bin: every pixel is background.
        return hist.iter().rposition(|&c| c > 0).unwrap_or(0) as u8;
    }
    best_t as u8
}

/// Per-pixel levels for adaptive thresholding: `level[x, y] = mean − offset·255`, the mean over
/// the in-image part of a `window × window` square, stored as `f32` rows. The foreground is
/// `v > level`.
pub fn adaptive_levels_into(src: &GrayImage, window_px: usize, offset: f64, out: &mut Vec<f32>) {
    let (w, h) = (src.width(), src.height());
    let r = window_px / 2;
    out.clear();
    out.resize(w * h, 0.0);
    // Column sums over the vertical window, updated incrementally row by row.
    let mut col = vec![0u32; w];
    let mut rows_in = 0u32;
    let src_s = src.as_slice();
    let add_row = |col: &mut [u32], y: usize, sign: bool| {
        let row = &src_s[y * w..(y + 1) * w];
        if sign {
            col.iter_mut()
                .zip(row)
                .for_each(|(c, &v)| *c += u32::from(v));
        } else {
            col.iter_mut()
                .zip(row)
                .for_each(|(c, &v)| *c -= u32::from(v));
        }
    };
    for y in 0..r.min(h) {
        add_row(&mut col, y, true);
        rows_in += 1;
    }
    let off = (offset * 255.0) as f32;
    for y in 0..h {
        if y + r < h {
            add_row(&mut col, y + r, true);
            rows_in += 1;
        }
        if y > r {
            add_row(&mut col, y - r - 1, false);
            rows_in -= 1;
        }
        // Horizontal running sum over the column sums.
        let orow = &mut out[y * w..(y + 1) * w];
        let mut acc: u32 = col[..r.min(w)].iter().sum();
        let mut cols_in = r.min(w) as u32;
        for x in 0..w {
            if x + r < w {
                acc += col[x + r];
                cols_in += 1;
            }
            if x > r {
                acc -= col[x - r - 1];
                cols_in -= 1;
            }
            orow[x] = acc as f32 / (cols_in * rows_in) as f32 - off;
        }
    }
}

/// Which way markers differ from the skin around them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Polarity {
    /// Brighter than the skin (painted pins and dots under light, seed 000, TacTip).
    Bright,
    /// Darker than the skin (printed dots on a lit gel: GelSight, 9DTact).
    Dark,
}

/// The polarity of the markers in `img`, for choosing a detector on a sensor never seen.
///
/// Markers are small against the skin, so on the luma channel minus its local mean (a window of
/// an eighth of the shorter image side, which also takes out uneven light) the markers make the
/// longer tail: bright markers the upper one, dark markers the lower one. The 0.5 % and 99.5 %
/// quantiles of that residual are compared; a flat image reads [`Polarity::Bright`].
///
/// ```
/// use visuotact_image::RgbImage;
/// use visuotact_vision::preprocess::{marker_polarity, Polarity};
/// // Dark dots every 16 px on a bright gel lit from the left.
/// let gel = RgbImage::from_fn(96, 64, |x, y| {
///     let dot = (x % 16) as i32 - 8;
///     let dot = dot * dot + ((y % 16) as i32 - 8).pow(2) <= 9;
///     let v = if dot { 30 } else { 150 + (x / 2) as u8 };
///     [v, v, v]
/// });
/// assert_eq!(marker_polarity(&gel), Polarity::Dark);
/// ```
pub fn marker_polarity(img: &RgbImage) -> Polarity {
    let gray = gray_from_rgb(img, Channel::Luma601, false);
    let window = (gray.width().min(gray.height()) / 8) | 1;
    let mut mean = Vec::new();
    adaptive_levels_into(&gray, window.max(3), 0.0, &mut mean);
    // Residuals rounded into 511 bins: −255..=255.
    let mut hist = [0u32; 511];
    for (&v, &m) in gray.as_slice().iter().zip(&mean) {
        let r = (f32::from(v) - m).round().clamp(-255.0, 255.0) as i32;
        hist[(r + 255) as usize] += 1;
    }
    let total: u64 = hist.iter().map(|&c| u64::from(c)).sum();
    let tail = (total / 200).max(1);
    let quantile = |bins: &mut dyn Iterator<Item = usize>| -> i32 {
        let mut seen = 0u64;
        for b in bins {
            seen += u64::from(hist[b]);
            if seen >= tail {
                return b as i32 - 255;
            }
        }
        0
    };
    let low = quantile(&mut (0..511));
    let high = quantile(&mut (0..511).rev());
    if -low > high {
        Polarity::Dark
    } else {
        Polarity::Bright
    }
}

#[cfg(test)]
mod channel_tests {
    use super::*;

    #[test]
    fn per_pixel_channels_equal_the_image_conversion() {
        let img = RgbImage::from_fn(37, 5, |x, y| {
            [
                (x * 7 + y * 3) as u8,
                (x * 13 + 200) as u8,
                (y * 50 + x) as u8,
            ]
        });
        for channel in Channel::ALL {
            for invert in [false, true] {
                let whole = gray_from_rgb(&img, channel, invert);
                for y in 0..5 {
                    let mut row = vec![0u8; 30];
                    channel_of_rgb(
                        &img.as_slice()[(y * 37 + 4) * 3..(y * 37 + 34) * 3],
                        channel,
                        invert,
                        &mut row,
                    );
                    assert_eq!(&row[..], &whole.row(y)[4..34], "{channel:?} {invert}");
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dots(bright: bool, gradient: bool) -> RgbImage {
        RgbImage::from_fn(160, 120, |x, y| {
            let (dx, dy) = ((x % 20) as i32 - 10, (y % 20) as i32 - 10);
            let on = dx * dx + dy * dy <= 20;
            let base = if gradient { (x / 4) as u8 } else { 0 };
            let v = match (bright, on) {
                (true, true) => 220,
                (true, false) => 25 + base,
                (false, true) => 35,
                (false, false) => 140 + base,
            };
            [v, v.saturating_add(5), v]
        })
    }

    #[test]
    fn polarity_follows_the_markers_not_the_light() {
        for gradient in [false, true] {
            assert_eq!(marker_polarity(&dots(true, gradient)), Polarity::Bright);
            assert_eq!(marker_polarity(&dots(false, gradient)), Polarity::Dark);
        }
        let flat = RgbImage::from_fn(40, 30, |_, _| [90, 90, 90]);
        assert_eq!(marker_polarity(&flat), Polarity::Bright);
    }

    #[test]
    fn streaming_open3_equals_separate_passes() {
        let mut seed = 7u64;
        for &(w, h) in &[
            (3, 3),
            (5, 4),
            (17, 9),
            (64, 33),
            (2, 7),
            (9, 1),
            (37, 6),
            (101, 5),
        ] {
            let rgb = RgbImage::from_fn(w, h, |_, _| {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let v = (seed >> 40) as u32;
                [v as u8, (v >> 8) as u8, (v >> 16) as u8]
            });
            for channel in Channel::ALL {
                for invert in [false, true] {
                    let mut want = gray_from_rgb(&rgb, channel, invert);
                    let cfg = PreprocessConfig {
                        open: true,
                        close: false,
                        morph_size: 3,
                        ..PreprocessConfig::IATS
                    };
                    morphology_in_place(&mut want, &cfg, &mut MorphScratch::default());
                    // Every pixel, and every fourth one of every second row, counted here.
                    let mut eighth = [0u32; 256];
                    for y in (0..want.height()).step_by(2) {
                        for x in (0..want.width()).step_by(4) {
                            eighth[want.get(x, y) as usize] += 1;
                        }
                    }
                    for (pixels, counted) in [
                        (HistogramPixels::All, histogram(want.as_slice())),
                        (HistogramPixels::Eighth, eighth),
                    ] {
                        let mut got = GrayImage::new(0, 0);
                        let mut hist = [0u32; 256];
                        open3_from_rgb_into(
                            &rgb,
                            channel,
                            invert,
                            &mut got,
                            Some((&mut hist, pixels)),
                            &mut Open3Scratch::default(),
                        );
                        assert_eq!(got, want, "{w}×{h} {channel:?} {invert}");
                        assert_eq!(hist, counted, "{w}×{h} {pixels:?}");
                        assert_eq!(histogram_of(&want, pixels), counted);
                    }
                }
            }
        }
    }

    #[test]
    fn otsu_level_skipping_empty_bins_equals_the_full_scan() {
        // Every bin's between-class variance, first maximum: the definition, bin by bin.
        let full = |hist: &[u32; 256]| -> u8 {
            let total: f64 = hist.iter().map(|&c| f64::from(c)).sum();
            let sum_all: f64 = hist
                .iter()
                .enumerate()
                .map(|(i, &c)| i as f64 * f64::from(c))
                .sum();
            let (mut w0, mut sum0, mut best, mut best_t) = (0.0, 0.0, -1.0, None);
            for (t, &c) in hist.iter().enumerate().take(255) {
                w0 += f64::from(c);
                sum0 += t as f64 * f64::from(c);
                let w1 = total - w0;
                if w0 > 0.0 && w1 > 0.0 {
                    let d = sum0 / w0 - (sum_all - sum0) / w1;
                    if w0 * w1 * d * d > best {
                        (best, best_t) = (w0 * w1 * d * d, Some(t as u8));
                    }
                }
            }
            best_t.unwrap_or_else(|| hist.iter().rposition(|&c| c > 0).unwrap_or(0) as u8)
        };
        let mut seed = 11u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 33) as u32
        };
        for case in 0..500 {
            let mut hist = [0u32; 256];
            // Sparse histograms (a few occupied bins) and dense ones.
            let occupied = if case % 2 == 0 {
                1 + next() % 6
            } else {
                40 + next() % 200
            };
            for _ in 0..occupied {
                hist[(next() % 256) as usize] += 1 + next() % 500;
            }
            assert_eq!(otsu_level(&hist), full(&hist), "case {case}");
        }
        assert_eq!(otsu_level(&[0; 256]), 0);
    }

    #[test]
    fn erosion_matches_brute_force_window() {
        let img = GrayImage::from_fn(11, 7, |x, y| ((x * 37 + y * 91) % 256) as u8);
        for k in [1usize, 3, 5] {
            let (mut out, mut tmp) = (GrayImage::new(0, 0), GrayImage::new(0, 0));
            erode(&img, &mut out, &mut tmp, k);
            let r = k / 2;
            for y in 0..7usize {
                for x in 0..11usize {
                    let mut m = 255u8;
                    for yy in y.saturating_sub(r)..=(y + r).min(6) {
                        for xx in x.saturating_sub(r)..=(x + r).min(10) {
                            m = m.min(img.get(xx, yy));
                        }
                    }
                    assert_eq!(out.get(x, y), m);
                }
            }
        }
    }
}
