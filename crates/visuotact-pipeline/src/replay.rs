//! Replaying a trained model over recorded frames as the live loop would (the inflatable cone
//! paper's Neural Network Testing Model), and the frame pass every table of frames shares.
//!
//! [`replay`] reads a session folder (its saved frames in `frames.csv` order) or any videos,
//! images and folders, estimates every frame with the [`LiveEstimator`] that `run` uses, and
//! writes one row per frame: the estimate, or NaN with the reason in the flags (no estimate
//! rather than a wrong one). The estimator's [`crate::LiveConfig`] says which frames get an
//! estimate: [`crate::LiveConfig::OFFLINE`] estimates every one against the sensor's reference;
//! [`crate::LiveConfig::LIVE`] gives what `run` would have sent (only frames in contact, from a
//! baseline that follows the skin's drift). Inputs of the model besides the marker features
//! (a pressure gauge's reading) come from a readings table keyed by frame. The feature, blob
//! and prediction tables of frames are in [`crate::extract`].
//!
//! Every pass over frames tells a [`FrameSink`] of each frame skipped and of how far it has
//! come; the sink may stop it, and a stopped pass writes nothing (its table never takes its
//! name, [`TableWriter::finish`]).

use std::path::{Path, PathBuf};

use visuotact_image::Frame;
use visuotact_io::table::{KeyedTable, TableError, TableFormat, TableWriter};

use crate::live::{LiveEstimator, LiveFrame};
use crate::sink::FrameSink;
use crate::source::{FrameSource, Next, SourceError};
use crate::PipelineError;
use visuotact_vision::field::FieldDynamics;

/// What to replay.
#[derive(Clone, Debug)]
pub struct ReplayConfig {
    /// A session folder, or videos / images / folders.
    pub inputs: Vec<PathBuf>,
    /// The estimates table to write.
    pub output: PathBuf,
    /// Frame rate of image sequences, frames per second.
    pub fps: f64,
    /// The readings table (default: a session's `labels.csv` when the model needs readings).
    pub readings: Option<PathBuf>,
    /// A slip detector: the table then ends with `slip_score` and `slip_state` (0 stick,
    /// 1 incipient, 2 slip) and the displacement field's signals it read
    /// ([`FieldDynamics::NAMES`]), the whole replay followed as one sequence.
    pub slip: Option<crate::slip::SlipDetector>,
}

