//! Slip over time: from a sequence's tracked markers, a state per frame (`stick`, `incipient`,
//! `slip`) with a score, and a verdict per sequence with its onset.
//!
//! Contract. Each frame's displacement field gives ten signals
//! ([`visuotact_vision::field::FieldDynamics`]: shift, spread, curl, divergence, affine
//! residual, entropy, and the rigid motion of the increments with the residual from it); an
//! eleventh, where measured ([`SlipConfig::imprint`], zero otherwise), is the object's imprint
//! sliding against the markers over the lag ([`visuotact_vision::imprint`]). Each
//! signal `x` is taken as `ln(1 + 10 |x|)`, averaged over the last `smooth_frames` frames, and
//! summed up over the sequence so far by three statistics — its largest value, its mean and its
//! largest change between frames — the 33 numbers of the [`SlipEvidence`]. The detector is a
//! logistic regression on them, standardised ([`SlipDetector`], a JSON file of 33 weights; a
//! file of the 30 before the imprint reads it with weight 0):
//! the frame's score is the probability of slip given the sequence up to that frame, its state
//! `slip` at or above [`SlipDetector::threshold`], `incipient` at or above
//! [`SlipDetector::incipient_threshold`], `stick` below. The sequence's verdict is its last
//! frame's state; the onset is the first frame of the run of `slip` frames that ends the
//! sequence. The statistics need no onset label: a detector is fitted on sequences labelled
//! slip or not ([`fit_detector`]); where the onsets are known ([`SlipTruth::onset_s`]), the
//! beginnings of slipping sequences, frame by frame around each onset, teach it when the score
//! must rise.
//!
//! Why these: stick moves the markers under an object together with it, slip leaves some
//! behind (the partial-slip annulus: the increments' residual from a rigid motion grows against
//! the motion) or lets the object go (the shear relaxes, the field's divergence and spread
//! change for the rest of the grasp); a shake moves the markers as far as a slip, but as one.
//!
//! [`SlipDetector::default`] is the detector fitted on the 300 sequences of the real GelSight
//! Mini grasps (`../shared/reference/real/gelsight_slip`, 130 slip; [`fit_detector`] with the
//! beginnings of the no-slip grasps); its figures on that set are not held out.
//! [`cross_validate`] gives held-out ones, by group (object).

use std::collections::VecDeque;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use visuotact_image::RgbImage;
use visuotact_io::frames::{is_image_path, is_video_path, FrameError, FrameStream};
use visuotact_nn::logistic::{fit_logistic, sigmoid, LogisticConfig};
use visuotact_vision::calibration::{CalibrationConfig, SensorCalibration};
use visuotact_vision::features::{FeatureExtractor, FeatureSet, FrameFeatures};
use visuotact_vision::field::{FieldDynamics, FieldTracker};
use visuotact_vision::imprint::{ImprintFollower, ImprintParams};
use visuotact_vision::options::{DetectorOptions, Purpose};
use visuotact_vision::track::TrackParams;

use crate::calibrate::{calibrate_frames, CalibrateError, ReferenceSource};

mod cv;
mod labels;

pub use cv::{cross_validate, cv_table, fused_scores, CrossValidation, Scores};
pub use labels::{labels_of, normalised, read_labels, Label};

/// Statistics per signal in [`SlipEvidence`].
pub const STATISTICS: [&str; 3] = ["max", "mean", "max_rate"];
/// Signals per frame in [`SlipEvidence`]: the field's ten ([`FieldDynamics::NAMES`]) and the
/// imprint's slide against the markers ([`IMPRINT_SIGNAL`]).
pub const SIGNALS: usize = FieldDynamics::NAMES.len() + 1;
/// Numbers in [`SlipEvidence`]: eleven signals × three statistics.
pub const EVIDENCE_LEN: usize = SIGNALS * STATISTICS.len();
/// The eleventh signal's name: the object's imprint sliding against the markers over the lag,
/// pitches ([`visuotact_vision::imprint`]).
pub const IMPRINT_SIGNAL: &str = "imprint_slide_pitches";
/// The frame rate assumed for a folder of images (videos carry their own).
const IMAGE_FPS: f64 = 25.0;

/// Why slip could not be detected or fitted.
#[derive(Debug, thiserror::Error)]
pub enum SlipError {
    /// A sequence's frames could not be read.
    #[error("{}: {source}", video.display())]
    Frames {
        /// The sequence.
        video: PathBuf,
        /// The reader's error.
        source: FrameError,
    },
    /// A sequence's first frames did not calibrate.
    #[error("{}: calibrating from its first {frames} frames: {source}", video.display())]
    Calibrate {
        /// The sequence.
        video: PathBuf,
        /// Frames tried.
        frames: usize,
        /// Why.
        source: CalibrateError,
    },
    /// A frame did not match the sensor.
    #[error("{}: frame {frame}: {why}", video.display())]
    Frame {
        /// The sequence.
        video: PathBuf,
        /// The frame's id.
        frame: String,
        /// Why.
        why: String,
    },
    /// A folder with no video in it, or a file that is no video.
    #[error("{}: {why}", path.display())]
    NoSequence {
        /// The path given.
        path: PathBuf,
        /// What was expected.
        why: &'static str,
    },
    /// A labels file that does not read as `video,slip`.
    #[error("{}:{line}: {why}", path.display())]
    Labels {
        /// The file.
        path: PathBuf,
        /// Its line (1-based).
        line: usize,
        /// What was expected.
        why: String,
    },
    /// A sequence given with no label.
    #[error("{}: no label for this video in {}", video.display(), labels.display())]
    Unlabelled {
        /// The sequence.
        video: PathBuf,
        /// The labels file.
        labels: PathBuf,
    },
    /// A labelled sequence that was not given.
    #[error("{}:{line}: {} is labelled but not among the videos given", labels.display(), video.display())]
    LabelledMissing {
        /// The labels file.
        labels: PathBuf,
        /// Its line.
        line: usize,
        /// The video named.
        video: PathBuf,
    },
    /// Fitting needs both classes.
    #[error("fitting needs sequences of both classes: {slip} slip, {stick} without")]
    OneClass {
        /// Sequences labelled slip.
        slip: usize,
        /// Sequences labelled no slip.
        stick: usize,
    },
    /// A detector file that cannot be read.
    #[error("{source_name}: not a slip detector: {why}")]
    Detector {
        /// Where it came from.
        source_name: String,
        /// Why.
        why: String,
    },
    /// The progress callback stopped the pass.
    #[error("stopped after {done} of {total} sequences")]
    Stopped {
        /// Sequences done.
        done: usize,
        /// Sequences in all.
        total: usize,
    },
}

