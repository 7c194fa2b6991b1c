//! Frame → estimate, the layer every visuotact front end shares: the command line, the Python
//! package and live runners call [`Estimator`] rather than composing the vision and network
//! crates themselves, so the same frame gives the same numbers everywhere. No command-line or
//! server dependencies.
//!
//! ```
//! use visuotact_pipeline::Estimator;
//! use visuotact_sim::iats::{render, IatsConfig, Touch};
//! use visuotact_vision::calibration::{calibrate, Preset};
//!
//! // Calibrate on two simulated contact-free frames of the 117-marker membrane, then read a
//! // press.
//! let cfg = IatsConfig::SEED000;
//! let rest: Vec<_> = (0..2).map(|k| render(&cfg, &Touch::default(), k).unwrap().0).collect();
//! let (sensor, _) =
//!     calibrate([("a", &rest[0]), ("b", &rest[1])], &Preset::Iats.config()).unwrap();
//! let mut est = Estimator::from_sensor(sensor).unwrap();
//! let press = Touch { x_mm: 30.0, y_mm: 22.0, depth_mm: 3.0, ..Touch::default() };
//! let frame = render(&cfg, &press, 7).unwrap().0;
//! let columns = est.feature_columns();
//! let f = est.features(&frame).unwrap();
//! assert_eq!(f.found, 117);
//! // The field summary (the last columns) says the skin moved.
//! let rms = f.values[columns.iter().position(|c| c == "field_rms_px").unwrap()];
//! assert!(rms > 0.5);
//! ```
//!
//! ## Modules and what each owns
//!
//! `estimator` (`Estimator`: frame → features (markers' and the field summary) → the model's
//! estimate, with reusable buffers (`estimate_into`); the model's input columns mapped to the
//! feature vector, extra inputs given per frame, a typed `PipelineError`), `live`
//! (`LiveEstimator`: the no-contact baseline and re-zeroing, the contact rule, marker health
//! and an ensemble over model files, by a `LiveConfig`; `LiveEstimate`, the line every live
//! output sends), `runner` (the live runner: source thread → drop-oldest queue →
//! `LiveEstimator` → `Sink`s (`LineSink`, `UdpSink`; the dashboard is one); `RunConfig`,
//! `RunSummary` with latency percentiles), `several` (several sensors in one run: a runner
//! thread each, every estimate named by its sensor into one set of sinks; `RunFile`, the
//! `run --sensors` TOML's typed form), `record` (the recorder: frames, simulated rigs,
//! camera and UDP/CSV force → a crash-safe, resumable session folder; `RecordConfig`,
//! `RecordSummary`, `RecordError`), `replay` (a model over recorded frames as the live loop
//! would), `extract` (feature, blob and prediction tables of frames), `calibrate` (calibration from frame files:
//! still or the lightest frames), `schema` (the feature and blob tables' columns and rows),
//! `dataset` (recorded sessions → one training table: features joined with cleaned, resampled
//! force labels; `clean_table`; `DatasetConfig`, `DatasetError`), `table` (a feature table
//! joined with labels on `frame`, inputs picked by name from it or a readings table, lost
//! markers kept, left out or refused; `JoinError`), `evaluation` (estimates against labels:
//! figures per target, contact distance D, plot and map points), `slip` (slip over time: the
//! field's signals summed up per sequence, a logistic detector giving each frame `stick`,
//! `incipient` or `slip` and each sequence a verdict and onset; `SlipMonitor` for the live loop,
//! fitting on labelled videos and cross-validation by object beside two baselines), `output`
//! (a frame's parts — targets, contact, force, marker cloud, image, health, slip — and the
//! `FrameTarget` every output writes them to; `LiveSink`, the runner's sink into any target),
//! `session_export` (a recorded session folder as frame parts into any target). No clap,
//! axum or tokio: the CLI, the Python package and live runners call it

pub mod calibrate;
pub mod dataset;
pub mod estimator;
pub mod evaluation;
pub mod extract;
pub mod live;
pub mod output;
pub mod record;
pub mod replay;
mod rig;
pub mod runner;
pub mod schema;
pub mod session_export;
pub mod several;
pub mod sink;
pub mod slip;
pub mod source;
pub mod table;

pub use estimator::{
    feature_set_of, sensor_of_model, Estimate, Estimator, PipelineError, TargetValue,
};
pub use live::{LiveConfig, LiveEstimate, LiveEstimator, LiveFrame};
pub use visuotact_io::queue::{self, Captured, LatestQueue};

/// The longest duration or period a setting may give, s (about 11.6 days).
const LONGEST_S: f64 = 1e6;

/// `v` seconds, named `what` in the error: finite, ≥ 0 and at most [`LONGEST_S`].
pub(crate) fn seconds(what: &str, v: f64) -> Result<std::time::Duration, String> {
    if !(0.0..=LONGEST_S).contains(&v) {
        return Err(format!(
            "{what} must be a number of seconds in 0..{LONGEST_S:e}, got {v}"
        ));
    }
    std::time::Duration::try_from_secs_f64(v).map_err(|e| format!("{what}: {e}"))
}

/// A rate in Hz, named `what`: finite, positive, its period at most [`LONGEST_S`].
pub(crate) fn rate(what: &str, v: f64) -> Result<f64, String> {
    if !(v.is_finite() && v > 0.0 && 1.0 / v <= LONGEST_S && v <= 1e9) {
        return Err(format!("{what} must be a positive rate in Hz, got {v}"));
    }
    Ok(v)
}

/// Any error of this crate: each module's error converts into it, for callers that handle them alike (`?` into one type; the Python package maps them all to one exception).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// [`calibrate::CalibrateError`].
    #[error(transparent)]
    Calibrate(#[from] calibrate::CalibrateError),
    /// [`dataset::DatasetError`].
    #[error(transparent)]
    Dataset(#[from] dataset::DatasetError),
    /// [`evaluation::EvaluationError`].
    #[error(transparent)]
    Evaluation(#[from] evaluation::EvaluationError),
    /// [`table::JoinError`].
    #[error(transparent)]
    Join(#[from] table::JoinError),
    /// [`PipelineError`].
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
    /// [`record::RecordError`].
    #[error(transparent)]
    Record(#[from] record::RecordError),
    /// [`replay::ReplayError`].
    #[error(transparent)]
    Replay(#[from] replay::ReplayError),
    /// [`runner::RunError`].
    #[error(transparent)]
    Run(#[from] runner::RunError),
}

/// What the crate's tests share.
#[cfg(test)]
pub(crate) mod test_support {
    use visuotact_sim::iats::{render, IatsConfig, Touch};
    use visuotact_vision::calibration::{calibrate, Preset, SensorCalibration};

    /// The seed-000 touch sensor calibrated on two rendered rest frames.
    pub(crate) fn iats_sensor() -> SensorCalibration {
        let cfg = IatsConfig::SEED000;
        let rest: Vec<_> = (0..2)
            .map(|k| render(&cfg, &Touch::default(), k).unwrap().0)
            .collect();
        calibrate([("a", &rest[0]), ("b", &rest[1])], &Preset::Iats.config())
            .unwrap()
            .0
    }
}
