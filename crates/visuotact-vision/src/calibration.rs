//! The sensor calibration: a no-contact reference built from still frames, markers numbered in
//! grid order, and every setting needed to measure later frames the same way. Saved as JSON.
//!
//! The reference image is the per-pixel mean of N still frames in the chosen channel (seed 001's
//! Calibration Data Model), on which markers are detected once; each still frame is then
//! tracked against it to measure each marker's jitter (RMS, pixels), the noise floor of the
//! displacement features.

use serde::{Deserialize, Serialize};
use visuotact_image::{GrayImage, RgbImage};

use crate::blobs::{Blob, MomentConvention};
use crate::detect::{Detector, DetectorConfig};
use crate::features::FeatureSet;
use crate::grid::{lattice_from_points, GridError, Layout};
use crate::preprocess::gray_from_rgb_into;
use crate::track::{track, TrackConfig, TrackReference};

/// Identifies sensor files.
pub const SENSOR_FORMAT: &str = "visuotact-sensor";
/// Current sensor file version.
pub const SENSOR_VERSION: u32 = 1;

/// One marker of the no-contact reference.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceMarker {
    /// Marker number in grid order (0-based); feature columns are named `m{id:03}_…`.
    pub id: u32,
    /// Grid row (0 = top).
    pub row: u32,
    /// Grid column (0 = left).
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
    pub track: TrackConfig,
    /// Default feature set for `extract`.
    pub features: FeatureSet,
    /// Ids of the frames averaged into the reference.
    pub reference_frames: Vec<String>,
    /// Grid rows spanned by the markers (1 for rings).
    pub grid_rows: u32,
    /// Grid columns spanned.
    pub grid_cols: u32,
    /// Typical spacing between neighbouring markers in pixels.
    pub pitch_px: f64,
    /// The reference markers in grid order.
    pub markers: Vec<ReferenceMarker>,
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
    Config(String),
    /// No marker passed the filter.
    #[error("no markers found in the reference image (threshold {threshold}; {raw} blobs before the area/border filter)")]
    NoMarkers {
        /// Threshold description.
        threshold: String,
        /// Blobs before filtering.
        raw: usize,
    },
    /// Grid recovery failed.
    #[error("could not number the markers: {0}")]
    Grid(#[from] GridError),
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
    /// Per calibration frame, the markers not found in it.
    pub missing_per_frame: Vec<(String, usize)>,
    /// Global threshold level used on the reference, if global.
    pub level: Option<u8>,
}

