//! Live estimation: the per-frame [`Estimator`] plus what a running sensor needs around it —
//! a no-contact baseline that follows the skin's slow drift (re-zeroing), a contact rule on the
//! markers' motion against their calibration jitter, marker health, an ensemble over several
//! model files, and the estimate every live output sends ([`LiveEstimate`], one JSON line).
//! `visuotact run` and its dashboard call it; so can any program with frames.

use serde::Serialize;
use visuotact_image::RgbImage;
use visuotact_nn::model::{EstimateScratch, Model};
use visuotact_vision::features::{FieldSummary, FIELD_COLUMNS};
use visuotact_vision::track::MarkerStatus;

use crate::estimator::Input;
use crate::slip::{SlipDetector, SlipEstimate, SlipMonitor};
use crate::{Estimator, PipelineError};

/// The contact and re-zeroing rules of [`LiveEstimator`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LiveConfig {
    /// Contact when at least [`LiveConfig::contact_markers`] markers move more than this many
    /// times their calibration jitter …
    pub contact_sigmas: f64,
    /// … and more than this many pixels, against the no-contact baseline.
    pub contact_min_px: f64,
    /// Markers that must move for contact (one noisy or half-visible marker is not a touch).
    pub contact_markers: usize,
    /// The baseline follows no-contact frames with this weight per frame (0: only
    /// [`LiveEstimator::rezero_now`] moves it).
    pub rezero_rate: f64,
    /// Estimate every frame, touched or not. Off, a frame without contact gets no targets and
    /// its slip state is `stick`: the skin at rest is not read for a load it does not carry.
    pub estimate_without_contact: bool,
}

impl LiveConfig {
    /// A live sensor (`run`): contact when 3 markers move 5 σ and 0.5 px; the baseline
    /// follows no-contact frames at 0.05 per frame; only frames in contact are estimated.
    pub const LIVE: Self = Self {
        contact_sigmas: 5.0,
        contact_min_px: 0.5,
        contact_markers: 3,
        rezero_rate: 0.05,
        estimate_without_contact: false,
    };

    /// An offline pass over recorded frames (`record`, `replay`): every frame estimated
    /// against the sensor's own reference (the baseline never moves), so a table's row
    /// depends on its frame (and, tracking frames in order, on those before it), never on
    /// when contact began. Contact and marker health are still reported; slip follows the
    /// whole pass as one sequence.
    pub const OFFLINE: Self = Self {
        rezero_rate: 0.0,
        estimate_without_contact: true,
        ..Self::LIVE
    };

    /// Refuses settings that mean nothing: a threshold that is not a number or below 0, no
    /// marker needed for contact, a re-zeroing weight outside 0–1.
    pub fn validate(&self) -> Result<(), PipelineError> {
        let bad = |name: &str, v: f64, range: &str| {
            Err(PipelineError::Setting(format!(
                "{name} {v}: expected {range}"
            )))
        };
        if !(self.contact_sigmas.is_finite() && self.contact_sigmas >= 0.0) {
            return bad(
                "contact_sigmas",
                self.contact_sigmas,
                "a number of σ, 0 or more",
            );
        }
        if !(self.contact_min_px.is_finite() && self.contact_min_px >= 0.0) {
            return bad("contact_min_px", self.contact_min_px, "pixels, 0 or more");
        }
        if self.contact_markers == 0 {
            return Err(PipelineError::Setting(
                "contact_markers 0: expected 1 or more markers".into(),
            ));
        }
        if !(0.0..=1.0).contains(&self.rezero_rate) {
            return bad(
                "rezero_rate",
                self.rezero_rate,
                "a weight from 0 to 1 per frame",
            );
        }
        Ok(())
    }
}

impl Default for LiveConfig {
    /// [`LiveConfig::LIVE`].
    fn default() -> Self {
        Self::LIVE
    }
}

