//! One way to hear about frames: a [`FrameSink`] is what every loop over frames tells as it
//! goes — `run` each estimate, `record` each frame it writes and each force sample, `replay`,
//! `extract` and the exports their progress and the frames they skip. Every method has a
//! default that does nothing, so a sink implements only what it wants to hear: standard output
//! and UDP take the JSON line, the dashboard and the ROS 2 and Rerun targets the estimate with
//! its markers and image, a recording's bag the rows, a progress line the counts. A closure
//! `FnMut(&str)` is a sink that hears the warnings.
//!
//! A sink ends the loop cleanly with [`ControlFlow::Break`] (a consumer that went away, a user
//! who pressed stop) or as a failure with a [`SinkError`] (a disk that filled up).
//!
//! ```
//! use std::ops::ControlFlow;
//! use visuotact_pipeline::sink::{FrameSink, SinkError, SinkFrame};
//!
//! /// Counts the frames in contact; stops after ten.
//! #[derive(Default)]
//! struct Touches(usize);
//!
//! impl FrameSink for Touches {
//!     fn frame(&mut self, f: &SinkFrame<'_>) -> Result<ControlFlow<()>, SinkError> {
//!         self.0 += usize::from(f.estimate.is_some_and(|e| e.contact));
//!         Ok(if self.0 < 10 { ControlFlow::Continue(()) } else { ControlFlow::Break(()) })
//!     }
//! }
//! ```

use std::ops::ControlFlow;
use std::sync::{Arc, Mutex};

use visuotact_image::RgbImage;
use visuotact_io::force::ForceSample;

use crate::live::{LiveEstimate, MarkerView};
use crate::output::OutputError;

/// Why a sink failed; the loop ends as a failed write would (what was written stays).
#[derive(Debug, thiserror::Error)]
pub enum SinkError {
    /// A frame's parts could not be written (a bag, DDS, Foxglove, a Rerun recording).
    #[error(transparent)]
    Output(#[from] OutputError),
    /// A file or socket could not be written.
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// A sink of the caller's own failed (its error, kept whole).
    #[error(transparent)]
    Other(Box<dyn std::error::Error + Send + Sync>),
}

impl SinkError {
    /// A caller's own error.
    pub fn other(e: impl std::error::Error + Send + Sync + 'static) -> Self {
        Self::Other(Box::new(e))
    }
}

/// A recording's rows of one frame as the session's tables hold them.
#[derive(Clone, Copy, Debug)]
pub struct RecordedRow<'a> {
    /// `features.csv`'s value columns and this frame's row (without an estimator, or a frame
    /// the extractor refused: `None`).
    pub features: Option<(&'a [String], &'a [f64])>,
    /// `estimates.csv`'s value columns and this frame's row, likewise.
    pub estimates: Option<(&'a [String], &'a [f64])>,
}

/// One frame as a loop tells it.
#[derive(Clone, Copy, Debug)]
pub struct SinkFrame<'a> {
    /// The frame's name (a file name, `iats_0004#12`, a session's `frame_000012.png`).
    pub id: &'a str,
    /// Its place in the source or session.
    pub index: u64,
    /// Its time on the loop's clock (a recording: the session's), seconds.
    pub timestamp_s: f64,
    /// The frame.
    pub image: &'a Arc<RgbImage>,
    /// The live estimate (`run`; `record` with a sensor, every frame estimated); `None`
    /// without an estimator.
    pub estimate: Option<&'a LiveEstimate>,
    /// The estimate as one JSON line, as `run` prints it.
    pub json: Option<&'a str>,
    /// The markers' positions and displacements, when a sink asked for them
    /// ([`FrameSink::wants_markers`]).
    pub markers: Option<&'a [MarkerView]>,
    /// A recording's rows of this frame, as written.
    pub rows: Option<RecordedRow<'a>>,
}

/// Where a loop's frames, samples, warnings and progress go (see the module's documentation).
pub trait FrameSink {
    /// The loop starts; its clock's zero is `started_unix_s` (UNIX time, s).
    fn start(&mut self, started_unix_s: f64) -> Result<(), SinkError> {
        let _ = started_unix_s;
        Ok(())
    }

    /// One frame; [`ControlFlow::Break`] ends the loop cleanly.
    fn frame(&mut self, frame: &SinkFrame<'_>) -> Result<ControlFlow<()>, SinkError> {
        let _ = frame;
        Ok(ControlFlow::Continue(()))
    }

    /// A force sample was written (a recording with a force sensor; its `timestamp_s` on the
    /// session's clock).
    fn force(&mut self, sample: &ForceSample) -> Result<(), SinkError> {
        let _ = sample;
        Ok(())
    }

    /// A frame skipped or incomplete, in words.
    fn warn(&mut self, message: &str) {
        let _ = message;
    }

    /// `done` frames of `total` (when known) are through; [`ControlFlow::Break`] stops the
    /// pass, which then writes nothing.
    fn progress(&mut self, done: usize, total: Option<usize>) -> ControlFlow<()> {
        let _ = (done, total);
        ControlFlow::Continue(())
    }

    /// Whether this sink wants the markers with each frame (drawing them costs).
    fn wants_markers(&self) -> bool {
        false
    }

    /// Whether the user asked to re-zero since the last call (a live run's estimator then
    /// takes the current frame as its baseline).
    fn take_rezero(&mut self) -> bool {
        false
    }

    /// The estimator re-zeroed at the sink's request.
    fn rezero_applied(&mut self) {}
}

/// A closure hears the warnings.
impl<F: FnMut(&str)> FrameSink for F {
    fn warn(&mut self, message: &str) {
        self(message);
    }
}

/// A sink shared by the threads of a recording (frames from the recording thread, force
/// samples from the force receiver's).
pub type SharedSink = Arc<Mutex<dyn FrameSink + Send>>;
