//! The per-frame step: frame → markers' features and field summary → the model's estimate.
//!
//! `predict --sensor` and the Python package call this estimator; `record --model`, `replay`
//! and `run` call it through the [`crate::LiveEstimator`] around it (with
//! [`crate::LiveConfig::OFFLINE`] for recorded frames), so the same frame gives the same
//! numbers in each. Buffers are kept between
//! frames: after the first frame, [`Estimator::process_with`] does not allocate for the
//! features.
//!
//! The short way in: [`Estimator::from_sensor`] (features only) or [`Estimator::from_model`]
//! (a model holding its sensor), [`Estimator::with_model`] to add or change the model, and
//! [`Estimator::estimate`], whose [`Estimate`] is read by name (`e.get("depth_mm")`). The
//! other forms serve the live loop (`estimate_into`, no allocation) and tables (`process`,
//! rows in column order).

use visuotact_image::RgbImage;
use visuotact_nn::model::{
    is_marker_column, Estimate as ModelOutput, EstimateError, EstimateScratch, Model,
};
use visuotact_vision::calibration::SensorCalibration;
use visuotact_vision::features::{
    is_field_column, px_twin, FeatureExtractor, FeatureSet, FrameFeatures, FrameSizeError,
    MmColumns,
};

/// Why an estimator could not be built or a frame not processed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PipelineError {
    /// Slip detection cannot run with these settings.
    #[error("{0}")]
    Slip(&'static str),
    /// Neither a sensor calibration nor a model holding one was given.
    #[error("the model holds no sensor calibration: give the sensor file")]
    NoSensor,
    /// The model's stored sensor calibration does not read.
    #[error("the model's sensor: {0}")]
    ModelSensor(visuotact_vision::calibration::SensorFileError),
    /// The model needs an input frames cannot give.
    #[error("the model needs the input `{column}`, which is not a marker feature: frames alone cannot give it (estimate with a table that has it: `predict --features F --readings TABLE` or `replay --readings TABLE`)")]
    NotAMarkerInput {
        /// The input's column name.
        column: String,
    },
    /// The model takes displacements in millimetres and the sensor has no scale.
    #[error("the model takes `{column}` in millimetres, but the sensor file has no scale: calibrate it with --pitch-mm (the distance between neighbouring markers on the skin, docs/calibration.md)")]
    NoScale {
        /// The input's column name.
        column: String,
    },
    /// The model names a feature the sensor does not have.
    #[error(
        "the sensor has no feature `{column}`: the model was trained with another sensor file"
    )]
    UnknownFeature {
        /// The feature's column name.
        column: String,
    },
    /// The feature extractor refused the calibration or feature set.
    #[error("features: {0}")]
    Features(#[from] visuotact_vision::ConfigError),
    /// A model of an ensemble does not fit the others or the sensor.
    #[error("model {model} of the ensemble: {why}")]
    Ensemble {
        /// Which model (from 1).
        model: usize,
        /// What is wrong with it.
        why: String,
    },
    /// A frame's size differs from the calibration's.
    #[error(transparent)]
    FrameSize(#[from] FrameSizeError),
    /// A setting out of its range (the message names it and the range).
    #[error("{0}")]
    Setting(String),
}

/// The feature set a model's input columns need (the field summary comes with every set; a
/// model on the field summary alone needs the displacements, `x,y`).
pub fn feature_set_of(columns: &[String]) -> Result<FeatureSet, PipelineError> {
    let mut kinds: Vec<&str> = Vec::new();
    for c in columns.iter().filter(|c| !is_field_column(c)) {
        let kind = match c.get(5..) {
            Some("dx_px" | "dx_mm") if is_marker_column(c) => "x",
            Some("dy_px" | "dy_mm") if is_marker_column(c) => "y",
            Some("darea_px" | "darea_mm2") if is_marker_column(c) => "area",
            Some("decc") if is_marker_column(c) => "ecc",
            _ => {
                return Err(PipelineError::NotAMarkerInput { column: c.clone() });
            }
        };
        if !kinds.contains(&kind) {
            kinds.push(kind);
        }
    }
    if kinds.is_empty() {
        kinds.extend(["x", "y"]);
    }
    FeatureSet::parse(&kinds.join(",")).map_err(PipelineError::Features)
}

/// [`PipelineError::NoScale`] when any of `columns` (a model's inputs) is in millimetres and
/// `cal` has no scale to measure it.
pub fn require_scale(cal: &SensorCalibration, columns: &[String]) -> Result<(), PipelineError> {
    match columns.iter().find(|c| px_twin(c).is_some()) {
        Some(c) if cal.mm_per_px().is_none() => Err(PipelineError::NoScale { column: c.clone() }),
        _ => Ok(()),
    }
}

/// The model's estimate of a frame, or why it has none.
pub type ModelEstimate = Result<ModelOutput, EstimateError>;

/// A frame's features and, with a model, the inputs filled or why there is no estimate.
pub type FrameEstimate<'a> = (&'a FrameFeatures, Option<Result<usize, EstimateError>>);