/// How sequences are followed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SlipConfig {
    /// Frames a sequence calibrates its reference from when no sensor is given.
    pub calibration_frames: usize,
    /// Track each frame from the last one's positions (the temporal prior) rather than from
    /// the reference.
    pub temporal: bool,
    /// Also measure the object's imprint sliding against the markers
    /// ([`TrackedFrame::imprint_slide_px`]; zero when off): on sensors that show the imprint
    /// (GelSight-type). About half the tracking's time again.
    pub imprint: bool,
}

impl Default for SlipConfig {
    fn default() -> Self {
        Self {
            calibration_frames: 5,
            temporal: false,
            imprint: false,
        }
    }
}

/// The running statistics of a sequence's signals ([module docs](self)).
#[derive(Clone, Debug)]
pub struct SlipEvidence {
    smooth: usize,
    /// The last `smooth` frames' transformed signals.
    window: VecDeque<[f64; SIGNALS]>,
    last: Option<[f64; SIGNALS]>,
    max: [f64; SIGNALS],
    sum: [f64; SIGNALS],
    max_rate: [f64; SIGNALS],
    frames: usize,
}

impl SlipEvidence {
    /// Statistics over windows of `smooth_frames` frames (at least 1).
    pub fn new(smooth_frames: usize) -> Self {
        Self {
            smooth: smooth_frames.max(1),
            window: VecDeque::new(),
            last: None,
            max: [0.0; SIGNALS],
            sum: [0.0; SIGNALS],
            max_rate: [0.0; SIGNALS],
            frames: 0,
        }
    }

    /// Adds one frame's signals: the field's, and the imprint's slide against the markers over
    /// the lag (pitches; 0 where not measured).
    pub fn push(&mut self, f: &FieldDynamics, imprint_slide_pitches: f64) {
        if self.window.len() == self.smooth {
            self.window.pop_front();
        }
        let mut x = [imprint_slide_pitches; SIGNALS];
        x[..SIGNALS - 1].copy_from_slice(&f.signals());
        self.window.push_back(x.map(|x| (10.0 * x.abs()).ln_1p()));
        let n = self.window.len() as f64;
        let mut s = [0.0; SIGNALS];
        for w in &self.window {
            for (a, b) in s.iter_mut().zip(w) {
                *a += b / n;
            }
        }
        for j in 0..SIGNALS {
            self.max[j] = self.max[j].max(s[j]);
            self.sum[j] += s[j];
            if let Some(l) = self.last {
                self.max_rate[j] = self.max_rate[j].max((s[j] - l[j]).abs());
            }
        }
        self.last = Some(s);
        self.frames += 1;
    }

    /// The thirty-three numbers, [`STATISTICS`] by signal.
    pub fn values(&self) -> [f64; EVIDENCE_LEN] {
        let mut v = [0.0; EVIDENCE_LEN];
        let n = self.frames.max(1) as f64;
        for j in 0..SIGNALS {
            v[j] = self.max[j];
            v[SIGNALS + j] = self.sum[j] / n;
            v[2 * SIGNALS + j] = self.max_rate[j];
        }
        v
    }

    /// The evidence's names: `max_shift_pitches`, …, `max_rate_imprint_slide_pitches`.
    pub fn names() -> Vec<String> {
        STATISTICS
            .iter()
            .flat_map(|s| {
                FieldDynamics::NAMES
                    .iter()
                    .chain([&IMPRINT_SIGNAL])
                    .map(move |n| format!("{s}_{n}"))
            })
            .collect()
    }

    /// The names of the evidence before the imprint's slide (detector files of 30 inputs).
    fn names_without_imprint() -> Vec<String> {
        Self::names()
            .into_iter()
            .filter(|n| !n.ends_with(IMPRINT_SIGNAL))
            .collect()
    }
}

/// A frame's slip state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SlipState {
    /// Nothing points to slip.
    Stick = 0,
    /// The score is rising towards slip.
    Incipient = 1,
    /// Slipping.
    Slip = 2,
}

impl SlipState {
    /// `stick`, `incipient` or `slip`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Stick => "stick",
            Self::Incipient => "incipient",
            Self::Slip => "slip",
        }
    }
}

/// The detector's settings that are not fitted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlipSettings {
    /// Frames an increment spans (2: 80 ms at 25 fps).
    pub lag_frames: usize,
    /// Frames the signals are averaged over (5: 200 ms at 25 fps).
    pub smooth_frames: usize,
    /// Score at or above which a frame is `slip`.
    pub threshold: f64,
    /// Score at or above which a frame is `incipient`.
    pub incipient_threshold: f64,
    /// Fit on the beginnings of sequences without slip too ([`fit_detector`]).
    pub stick_prefixes: bool,
}

impl Default for SlipSettings {
    fn default() -> Self {
        Self {
            lag_frames: 2,
            smooth_frames: 5,
            threshold: 0.5,
            incipient_threshold: 0.25,
            stick_prefixes: true,
        }
    }
}

/// The slip detector: a logistic regression on the standardised [`SlipEvidence`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SlipDetector {
    /// `visuotact-slip`.
    pub format: String,
    /// File version (1).
    pub version: u32,
    /// Frames an increment spans.
    pub lag_frames: usize,
    /// Frames the signals are averaged over.
    pub smooth_frames: usize,
    /// The evidence's names, in order.
    pub inputs: Vec<String>,
    /// Subtracted from each number of the evidence.
    pub center: Vec<f64>,
    /// Each number of the evidence is divided by this.
    pub scale: Vec<f64>,
    /// The logistic regression's weights.
    pub weights: Vec<f64>,
    /// Its intercept.
    pub bias: f64,
    /// Score at or above which a frame is `slip`.
    pub threshold: f64,
    /// Score at or above which a frame is `incipient`.
    pub incipient_threshold: f64,
    /// Sequences it was fitted on, and of them labelled slip.
    pub fitted_on: [usize; 2],
    /// The fewest frames of evidence it was fitted on (the shortest beginning or sequence):
    /// it reads a sequence from this frame on, and calls the frames before it `stick` with
    /// score 0 rather than read evidence shorter than any it has seen (a sequence's first
    /// frames are its rest, its reference calibrated from them). Files without it: 25.
    #[serde(default = "prefix_every")]
    pub min_frames: usize,
}

