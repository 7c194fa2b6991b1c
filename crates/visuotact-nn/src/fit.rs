//! A model from a table of inputs and targets: scaling, the optional projection of the
//! markers' features, one network or an ensemble, trained by [`crate::mlp::train`].
//!
//! This is what `visuotact train` and `sweep` run, reachable without the command line:
//!
//! ```
//! use visuotact_nn::fit::{fit, quietly, FitConfig, FitData};
//! use visuotact_nn::lm::Control;
//!
//! // y = 2·a − b on 40 samples; one small network by trainlm.
//! let x: Vec<Vec<f64>> = (0..40).map(|i| vec![(i % 7) as f64, (i % 5) as f64]).collect();
//! let t: Vec<Vec<f64>> = x.iter().map(|r| vec![2.0 * r[0] - r[1]]).collect();
//! let columns = ["a".to_string(), "b".to_string()];
//! let targets = ["y".to_string()];
//! let data = FitData { x: &x, t: &t, feature_columns: &columns, targets: &targets };
//! let cfg = FitConfig { hidden: vec![3], ensemble: 1, ..FitConfig::default() };
//! let model = fit(&data, &cfg, quietly).unwrap();
//! assert!((model.predict(&[3.0, 1.0])[0] - 5.0).abs() < 0.05);
//! ```

use rayon::prelude::*;

use crate::heldout::HeldOutErrors;
use crate::lm::Control;
use crate::metrics::target_errors;
use crate::mlp::{Algorithm, BrTraining, MinMax, Mlp, Settle, TrainConfig, Trainer};
use crate::model::{Model, TrainingSummary, MODEL_FORMAT, MODEL_VERSION};
use crate::pca::Projection;
use crate::pca::ProjectionError;

/// Components `auto` keeps for sensors with many inputs. Tables of thousands of frames get
/// their capacity from the wide network ([`InputSet::wide`]) instead: twice as many
/// components cost Levenberg–Marquardt 2–4 times as much per epoch.
pub const AUTO_COMPONENTS: usize = 10;

/// From this many training samples a table is large: the wide network ([`InputSet::wide`])
/// is a candidate, and the input choice holds out one fold instead of cross-validating over
/// all ([`folds_trained`]).
pub const LARGE_TABLE: usize = 1000;

/// The wide network's hidden layers ([`InputSet::wide`]).
pub const WIDE_HIDDEN: [usize; 2] = [64, 64];

/// Principal components that fill a lost marker's features for a network reading the markers'
/// features themselves ([`crate::model::Model::filler`]).
pub const FILL_COMPONENTS: usize = 20;

/// The components `auto` keeps for `inputs` marker inputs (`None`: the inputs themselves):
/// a projection only when there are over twice as many inputs as components.
pub fn auto_components(inputs: usize) -> Option<usize> {
    (inputs > 2 * AUTO_COMPONENTS).then_some(AUTO_COMPONENTS)
}

/// Whether the field summary goes in beside the markers' features by default: when those are
/// projected, i.e. the same threshold as [`auto_components`].
pub fn auto_field(inputs: usize) -> bool {
    auto_components(inputs).is_some()
}

/// Which inputs a network reads: the markers' features, the field summary, or both
/// (`visuotact train --field`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FieldInputs {
    /// When [`auto_field`] says so for the markers' features, the table keeps the field
    /// summary beside them ([`FieldInputs::resolve`] gives `Yes`) and training chooses between
    /// the two together and the field summary alone ([`candidate_inputs`]); else `No`.
    Auto,
    /// The markers' features only.
    No,
    /// The markers' features, then the field summary.
    Yes,
    /// The field summary only.
    Only,
}

visuotact_image::names_from_str!(FieldInputs, "field-summary choice");

impl FieldInputs {
    /// The names [`FieldInputs::from_name`] and `FromStr` read (each is also what `name` writes,
    /// where the type has one).
    pub const NAMES: &'static [&'static str] = &["auto", "yes", "only", "no"];

    /// The choice called `name` (`auto`, `no`, `yes`, `only`).
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "auto" => Some(Self::Auto),
            "no" => Some(Self::No),
            "yes" => Some(Self::Yes),
            "only" => Some(Self::Only),
            _ => None,
        }
    }

    /// `Auto` decided for `marker_inputs` markers' features; the others as they are.
    pub fn resolve(self, marker_inputs: usize) -> Self {
        match self {
            Self::Auto if auto_field(marker_inputs) => Self::Yes,
            Self::Auto => Self::No,
            other => other,
        }
    }
}

/// The principal components for `marker_inputs` markers' features from a choice written as
/// `auto` ([`auto_components`]), `0` (none) or a count; an error names what was expected.
pub fn components_from_name(name: &str, marker_inputs: usize) -> Result<Option<usize>, FitError> {
    match name {
        _ if marker_inputs == 0 => Ok(None),
        "auto" => Ok(auto_components(marker_inputs)),
        k => match k.parse::<usize>() {
            Ok(0) => Ok(None),
            Ok(k) => Ok(Some(k)),
            Err(_) => Err(FitError::Components(format!(
                "{k:?}: expected auto, 0 or a number of components"
            ))),
        },
    }
}

/// What a column of a training table is, for choosing a network's inputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColumnKind {
    /// A marker's feature (`m017_dx_px`): projected, filled when lost.
    Marker,
    /// A marker's shape change (`m017_darea_px`, `m017_decc`): a marker's feature like the
    /// others, which the wide network is also tried without ([`candidate_inputs`]): where the
    /// markers are a few pixels across, or binarised, their area moves in whole pixels and can
    /// add more noise than it tells.
    MarkerShape,
    /// A field-summary value (`field_rms_px`): passes by the projection.
    Field,
    /// Another input (a gauge's reading): passes by the projection, kept by every input set.
    Other,
}

/// The kind of each of `columns`, `field_columns` naming the field summary's.
pub fn column_kinds(columns: &[String], field_columns: &[&str]) -> Vec<ColumnKind> {
    columns
        .iter()
        .map(|c| {
            if visuotact_image::is_marker_shape_column(c) {
                ColumnKind::MarkerShape
            } else if crate::model::is_marker_column(c) {
                ColumnKind::Marker
            } else if field_columns.contains(&c.as_str()) {
                ColumnKind::Field
            } else {
                ColumnKind::Other
            }
        })
        .collect()
}

impl ColumnKind {
    /// A marker's feature of either kind.
    pub fn is_marker(self) -> bool {
        matches!(self, Self::Marker | Self::MarkerShape)
    }
}

/// A set of a table's columns to train on, with how its markers' features are projected.
#[derive(Clone, Debug, PartialEq)]
pub struct InputSet {
    /// What it reads, in words (`10 principal components + field summary`).
    pub name: String,
    /// The table's columns it reads, markers' features first.
    pub columns: Vec<usize>,
    /// Principal components of its markers' features (`None`: them as they are).
    pub components: Option<usize>,
    /// How many of its trailing columns pass by the projection.
    pub passthrough: usize,
    /// The wide network: every marker's feature as it is (a lost one filled from
    /// [`FILL_COMPONENTS`] principal components of the others), [`WIDE_HIDDEN`] hidden units,
    /// trained by mini-batch Adam ([`crate::adam`]) — capacity that thousands of frames can
    /// pay for, where Levenberg–Marquardt's `JᵀJ` of so many weights would not.
    pub wide: bool,
}

/// How far apart one held-out fold must score two input sets for it to tell them apart
/// ([`choose_inputs`] on a large table): 5 %. On the zoo TacTip (5 000 simulated touches, 6
/// targets) one set's error on one fold moved by 3 % between seeds; on the real 331-pin
/// TacTip set two sets one fold put 0.4 % apart were 5 % apart on all five, and the one all
/// five chose had every target's test error 3–15 % lower (docs/benchmarks.md).
pub const ONE_FOLD_RESOLUTION: f64 = 1.05;

impl InputSet {
    /// The inputs the network itself sees: the components and the columns passing by them, or
    /// every column.
    pub fn network_inputs(&self) -> usize {
        self.components
            .map_or(self.columns.len(), |k| k + self.passthrough)
    }

    /// How many inputs the set reads and how they reach the network, in words (`130 inputs
    /// (the markers' 117 as 10 principal components, 13 more as they are)`).
    pub fn in_words(&self) -> String {
        let n = self.columns.len();
        match self.components {
            None if self.wide => format!(
                "{n} inputs (the markers' {} as they are, lost ones filled from {FILL_COMPONENTS} principal components{})",
                n - self.passthrough,
                if self.passthrough > 0 {
                    format!(", {} more", self.passthrough)
                } else {
                    String::new()
                }
            ),
            None => n.to_string(),
            Some(k) => format!(
                "{n} inputs (the markers' {} as {k} principal components{})",
                n - self.passthrough,
                if self.passthrough > 0 {
                    format!(", {} more as they are", self.passthrough)
                } else {
                    String::new()
                }
            ),
        }
    }

    /// `in → hidden → out (n weights` for the network this set feeds (the caller closes the
    /// parenthesis after adding what it knows, e.g. the algorithm).
    pub fn network_in_words(&self, hidden: &[usize], targets: usize) -> String {
        let hidden = self.hidden(hidden);
        let sizes = [&[self.network_inputs()][..], hidden, &[targets]].concat();
        let layers: Vec<String> = hidden.iter().map(usize::to_string).collect();
        format!(
            "{} → {} → {targets} ({} weights",
            self.in_words(),
            layers.join(" → "),
            Mlp::n_params_for(&sizes)
        )
    }