/// One target's estimate.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct TargetEstimate {
    /// The target's name with its unit (`x_mm`).
    pub name: String,
    /// The ensemble's mean.
    pub value: f64,
    /// How far off the value may be, as `predict`'s `<target>_std`: the larger of the
    /// standard deviation over the ensemble's networks and the held-out error nearest the
    /// estimate ([`visuotact_nn::model::Model::widen_spread`]); absent with one network
    /// and no held-out table.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub std: Option<f64>,
}

/// Marker health counts.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct Health {
    /// Markers found where expected.
    pub ok: usize,
    /// Markers not found.
    pub lost: usize,
    /// Markers merged with a neighbour.
    pub merged: usize,
    /// Markers with two candidates.
    pub ambiguous: usize,
    /// Markers split from a merged pair: a position, no area.
    pub split: usize,
    /// Inputs the model filled this frame (lost markers, from the markers found).
    pub filled: usize,
    /// Markers whose no-contact baseline moved away from the calibration.
    pub drifting: usize,
    /// The sensor's reference was taken under contact (`calibrate --reference lightest:N`
    /// on a data set with no contact-free frame): displacements are relative to a lightly
    /// pressed skin.
    pub reference_under_contact: bool,
}

/// One frame's result from [`LiveEstimator::process`].
#[derive(Clone, Debug, PartialEq)]
pub struct LiveFrame {
    /// Whether the skin is touched (the contact rule).
    pub contact: bool,
    /// Largest marker displacement from the baseline, pixels.
    pub max_displacement_px: f64,
    /// The estimate (empty without contact, a model, or enough markers).
    pub targets: Vec<TargetEstimate>,
    /// Marker health.
    pub health: Health,
    /// The slip state, when a detector was given ([`LiveEstimator::set_slip`]).
    pub slip: Option<SlipEstimate>,
}

impl LiveFrame {
    fn new(
        contact: bool,
        max_displacement_px: f64,
        targets: Vec<TargetEstimate>,
        health: Health,
    ) -> Self {
        Self {
            contact,
            max_displacement_px,
            targets,
            health,
            slip: None,
        }
    }
}

/// One estimate, as every live output sends it (a JSON line on standard output, a UDP
/// datagram, a WebSocket message).
#[derive(Clone, Debug, Serialize)]
pub struct LiveEstimate {
    /// The sensor's name in a run of several ([`crate::several::run_several`]): every output
    /// keeps each sensor's estimates under its own name. Absent for a single sensor.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sensor: Option<String>,
    /// The frame's name.
    pub frame: String,
    /// Its place in the source.
    pub index: u64,
    /// Capture time on the run's clock, seconds.
    pub timestamp_s: f64,
    /// Capture → estimate, milliseconds.
    pub latency_ms: f64,
    /// Frame in memory → estimate, milliseconds.
    pub processing_ms: f64,
    /// Whether the skin is touched.
    pub contact: bool,
    /// Largest marker displacement from the baseline, pixels.
    pub max_displacement_px: f64,
    /// Targets (empty when there is no contact or a needed marker was lost).
    pub targets: Vec<TargetEstimate>,
    /// Marker health.
    pub health: Health,
    /// Frames dropped by the capture queue so far.
    pub dropped_frames: u64,
    /// The slip state and score (`run --slip`): absent without a slip detector.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slip: Option<SlipEstimate>,
    /// The sensor's scale (`calibrate --pitch-mm`), for outputs that give the markers'
    /// displacements in millimetres too; not in the JSON line.
    #[serde(skip)]
    pub mm_per_px: Option<f64>,
}

impl LiveEstimate {
    /// The value of target `name` (`depth_mm`), if estimated for this frame (targets are
    /// empty without contact).
    pub fn get(&self, name: &str) -> Option<f64> {
        self.targets
            .iter()
            .find(|t| t.name == name)
            .map(|t| t.value)
    }
}

/// Marker drawing data for the dashboard: position, displacement from the baseline, status.
#[derive(Clone, Debug, Serialize)]
pub struct MarkerView {
    /// Calibrated position, pixels.
    pub x: f32,
    /// Calibrated position, pixels.
    pub y: f32,
    /// Displacement from the baseline, pixels (0 when lost).
    pub dx: f32,
    /// Displacement from the baseline, pixels (0 when lost).
    pub dy: f32,
    /// Whether the marker has a position this frame.
    pub ok: bool,
}

