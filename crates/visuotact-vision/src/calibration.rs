//! The sensor calibration: a no-contact reference built from still frames, markers numbered by
//! their layout ([`crate::layout`]), and every setting needed to measure later frames the same
//! way. Saved as JSON.
//!
//! A reference in contact can squeeze two markers into one blob; such a blob (about twice a
//! marker's area, the array's or its neighbours' where a crease squeezes them to slivers, its
//! moments those of two discs) is split in two where the lattice agrees: numbered with the
//! halves, the array is a grid or hexagonal array holding both (`split_touching_pairs`; tests
//! `tests/touching_pairs.rs` and the 331-pin TacTip's `image_200` in `tests/real_frames.rs`).
//!
//! The reference image is the per-pixel mean of N still frames in the chosen channel (seed 001's
//! Calibration Data Model), on which markers are detected once; each still frame is then
//! tracked against it to measure each marker's jitter (RMS, pixels), the noise floor of the
//! displacement features.
//!
//! A data set with no contact-free frame (every frame pressed) gets its reference from its
//! lightest frames instead ([`LightestFinder`]): every frame's markers are tracked against a
//! provisional reference, each marker's median position over all frames estimates where it
//! rests (touches at different places leave any one marker alone in most frames), and the N
//! frames closest to that estimate (RMS over the markers) are the ones averaged. The sensor
//! file says so ([`ReferenceInfo`]), with how far those frames still were from the estimate.

use serde::{Deserialize, Serialize};
use visuotact_image::{GrayImage, RgbImage};

use crate::blobs::{Blob, MomentConvention};
use crate::detect::{Detector, DetectorConfig};
use crate::features::FeatureSet;
use crate::layout::{
    annuli_share_centres, k_nearest_all, median, number_markers, Layout, LayoutChoice, LayoutError,
};
use crate::preprocess::gray_from_rgb_into;
use crate::track::{fill_sigma_from_rest, track, unseen_sites, TrackParams, TrackReference};
use rayon::prelude::*;

/// Identifies sensor files.
pub const SENSOR_FORMAT: &str = "visuotact-sensor";
/// Current sensor file version (2: layouts beyond grid and rings, marker neighbours, reference
/// provenance; version 1 files read as grids or rings with neighbours rebuilt).
pub const SENSOR_VERSION: u32 = 2;

/// One marker of the no-contact reference.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceMarker {
    /// Marker number in the layout's order (0-based); feature columns are named `m{id:03}_…`.
    pub id: u32,
    /// Row in the layout (grid and hex: lattice row, 0 = top; dot rings: ring, 0 = centre).
    pub row: u32,
    /// Column in the layout (grid: lattice column; hex: half-pitch steps; dot rings: position
    /// in the ring).
    pub col: u32,
    /// Centroid column in pixels.
    pub x_px: f64,
    /// Centroid row in pixels.
    pub y_px: f64,
    /// Area in pixels.
    pub area_px: f64,
    /// Eccentricity (convention of the calibration).
    pub eccentricity: f64,
    /// Major axis length in pixels.
    pub major_axis_px: f64,
    /// Minor axis length in pixels.
    pub minor_axis_px: f64,
    /// Whether the marker touches the image border (cut markers kept with `keep_border`).
    pub touches_border: bool,
    /// RMS displacement over the calibration frames, pixels (0 with one frame; `None` when the
    /// marker was never matched in a single calibration frame).
    pub jitter_px: Option<f64>,
    /// Ids of the marker's neighbours in the layout (lattice steps, or the markers within 1.5 ×
    /// its nearest distance), nearest first.
    #[serde(default)]
    pub neighbours: Vec<u32>,
}

/// How the reference was taken.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ReferenceInfo {
    /// `still` (the mean of frames given as contact-free) or `lightest` (the lightest frames of
    /// a data set with no contact-free frame).
    pub method: String,
    /// Frames the lightest ones were chosen from (0 for still frames).
    pub frames_considered: usize,
    /// RMS distance of the chosen frames' markers from their estimated rest positions, pixels
    /// (`lightest` only): what contact the reference still holds.
    pub residual_px: Option<f64>,
    /// Largest single marker's distance from its estimated rest position, pixels (`lightest`).
    pub residual_max_px: Option<f64>,
    /// The reference was taken under contact: displacement features are relative to a lightly
    /// pressed skin, not to the skin at rest.
    pub under_contact: bool,
}

impl ReferenceInfo {
    /// A reference from frames given as contact-free.
    pub fn still() -> Self {
        Self {
            method: "still".to_string(),
            ..Self::default()
        }
    }
}

/// What calibration builds from the frames.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct CalibrationConfig {
    /// Preprocessing and blob filter.
    pub detector: DetectorConfig,
    /// Marker layout: recognised, or one that must fit.
    pub layout: LayoutChoice,
    /// Default feature set for `extract`.
    pub features: FeatureSet,
    /// Tracker settings saved in the sensor file.
    pub track: TrackParams,
}

/// Named starting points for a sensor's calibration: preprocessing, centroid, feature set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Preset {
    /// Bright markers on a darker skin (seed 000's green markers, TacTip pins): the green
    /// channel, a 3 × 3 opening, Otsu's level from an eighth of the pixels
    /// ([`Threshold::OtsuSampled`]: the frame's costliest step in an eighth of the time, the
    /// same tracking accuracy with grey-level centroids), grey-level centroids, features
    /// `x,y,area`.
    ///
    /// [`Threshold::OtsuSampled`]: crate::preprocess::Threshold::OtsuSampled
    Iats,
    /// Seed 001's cone: BT.601 luma, fixed level 0.25, grey-weighted centroids (steadiest on
    /// thin annuli), features `x,y,area,ecc`.
    Cone,
    /// Dark markers on a bright, unevenly lit gel (GelSight, 9DTact): inverted luma, an
    /// adaptive level, grey-level centroids, features `x,y,area`.
    DarkMarkers,
}

visuotact_image::names_from_str!(Preset, "preset");

