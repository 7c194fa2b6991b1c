//! The model file: a trained network with everything needed to use it on new data — its input
//! and target scaling, the feature columns it expects in order, the target names with units,
//! how training went, and the sensor calibration it was trained with. JSON, versioned.

use serde::{Deserialize, Serialize};

use crate::heldout::{HeldOutErrors, LookupScratch};
use crate::mlp::{MinMax, Mlp};

/// Identifies model files.
pub const MODEL_FORMAT: &str = "visuotact-model";
/// Current model file version.
pub const MODEL_VERSION: u32 = 2;

/// How training went.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrainingSummary {
    /// Epochs run.
    pub epochs: usize,
    /// Epoch whose weights were kept (best validation error).
    pub best_epoch: usize,
    /// Why it stopped.
    pub stop: String,
    /// Samples in training, validation, test.
    pub samples: [usize; 3],
    /// Mean squared error per target in target units: training, validation, test.
    pub mse: [Vec<f64>; 3],
    /// Regression R per target (estimates against targets): training, validation, test —
    /// MATLAB's `plotregression` figures (seed 000 Figs. 6–7). Empty in models written before
    /// it was kept.
    #[serde(default)]
    pub r: [Vec<f64>; 3],
    /// Seed of the split and the initial weights.
    pub seed: u64,
    /// `trainlm` or `trainbr` (models written before it was kept: `trainlm`).
    #[serde(default = "trainlm_name")]
    pub algorithm: String,
    /// trainbr's final α, β and effective number of parameters γ.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub evidence: Option<crate::br::Evidence>,
    /// The input sets training compared by cross-validation, with their scores (empty when
    /// there was no choice).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub selection: Vec<crate::fit::InputScore>,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

fn trainlm_name() -> String {
    "trainlm".to_string()
}

/// Over this fraction of missing inputs a frame gets no estimate.
pub const MAX_MISSING_FRACTION: f64 = 0.25;

/// An estimate and how many of its inputs were filled.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Estimate {
    /// Targets in their units (the ensemble's mean).
    pub values: Vec<f64>,
    /// Per target, how far off the values may be (`<target>_std`): the larger of the
    /// ensemble's standard deviation and, when the model keeps them, the root-mean-square error
    /// of the held-out training samples with the nearest estimates ([`crate::heldout`]); empty
    /// for one network without held-out samples.
    pub spread: Vec<f64>,
    /// Inputs that were missing and filled.
    pub filled: usize,
}

/// A trained model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Model {
    /// Always [`MODEL_FORMAT`].
    pub format: String,
    /// File version.
    pub version: u32,
    /// The network.
    pub net: Mlp,
    /// Further networks of an ensemble (other seeds and splits; same scaling, projection,
    /// columns): estimates are the mean over all, with their standard deviation.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub members: Vec<Mlp>,
    /// Input scaling (mapminmax over the training inputs).
    pub input_scaling: MinMax,
    /// Principal-component projection of the scaled inputs, when training reduced them: the
    /// network then reads its scores.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub projection: Option<crate::pca::Projection>,
    /// How many trailing feature columns bypass the projection (the field summary, a gauge's
    /// reading): the network reads the scores, then these scaled inputs. 0 in models written
    /// before it was kept (the projection read every input).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub passthrough: usize,
    /// For a network that reads the markers' features themselves (no projection): principal
    /// components of the scaled markers' features that fill a lost marker's features from the
    /// markers found ([`crate::pca::Projection::fill_missing`]); the network then reads every
    /// input. Absent in models written before version 2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub filler: Option<crate::pca::Projection>,
    /// Target scaling.
    pub target_scaling: MinMax,
    /// Feature columns, in input order.
    pub feature_columns: Vec<String>,
    /// Target names with units (`x_mm`, `force_n`, …), in output order.
    pub target_columns: Vec<String>,
    /// Training summary.
    pub training: TrainingSummary,
    /// The sensor calibration the features came from, when known.
    pub sensor: Option<serde_json::Value>,
    /// The training samples its networks held out, with their estimates and errors: what
    /// [`Estimate::spread`] is looked up in. Absent when no network held samples out (trainbr
    /// trains on all) and in models written before it was kept.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub held_out: Option<HeldOutErrors>,
}