/// One target of an [`Estimate`]: its name, value and, for an ensemble, its spread.
#[derive(Clone, Debug, PartialEq)]
pub struct TargetValue {
    /// The target's column name, with its unit (`depth_mm`, `force_n`).
    pub name: String,
    /// The estimate, in the target's unit (an ensemble's mean).
    pub value: f64,
    /// How far off the value may be ([`visuotact_nn::model::Estimate::spread`]); `None` for one
    /// network without held-out samples.
    pub spread: Option<f64>,
}

/// One frame read by [`Estimator::estimate`]: the model's targets by name (none without a
/// model, or when the model could not estimate this frame — [`Estimate::no_estimate`] says
/// why) and how many markers were found.
///
/// ```
/// use visuotact_pipeline::{Estimate, TargetValue};
///
/// let e = Estimate::new(
///     vec![TargetValue { name: "depth_mm".into(), value: 2.5, spread: Some(0.1) }],
///     117,
///     117,
/// );
/// assert_eq!(e.get("depth_mm"), Some(2.5));
/// assert_eq!(e.spread("depth_mm"), Some(0.1));
/// assert_eq!(e.get("force_n"), None);
/// for t in &e {
///     println!("{} = {} ± {:?}", t.name, t.value, t.spread);
/// }
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    targets: Vec<TargetValue>,
    /// Markers found in the frame.
    pub markers_found: usize,
    /// Markers in the sensor's calibration.
    pub markers: usize,
    /// Why the model gave no estimate for this frame (`None` when it did, or without a model).
    pub no_estimate: Option<EstimateError>,
}

impl Estimate {
    /// An estimate of these targets from a frame where `markers_found` of `markers` were found.
    pub fn new(targets: Vec<TargetValue>, markers_found: usize, markers: usize) -> Self {
        Self {
            targets,
            markers_found,
            markers,
            no_estimate: None,
        }
    }

    /// The value of target `name`, if the model estimates it and did for this frame.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.target(name).map(|t| t.value)
    }

    /// How far off target `name` may be (`<target>_std`: [`visuotact_nn::model::Estimate::spread`];
    /// `None` without one or for an unknown name).
    pub fn spread(&self, name: &str) -> Option<f64> {
        self.target(name).and_then(|t| t.spread)
    }

    /// Target `name` whole.
    pub fn target(&self, name: &str) -> Option<&TargetValue> {
        self.targets.iter().find(|t| t.name == name)
    }

    /// The targets, in the model's order.
    pub fn iter(&self) -> std::slice::Iter<'_, TargetValue> {
        self.targets.iter()
    }

    /// Whether there is no value (no model, or none for this frame).
    pub fn is_empty(&self) -> bool {
        self.targets.is_empty()
    }
}

impl<'a> IntoIterator for &'a Estimate {
    type Item = &'a TargetValue;
    type IntoIter = std::slice::Iter<'a, TargetValue>;

    fn into_iter(self) -> Self::IntoIter {
        self.targets.iter()
    }
}

/// Where one of the model's inputs comes from.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Input {
    /// This position of the frame's feature vector, times this factor (1, or the sensor's
    /// scale for an input in millimetres).
    Feature(usize, f64),
    /// This position of the extra inputs given with the frame.
    Extra(usize),
}