impl Preset {
    /// What a user may choose: `auto` ([`Preset::for_frame`]) or a preset's name.
    pub const CHOICES: &'static [&'static str] = &["auto", "iats", "cone", "dark-markers"];

    /// The names [`Preset::from_name`] and `FromStr` read (each is also what `name` writes,
    /// where the type has one).
    pub const NAMES: &'static [&'static str] = &["iats", "cone", "dark-markers"];

    /// Every preset, in the order `--preset` lists them.
    pub const ALL: [Preset; 3] = [Preset::Iats, Preset::Cone, Preset::DarkMarkers];

    /// Name on the command line and in Python.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Iats => "iats",
            Preset::Cone => "cone",
            Preset::DarkMarkers => "dark-markers",
        }
    }

    /// The preset called `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }

    /// `auto`: [`Preset::DarkMarkers`] when the markers in `frame` are darker than the skin,
    /// else [`Preset::Iats`].
    pub fn for_frame(frame: &RgbImage) -> Self {
        match crate::preprocess::marker_polarity(frame) {
            crate::preprocess::Polarity::Dark => Preset::DarkMarkers,
            _ => Preset::Iats,
        }
    }

    /// The calibration settings: this preset's detector and features, the layout recognised
    /// automatically, the default tracker.
    pub fn config(self) -> CalibrationConfig {
        use crate::detect::Centroid;
        use crate::preprocess::PreprocessConfig;
        let (preprocess, centroid, features) = match self {
            Preset::Iats => (
                PreprocessConfig {
                    threshold: crate::preprocess::Threshold::OtsuSampled,
                    ..PreprocessConfig::IATS
                },
                Centroid::Grey,
                FeatureSet::IATS,
            ),
            Preset::Cone => (PreprocessConfig::CONE, Centroid::Weighted, FeatureSet::CONE),
            Preset::DarkMarkers => (
                PreprocessConfig::DARK_MARKERS,
                Centroid::Grey,
                FeatureSet::IATS,
            ),
        };
        CalibrationConfig {
            detector: DetectorConfig {
                preprocess,
                centroid,
                ..DetectorConfig::default()
            },
            layout: LayoutChoice::Auto,
            features,
            track: TrackParams::DEFAULT,
        }
    }
}

/// Everything `extract` needs to turn frames of this sensor into features.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SensorCalibration {
    /// Always [`SENSOR_FORMAT`].
    pub format: String,
    /// File version, [`SENSOR_VERSION`].
    pub version: u32,
    /// Frame width in pixels.
    pub image_width: usize,
    /// Frame height in pixels.
    pub image_height: usize,
    /// Preprocessing and blob filter.
    pub detector: DetectorConfig,
    /// How markers are numbered.
    pub layout: Layout,
    /// Moment convention for eccentricity features.
    pub moment_convention: MomentConvention,
    /// Tracker settings.
    pub track: TrackParams,
    /// Default feature set for `extract`.
    pub features: FeatureSet,
    /// Ids of the frames averaged into the reference.
    pub reference_frames: Vec<String>,
    /// How the reference was taken (still frames unless said otherwise).
    #[serde(default = "ReferenceInfo::still")]
    pub reference: ReferenceInfo,
    /// Rows spanned by the markers (grid, hex: lattice rows; dot rings: rings; 1 for annuli).
    pub grid_rows: u32,
    /// Columns spanned (hex: half-pitch steps; dot rings: most dots in a ring).
    pub grid_cols: u32,
    /// Median distance between nearest neighbouring markers in pixels (annuli: the smallest
    /// gap between ring radii).
    pub pitch_px: f64,
    /// The reference markers in grid order.
    pub markers: Vec<ReferenceMarker>,
    /// The markers' size and spacing measured before detection, when the detector's opening
    /// and smallest area were chosen from them ([`crate::sizing`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub marker_size: Option<crate::sizing::MarkerSize>,
    /// Millimetres per pixel on the skin, when the markers' pitch in millimetres was given
    /// ([`SensorCalibration::set_pitch_mm`]): feature tables then carry displacements in
    /// millimetres beside the pixels, comparable between sensors of one design.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<PixelScale>,
    /// Hexagonal arrays: blobs of the reference the numbering left out, `(x_px, y_px,
    /// area_px)` (pins on a seam where the numbering skipped a row, in a reference taken in
    /// contact). Not markers (no column of features); the tracker follows them as markers it
    /// never reports, so that a reading shifted a lattice step onto their pins pays for the
    /// pins it leaves without their owner.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub unnumbered: Vec<(f64, f64, f64)>,
}

/// The skin's scale in the image: from the markers' pitch measured in millimetres on the skin
/// and in pixels in the reference.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PixelScale {
    /// Millimetres per pixel (`pitch_mm / pitch_px`).
    pub mm_per_px: f64,
    /// The pitch given, millimetres.
    pub pitch_mm: f64,
}

impl PixelScale {
    /// Why a scale read from a file is not one (a length that is not positive), or `None`.
    fn invalid(self) -> Option<String> {
        let ok = |v: f64| v.is_finite() && v > 0.0;
        (!(ok(self.mm_per_px) && ok(self.pitch_mm))).then(|| {
            format!(
                "scale: mm_per_px {} and pitch_mm {} must be positive",
                self.mm_per_px, self.pitch_mm
            )
        })
    }
}

impl SensorCalibration {
    /// Sets the scale from the distance between neighbouring markers on the skin, in
    /// millimetres: the same distance as [`SensorCalibration::pitch_px`] (nearest
    /// neighbours; for annuli, the smallest gap between ring radii). Refused unless it is a
    /// positive length.
    pub fn set_pitch_mm(&mut self, pitch_mm: f64) -> Result<(), crate::ConfigError> {
        if !(pitch_mm.is_finite() && pitch_mm > 0.0) {
            return Err(crate::ConfigError::out_of_range(
                "marker pitch (mm)",
                pitch_mm,
                "a positive length in millimetres",
            ));
        }
        if !(self.pitch_px.is_finite() && self.pitch_px > 0.0) {
            return Err(crate::ConfigError::out_of_range(
                "the calibration's marker pitch (px)",
                self.pitch_px,
                "positive to take a scale from it",
            ));
        }
        self.scale = Some(PixelScale {
            mm_per_px: pitch_mm / self.pitch_px,
            pitch_mm,
        });
        Ok(())
    }

    /// Millimetres per pixel, when the sensor has a scale.
    pub fn mm_per_px(&self) -> Option<f64> {
        self.scale.map(|s| s.mm_per_px)
    }
}

