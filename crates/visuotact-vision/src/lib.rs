//! Frames → markers → features.
//!
//! The path every visuotact frame takes: [`preprocess`] (channel, inversion, morphology,
//! threshold level), [`blobs`] (one fused threshold + labelling + moments pass, with a plain
//! reference implementation beside it), [`detect`] (the two with reusable buffers and a blob
//! filter), [`layout`] (marker layouts recognised and numbered), [`track`] (reference markers matched to
//! the blobs of any frame), [`calibration`] (the sensor file) and [`features`] (feature vectors
//! in named units).
//!
//! ## Modules and what each owns
//!
//! `preprocess` (channel, inversion, morphology, Otsu (every pixel or an eighth of them) /
//! fixed / adaptive levels), `blobs` (fused threshold + labelling + moments pass, and the
//! flood-fill reference it is tested against), `kernels` (pixel loops with runtime CPU
//! dispatch), `detect` (the per-frame detector with reusable buffers; binary, grey-weighted and
//! grey-level centroids), `layout` (marker layouts recognised and numbered: lattice walks with
//! local bases for grids and hexagonal arrays, dot rings, irregular patterns, annuli), `assign`
//! (sparse minimum-cost assignment, tested against brute force), `track` (registration, seeds,
//! growth from a local affine motion model, verification, all-at-once quadratic reassignment
//! and chain slides when a marker or blob is left over; temporal prior; markers cut by the
//! border or a circular view), `calibration` (sensor file; references from still or the
//! lightest frames), `features` (feature vectors, and the field summary every row ends with:
//! how much the markers moved and where), `field` (the displacement field's dynamics frame to
//! frame: shift, spread, curl, divergence, affine residual, entropy, the increments' rigid motion
//! and the residual from it — what the slip detector reads), `options` (`DetectorOptions`: a preset, or `auto`
//! told from the first frame, with settings changed over it — what the CLI's detection options
//! and Python's keyword arguments build; `sized` fits the opening and smallest blob to the
//! markers), `sizing` (`MarkerSize`: the markers' size and spacing measured in a frame, and the
//! opening and area rules they call for)

/// Settings that do not fit together or do not parse; the message says which and why.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct ConfigError(pub String);

pub mod assign;
pub mod blobs;
pub mod calibration;
pub mod detect;
pub mod features;
pub mod field;
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
