//! Feature vectors: per marker, differences from the no-contact reference, in named units.
//!
//! Columns come marker by marker in grid order, each marker's in the order `dx_px`, `dy_px`,
//! `darea_px`, `decc` (those selected): seed 000 uses area, x, y of 117 markers (351 inputs);
//! seed 001 x, y and eccentricity of the annuli. A marker that is not matched in a frame has
//! NaN in its cells (written empty in tables) and a status; other columns never move. A marker
//! split from a merged pair ([`MarkerStatus::Split`]) has its displacement and NaN area and
//! eccentricity.

use serde::{Deserialize, Serialize};
use visuotact_image::RgbImage;

use crate::blobs::Blob;
use crate::calibration::{track_reference, SensorCalibration};
use crate::detect::Detector;
use crate::track::{track_with, MarkerStatus, TrackHints, TrackReference, TrackResult, View};
use crate::ConfigError;

/// Which per-marker features to output.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FeatureSet {
    /// Displacement along x, pixels.
    pub dx: bool,
    /// Displacement along y, pixels.
    pub dy: bool,
    /// Area change, pixels.
    pub area: bool,
    /// Eccentricity change.
    pub eccentricity: bool,
}

visuotact_image::from_str_by_parse!(FeatureSet, ConfigError);

impl FeatureSet {
    /// Seed 000: area, x, y.
    pub const IATS: Self = Self {
        dx: true,
        dy: true,
        area: true,
        eccentricity: false,
    };
    /// Seed 001: x, y, eccentricity.
    pub const CONE: Self = Self {
        dx: true,
        dy: true,
        area: false,
        eccentricity: true,
    };
    /// Everything.
    pub const ALL: Self = Self {
        dx: true,
        dy: true,
        area: true,
        eccentricity: true,
    };

    /// Parses a comma-separated list of `x`, `y`, `area`, `ecc` (or `eccentricity`), or `all`.
    pub fn parse(s: &str) -> Result<Self, ConfigError> {
        let mut f = Self {
            dx: false,
            dy: false,
            area: false,
            eccentricity: false,
        };
        for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            match part {
                "x" | "dx" => f.dx = true,
                "y" | "dy" => f.dy = true,
                "area" => f.area = true,
                "ecc" | "eccentricity" => f.eccentricity = true,
                "all" => f = Self::ALL,
                other => {
                    return Err(ConfigError::unknown(
                        "feature",
                        other,
                        "a list of x, y, area, ecc (or all)",
                    ))
                }
            }
        }
        if f.per_marker() == 0 {
            return Err(ConfigError::NoFeatures);
        }
        Ok(f)
    }

    /// Features per marker.
    pub fn per_marker(&self) -> usize {
        usize::from(self.dx)
            + usize::from(self.dy)
            + usize::from(self.area)
            + usize::from(self.eccentricity)
    }

    /// Column suffixes in output order.
    pub fn suffixes(&self) -> Vec<&'static str> {
        let mut v = Vec::new();
        if self.dx {
            v.push("dx_px");
        }
        if self.dy {
            v.push("dy_px");
        }
        if self.area {
            v.push("darea_px");
        }
        if self.eccentricity {
            v.push("decc");
        }
        v
    }

    /// Column names for markers with these ids: `m017_dx_px`, …
    pub fn column_names(&self, ids: impl IntoIterator<Item = u32>) -> Vec<String> {
        let suffixes = self.suffixes();
        ids.into_iter()
            .flat_map(|id| suffixes.iter().map(move |s| format!("m{id:03}_{s}")))
            .collect()
    }
}

impl Default for FeatureSet {
    fn default() -> Self {
        Self::IATS
    }
}

pub use visuotact_image::{is_field_column, FIELD_COLUMNS, FIELD_COLUMNS_MM};

/// Pixel column suffixes with a length unit, their millimetre twins, and the power of the scale
/// that converts one into the other.
const MM_TWINS: [(&str, &str, i32); 3] = [
    ("_dx_px", "_dx_mm", 1),
    ("_dy_px", "_dy_mm", 1),
    ("_darea_px", "_darea_mm2", 2),
];