    /// The hidden layers of this set's network: [`WIDE_HIDDEN`] for the wide one, else
    /// `configured`.
    pub fn hidden<'a>(&self, configured: &'a [usize]) -> &'a [usize] {
        if self.wide {
            &WIDE_HIDDEN
        } else {
            configured
        }
    }

    /// The algorithm of this set's network: Adam for the wide one, else `configured`.
    pub fn algorithm(&self, configured: Algorithm) -> Algorithm {
        if self.wide {
            Algorithm::Adam
        } else {
            configured
        }
    }

    /// Every column of a table whose columns are `kinds` (markers' features first), the
    /// markers' features projected to `components` when there are any.
    pub fn all(kinds: &[ColumnKind], components: Option<usize>) -> Self {
        Self::keeping(kinds, components, |_| true)
    }

    /// The columns of `kinds` for which `keep` holds, markers' features first.
    fn keeping(
        kinds: &[ColumnKind],
        components: Option<usize>,
        keep: impl Fn(ColumnKind) -> bool,
    ) -> Self {
        let of = |wanted: fn(ColumnKind) -> bool| -> Vec<usize> {
            (0..kinds.len())
                .filter(|&i| wanted(kinds[i]) && keep(kinds[i]))
                .collect()
        };
        let (markers, field, other) = (
            of(ColumnKind::is_marker),
            of(|k| k == ColumnKind::Field),
            of(|k| k == ColumnKind::Other),
        );
        let components = components.filter(|_| !markers.is_empty());
        // Markers' features without the shape columns a table has are their displacements.
        let what = if kinds.contains(&ColumnKind::MarkerShape)
            && !markers.iter().any(|&i| kinds[i] == ColumnKind::MarkerShape)
        {
            "markers' displacements"
        } else {
            "markers' features"
        };
        let mut parts = Vec::new();
        if !markers.is_empty() {
            parts.push(match components {
                Some(k) => format!("{k} principal components of {} {what}", markers.len()),
                None => format!("{} {what}", markers.len()),
            });
        }
        if !field.is_empty() {
            parts.push("the field summary".to_string());
        }
        if !other.is_empty() {
            parts.push(format!("{} other inputs", other.len()));
        }
        let passthrough = field.len() + other.len();
        Self {
            name: parts.join(" + "),
            columns: [markers, field, other].concat(),
            components,
            passthrough,
            wide: false,
        }
    }
}

/// The input sets training compares for a table whose columns are `kinds` after the `field`
/// choice picked them. With [`FieldInputs::Auto`], the field summary and enough markers'
/// features for [`auto_field`]: the two together (the markers' projected by `components`)
/// against the field summary alone — which generalises better depends on the sensor
/// (docs/benchmarks.md) — and, when `wide` (a large table: [`crate::plan::Plan`]), every
/// column into the wide network ([`InputSet::wide`]) and, where the table has markers' shape
/// columns ([`ColumnKind::MarkerShape`]), every column but those into it too (the binarised
/// pins of the real 127-pin TacTip set are better read without their areas:
/// docs/benchmarks.md). Otherwise every column, one set.
pub fn candidate_inputs(
    kinds: &[ColumnKind],
    components: Option<usize>,
    field: FieldInputs,
    wide: bool,
) -> Vec<InputSet> {
    let all = InputSet::all(kinds, components);
    let markers = kinds.iter().filter(|k| k.is_marker()).count();
    if field == FieldInputs::Auto && auto_field(markers) && kinds.contains(&ColumnKind::Field) {
        let without_markers = InputSet::keeping(kinds, None, |k| !k.is_marker());
        let mut sets = vec![all, without_markers];
        if wide {
            let into_wide = |mut set: InputSet| {
                set.name = format!("{} into the wide network", set.name);
                set.wide = true;
                set
            };
            sets.push(into_wide(InputSet::keeping(kinds, None, |_| true)));
            if kinds.contains(&ColumnKind::Marker) && kinds.contains(&ColumnKind::MarkerShape) {
                let shapeless = |k: ColumnKind| k != ColumnKind::MarkerShape;
                sets.push(into_wide(InputSet::keeping(kinds, None, shapeless)));
            }
        }
        sets
    } else {
        vec![all]
    }
}

/// Folds of the cross-validation that chooses between input sets.
pub const SELECTION_FOLDS: usize = 5;

/// An input set's cross-validated error (kept in the model file).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct InputScore {
    /// The input set, in words.
    pub inputs: String,
    /// Per target, the held-out squared error over the target's variance (0: perfect, 1: no
    /// better than the mean), over every sample held out once.
    pub normalised_mse: Vec<f64>,
    /// Their mean over targets: what the choice minimises (units do not weigh in).
    pub error: f64,
    /// How many folds' held-out samples the score is over (older model files: 0, not said).
    #[serde(default)]
    pub folds: usize,
    /// Whether this set was chosen.
    pub chosen: bool,
    /// Each sample its fold held out, with the fold network's estimate (target units): the
    /// errors [`with_held_out_errors`] keeps for a model that holds none out itself. Not kept
    /// in the model file.
    #[serde(skip)]
    pub held_out: Vec<(usize, Vec<f64>)>,
}

/// How a model is trained. [`Default`] is visuotact's default (what `visuotact train` does
/// with no options); [`FitConfig::paper`] is the source documents' way.
#[derive(Clone, Debug, PartialEq)]
pub struct FitConfig {
    /// Hidden layer sizes.
    pub hidden: Vec<usize>,
    /// Seed of the split and the initial weights (members of an ensemble add multiples of a
    /// prime to it).
    pub seed: u64,
    /// Most epochs.
    pub max_epochs: usize,
    /// The objective.
    pub algorithm: Algorithm,
    /// Keep trainlm's validation and test subsets with trainbr too (a sweep compares networks
    /// on them); otherwise trainbr trains on every sample.
    pub hold_out: bool,
    /// Feed the network this many principal components of the scaled markers' features
    /// (`None`: the inputs themselves).
    pub components: Option<usize>,
    /// How many trailing input columns are not markers' features (the field summary, extra
    /// inputs such as a gauge): they bypass the projection.
    pub passthrough: usize,
    /// Networks in the model (1: one; more: an ensemble on other seeds and splits, estimates
    /// their mean with the standard deviation as the spread).
    pub ensemble: usize,
    /// When the markers' features are not projected: fill a lost marker's features from this
    /// many principal components of the others ([`crate::model::Model::filler`]); `None`: a
    /// lost marker is refused.
    pub fill: Option<usize>,
}

impl Default for FitConfig {
    /// trainbr, one hidden layer of 20, 5 networks, every input as it is: on 280 simulated
    /// touches of four sensors it generalised best (docs/benchmarks.md).
    fn default() -> Self {
        Self {
            hidden: vec![20],
            seed: 1,
            max_epochs: 1000,
            algorithm: Algorithm::Trainbr,
            hold_out: false,
            components: None,
            passthrough: 0,
            ensemble: 5,
            fill: None,
        }
    }
}

impl FitConfig {
    /// The default for `marker_inputs` markers' features followed by `passthrough` other
    /// inputs: the markers' features projected by [`auto_components`].
    pub fn auto(marker_inputs: usize, passthrough: usize) -> Self {
        Self {
            components: auto_components(marker_inputs),
            passthrough,
            ..Self::default()
        }
    }

    /// Whether a lost marker's features are filled (projected, or a filler).
    pub fn fills(&self) -> bool {
        self.components.is_some() || self.fill.is_some()
    }

    /// The source documents' way: trainlm (70/15/15 split, validation stop), every input,
    /// one network with these hidden layers.
    pub fn paper(hidden: &[usize]) -> Self {
        Self {
            hidden: hidden.to_vec(),
            algorithm: Algorithm::Trainlm,
            ensemble: 1,
            ..Self::default()
        }
    }
}

/// The training table: one row of inputs and one of targets per sample, and their names
/// (kept in the model file).
#[derive(Clone, Copy, Debug)]
pub struct FitData<'a> {
    /// Inputs per sample; NaN for a marker's feature that was lost (filled from the others
    /// when the markers' features are projected).
    pub x: &'a [Vec<f64>],
    /// Targets per sample, in their units.
    pub t: &'a [Vec<f64>],
    /// Names of the inputs (markers' features first, then the pass-through columns).
    pub feature_columns: &'a [String],
    /// Names of the targets.
    pub targets: &'a [String],
}

