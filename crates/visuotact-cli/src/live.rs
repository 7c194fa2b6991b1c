//! Frame → features → estimate, the per-frame step `record --model`, `replay` and `predict
//! --sensor` share, so that the same frame gives the same numbers in each.

use std::path::Path;

use anyhow::{bail, Context};
use visuotact_image::RgbImage;
use visuotact_nn::model::Model;
use visuotact_vision::calibration::SensorCalibration;
use visuotact_vision::features::{is_field_column, FeatureExtractor, FrameFeatures};

/// Where one of the model's inputs comes from.
#[derive(Clone, Copy, Debug)]
enum Input {
    /// This position of the frame's feature vector.
    Feature(usize),
    /// This position of the extra inputs given with the frame.
    Extra(usize),
}

/// Per-frame estimator with reusable buffers.
pub(crate) struct Estimator {
    ex: FeatureExtractor,
    model: Option<(Model, Vec<Input>)>,
    /// The model's inputs that are not marker features (given with each frame), in order.
    extra_inputs: Vec<String>,
    features: FrameFeatures,
    x: Vec<f64>,
    n_markers: usize,
}

impl Estimator {
    /// Features from `sensor` (or the calibration stored in the model), and estimates when a
    /// model is given. The feature set is the model's, else the sensor file's. A model with
    /// inputs besides the marker features is refused: frames alone cannot give them.
    pub(crate) fn new(sensor: Option<&Path>, model: Option<Model>) -> anyhow::Result<Self> {
        let est = Self::with_extra_inputs(sensor, model)?;
        match est.extra_inputs.first() {
            Some(c) => Err(crate::train::non_marker_input(c)),
            None => Ok(est),
        }
    }

    /// As [`Estimator::new`], also for a model with inputs besides the marker features; their
    /// values come with each frame to [`Estimator::process_with`], in the order of
    /// [`Estimator::extra_inputs`].
    pub(crate) fn with_extra_inputs(
        sensor: Option<&Path>,
        model: Option<Model>,
    ) -> anyhow::Result<Self> {
        let cal = match (sensor, &model) {
            (Some(p), _) => crate::load_sensor(p)?,
            (None, Some(m)) => match &m.sensor {
                Some(v) => SensorCalibration::from_json(&v.to_string(), "the model's sensor")
                    .map_err(anyhow::Error::msg)?,
                None => bail!("the model holds no sensor calibration: give --sensor"),
            },
            (None, None) => bail!("give --sensor (and --model for estimates)"),
        };
        let (markers, extra_inputs): (Vec<String>, Vec<String>) = model
            .iter()
            .flat_map(|m| m.feature_columns.iter().cloned())
            .partition(|c| crate::train::is_marker_column(c) || is_field_column(c));
        let set = match &model {
            Some(_) => crate::train::feature_set_of(&markers)?,
            None => cal.features,
        };
        let n_markers = cal.markers.len();
        let ex = FeatureExtractor::new(cal, set).map_err(anyhow::Error::msg)?;
        let model = match model {
            Some(m) => {
                let cols = m
                    .feature_columns
                    .iter()
                    .map(|c| match extra_inputs.iter().position(|e| e == c) {
                        Some(j) => Ok(Input::Extra(j)),
                        None => feature_index(&ex, c).map(Input::Feature),
                    })
                    .collect::<anyhow::Result<_>>()?;
                Some((m, cols))
            }
            None => None,
        };
        Ok(Self {
            ex,
            model,
            extra_inputs,
            features: FrameFeatures::default(),
            x: Vec::new(),
            n_markers,
        })
    }

    /// Feature column names, in extraction order.
    pub(crate) fn feature_columns(&self) -> Vec<String> {
        self.ex.column_names()
    }

    /// The model's inputs that come with each frame rather than from it.
    pub(crate) fn extra_inputs(&self) -> &[String] {
        &self.extra_inputs
    }

    /// The estimate's columns (empty without a model): the targets, then for an ensemble each
    /// target's spread (`<target>_std`, the standard deviation over its networks).
    pub(crate) fn target_columns(&self) -> Vec<String> {
        self.model
            .as_ref()
            .map(|(m, _)| m.estimate_columns())
            .unwrap_or_default()
    }

    /// The sensor calibration in use.
    pub(crate) fn calibration(&self) -> &SensorCalibration {
        self.ex.calibration()
    }

    /// Starts each frame's tracking from the last frame's marker positions (frames in order).
    pub(crate) fn set_temporal_prior(&mut self, on: bool) {
        self.ex.set_temporal_prior(on);
    }

    /// The feature set in use.
    pub(crate) fn feature_set(&self) -> visuotact_vision::features::FeatureSet {
        self.ex.feature_set()
    }

    /// Markers in the calibration.
    pub(crate) fn n_markers(&self) -> usize {
        self.n_markers
    }

    /// Where each of `m`'s inputs sits in this estimator's feature vector.
    pub(crate) fn columns_of(&self, m: &Model) -> anyhow::Result<Vec<usize>> {
        columns_of(&self.ex, m)
    }

    /// One frame's features only (no estimate).
    pub(crate) fn features(&mut self, img: &RgbImage) -> anyhow::Result<&FrameFeatures> {
        self.ex.extract_into(img, &mut self.features)?;
        Ok(&self.features)
    }

    /// Processes one frame: its features, and the estimate (`None` without a model or when a
    /// marker the model needs was lost — no estimate rather than a wrong one).
    pub(crate) fn process(
        &mut self,
        img: &RgbImage,
    ) -> anyhow::Result<(&FrameFeatures, Option<Vec<f64>>)> {
        self.process_with(img, &[])
    }

    /// As [`Estimator::process`], with the values of the model's extra inputs for this frame
    /// (in the order of [`Estimator::extra_inputs`]); a missing or NaN value gives no estimate.
    pub(crate) fn process_with(
        &mut self,
        img: &RgbImage,
        extra: &[f64],
    ) -> anyhow::Result<(&FrameFeatures, Option<Vec<f64>>)> {
        self.features(img)?;
        let est = match &self.model {
            Some((m, cols)) => {
                self.x.clear();
                self.x.extend(cols.iter().map(|&c| match c {
                    Input::Feature(i) => self.features.values[i],
                    Input::Extra(j) => extra.get(j).copied().unwrap_or(f64::NAN),
                }));
                // Lost markers filled (models on principal components); a missing reading or
                // too many lost markers: no estimate.
                m.estimate(&self.x).ok().map(|e| e.into_row())
            }
            None => None,
        };
        Ok((&self.features, est))
    }
}

/// Where feature `c` sits in `ex`'s feature vector.
fn feature_index(ex: &FeatureExtractor, c: &str) -> anyhow::Result<usize> {
    ex.column_names()
        .iter()
        .position(|n| n == c)
        .with_context(|| {
            format!(
                "the sensor has no feature `{c}`: the model was trained with another sensor file"
            )
        })
}

/// Where each of `m`'s inputs sits in `ex`'s feature vector.
fn columns_of(ex: &FeatureExtractor, m: &Model) -> anyhow::Result<Vec<usize>> {
    m.feature_columns
        .iter()
        .map(|c| feature_index(ex, c))
        .collect()
}
