//! Rendered marker frames with exact ground truth.
//!
//! [`render`] rasterises ellipses and annuli anti-aliased (coverage by 16 × 16 supersampling of
//! edge pixels), so a shape's area, centre and eccentricity are known in closed form.
//! [`pattern`] lays markers out as a sensor would show them: a grid of dots displaced by a
//! press (with optional sideways drag), or concentric annuli, with camera noise and 8-bit
//! quantisation. Everything is deterministic given a seed.
//!
//! This is the test-pattern generator the vision pipeline is checked against; the sensor
//! physics of the two seed sensors builds on it.

/// Settings a simulated sensor cannot be drawn with, or a touch it cannot take; the message
/// says which and why.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct SimError(pub String);

pub mod camera;
pub mod cone;
pub mod iats;
pub mod jr3;
pub mod pattern;
pub mod protocol;
pub mod render;
pub mod rig;
pub mod zoo;