/// Why a row gets no estimate.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum EstimateError {
    /// The row's width is not the model's.
    #[error("{given} inputs given, the model reads {expected} ({first}…)")]
    Width {
        /// Values given.
        given: usize,
        /// Columns the model reads.
        expected: usize,
        /// The model's first column.
        first: String,
    },
    /// A table lacks one of the model's input columns.
    #[error("no column `{column}` among the {given} given (the model reads {reads} columns)")]
    NoColumn {
        /// The missing column.
        column: String,
        /// Columns given.
        given: usize,
        /// Columns the model reads.
        reads: usize,
    },
    /// An input that is not a marker's feature is missing: nothing can fill it.
    #[error("`{column}`: missing reading")]
    MissingReading {
        /// The input's column.
        column: String,
    },
    /// Over [`MAX_MISSING_FRACTION`] of the inputs are missing.
    #[error("{missing} of {inputs} inputs missing (over a quarter): too few markers found")]
    TooManyMissing {
        /// Inputs missing.
        missing: usize,
        /// Inputs in all.
        inputs: usize,
    },
    /// Inputs are missing and the model has no projection to fill them from.
    #[error("{missing} inputs missing and the model has no principal components to fill them (train with --components)")]
    NoProjection {
        /// Inputs missing.
        missing: usize,
    },
    /// Too few inputs are left for the projection's components.
    #[error("{missing} inputs missing: too few left to fill them")]
    TooFewLeft {
        /// Inputs missing.
        missing: usize,
    },
    /// The networks give a value that is not a finite number (weights so large that the
    /// sums overflow): no estimate rather than an empty one.
    #[error("the model gives a non-finite `{target}` (its weights overflow)")]
    NonFinite {
        /// The first target without a finite value.
        target: String,
    },
}

/// Why a model file does not load.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{source_name}: {why}")]
pub struct ModelFileError {
    /// The file (or what the text came from).
    pub source_name: String,
    /// What is wrong with it.
    pub why: String,
}

/// Whether a feature column is a marker's (`m017_dx_px`): a lost marker can be filled from the
/// markers found, another input (a gauge's reading) cannot.
pub use visuotact_image::is_marker_column;

/// Why a row of `columns` with missing (NaN) inputs cannot be filled — a missing input that is
/// not a marker's, or over [`MAX_MISSING_FRACTION`] of the inputs missing — or `None` when it
/// can (or nothing is missing). Training and estimation apply the same rule.
pub fn unfillable(columns: &[String], row: &[f64]) -> Option<EstimateError> {
    if let Some((c, _)) = columns
        .iter()
        .zip(row)
        .find(|(c, v)| v.is_nan() && !is_marker_column(c))
    {
        return Some(EstimateError::MissingReading { column: c.clone() });
    }
    let missing = row.iter().filter(|v| v.is_nan()).count();
    (missing as f64 > MAX_MISSING_FRACTION * row.len() as f64).then_some(
        EstimateError::TooManyMissing {
            missing,
            inputs: row.len(),
        },
    )
}

impl Estimate {
    /// The values, then the spread (the columns of [`Model::estimate_columns`]).
    pub fn into_row(self) -> Vec<f64> {
        let mut row = self.values;
        row.extend(self.spread);
        row
    }
}

/// Buffers of [`Model::estimate_into`] and [`Model::estimate_each_into`], kept between
/// frames so that estimating does not allocate.
#[derive(Clone, Debug, Default)]
pub struct EstimateScratch {
    x: Vec<f64>,
    scores: Vec<f64>,
    z: Vec<f64>,
    acts: Vec<Vec<f64>>,
    outs: Vec<Vec<f64>>,
    n: usize,
    scaled: Vec<f64>,
    lookup: LookupScratch,
    rms: Vec<f64>,
}

impl EstimateScratch {
    /// Every network's estimate of the last row, target units.
    pub fn outputs(&self) -> &[Vec<f64>] {
        &self.outs[..self.n]
    }
}