/// [`PREFIX_EVERY`], the shortest evidence of a fit when no sequence is shorter.
fn prefix_every() -> usize {
    PREFIX_EVERY
}

const FORMAT: &str = "visuotact-slip";

impl Default for SlipDetector {
    /// Fitted on the real GelSight Mini grasps ([module docs](self)).
    fn default() -> Self {
        Self::try_default().unwrap_or_else(|| unreachable!("the built-in detector reads (test)"))
    }
}

impl SlipDetector {
    /// The built-in detector ([`SlipDetector::default`]); `None` only if its file were broken,
    /// which a test rules out.
    pub fn try_default() -> Option<Self> {
        Self::from_json(include_str!("slip_default.json"), "the built-in detector").ok()
    }

    /// The detector at `path`, or the built-in one for `builtin` (what `--slip`, `--detector`
    /// and Python's `slip=` accept).
    pub fn load(path: &Path) -> Result<Self, SlipError> {
        if path == Path::new("builtin") {
            return Ok(Self::default());
        }
        let name = path.display().to_string();
        let text = visuotact_io::read::text_of_file(path).map_err(|e| SlipError::Detector {
            source_name: name.clone(),
            why: format!("cannot read it: {e}"),
        })?;
        Self::from_json(&text, &name)
    }

    /// Reads a detector file's text; `source_name` names it in errors.
    pub fn from_json(text: &str, source_name: &str) -> Result<Self, SlipError> {
        let bad = |why: String| SlipError::Detector {
            source_name: source_name.to_string(),
            why,
        };
        let mut d: Self = serde_json::from_str(text).map_err(|e| bad(e.to_string()))?;
        if d.format != FORMAT || d.version != 1 {
            return Err(bad(format!(
                "format {:?} version {}: expected {FORMAT:?} version 1",
                d.format, d.version
            )));
        }
        let n = EVIDENCE_LEN;
        // A file written before the imprint's slide was measured reads it with weight 0.
        let earlier = SlipEvidence::names_without_imprint();
        if d.inputs == earlier
            && [&d.center, &d.scale, &d.weights]
                .iter()
                .all(|v| v.len() == earlier.len())
        {
            d.with_every_input();
        }
        if d.inputs != SlipEvidence::names()
            || d.center.len() != n
            || d.scale.len() != n
            || d.weights.len() != n
        {
            return Err(bad(format!("expected {n} inputs named as this version's evidence, with a center, scale and weight each")));
        }
        let finite = d
            .center
            .iter()
            .chain(&d.weights)
            .chain([&d.bias])
            .all(|x| x.is_finite());
        if !finite || d.scale.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(bad(
                "every center, weight and the bias must be finite, every scale positive".into(),
            ));
        }
        let unit = |t: f64| (0.0..=1.0).contains(&t);
        if !(unit(d.threshold)
            && unit(d.incipient_threshold)
            && d.incipient_threshold <= d.threshold)
        {
            return Err(bad(
                "expected 0 ≤ incipient_threshold ≤ threshold ≤ 1".into()
            ));
        }
        if d.lag_frames == 0 || d.smooth_frames == 0 || d.min_frames == 0 {
            return Err(bad(
                "lag_frames, smooth_frames and min_frames must be at least 1".into(),
            ));
        }
        Ok(d)
    }

    /// Every input of this version's evidence, those the file lacks with weight 0.
    fn with_every_input(&mut self) {
        let names = SlipEvidence::names();
        let mut center = vec![0.0; names.len()];
        let mut scale = vec![1.0; names.len()];
        let mut weights = vec![0.0; names.len()];
        for (k, name) in names.iter().enumerate() {
            if let Some(j) = self.inputs.iter().position(|i| i == name) {
                (center[k], scale[k], weights[k]) =
                    (self.center[j], self.scale[j], self.weights[j]);
            }
        }
        (self.inputs, self.center, self.scale, self.weights) = (names, center, scale, weights);
    }

    /// Whether it reads the imprint's slide (a weight on it): only then is it measured, from
    /// the frames themselves ([`SlipMonitor::observe_frame`]).
    pub fn reads_imprint(&self) -> bool {
        self.inputs
            .iter()
            .zip(&self.weights)
            .any(|(i, w)| i.ends_with(IMPRINT_SIGNAL) && *w != 0.0)
    }

    /// Its settings that are not fitted.
    pub fn settings(&self) -> SlipSettings {
        SlipSettings {
            lag_frames: self.lag_frames,
            smooth_frames: self.smooth_frames,
            threshold: self.threshold,
            incipient_threshold: self.incipient_threshold,
            stick_prefixes: true,
        }
    }

    /// The detector file's text.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// The probability of slip given `evidence`.
    pub fn score(&self, evidence: &[f64; EVIDENCE_LEN]) -> f64 {
        let z: f64 = evidence
            .iter()
            .zip(&self.center)
            .zip(&self.scale)
            .zip(&self.weights)
            .map(|(((x, c), s), w)| w * (x - c) / s)
            .sum();
        sigmoid(z + self.bias)
    }

    /// The probability of slip given `evidence` of a sequence's first `frames` frames: 0
    /// before [`SlipDetector::min_frames`], [`SlipDetector::score`] from it on.
    pub fn live_score(&self, evidence: &[f64; EVIDENCE_LEN], frames: usize) -> f64 {
        if frames < self.min_frames {
            0.0
        } else {
            self.score(evidence)
        }
    }

    /// The state a score stands for.
    pub fn state_of(&self, score: f64) -> SlipState {
        if score >= self.threshold {
            SlipState::Slip
        } else if score >= self.incipient_threshold {
            SlipState::Incipient
        } else {
            SlipState::Stick
        }
    }
}