/// Per-frame estimator with reusable buffers.
pub struct Estimator {
    ex: FeatureExtractor,
    model: Option<(Model, Vec<Input>)>,
    /// The model's inputs that are not marker features (given with each frame), in order.
    extra_inputs: Vec<String>,
    features: FrameFeatures,
    x: Vec<f64>,
    scratch: EstimateScratch,
    n_markers: usize,
    /// The millimetre twins of the feature columns (none without a scale).
    mm: MmColumns,
}

/// The sensor calibration a model file holds (`None`: it holds none).
pub fn sensor_of_model(model: &Model) -> Result<Option<SensorCalibration>, PipelineError> {
    model
        .sensor
        .as_ref()
        .map(|v| {
            SensorCalibration::from_json(&v.to_string(), "the model's sensor")
                .map_err(PipelineError::ModelSensor)
        })
        .transpose()
}

impl Estimator {
    /// Features from `sensor` (or, when `None`, the calibration stored in the model), and
    /// estimates when a model is given. The feature set is the model's, else the sensor's.
    /// A model with inputs besides the marker features is refused: frames alone cannot give
    /// them (see [`Estimator::with_extra_inputs`]).
    pub fn new(
        sensor: Option<SensorCalibration>,
        model: Option<Model>,
    ) -> Result<Self, PipelineError> {
        let est = Self::with_extra_inputs(sensor, model)?;
        match est.extra_inputs.first() {
            Some(c) => Err(PipelineError::NotAMarkerInput { column: c.clone() }),
            None => Ok(est),
        }
    }

    /// Features from `sensor`, no model yet ([`Estimator::with_model`] adds one).
    pub fn from_sensor(sensor: SensorCalibration) -> Result<Self, PipelineError> {
        Self::new(Some(sensor), None)
    }

    /// Features and estimates from a model that holds its sensor's calibration (`visuotact
    /// train --sensor` stores it); [`PipelineError::NoSensor`] when it holds none.
    pub fn from_model(model: Model) -> Result<Self, PipelineError> {
        Self::new(None, Some(model))
    }

    /// This estimator's sensor with `model` estimating (replacing any model it had).
    pub fn with_model(self, model: Model) -> Result<Self, PipelineError> {
        let mut est = Self::new(Some(self.ex.calibration().clone()), Some(model))?;
        est.set_temporal_prior(self.ex.temporal_prior());
        Ok(est)
    }

    /// One frame's estimate, read by name ([`Estimate::get`]). `Err` only when the frame
    /// cannot be read (its size is not the calibration's); a frame the model cannot estimate
    /// (too many markers lost) gives an empty estimate with the reason.
    pub fn estimate(&mut self, img: &RgbImage) -> Result<Estimate, PipelineError> {
        let mut out = ModelOutput::default();
        let (f, got) = self.estimate_into(img, &[], &mut out)?;
        let mut e = Estimate::new(Vec::new(), f.found, self.n_markers);
        let Some(model) = self.model() else {
            return Ok(e);
        };
        match got {
            Some(Ok(_)) => {
                e.targets = model
                    .target_columns
                    .iter()
                    .enumerate()
                    .map(|(j, name)| TargetValue {
                        name: name.clone(),
                        value: out.values[j],
                        spread: out.spread.get(j).copied(),
                    })
                    .collect();
            }
            Some(Err(why)) => e.no_estimate = Some(why),
            None => {}
        }
        Ok(e)
    }

    /// As [`Estimator::new`], also for a model with inputs besides the marker features; their
    /// values come with each frame to [`Estimator::process_with`], in the order of
    /// [`Estimator::extra_inputs`].
    pub fn with_extra_inputs(
        sensor: Option<SensorCalibration>,
        model: Option<Model>,
    ) -> Result<Self, PipelineError> {
        let cal = match (sensor, &model) {
            (Some(c), _) => c,
            (None, Some(m)) => sensor_of_model(m)?.ok_or(PipelineError::NoSensor)?,
            (None, None) => return Err(PipelineError::NoSensor),
        };
        let (markers, extra_inputs): (Vec<String>, Vec<String>) = model
            .iter()
            .flat_map(|m| m.feature_columns.iter().cloned())
            .partition(|c| is_marker_column(c) || is_field_column(c));
        let set = match &model {
            Some(_) => feature_set_of(&markers)?,
            None => cal.features,
        };
        let n_markers = cal.markers.len();
        let ex = FeatureExtractor::new(cal, set).map_err(PipelineError::Features)?;
        let model = match model {
            Some(m) => {
                let cols = inputs_of(&ex, &extra_inputs, &m)?;
                Some((m, cols))
            }
            None => None,
        };
        let mm = MmColumns::of_sensor(ex.calibration(), &ex.column_names());
        Ok(Self {
            mm,
            ex,
            model,
            extra_inputs,
            features: FrameFeatures::default(),
            x: Vec::new(),
            scratch: EstimateScratch::default(),
            n_markers,
        })
    }