impl Model {
    /// Estimates targets (original units) from one row of features (original units): the
    /// ensemble's mean, lost markers filled as [`Model::estimate`] does; NaN when it refuses.
    pub fn predict(&self, features: &[f64]) -> Vec<f64> {
        self.estimate(features)
            .map_or_else(|_| vec![f64::NAN; self.target_columns.len()], |e| e.values)
    }

    /// Every network of the model, the first one first.
    pub fn networks(&self) -> impl Iterator<Item = &Mlp> {
        std::iter::once(&self.net).chain(&self.members)
    }

    /// Where each of the model's input columns sits in a table whose columns are `names`; an
    /// error names the first one missing.
    pub fn columns_in(&self, names: &[String]) -> Result<Vec<usize>, EstimateError> {
        self.feature_columns
            .iter()
            .map(|c| {
                names
                    .iter()
                    .position(|n| n == c)
                    .ok_or_else(|| EstimateError::NoColumn {
                        column: c.clone(),
                        given: names.len(),
                        reads: self.feature_columns.len(),
                    })
            })
            .collect()
    }

    /// What [`Estimate::spread`] will be, in words (`None` for one network without held-out
    /// samples): the held-out table's size and overall RMS error per target, or the networks'
    /// standard deviation when nothing was held out.
    pub fn spread_in_words(&self) -> Option<String> {
        match &self.held_out {
            Some(h) => {
                let rms = |j: usize| {
                    let ss: f64 = h.errors.iter().map(|e| e[j] * e[j]).sum();
                    (ss / h.errors.len() as f64).sqrt()
                };
                let overall: Vec<String> = self
                    .target_columns
                    .iter()
                    .enumerate()
                    .map(|(j, t)| format!("{t} {:.4}", rms(j)))
                    .collect();
                Some(format!(
                    "the larger of the networks' disagreement and the held-out RMS error of the {} nearest of {} held-out frames (overall {})",
                    h.neighbours,
                    h.estimates.len(),
                    overall.join(", ")
                ))
            }
            None if !self.members.is_empty() => {
                Some("the networks' standard deviation (no frame was held out)".to_string())
            }
            None => None,
        }
    }

    /// The columns of [`Estimate::into_row`]: the targets, then for an ensemble or a model
    /// with held-out samples each target's spread (`<target>_std`).
    pub fn estimate_columns(&self) -> Vec<String> {
        let mut c = self.target_columns.clone();
        if !self.members.is_empty() || self.held_out.is_some() {
            c.extend(self.target_columns.iter().map(|t| format!("{t}_std")));
        }
        c
    }

    /// Every network's estimate (target units) from a row that may have missing (NaN) inputs,
    /// and how many were filled. The inputs are scaled and projected once for all networks. A
    /// model with a principal-component projection fills lost markers: the scores are fitted
    /// to the inputs present ([`crate::pca::Projection::apply_partial`]). Refused, with the
    /// reason, when [`unfillable`] says so or the model has no projection.
    pub fn estimate_each(&self, features: &[f64]) -> Result<(Vec<Vec<f64>>, usize), EstimateError> {
        let mut scratch = EstimateScratch::default();
        let filled = self.estimate_each_into(features, &mut scratch)?;
        Ok((scratch.outputs().to_vec(), filled))
    }