/// One frame's slip estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlipFrame {
    /// The frame's time, seconds from the sequence's start.
    pub timestamp_s: f64,
    /// The state.
    pub state: SlipState,
    /// The probability of slip given the sequence so far.
    pub score: f64,
    /// The field's signals this frame.
    pub field: FieldDynamics,
}

/// The displacement field's dynamics of a sensor's frames in order, from their features: what
/// [`SlipMonitor`] reads and `extract --temporal` writes.
#[derive(Clone, Debug)]
pub struct FieldFollower {
    tracker: FieldTracker,
    field: FieldDynamics,
    /// The displacements of the last frame (kept between frames: no allocation once warm).
    displacements: Vec<Option<(f64, f64)>>,
}

impl FieldFollower {
    /// A follower of markers at `reference_px`, `pitch_px` apart, increments over `lag_frames`.
    pub fn new(reference_px: &[(f64, f64)], pitch_px: f64, lag_frames: usize) -> Self {
        Self {
            tracker: FieldTracker::new(reference_px, pitch_px, lag_frames),
            field: FieldDynamics::default(),
            displacements: Vec::new(),
        }
    }

    /// A follower of `sensor`'s markers.
    pub fn of_sensor(sensor: &SensorCalibration, lag_frames: usize) -> Self {
        let reference: Vec<(f64, f64)> = sensor.markers.iter().map(|m| (m.x_px, m.y_px)).collect();
        Self::new(&reference, sensor.pitch_px, lag_frames)
    }

    /// Starts a new sequence.
    pub fn reset(&mut self) {
        self.tracker.reset();
    }

    /// This frame's dynamics from the markers' displacements (pixels, `None`: not tracked).
    pub fn update(&mut self, displacement_px: &[Option<(f64, f64)>]) -> &FieldDynamics {
        self.tracker.update_into(displacement_px, &mut self.field);
        &self.field
    }

    /// [`FieldFollower::update`] from a frame's features of `set` (which must hold `dx` and
    /// `dy`: [`SlipMonitor::reads`]).
    pub fn update_features(&mut self, f: &FrameFeatures, set: FeatureSet) -> &FieldDynamics {
        let mut d = std::mem::take(&mut self.displacements);
        displacements_into(f, set, self.tracker.markers(), &mut d);
        self.tracker.update_into(&d, &mut self.field);
        self.displacements = d;
        &self.field
    }

    /// The last frame's dynamics.
    pub fn field(&self) -> &FieldDynamics {
        &self.field
    }
}

/// The imprint's slide over the last `lag` frames, from each frame's slide.
#[derive(Clone, Debug)]
struct LagSum {
    lag: usize,
    recent: VecDeque<(f64, f64)>,
}

impl LagSum {
    fn new(lag: usize) -> Self {
        Self {
            lag: lag.max(1),
            recent: VecDeque::new(),
        }
    }

    /// The length of the last `lag` frames' slides summed, this frame's `slide_px` the last.
    fn push(&mut self, slide_px: (f64, f64)) -> f64 {
        if self.recent.len() == self.lag {
            self.recent.pop_front();
        }
        self.recent.push_back(slide_px);
        let (x, y) = self
            .recent
            .iter()
            .fold((0.0, 0.0), |(x, y), (a, b)| (x + a, y + b));
        x.hypot(y)
    }
}

/// The live form: frame after frame, the slip state ([`SlipMonitor::update`]).
#[derive(Clone, Debug)]
pub struct SlipMonitor {
    detector: SlipDetector,
    follower: FieldFollower,
    evidence: SlipEvidence,
    /// Measures the imprint's slide from the frames (when the detector reads it).
    imprint: Option<ImprintFollower>,
    imprint_lag: LagSum,
    /// This frame's imprint slide, pixels, until it is scored.
    imprint_px: (f64, f64),
    pitch_px: f64,
}

impl SlipMonitor {
    /// A monitor of markers at `reference_px`, `pitch_px` apart, with `detector`.
    pub fn new(detector: SlipDetector, reference_px: &[(f64, f64)], pitch_px: f64) -> Self {
        Self {
            follower: FieldFollower::new(reference_px, pitch_px, detector.lag_frames),
            evidence: SlipEvidence::new(detector.smooth_frames),
            imprint: detector
                .reads_imprint()
                .then(|| ImprintFollower::new(ImprintParams::DEFAULT, 1)),
            imprint_lag: LagSum::new(detector.lag_frames),
            imprint_px: (0.0, 0.0),
            pitch_px,
            detector,
        }
    }

    /// A monitor of `est`'s markers, refused when its features lack the displacements.
    pub fn for_estimator(
        detector: SlipDetector,
        est: &crate::Estimator,
    ) -> Result<Self, crate::PipelineError> {
        if !Self::reads(est.feature_set()) {
            return Err(crate::PipelineError::Slip(
                "slip detection reads the markers' displacements: the features must include x and y",
            ));
        }
        Ok(Self::of_sensor(detector, est.calibration()))
    }

    /// A monitor of `sensor`'s markers.
    pub fn of_sensor(detector: SlipDetector, sensor: &SensorCalibration) -> Self {
        let reference: Vec<(f64, f64)> = sensor.markers.iter().map(|m| (m.x_px, m.y_px)).collect();
        Self::new(detector, &reference, sensor.pitch_px)
    }

    /// Starts a new sequence.
    pub fn reset(&mut self) {
        self.follower.reset();
        self.evidence = SlipEvidence::new(self.detector.smooth_frames);
        if let Some(f) = &mut self.imprint {
            f.reset();
        }
        self.imprint_lag = LagSum::new(self.detector.lag_frames);
        self.imprint_px = (0.0, 0.0);
    }

    /// Reads this frame's image for the imprint's slide, before its markers are scored
    /// ([`SlipMonitor::estimate`] and the like); nothing when the detector does not read it.
    pub fn observe_frame(&mut self, img: &RgbImage) {
        if let Some(f) = &mut self.imprint {
            self.imprint_px = f.update(img);
        }
    }

