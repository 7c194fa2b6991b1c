//! Force signal processing for training data: windowed-sinc FIR design equal to scipy's
//! `firwin` ([`fir`]), forward–backward zero-phase filtering equal to scipy's `filtfilt`
//! ([`fir::filtfilt`]), bias estimation from no-contact periods with drift ([`bias`]), and
//! resampling onto frame timestamps ([`align`]); [`clean`] puts them together for a force
//! record.

pub mod align;
pub mod bias;
pub mod clean;
pub mod fir;