/// Why no model was trained.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FitError {
    /// No samples, or no inputs or targets.
    #[error("nothing to train on: {samples} samples, {inputs} inputs, {targets} targets")]
    Empty {
        /// Samples given.
        samples: usize,
        /// Input columns named.
        inputs: usize,
        /// Target columns named.
        targets: usize,
    },
    /// A row's width differs from its column names.
    #[error("sample {row}: {got} {what}, expected {expected}")]
    Width {
        /// Which sample (from 0).
        row: usize,
        /// `inputs` or `targets`.
        what: &'static str,
        /// Values in the row.
        got: usize,
        /// Columns named.
        expected: usize,
    },
    /// A target is not a finite number, or an input is infinite or missing where it cannot be
    /// filled.
    #[error("sample {row}, column `{column}`: {value} ({why})")]
    NotFinite {
        /// Which sample (from 0).
        row: usize,
        /// The column's name.
        column: String,
        /// The value.
        value: f64,
        /// What is allowed there.
        why: &'static str,
    },
    /// The hidden layers or the ensemble size are zero, or the pass-through count exceeds the
    /// inputs.
    #[error("invalid configuration: {0}")]
    Config(String),
    /// A number of components that does not parse.
    #[error("{0}")]
    Components(String),
    /// The principal components could not be taken.
    #[error("principal components: {0}")]
    Projection(#[from] ProjectionError),
    /// A model fitted in cross-validation could not estimate one of its held-out samples.
    #[error("held-out sample {sample}: {source}")]
    HeldOut {
        /// The sample (from 0).
        sample: usize,
        /// Why.
        source: crate::model::EstimateError,
    },
}

/// Most networks in one ensemble.
pub const MAX_ENSEMBLE: usize = 1000;

/// The first name that `names` holds twice.
fn duplicate(names: &[String]) -> Option<&str> {
    let mut seen = std::collections::HashSet::new();
    names
        .iter()
        .find(|n| !seen.insert(n.as_str()))
        .map(String::as_str)
}

impl FitData<'_> {
    /// Refuses settings that would train nothing, and a column named twice.
    fn settings_train_something(&self, cfg: &FitConfig) -> Result<(), FitError> {
        if cfg.ensemble == 0 {
            return Err(FitError::Config(
                "an ensemble of 0 networks: need 1 or more".into(),
            ));
        }
        if cfg.ensemble > MAX_ENSEMBLE {
            return Err(FitError::Config(format!(
                "an ensemble of {} networks: at most {MAX_ENSEMBLE} (beyond a few, more networks \
                 no longer lower the error; each costs a training and a model file's weights)",
                cfg.ensemble
            )));
        }
        if cfg.max_epochs == 0 {
            return Err(FitError::Config(
                "at most 0 epochs: need 1 or more (0 would keep the random initial weights)".into(),
            ));
        }
        if let Some(name) = duplicate(self.targets) {
            return Err(FitError::Config(format!("target `{name}` named twice")));
        }
        if let Some(name) = duplicate(self.feature_columns) {
            return Err(FitError::Config(format!(
                "input column `{name}` named twice"
            )));
        }
        Ok(())
    }

    /// Checks shapes and values against `cfg`.
    fn validate(&self, cfg: &FitConfig) -> Result<(), FitError> {
        let (inputs, targets) = (self.feature_columns.len(), self.targets.len());
        if self.x.is_empty() || inputs == 0 || targets == 0 || self.t.len() != self.x.len() {
            return Err(FitError::Empty {
                samples: self.x.len().min(self.t.len()),
                inputs,
                targets,
            });
        }
        if cfg.hidden.is_empty() || cfg.hidden.contains(&0) {
            return Err(FitError::Config(format!(
                "hidden layers {:?}: need one or more positive sizes",
                cfg.hidden
            )));
        }
        if cfg.passthrough > inputs {
            return Err(FitError::Config(format!(
                "{} pass-through inputs of {inputs}",
                cfg.passthrough
            )));
        }
        self.settings_train_something(cfg)?;
        let projected = inputs - cfg.passthrough;
        for (row, (x, t)) in self.x.iter().zip(self.t).enumerate() {
            for (what, got, expected) in
                [("inputs", x.len(), inputs), ("targets", t.len(), targets)]
            {
                if got != expected {
                    return Err(FitError::Width {
                        row,
                        what,
                        got,
                        expected,
                    });
                }
            }
            let bad_input = x.iter().enumerate().find(|&(j, v)| {
                v.is_infinite()
                    || v.abs() > LARGEST_VALUE
                    || (v.is_nan() && (!cfg.fills() || j >= projected))
            });
            if let Some((j, &value)) = bad_input {
                return Err(FitError::NotFinite {
                    row,
                    column: self.feature_columns[j].clone(),
                    value,
                    why: if value.abs() > LARGEST_VALUE && value.is_finite() {
                        "beyond ±1e15: not a measurement (scaling would lose every other value)"
                    } else if cfg.fills() && j < projected {
                        "inputs must be finite; a missing marker's feature may be NaN"
                    } else {
                        "inputs that are not projected must be finite"
                    },
                });
            }
            let bad_target = t
                .iter()
                .enumerate()
                .find(|(_, v)| !v.is_finite() || v.abs() > LARGEST_VALUE);
            if let Some((j, &value)) = bad_target {
                return Err(FitError::NotFinite {
                    row,
                    column: self.targets[j].clone(),
                    value,
                    why: "targets must be finite and within ±1e15",
                });
            }
        }
        Ok(())
    }
}

/// The memory a training needs at its peak, bytes (a bound, not an exact count), for each
/// network trained at once (an ensemble's members train in parallel):
/// - the damped system, one buffer of the smaller of residuals and weights, squared (see
///   [`crate::lm`]), and its kept band;
/// - with fewer residuals than weights (the dual system) the Jacobian by layers: each
///   layer's sensitivities (residuals × width) and inputs (samples × inputs), and the Gram
///   matrix of each layer's inputs (samples²);
/// - otherwise one block of [`crate::mlp::NORMAL_BLOCK`] samples' Jacobian rows: weights ×
///   block residuals — the same for any number of samples;
/// - the samples' activations.
pub fn training_memory_bytes(
    inputs: usize,
    samples: usize,
    targets: usize,
    cfg: &FitConfig,
) -> u64 {
    let sizes: Vec<usize> = std::iter::once(inputs)
        .chain(cfg.hidden.iter().copied())
        .chain(std::iter::once(targets))
        .collect();
    let n = Mlp::n_params_for(&sizes) as u128;
    let (s, t) = (samples as u128, targets as u128);
    let m = s * t;
    let k = n.min(m);
    let layers = sizes.len() as u128 - 1;
    let widths: u128 = sizes[1..].iter().map(|&w| w as u128).sum();
    let fan_in: u128 = sizes[..sizes.len() - 1]
        .iter()
        .map(|&w| w as u128 + 1)
        .sum();
    let jacobian = if m < n {
        m * widths + s * fan_in + layers * s * s
    } else {
        let block = crate::mlp::NORMAL_BLOCK as u128;
        n * block * (t + 1) + block * (widths + fan_in) * (t + 1)
    };
    let activations = s * sizes.iter().map(|&w| w as u128).sum::<u128>();
    let system = crate::damped::buffer_len(k as usize) as u128 + k * crate::damped::BAND as u128;
    let one = 8 * (system + jacobian + 2 * activations + 4 * n);
    let parallel = cfg.ensemble.max(1).min(rayon::current_num_threads()) as u128;
    u64::try_from(one * parallel).unwrap_or(u64::MAX)
}

/// Refuses a training whose [`training_memory_bytes`] exceed `limit_bytes`, saying both;
/// otherwise gives the estimate, to be stated before the training starts.
pub fn check_training_memory(
    (inputs, samples, targets): (usize, usize, usize),
    cfg: &FitConfig,
    limit_bytes: u64,
) -> Result<u64, FitError> {
    let need = training_memory_bytes(inputs, samples, targets, cfg);
    if need > limit_bytes {
        let gib = |b: u64| b as f64 / 1024f64.powi(3);
        return Err(FitError::Config(format!(
            "this training needs about {:.1} GiB ({inputs} inputs, hidden {:?}, {samples} samples × {targets} targets) and {:.1} GiB may be used: use fewer or smaller hidden layers, or fewer inputs (components)",
            gib(need),
            cfg.hidden,
            gib(limit_bytes)
        )));
    }
    Ok(need)
}

/// The largest magnitude an input or a target may have: beyond it a value is not a
/// measurement, and mapminmax scaling would squash every other value of its column to one.
pub const LARGEST_VALUE: f64 = 1e15;

impl FitData<'_> {
    /// The targets whose every sample has the same value: a network learns nothing about them
    /// (their R is 0 by definition); worth a warning.
    pub fn constant_targets(&self) -> Vec<String> {
        (0..self.targets.len())
            .filter(|&j| self.t.iter().all(|r| r[j] == self.t[0][j]))
            .map(|j| self.targets[j].clone())
            .collect()
    }
}

/// The scaled inputs projected onto `cfg.components` principal components of their first
/// `projected` columns (the rest pass by), when asked for. The components come from the
/// complete samples; samples with lost markers get the scores that fit the markers found.
fn project(
    xs: Vec<Vec<f64>>,
    projected: usize,
    cfg: &FitConfig,
) -> Result<(Option<Projection>, Vec<Vec<f64>>), FitError> {
    let projection = cfg
        .components
        .map(|k| {
            let complete: Vec<Vec<f64>> = xs
                .iter()
                .filter(|r| r.iter().all(|v| !v.is_nan()))
                .map(|r| r[..projected].to_vec())
                .collect();
            Projection::fit(&complete, k)
        })
        .transpose()?;
    let xs = match &projection {
        Some(p) => xs
            .iter()
            .enumerate()
            .map(|(row, r)| {
                let mut z = p
                    .apply_partial(&r[..projected])
                    .ok_or(FitError::Projection(ProjectionError::Sparse(row)))?;
                z.extend_from_slice(&r[projected..]);
                Ok(z)
            })
            .collect::<Result<_, FitError>>()?,
        None => xs,
    };
    Ok((projection, xs))
}