    /// This frame's imprint slide since the last frame, `(dx, dy)` pixels, measured elsewhere
    /// (a [`TrackedFrame`]'s), before its markers are scored.
    pub fn set_imprint_slide(&mut self, slide_px: (f64, f64)) {
        self.imprint_px = slide_px;
    }

    /// This frame's state from the markers' displacements (pixels, `None`: not tracked).
    pub fn update(
        &mut self,
        displacement_px: &[Option<(f64, f64)>],
        timestamp_s: f64,
    ) -> SlipFrame {
        let e = self.estimate(displacement_px);
        SlipFrame {
            timestamp_s,
            state: e.state,
            score: e.score,
            field: e.field,
        }
    }

    /// [`SlipMonitor::update`]'s state, score and field signals (the live loop's form).
    pub fn estimate(&mut self, displacement_px: &[Option<(f64, f64)>]) -> SlipEstimate {
        let field = *self.follower.update(displacement_px);
        self.score(field)
    }

    /// The state and score once `field` is this frame's dynamics.
    fn score(&mut self, field: FieldDynamics) -> SlipEstimate {
        let slide_px = self.imprint_lag.push(std::mem::take(&mut self.imprint_px));
        self.evidence.push(&field, slide_px / self.pitch_px);
        let score = self
            .detector
            .live_score(&self.evidence.values(), self.evidence.frames);
        SlipEstimate {
            state: self.detector.state_of(score),
            score,
            field,
        }
    }

    /// [`SlipMonitor::estimate`] from a frame's features of `set` (which must hold `dx` and
    /// `dy`: [`SlipMonitor::reads`]), allocating nothing once warm.
    pub fn estimate_features(&mut self, f: &FrameFeatures, set: FeatureSet) -> SlipEstimate {
        let field = *self.follower.update_features(f, set);
        self.score(field)
    }

    /// Whether features of `set` carry what the monitor reads (the displacements).
    pub fn reads(set: FeatureSet) -> bool {
        set.dx && set.dy
    }

    /// The evidence so far.
    pub fn evidence(&self) -> &SlipEvidence {
        &self.evidence
    }

    /// The last frame's displacement-field signals (what [`SlipMonitor::estimate`] read).
    pub fn field(&self) -> &FieldDynamics {
        self.follower.field()
    }
}

/// Each marker's displacement in `f` (features of `set`, in column order), into `out`;
/// `None` where it was not tracked. Empty unless `set` has both `dx` and `dy`.
pub fn displacements_into(
    f: &FrameFeatures,
    set: FeatureSet,
    markers: usize,
    out: &mut Vec<Option<(f64, f64)>>,
) {
    out.clear();
    if !(set.dx && set.dy) {
        return;
    }
    let per = set.per_marker();
    out.extend((0..markers).map(|i| {
        let (x, y) = (
            f.values.get(per * i).copied().unwrap_or(f64::NAN),
            f.values.get(per * i + 1).copied().unwrap_or(f64::NAN),
        );
        (x.is_finite() && y.is_finite()).then_some((x, y))
    }));
}

/// A frame's slip estimate, as live outputs send it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct SlipEstimate {
    /// `stick`, `incipient` or `slip`.
    pub state: SlipState,
    /// The probability of slip given the sequence so far.
    pub score: f64,
    /// The displacement field's signals this frame, which the detector read.
    pub field: FieldDynamics,
}

impl SlipEstimate {
    /// A frame without contact: nothing to slip (`stick`, score 0, no field signals).
    pub fn without_contact() -> Self {
        Self {
            state: SlipState::Stick,
            score: 0.0,
            field: FieldDynamics::default(),
        }
    }
}

/// A sequence's displacements, frame by frame.
#[derive(Clone, Debug, Default)]
pub struct TrackedSequence {
    /// The sensor it was tracked with.
    pub markers_px: Vec<(f64, f64)>,
    /// Its marker pitch.
    pub pitch_px: f64,
    /// Its frames.
    pub frames: Vec<TrackedFrame>,
}

/// One frame of a [`TrackedSequence`].
#[derive(Clone, Debug, Default)]
pub struct TrackedFrame {
    /// Seconds from the sequence's start.
    pub timestamp_s: f64,
    /// The frame's id (a video frame's index).
    pub id: String,
    /// Each marker's displacement from the reference, pixels (`None`: not tracked).
    pub displacement_px: Vec<Option<(f64, f64)>>,
    /// The object's imprint slide against the markers since the last frame, `(dx, dy)` pixels
    /// ([`visuotact_vision::imprint`]; zero unless [`SlipConfig::imprint`]).
    pub imprint_slide_px: (f64, f64),
}

/// The sensor a sequence calibrates from its first frames.
pub fn calibrate_sequence(video: &Path, cfg: &SlipConfig) -> Result<SensorCalibration, SlipError> {
    let frames = cfg.calibration_frames.max(1);
    let open = || Ok(FrameStream::open(&[video.to_path_buf()], IMAGE_FPS)?.take_first(frames));
    let calib_err = |source| SlipError::Calibrate {
        video: video.to_path_buf(),
        frames,
        source,
    };
    let opts = DetectorOptions {
        keep_border: true,
        ..DetectorOptions::default()
    };
    let fc = opts
        .config_for_frames(Purpose::Tracking, || {
            open().ok()?.next()?.ok().map(|f| f.image)
        })
        .map_err(|e| calib_err(CalibrateError::Calibration(e.into())))?;
    let cfg = CalibrationConfig {
        detector: fc.detector,
        layout: Default::default(),
        features: fc.features,
        track: TrackParams::DEFAULT,
    };
    let mut done = calibrate_frames(open, ReferenceSource::Still, &cfg, &mut |_, _| {
        ControlFlow::Continue(())
    })
    .map_err(calib_err)?;
    done.calibration.marker_size = fc.size;
    Ok(done.calibration)
}

