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
//!
//! ## Modules and what each owns
//!
//! `camera` (pinhole + radial distortion), `render` (anti-aliased ellipses and convex polygons
//! with exact area/centroid, blur), `iats` (seed 000's clamped membrane under a spherical tip,
//! with drag), `cone` (seed 001's inflated cone bent and shortened by a force, pressure drift),
//! `jr3` (6-axis force/torque stream with noise and drifting bias), `protocol` (grid, random,
//! shear, line, press, press-rotate; zoo grid, random, shear, drag; `zoo_slip`: grasps that
//! press, drag under the friction limit, twist or slip past it — Cattaneo–Mindlin partial slip
//! with the slip frame in the truth), `pattern` (simple marker
//! grids for vision tests), `zoo` (sensors the pipeline was not written for: a TacTip-like dome
//! with a hexagonal pin array (also `tactip-small`, as published data sets store it: 128 × 128
//! binarised), a GelSight-like dark-dot grid on a shaded gel, random dots; every parameter
//! drawn from documented ranges per variant; truth with visibility), `rig` (one seed mixer
//! `frame_seed` for every simulated frame, the cone's label row with its pressure gauge, the
//! looping simulated camera of a live run, `SimRig`: the recorder's simulated cone and membrane
//! with their labels)

/// Settings a simulated sensor cannot be drawn with, or a touch it cannot take: which, and why.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SimError {
    /// A setting or a touch's value outside its range (`range` in words, with its unit).
    #[error("{name} must be {range}, got {value}")]
    OutOfRange {
        /// The setting or value, as files and options name it.
        name: &'static str,
        /// What was given.
        value: f64,
        /// What it must be.
        range: String,
    },
    /// A value that must be finite is not.
    #[error("{0} must be finite")]
    NotFinite(&'static str),
    /// Two settings that cannot hold together.
    #[error("{a} and {b} do not fit together: {why}")]
    Mismatch {
        /// The first setting.
        a: &'static str,
        /// The second.
        b: &'static str,
        /// Why, with their values.
        why: String,
    },
    /// A camera or marker grid size outside the simulator's limits.
    #[error("{what} {width}×{height}: {limit}")]
    Size {
        /// The camera or the marker grid.
        what: &'static str,
        /// Columns or pixels across.
        width: usize,
        /// Rows or pixels down.
        height: usize,
        /// The limit it breaks.
        limit: String,
    },
    /// A touch off the marker field.
    #[error("touch at ({x_mm}, {y_mm}) mm is off the marker field")]
    OffField {
        /// Where, mm.
        x_mm: f64,
        /// Where, mm.
        y_mm: f64,
    },
    /// A drag or twist at zero depth.
    #[error("a drag or twist needs contact (depth > 0)")]
    DragWithoutContact,
    /// A simulated source other than `sim:iats` or `sim:cone`.
    #[error("sim:{0}: expected sim:iats or sim:cone")]
    UnknownRig(String),
    /// A touch or reference the sensor at hand cannot take (a touch of another family).
    #[error("{0}")]
    WrongSensor(&'static str),
}

impl SimError {
    /// `name` = `value` is not `range`.
    pub fn out_of_range(name: &'static str, value: f64, range: impl Into<String>) -> Self {
        Self::OutOfRange {
            name,
            value,
            range: range.into(),
        }
    }
}

/// Largest image side the simulator draws, pixels: a 4K camera. Beyond it one frame's
/// canvases alone need gigabytes.
pub const MAX_CAMERA_SIDE_PX: usize = 4096;

/// Largest optical blur, pixels (Gaussian σ). A blur this wide already smears a marker over
/// its neighbours; wider ones only cost time (the taps grow with σ).
pub const MAX_BLUR_PX: f64 = 25.0;

/// Most frames one simulated session holds (touches, or the cone's press frames): 11 hours at
/// 25 fps, and about as many files as one folder should hold.
pub const MAX_FRAMES: usize = 1_000_000;

/// Most no-contact reference frames one simulated session holds.
pub const MAX_REFERENCES: usize = 10_000;

/// Checks an optical blur σ: finite, ≥ 0 and at most [`MAX_BLUR_PX`].
pub fn check_blur_px(blur_px: f64) -> Result<(), SimError> {
    if blur_px.is_finite() && (0.0..=MAX_BLUR_PX).contains(&blur_px) {
        Ok(())
    } else {
        Err(SimError::out_of_range(
            "blur_px",
            blur_px,
            format!("in 0..{MAX_BLUR_PX} px (Gaussian σ)"),
        ))
    }
}

pub mod camera;
pub mod cone;
pub mod iats;
pub mod jr3;
pub mod pattern;
pub mod protocol;
pub mod render;
pub mod rig;
pub mod zoo;