/// Errors from building a calibration.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationError {
    /// No frames given.
    #[error("no calibration frames given")]
    NoFrames,
    /// A frame of another size than the first.
    #[error("frame {frame}: expected {expected_w}×{expected_h} like the first frame, got {got_w}×{got_h}")]
    SizeMismatch {
        /// The frame's id.
        frame: String,
        /// Width of the first frame.
        expected_w: usize,
        /// Height of the first frame.
        expected_h: usize,
        /// Width found.
        got_w: usize,
        /// Height found.
        got_h: usize,
    },
    /// Invalid settings.
    #[error("invalid settings: {0}")]
    Config(#[from] crate::ConfigError),
    /// An image buffer that does not hold its size's pixels.
    #[error(transparent)]
    Image(#[from] visuotact_image::ImageError),
    /// No marker passed the filter.
    #[error("no markers found in the reference image (threshold {threshold}; {raw} blobs before the area/border filter)")]
    NoMarkers {
        /// Threshold description.
        threshold: String,
        /// Blobs before filtering.
        raw: usize,
    },
    /// Numbering failed, or the requested layout does not fit.
    #[error("could not number the markers: {0}")]
    Layout(#[from] LayoutError),
    /// No frame qualifies as one of the lightest.
    #[error("{0}")]
    Lightest(String),
}

/// What calibration saw, for the user.
#[derive(Clone, Debug, Default)]
pub struct CalibrationReport {
    /// Blobs found in the reference before filtering.
    pub raw_blobs: usize,
    /// Blobs that passed the filter.
    pub candidate_blobs: usize,
    /// Blobs left out because they are not on the marker lattice.
    pub off_grid: Vec<(f64, f64)>,
    /// The layout recognised or used.
    pub layout: Layout,
    /// Per calibration frame, the markers not found in it.
    pub missing_per_frame: Vec<(String, usize)>,
    /// Global threshold level used on the reference, if global.
    pub level: Option<u8>,
}

/// The mean of `frames` in the detector's working channel, rounded.
fn mean_frame(
    frames: &[(&str, &RgbImage)],
    detector: &DetectorConfig,
    (w, h): (usize, usize),
) -> Result<GrayImage, CalibrationError> {
    // Mean of the frames in the working channel.
    let mut sum = vec![0u32; w * h];
    let mut gray = GrayImage::new(0, 0);
    for &(id, img) in frames {
        same_size(id, img, (w, h))?;
        gray_from_rgb_into(
            img,
            detector.preprocess.channel,
            detector.preprocess.invert,
            &mut gray,
        );
        sum.iter_mut()
            .zip(gray.as_slice())
            .for_each(|(s, &v)| *s += u32::from(v));
    }
    let n = frames.len() as u32;
    GrayImage::from_vec(
        w,
        h,
        sum.iter().map(|&s| ((2 * s + n) / (2 * n)) as u8).collect(),
    )
    .map_err(CalibrationError::Image)
}

/// Markers are alike in size: interior blobs under a fifth of the median interior area, and
/// under a fifth of the median of the six blobs nearest them, are specks, not markers (border
/// blobs are cut markers and may be any size). A reference in contact squeezes a crease of
/// markers to slivers: such a sliver is judged beside its squeezed neighbours (test
/// `markers_a_crease_squeezes_to_slivers_are_markers_not_specks`).
fn drop_specks(blobs: &mut Vec<Blob>) {
    let Some(median) = interior_median_area(blobs, 1) else {
        return;
    };
    let floor = median / 5;
    let kept: Vec<Blob> = (0..blobs.len())
        .filter(|&k| {
            let b = &blobs[k];
            b.touches_border
                || b.area_px >= floor
                || f64::from(b.area_px) >= nearby_area(blobs, k) / 5.0
        })
        .map(|k| blobs[k])
        .collect();
    *blobs = kept;
}

/// The median area of the blobs not touching the border, when there are at least `least`.
fn interior_median_area(blobs: &[Blob], least: usize) -> Option<u32> {
    let mut interior: Vec<u32> = blobs
        .iter()
        .filter(|b| !b.touches_border)
        .map(|b| b.area_px)
        .collect();
    if interior.len() < least.max(1) {
        return None;
    }
    interior.sort_unstable();
    Some(interior[interior.len() / 2])
}

/// The two halves of each blob that may be two markers touching at rest (a reference frame in
/// contact squeezes neighbours together): a blob nearer twice a marker's area than once or four
/// times (in ratio) whose largest variance puts the centres of two discs of half its area
/// between three quarters of a diameter and one and a half diameters apart. A marker's area is
/// the median interior blob's, or the median of the six blobs nearest it: a contact squeezes a
/// crease of markers to slivers, and two slivers merged there are one whole marker's area. One
/// round blob of that area puts the discs half a diameter apart, two touching discs one
/// diameter; a blob longer than two discs can span is a marker with a tail. Each half is a disc
/// of half the area centred where the moments put it ([`Blob::two_discs`], as the tracker
/// splits a merged pair; its box the whole blob's). Returns the blob's index and its halves.
fn touching_pairs(blobs: &[Blob]) -> Vec<(usize, [Blob; 2])> {
    let Some(one) = interior_median_area(blobs, 3).map(f64::from) else {
        return Vec::new();
    };
    let pi = std::f64::consts::PI;
    let about_two = |a: f64, one: f64| {
        (std::f64::consts::SQRT_2 * one..=2.0 * std::f64::consts::SQRT_2 * one).contains(&a)
    };
    let mut pairs = Vec::new();
    for (k, b) in blobs.iter().enumerate() {
        let a = f64::from(b.area_px);
        if b.touches_border {
            continue;
        }
        let diameter = 2.0 * (0.5 * a / pi).sqrt();
        let Some((d, u)) = b.two_discs(0.5 * a, 0.5 * a) else {
            continue;
        };
        // The shape first: the neighbours' areas are looked up only for a blob shaped as two.
        if !(0.75 * diameter..=1.5 * diameter).contains(&d)
            || !(about_two(a, one) || about_two(a, nearby_area(blobs, k)))
        {
            continue;
        }
        let var = 0.5 * a / (4.0 * pi);
        let half = |s: f64| Blob {
            area_px: ((0.5 * a).round() as u32).max(1),
            x_px: b.x_px + s * d * u.0,
            y_px: b.y_px + s * d * u.1,
            mu20_px2: var,
            mu11_px2: 0.0,
            mu02_px2: var,
            bbox: b.bbox,
            touches_border: false,
        };
        pairs.push((k, [half(-0.5), half(0.5)]));
    }
    pairs
}

/// The median area of the six blobs nearest blob `k` (of fewer where there are fewer; its own
/// where it is alone).
fn nearby_area(blobs: &[Blob], k: usize) -> f64 {
    let b = &blobs[k];
    let mut near: Vec<(f64, u32)> = blobs
        .iter()
        .enumerate()
        .filter(|&(j, _)| j != k)
        .map(|(_, o)| ((o.x_px - b.x_px).hypot(o.y_px - b.y_px), o.area_px))
        .collect();
    near.sort_unstable_by(|p, q| p.0.total_cmp(&q.0));
    near.truncate(6);
    let mut areas: Vec<u32> = near.iter().map(|p| p.1).collect();
    areas.sort_unstable();
    areas
        .get(areas.len() / 2)
        .map_or(f64::from(b.area_px), |&a| f64::from(a))
}

/// Splits the blobs of two touching markers ([`touching_pairs`]) where the lattice agrees: a
/// split is kept when both halves are numbered and the numbering gains one marker for it
/// (the pair sat on two lattice sites); otherwise the blob stays whole. The lattice is the
/// judge: the numbering with the splits must be a grid or a hexagonal array, as the one without
/// them, or where a merged pair kept the array from being numbered as one, irregular.
fn split_touching_pairs(
    blobs: &mut Vec<Blob>,
    numbered: &mut Ordered,
    layout: LayoutChoice,
    convention: MomentConvention,
    report: &mut CalibrationReport,
) {
    let lattice = |l: Layout| matches!(l, Layout::Hex | Layout::Grid);
    if !matches!(
        numbered.layout,
        Layout::Hex | Layout::Grid | Layout::Irregular
    ) {
        return;
    }
    let mut pairs = touching_pairs(blobs);
    let numbered_has = |o: &Ordered, b: &Blob| {
        o.blobs
            .iter()
            .any(|(n, _, _)| n.x_px == b.x_px && n.y_px == b.y_px)
    };
    // At most two rounds: all candidates, then those whose halves were both numbered.
    for _ in 0..2 {
        if pairs.is_empty() {
            return;
        }
        let split: Vec<Blob> = blobs
            .iter()
            .enumerate()
            .filter(|(k, _)| !pairs.iter().any(|(p, _)| p == k))
            .map(|(_, b)| *b)
            .chain(pairs.iter().flat_map(|(_, h)| h.iter().copied()))
            .collect();
        let mut trial_report = CalibrationReport::default();
        let Ok(trial) = number_blobs(&split, layout, convention, &mut trial_report) else {
            return;
        };
        let kept: Vec<(usize, [Blob; 2])> = pairs
            .iter()
            .filter(|(_, h)| h.iter().all(|b| numbered_has(&trial, b)))
            .copied()
            .collect();
        if kept.len() == pairs.len() {
            let same = trial.layout == numbered.layout || numbered.layout == Layout::Irregular;
            if lattice(trial.layout)
                && same
                && trial.blobs.len() >= numbered.blobs.len() + kept.len()
            {
                *blobs = split;
                *numbered = trial;
                report.off_grid = trial_report.off_grid;
            }
            return;
        }
        pairs = kept;
    }
}

/// The blobs numbered by `layout`: concentric annuli in ring order, else by the layout found
/// (the blobs off it listed in `report`).
fn number_blobs(
    blobs: &[Blob],
    layout: LayoutChoice,
    convention: MomentConvention,
    report: &mut CalibrationReport,
) -> Result<Ordered, CalibrationError> {
    let annuli = annuli_share_centres(blobs);
    let rings = match layout {
        LayoutChoice::Auto => annuli,
        LayoutChoice::Only(Layout::Rings) if !annuli => {
            let pts: Vec<(f64, f64)> = blobs.iter().map(|b| (b.x_px, b.y_px)).collect();
            let seen =
                number_markers(&pts, LayoutChoice::Auto).map_or(Layout::Irregular, |n| n.layout);
            return Err(LayoutError::DoesNotFit {
                layout: Layout::Rings,
                why: format!("no two of the {} blobs share a centre", blobs.len()),
                seen,
            }
            .into());
        }
        LayoutChoice::Only(l) => l == Layout::Rings,
    };
    Ok(if rings {
        rings_order(blobs, convention)
    } else {
        let pts: Vec<(f64, f64)> = blobs.iter().map(|b| (b.x_px, b.y_px)).collect();
        let num = number_markers(&pts, layout)?;
        report.off_grid = num.left_out.iter().map(|&i| pts[i]).collect();
        Ordered {
            layout: num.layout,
            blobs: num
                .order
                .iter()
                .zip(&num.row_col)
                .map(|(&i, &(r, c))| (blobs[i], r, c))
                .collect(),
            rows: num.rows,
            cols: num.cols,
            pitch_px: num.pitch_px,
            neighbours: num.neighbours,
        }
    })
}

/// The blobs of a lattice numbering that are specks, not markers: each hangs on the array by
/// fewer neighbours than a corner of the array has (a grid's corner two, a hexagonal array's
/// three) and has under half its neighbours' mean area
/// (markers side by side have about one size). A speck beyond the array can still land on a
/// free lattice site: the rim of a TacTip in one in-contact frame (12 px² beside a 37 px² pin),
/// a glint above the real 331-pin array (24 px² beside 120 px² pins).
fn specks_of(numbered: &Ordered) -> Vec<Blob> {
    let corner = match numbered.layout {
        Layout::Hex => 3,
        Layout::Grid => 2,
        _ => return Vec::new(),
    };
    numbered
        .neighbours
        .iter()
        .zip(&numbered.blobs)
        .filter_map(|(nb, (b, _, _))| {
            let around: u32 = nb
                .iter()
                .map(|&k| numbered.blobs[k as usize].0.area_px)
                .sum();
            let small = 2 * b.area_px * (nb.len() as u32) < around;
            (!nb.is_empty() && nb.len() < corner && small).then_some(*b)
        })
        .collect()
}

/// A hexagonal numbering's left-out blobs that are pins it skipped
/// ([`SensorCalibration::unnumbered`]): not cut by the border, and where a pin of the array
/// can be that no numbered pin already is —
/// - no numbered pin within three quarters of the pins' spacing there (a pin's site is a
///   spacing from its neighbours; a piece of a pin, or a speck in the middle of a lattice
///   triangle, 0.58 spacings from its corners, lies nearer);
/// - numbered pins all around within 1.6 pitches: no gap of half a turn between their
///   directions (a blob beside the array, a screw or a glint past its rim, is no pin of it);
/// - an area within a factor of four of those pins' median (not a speck, not a glare).
fn unnumbered_of(blobs: &[Blob], numbered: &Ordered) -> Vec<(f64, f64, f64)> {
    if numbered.layout != Layout::Hex {
        return Vec::new();
    }
    let left_out: Vec<&Blob> = blobs
        .iter()
        .filter(|b| {
            !b.touches_border
                && !numbered
                    .blobs
                    .iter()
                    .any(|(n, _, _)| n.x_px == b.x_px && n.y_px == b.y_px)
        })
        .collect();
    if left_out.is_empty() {
        return Vec::new();
    }
    let pins: Vec<(f64, f64)> = numbered
        .blobs
        .iter()
        .map(|(b, _, _)| (b.x_px, b.y_px))
        .collect();
    // Each pin's spacing: the distance to its nearest pin (a dome's pitch varies across the
    // image, a crease squeezes it).
    let spacing: Vec<f64> = k_nearest_all(&pins, 1)
        .iter()
        .map(|v| v.first().map_or(f64::NAN, |x| x.1))
        .collect();
    let is_pin = |b: &Blob| {
        let dist = |k: usize| (pins[k].0 - b.x_px).hypot(pins[k].1 - b.y_px);
        let near: Vec<usize> = (0..pins.len())
            .filter(|&k| dist(k) < 1.6 * numbered.pitch_px)
            .collect();
        if near.len() < 3 {
            return false;
        }
        let local_spacing = median(&mut near.iter().map(|&k| spacing[k]).collect::<Vec<_>>());
        let nearest = near.iter().map(|&k| dist(k)).fold(f64::INFINITY, f64::min);
        let mut angles: Vec<f64> = near
            .iter()
            .map(|&k| (pins[k].1 - b.y_px).atan2(pins[k].0 - b.x_px))
            .collect();
        angles.sort_by(f64::total_cmp);
        let turn = std::f64::consts::TAU;
        let widest = angles
            .windows(2)
            .map(|w| w[1] - w[0])
            .fold(angles[0] + turn - angles[angles.len() - 1], f64::max);
        let mut areas: Vec<f64> = near
            .iter()
            .map(|&k| f64::from(numbered.blobs[k].0.area_px))
            .collect();
        let area = f64::from(b.area_px) / median(&mut areas);
        nearest >= 0.75 * local_spacing && widest < 0.5 * turn && (0.25..=4.0).contains(&area)
    };
    left_out
        .into_iter()
        .filter(|b| is_pin(b))
        .map(|b| (b.x_px, b.y_px, f64::from(b.area_px)))
        .collect()
}

/// The reference markers of numbered blobs (jitter still unknown).
fn reference_markers(numbered: &Ordered, convention: MomentConvention) -> Vec<ReferenceMarker> {
    numbered
        .blobs
        .iter()
        .zip(&numbered.neighbours)
        .enumerate()
        .map(|(k, ((b, r, c), nb))| {
            let s = b.shape(convention);
            ReferenceMarker {
                id: k as u32,
                row: *r,
                col: *c,
                x_px: b.x_px,
                y_px: b.y_px,
                area_px: f64::from(b.area_px),
                eccentricity: s.eccentricity,
                major_axis_px: s.major_axis_px,
                minor_axis_px: s.minor_axis_px,
                touches_border: b.touches_border,
                jitter_px: None,
                neighbours: nb.clone(),
            }
        })
        .collect()
}

/// Jitter: tracks each still frame against the mean reference (major axes as tracked); each
/// marker's RMS distance from its mean position, and the markers missing per frame.
fn measure_jitter(
    frames: &[(&str, &RgbImage)],
    det: &mut Detector,
    cal: &mut SensorCalibration,
    report: &mut CalibrationReport,
) {
    let reference = track_reference(cal);
    let markers = &mut cal.markers;
    let mut blobs = Vec::new();
    let mut sq = vec![0.0f64; markers.len()];
    let mut cnt = vec![0u32; markers.len()];
    for &(id, img) in frames {
        det.detect_into(img, &mut blobs);
        let t = track(&reference, &blobs, &cal.track);
        let mut missing = 0;
        for (i, a) in t.assignment.iter().enumerate() {
            match a {
                Some(j) => {
                    let b = &blobs[*j];
                    sq[i] +=
                        (b.x_px - markers[i].x_px).powi(2) + (b.y_px - markers[i].y_px).powi(2);
                    cnt[i] += 1;
                }
                None => missing += 1,
            }
        }
        if missing > 0 {
            report.missing_per_frame.push((id.to_string(), missing));
        }
    }
    for (m, (s, c)) in markers.iter_mut().zip(sq.iter().zip(&cnt)) {
        m.jitter_px = (*c > 0).then(|| (s / f64::from(*c)).sqrt());
    }
}

/// Builds a calibration from still frames `(id, image)`.
pub fn calibrate<'a, I>(
    frames: I,
    cfg: &CalibrationConfig,
) -> Result<(SensorCalibration, CalibrationReport), CalibrationError>
where
    I: IntoIterator<Item = (&'a str, &'a RgbImage)>,
{
    let detector = cfg.detector.clone();
    let frames: Vec<(&str, &RgbImage)> = frames.into_iter().collect();
    let Some(&(_, first)) = frames.first() else {
        return Err(CalibrationError::NoFrames);
    };
    let (w, h) = (first.width(), first.height());
    let mut det = Detector::new(detector.clone()).map_err(CalibrationError::Config)?;
    let mean = mean_frame(&frames, &detector, (w, h))?;
    let mut blobs = Vec::new();
    let detection = det.detect_gray_into(&mean, &mut blobs);
    if blobs.is_empty() {
        return Err(CalibrationError::NoMarkers {
            threshold: detection
                .level
                .map_or("adaptive".to_string(), |t| format!("level {t}")),
            raw: detection.raw_count,
        });
    }
    drop_specks(&mut blobs);
    let convention = MomentConvention::Pixel;
    let mut report = CalibrationReport {
        raw_blobs: detection.raw_count,
        candidate_blobs: blobs.len(),
        level: detection.level,
        ..Default::default()
    };
    let mut numbered = number_blobs(&blobs, cfg.layout, convention, &mut report)?;
    split_touching_pairs(
        &mut blobs,
        &mut numbered,
        cfg.layout,
        convention,
        &mut report,
    );
    let specks = specks_of(&numbered);
    if !specks.is_empty() {
        blobs.retain(|b| !specks.iter().any(|s| s.x_px == b.x_px && s.y_px == b.y_px));
        numbered = number_blobs(&blobs, cfg.layout, convention, &mut report)?;
        report
            .off_grid
            .extend(specks.iter().map(|b| (b.x_px, b.y_px)));
    }
    report.layout = numbered.layout;
    let (layout, pitch) = (numbered.layout, numbered.pitch_px);
    let mut cal = SensorCalibration {
        format: SENSOR_FORMAT.to_string(),
        version: SENSOR_VERSION,
        image_width: w,
        image_height: h,
        detector,
        layout,
        moment_convention: convention,
        track: cfg.track,
        features: cfg.features,
        reference_frames: frames.iter().map(|(id, _)| id.to_string()).collect(),
        reference: ReferenceInfo::still(),
        grid_rows: numbered.rows,
        grid_cols: numbered.cols,
        pitch_px: pitch,
        markers: reference_markers(&numbered, convention),
        marker_size: None,
        scale: None,
        unnumbered: unnumbered_of(&blobs, &numbered),
    };
    measure_jitter(&frames, &mut det, &mut cal, &mut report);
    Ok((cal, report))
}

/// Refuses a frame of another size than the first.
fn same_size(id: &str, img: &RgbImage, (w, h): (usize, usize)) -> Result<(), CalibrationError> {
    if (img.width(), img.height()) == (w, h) {
        return Ok(());
    }
    Err(CalibrationError::SizeMismatch {
        frame: id.to_string(),
        expected_w: w,
        expected_h: h,
        got_w: img.width(),
        got_h: img.height(),
    })
}

/// Reference blobs in numbering order with their `(row, col)`, and the layout's figures.
struct Ordered {
    layout: Layout,
    blobs: Vec<(Blob, u32, u32)>,
    rows: u32,
    cols: u32,
    pitch_px: f64,
    neighbours: Vec<Vec<u32>>,
}

/// Concentric annuli, smallest first; the pitch is the smallest gap between ring radii and each
/// annulus neighbours the next smaller and larger one.
fn rings_order(blobs: &[Blob], convention: MomentConvention) -> Ordered {
    let mut b = blobs.to_vec();
    let major = |x: &Blob| x.shape(convention).major_axis_px;
    b.sort_by(|a, c| major(a).total_cmp(&major(c)));
    let pitch_px = if b.len() > 1 {
        b.windows(2)
            .map(|p| 0.5 * (major(&p[1]) - major(&p[0])))
            .fold(f64::INFINITY, f64::min)
            .max(1.0)
    } else {
        major(&b[0]).max(1.0)
    };
    let n = b.len() as u32;
    Ordered {
        layout: Layout::Rings,
        neighbours: (0..n)
            .map(|k| {
                [k.checked_sub(1), (k + 1 < n).then_some(k + 1)]
                    .into_iter()
                    .flatten()
                    .collect()
            })
            .collect(),
        blobs: b
            .into_iter()
            .enumerate()
            .map(|(k, bl)| (bl, 0, k as u32))
            .collect(),
        rows: 1,
        cols: n,
        pitch_px,
    }
}

/// The tracker's view of a sensor's reference markers: positions, areas and how loosely the
/// markers not cut by the border fill their moments' ellipse
/// ([`TrackReference::fill_sigma`]).
pub fn track_reference(cal: &SensorCalibration) -> TrackReference {
    let (markers, pitch_px, layout) = (&cal.markers, cal.pitch_px, cal.layout);
    let mut positions: Vec<(f64, f64)> = markers.iter().map(|m| (m.x_px, m.y_px)).collect();
    let mut areas_px: Vec<f64> = markers.iter().map(|m| m.area_px).collect();
    // An unseen site's pin is expected at the markers' median area.
    let unseen_area_px = median(&mut areas_px.clone());
    let steps = layout.row_col_steps();
    let mut sites: Vec<(i64, i64)> = markers
        .iter()
        .map(|m| (i64::from(m.row), i64::from(m.col)))
        .collect();
    // The unnumbered pins, followed after the markers: each at a site of its own far off the
    // lattice (no step reaches it), and no site is unseen where one of them lies.
    for (k, &(x, y, area)) in cal.unnumbered.iter().enumerate() {
        positions.push((x, y));
        areas_px.push(area);
        sites.push((i64::MIN / 4 - 16 * k as i64, 0));
    }
    // A numbered array's sites where the reference (taken in contact) saw no pin.
    let unseen = if steps.is_empty() {
        Vec::new()
    } else {
        unseen_sites(&sites, &positions, steps)
    };
    sites.extend(unseen.iter().map(|u| u.0));
    let unseen_px: Vec<(f64, f64)> = unseen.iter().map(|u| u.1).collect();
    let mut r = TrackReference::with_unseen(positions, areas_px, &unseen_px, unseen_area_px);
    r.set_unnumbered(cal.unnumbered.len());
    // The axes are 4·√λ in the file's convention; the fill counts each pixel as a unit square.
    let square = match cal.moment_convention {
        MomentConvention::Pixel => 1.0 / 12.0,
        MomentConvention::Matlab => 0.0,
    };
    r.fill_sigma = fill_sigma_from_rest(markers.iter().filter(|m| !m.touches_border).map(|m| {
        let l1 = (m.major_axis_px / 4.0).powi(2) + square;
        let l2 = (m.minor_axis_px / 4.0).powi(2) + square;
        (m.area_px, l1 * l2)
    }));
    if layout == Layout::Hex {
        // The pin array's six neighbours per pin, as numbered (grids keep their geometric
        // steps: the numbering changed nothing there but some slip grasps' readings).
        r.take_lattice(&sites, steps);
    }
    if layout == Layout::Rings {
        // Concentric rings share a centre: they are told apart by size.
        r.ring_sizes_px = Some(markers.iter().map(|m| m.major_axis_px).collect());
        if pitch_px > 0.0 {
            r.pitch_px = pitch_px;
        }
    }
    r
}

/// Most markers a sensor file may list: far beyond any published sensor (a 331-pin TacTip,
/// a few thousand random dots), and a bound on the tracker's work per frame.
pub const MAX_MARKERS: usize = 100_000;

/// Why a sensor file does not load.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{source_name}: {why}")]
pub struct SensorFileError {
    /// The file (or what the text came from).
    pub source_name: String,
    /// What is wrong with it.
    pub why: String,
}

impl SensorCalibration {
    /// Parses a sensor file's text; `source` names it in errors.
    pub fn from_json(text: &str, source: &str) -> Result<Self, SensorFileError> {
        let bad = |why: String| SensorFileError {
            source_name: source.to_string(),
            why,
        };
        let cal: SensorCalibration =
            serde_json::from_str(text).map_err(|e| bad(format!("not a sensor file: {e}")))?;
        if cal.format != SENSOR_FORMAT {
            return Err(bad(format!(
                "format is {:?}, expected {SENSOR_FORMAT:?}",
                cal.format
            )));
        }
        if cal.version > SENSOR_VERSION {
            return Err(bad(format!(
                "sensor file version {} is newer than this program reads ({SENSOR_VERSION})",
                cal.version
            )));
        }
        if cal.markers.is_empty() {
            return Err(bad("the sensor file lists no markers".to_string()));
        }
        let n = cal.markers.len();
        if n > MAX_MARKERS {
            return Err(bad(format!(
                "{n} markers: over the limit of {MAX_MARKERS} a sensor"
            )));
        }
        let mut ids = std::collections::HashSet::with_capacity(n);
        for m in &cal.markers {
            if !ids.insert(m.id) {
                return Err(bad(format!("marker id {} is listed twice", m.id)));
            }
            if let Some(k) = m.neighbours.iter().find(|&&k| k as usize >= n) {
                return Err(bad(format!(
                    "marker {} names neighbour {k}, but the file lists {n} markers",
                    m.id
                )));
            }
        }
        let (w, h) = (cal.image_width, cal.image_height);
        if !(1..=100_000).contains(&w) || !(1..=100_000).contains(&h) {
            return Err(bad(format!(
                "image size {w}×{h}: expected 1 to 100 000 pixels each way"
            )));
        }
        if !(cal.pitch_px.is_finite() && cal.pitch_px > 0.0) {
            return Err(bad(format!("pitch_px {} must be positive", cal.pitch_px)));
        }
        if let Some(why) = cal.scale.and_then(PixelScale::invalid) {
            return Err(bad(why));
        }
        let outside = |m: &ReferenceMarker| {
            !(m.area_px.is_finite()
                && (-1.0..=w as f64).contains(&m.x_px)
                && (-1.0..=h as f64).contains(&m.y_px))
        };
        if let Some(m) = cal.markers.iter().find(|m| outside(m)) {
            return Err(bad(format!(
                "marker {} at ({}, {}) lies outside the {w}×{h} image",
                m.id, m.x_px, m.y_px
            )));
        }
        cal.detector
            .preprocess
            .validate()
            .map_err(|e| bad(e.to_string()))?;
        if let Some(r) = cal.detector.preprocess.roi {
            if r.x.saturating_add(r.width) > w || r.y.saturating_add(r.height) > h {
                return Err(bad(format!(
                    "region of interest {}×{} at ({}, {}) reaches outside the {w}×{h} image",
                    r.width, r.height, r.x, r.y
                )));
            }
        }
        cal.track.validate().map_err(|e| bad(e.to_string()))?;
        Ok(cal)
    }

    /// The layout found, in words (`9 rows × 13 columns`, `2 concentric rings`).
    pub fn layout_in_words(&self) -> String {
        match self.layout {
            Layout::Rings => format!("{} concentric rings", self.markers.len()),
            Layout::Irregular => "irregular pattern".to_string(),
            Layout::DotRings => format!("{} rings of dots", self.grid_rows),
            Layout::Hex => format!("hexagonal, {} rows", self.grid_rows),
            Layout::Grid => format!("{} rows × {} columns", self.grid_rows, self.grid_cols),
        }
    }

    /// The JSON text of the file.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default()
    }
}