/// Tracks `video`'s markers with `sensor`, or with the sensor its first frames calibrate.
pub fn track_sequence(
    video: &Path,
    sensor: Option<&SensorCalibration>,
    cfg: &SlipConfig,
) -> Result<TrackedSequence, SlipError> {
    let cal = match sensor {
        Some(s) => s.clone(),
        None => calibrate_sequence(video, cfg)?,
    };
    let frame_err = |frame: String, why: String| SlipError::Frame {
        video: video.to_path_buf(),
        frame,
        why,
    };
    let mut out = TrackedSequence {
        markers_px: cal.markers.iter().map(|m| (m.x_px, m.y_px)).collect(),
        pitch_px: cal.pitch_px,
        frames: Vec::new(),
    };
    let n = cal.markers.len();
    let set = FeatureSet {
        dx: true,
        dy: true,
        area: false,
        eccentricity: false,
    };
    let mut ex =
        FeatureExtractor::new(cal, set).map_err(|e| frame_err("-".into(), e.to_string()))?;
    ex.set_temporal_prior(cfg.temporal);
    let frames_err = |source| SlipError::Frames {
        video: video.to_path_buf(),
        source,
    };
    let mut f = FrameFeatures::default();
    let mut imprint = cfg
        .imprint
        .then(|| ImprintFollower::new(ImprintParams::DEFAULT, 1));
    for frame in FrameStream::open(&[video.to_path_buf()], IMAGE_FPS).map_err(frames_err)? {
        let frame = frame.map_err(frames_err)?;
        ex.extract_into(&frame.image, &mut f)
            .map_err(|e| frame_err(frame.id.clone(), e.to_string()))?;
        let mut d = Vec::with_capacity(n);
        displacements_into(&f, set, n, &mut d);
        out.frames.push(TrackedFrame {
            timestamp_s: frame.timestamp_s,
            id: frame.id,
            displacement_px: d,
            imprint_slide_px: imprint
                .as_mut()
                .map_or((0.0, 0.0), |f| f.update(&frame.image)),
        });
    }
    Ok(out)
}

/// A sequence's verdict.
#[derive(Clone, Debug, PartialEq)]
pub struct SlipVerdict {
    /// Whether the sequence ends slipping.
    pub slip: bool,
    /// When the final run of `slip` frames began, seconds (`None` without slip).
    pub onset_s: Option<f64>,
    /// The last frame's score.
    pub score: f64,
    /// Every frame's estimate.
    pub frames: Vec<SlipFrame>,
    /// The whole sequence's evidence.
    pub evidence: [f64; EVIDENCE_LEN],
}

/// Runs `detector` over a tracked sequence.
pub fn detect(seq: &TrackedSequence, detector: &SlipDetector) -> SlipVerdict {
    let mut m = SlipMonitor::new(detector.clone(), &seq.markers_px, seq.pitch_px);
    let frames: Vec<SlipFrame> = seq
        .frames
        .iter()
        .map(|f| {
            m.set_imprint_slide(f.imprint_slide_px);
            m.update(&f.displacement_px, f.timestamp_s)
        })
        .collect();
    verdict_of(frames, m.evidence().values())
}

/// The verdict of a sequence's frames: its last frame's state and score, and when the final
/// run of `slip` frames began.
fn verdict_of(frames: Vec<SlipFrame>, evidence: [f64; EVIDENCE_LEN]) -> SlipVerdict {
    let score = frames.last().map_or(0.0, |f| f.score);
    let slip = frames.last().is_some_and(|f| f.state == SlipState::Slip);
    let onset_s = slip
        .then(|| {
            let start = frames
                .iter()
                .rposition(|f| f.state != SlipState::Slip)
                .map_or(0, |i| i + 1);
            frames.get(start).map(|f| f.timestamp_s)
        })
        .flatten();
    SlipVerdict {
        slip,
        onset_s,
        score,
        frames,
        evidence,
    }
}

/// The score of one grasp seen by several sensors at once (a gripper's fingers, filmed
/// together) from each sensor's `scores`: the object slips against all of them, so each score
/// is evidence of the same event, taken as independent — their log-odds add.
pub fn fused_score(scores: impl IntoIterator<Item = f64>) -> f64 {
    let logit = |p: f64| {
        let p = p.clamp(1e-9, 1.0 - 1e-9);
        (p / (1.0 - p)).ln()
    };
    sigmoid(scores.into_iter().map(logit).sum())
}

/// One grasp's verdict from its sensors' `verdicts` ([`fused_score`] frame by frame, frames
/// matched by their place in each sequence, up to the shortest; each fused frame keeps the
/// first sensor's time and field signals, and the evidence is the sensors' mean).
pub fn fuse(verdicts: &[&SlipVerdict], detector: &SlipDetector) -> SlipVerdict {
    let Some(first) = verdicts.first() else {
        return verdict_of(Vec::new(), [0.0; EVIDENCE_LEN]);
    };
    let len = verdicts.iter().map(|v| v.frames.len()).min().unwrap_or(0);
    let frames = (0..len)
        .map(|k| {
            let score = fused_score(verdicts.iter().map(|v| v.frames[k].score));
            SlipFrame {
                state: detector.state_of(score),
                score,
                ..first.frames[k]
            }
        })
        .collect();
    let mut evidence = [0.0; EVIDENCE_LEN];
    for v in verdicts {
        for (e, x) in evidence.iter_mut().zip(&v.evidence) {
            *e += x / verdicts.len() as f64;
        }
    }
    verdict_of(frames, evidence)
}

/// Each video's grasp, when the videos in one folder are one grasp filmed by several sensors:
/// the index of its folder among the videos' folders, in order of first appearance.
pub fn grasps_of(videos: &[PathBuf]) -> Vec<usize> {
    let mut folders: Vec<&Path> = Vec::new();
    videos
        .iter()
        .map(|v| {
            let f = v.parent().unwrap_or(Path::new(""));
            folders.iter().position(|&g| g == f).unwrap_or_else(|| {
                folders.push(f);
                folders.len() - 1
            })
        })
        .collect()
}

/// Each sequence's verdict fused with those of the other sequences of its grasp ([`fuse`];
/// `grasp_of[i]`: sequence `i`'s grasp, as [`grasps_of`] gives).
pub fn fuse_grasps(
    verdicts: &[SlipVerdict],
    grasp_of: &[usize],
    detector: &SlipDetector,
) -> Vec<SlipVerdict> {
    (0..verdicts.len())
        .map(|i| {
            let same: Vec<&SlipVerdict> = (0..verdicts.len())
                .filter(|&j| grasp_of[j] == grasp_of[i])
                .map(|j| &verdicts[j])
                .collect();
            fuse(&same, detector)
        })
        .collect()
}