/// The millimetre twin of a feature column in pixels and the power of the scale that converts
/// it: `m017_dx_px` → (`m017_dx_mm`, 1), `m017_darea_px` → (`m017_darea_mm2`, 2),
/// `field_rms_px` → (`field_rms_mm`, 1); `None` for a column without a length unit (`decc`).
///
/// ```
/// use visuotact_vision::features::mm_twin;
/// assert_eq!(mm_twin("m017_darea_px"), Some(("m017_darea_mm2".to_string(), 2)));
/// assert_eq!(mm_twin("m017_decc"), None);
/// ```
pub fn mm_twin(column: &str) -> Option<(String, i32)> {
    twin(column, true)
}

/// The pixel column a millimetre column is measured from, and the power of the scale that
/// converts it (the inverse of [`mm_twin`]); `None` for a column not in millimetres.
pub fn px_twin(column: &str) -> Option<(String, i32)> {
    twin(column, false)
}

/// A column's twin in the other unit ([`mm_twin`] when `to_mm`, else [`px_twin`]).
fn twin(column: &str, to_mm: bool) -> Option<(String, i32)> {
    let (from, to) = if to_mm {
        (&FIELD_COLUMNS, &FIELD_COLUMNS_MM)
    } else {
        (&FIELD_COLUMNS_MM, &FIELD_COLUMNS)
    };
    if let Some(i) = from.iter().position(|c| *c == column) {
        return Some((to[i].to_string(), 1));
    }
    if !visuotact_image::is_marker_column(column) {
        return None;
    }
    MM_TWINS.iter().find_map(|&(px, mm, power)| {
        let (from, to) = if to_mm { (px, mm) } else { (mm, px) };
        column
            .strip_suffix(from)
            .map(|stem| (format!("{stem}{to}"), power))
    })
}

/// Whether a feature column is in millimetres (`m017_dx_mm`, `m017_darea_mm2`,
/// `field_rms_mm`): a table with such columns trains a model on them.
pub fn is_mm_column(c: &str) -> bool {
    px_twin(c).is_some()
}

/// The millimetre columns of a sensor with a scale: which feature value (in pixels) each one
/// converts, and by what factor (the scale for lengths, its square for areas). Tables written
/// by `extract` and `record` carry them after the pixel columns; the feature vector itself
/// stays in pixels.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MmColumns {
    names: Vec<String>,
    sources: Vec<(usize, f64)>,
}

impl MmColumns {
    /// The twins of `columns` (a feature vector's names, in pixels) at `mm_per_px`.
    pub fn new(columns: &[String], mm_per_px: f64) -> Self {
        let mut out = Self::default();
        for (i, c) in columns.iter().enumerate() {
            if let Some((name, power)) = mm_twin(c) {
                out.names.push(name);
                out.sources.push((i, mm_per_px.powi(power)));
            }
        }
        out
    }

    /// The twins for `cal`'s feature vector `columns`: none when the sensor has no scale.
    pub fn of_sensor(cal: &SensorCalibration, columns: &[String]) -> Self {
        cal.mm_per_px()
            .map_or_else(Self::default, |s| Self::new(columns, s))
    }

    /// The columns' names.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Appends the millimetre values of a feature vector `px_values` (in the order of the
    /// columns it was made from) to `out`.
    pub fn values_into(&self, px_values: &[f64], out: &mut Vec<f64>) {
        out.extend(
            self.sources
                .iter()
                .map(|&(i, k)| px_values.get(i).map_or(f64::NAN, |v| v * k)),
        );
    }
}

/// How many of the largest displacements [`FieldSummary::top_px`] averages.
pub const FIELD_TOP: usize = 5;

/// Weight every marker keeps in the field's centroid, as a displacement in pixels (about the
/// tracking noise): with the skin at rest the centroid is the markers' mean position, and it
/// moves smoothly towards a touch as the displacements grow.
pub const FIELD_FLOOR_PX: f64 = 0.1;

