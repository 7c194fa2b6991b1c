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
//! and the residual from it — what the slip detector reads), `imprint` (the object's imprint
//! sliding against the markers, from the image: a slip signal on GelSight-type sensors),
//! `options` (`DetectorOptions`: a preset, or `auto`
//! told from the first frame, with settings changed over it — what the CLI's detection options
//! and Python's keyword arguments build; `sized` fits the opening and smallest blob to the
//! markers), `sizing` (`MarkerSize`: the markers' size and spacing measured in a frame, and the
//! opening and area rules they call for)

/// Settings that do not fit together or do not parse: which, and why.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ConfigError {
    /// A setting outside its range (`range` in words, with its unit).
    #[error("{name} must be {range}, got {value}")]
    OutOfRange {
        /// The setting, as options and files name it.
        name: &'static str,
        /// What was given.
        value: f64,
        /// What it must be.
        range: String,
    },
    /// A name that is none of the choices.
    #[error("{what} {given:?}: expected {expected}")]
    Unknown {
        /// What was named (a feature, a layout, a threshold, a tracker setting).
        what: &'static str,
        /// The name given.
        given: String,
        /// The choices, in words.
        expected: String,
    },
    /// A `name=value` setting whose value is not a number.
    #[error("{name}: {value:?} is not a number")]
    NotANumber {
        /// The setting.
        name: String,
        /// Its text.
        value: String,
    },
    /// The smallest marker area above the largest.
    #[error("smallest marker area {min_px} px exceeds the largest, {max_px} px")]
    AreaRange {
        /// The smallest area, pixels.
        min_px: u32,
        /// The largest, pixels.
        max_px: u32,
    },
    /// A region of interest without a pixel.
    #[error("region of interest of {width} × {height} px holds no pixel")]
    EmptyRegion {
        /// Its width, pixels.
        width: usize,
        /// Its height, pixels.
        height: usize,
    },
    /// A circular mask with no finite centre or no positive radius.
    #[error("circular mask needs a finite centre and a positive radius")]
    BadCircle,
    /// A window or offset given with a threshold other than the adaptive one.
    #[error("the window and offset apply to the adaptive threshold only")]
    NotAdaptive,
    /// No feature chosen.
    #[error("the feature set is empty")]
    NoFeatures,
}

impl ConfigError {
    /// `name` = `value` is not `range`.
    pub fn out_of_range(name: &'static str, value: f64, range: impl Into<String>) -> Self {
        Self::OutOfRange {
            name,
            value,
            range: range.into(),
        }
    }

    /// `given` is no `what` of `expected`.
    pub fn unknown(what: &'static str, given: &str, expected: impl Into<String>) -> Self {
        Self::Unknown {
            what,
            given: given.to_string(),
            expected: expected.into(),
        }
    }
}

pub mod assign;
pub mod blobs;
pub mod calibration;
pub mod detect;
pub mod features;
pub mod field;
pub mod imprint;
pub mod kernels;
pub mod layout;
pub mod options;
pub mod preprocess;
pub mod separate;
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