    /// [`Model::estimate_each`] into `scratch` (the outputs: [`EstimateScratch::outputs`]);
    /// allocation-free once `scratch` has held a row of this model, unless inputs are missing
    /// (filling them solves a small least-squares problem). Returns the inputs filled.
    pub fn estimate_each_into(
        &self,
        features: &[f64],
        scratch: &mut EstimateScratch,
    ) -> Result<usize, EstimateError> {
        if features.len() != self.feature_columns.len() {
            return Err(EstimateError::Width {
                given: features.len(),
                expected: self.feature_columns.len(),
                first: self.feature_columns.first().cloned().unwrap_or_default(),
            });
        }
        let missing = features.iter().filter(|v| v.is_nan()).count();
        if missing > 0 {
            if let Some(why) = unfillable(&self.feature_columns, features) {
                return Err(why);
            }
            if self.projection.is_none() && self.filler.is_none() {
                return Err(EstimateError::NoProjection { missing });
            }
        }
        let s = scratch;
        self.input_scaling.apply_into(features, &mut s.x);
        if let (Some(f), None, true) = (&self.filler, &self.projection, missing > 0) {
            let filled = s.x.len() - self.passthrough.min(s.x.len());
            if !f.fill_missing(&mut s.x[..filled]) {
                return Err(EstimateError::TooFewLeft { missing });
            }
        }
        match &self.projection {
            Some(p) => {
                let projected = s.x.len() - self.passthrough.min(s.x.len());
                if missing == 0 {
                    p.apply_into(&s.x[..projected], &mut s.scores, &mut s.z);
                } else {
                    s.z = p
                        .apply_partial(&s.x[..projected])
                        .ok_or(EstimateError::TooFewLeft { missing })?;
                }
                s.z.extend_from_slice(&s.x[projected..]);
            }
            None => {
                s.z.clear();
                s.z.extend_from_slice(&s.x);
            }
        }
        let n = self.networks().count();
        s.outs.resize(n, Vec::new());
        for (net, out) in self.networks().zip(&mut s.outs) {
            self.target_scaling
                .invert_into(net.forward_with(&s.z, &mut s.acts), out);
            if let Some(k) = out.iter().position(|v| !v.is_finite()) {
                return Err(EstimateError::NonFinite {
                    target: self.target_columns.get(k).cloned().unwrap_or_default(),
                });
            }
        }
        s.n = n;
        Ok(missing)
    }

    /// The ensemble's mean and standard deviation (empty for one network) from a row that may
    /// miss inputs, as [`Model::estimate_each`].
    pub fn estimate(&self, features: &[f64]) -> Result<Estimate, EstimateError> {
        let mut e = Estimate::default();
        self.estimate_into(features, &mut EstimateScratch::default(), &mut e)?;
        Ok(e)
    }

    /// [`Model::estimate`] into `out` (its vectors reused), with `scratch` kept between
    /// frames: allocation-free after the first frame when no input is missing. Returns the
    /// inputs filled (also in `out.filled`).
    pub fn estimate_into(
        &self,
        features: &[f64],
        scratch: &mut EstimateScratch,
        out: &mut Estimate,
    ) -> Result<usize, EstimateError> {
        let filled = self.estimate_each_into(features, scratch)?;
        let outs = scratch.outputs();
        let k = outs.len() as f64;
        let width = outs[0].len();
        out.values.clear();
        out.values
            .extend((0..width).map(|j| outs.iter().map(|o| o[j]).sum::<f64>() / k));
        out.spread.clear();
        if outs.len() > 1 {
            out.spread.extend((0..width).map(|j| {
                let v = outs
                    .iter()
                    .map(|o| (o[j] - out.values[j]).powi(2))
                    .sum::<f64>();
                (v / (k - 1.0)).sqrt()
            }));
        }
        if self.held_out.is_some() {
            out.spread.resize(width, 0.0);
            self.widen_spread(&out.values, scratch, &mut out.spread);
        }
        out.filled = filled;
        Ok(filled)
    }

    /// Raises each target's `spread` (the networks' standard deviation at the estimate
    /// `values`, target units) to the root-mean-square error of the held-out training samples
    /// whose estimates lie nearest `values` ([`crate::heldout`]), when that is larger: the
    /// held-out errors see what no network can tell, the networks' disagreement a frame unlike
    /// those they trained on. Returns whether the model keeps a held-out table (without one,
    /// `spread` is left as it is). Allocation-free once `scratch` has held a lookup.
    pub fn widen_spread(
        &self,
        values: &[f64],
        scratch: &mut EstimateScratch,
        spread: &mut [f64],
    ) -> bool {
        let Some(h) = &self.held_out else {
            return false;
        };
        self.target_scaling.apply_into(values, &mut scratch.scaled);
        h.rms_error_into(&scratch.scaled, &mut scratch.lookup, &mut scratch.rms);
        for (s, r) in spread.iter_mut().zip(&scratch.rms) {
            *s = s.max(*r);
        }
        true
    }