/// Networks in the default ensemble for `samples` training samples and the input set chosen:
/// five; from [`LARGE_TABLE`] samples three Levenberg–Marquardt networks, where each costs
/// seconds per network and three were within 2.5 % of five on 1 280 touches of seed 000's
/// membrane, or [`WIDE_ENSEMBLE`] wide networks (docs/benchmarks.md).
pub fn ensemble_for(samples: usize, set: &InputSet, cfg: &FitConfig) -> usize {
    if samples < LARGE_TABLE {
        cfg.ensemble
    } else if set.algorithm(cfg.algorithm) == Algorithm::Adam {
        cfg.ensemble.min(WIDE_ENSEMBLE)
    } else {
        cfg.ensemble.min(3)
    }
}

/// Wide networks (Adam) in the default ensemble: four train in two rounds on two cores where
/// five took three, 24 % less wall time (84.4 → 64.3 s on the real 127-pin TacTip set, 164 →
/// 125 s on 5 000 simulated TacTip touches × 6 targets), with test errors within 1.3 % and
/// 1.8 % of five's (docs/benchmarks.md).
pub const WIDE_ENSEMBLE: usize = 4;

/// When trainbr stops early for a table of `samples` samples: from [`LARGE_TABLE`] once
/// [`Settle::DEFAULT`] (3 % over 10 epochs) holds; below it never — a few hundred touches
/// train in seconds to LM's own stops, and stopping them early cost 2–17 % of accuracy on the
/// zoo (docs/benchmarks.md).
pub fn settle_for(samples: usize) -> Option<Settle> {
    (samples >= LARGE_TABLE).then_some(Settle::DEFAULT)
}

/// The trainer's settings for `cfg`: its algorithm's, with its epochs, seed and subsets.
fn train_config(cfg: &FitConfig, samples: usize) -> TrainConfig {
    let base = TrainConfig::of(cfg.algorithm);
    // Adam's epochs are cheap passes that its own stop ends; it keeps its own cap too.
    let most = match base.trainer {
        Trainer::Adam(adam) => cfg.max_epochs.min(adam.max_epochs),
        Trainer::Lm(_) | Trainer::Br(_) => cfg.max_epochs,
    };
    let trainer = match base.trainer.with_max_epochs(most) {
        Trainer::Br(br) => Trainer::Br(BrTraining {
            settle: br.settle.and(settle_for(samples)),
            ..br
        }),
        other => other,
    };
    TrainConfig {
        trainer,
        seed: cfg.seed,
        split: if cfg.hold_out {
            TrainConfig::TRAINLM.split
        } else {
            base.split
        },
    }
}

/// Per target, a subset's MSE in target units (scaled MSE × (span / 2)²) and R (unchanged by
/// mapminmax, a linear map per target), from one forward pass per sample. An empty subset
/// (trainbr trains on every sample) has no figures: empty lists, never NaN (JSON has no NaN).
fn subset_figures(
    net: &Mlp,
    ids: &[usize],
    (xs, ts): (&[Vec<f64>], &[Vec<f64>]),
    target_scaling: &MinMax,
) -> (Vec<f64>, Vec<f64>) {
    if ids.is_empty() {
        return (Vec::new(), Vec::new());
    }
    let est: Vec<Vec<f64>> = ids.iter().map(|&i| net.forward(&xs[i])).collect();
    (0..target_scaling.min.len())
        .map(|j| {
            let e: Vec<f64> = est.iter().map(|v| v[j]).collect();
            let t: Vec<f64> = ids.iter().map(|&i| ts[i][j]).collect();
            let f = target_errors("", &e, &t);
            let half = 0.5 * (target_scaling.max[j] - target_scaling.min[j]);
            (f.mse * half * half, f.r)
        })
        .unzip()
}

/// Where a training is, for progress lines: sent after every epoch of every network, and once
/// more when a network has finished.
#[derive(Clone, Copy, Debug)]
pub struct FitProgress {
    /// Which network (from 0) of this [`fit`]'s ensemble.
    pub network: usize,
    /// Networks in this [`fit`].
    pub networks: usize,
    /// Epochs done by this network.
    pub epoch: usize,
    /// Its training MSE (scaled targets).
    pub train_mse: f64,
    /// Its validation MSE (NaN without a validation subset).
    pub validation_mse: f64,
    /// Whether this network has finished (the last call for it).
    pub finished: bool,
}

/// A progress callback: may be called from several threads at once (the ensemble's networks
/// train in parallel); [`Control::Stop`] stops the network that called it.
pub trait Progress: Fn(&FitProgress) -> Control + Sync {}
impl<F: Fn(&FitProgress) -> Control + Sync> Progress for F {}

/// No progress wanted.
pub fn quietly(_: &FitProgress) -> Control {
    Control::Continue
}

/// The filler of `xs`' first `markers` columns (scaled) when `cfg` asks for one and they are
/// not projected, with the rows' lost values filled by it.
fn fill(
    mut xs: Vec<Vec<f64>>,
    markers: usize,
    cfg: &FitConfig,
) -> Result<(Option<Projection>, Vec<Vec<f64>>), FitError> {
    let Some(k) = cfg.fill.filter(|_| cfg.components.is_none() && markers > 0) else {
        return Ok((None, xs));
    };
    let complete: Vec<Vec<f64>> = xs
        .iter()
        .filter(|r| r[..markers].iter().all(|v| !v.is_nan()))
        .map(|r| r[..markers].to_vec())
        .collect();
    let k = k.min(markers).min(complete.len().saturating_sub(1)).max(1);
    let filler = Projection::fit(&complete, k)?;
    for (row, r) in xs.iter_mut().enumerate() {
        if !filler.fill_missing(&mut r[..markers]) {
            return Err(FitError::Projection(ProjectionError::Sparse(row)));
        }
    }
    Ok((Some(filler), xs))
}

/// Network `i` of `networks` of a model with layer `sizes`, trained on the scaled rows
/// `xs`, `ts` on its own seed, telling `progress`.
fn train_network(
    (xs, ts): (&[Vec<f64>], &[Vec<f64>]),
    sizes: &[usize],
    (i, networks): (usize, usize),
    cfg: &FitConfig,
    progress: &impl Progress,
) -> (Mlp, crate::mlp::TrainOutcome) {
    let seed = cfg.seed.wrapping_add(7919 * i as u64);
    let mut net = match cfg.algorithm {
        Algorithm::Adam => Mlp::glorot(sizes, seed),
        Algorithm::Trainlm | Algorithm::Trainbr => Mlp::nguyen_widrow(sizes, seed),
    };
    let member_cfg = TrainConfig {
        seed,
        ..train_config(cfg, xs.len())
    };
    let mut last = (0, f64::NAN, f64::NAN);
    let out = crate::mlp::train(&mut net, xs, ts, &member_cfg, |epoch, tr, va| {
        last = (epoch, tr, va);
        progress(&FitProgress {
            network: i,
            networks,
            epoch,
            train_mse: tr,
            validation_mse: va,
            finished: false,
        })
    });
    progress(&FitProgress {
        network: i,
        networks,
        epoch: last.0,
        train_mse: last.1,
        validation_mse: last.2,
        finished: true,
    });
    (net, out)
}

/// Scales, projects (or fills), initialises and trains the model's networks — all of an
/// ensemble's in parallel — calling `progress` after every epoch of each (returning
/// [`Control::Stop`] stops that network). The first network reports the training figures.
/// Non-convergence is in the model's [`TrainingSummary::stop`], not an error.
pub fn fit(
    data: &FitData<'_>,
    cfg: &FitConfig,
    progress: impl Progress,
) -> Result<Model, FitError> {
    data.validate(cfg)?;
    let (x, t) = (data.x, data.t);
    let input_scaling = MinMax::fit(x);
    let target_scaling = MinMax::fit(t);
    let xs: Vec<Vec<f64>> = x.iter().map(|r| input_scaling.apply(r)).collect();
    let markers = data.feature_columns.len() - cfg.passthrough;
    let (projection, xs) = project(xs, markers, cfg)?;
    let (filler, xs) = fill(xs, markers, cfg)?;
    let ts: Vec<Vec<f64>> = t.iter().map(|r| target_scaling.apply(r)).collect();
    let mut sizes = vec![projection.as_ref().map_or(data.feature_columns.len(), |p| {
        p.outputs() + cfg.passthrough
    })];
    sizes.extend(&cfg.hidden);
    sizes.push(data.targets.len());
    let networks = cfg.ensemble.max(1);
    // Every network on its own seed (and split), in parallel.
    let mut trained: Vec<(Mlp, crate::mlp::TrainOutcome)> = (0..networks)
        .into_par_iter()
        .map(|i| train_network((&xs, &ts), &sizes, (i, networks), cfg, &progress))
        .collect();
    let held_out = held_out_errors(&trained, (&xs, &ts), &target_scaling);
    let (net, out) = trained.remove(0);
    let members: Vec<Mlp> = trained.into_iter().map(|(m, _)| m).collect();
    let figures = |ids: &[usize]| subset_figures(&net, ids, (&xs, &ts), &target_scaling);
    let [(mse0, r0), (mse1, r1), (mse2, r2)] = out.subsets.each_ref().map(|ids| figures(ids));
    let stop = if out.validation_stop {
        "validation".to_string()
    } else if out.settled {
        "settled".to_string()
    } else {
        format!("{:?}", out.lm.reason)
    };
    Ok(Model {
        format: MODEL_FORMAT.to_string(),
        version: MODEL_VERSION,
        net,
        members,
        input_scaling,
        passthrough: if projection.is_some() || filler.is_some() {
            cfg.passthrough
        } else {
            0
        },
        projection,
        filler,
        target_scaling,
        feature_columns: data.feature_columns.to_vec(),
        target_columns: data.targets.to_vec(),
        training: TrainingSummary {
            epochs: out.lm.iterations,
            best_epoch: out.best_epoch,
            stop,
            samples: out.subsets.each_ref().map(Vec::len),
            mse: [mse0, mse1, mse2],
            r: [r0, r1, r2],
            seed: cfg.seed,
            algorithm: cfg.algorithm.name().to_string(),
            evidence: out.evidence,
            selection: Vec::new(),
        },
        sensor: None,
        held_out,
    })
}