/// The lightest frames of a data set, for a reference when no frame is free of contact.
#[derive(Clone, Debug, PartialEq)]
pub struct LightestSelection {
    /// Ids of the chosen frames, lightest first.
    pub chosen: Vec<String>,
    /// Each chosen frame's RMS marker distance from the rest estimate, pixels.
    pub deformation_px: Vec<f64>,
    /// Frames looked at.
    pub considered: usize,
    /// Frames in which at least 90 % of the markers were tracked (the candidates).
    pub usable: usize,
    /// Median deformation over the usable frames, pixels.
    pub median_deformation_px: f64,
    /// RMS over the markers of the chosen frames' mean position's distance from the rest
    /// estimate, pixels: the contact the reference still holds.
    pub residual_px: f64,
    /// The largest single marker's such distance, pixels.
    pub residual_max_px: f64,
}

impl LightestSelection {
    /// What was chosen and how still it is, in words.
    pub fn in_words(&self) -> String {
        format!(
            "the {} lightest of {} frames ({} usable): their deformation {:.3}–{:.3} px RMS (median frame {:.3} px); residual motion of the reference {:.3} px RMS, {:.3} px at worst",
            self.chosen.len(),
            self.considered,
            self.usable,
            self.deformation_px.first().copied().unwrap_or(0.0),
            self.deformation_px.last().copied().unwrap_or(0.0),
            self.median_deformation_px,
            self.residual_px,
            self.residual_max_px,
        )
    }