    /// Feature column names, in extraction order.
    pub fn feature_columns(&self) -> Vec<String> {
        self.ex.column_names()
    }

    /// The millimetre twins of [`Estimator::feature_columns`] that tables carry after them
    /// (none when the sensor has no scale).
    pub fn mm_columns(&self) -> &MmColumns {
        &self.mm
    }

    /// The model's inputs that come with each frame rather than from it.
    pub fn extra_inputs(&self) -> &[String] {
        &self.extra_inputs
    }

    /// The estimate's columns (empty without a model): the targets, then for an ensemble each
    /// target's spread (`<target>_std`, [`visuotact_nn::model::Estimate::spread`]).
    pub fn target_columns(&self) -> Vec<String> {
        self.model
            .as_ref()
            .map(|(m, _)| m.estimate_columns())
            .unwrap_or_default()
    }

    /// The model, if any.
    pub fn model(&self) -> Option<&Model> {
        self.model.as_ref().map(|(m, _)| m)
    }

    /// The sensor calibration in use.
    pub fn calibration(&self) -> &SensorCalibration {
        self.ex.calibration()
    }

    /// Starts each frame's tracking from the last frame's marker positions (frames in order).
    pub fn set_temporal_prior(&mut self, on: bool) {
        self.ex.set_temporal_prior(on);
    }

    /// The feature set in use.
    pub fn feature_set(&self) -> FeatureSet {
        self.ex.feature_set()
    }

    /// Markers in the calibration.
    pub fn n_markers(&self) -> usize {
        self.n_markers
    }

    /// Where each of `m`'s inputs sits in this estimator's feature vector, and the factor
    /// that converts it (1, or the sensor's scale for an input in millimetres).
    pub fn columns_of(&self, m: &Model) -> Result<Vec<(usize, f64)>, PipelineError> {
        let names = self.ex.column_names();
        let cal = self.ex.calibration();
        m.feature_columns
            .iter()
            .map(|c| feature_index(cal, &names, c))
            .collect()
    }

    /// Where each of `m`'s inputs comes from: this estimator's features, or its extra inputs
    /// ([`Estimator::extra_inputs`]) given with each frame.
    pub(crate) fn inputs_of(&self, m: &Model) -> Result<Vec<Input>, PipelineError> {
        inputs_of(&self.ex, &self.extra_inputs, m)
    }

    /// This estimator without its model, and the model (the live loop holds its models as an
    /// ensemble); the extra inputs and the feature set stay the model's.
    pub(crate) fn without_model(mut self) -> (Self, Option<Model>) {
        let model = self.model.take().map(|(m, _)| m);
        (self, model)
    }

    /// The last frame's features ([`Estimator::features`]; empty before the first frame).
    pub fn last_features(&self) -> &FrameFeatures {
        &self.features
    }

    /// One frame's features only (no estimate).
    pub fn features(&mut self, img: &RgbImage) -> Result<&FrameFeatures, PipelineError> {
        self.ex.extract_into(img, &mut self.features)?;
        Ok(&self.features)
    }

    /// Processes one frame: its features, and the estimate as a row (targets, then spreads;
    /// `None` without a model or when the model cannot estimate it — no estimate rather than
    /// a wrong one).
    pub fn process(
        &mut self,
        img: &RgbImage,
    ) -> Result<(&FrameFeatures, Option<Vec<f64>>), PipelineError> {
        self.process_with(img, &[])
    }

