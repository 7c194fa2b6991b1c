//! Force signal processing for training data: windowed-sinc FIR design equal to scipy's
//! `firwin` ([`fir`]), forward–backward zero-phase filtering equal to scipy's `filtfilt`
//! ([`fir::filtfilt`]), bias estimation from no-contact periods with drift ([`bias`]), and
//! resampling onto frame timestamps ([`align`]); [`clean`] puts them together for a force
//! record.
//!
//! ## Modules and what each owns
//!
//! `fir` (windowed-sinc design equal to scipy `firwin`; `lfilter`, `lfilter_zi`; zero-phase
//! `filtfilt` with odd/even/constant/no padding and scipy or MATLAB pad length; blocked
//! convolution with a runtime AVX copy), `bias` (no-contact windows detected or given, drifting
//! bias interpolated between them), `align` (linear resampling onto frame times with a latency
//! offset, no bridging of gaps), `clean` (a force record on a uniform grid, low-passed and
//! debiased: `CleanConfig`, `BiasRemoval`; option parsers `Padding::from_name`,
//! `PadLen::parse`, `BiasRemoval::parse`)

pub mod align;
pub mod bias;
pub mod clean;
pub mod fir;

/// Any error of this crate: each module's error converts into it, for callers that handle them alike (`?` into one type).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// [`align::AlignError`].
    #[error(transparent)]
    Align(#[from] align::AlignError),
    /// [`bias::BiasError`].
    #[error(transparent)]
    Bias(#[from] bias::BiasError),
    /// [`clean::CleanError`].
    #[error(transparent)]
    Clean(#[from] clean::CleanError),
    /// [`fir::FilterError`].
    #[error(transparent)]
    Filter(#[from] fir::FilterError),
}