    /// The provenance a reference from these frames carries: under contact when some marker is
    /// over a quarter pixel from its rest estimate (more than tracking noise).
    pub fn reference_info(&self) -> ReferenceInfo {
        ReferenceInfo {
            method: "lightest".to_string(),
            frames_considered: self.considered,
            residual_px: Some(self.residual_px),
            residual_max_px: Some(self.residual_max_px),
            under_contact: self.residual_max_px > 0.25,
        }
    }
}

/// Each marker's rest position: the median of its tracked positions over the frames.
fn rest_positions(tracked: &[Vec<Option<(f64, f64)>>], m: usize) -> Vec<Option<(f64, f64)>> {
    (0..m)
        .map(|i| {
            let mut xs: Vec<f64> = tracked.iter().filter_map(|t| t[i].map(|p| p.0)).collect();
            let mut ys: Vec<f64> = tracked.iter().filter_map(|t| t[i].map(|p| p.1)).collect();
            (!xs.is_empty()).then(|| (median(&mut xs), median(&mut ys)))
        })
        .collect()
}

/// Each frame's RMS distance of its markers from rest, with the frame's index, for frames
/// with 90 % of the `m` markers tracked.
fn deformations(
    tracked: &[Vec<Option<(f64, f64)>>],
    rest: &[Option<(f64, f64)>],
    m: usize,
) -> Vec<(f64, usize)> {
    tracked
        .iter()
        .enumerate()
        .filter_map(|(k, t)| {
            let (mut sq, mut c) = (0.0, 0usize);
            for (p, r) in t.iter().zip(rest) {
                if let (Some(p), Some(r)) = (p, r) {
                    sq += (p.0 - r.0).powi(2) + (p.1 - r.1).powi(2);
                    c += 1;
                }
            }
            (10 * c >= 9 * m).then(|| ((sq / c as f64).sqrt(), k))
        })
        .collect()
}