/// The samples some network of `trained` held out (validation and test subsets), each with
/// the mean estimate of the networks that held it out (scaled) and its absolute error per
/// target in target units; `None` when too few were held out ([`HeldOutErrors::new`]).
fn held_out_errors(
    trained: &[(Mlp, crate::mlp::TrainOutcome)],
    (xs, ts): (&[Vec<f64>], &[Vec<f64>]),
    target_scaling: &MinMax,
) -> Option<HeldOutErrors> {
    let width = target_scaling.min.len();
    let mut sum = vec![vec![0.0; width]; xs.len()];
    let mut count = vec![0usize; xs.len()];
    for (net, out) in trained {
        for &i in out.subsets[1].iter().chain(&out.subsets[2]) {
            for (s, e) in sum[i].iter_mut().zip(net.forward(&xs[i])) {
                *s += e;
            }
            count[i] += 1;
        }
    }
    let half: Vec<f64> = (0..width)
        .map(|j| 0.5 * (target_scaling.max[j] - target_scaling.min[j]))
        .collect();
    let (estimates, errors) = (0..xs.len())
        .filter(|&i| count[i] > 0)
        .map(|i| {
            let e: Vec<f64> = sum[i].iter().map(|s| s / count[i] as f64).collect();
            let err = (0..width)
                .map(|j| (e[j] - ts[i][j]).abs() * half[j])
                .collect();
            (e, err)
        })
        .unzip();
    HeldOutErrors::new(estimates, errors)
}

/// Trains on every sample of `data`, reading the columns of `set` (`cfg` otherwise).
pub fn fit_set(
    data: &FitData<'_>,
    set: &InputSet,
    cfg: &FitConfig,
    progress: impl Progress,
) -> Result<Model, FitError> {
    let everyone: Vec<usize> = (0..data.x.len()).collect();
    fit_rows(data, set, &everyone, cfg, progress)
}

/// Trains on the samples `rows` of `data`, reading the columns of `set` (`cfg` otherwise; the
/// wide set its own network).
fn fit_rows(
    data: &FitData<'_>,
    set: &InputSet,
    rows: &[usize],
    cfg: &FitConfig,
    progress: impl Progress,
) -> Result<Model, FitError> {
    let x: Vec<Vec<f64>> = rows
        .iter()
        .map(|&i| set.columns.iter().map(|&c| data.x[i][c]).collect())
        .collect();
    let t: Vec<Vec<f64>> = rows.iter().map(|&i| data.t[i].clone()).collect();
    let names: Vec<String> = set
        .columns
        .iter()
        .map(|&c| data.feature_columns[c].clone())
        .collect();
    let sub = FitData {
        x: &x,
        t: &t,
        feature_columns: &names,
        targets: data.targets,
    };
    let set_cfg = FitConfig {
        components: set.components,
        passthrough: set.passthrough,
        hidden: set.hidden(&cfg.hidden).to_vec(),
        algorithm: set.algorithm(cfg.algorithm),
        fill: if set.wide {
            Some(FILL_COMPONENTS)
        } else {
            cfg.fill
        },
        ..cfg.clone()
    };
    fit(&sub, &set_cfg, progress)
}

/// How many of `folds` folds the input choice trains for `samples` samples: all of them below
/// [`LARGE_TABLE`]; from it one (a hold-out of one sample in `folds`, plenty to tell the sets
/// apart and `folds` times cheaper).
pub fn folds_trained(samples: usize, folds: usize) -> usize {
    if samples >= LARGE_TABLE {
        1
    } else {
        folds
    }
}

/// Which of `sets` to train on: the one whose `folds`-fold cross-validated error is lowest (one
/// network per fold, `cfg` otherwise), with every set's score. On a large table
/// ([`folds_trained`]) every set is first scored on one fold; the sets that fold cannot tell
/// from the best ([`ONE_FOLD_RESOLUTION`]) are then scored on every fold, and the choice is
/// theirs. One set (or too few samples for the folds): the first, with no scores. `progress`
/// numbers the networks over all sets and folds, those of the second round after the first's.
pub fn choose_inputs(
    data: &FitData<'_>,
    cfg: &FitConfig,
    sets: &[InputSet],
    folds: usize,
    progress: impl Progress,
) -> Result<(usize, Vec<InputScore>), FitError> {
    if sets.len() <= 1 || folds < 2 || data.x.len() < 2 * folds {
        return Ok((0, Vec::new()));
    }
    let n = data.x.len();
    // Fold k holds out the samples whose place in a seeded shuffle is k modulo `folds`.
    let [order, _, _] = crate::mlp::random_split(n, [1.0, 0.0, 0.0], cfg.seed ^ 0xF01D);
    let mut fold_of = vec![0; n];
    for (place, &i) in order.iter().enumerate() {
        fold_of[i] = place % folds;
    }
    let first = folds_trained(n, folds);
    let variance = target_variances(data.t, data.targets.len());
    let held = held_out_estimates(data, cfg, sets, (&fold_of, 0..first), (0, &progress))?;
    let mut scores: Vec<InputScore> = sets
        .iter()
        .zip(held)
        .map(|(set, h)| score_of(data.t, &variance, (&set.name, h), first))
        .collect();
    let lowest = |scores: &[InputScore], among: &mut dyn Iterator<Item = usize>| {
        among
            .min_by(|&a, &b| scores[a].error.total_cmp(&scores[b].error))
            .unwrap_or(0)
    };
    let mut best = lowest(&scores, &mut (0..sets.len()));
    if first < folds {
        let close: Vec<usize> = (0..sets.len())
            .filter(|&s| scores[s].error <= ONE_FOLD_RESOLUTION * scores[best].error)
            .collect();
        if close.len() > 1 {
            let contenders: Vec<InputSet> = close.iter().map(|&s| sets[s].clone()).collect();
            let more = held_out_estimates(
                data,
                cfg,
                &contenders,
                (&fold_of, first..folds),
                (sets.len() * first, &progress),
            )?;
            for (&s, extra) in close.iter().zip(more) {
                let mut h = std::mem::take(&mut scores[s].held_out);
                h.extend(extra);
                scores[s] = score_of(data.t, &variance, (&sets[s].name, h), folds);
            }
            best = lowest(&scores, &mut close.into_iter());
        }
    }
    scores[best].chosen = true;
    Ok((best, scores))
}

/// [`choose_inputs`], then [`fit_set`] on the set chosen; the model's
/// [`TrainingSummary::selection`] keeps every set's score. No sets: every column as `cfg`
/// says. `progress` follows the final training.
pub fn fit_choosing(
    data: &FitData<'_>,
    cfg: &FitConfig,
    sets: &[InputSet],
    folds: usize,
    progress: impl Progress,
) -> Result<Model, FitError> {
    fit_choosing_ensemble(data, cfg, (sets, folds), |_| cfg.ensemble, progress)
}

/// [`fit_choosing`] with `ensemble(set)` networks for the set chosen — `visuotact train`'s
/// default is [`ensemble_for`] the table's size.
pub fn fit_choosing_ensemble(
    data: &FitData<'_>,
    cfg: &FitConfig,
    (sets, folds): (&[InputSet], usize),
    ensemble: impl Fn(&InputSet) -> usize,
    progress: impl Progress,
) -> Result<Model, FitError> {
    if sets.is_empty() {
        return fit(data, cfg, progress);
    }
    let (best, mut scores) = choose_inputs(data, cfg, sets, folds, quietly)?;
    let cfg = FitConfig {
        ensemble: ensemble(&sets[best]),
        ..cfg.clone()
    };
    let mut model = fit_set(data, &sets[best], &cfg, progress)?;
    with_held_out_errors(&mut model, &mut scores, data.t);
    model.training.selection = scores;
    Ok(model)
}

/// Gives `model` (trained on every sample of `targets`) the held-out errors of the chosen
/// set's cross-validation ([`InputScore::held_out`]) when its own networks held nothing out
/// (trainbr), so that its spread is a held-out error too ([`crate::heldout`]). The fold
/// networks are single ones, not the ensemble: the figure leans to the cautious side. Every
/// score's estimates are taken out (the scores then equal what the model file keeps).
pub fn with_held_out_errors(model: &mut Model, scores: &mut [InputScore], targets: &[Vec<f64>]) {
    let taken: Vec<Vec<(usize, Vec<f64>)>> = scores
        .iter_mut()
        .map(|s| std::mem::take(&mut s.held_out))
        .collect();
    if model.held_out.is_some() {
        return;
    }
    let Some(chosen) = scores.iter().position(|s| s.chosen) else {
        return;
    };
    let (estimates, errors) = taken[chosen]
        .iter()
        .filter(|(i, e)| *i < targets.len() && e.iter().all(|v| v.is_finite()))
        .map(|(i, e)| {
            let err = e
                .iter()
                .zip(&targets[*i])
                .map(|(e, t)| (e - t).abs())
                .collect();
            (model.target_scaling.apply(e), err)
        })
        .unzip();
    model.held_out = HeldOutErrors::new(estimates, errors);
}