    /// As [`Estimator::process`], with the values of the model's extra inputs for this frame
    /// (in the order of [`Estimator::extra_inputs`]); a missing or NaN value gives no estimate.
    pub fn process_with(
        &mut self,
        img: &RgbImage,
        extra: &[f64],
    ) -> Result<(&FrameFeatures, Option<Vec<f64>>), PipelineError> {
        let (f, e) = self.estimate_with(img, extra)?;
        Ok((f, e.and_then(Result::ok).map(ModelOutput::into_row)))
    }

    /// As [`Estimator::process_with`], the estimate whole (values, spread, inputs filled) or
    /// why the model has none for this frame; `None` without a model.
    pub fn estimate_with(
        &mut self,
        img: &RgbImage,
        extra: &[f64],
    ) -> Result<(&FrameFeatures, Option<ModelEstimate>), PipelineError> {
        let mut e = ModelOutput::default();
        let (_, got) = self.estimate_into(img, extra, &mut e)?;
        Ok((&self.features, got.map(|r| r.map(|_| e))))
    }

    /// The live loop's form of [`Estimator::estimate_with`]: the estimate into `out` (its
    /// vectors reused), allocation-free after the first frame when no input is missing.
    /// Returns the features and, with a model, the inputs filled or why there is no estimate.
    pub fn estimate_into(
        &mut self,
        img: &RgbImage,
        extra: &[f64],
        out: &mut ModelOutput,
    ) -> Result<FrameEstimate<'_>, PipelineError> {
        self.ex.extract_into(img, &mut self.features)?;
        let got = match &self.model {
            Some((m, cols)) => {
                self.x.clear();
                self.x.extend(cols.iter().map(|&c| match c {
                    Input::Feature(i, k) => self.features.values[i] * k,
                    Input::Extra(j) => extra.get(j).copied().unwrap_or(f64::NAN),
                }));
                // Lost markers filled (models on principal components); a missing reading or
                // too many lost markers: no estimate.
                Some(m.estimate_into(&self.x, &mut self.scratch, out))
            }
            None => None,
        };
        Ok((&self.features, got))
    }
}

/// Where each of `m`'s inputs comes from: `ex`'s features, or the `extra` inputs given with
/// each frame.
fn inputs_of(
    ex: &FeatureExtractor,
    extra: &[String],
    m: &Model,
) -> Result<Vec<Input>, PipelineError> {
    let names = ex.column_names();
    let cal = ex.calibration();
    m.feature_columns
        .iter()
        .map(|c| match extra.iter().position(|e| e == c) {
            Some(j) => Ok(Input::Extra(j)),
            None => feature_index(cal, &names, c).map(|(i, k)| Input::Feature(i, k)),
        })
        .collect()
}

/// Where feature `c` sits among `names` (a feature vector in pixels) and the factor that
/// converts it: 1, or for a column in millimetres its pixel twin's position and `cal`'s scale
/// (squared for an area).
fn feature_index(
    cal: &SensorCalibration,
    names: &[String],
    c: &str,
) -> Result<(usize, f64), PipelineError> {
    let at = |c: &str| names.iter().position(|n| n == c);
    if let Some(i) = at(c) {
        return Ok((i, 1.0));
    }
    let unknown = || PipelineError::UnknownFeature {
        column: c.to_string(),
    };
    let (px, power) = px_twin(c).ok_or_else(unknown)?;
    let i = at(&px).ok_or_else(unknown)?;
    let scale = cal.mm_per_px().ok_or_else(|| PipelineError::NoScale {
        column: c.to_string(),
    })?;
    Ok((i, scale.powi(power)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cols(names: &[&str]) -> Vec<String> {
        names.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn the_feature_set_follows_the_models_columns() {
        let set = feature_set_of(&cols(&["m000_dx_px", "m000_dy_px", "field_rms_px"])).unwrap();
        assert_eq!(set, FeatureSet::parse("x,y").unwrap());
        let set = feature_set_of(&cols(&["m001_darea_px", "m001_dx_px"])).unwrap();
        assert_eq!(set, FeatureSet::parse("area,x").unwrap());
        assert_eq!(
            feature_set_of(&cols(&["field_top_px"])).unwrap(),
            FeatureSet::parse("x,y").unwrap()
        );
        assert_eq!(
            feature_set_of(&cols(&["m000_dx_px", "gauge_kpa"])),
            Err(PipelineError::NotAMarkerInput {
                column: "gauge_kpa".into()
            })
        );
    }
}
