//! Calibrating from frame files: the mean of still no-contact frames, or — for data sets with
//! no contact-free frame — the N frames of the whole set with the smallest deformation
//! ([`LightestFinder`], two passes over the frames; the sensor file says so).
//!
//! A calibration built from a partial set would be silently different, so any unreadable
//! frame stops it. The ranking pass tells a progress callback how far it is after every frame;
//! the callback may stop it ([`CalibrateError::Stopped`]).

use std::ops::ControlFlow;

use visuotact_image::Frame;
use visuotact_io::frames::{FrameError, FrameStream};
use visuotact_vision::calibration::{
    calibrate, CalibrationConfig, CalibrationError, CalibrationReport, LightestFinder,
    LightestSelection, SensorCalibration,
};

/// Where the reference comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReferenceSource {
    /// The mean of the frames given, which must be free of contact.
    Still,
    /// The N lightest frames of the set.
    Lightest(usize),
}

visuotact_image::from_str_by_parse!(ReferenceSource, CalibrateError);

impl ReferenceSource {
    /// Parses `still` or `lightest:N` (N ≥ 1).
    pub fn parse(s: &str) -> Result<Self, CalibrateError> {
        if s == "still" {
            return Ok(Self::Still);
        }
        match s.strip_prefix("lightest:").map(str::parse::<usize>) {
            Some(Ok(n)) if n > 0 => Ok(Self::Lightest(n)),
            _ => Err(CalibrateError::Source(s.to_string())),
        }
    }
}

/// Why a calibration from files failed.
#[derive(Debug, thiserror::Error)]
pub enum CalibrateError {
    /// The reference source does not parse.
    #[error("reference {0:?}: expected still or lightest:N with N ≥ 1")]
    Source(String),
    /// A frame could not be read.
    #[error("{why}: {source}")]
    Unreadable {
        /// What needed the frame.
        why: &'static str,
        /// The frame's error.
        source: FrameError,
    },
    /// No frames.
    #[error("no frames could be read")]
    NoFrames,
    /// The progress callback stopped the ranking.
    #[error("stopped after ranking {frames} frames")]
    Stopped {
        /// Frames ranked when it stopped.
        frames: usize,
    },
    /// The frames do not open.
    #[error(transparent)]
    Frames(#[from] FrameError),
    /// Calibration failed.
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
}

/// A calibration and how it was made.
#[derive(Clone, Debug)]
pub struct Calibrated {
    /// The sensor.
    pub calibration: SensorCalibration,
    /// What calibration found.
    pub report: CalibrationReport,
    /// The lightest frames chosen, when the reference came from them.
    pub selection: Option<LightestSelection>,
    /// Frames averaged.
    pub frames: usize,
}

/// Every frame of `stream`, or the first unreadable one's error.
fn read_all(
    stream: FrameStream,
    why: &'static str,
    mut keep: impl FnMut(&Frame) -> bool,
) -> Result<Vec<Frame>, CalibrateError> {
    let mut frames = Vec::new();
    for f in stream {
        let f = f.map_err(|source| CalibrateError::Unreadable { why, source })?;
        if keep(&f) {
            frames.push(f);
        }
    }
    Ok(frames)
}

/// Calibrates on the frames `open` streams (called once, or twice for the lightest frames);
/// `progress` hears how many frames of how many (when known) the lightest frames' ranking has
/// been through, and may stop it.
pub fn calibrate_frames(
    open: impl Fn() -> Result<FrameStream, FrameError>,
    source: ReferenceSource,
    cfg: &CalibrationConfig,
    progress: &mut dyn FnMut(usize, Option<usize>) -> ControlFlow<()>,
) -> Result<Calibrated, CalibrateError> {
    const READABLE: &str = "calibration frames must all be readable";
    let (frames, selection) = match source {
        ReferenceSource::Still => (read_all(open()?, READABLE, |_| true)?, None),
        ReferenceSource::Lightest(n) => {
            // Pass 1 keeps only each frame's blobs; pass 2 reads the chosen frames again.
            let mut finder = LightestFinder::new(cfg)?;
            let stream = open()?;
            let total = stream.expected_frames();
            let mut seen = 0;
            for (n, f) in stream.enumerate() {
                if progress(n, total).is_break() {
                    return Err(CalibrateError::Stopped { frames: n });
                }
                seen = n + 1;
                let f = f.map_err(|source| CalibrateError::Unreadable {
                    why: "every frame must be readable to rank them",
                    source,
                })?;
                finder.add(&f.id, &f.image)?;
            }
            // A stop heard as the frames ran out (Ctrl-C also ends a video's decoder).
            if progress(seen, total).is_break() {
                return Err(CalibrateError::Stopped { frames: seen });
            }
            let sel = finder.choose(n)?;
            let frames = read_all(open()?, READABLE, |f| sel.chosen.contains(&f.id))?;
            (frames, Some(sel))
        }
    };
    if frames.is_empty() {
        return Err(CalibrateError::NoFrames);
    }
    let (mut calibration, report) =
        calibrate(frames.iter().map(|f| (f.id.as_str(), &f.image)), cfg)?;
    if let Some(sel) = &selection {
        calibration.reference = sel.reference_info();
    }
    Ok(Calibrated {
        calibration,
        report,
        selection,
        frames: frames.len(),
    })
}