/// Frames between two snapshots of [`SequenceEvidence::prefixes`] (1 s at 25 fps).
pub const PREFIX_EVERY: usize = 25;

/// A sequence's evidence: over the whole of it, and over its beginnings.
#[derive(Clone, Debug, PartialEq)]
pub struct SequenceEvidence {
    /// Over the whole sequence (what its verdict reads).
    pub whole: [f64; EVIDENCE_LEN],
    /// Over its first 25, 50, … frames (short of the whole): what the live score read then.
    pub prefixes: Vec<[f64; EVIDENCE_LEN]>,
    /// The time of each prefix's last frame, seconds from the sequence's start.
    pub prefix_end_s: Vec<f64>,
    /// Over its first [`START_FRAMES`] frames (or all, if fewer): a grasp's start, before
    /// anything can have slipped.
    pub start: [f64; EVIDENCE_LEN],
    /// Its frames.
    pub frames: usize,
    /// Where its slip's onset was given ([`evidence_of`]), its beginnings ending within
    /// [`ONSET_FRAMES`] frames of it (before it and from it), each with the time of its last
    /// frame and its length in frames.
    pub near_onset: Vec<([f64; EVIDENCE_LEN], f64, usize)>,
}

/// Frames either side of a labelled onset whose beginnings each count in a fit
/// ([`fit_detector`]), so that the score is taught to rise at the onset's frame, not only
/// within the second of [`PREFIX_EVERY`].
pub const ONSET_FRAMES: usize = 5;

/// Frames of a sequence's start ([`SequenceEvidence::start`]): the frames a sequence
/// calibrates its reference from by default.
pub const START_FRAMES: usize = 5;

/// What is known of a sequence: whether it slipped and, when labelled, when the slip began.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SlipTruth {
    /// Whether it slipped.
    pub slip: bool,
    /// When the slip began, seconds from the sequence's start (`None`: not labelled).
    pub onset_s: Option<f64>,
}

impl From<bool> for SlipTruth {
    fn from(slip: bool) -> Self {
        Self {
            slip,
            onset_s: None,
        }
    }
}

/// The evidence of a tracked sequence under `settings`' lag and smoothing; with `onset_s`,
/// when its slip began, also its beginnings near the onset.
pub fn evidence_of(
    seq: &TrackedSequence,
    settings: &SlipSettings,
    onset_s: Option<f64>,
) -> SequenceEvidence {
    let mut t = FieldTracker::new(&seq.markers_px, seq.pitch_px, settings.lag_frames);
    let mut e = SlipEvidence::new(settings.smooth_frames);
    let mut f = FieldDynamics::default();
    let mut imprint = LagSum::new(settings.lag_frames);
    let (mut prefixes, mut prefix_end_s) = (Vec::new(), Vec::new());
    let mut start = [0.0; EVIDENCE_LEN];
    let near = onset_s.map_or(0..0, |onset| {
        let k = seq.frames.partition_point(|f| f.timestamp_s < onset);
        k.saturating_sub(ONSET_FRAMES)..k + ONSET_FRAMES
    });
    let mut near_onset = Vec::with_capacity(near.len());
    for (k, frame) in seq.frames.iter().enumerate() {
        t.update_into(&frame.displacement_px, &mut f);
        e.push(&f, imprint.push(frame.imprint_slide_px) / seq.pitch_px);
        if near.contains(&k) {
            near_onset.push((e.values(), frame.timestamp_s, k + 1));
        }
        if k + 1 == START_FRAMES.min(seq.frames.len()) {
            start = e.values();
        }
        if (k + 1) % PREFIX_EVERY == 0 && k + 1 < seq.frames.len() {
            prefixes.push(e.values());
            prefix_end_s.push(frame.timestamp_s);
        }
    }
    SequenceEvidence {
        whole: e.values(),
        prefixes,
        prefix_end_s,
        start,
        frames: seq.frames.len(),
        near_onset,
    }
}

/// Fits a detector with `settings` on sequences labelled slip or not. Each sequence counts by
/// its whole evidence, and a sequence without slip also by each of its beginnings (no slip
/// had happened there either): so that the live score stays low through a grasp that holds,
/// not only at its end. A slipping sequence's beginnings count only when its onset is
/// labelled ([`SlipTruth::onset_s`]): those ending before it as no slip, the others as slip,
/// every second and at every frame within [`ONSET_FRAMES`] of the onset, so that the score
/// rises at the frame the slip begins. A still field (no marker moved) counts as no
/// slip too, as often as there are slipping sequences. Both classes weigh the same.
pub fn fit_detector(
    evidence: &[SequenceEvidence],
    truth: &[SlipTruth],
    settings: &SlipSettings,
) -> Result<SlipDetector, SlipError> {
    let pos = truth.iter().filter(|t| t.slip).count();
    if pos == 0 || pos == truth.len() {
        return Err(SlipError::OneClass {
            slip: pos,
            stick: truth.len() - pos,
        });
    }
    // A skin that has not moved has not slipped: the evidence of a still field (every
    // statistic 0), once per no-slip sequence, so that it weighs as a sequence of its own.
    let still = if settings.stick_prefixes {
        pos.min(truth.len() - pos)
    } else {
        0
    };
    let mut rows: Vec<[f64; EVIDENCE_LEN]> = vec![[0.0; EVIDENCE_LEN]; still];
    let mut labels = vec![false; still];
    let mut min_frames = PREFIX_EVERY;
    for (e, t) in evidence.iter().zip(truth) {
        rows.push(e.whole);
        labels.push(t.slip);
        min_frames = min_frames.min(e.frames.max(1));
        // A beginning is known not to have slipped, or (onset labelled) whether it had.
        if settings.stick_prefixes && (!t.slip || t.onset_s.is_some()) {
            rows.extend_from_slice(&e.prefixes);
            labels.extend(
                e.prefix_end_s
                    .iter()
                    .map(|&end| t.onset_s.is_some_and(|onset| t.slip && end >= onset)),
            );
        }
        if let (true, Some(onset)) = (settings.stick_prefixes && t.slip, t.onset_s) {
            for &(v, end, frames) in &e.near_onset {
                min_frames = min_frames.min(frames);
                rows.push(v);
                labels.push(end >= onset);
            }
        }
    }
    let mut d = fit_rows(&rows, &labels, settings);
    d.fitted_on = [truth.len(), pos];
    d.min_frames = min_frames;
    Ok(d)
}

