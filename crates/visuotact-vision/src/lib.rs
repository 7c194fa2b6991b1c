//! Frames → markers → features.
//!
//! The path every visuotact frame takes: [`preprocess`] (channel, inversion, morphology,
//! threshold level), [`blobs`] (one fused threshold + labelling + moments pass, with a plain
//! reference implementation beside it), [`detect`] (the two with reusable buffers and a blob
//! filter), [`layout`] (marker layouts recognised and numbered), [`track`] (reference markers matched to
//! the blobs of any frame), [`calibration`] (the sensor file) and [`features`] (feature vectors
//! in named units).

/// Settings that do not fit together or do not parse; the message says which and why.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct ConfigError(pub String);

pub mod assign;
pub mod blobs;
pub mod calibration;
pub mod detect;
pub mod features;
pub mod kernels;
pub mod layout;
pub mod options;
pub mod preprocess;
pub mod sizing;
pub mod track;

/// Any error of this crate: each module's error converts into it, for callers that handle them alike (`?` into one type).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// [`calibration::CalibrationError`].
    #[error(transparent)]
    Calibration(#[from] calibration::CalibrationError),
    /// [`ConfigError`].
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// [`features::FrameSizeError`].
    #[error(transparent)]
    FrameSize(#[from] features::FrameSizeError),
    /// [`layout::LayoutError`].
    #[error(transparent)]
    Layout(#[from] layout::LayoutError),
    /// [`calibration::SensorFileError`].
    #[error(transparent)]
    SensorFile(#[from] calibration::SensorFileError),
}