/// The chosen frames' mean position per marker against the rest estimate: RMS and worst.
fn residual(
    tracked: &[Vec<Option<(f64, f64)>>],
    rest: &[Option<(f64, f64)>],
    chosen: &[(f64, usize)],
) -> (f64, f64) {
    let (mut sq, mut c, mut worst) = (0.0, 0usize, 0.0f64);
    for (i, r) in rest.iter().enumerate() {
        let Some(r) = r else { continue };
        let ps: Vec<(f64, f64)> = chosen.iter().filter_map(|&(_, k)| tracked[k][i]).collect();
        if ps.is_empty() {
            continue;
        }
        let k = ps.len() as f64;
        let mx = ps.iter().map(|p| p.0).sum::<f64>() / k;
        let my = ps.iter().map(|p| p.1).sum::<f64>() / k;
        let d2 = (mx - r.0).powi(2) + (my - r.1).powi(2);
        sq += d2;
        c += 1;
        worst = worst.max(d2.sqrt());
    }
    (if c > 0 { (sq / c as f64).sqrt() } else { 0.0 }, worst)
}

/// Finds the lightest frames of a data set in one pass over its frames (only their blobs are
/// kept): [`LightestFinder::add`] every frame, then [`LightestFinder::choose`].
#[derive(Debug)]
pub struct LightestFinder {
    detector: Detector,
    track: TrackParams,
    frames: Vec<(String, Vec<Blob>)>,
    size: Option<(usize, usize)>,
}