/// The per-frame estimator state: baseline, contact rule, ensemble.
pub struct LiveEstimator {
    /// The markers' rest positions (the field summary's centroid).
    rest_px: Vec<(f64, f64)>,
    est: Estimator,
    ensemble: Vec<Model>,
    /// Where each model's inputs come from.
    cols: Vec<Vec<Input>>,
    baseline: Vec<f64>,
    /// Whether the baseline has moved from the calibration (re-zeroed).
    rezeroed: bool,
    jitter: Vec<f64>,
    /// Indices of each marker's dx and dy in the feature vector.
    xy: Vec<Option<(usize, usize)>>,
    /// Calibrated marker positions, pixels.
    marker_px: Vec<(f32, f32)>,
    cfg: LiveConfig,
    zeroed: Vec<f64>,
    /// This frame's marker statuses.
    status: Vec<MarkerStatus>,
    /// The sensor's name in a run of several.
    name: Option<String>,
    /// The ensemble's input row (kept between frames).
    x: Vec<f64>,
    /// Each model's estimation buffers (kept between frames).
    scratch: Vec<EstimateScratch>,
    /// Every network's outputs, one row per network (kept between frames).
    outputs: Vec<f64>,
    /// The slip detector following the frames, and its displacement buffer.
    slip: Option<SlipMonitor>,
    /// Whether the last frame was in contact (a new contact starts a new slip sequence).
    was_contact: bool,
}