/// Samples held out, each with its estimate (target units).
type HeldOut = Vec<(usize, Vec<f64>)>;

/// Per set, each sample held out by the folds `trained` of `fold_of` (a sample's fold) with
/// the estimate of the network trained without that fold (target units). Every set sees the
/// same folds and initial weights. `progress` numbers the networks after the first `done`.
fn held_out_estimates(
    data: &FitData<'_>,
    cfg: &FitConfig,
    sets: &[InputSet],
    (fold_of, trained): (&[usize], std::ops::Range<usize>),
    (done, progress): (usize, &impl Progress),
) -> Result<Vec<HeldOut>, FitError> {
    let n = data.x.len();
    let fold_cfg = FitConfig {
        ensemble: 1,
        ..cfg.clone()
    };
    let jobs: Vec<(usize, usize)> = (0..sets.len())
        .flat_map(|s| trained.clone().map(move |k| (s, k)))
        .collect();
    let estimates: Vec<HeldOut> = jobs
        .par_iter()
        .enumerate()
        .map(|(job, &(s, k))| {
            let train: Vec<usize> = (0..n).filter(|&i| fold_of[i] != k).collect();
            let model = fit_rows(data, &sets[s], &train, &fold_cfg, |p: &FitProgress| {
                progress(&FitProgress {
                    network: done + job,
                    networks: done + jobs.len(),
                    ..*p
                })
            })?;
            (0..n)
                .filter(|&i| fold_of[i] == k)
                .map(|i| {
                    let row: Vec<f64> = sets[s].columns.iter().map(|&c| data.x[i][c]).collect();
                    let e = model
                        .estimate(&row)
                        .map_err(|source| FitError::HeldOut { sample: i, source })?;
                    Ok((i, e.values))
                })
                .collect::<Result<_, FitError>>()
        })
        .collect::<Result<_, FitError>>()?;
    let mut per_set = vec![Vec::new(); sets.len()];
    for ((s, _), e) in jobs.into_iter().zip(estimates) {
        per_set[s].extend(e);
    }
    Ok(per_set)
}

/// The score of the set `name` from the samples `held` out (over `folds` folds) with their
/// estimates: per target the squared error over the target's `variance` (over every sample of
/// `targets`), and their mean.
fn score_of(
    targets: &[Vec<f64>],
    variance: &[f64],
    (name, held): (&str, HeldOut),
    folds: usize,
) -> InputScore {
    let normalised_mse: Vec<f64> = variance
        .iter()
        .enumerate()
        .map(|(j, v)| {
            let se: f64 = held
                .iter()
                .map(|(i, e)| (e[j] - targets[*i][j]).powi(2))
                .sum();
            se / held.len().max(1) as f64 / v.max(f64::MIN_POSITIVE)
        })
        .collect();
    InputScore {
        inputs: name.to_string(),
        error: normalised_mse.iter().sum::<f64>() / normalised_mse.len().max(1) as f64,
        normalised_mse,
        folds,
        chosen: false,
        held_out: held,
    }
}