impl LightestFinder {
    /// A finder detecting markers as `cfg` says.
    pub fn new(cfg: &CalibrationConfig) -> Result<Self, CalibrationError> {
        Ok(Self {
            detector: Detector::new(cfg.detector.clone()).map_err(CalibrationError::Config)?,
            track: cfg.track,
            frames: Vec::new(),
            size: None,
        })
    }

    /// Detects the markers of one frame and keeps them.
    pub fn add(&mut self, id: &str, img: &RgbImage) -> Result<(), CalibrationError> {
        let (w, h) = *self.size.get_or_insert((img.width(), img.height()));
        same_size(id, img, (w, h))?;
        let mut blobs = Vec::new();
        self.detector.detect_into(img, &mut blobs);
        self.frames.push((id.to_string(), blobs));
        Ok(())
    }

    /// Chooses the `n` lightest frames: every frame is tracked against a provisional reference
    /// (the frame with the most markers, short of the 10 % with the most blobs), each marker's
    /// median position over all frames is its rest estimate, and the frames whose markers lie
    /// closest to it (RMS) are chosen.
    pub fn choose(&self, n: usize) -> Result<LightestSelection, CalibrationError> {
        let fail = |m: String| Err(CalibrationError::Lightest(m));
        if n == 0 {
            return fail("choose at least 1 frame".to_string());
        }
        if self.frames.len() < n {
            return fail(format!(
                "{} frames given, {n} asked for: the lightest frames must be a subset",
                self.frames.len()
            ));
        }
        let mut counts: Vec<usize> = self.frames.iter().map(|f| f.1.len()).collect();
        counts.sort_unstable();
        let cap = counts[(counts.len() * 9 / 10).min(counts.len() - 1)];
        let boot = (0..self.frames.len())
            .filter(|&k| self.frames[k].1.len() <= cap)
            .max_by_key(|&k| (self.frames[k].1.len(), usize::MAX - k))
            .unwrap_or(0);
        let boot_blobs = &self.frames[boot].1;
        if boot_blobs.len() < 2 {
            return fail(format!(
                "frame {}: {} markers found; cannot build a reference",
                self.frames[boot].0,
                boot_blobs.len()
            ));
        }
        let reference = TrackReference::new(
            boot_blobs.iter().map(|b| (b.x_px, b.y_px)).collect(),
            boot_blobs.iter().map(|b| f64::from(b.area_px)).collect(),
        );
        let m = boot_blobs.len();
        // Every frame on its own: tracked in parallel.
        let tracked: Vec<Vec<Option<(f64, f64)>>> = self
            .frames
            .par_iter()
            .map(|(_, blobs)| {
                track(&reference, blobs, &self.track)
                    .assignment
                    .iter()
                    .map(|a| a.map(|j| (blobs[j].x_px, blobs[j].y_px)))
                    .collect()
            })
            .collect();
        let rest = rest_positions(&tracked, m);
        let mut scored = deformations(&tracked, &rest, m);
        let usable = scored.len();
        if usable < n {
            return fail(format!(
                "only {usable} of {} frames have 90 % of the {m} markers tracked; {n} needed",
                self.frames.len()
            ));
        }
        scored.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut all: Vec<f64> = scored.iter().map(|s| s.0).collect();
        let median_deformation_px = median(&mut all);
        let chosen = &scored[..n];
        let (residual_px, residual_max_px) = residual(&tracked, &rest, chosen);
        Ok(LightestSelection {
            chosen: chosen
                .iter()
                .map(|&(_, k)| self.frames[k].0.clone())
                .collect(),
            deformation_px: chosen.iter().map(|&(d, _)| d).collect(),
            considered: self.frames.len(),
            usable,
            median_deformation_px,
            residual_px,
            residual_max_px,
        })
    }
}