    /// Parses a model file's text; `source` names it in errors.
    pub fn from_json(text: &str, source: &str) -> Result<Self, ModelFileError> {
        let bad = |why: String| ModelFileError {
            source_name: source.to_string(),
            why,
        };
        let m: Model =
            serde_json::from_str(text).map_err(|e| bad(format!("not a model file: {e}")))?;
        if m.format != MODEL_FORMAT {
            return Err(bad(format!(
                "format is {:?}, expected {MODEL_FORMAT:?}",
                m.format
            )));
        }
        if m.version > MODEL_VERSION {
            return Err(bad(format!(
                "model version {} is newer than this program reads ({MODEL_VERSION})",
                m.version
            )));
        }
        let s = &m.net.sizes;
        if m.passthrough > m.feature_columns.len() {
            return Err(bad(format!(
                "inconsistent model ({} pass-through inputs of {} columns)",
                m.passthrough,
                m.feature_columns.len()
            )));
        }
        let net_inputs = match &m.projection {
            Some(p) => {
                if p.inputs() + m.passthrough != m.feature_columns.len()
                    || p.components.iter().any(|c| c.len() != p.inputs())
                    || !p.score_scaling.scales(p.outputs())
                {
                    return Err(bad(
                        "inconsistent model (the projection and the feature columns disagree)"
                            .to_string(),
                    ));
                }
                p.outputs() + m.passthrough
            }
            None => m.feature_columns.len(),
        };
        if let Some(f) = &m.filler {
            if m.projection.is_some()
                || f.inputs() + m.passthrough != m.feature_columns.len()
                || f.components.iter().any(|c| c.len() != f.inputs())
                || !f.score_scaling.scales(f.outputs())
            {
                return Err(bad(
                    "inconsistent model (the filler and the feature columns disagree)".to_string(),
                ));
            }
        }
        if s.len() < 2
            || s[0] != net_inputs
            || s[s.len() - 1] != m.target_columns.len()
            || m.net.params.len() != Mlp::n_params_for(s)
            || m.members
                .iter()
                .any(|n| n.sizes != *s || n.params.len() != m.net.params.len())
            || !m.input_scaling.scales(m.feature_columns.len())
            || !m.target_scaling.scales(s[s.len() - 1])
        {
            return Err(bad(
                "inconsistent model (layer sizes, columns and weights disagree)".to_string(),
            ));
        }
        if let Some(h) = &m.held_out {
            h.check(m.target_columns.len())
                .map_err(|e| bad(format!("inconsistent model ({e})")))?;
        }
        Ok(m)
    }