/// Each of the `count` targets' variance over the samples `targets`.
fn target_variances(targets: &[Vec<f64>], count: usize) -> Vec<f64> {
    let n = targets.len() as f64;
    (0..count)
        .map(|j| {
            let mean = targets.iter().map(|r| r[j]).sum::<f64>() / n;
            targets.iter().map(|r| (r[j] - mean).powi(2)).sum::<f64>() / n
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(prefix: &str, n: usize) -> Vec<String> {
        (0..n).map(|i| format!("{prefix}{i}")).collect()
    }

    #[test]
    fn each_algorithm_trains_with_its_own_settings_and_the_users_epochs() {
        let with = |algorithm, max_epochs| FitConfig {
            algorithm,
            max_epochs,
            seed: 9,
            ..FitConfig::default()
        };
        let lm = train_config(&with(Algorithm::Trainlm, 50), 100);
        assert_eq!(lm.trainer, TrainConfig::TRAINLM.trainer.with_max_epochs(50));
        assert_eq!((lm.seed, lm.split), (9, TrainConfig::TRAINLM.split));
        // trainbr settles early only on a large table.
        let br = |samples| match train_config(&with(Algorithm::Trainbr, 50), samples).trainer {
            Trainer::Br(br) => (br.settle, br.lm.max_iterations),
            other => panic!("trainbr trained by {other:?}"),
        };
        assert_eq!(br(LARGE_TABLE - 1), (None, 50));
        assert_eq!(br(LARGE_TABLE), (Some(Settle::DEFAULT), 50));
        // Adam keeps its own cap and patience.
        let adam = crate::adam::AdamConfig::DEFAULT;
        for (asked, got) in [(50, 50), (100_000, adam.max_epochs)] {
            let cfg = train_config(&with(Algorithm::Adam, asked), 100);
            assert_eq!(cfg.trainer, Trainer::Adam(adam).with_max_epochs(got));
            assert_eq!(cfg.trainer.algorithm(), Algorithm::Adam);
            assert_eq!(cfg.trainer.max_epochs(), got);
        }
    }

    #[test]
    fn bad_tables_are_refused_with_the_sample_and_column() {
        let x = vec![vec![0.0, 1.0], vec![1.0, f64::INFINITY]];
        let t = vec![vec![0.0], vec![1.0]];
        let (cols, targets) = (names("m", 2), names("y", 1));
        let data = FitData {
            x: &x,
            t: &t,
            feature_columns: &cols,
            targets: &targets,
        };
        let err = fit(&data, &FitConfig::default(), quietly).unwrap_err();
        assert!(
            matches!(&err, FitError::NotFinite { row: 1, column, .. } if column == "m1"),
            "{err}"
        );
        let t_nan = vec![vec![0.0], vec![f64::NAN]];
        let x_ok = vec![vec![0.0, 1.0], vec![1.0, 0.0]];
        let data = FitData {
            x: &x_ok,
            t: &t_nan,
            ..data
        };
        let err = fit(&data, &FitConfig::default(), quietly).unwrap_err();
        assert!(err.to_string().contains("targets must be finite"), "{err}");
        let short = vec![vec![0.0], vec![1.0, 0.0]];
        let data = FitData {
            x: &short,
            t: &t,
            ..data
        };
        let err = fit(&data, &FitConfig::default(), quietly).unwrap_err();
        assert_eq!(
            err,
            FitError::Width {
                row: 0,
                what: "inputs",
                got: 1,
                expected: 2
            }
        );
        let bad = FitConfig {
            hidden: vec![],
            ..FitConfig::default()
        };
        let data = FitData { x: &x_ok, ..data };
        assert!(matches!(
            fit(&data, &bad, quietly),
            Err(FitError::Config(_))
        ));
        // Settings that would train nothing, and a column named twice.
        for (bad, why) in [
            (
                FitConfig {
                    ensemble: 0,
                    ..FitConfig::default()
                },
                "ensemble of 0",
            ),
            (
                FitConfig {
                    max_epochs: 0,
                    ..FitConfig::default()
                },
                "at most 0 epochs",
            ),
        ] {
            let err = fit(&data, &bad, quietly).unwrap_err().to_string();
            assert!(err.contains(why), "{err}");
        }
        let (t2, twice) = (
            vec![vec![0.0, 0.0], vec![1.0, 1.0]],
            vec!["y0".to_string(), "y0".to_string()],
        );
        let data = FitData {
            t: &t2,
            targets: &twice,
            ..data
        };
        let err = fit(&data, &FitConfig::default(), quietly).unwrap_err();
        assert!(err.to_string().contains("`y0` named twice"), "{err}");
    }

    #[test]
    fn an_ensemble_is_deterministic_and_its_members_differ() {
        let x: Vec<Vec<f64>> = (0..60)
            .map(|i| vec![(i % 6) as f64, (i % 10) as f64 * 0.3])
            .collect();
        let t: Vec<Vec<f64>> = x.iter().map(|r| vec![(r[0] * r[1]).sin()]).collect();
        let cfg = FitConfig {
            hidden: vec![4],
            ensemble: 3,
            max_epochs: 50,
            ..FitConfig::default()
        };
        let a = fitted(&x, &t, &cfg);
        let b = fitted(&x, &t, &cfg);
        assert_eq!(a.to_json(), b.to_json());
        assert_eq!(a.networks().count(), 3);
        assert_ne!(a.members[0], a.members[1]);
        assert_eq!(a.training.algorithm, "trainbr");
        // A row of the wrong width is refused, never read out of bounds.
        let err = a.estimate(&[1.0]).unwrap_err();
        assert!(
            matches!(
                err,
                crate::model::EstimateError::Width {
                    given: 1,
                    expected: 2,
                    ..
                }
            ),
            "{err}"
        );
        assert!(err
            .to_string()
            .contains("1 inputs given, the model reads 2"));
        assert!(a.predict(&[1.0, 2.0, 3.0])[0].is_nan());
    }

    /// t = 2x plus noise of σ 0.02 below x = 0.5 and 0.3 above (800 samples, seeded).
    fn noisy_line() -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut gauss = || {
            let (u, v): (f64, f64) = (rng.random_range(1e-12..1.0), rng.random_range(0.0..1.0));
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        };
        let x: Vec<Vec<f64>> = (0..800).map(|i| vec![(i as f64 + 0.5) / 800.0]).collect();
        let t = x
            .iter()
            .map(|r| vec![2.0 * r[0] + if r[0] < 0.5 { 0.02 } else { 0.3 } * gauss()])
            .collect();
        (x, t)
    }

    /// The standard deviation of `m`'s networks' estimates of target 0 at `x`.
    fn networks_sd(m: &Model, x: f64) -> f64 {
        let (each, _) = m.estimate_each(&[x]).unwrap();
        let k = each.len() as f64;
        let mean = each.iter().map(|o| o[0]).sum::<f64>() / k;
        (each.iter().map(|o| (o[0] - mean).powi(2)).sum::<f64>() / (k - 1.0)).sqrt()
    }

    /// A model of targets `t` (columns y0, y1, …) from inputs `x` (m0, m1, …) trained as `cfg`.
    fn fitted(x: &[Vec<f64>], t: &[Vec<f64>], cfg: &FitConfig) -> Model {
        let (cols, targets) = (names("m", x[0].len()), names("y", t[0].len()));
        let data = FitData {
            x,
            t,
            feature_columns: &cols,
            targets: &targets,
        };
        fit(&data, cfg, quietly).unwrap()
    }

    /// A 3-network model of [`noisy_line`] trained by `algorithm`.
    fn noisy_line_model(algorithm: Algorithm) -> Model {
        let (x, t) = noisy_line();
        let cfg = FitConfig {
            hidden: vec![3],
            ensemble: 3,
            algorithm,
            max_epochs: 100,
            ..FitConfig::default()
        };
        fitted(&x, &t, &cfg)
    }

    #[test]
    fn the_spread_is_the_held_out_error_where_the_networks_agree_on_noise() {
        // Every network fits the same line, so their spread is small on both halves; the
        // held-out errors are not.
        let m = noisy_line_model(Algorithm::Trainlm);
        let h = m
            .held_out
            .as_ref()
            .expect("trainlm holds out 30 % per network");
        // Three networks holding out 30 % each: about two thirds of the samples.
        assert!(
            (400..700).contains(&h.estimates.len()),
            "{}",
            h.estimates.len()
        );
        for (x, lo, hi) in [
            (0.2, 0.01, 0.05),
            (0.3, 0.01, 0.05),
            (0.7, 0.2, 0.45),
            (0.85, 0.2, 0.45),
        ] {
            let e = m.estimate(&[x]).unwrap();
            assert!(
                (lo..hi).contains(&e.spread[0]),
                "x {x}: held-out rms {}",
                e.spread[0]
            );
            // The networks agree within a fraction of the noise above 0.5.
            assert!(networks_sd(&m, x) < 0.05, "x {x}");
        }
        assert_eq!(m.estimate_columns(), ["y0", "y0_std"]);
        // Where the held-out errors are smaller than the networks' disagreement, the spread is
        // the disagreement: the larger of the two.
        let mut exact = m.clone();
        for e in &mut exact.held_out.as_mut().unwrap().errors {
            e[0] = 0.0;
        }
        let sd = networks_sd(&exact, 0.7);
        assert!(sd > 0.0 && exact.estimate(&[0.7]).unwrap().spread[0] == sd);
        // The table travels in the model file; a damaged one is refused with the row.
        let back = Model::from_json(&m.to_json(), "m.json").unwrap();
        assert_eq!(back.held_out, m.held_out);
        let mut bad = m.clone();
        bad.held_out.as_mut().unwrap().errors[3] = vec![];
        let e = Model::from_json(&bad.to_json(), "m.json").unwrap_err();
        assert!(e.to_string().contains("row 3 has 0 values"), "{e}");
    }

    #[test]
    fn a_model_that_held_nothing_out_states_its_networks_spread() {
        // trainbr trains on every sample: no held-out table, the ensemble's spread as before.
        let br = noisy_line_model(Algorithm::Trainbr);
        assert!(br.held_out.is_none());
        let e = br.estimate(&[0.7]).unwrap();
        assert!((e.spread[0] - networks_sd(&br, 0.7)).abs() < 1e-12);
    }

    #[test]
    fn the_auto_rule_projects_wide_tables_only() {
        assert_eq!(auto_components(20), None);
        assert_eq!(auto_components(21), Some(AUTO_COMPONENTS));
        assert!(!auto_field(6) && auto_field(351));
        let cfg = FitConfig::auto(351, 6);
        assert_eq!((cfg.components, cfg.passthrough), (Some(10), 6));
        assert_eq!(FitConfig::paper(&[20]).algorithm, Algorithm::Trainlm);
        assert_eq!(FieldInputs::Auto.resolve(351), FieldInputs::Yes);
        assert_eq!(FieldInputs::Auto.resolve(6), FieldInputs::No);
        assert_eq!(
            FieldInputs::from_name("only").unwrap().resolve(6),
            FieldInputs::Only
        );
        assert_eq!(components_from_name("auto", 351), Ok(Some(10)));
        assert_eq!(components_from_name("0", 351), Ok(None));
        assert_eq!(components_from_name("4", 0), Ok(None));
        assert!(components_from_name("x", 351)
            .unwrap_err()
            .to_string()
            .contains("expected auto"));
    }

    #[test]
    fn auto_compares_markers_and_field_against_the_field_alone_on_wide_tables() {
        use ColumnKind::{Field, Marker, Other};
        let wide = [vec![Marker; 30], vec![Field; 6], vec![Other]].concat();
        let sets = candidate_inputs(&wide, Some(10), FieldInputs::Auto, false);
        assert_eq!(sets.len(), 2);
        assert_eq!(sets[0].columns, (0..37).collect::<Vec<_>>());
        assert_eq!((sets[0].components, sets[0].passthrough), (Some(10), 7));
        assert_eq!(sets[1].columns, (30..37).collect::<Vec<_>>());
        assert_eq!((sets[1].components, sets[1].passthrough), (None, 7));
        assert_eq!(sets[1].name, "the field summary + 1 other inputs");
        // Told what to read, or too few markers for the field summary by default: one set.
        assert_eq!(
            candidate_inputs(&wide, Some(10), FieldInputs::Yes, false).len(),
            1
        );
        let narrow = [vec![Marker; 6], vec![Field; 6]].concat();
        assert_eq!(
            candidate_inputs(&narrow, None, FieldInputs::Auto, false).len(),
            1
        );
        // Markers' features always come first, whatever the table's order.
        let mixed = [Other, Marker, Field, Marker];
        assert_eq!(InputSet::all(&mixed, None).columns, vec![1, 3, 2, 0]);
        let names: Vec<String> = ["m000_dx_px", "field_rms_px", "gauge_kpa"]
            .map(String::from)
            .to_vec();
        assert_eq!(
            column_kinds(&names, &["field_rms_px"]),
            vec![Marker, Field, Other]
        );
    }

    #[test]
    fn the_wide_network_is_also_tried_without_the_markers_shape_columns() {
        use ColumnKind::{Field, Marker, MarkerShape};
        // Ten markers: displacements, and an area change or an eccentricity change each.
        let mut names: Vec<String> = (0..10)
            .flat_map(|i| {
                let shape = if i % 2 == 0 { "darea_px" } else { "decc" };
                ["dx_px", "dy_px", shape].map(|s| format!("m{i:03}_{s}"))
            })
            .collect();
        names.push("field_rms_px".to_string());
        let kinds = column_kinds(&names, &["field_rms_px"]);
        assert_eq!(kinds.iter().filter(|&&k| k == MarkerShape).count(), 10);
        assert_eq!(kinds.iter().filter(|&&k| k == Marker).count(), 20);
        assert_eq!(kinds.last(), Some(&Field));
        let sets = candidate_inputs(&kinds, Some(10), FieldInputs::Auto, true);
        assert_eq!(sets.len(), 4);
        assert_eq!(sets[0].columns.len(), 31);
        assert_eq!(sets[2].columns.len(), 31);
        let shapeless = &sets[3];
        assert!(shapeless.wide && shapeless.components.is_none());
        assert_eq!(shapeless.columns.len(), 21);
        assert!(shapeless.columns[..20].iter().all(|&c| kinds[c] == Marker));
        assert_eq!(
            shapeless.name,
            "20 markers' displacements + the field summary into the wide network"
        );
        assert_eq!(
            sets[2].name,
            "30 markers' features + the field summary into the wide network"
        );
        // Not on small tables, nor where the markers have no shape columns.
        assert_eq!(
            candidate_inputs(&kinds, Some(10), FieldInputs::Auto, false).len(),
            2
        );
        // The default ensemble: five below a large table, then three LM networks or four wide.
        let cfg = FitConfig::default();
        let ensemble = |n: usize, s: &InputSet| ensemble_for(n, s, &cfg);
        assert_eq!(ensemble(LARGE_TABLE - 1, &sets[2]), 5);
        assert_eq!(ensemble(LARGE_TABLE, &sets[0]), 3);
        assert_eq!(ensemble(LARGE_TABLE, &sets[3]), WIDE_ENSEMBLE);
        let no_shape: Vec<ColumnKind> = kinds
            .iter()
            .map(|&k| if k == MarkerShape { Marker } else { k })
            .collect();
        assert_eq!(
            candidate_inputs(&no_shape, Some(10), FieldInputs::Auto, true).len(),
            3
        );
    }

    type Signal = dyn Fn(&[f64]) -> f64;

    /// A table of 24 "markers' features" (two latent values seen with noise) and 3 "field"
    /// columns (independent) where the target is a smooth function of the columns `signal`
    /// picks, with noise; seeded.
    fn table(signal: &Signal) -> (Vec<Vec<f64>>, Vec<Vec<f64>>, Vec<String>) {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        // The markers move together: two latent values, seen by each with its own weights.
        let x: Vec<Vec<f64>> = (0..80)
            .map(|_| {
                let (a, b): (f64, f64) = (rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
                let mut r: Vec<f64> = (0..24)
                    .map(|j| a * (j as f64).cos() + b * (j as f64).sin())
                    .map(|v| v + 0.05 * rng.random_range(-1.0..1.0))
                    .collect();
                r.extend((0..3).map(|_| rng.random_range(-1.0..1.0)));
                r
            })
            .collect();
        let t = x
            .iter()
            .map(|r| vec![signal(r) + 0.05 * rng.random_range(-1.0..1.0)])
            .collect();
        let mut columns = names("m0", 24);
        for c in &mut columns {
            *c = format!("m{:03}_dx_px", c[2..].parse::<usize>().unwrap());
        }
        columns.extend(names("field", 3));
        (x, t, columns)
    }

    #[test]
    fn cross_validation_keeps_the_inputs_that_carry_the_signal() {
        let targets = names("y", 1);
        let cfg = FitConfig {
            hidden: vec![6],
            ensemble: 1,
            max_epochs: 100,
            ..FitConfig::default()
        };
        let field_only = |r: &[f64]| (2.0 * r[24]).sin() * (1.5 * r[25]).cos();
        let markers_too = move |r: &[f64]| field_only(r) + r[0] - r[1];
        let signals: [&Signal; 2] = [&field_only, &markers_too];
        for (expected, signal) in [1, 0].into_iter().zip(signals) {
            let (x, t, columns) = table(signal);
            let kinds = column_kinds(&columns, &["field0", "field1", "field2"]);
            let sets = candidate_inputs(&kinds, Some(10), FieldInputs::Auto, false);
            let data = FitData {
                x: &x,
                t: &t,
                feature_columns: &columns,
                targets: &targets,
            };
            let m = fit_choosing(&data, &cfg, &sets, 4, quietly).unwrap();
            let chosen: Vec<bool> = m.training.selection.iter().map(|s| s.chosen).collect();
            assert_eq!(
                chosen,
                [expected == 0, expected == 1],
                "{:?}",
                m.training.selection
            );
            let wanted: Vec<&String> = sets[expected]
                .columns
                .iter()
                .map(|&c| &columns[c])
                .collect();
            assert_eq!(m.feature_columns.iter().collect::<Vec<_>>(), wanted);
            let winner = &m.training.selection[expected];
            assert!(
                winner.error < 0.2 && winner.error == winner.normalised_mse[0],
                "{winner:?}"
            );
            // The model file keeps the scores (not the fold networks' estimates).
            let back = Model::from_json(&m.to_json(), "test").unwrap();
            assert_eq!(back.training.selection, m.training.selection);
            // trainbr held nothing out; the folds held out every sample once, and the errors
            // the model keeps are those of the chosen set's fold networks.
            let h = m.held_out.as_ref().expect("the folds' held-out errors");
            assert_eq!(h.estimates.len(), x.len());
            let mse = h.errors.iter().map(|e| e[0] * e[0]).sum::<f64>() / x.len() as f64;
            let mean = t.iter().map(|r| r[0]).sum::<f64>() / x.len() as f64;
            let var = t.iter().map(|r| (r[0] - mean).powi(2)).sum::<f64>() / x.len() as f64;
            assert!((mse / var - winner.error).abs() < 1e-9 * winner.error.max(1.0));
            assert_eq!(back.held_out, m.held_out);
        }
    }

    #[test]
    fn a_large_table_chooses_the_wide_network_which_fills_lost_markers() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        // 24 markers' features moving on their own (ten components cannot hold them) and a
        // target that needs three of them.
        let n = LARGE_TABLE + 100;
        let mut x: Vec<Vec<f64>> = (0..n)
            .map(|_| (0..27).map(|_| rng.random_range(-1.0..1.0)).collect())
            .collect();
        let t: Vec<Vec<f64>> = x
            .iter()
            .map(|r: &Vec<f64>| vec![(2.0 * r[0]).sin() + r[1] * r[2]])
            .collect();
        for r in x.iter_mut().step_by(17) {
            r[7] = f64::NAN;
        }
        let mut columns: Vec<String> = (0..24).map(|i| format!("m{i:03}_dx_px")).collect();
        columns.extend(names("field", 3));
        let kinds = column_kinds(&columns, &["field0", "field1", "field2"]);
        let cfg = FitConfig {
            ensemble: 1,
            ..FitConfig::default()
        };
        let sets = candidate_inputs(&kinds, Some(10), FieldInputs::Auto, true);
        assert_eq!(
            sets.iter().map(|s| s.wide).collect::<Vec<_>>(),
            [false, false, true]
        );
        let data = FitData {
            x: &x,
            t: &t,
            feature_columns: &columns,
            targets: &names("y", 1),
        };
        let m = fit_choosing(&data, &cfg, &sets, SELECTION_FOLDS, quietly).unwrap();
        let chosen: Vec<bool> = m.training.selection.iter().map(|s| s.chosen).collect();
        assert_eq!(chosen, [false, false, true], "{:?}", m.training.selection);
        assert_eq!(m.net.sizes, [27, 64, 64, 1]);
        assert_eq!(m.training.algorithm, "adam");
        assert!(m.projection.is_none() && m.filler.is_some());
        // A frame with a lost marker is estimated, and the file reads back the same.
        let mut row = vec![0.5, -0.5, 0.5, 0.1, 0.2, 0.3, 0.4, 0.0];
        row.extend(std::iter::repeat_n(0.0, 19));
        row[7] = f64::NAN;
        let e = m.estimate(&row).unwrap();
        let want = 1f64.sin() - 0.25;
        assert!(
            (e.values[0] - want).abs() < 0.25,
            "{} vs {want}",
            e.values[0]
        );
        let back = Model::from_json(&m.to_json(), "test").unwrap();
        assert_eq!(back.estimate(&row).unwrap().values, e.values);
    }

    #[test]
    fn sets_one_fold_cannot_tell_apart_are_scored_on_every_fold() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let n = LARGE_TABLE;
        let x: Vec<Vec<f64>> = (0..n)
            .map(|_| (0..3).map(|_| rng.random_range(-1.0..1.0)).collect())
            .collect();
        let t: Vec<Vec<f64>> = x.iter().map(|r| vec![r[0] + 0.5 * r[1] * r[1]]).collect();
        let set = |name: &str, columns: Vec<usize>| InputSet {
            name: name.to_string(),
            columns,
            components: None,
            passthrough: 0,
            wide: false,
        };
        // Two sets reading the same columns score alike on the first fold; one reading only
        // the column the target does not depend on is far worse.
        let sets = [
            set("a", vec![0, 1, 2]),
            set("b", vec![0, 1, 2]),
            set("c", vec![2]),
        ];
        let cfg = FitConfig {
            hidden: vec![4],
            max_epochs: 20,
            ensemble: 1,
            ..FitConfig::default()
        };
        let data = FitData {
            x: &x,
            t: &t,
            feature_columns: &names("c", 3),
            targets: &names("y", 1),
        };
        let (best, scores) = choose_inputs(&data, &cfg, &sets, SELECTION_FOLDS, quietly).unwrap();
        let folds: Vec<usize> = scores.iter().map(|s| s.folds).collect();
        assert_eq!(folds, [SELECTION_FOLDS, SELECTION_FOLDS, 1], "{scores:?}");
        assert_eq!(best, 0);
        assert!(scores[0].chosen && !scores[1].chosen);
        // Every sample is held out once by the sets scored on every fold, a fifth by the other.
        assert_eq!(scores[0].held_out.len(), n);
        assert_eq!(scores[2].held_out.len(), n / SELECTION_FOLDS);
        assert!(scores[2].error > 2.0 * scores[0].error, "{scores:?}");
    }

    #[test]
    fn trainbr_settles_when_errors_and_effective_parameters_stop_moving() {
        let s = crate::mlp::Settle::DEFAULT;
        let falling: Vec<(f64, f64)> = (0..30).map(|i| (100.0 * 0.9f64.powi(i), 50.0)).collect();
        assert!(!s.settled(&falling));
        let flat: Vec<(f64, f64)> = (0..30)
            .map(|i| (10.0 - 0.001 * f64::from(i), 50.0))
            .collect();
        assert!(s.settled(&flat));
        assert!(!s.settled(&flat[..s.window]), "too short to tell");
        let gamma_moves: Vec<(f64, f64)> = (0..30).map(|i| (10.0, 40.0 + f64::from(i))).collect();
        assert!(!s.settled(&gamma_moves));
    }
}