/// Builds a calibration from still frames `(id, image)`.
pub fn calibrate<'a, I>(
    frames: I,
    detector: DetectorConfig,
    layout: Layout,
    features: FeatureSet,
) -> Result<(SensorCalibration, CalibrationReport), CalibrationError>
where
    I: IntoIterator<Item = (&'a str, &'a RgbImage)>,
{
    let frames: Vec<(&str, &RgbImage)> = frames.into_iter().collect();
    let Some(&(_, first)) = frames.first() else {
        return Err(CalibrationError::NoFrames);
    };
    let (w, h) = (first.width(), first.height());
    let mut det = Detector::new(detector.clone()).map_err(CalibrationError::Config)?;
    // Mean of the frames in the working channel.
    let mut sum = vec![0u32; w * h];
    let mut gray = GrayImage::new(0, 0);
    for &(id, img) in &frames {
        if (img.width(), img.height()) != (w, h) {
            return Err(CalibrationError::SizeMismatch {
                frame: id.to_string(),
                expected_w: w,
                expected_h: h,
                got_w: img.width(),
                got_h: img.height(),
            });
        }
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
    let mean = GrayImage::from_vec(
        w,
        h,
        sum.iter().map(|&s| ((2 * s + n) / (2 * n)) as u8).collect(),
    )
    .map_err(|e| CalibrationError::Config(e.to_string()))?;
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
    // Markers are alike in size: interior blobs under a fifth of the median interior area are
    // specks, not markers (border blobs are cut markers and may be any size).
    let mut interior: Vec<u32> = blobs
        .iter()
        .filter(|b| !b.touches_border)
        .map(|b| b.area_px)
        .collect();
    if !interior.is_empty() {
        interior.sort_unstable();
        let floor = interior[interior.len() / 2] / 5;
        blobs.retain(|b| b.touches_border || b.area_px >= floor);
    }
    let convention = MomentConvention::Pixel;
    let mut report = CalibrationReport {
        raw_blobs: detection.raw_count,
        candidate_blobs: blobs.len(),
        level: detection.level,
        ..Default::default()
    };
    let (ordered, rows, cols, pitch): (Vec<(Blob, u32, u32)>, u32, u32, f64) = match layout {
        Layout::Rings => {
            let mut b = blobs.clone();
            b.sort_by(|a, c| {
                a.shape(convention)
                    .major_axis_px
                    .total_cmp(&c.shape(convention).major_axis_px)
            });
            let pitch = if b.len() > 1 {
                let mut gaps: Vec<f64> = b
                    .windows(2)
                    .map(|p| {
                        0.5 * (p[1].shape(convention).major_axis_px
                            - p[0].shape(convention).major_axis_px)
                    })
                    .collect();
                gaps.sort_by(f64::total_cmp);
                gaps[0].max(1.0)
            } else {
                b[0].shape(convention).major_axis_px.max(1.0)
            };
            let n = b.len() as u32;
            (
                b.into_iter()
                    .enumerate()
                    .map(|(k, bl)| (bl, 0, k as u32))
                    .collect(),
                1,
                n,
                pitch,
            )
        }
        Layout::Grid => {
            let pts: Vec<(f64, f64)> = blobs.iter().map(|b| (b.x_px, b.y_px)).collect();
            let lat = lattice_from_points(&pts)?;
            report.off_grid = lat.left_out.iter().map(|&i| pts[i]).collect();
            let ordered = lat
                .order
                .iter()
                .zip(&lat.row_col)
                .map(|(&i, &(r, c))| (blobs[i], r, c))
                .collect();
            (
                ordered,
                lat.rows,
                lat.cols,
                0.5 * (lat.pitch_x_px + lat.pitch_y_px),
            )
        }
    };
    let mut markers: Vec<ReferenceMarker> = ordered
        .iter()
        .enumerate()
        .map(|(k, (b, r, c))| {
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
            }
        })
        .collect();
    let mut cal = SensorCalibration {
        format: SENSOR_FORMAT.to_string(),
        version: SENSOR_VERSION,
        image_width: w,
        image_height: h,
        detector,
        layout,
        moment_convention: convention,
        track: TrackConfig::DEFAULT,
        features,
        reference_frames: frames.iter().map(|(id, _)| id.to_string()).collect(),
        grid_rows: rows,
        grid_cols: cols,
        pitch_px: pitch,
        markers: Vec::new(),
    };
    // Jitter: track each still frame against the mean reference (major axes as tracked).
    let reference = track_reference(&markers, pitch, layout);
    let mut sq = vec![0.0f64; markers.len()];
    let mut cnt = vec![0u32; markers.len()];
    for &(id, img) in &frames {
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
    cal.markers = markers;
    Ok((cal, report))
}

/// The tracker's view of a set of reference markers.
pub fn track_reference(
    markers: &[ReferenceMarker],
    pitch_px: f64,
    layout: Layout,
) -> TrackReference {
    let mut r = TrackReference::new(
        markers.iter().map(|m| (m.x_px, m.y_px)).collect(),
        markers.iter().map(|m| m.area_px).collect(),
    );
    if layout == Layout::Rings {
        // Concentric rings share a centre: they are told apart by size.
        r.ring_sizes_px = Some(markers.iter().map(|m| m.major_axis_px).collect());
        if pitch_px > 0.0 {
            r.pitch_px = pitch_px;
        }
    }
    r
}

impl SensorCalibration {
    /// Parses a sensor file's text; `source` names it in errors.
    pub fn from_json(text: &str, source: &str) -> Result<Self, String> {
        let cal: SensorCalibration =
            serde_json::from_str(text).map_err(|e| format!("{source}: not a sensor file: {e}"))?;
        if cal.format != SENSOR_FORMAT {
            return Err(format!(
                "{source}: format is {:?}, expected {SENSOR_FORMAT:?}",
                cal.format
            ));
        }
        if cal.version > SENSOR_VERSION {
            return Err(format!(
                "{source}: sensor file version {} is newer than this program reads ({SENSOR_VERSION})",
                cal.version
            ));
        }
        if cal.markers.is_empty() {
            return Err(format!("{source}: the sensor file lists no markers"));
        }
        cal.detector
            .preprocess
            .validate()
            .map_err(|e| format!("{source}: {e}"))?;
        Ok(cal)
    }

    /// The JSON text of the file.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default()
    }
}