/// A summary of the displacement field of the markers found in one frame, in pixels. With
/// `m_i` the displacement length of marker `i` and its weight `w_i = m_i² + f²`
/// (`f` = [`FIELD_FLOOR_PX`]): the RMS and the largest `m_i`, the mean of the
/// [`FIELD_TOP`] largest, the weighted centroid of the markers' rest positions (where the skin
/// moves: the touch) and the weighted RMS distance of the markers from it (how wide the
/// moving patch is).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FieldSummary {
    /// RMS displacement length over the markers found.
    pub rms_px: f64,
    /// Largest displacement length.
    pub max_px: f64,
    /// Mean of the [`FIELD_TOP`] largest displacement lengths (all of them when fewer).
    pub top_px: f64,
    /// Weighted centroid of the rest positions, x.
    pub cx_px: f64,
    /// Weighted centroid of the rest positions, y.
    pub cy_px: f64,
    /// Weighted RMS distance of the rest positions from the centroid.
    pub spread_px: f64,
}

impl FieldSummary {
    /// The summary of markers at rest positions `rest` displaced by `disp` (`None`: not
    /// found); `None` when no marker was found.
    ///
    /// ```
    /// use visuotact_vision::features::FieldSummary;
    /// // Two markers 10 px apart; only the right one moves, by 3 px.
    /// let s = FieldSummary::of([((0.0, 0.0), Some((0.0, 0.0))), ((10.0, 0.0), Some((3.0, 4.0)))])
    ///     .unwrap();
    /// assert_eq!((s.max_px, s.top_px), (5.0, 2.5));
    /// assert!((s.cx_px - 10.0 * 25.01 / 25.02).abs() < 1e-12);
    /// ```
    pub fn of(markers: impl IntoIterator<Item = ((f64, f64), Option<(f64, f64)>)>) -> Option<Self> {
        let floor = FIELD_FLOOR_PX * FIELD_FLOOR_PX;
        let (mut n, mut sq, mut max) = (0usize, 0.0f64, 0.0f64);
        let (mut sw, mut sx, mut sy, mut sxx) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        let mut top = [0.0f64; FIELD_TOP];
        for ((x, y), d) in markers {
            let Some((dx, dy)) = d else { continue };
            let m2 = dx * dx + dy * dy;
            n += 1;
            sq += m2;
            let m = m2.sqrt();
            max = max.max(m);
            // Keep the largest FIELD_TOP lengths, smallest first.
            if m > top[0] {
                top[0] = m;
                top.sort_unstable_by(f64::total_cmp);
            }
            let w = m2 + floor;
            sw += w;
            sx += w * x;
            sy += w * y;
            sxx += w * (x * x + y * y);
        }
        if n == 0 {
            return None;
        }
        let (cx, cy) = (sx / sw, sy / sw);
        let k = n.min(FIELD_TOP);
        Some(Self {
            rms_px: (sq / n as f64).sqrt(),
            max_px: max,
            top_px: top[FIELD_TOP - k..].iter().sum::<f64>() / k as f64,
            cx_px: cx,
            cy_px: cy,
            spread_px: (sxx / sw - cx * cx - cy * cy).max(0.0).sqrt(),
        })
    }

    /// The values in the order of [`FIELD_COLUMNS`].
    pub fn values(&self) -> [f64; 6] {
        [
            self.rms_px,
            self.max_px,
            self.top_px,
            self.cx_px,
            self.cy_px,
            self.spread_px,
        ]
    }
}

/// Features of one frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameFeatures {
    /// Values in column order: the markers' (NaN where a marker was not matched), then the
    /// [`FIELD_COLUMNS`] (NaN when no marker was found).
    pub values: Vec<f64>,
    /// Per-marker tracking status.
    pub status: Vec<MarkerStatus>,
    /// Markers matched.
    pub found: usize,
    /// Blobs not given to any marker.
    pub spurious: usize,
    /// Overall motion found by the registration, pixels.
    pub shift_px: (f64, f64),
}

