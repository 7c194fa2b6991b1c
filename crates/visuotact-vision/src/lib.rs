//! Frames → markers → features.
//!
//! The path every visuotact frame takes: [`preprocess`] (channel, inversion, morphology,
//! threshold level), [`blobs`] (one fused threshold + labelling + moments pass, with a plain
//! reference implementation beside it), [`detect`] (the two with reusable buffers and a blob
//! filter), [`grid`] (markers numbered in grid order), [`track`] (reference markers matched to
//! the blobs of any frame), [`calibration`] (the sensor file) and [`features`] (feature vectors
//! in named units).

pub mod blobs;
pub mod calibration;
pub mod detect;
pub mod features;
pub mod grid;
pub mod kernels;
pub mod preprocess;
pub mod track;