    /// The JSON text.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).unwrap_or_default()
    }

    /// The JSON text of a model worth a file, for writing to `path`: refused when training
    /// met non-finite numbers, and read back before it is handed out, so a written model file
    /// always loads.
    pub fn to_checked_json(&self, path: &str) -> Result<String, ModelFileError> {
        let bad = |why: &str| ModelFileError {
            source_name: path.to_string(),
            why: why.to_string(),
        };
        if self.training.stop == "NonFinite" {
            return Err(bad("training met non-finite numbers (are inputs of wildly different scales?): no model written"));
        }
        let json = self.to_json();
        Self::from_json(&json, path).map_err(|e| {
            bad(&format!(
                "the trained model does not read back, not written: {}",
                e.why
            ))
        })?;
        Ok(json)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::mlp::{MinMax, Mlp};

    /// A model of `sizes` with `members` more networks, inputs and targets on 0..1.
    pub(crate) fn model(sizes: &[usize], members: usize) -> Model {
        let (n_in, n_out) = (sizes[0], sizes[sizes.len() - 1]);
        Model {
            format: MODEL_FORMAT.to_string(),
            version: MODEL_VERSION,
            net: Mlp::nguyen_widrow(sizes, 1),
            members: (0..members)
                .map(|k| Mlp::nguyen_widrow(sizes, 2 + k as u64))
                .collect(),
            input_scaling: MinMax {
                min: vec![0.0; n_in],
                max: vec![1.0; n_in],
            },
            projection: None,
            passthrough: 0,
            filler: None,
            target_scaling: MinMax {
                min: vec![0.0; n_out],
                max: vec![1.0; n_out],
            },
            feature_columns: (0..n_in).map(|i| format!("f{i}")).collect(),
            target_columns: (0..n_out).map(|i| format!("t{i}")).collect(),
            training: TrainingSummary {
                epochs: 1,
                best_epoch: 1,
                stop: String::new(),
                samples: [1, 1, 1],
                mse: [vec![], vec![], vec![]],
                r: [vec![], vec![], vec![]],
                seed: 1,
                algorithm: "trainlm".into(),
                evidence: None,
                selection: Vec::new(),
            },
            sensor: None,
            held_out: None,
        }
    }

    #[test]
    fn weights_that_overflow_give_no_estimate_with_the_reason() {
        let mut m = model(&[3, 4, 2], 0);
        m.net.params.iter_mut().for_each(|w| *w = 1e308);
        let e = m.estimate(&[0.5, 0.5, 0.5]).unwrap_err();
        assert!(matches!(e, EstimateError::NonFinite { .. }), "{e}");
        assert!(e.to_string().contains("non-finite `t0`"), "{e}");
    }

    #[test]
    fn scalings_of_the_wrong_width_are_refused_with_the_file_name() {
        let good = model(&[3, 4, 2], 0);
        assert!(Model::from_json(&good.to_json(), "m.json").is_ok());
        let short_max = |s: &mut MinMax| {
            s.max.pop();
        };
        let mut input = good.clone();
        short_max(&mut input.input_scaling);
        let mut target = good.clone();
        short_max(&mut target.target_scaling);
        let mut filler = good.clone();
        let rows: Vec<Vec<f64>> = (0..6)
            .map(|i| {
                (0..3)
                    .map(|j| f64::from(i * j) + f64::from(i).sin())
                    .collect()
            })
            .collect();
        let mut f = crate::pca::Projection::fit(&rows, 2).unwrap();
        assert!(f.score_scaling.scales(2));
        filler.filler = Some(f.clone());
        assert!(Model::from_json(&filler.to_json(), "m.json").is_ok());
        short_max(&mut f.score_scaling);
        filler.filler = Some(f);
        for bad in [input, target, filler] {
            let e = Model::from_json(&bad.to_json(), "m.json").unwrap_err();
            assert!(e.to_string().contains("m.json"), "{e}");
            assert!(e.to_string().contains("inconsistent model"), "{e}");
        }
    }

    #[test]
    fn estimates_into_reused_buffers_equal_the_allocating_ones() {
        let plain = model(&[3, 4, 2], 2);
        // The same with a held-out table of 40 samples on a diagonal, errors growing along it.
        let mut held = plain.clone();
        held.held_out = HeldOutErrors::new(
            (0..40)
                .map(|i| vec![f64::from(i) / 20.0 - 1.0; 2])
                .collect(),
            (0..40).map(|i| vec![f64::from(i) * 0.01, 0.5]).collect(),
        );
        assert!(held.held_out.is_some());
        for m in [plain, held] {
            let (mut scratch, mut out) = (EstimateScratch::default(), Estimate::default());
            let rows = [[0.1, 0.5, 0.9], [0.7, 0.2, 0.3]];
            m.estimate_into(&rows[0], &mut scratch, &mut out).unwrap();
            let caps = |out: &Estimate, scratch: &EstimateScratch| {
                (
                    out.values.capacity(),
                    out.spread.capacity(),
                    scratch.x.capacity(),
                    scratch.scaled.capacity(),
                    scratch.rms.capacity(),
                )
            };
            let before = caps(&out, &scratch);
            for row in rows {
                m.estimate_into(&row, &mut scratch, &mut out).unwrap();
                // Bit-identical to the allocating call, and no buffer had to grow.
                assert_eq!(out, m.estimate(&row).unwrap());
                assert_eq!(out.spread.len(), 2);
                assert_eq!(caps(&out, &scratch), before);
            }
            assert_eq!(scratch.outputs().len(), 3);
            assert!(m.estimate_into(&[0.1], &mut scratch, &mut out).is_err());
            if m.held_out.is_some() {
                // Target 1's held-out error is 0.5 everywhere: above the networks' spread.
                assert_eq!(out.spread[1], 0.5);
            }
        }
    }
}