/// A frame whose size differs from the calibration's.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("expected {expected_w}×{expected_h} like the reference, got {got_w}×{got_h}")]
pub struct FrameSizeError {
    /// Calibrated width.
    pub expected_w: usize,
    /// Calibrated height.
    pub expected_h: usize,
    /// Frame width.
    pub got_w: usize,
    /// Frame height.
    pub got_h: usize,
}

/// The view of a calibration: the image or its region of interest, and its circular mask.
fn view_of(cal: &SensorCalibration) -> View {
    let p = &cal.detector.preprocess;
    let (w, h) = (cal.image_width as f64, cal.image_height as f64);
    let (x0, y0, x1, y1) = p.roi.map_or((0.0, 0.0, w, h), |r| {
        (
            r.x as f64,
            r.y as f64,
            ((r.x + r.width) as f64).min(w),
            ((r.y + r.height) as f64).min(h),
        )
    });
    View {
        x0: x0 - 0.5,
        y0: y0 - 0.5,
        x1: x1 - 0.5,
        y1: y1 - 0.5,
        circle: p.circle.map(|c| ((c.cx_px, c.cy_px), c.radius_px)),
    }
}

/// Frame → feature vector for one calibrated sensor, with reusable buffers.
#[derive(Clone, Debug)]
pub struct FeatureExtractor {
    cal: SensorCalibration,
    features: FeatureSet,
    detector: Detector,
    reference: TrackReference,
    blobs: Vec<Blob>,
    /// How many blobs at the end of `blobs` are markers cut by the border.
    cut: usize,
    last_track: TrackResult,
    /// Start each frame from the last one's marker positions.
    temporal: bool,
    /// The last frame's marker positions (temporal prior).
    prior: Vec<Option<(f64, f64)>>,
    /// Where markers can be seen (fixed by the calibration).
    view: View,
}

impl FeatureExtractor {
    /// An extractor for `cal` producing `features`.
    pub fn new(cal: SensorCalibration, features: FeatureSet) -> Result<Self, ConfigError> {
        let detector = Detector::new(cal.detector.clone())?;
        let reference = track_reference(&cal);
        let view = view_of(&cal);
        Ok(Self {
            cal,
            features,
            detector,
            reference,
            blobs: Vec::new(),
            cut: 0,
            last_track: TrackResult::default(),
            temporal: false,
            prior: Vec::new(),
            view,
        })
    }

    /// For frames in order (video, live camera): start each frame's tracking from the last
    /// frame's marker positions, which follows motions of more than a pitch built up over
    /// several frames. A frame where that loses track (far fewer markers than the last frame
    /// had) is tracked from the reference as well and that result kept if it finds clearly
    /// more. Off by default (frames in any order); turning it on or off forgets the last frame.
    pub fn set_temporal_prior(&mut self, on: bool) {
        self.temporal = on;
        self.prior.clear();
    }

    /// Whether tracking starts from the last frame ([`FeatureExtractor::set_temporal_prior`]).
    pub fn temporal_prior(&self) -> bool {
        self.temporal
    }

    /// Where markers can be seen: the image, or its region of interest, cut to the circular
    /// mask if there is one.
    pub fn view(&self) -> View {
        self.view
    }

    /// The calibration.
    pub fn calibration(&self) -> &SensorCalibration {
        &self.cal
    }

    /// The feature set.
    pub fn feature_set(&self) -> FeatureSet {
        self.features
    }

    /// Output column names: the markers' features, then the [`FIELD_COLUMNS`].
    pub fn column_names(&self) -> Vec<String> {
        let mut names = self
            .features
            .column_names(self.cal.markers.iter().map(|m| m.id));
        names.extend(FIELD_COLUMNS.iter().map(|c| (*c).to_string()));
        names
    }

    /// The blobs of the last frame: those the filter kept, then the markers cut by the
    /// image's edge (a marker whose cut blob is as big as a whole marker keeps it). Blob
    /// indices of [`FeatureExtractor::last_track`] point into them.
    pub fn last_blobs(&self) -> &[Blob] {
        &self.blobs
    }