/// The logistic regression of `labels` on the standardised `rows`.
fn fit_rows(rows: &[[f64; EVIDENCE_LEN]], labels: &[bool], like: &SlipSettings) -> SlipDetector {
    let n = rows.len().max(1) as f64;
    let mut center = vec![0.0; EVIDENCE_LEN];
    let mut scale = vec![0.0; EVIDENCE_LEN];
    for j in 0..EVIDENCE_LEN {
        center[j] = rows.iter().map(|e| e[j]).sum::<f64>() / n;
        let var = rows.iter().map(|e| (e[j] - center[j]).powi(2)).sum::<f64>() / n;
        scale[j] = if var > 1e-18 { var.sqrt() } else { 1.0 };
    }
    let x: Vec<Vec<f64>> = rows
        .iter()
        .map(|e| {
            (0..EVIDENCE_LEN)
                .map(|j| (e[j] - center[j]) / scale[j])
                .collect()
        })
        .collect();
    let fit = fit_logistic(&x, labels, &LogisticConfig::default());
    SlipDetector {
        format: FORMAT.into(),
        version: 1,
        lag_frames: like.lag_frames,
        smooth_frames: like.smooth_frames,
        inputs: SlipEvidence::names(),
        center,
        scale,
        weights: fit.weights,
        bias: fit.bias,
        threshold: like.threshold,
        incipient_threshold: like.incipient_threshold,
        fitted_on: [rows.len(), labels.iter().filter(|&&y| y).count()],
        min_frames: PREFIX_EVERY,
    }
}

/// The sequences among `paths`: a video file is one, a folder of images is one (its images in
/// name order, at 25 fps: a recorded or simulated session's `frames/`), and any other folder
/// holds every video and folder of images under it (sorted).
pub fn sequences_in(paths: &[PathBuf]) -> Result<Vec<PathBuf>, SlipError> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) -> std::io::Result<()> {
        let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)?
            .map(|e| e.map(|e| e.path()))
            .collect::<Result<_, _>>()?;
        entries.sort();
        // A folder of images (a recorded session's `frames/`) is one sequence.
        if entries.iter().any(|p| p.is_file() && is_image_path(p)) {
            out.push(dir.to_path_buf());
            return Ok(());
        }
        for p in entries {
            if p.is_dir() {
                walk(&p, out)?;
            } else if is_video_path(&p) {
                out.push(p);
            }
        }
        Ok(())
    }
    let mut out = Vec::new();
    for p in paths {
        if p.is_dir() {
            let before = out.len();
            walk(p, &mut out).map_err(|source| SlipError::Frames {
                video: p.clone(),
                source: FrameError::Io {
                    path: p.clone(),
                    source,
                },
            })?;
            if out.len() == before {
                return Err(SlipError::NoSequence {
                    path: p.clone(),
                    why:
                        "folder has no video (avi, mp4, mkv, mov, webm, m4v, mpg, mpeg) nor images \
                          (png, jpg, ppm) under it",
                });
            }
        } else if is_video_path(p) {
            out.push(p.clone());
        } else {
            return Err(SlipError::NoSequence {
                path: p.clone(),
                why: "expected a video (avi, mp4, mkv, mov, webm, m4v, mpg, mpeg) or a folder of them",
            });
        }
    }
    Ok(out)
}

/// Tracks every sequence in parallel; `progress(done, total)` may stop the pass.
pub fn track_sequences(
    videos: &[PathBuf],
    sensor: Option<&SensorCalibration>,
    cfg: &SlipConfig,
    progress: &(dyn Fn(usize, usize) -> ControlFlow<()> + Sync),
) -> Result<Vec<TrackedSequence>, SlipError> {
    let (done, stop) = (AtomicUsize::new(0), AtomicBool::new(false));
    let total = videos.len();
    let out: Vec<Result<TrackedSequence, SlipError>> = videos
        .par_iter()
        .map(|v| {
            if stop.load(Ordering::Relaxed) {
                return Err(SlipError::Stopped { done: 0, total });
            }
            let r = track_sequence(v, sensor, cfg);
            let d = done.fetch_add(1, Ordering::Relaxed) + 1;
            if progress(d, total).is_break() {
                stop.store(true, Ordering::Relaxed);
            }
            r
        })
        .collect();
    if stop.load(Ordering::Relaxed) {
        return Err(SlipError::Stopped {
            done: done.load(Ordering::Relaxed),
            total,
        });
    }
    out.into_iter().collect()
}

/// The CSV of verdicts: one row per sequence (`video,slip,onset_s,score`), or with
/// `per_frame` one per frame (`video,frame,timestamp_s,state,score` and the field's signals).
pub fn verdicts_csv(
    verdicts: &[(PathBuf, &TrackedSequence, SlipVerdict)],
    per_frame: bool,
) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    if per_frame {
        s.push_str("video,frame,timestamp_s,state,score");
        for n in FieldDynamics::NAMES {
            let _ = write!(s, ",{n}");
        }
        s.push('\n');
    } else {
        s.push_str("video,slip,onset_s,score\n");
    }
    for (video, seq, v) in verdicts {
        let name = video.display();
        if !per_frame {
            let onset = v.onset_s.map_or(String::new(), |t| format!("{t:.3}"));
            let _ = writeln!(s, "{name},{},{onset},{:.4}", u8::from(v.slip), v.score);
            continue;
        }
        for (frame, f) in seq.frames.iter().zip(&v.frames) {
            let id = &frame.id;
            let _ = write!(
                s,
                "{name},{id},{:.4},{},{:.4}",
                f.timestamp_s,
                f.state.name(),
                f.score
            );
            for x in f.field.signals() {
                let _ = write!(s, ",{x:.5}");
            }
            s.push('\n');
        }
    }
    s
}

#[cfg(test)]
mod tests;