/// Why a replay or an extraction could not run.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// The model needs readings and none were found.
    #[error("the model needs {0} besides the marker features: give a readings table keyed by frame (--readings)")]
    NoReadings(String),
    /// The readings table lacks an input of the model.
    #[error("{}: no column `{column}`, an input of the model", path.display())]
    MissingReading {
        /// The table.
        path: PathBuf,
        /// The input it lacks.
        column: String,
    },
    /// A session folder with no saved frames.
    #[error("{}: no saved frames (record with --save-frames to replay a session)", .0.display())]
    NoFrames(PathBuf),
    /// A table does not read.
    #[error(transparent)]
    Table(#[from] TableError),
    /// The estimator refused a setting.
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
    /// The frames do not open.
    #[error(transparent)]
    Frames(#[from] SourceError),
    /// The observer stopped the pass.
    #[error("stopped after {frames} frames: nothing written")]
    Stopped {
        /// Frames through when it stopped.
        frames: usize,
    },
    /// No row got an estimate: the output is not written.
    #[error("{}: not written, no frame got an estimate (the first of {frames}: {why})", path.display())]
    NoEstimate {
        /// The output.
        path: PathBuf,
        /// Frames tried.
        frames: usize,
        /// The first frame's reason.
        why: String,
    },
    /// No frame could be processed: the feature table is not written.
    #[error("{}: not written, no frame could be processed (the first of {frames}: {why})", path.display())]
    NothingExtracted {
        /// The output.
        path: PathBuf,
        /// Frames tried.
        frames: usize,
        /// The first frame's reason.
        why: String,
    },
    /// Writing the output failed.
    #[error("{}: {source}", path.display())]
    Write {
        /// The output.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

/// The frames of a pass: before each frame, and once more when they run out (Ctrl-C also ends
/// a video's decoder), the observer hears how far the pass is and may stop it.
pub(crate) struct Pass {
    source: FrameSource,
    total: Option<usize>,
    done: usize,
    /// Frames that did not read (skipped, each told to the observer).
    pub(crate) unreadable: usize,
}

impl Pass {
    /// `paths` as one frame stream, with how many frames it holds when known.
    pub(crate) fn open(paths: &[PathBuf], fps: f64) -> Result<Self, ReplayError> {
        let source = FrameSource::files(paths, fps)?;
        let total = source.expected_frames();
        Ok(Self {
            source,
            total,
            done: 0,
            unreadable: 0,
        })
    }

    /// The next frame that reads, after telling `obs` how far the pass is;
    /// [`ReplayError::Stopped`] when it stops the pass. A frame that does not read is told to
    /// `obs`, counted in [`Pass::unreadable`] and passed over.
    pub(crate) fn next(&mut self, obs: &mut dyn FrameSink) -> Result<Option<Frame>, ReplayError> {
        loop {
            if obs.progress(self.done, self.total).is_break() {
                return Err(ReplayError::Stopped { frames: self.done });
            }
            match self.source.next_frame()? {
                Next::End => return Ok(None),
                Next::Frame(f) => {
                    self.done += 1;
                    return Ok(Some(f.frame));
                }
                Next::Unreadable(why) => {
                    self.done += 1;
                    self.unreadable += 1;
                    obs.warn(&format!("{why}; skipped"));
                }
                // Files are never paced, so never dropped.
                Next::Dropped => {}
            }
        }
    }
}

/// What a replay did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Replayed {
    /// Frames estimated (or tried).
    pub frames: usize,
    /// Of them, frames without an estimate.
    pub missing: usize,
    /// Time taken, decoding included, s.
    pub seconds: f64,
    /// The session folder replayed, if the input was one.
    pub session: Option<PathBuf>,
}

/// The extra inputs of each frame, from a table keyed by `frame`.
struct Readings {
    table: KeyedTable,
    columns: Vec<usize>,
}

impl Readings {
    /// Finds `names` in the table at `path`; an unfinished last line left out is said in
    /// `notes`.
    fn open(path: &Path, names: &[String], notes: &mut Vec<String>) -> Result<Self, ReplayError> {
        let table = KeyedTable::read_noting(path, &[], notes)?;
        let columns = names
            .iter()
            .map(|c| {
                table.column(c).ok_or_else(|| ReplayError::MissingReading {
                    path: path.to_path_buf(),
                    column: c.clone(),
                })
            })
            .collect::<Result<_, _>>()?;
        Ok(Self { table, columns })
    }
}

/// A session's saved frames in recorded order; `warn` hears how many listed are missing.
fn session_frames(s: &Path, warn: &mut dyn FnMut(&str)) -> Result<Vec<PathBuf>, ReplayError> {
    let mut notes = Vec::new();
    let index = visuotact_io::session::frame_index(s, &mut notes)?;
    notes.iter().for_each(|n| warn(n));
    let listed = index.iter().filter(|f| !f.reference).count();
    let frames: Vec<PathBuf> = index
        .iter()
        .filter(|f| !f.reference)
        .map(|f| s.join("frames").join(&f.name))
        .filter(|p| p.is_file())
        .collect();
    if frames.is_empty() {
        return Err(ReplayError::NoFrames(s.to_path_buf()));
    }
    if frames.len() < listed {
        warn(&format!(
            "{}: {} of the {listed} frames listed in frames.csv are not in frames/: replaying the {} there",
            s.display(),
            listed - frames.len(),
            frames.len()
        ));
    }
    Ok(frames)
}

/// Replays `live` over `cfg.inputs` (see the module's documentation); `obs` hears of frames
/// that cannot be read and of the progress.
pub fn replay(
    live: &mut LiveEstimator,
    cfg: &ReplayConfig,
    obs: &mut dyn FrameSink,
) -> Result<Replayed, ReplayError> {
    let session = (cfg.inputs.len() == 1 && cfg.inputs[0].join("frames.csv").is_file())
        .then(|| cfg.inputs[0].clone());
    let extra = live.estimator().extra_inputs().to_vec();
    let readings = if extra.is_empty() {
        None
    } else {
        let path = cfg
            .readings
            .clone()
            .or_else(|| session.as_ref().map(|s| s.join("labels.csv")))
            .filter(|p| p.is_file())
            .ok_or_else(|| ReplayError::NoReadings(extra.join(", ")))?;
        let mut notes = Vec::new();
        let r = Readings::open(&path, &extra, &mut notes)?;
        notes.iter().for_each(|n| obs.warn(n));
        Some(r)
    };
    let by_key = readings.as_ref().map(|r| r.table.rows_by_key());
    let paths = match &session {
        Some(s) => session_frames(s, &mut |w: &str| obs.warn(w))?,
        None => cfg.inputs.clone(),
    };
    let write_err = |source| ReplayError::Write {
        path: cfg.output.clone(),
        source,
    };
    let mut columns = live.estimate_columns();
    let width = columns.len();
    if let Some(d) = cfg.slip.clone() {
        columns.extend(["slip_score".to_string(), "slip_state".to_string()]);
        columns.extend(FieldDynamics::NAMES.iter().map(|n| n.to_string()));
        live.set_slip(d)?;
    }
    let mut out = TableWriter::create(&cfg.output, TableFormat::Csv, columns).map_err(write_err)?;
    let mut row = Vec::new();
    let mut done = Replayed::default();
    let mut extra_values = Vec::with_capacity(extra.len());
    let t0 = std::time::Instant::now();
    let mut pass = Pass::open(&paths, cfg.fps)?;
    while let Some(frame) = pass.next(obs)? {
        extra_values.clear();
        if let (Some(r), Some(by_key)) = (&readings, &by_key) {
            let row = by_key.get(frame.id.as_str()).map(|&i| &r.table.rows[i]);
            extra_values.extend(
                r.columns
                    .iter()
                    .map(|&c| row.map_or(f64::NAN, |row| row[c])),
            );
        }
        let result = live.process_with(&frame.image, &extra_values, None);
        let flag = frame_row(live, &result, (width, cfg.slip.is_some()), &mut row);
        done.missing += usize::from(!flag.is_empty());
        let written = out.write_row(&frame.id, &row, &flag);
        written.map_err(write_err)?;
        done.frames += 1;
    }
    out.finish().map_err(write_err)?;
    done.seconds = t0.elapsed().as_secs_f64();
    done.session = session;
    Ok(done)
}

/// A replayed frame's row into `row`: the estimate (`width` cells: the targets, then their
/// spreads; NaN without one) and, with a slip detector, the score, the state (0 stick,
/// 1 incipient, 2 slip) and the field's signals it read (NaN for a frame not estimated).
/// Returns the flag: empty, or why the frame has no estimate.
fn frame_row(
    live: &LiveEstimator,
    result: &Result<LiveFrame, PipelineError>,
    (width, slip): (usize, bool),
    row: &mut Vec<f64>,
) -> String {
    row.clear();
    let estimated = |r: &LiveFrame| r.contact || live.config().estimate_without_contact;
    let flag = match result {
        Ok(r) if !r.targets.is_empty() => {
            row.extend(r.targets.iter().map(|t| t.value));
            row.extend(r.targets.iter().filter_map(|t| t.std));
            String::new()
        }
        Ok(r) if !estimated(r) => "no contact".to_string(),
        Ok(_) => "missing features".to_string(),
        Err(e) => format!("error: {e}"),
    };
    row.resize(width, f64::NAN);
    if slip {
        let mut cells = [f64::NAN; SLIP_CELLS];
        if let Ok(r) = result {
            if let Some(s) = &r.slip {
                cells[0] = s.score;
                cells[1] = f64::from(s.state as u8);
            }
            if let (true, Some(signals)) = (estimated(r), live.slip_signals()) {
                cells[2..].copy_from_slice(&signals);
            }
        }
        row.extend_from_slice(&cells);
    }
    flag
}

/// Cells a slip detector adds to a replayed frame's row.
const SLIP_CELLS: usize = 2 + FieldDynamics::NAMES.len();

#[cfg(test)]
mod tests {
    use super::session_frames;

    /// Frames listed in `frames.csv` but gone from `frames/` are counted in a warning; a
    /// session with none left is an error naming it.
    #[test]
    fn frames_listed_but_missing_are_counted() {
        let d = std::env::temp_dir().join(format!("visuotact-listed-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(d.join("frames")).unwrap();
        std::fs::write(
            d.join("frames.csv"),
            "frame,index,timestamp_s,kind\na.png,0,0,touch\nb.png,1,0.04,touch\nc.png,2,0.08,touch\n",
        )
        .unwrap();
        for name in ["a.png", "c.png"] {
            std::fs::write(d.join("frames").join(name), b"").unwrap();
        }
        let mut warnings = Vec::new();
        let frames = session_frames(&d, &mut |w| warnings.push(w.to_string())).unwrap();
        assert_eq!(frames.len(), 2);
        assert_eq!(warnings.len(), 1);
        assert!(
            warnings[0].contains("1 of the 3 frames listed in frames.csv are not in frames/"),
            "{}",
            warnings[0]
        );
        for name in ["a.png", "c.png"] {
            std::fs::remove_file(d.join("frames").join(name)).unwrap();
        }
        let err = session_frames(&d, &mut |_| {}).unwrap_err();
        assert!(err.to_string().contains(&d.display().to_string()), "{err}");
        std::fs::remove_dir_all(&d).unwrap();
    }
}