    /// The tracking result of the last frame.
    pub fn last_track(&self) -> &TrackResult {
        &self.last_track
    }

    /// Tracks this frame's blobs: from the last frame's positions when tracking is temporal
    /// and the last frame found markers, else (or when that loses track) from the reference.
    fn track(&self) -> TrackResult {
        let view = Some(self.view);
        // A frame after one whose first start left something unexplained is searched from
        // every start at once (the frames of a video are alike).
        let from_reference = TrackHints {
            cut: self.cut,
            prior: None,
            view,
            starts_side_by_side: self.last_track.searched_again,
        };
        if self.temporal && self.prior.iter().any(Option::is_some) {
            let t = track_with(
                &self.reference,
                &self.blobs,
                &self.cal.track,
                TrackHints {
                    prior: Some(&self.prior),
                    ..from_reference
                },
            );
            // The prior lost track (far fewer markers than the last frame had): start again
            // from the reference, and keep that if it finds clearly more and gives every
            // marker the followed reading holds the same blob (else it is another reading).
            let had = self.prior.iter().filter(|p| p.is_some()).count();
            if t.found() + 3 + had / 20 < had {
                let r = track_with(
                    &self.reference,
                    &self.blobs,
                    &self.cal.track,
                    from_reference,
                );
                let agree = t
                    .assignment
                    .iter()
                    .zip(&r.assignment)
                    .all(|(a, b)| a.is_none() || b.is_none() || a == b);
                if agree && r.found() > t.found() + 2 {
                    r
                } else {
                    t
                }
            } else {
                t
            }
        } else {
            track_with(
                &self.reference,
                &self.blobs,
                &self.cal.track,
                from_reference,
            )
        }
    }

    /// The markers' features of the last track into `out` (statuses and values).
    fn marker_values_into(&self, out: &mut FrameFeatures) {
        let t = &self.last_track;
        out.values.clear();
        out.status.clear();
        let conv = self.cal.moment_convention;
        for (i, (m, (a, st))) in self
            .cal
            .markers
            .iter()
            .zip(t.assignment.iter().zip(&t.status))
            .enumerate()
        {
            out.status.push(*st);
            let b = a.map(|j| &self.blobs[j]);
            // A split marker has a position but no blob of its own.
            let p = t.position_px(i, &self.blobs);
            let f = &self.features;
            if f.dx {
                out.values.push(p.map_or(f64::NAN, |p| p.0 - m.x_px));
            }
            if f.dy {
                out.values.push(p.map_or(f64::NAN, |p| p.1 - m.y_px));
            }
            if f.area {
                out.values
                    .push(b.map_or(f64::NAN, |b| f64::from(b.area_px) - m.area_px));
            }
            if f.eccentricity {
                out.values
                    .push(b.map_or(f64::NAN, |b| b.shape(conv).eccentricity - m.eccentricity));
            }
        }
    }

    /// Features of `rgb` into `out` (buffers reused).
    pub fn extract_into(
        &mut self,
        rgb: &RgbImage,
        out: &mut FrameFeatures,
    ) -> Result<(), FrameSizeError> {
        if (rgb.width(), rgb.height()) != (self.cal.image_width, self.cal.image_height) {
            return Err(FrameSizeError {
                expected_w: self.cal.image_width,
                expected_h: self.cal.image_height,
                got_w: rgb.width(),
                got_h: rgb.height(),
            });
        }
        self.detector.detect_into(rgb, &mut self.blobs);
        // Markers a threshold joined are parted where the grey image dips between them, when
        // the blob fills its ellipse less than the sensor's own markers do.
        let max_fill = 1.0 - self.reference.fill_sigma;
        self.detector.part_touching(&mut self.blobs, max_fill);
        // Markers cut by the border go after the measurable blobs: they explain an absence.
        self.cut = self.detector.last_cut().len();
        self.blobs.extend_from_slice(self.detector.last_cut());
        self.last_track = self.track();
        // A marker's dot in pieces is measured on its pieces together.
        self.last_track.merge_pieces(&mut self.blobs);
        if self.temporal {
            let blobs = &self.blobs;
            self.prior.clear();
            let t = &self.last_track;
            self.prior
                .extend((0..t.status.len()).map(|i| t.followed_px(i, blobs)));
        }
        self.marker_values_into(out);
        let t = &self.last_track;
        let blobs = &self.blobs;
        let field = FieldSummary::of(self.cal.markers.iter().enumerate().map(|(i, m)| {
            let d = t
                .position_px(i, blobs)
                .map(|p| (p.0 - m.x_px, p.1 - m.y_px));
            ((m.x_px, m.y_px), d)
        }));
        out.values
            .extend(field.map_or([f64::NAN; 6], |f| f.values()));
        out.found = t.found();
        out.spurious = t.spurious;
        out.shift_px = t.shift_px;
        Ok(())
    }