impl LiveEstimator {
    /// Live estimation with `est`'s sensor and `models` as one ensemble (every network of
    /// every model counts; none: contact and marker health only), by `cfg`'s contact and
    /// re-zeroing rules. The models must estimate the same targets from `est`'s features.
    pub fn new(
        est: Estimator,
        models: Vec<Model>,
        cfg: &LiveConfig,
    ) -> Result<Self, PipelineError> {
        cfg.validate()?;
        let names = est.feature_columns();
        let cols = models
            .iter()
            .enumerate()
            .map(|(k, m)| {
                est.inputs_of(m).map_err(|e| PipelineError::Ensemble {
                    model: k + 1,
                    why: e.to_string(),
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        if let Some(k) = models
            .iter()
            .position(|m| m.target_columns != models[0].target_columns)
        {
            return Err(PipelineError::Ensemble {
                model: k + 1,
                why: format!(
                    "estimates {} where the first model estimates {}",
                    models[k].target_columns.join(", "),
                    models[0].target_columns.join(", ")
                ),
            });
        }
        let set = est.feature_set();
        let per_marker = [set.dx, set.dy, set.area, set.eccentricity]
            .iter()
            .filter(|b| **b)
            .count();
        let cal = est.calibration();
        let xy = (0..cal.markers.len())
            .map(|m| (set.dx && set.dy).then_some((m * per_marker, m * per_marker + 1)))
            .collect();
        let marker_px: Vec<(f32, f32)> = cal
            .markers
            .iter()
            .map(|m| (m.x_px as f32, m.y_px as f32))
            .collect();
        let jitter: Vec<f64> = cal
            .markers
            .iter()
            .map(|m| m.jitter_px.unwrap_or(0.0))
            .collect();
        let rest_px = cal.markers.iter().map(|m| (m.x_px, m.y_px)).collect();
        Ok(Self {
            rest_px,
            baseline: vec![0.0; names.len()],
            rezeroed: false,
            est,
            cols,
            jitter,
            xy,
            marker_px,
            cfg: LiveConfig {
                contact_markers: cfg.contact_markers.max(1),
                ..*cfg
            },
            zeroed: Vec::new(),
            status: Vec::new(),
            name: None,
            x: Vec::new(),
            scratch: vec![EstimateScratch::default(); models.len()],
            outputs: Vec::new(),
            ensemble: models,
            slip: None,
            was_contact: false,
        })
    }

    /// Live estimation with `est` and its own model, if it has one (an ensemble of one), by
    /// `cfg`'s rules. A model with inputs besides the marker features
    /// ([`Estimator::with_extra_inputs`]) takes their values with each frame
    /// ([`LiveEstimator::process_with`]).
    pub fn from_estimator(est: Estimator, cfg: &LiveConfig) -> Result<Self, PipelineError> {
        let (est, model) = est.without_model();
        Self::new(est, model.into_iter().collect(), cfg)
    }

    /// Follows the frames with a slip detector: every frame then carries its slip state
    /// ([`LiveFrame::slip`]), from the markers' displacements from the sensor's reference.
    /// Each contact is one sequence: the detector starts afresh when a contact begins (and on
    /// re-zeroing), and reads it from its [`SlipDetector::min_frames`]-th frame. Nothing slips
    /// without contact: a frame without one is `stick` with score 0 and no field signals (the
    /// markers' noise at rest is no evidence). Needs a feature set with `dx` and `dy`.
    pub fn set_slip(&mut self, detector: SlipDetector) -> Result<(), PipelineError> {
        self.slip = Some(SlipMonitor::for_estimator(detector, &self.est)?);
        Ok(())
    }

    /// Names the sensor: its estimates carry the name ([`LiveEstimate::sensor`]).
    pub fn set_sensor_name(&mut self, name: &str) {
        self.name = Some(name.to_string());
    }

    /// The sensor's name, when it has one.
    pub fn sensor_name(&self) -> Option<&str> {
        self.name.as_deref()
    }

    /// The targets estimated (empty without a model).
    pub fn target_names(&self) -> Vec<String> {
        self.ensemble
            .first()
            .map(|m| m.target_columns.clone())
            .unwrap_or_default()
    }

    /// The estimate's columns as tables hold them: the targets, then each target's spread
    /// (`<target>_std`) when the ensemble has several networks or keeps held-out errors
    /// ([`TargetEstimate::std`]); empty without a model.
    pub fn estimate_columns(&self) -> Vec<String> {
        let names = self.target_names();
        let spread = self.ensemble.len() > 1
            || self
                .ensemble
                .iter()
                .any(|m| !m.members.is_empty() || m.held_out.is_some());
        let stds: Vec<String> = names.iter().map(|t| format!("{t}_std")).collect();
        let mut columns = names;
        if spread {
            columns.extend(stds);
        }
        columns
    }

    /// The contact, re-zeroing and estimation rules in use.
    pub fn config(&self) -> &LiveConfig {
        &self.cfg
    }

    /// The per-frame estimator: the features, their columns and the sensor (its model, if it
    /// had one, is in this ensemble).
    pub fn estimator(&self) -> &Estimator {
        &self.est
    }

    /// The displacement field's signals the slip detector read on the last frame
    /// ([`visuotact_vision::field::FieldDynamics::NAMES`]); `None` without a detector.
    pub fn slip_signals(
        &self,
    ) -> Option<[f64; visuotact_vision::field::FieldDynamics::NAMES.len()]> {
        self.slip.as_ref().map(|m| m.field().signals())
    }

    /// Sets the baseline to the current frame's features (the re-zero button).
    pub fn rezero_now(&mut self) {
        self.rezeroed = true;
        if let Some(m) = self.slip.as_mut() {
            m.reset();
        }
        let n = self.marker_values();
        for (b, z) in self.baseline[..n].iter_mut().zip(&self.zeroed) {
            if z.is_finite() {
                *b += z;
            }
        }
    }

    /// How many feature values are the markers' (the field summary follows them).
    fn marker_values(&self) -> usize {
        self.baseline.len().saturating_sub(FIELD_COLUMNS.len())
    }

    /// Processes one frame; `markers` gets the drawing data when asked for. Without contact
    /// (unless [`LiveConfig::estimate_without_contact`]), or when the models cannot estimate
    /// the frame (too many markers lost), the targets are empty: no estimate rather than a
    /// wrong one.
    pub fn process(
        &mut self,
        img: &RgbImage,
        markers: Option<&mut Vec<MarkerView>>,
    ) -> Result<LiveFrame, PipelineError> {
        self.process_with(img, &[], markers)
    }

    /// As [`LiveEstimator::process`], with the values of the models' inputs besides the
    /// marker features for this frame (in the order of [`Estimator::extra_inputs`]); a
    /// missing or NaN value gives no estimate.
    pub fn process_with(
        &mut self,
        img: &RgbImage,
        extra: &[f64],
        markers: Option<&mut Vec<MarkerView>>,
    ) -> Result<LiveFrame, PipelineError> {
        // Features only: the ensemble below predicts on the re-zeroed ones.
        let f = self.est.features(img)?;
        self.zeroed.clear();
        self.zeroed
            .extend(f.values.iter().zip(&self.baseline).map(|(v, b)| v - b));
        self.status.clear();
        self.status.extend_from_slice(&f.status);
        if self.rezeroed {
            self.rezero_field();
        }
        let (mut health, max_disp, moved) = self.motion();
        let contact = moved >= self.cfg.contact_markers.min(self.marker_px.len().max(1));
        let estimating = contact || self.cfg.estimate_without_contact;
        let slip = self.slip_of(estimating, img);
        if let Some(out) = markers {
            self.marker_views(out);
        }
        // No contact: follow the rest position (automatic re-zeroing).
        if !contact {
            self.follow_rest();
        }
        let targets = if estimating {
            self.ensemble_targets(extra, &mut health)
        } else {
            Vec::new()
        };
        let mut out = LiveFrame::new(contact, max_disp, targets, health);
        out.slip = slip;
        Ok(out)
    }

    /// The slip state of this frame's displacements: each contact (each run of frames
    /// estimated) is a sequence of its own, followed from its first frame until it ends;
    /// without contact, `stick`.
    fn slip_of(&mut self, contact: bool, img: &RgbImage) -> Option<SlipEstimate> {
        let monitor = self.slip.as_mut()?;
        if contact && !self.was_contact {
            monitor.reset();
        }
        self.was_contact = contact;
        if !contact {
            return Some(SlipEstimate::without_contact());
        }
        monitor.observe_frame(img);
        Some(monitor.estimate_features(self.est.last_features(), self.est.feature_set()))
    }

    /// The field summary of the re-zeroed displacements (the baseline never moves it).
    fn rezero_field(&mut self) {
        let n = self.marker_values();
        if self.zeroed.len() == n + FIELD_COLUMNS.len() && self.xy.iter().all(Option::is_some) {
            let zeroed = &self.zeroed;
            let field = FieldSummary::of(self.rest_px.iter().zip(&self.xy).map(|(&p, xy)| {
                let d = xy
                    .map(|(ix, iy)| (zeroed[ix], zeroed[iy]))
                    .filter(|d| d.0.is_finite() && d.1.is_finite());
                (p, d)
            }));
            self.zeroed[n..].copy_from_slice(&field.map_or([f64::NAN; 6], |f| f.values()));
        }
    }

    /// The markers' health, the largest re-zeroed displacement, and how many markers moved
    /// beyond the contact rule.
    fn motion(&self) -> (Health, f64, usize) {
        let mut health = Health {
            reference_under_contact: self.est.calibration().reference.under_contact,
            ..Health::default()
        };
        let (mut max_disp, mut moved) = (0.0f64, 0usize);
        for (m, st) in self.status.iter().enumerate() {
            match st {
                MarkerStatus::Ok => health.ok += 1,
                MarkerStatus::Lost => health.lost += 1,
                MarkerStatus::Merged => health.merged += 1,
                MarkerStatus::Ambiguous => health.ambiguous += 1,
                MarkerStatus::Split => health.split += 1,
            }
            let Some((ix, iy)) = self.xy[m] else { continue };
            let d = self.zeroed[ix].hypot(self.zeroed[iy]);
            if d.is_finite() {
                max_disp = max_disp.max(d);
                let threshold = self
                    .cfg
                    .contact_min_px
                    .max(self.cfg.contact_sigmas * self.jitter[m]);
                moved += usize::from(d > threshold);
            }
            let drift = self.baseline[ix].hypot(self.baseline[iy]);
            if drift > 0.5f64.max(3.0 * self.jitter[m]) {
                health.drifting += 1;
            }
        }
        (health, max_disp, moved)
    }

    /// The markers' positions and re-zeroed displacements, for drawing.
    fn marker_views(&self, out: &mut Vec<MarkerView>) {
        out.clear();
        for (m, &(x, y)) in self.marker_px.iter().enumerate() {
            let (dx, dy) =
                self.xy[m].map_or((0.0, 0.0), |(ix, iy)| (self.zeroed[ix], self.zeroed[iy]));
            out.push(MarkerView {
                x,
                y,
                dx: if dx.is_finite() { dx as f32 } else { 0.0 },
                dy: if dy.is_finite() { dy as f32 } else { 0.0 },
                ok: self.status[m].has_position(),
            });
        }
    }

    /// Automatic re-zeroing: the baseline follows a no-contact frame.
    fn follow_rest(&mut self) {
        if self.cfg.rezero_rate > 0.0 {
            self.rezeroed = true;
            let n = self.marker_values();
            for (b, z) in self.baseline[..n].iter_mut().zip(&self.zeroed) {
                if z.is_finite() {
                    *b += self.cfg.rezero_rate * z;
                }
            }
        }
    }

    /// The ensemble's estimate of the re-zeroed features (and the `extra` inputs): every
    /// network of every model file counts (each file scales and projects its inputs once for
    /// all its networks), its mean and standard deviation computed as one model file's
    /// ([`Model::estimate_into`]), so a single file gives its own numbers. Lost markers are
    /// filled by models on principal components; otherwise, or with too many lost, no targets
    /// this frame.
    fn ensemble_targets(&mut self, extra: &[f64], health: &mut Health) -> Vec<TargetEstimate> {
        let Some(first) = self.ensemble.first() else {
            return Vec::new();
        };
        let width = first.target_columns.len();
        self.outputs.clear();
        for ((m, cols), scratch) in self.ensemble.iter().zip(&self.cols).zip(&mut self.scratch) {
            self.x.clear();
            self.x.extend(cols.iter().map(|&c| match c {
                Input::Feature(i, k) => self.zeroed[i] * k,
                Input::Extra(j) => extra.get(j).copied().unwrap_or(f64::NAN),
            }));
            if self.x.iter().any(|v| v.is_infinite()) {
                return Vec::new();
            }
            let Ok(filled) = m.estimate_each_into(&self.x, scratch) else {
                return Vec::new();
            };
            health.filled = health.filled.max(filled);
            scratch
                .outputs()
                .iter()
                .for_each(|o| self.outputs.extend_from_slice(o));
        }
        let networks = self.outputs.len() / width.max(1);
        let n = networks as f64;
        let column = |j: usize| self.outputs.iter().skip(j).step_by(width.max(1));
        let means: Vec<f64> = (0..width).map(|j| column(j).sum::<f64>() / n).collect();
        let mut std: Vec<f64> = means
            .iter()
            .enumerate()
            .map(|(j, mean)| {
                if networks > 1 {
                    (column(j).map(|o| (o - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
                } else {
                    0.0
                }
            })
            .collect();
        // As `predict`'s `<target>_std`: raised to the held-out error nearest the estimate (the
        // largest over the files keeping one).
        let mut held = false;
        for (m, scratch) in self.ensemble.iter().zip(&mut self.scratch) {
            held |= m.widen_spread(&means, scratch, &mut std);
        }
        first
            .target_columns
            .iter()
            .zip(means.iter().zip(&std))
            .map(|(name, (&value, &std))| TargetEstimate {
                name: name.clone(),
                value,
                std: (networks > 1 || held).then_some(std),
            })
            .collect()
    }

    /// The sensor calibration in use.
    pub fn calibration(&self) -> &visuotact_vision::calibration::SensorCalibration {
        self.est.calibration()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::slip::SlipState;
    use visuotact_nn::fit::{fit, quietly, FitConfig, FitData};
    use visuotact_sim::iats::{render, IatsConfig, Touch};

    fn sensor() -> Estimator {
        Estimator::new(Some(crate::test_support::iats_sensor()), None).unwrap()
    }

    /// A one-input model of `target` on the field summary's RMS displacement.
    fn tiny_model(target: &str) -> Model {
        let x: Vec<Vec<f64>> = (0..20).map(|i| vec![f64::from(i)]).collect();
        let t: Vec<Vec<f64>> = x.iter().map(|r| vec![0.1 * r[0]]).collect();
        let (columns, targets) = (["field_rms_px".to_string()], [target.to_string()]);
        let data = FitData {
            x: &x,
            t: &t,
            feature_columns: &columns,
            targets: &targets,
        };
        let cfg = FitConfig {
            hidden: vec![2],
            ensemble: 2,
            max_epochs: 20,
            ..FitConfig::default()
        };
        fit(&data, &cfg, quietly).unwrap()
    }

    #[test]
    fn a_slip_detector_gives_every_frame_a_state_sticks_without_contact_and_starts_afresh() {
        let cfg = IatsConfig::SEED000;
        let mut live = LiveEstimator::new(sensor(), vec![], &LiveConfig::default()).unwrap();
        assert!(live
            .process(&render(&cfg, &Touch::default(), 3).unwrap().0, None)
            .unwrap()
            .slip
            .is_none());
        live.set_slip(SlipDetector::default()).unwrap();
        let touch = |k: usize| Touch {
            x_mm: 20.0 + 2.0 * k as f64,
            y_mm: 22.0,
            depth_mm: 3.0,
            ..Touch::default()
        };
        let mut first_of_contact = Vec::new();
        for round in 0..2 {
            for k in 0..3 {
                let r = live
                    .process(&render(&cfg, &Touch::default(), 20 + k).unwrap().0, None)
                    .unwrap();
                let s = r.slip.unwrap();
                assert!(
                    !r.contact && s.state == SlipState::Stick && s.score == 0.0,
                    "{s:?}"
                );
            }
            for k in 0..4 {
                let r = live
                    .process(&render(&cfg, &touch(k), 30 + k as u64).unwrap().0, None)
                    .unwrap();
                let s = r.slip.unwrap();
                assert!(
                    r.contact && (0.0..=1.0).contains(&s.score),
                    "{round} {k}: {r:?}"
                );
                if k == 0 {
                    first_of_contact.push(s.score);
                }
            }
        }
        assert_eq!(
            first_of_contact[0], first_of_contact[1],
            "each contact is a sequence of its own"
        );
        let mut cal = sensor().calibration().clone();
        cal.features = visuotact_vision::features::FeatureSet::parse("area").unwrap();
        let mut live = LiveEstimator::new(
            Estimator::new(Some(cal), None).unwrap(),
            vec![],
            &LiveConfig::default(),
        )
        .unwrap();
        let e = live
            .set_slip(SlipDetector::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("must include x and y"), "{e}");
    }

    #[test]
    fn contact_health_and_the_estimate_follow_the_skin() {
        let cfg = IatsConfig::SEED000;
        let model = tiny_model("a_mm");
        let mut live =
            LiveEstimator::new(sensor(), vec![model.clone(), model], &LiveConfig::default())
                .unwrap();
        assert_eq!(live.target_names(), ["a_mm"]);
        let rest = render(&cfg, &Touch::default(), 9).unwrap().0;
        let mut views = Vec::new();
        let r = live.process(&rest, Some(&mut views)).unwrap();
        assert!(!r.contact && r.targets.is_empty(), "{r:?}");
        assert_eq!((r.health.ok, r.health.lost), (117, 0));
        assert!(r.max_displacement_px < 0.5, "{r:?}");
        assert_eq!(views.len(), 117);
        let press = Touch {
            x_mm: 30.0,
            y_mm: 22.0,
            depth_mm: 3.0,
            ..Touch::default()
        };
        let r = live
            .process(&render(&cfg, &press, 10).unwrap().0, None)
            .unwrap();
        assert!(r.contact && r.max_displacement_px > 1.0, "{r:?}");
        // Four networks in two files (two on other seeds in each): a mean and a spread.
        assert_eq!(r.targets.len(), 1);
        let (value, std) = (r.targets[0].value, r.targets[0].std.unwrap());
        assert!(value.is_finite() && std > 0.0 && std.is_finite(), "{r:?}");
        // A model file keeping held-out errors (7 everywhere, above the networks' spread):
        // the spread is `predict`'s, the held-out error nearest the estimate.
        let mut held = tiny_model("a_mm");
        held.held_out = visuotact_nn::heldout::HeldOutErrors::new(
            (0..40).map(|i| vec![f64::from(i) / 20.0 - 1.0]).collect(),
            vec![vec![7.0]; 40],
        );
        let mut live = LiveEstimator::new(sensor(), vec![held], &LiveConfig::default()).unwrap();
        live.process(&rest, None).unwrap();
        let r = live
            .process(&render(&cfg, &press, 10).unwrap().0, None)
            .unwrap();
        assert_eq!(r.targets[0].std, Some(7.0), "{r:?}");
        assert!(
            (r.targets[0].value - value).abs() < 1e-9,
            "the same networks: {r:?}"
        );
    }

    /// The offline rules estimate every frame with the numbers of the per-frame estimator,
    /// spread included; the live rules leave a frame at rest unestimated.
    #[test]
    fn an_offline_pass_estimates_every_frame_as_the_per_frame_estimator_does() {
        let cfg = IatsConfig::SEED000;
        let model = tiny_model("a_mm");
        assert!(!model.members.is_empty());
        let with_model = || sensor().with_model(model.clone()).unwrap();
        let mut one = with_model();
        let mut offline =
            LiveEstimator::from_estimator(with_model(), &LiveConfig::OFFLINE).unwrap();
        let mut live = LiveEstimator::from_estimator(with_model(), &LiveConfig::LIVE).unwrap();
        assert_eq!(offline.estimate_columns(), one.target_columns());
        let press = Touch {
            x_mm: 30.0,
            y_mm: 22.0,
            depth_mm: 3.0,
            ..Touch::default()
        };
        for (touch, seed) in [(Touch::default(), 9), (press, 10)] {
            let img = render(&cfg, &touch, seed).unwrap().0;
            let want = one.estimate(&img).unwrap();
            let got = offline.process(&img, None).unwrap();
            assert_eq!(got.targets.len(), 1, "{got:?}");
            assert_eq!(got.targets[0].value, want.get("a_mm").unwrap());
            assert_eq!(got.targets[0].std, want.spread("a_mm"));
            let r = live.process(&img, None).unwrap();
            assert_eq!(r.targets.is_empty(), !r.contact, "{r:?}");
            assert_eq!(r.contact, seed == 10, "{r:?}");
        }
    }

    #[test]
    fn an_ensemble_of_different_targets_is_refused() {
        let err = LiveEstimator::new(
            sensor(),
            vec![tiny_model("a_mm"), tiny_model("b_mm")],
            &LiveConfig::default(),
        )
        .err()
        .unwrap();
        assert!(
            matches!(&err, PipelineError::Ensemble { model: 2, why } if why.contains("b_mm")),
            "{err}"
        );
    }

    #[test]
    fn meaningless_contact_and_rezero_settings_are_refused() {
        let ok = LiveConfig::default();
        assert!(ok.validate().is_ok());
        for (bad, what) in [
            (
                LiveConfig {
                    contact_sigmas: f64::NAN,
                    ..ok
                },
                "contact_sigmas NaN",
            ),
            (
                LiveConfig {
                    contact_min_px: -1.0,
                    ..ok
                },
                "contact_min_px -1",
            ),
            (
                LiveConfig {
                    contact_markers: 0,
                    ..ok
                },
                "contact_markers 0",
            ),
            (
                LiveConfig {
                    rezero_rate: 2.0,
                    ..ok
                },
                "rezero_rate 2",
            ),
        ] {
            let e = bad.validate().unwrap_err().to_string();
            assert!(e.starts_with(what), "{e}");
        }
    }
}