    /// Allocating form of [`FeatureExtractor::extract_into`].
    pub fn extract(&mut self, rgb: &RgbImage) -> Result<FrameFeatures, FrameSizeError> {
        let mut out = FrameFeatures::default();
        self.extract_into(rgb, &mut out)?;
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::{FieldSummary, FIELD_TOP};

    /// A marker's rest position and its displacement (`None`: lost).
    type Marker = ((f64, f64), Option<(f64, f64)>);

    /// Markers on a circle of radius `r` about (cx, cy), each displaced radially outwards by
    /// `push` px: the closed form is known whatever the floor weight.
    fn ring(n: usize, (cx, cy): (f64, f64), r: f64, push: f64) -> Vec<Marker> {
        (0..n)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                let (s, c) = a.sin_cos();
                ((cx + r * c, cy + r * s), Some((push * c, push * s)))
            })
            .collect()
    }

    #[test]
    fn a_radial_ring_is_centred_on_its_centre() {
        let s = FieldSummary::of(ring(12, (40.0, -7.5), 9.0, 1.5)).unwrap();
        assert!((s.cx_px - 40.0).abs() < 1e-12 && (s.cy_px + 7.5).abs() < 1e-12);
        assert!((s.spread_px - 9.0).abs() < 1e-9, "{s:?}");
        for v in [s.rms_px, s.max_px, s.top_px] {
            assert!((v - 1.5).abs() < 1e-12, "{s:?}");
        }
    }

    #[test]
    fn the_centroid_follows_the_moving_markers() {
        // A still ring about the origin and a moving one about (100, 0): the centroid lies
        // between them in the ratio of their weights (push² + floor² against floor²).
        let mut m = ring(8, (0.0, 0.0), 5.0, 0.0);
        m.extend(ring(8, (100.0, 0.0), 5.0, 2.0));
        let s = FieldSummary::of(m).unwrap();
        let (w0, w1) = (0.01, 4.0 + 0.01);
        assert!((s.cx_px - 100.0 * w1 / (w0 + w1)).abs() < 1e-9, "{s:?}");
        assert!(s.cy_px.abs() < 1e-12);
        assert!((s.rms_px - 2.0f64.sqrt()).abs() < 1e-12);
        assert!((s.top_px - 2.0).abs() < 1e-12 && (s.max_px - 2.0).abs() < 1e-12);
    }

    #[test]
    fn lost_markers_are_left_out_and_none_found_is_none() {
        let mut m = ring(6, (0.0, 0.0), 3.0, 1.0);
        m[0].1 = None;
        m[1].1 = Some((0.0, 4.0));
        let s = FieldSummary::of(m.clone()).unwrap();
        // Five found: lengths 4, 1, 1, 1, 1.
        assert!((s.rms_px - (20.0f64 / 5.0).sqrt()).abs() < 1e-12);
        assert_eq!(s.max_px, 4.0);
        assert!((s.top_px - 8.0 / FIELD_TOP as f64).abs() < 1e-12);
        for x in &mut m {
            x.1 = None;
        }
        assert_eq!(FieldSummary::of(m), None);
        assert_eq!(FieldSummary::of(Vec::new()), None);
    }
}
