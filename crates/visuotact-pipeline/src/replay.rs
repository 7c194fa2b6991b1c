//! Replaying a trained model over recorded frames as the live loop would — seed 001's Neural
//! Network Testing Model — and extracting feature tables from frames.
//!
//! [`replay`] reads a session folder (its saved frames in `frames.csv` order) or any videos,
//! images and folders, estimates every frame with the [`Estimator`], and writes one row per
//! frame: the estimate, or NaN with the reason in the flags (no estimate rather than a wrong
//! one). Inputs of the model besides the marker features (a pressure gauge's reading) come
//! from a readings table keyed by frame. [`extract`] writes the feature table of frames,
//! [`features_table`] keeps it in memory, and [`predict_table`] runs a model over a table.
//!
//! Every pass over frames tells a [`PassObserver`] of each frame skipped and of how far it has
//! come; the observer may stop it, and a stopped pass writes nothing (its table never takes its
//! name, [`TableWriter::finish`]).

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use visuotact_image::Frame;
use visuotact_io::frames::{FrameError, FrameStream};
use visuotact_io::table::{KeyedTable, TableError, TableFormat, TableWriter};
use visuotact_vision::features::{FeatureExtractor, FrameFeatures};

use visuotact_nn::model::Model;

use visuotact_vision::blobs::MomentConvention;
use visuotact_vision::detect::Detector;

use crate::schema::{
    blob_row, feature_columns, feature_row_into, flags_of, missing_summary, BLOB_COLUMNS,
};
use crate::table::InputSources;
use crate::Estimator;

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
    /// The frames do not open.
    #[error(transparent)]
    Frames(#[from] FrameError),
    /// The observer stopped the pass.
    #[error("stopped after {frames} frames: nothing written")]
    Stopped {
        /// Frames through when it stopped.
        frames: usize,
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

/// What a pass over frames tells its caller: each frame skipped or incomplete, and after every
/// frame how far it has come (the caller may stop it there). A closure `FnMut(&str)` is an
/// observer that hears the warnings and never stops.
pub trait PassObserver {
    /// A frame skipped or incomplete, in words.
    fn warn(&mut self, message: &str);

    /// `done` frames of `total` (when known) are through; [`ControlFlow::Break`] stops the pass,
    /// which then writes nothing and returns [`ReplayError::Stopped`].
    fn frames_done(&mut self, done: usize, total: Option<usize>) -> ControlFlow<()> {
        let _ = (done, total);
        ControlFlow::Continue(())
    }
}

impl<F: FnMut(&str)> PassObserver for F {
    fn warn(&mut self, message: &str) {
        self(message);
    }
}

/// The frames of a pass: before each frame, and once more when they run out (Ctrl-C also ends
/// a video's decoder), the observer hears how far the pass is and may stop it.
struct Pass {
    stream: FrameStream,
    total: Option<usize>,
    done: usize,
}

impl Pass {
    /// `paths` as one frame stream, with how many frames it holds when known.
    fn open(paths: &[PathBuf], fps: f64) -> Result<Self, ReplayError> {
        let stream = FrameStream::open(paths, fps)?;
        let total = stream.expected_frames();
        Ok(Self {
            stream,
            total,
            done: 0,
        })
    }

    /// The next frame, after telling `obs`; [`ReplayError::Stopped`] when it stops the pass.
    fn next(
        &mut self,
        obs: &mut dyn PassObserver,
    ) -> Result<Option<Result<Frame, FrameError>>, ReplayError> {
        if obs.frames_done(self.done, self.total).is_break() {
            return Err(ReplayError::Stopped { frames: self.done });
        }
        let item = self.stream.next();
        self.done += usize::from(item.is_some());
        Ok(item)
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
    /// Finds `names` in the table at `path`.
    fn open(path: &Path, names: &[String]) -> Result<Self, ReplayError> {
        let table = KeyedTable::read(path, &[])?;
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
    let t = KeyedTable::read(&s.join("frames.csv"), &["kind"])?;
    let listed = t.keys.len();
    let frames: Vec<PathBuf> = t
        .keys
        .iter()
        .map(|k| s.join("frames").join(k))
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

/// Replays `est` over `cfg.inputs` (see the module's documentation); `obs` hears of frames
/// that cannot be read and of the progress.
pub fn replay(
    est: &mut Estimator,
    cfg: &ReplayConfig,
    obs: &mut dyn PassObserver,
) -> Result<Replayed, ReplayError> {
    let session = (cfg.inputs.len() == 1 && cfg.inputs[0].join("frames.csv").is_file())
        .then(|| cfg.inputs[0].clone());
    let extra = est.extra_inputs().to_vec();
    let readings = if extra.is_empty() {
        None
    } else {
        let path = cfg
            .readings
            .clone()
            .or_else(|| session.as_ref().map(|s| s.join("labels.csv")))
            .filter(|p| p.is_file())
            .ok_or_else(|| ReplayError::NoReadings(extra.join(", ")))?;
        Some(Readings::open(&path, &extra)?)
    };
    let by_key = readings.as_ref().map(|r| r.table.rows_by_key());
    let paths = match &session {
        Some(s) => session_frames(s, &mut |w: &str| obs.warn(w))?,
        None => cfg.inputs.clone(),
    };
    let targets = est.target_columns();
    let write_err = |source| ReplayError::Write {
        path: cfg.output.clone(),
        source,
    };
    let mut out =
        TableWriter::create(&cfg.output, TableFormat::Csv, targets.clone()).map_err(write_err)?;
    let nan = vec![f64::NAN; targets.len()];
    let mut done = Replayed::default();
    let mut extra_values = Vec::with_capacity(extra.len());
    let t0 = std::time::Instant::now();
    let mut pass = Pass::open(&paths, cfg.fps)?;
    while let Some(item) = pass.next(obs)? {
        let frame = match item {
            Ok(f) => f,
            Err(e) => {
                obs.warn(&format!("{e}; skipped"));
                continue;
            }
        };
        extra_values.clear();
        if let (Some(r), Some(by_key)) = (&readings, &by_key) {
            let row = by_key.get(frame.id.as_str()).map(|&i| &r.table.rows[i]);
            extra_values.extend(
                r.columns
                    .iter()
                    .map(|&c| row.map_or(f64::NAN, |row| row[c])),
            );
        }
        let written = match est.process_with(&frame.image, &extra_values) {
            Ok((_, Some(v))) => out.write_row(&frame.id, &v, ""),
            Ok((_, None)) => {
                done.missing += 1;
                out.write_row(&frame.id, &nan, "missing features")
            }
            Err(e) => {
                done.missing += 1;
                out.write_row(&frame.id, &nan, &format!("error: {e}"))
            }
        };
        written.map_err(write_err)?;
        done.frames += 1;
    }
    out.finish().map_err(write_err)?;
    done.seconds = t0.elapsed().as_secs_f64();
    done.session = session;
    Ok(done)
}

/// What an extraction did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Extracted {
    /// Rows written.
    pub written: usize,
    /// Frames skipped (unreadable, or of another size).
    pub skipped: usize,
    /// Frames with markers not found.
    pub incomplete: usize,
    /// Marker-frames not found, in all.
    pub lost: usize,
}

/// Writes the feature table of `frames` (image files, folders, videos at `fps`) to `output`
/// in `format`: one row per frame ([`crate::schema`]). `obs` hears of the progress and of every frame skipped
/// or with markers not found.
pub fn extract(
    ex: &mut FeatureExtractor,
    frames: &[PathBuf],
    fps: f64,
    (output, format): (&Path, TableFormat),
    obs: &mut dyn PassObserver,
) -> Result<Extracted, ReplayError> {
    let n_markers = ex.calibration().markers.len();
    let mut pass = Pass::open(frames, fps)?;
    let write_err = |source| ReplayError::Write {
        path: output.to_path_buf(),
        source,
    };
    let mut out = TableWriter::create(output, format, feature_columns(&ex.column_names()))
        .map_err(write_err)?;
    let mut done = Extracted::default();
    let (mut f, mut row) = (FrameFeatures::default(), Vec::new());
    while let Some(item) = pass.next(obs)? {
        let frame = match item {
            Ok(fr) => fr,
            Err(e) => {
                done.skipped += 1;
                obs.warn(&format!("{e}; skipped"));
                continue;
            }
        };
        if let Err(e) = ex.extract_into(&frame.image, &mut f) {
            done.skipped += 1;
            obs.warn(&format!("frame {}: {e}; skipped", frame.id));
            continue;
        }
        let missing = n_markers - f.found;
        if missing > 0 {
            done.incomplete += 1;
            done.lost += missing;
            let what = if missing * 2 >= n_markers {
                "; half or more: is the skin in view?"
            } else {
                ""
            };
            obs.warn(&format!(
                "frame {}: {missing} of {n_markers} markers not found ({}){what}",
                frame.id,
                missing_summary(&f)
            ));
        }
        feature_row_into(&mut row, frame.timestamp_s, n_markers, &f);
        out.write_row(&frame.id, &row, &flags_of(&f))
            .map_err(write_err)?;
        done.written += 1;
    }
    out.finish().map_err(write_err)?;
    Ok(done)
}

/// The features of `frames` (image files, folders, videos at `fps`) as a keyed table, one row
/// per frame read; `obs` hears of frames skipped and of the progress.
pub fn features_table(
    ex: &mut FeatureExtractor,
    frames: &[PathBuf],
    fps: f64,
    obs: &mut dyn PassObserver,
) -> Result<KeyedTable, ReplayError> {
    let (mut keys, mut rows) = (Vec::new(), Vec::new());
    let mut pass = Pass::open(frames, fps)?;
    while let Some(item) = pass.next(obs)? {
        let frame = match item {
            Ok(f) => f,
            Err(e) => {
                obs.warn(&format!("{e}; skipped"));
                continue;
            }
        };
        match ex.extract(&frame.image) {
            Ok(f) => {
                keys.push(frame.id);
                rows.push(f.values);
            }
            Err(e) => obs.warn(&format!("frame {}: {e}; skipped", frame.id)),
        }
    }
    Ok(KeyedTable {
        columns: ex.column_names(),
        text: vec![Vec::new(); rows.len()],
        keys,
        rows,
        dropped_partial_line: false,
    })
}

/// What [`predict_table`] wrote.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Predicted {
    /// Rows with an estimate.
    pub written: usize,
    /// Rows without (NaN, the reason in the flags).
    pub missing: usize,
    /// Of the estimates, rows with lost markers filled.
    pub filled: usize,
}

/// Estimates every row of `keys` with `model` from `sources` into the CSV at `output` (the
/// model's estimate columns; an ensemble's spreads too). Lost markers are filled by a model on
/// principal components; a missing reading, too many lost markers or a model without
/// components gives no estimate rather than a wrong one, with the reason in the flags.
pub fn predict_table(
    model: &Model,
    sources: &InputSources<'_>,
    keys: &[String],
    output: &Path,
) -> Result<Predicted, ReplayError> {
    let write_err = |source| ReplayError::Write {
        path: output.to_path_buf(),
        source,
    };
    let columns = model.estimate_columns();
    let nan = vec![f64::NAN; columns.len()];
    let mut out = TableWriter::create(output, TableFormat::Csv, columns).map_err(write_err)?;
    let mut done = Predicted::default();
    let mut x = Vec::with_capacity(model.feature_columns.len());
    for (r, key) in keys.iter().enumerate() {
        sources.row_into(r, &mut x);
        let written = match model.estimate(&x) {
            Ok(e) => {
                done.written += 1;
                let note = if e.filled > 0 {
                    done.filled += 1;
                    format!("filled {} inputs", e.filled)
                } else {
                    String::new()
                };
                out.write_row(key, &e.into_row(), &note)
            }
            Err(why) => {
                done.missing += 1;
                out.write_row(key, &nan, &why.to_string())
            }
        };
        written.map_err(write_err)?;
    }
    out.finish().map_err(write_err)?;
    Ok(done)
}

/// What [`blobs_table`] wrote.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BlobsWritten {
    /// Frames detected.
    pub frames: usize,
    /// Blobs written.
    pub blobs: usize,
    /// Frames that could not be read.
    pub skipped: usize,
}

/// Writes every blob `det` finds in `frames` to `output` in `format` (one row per blob,
/// [`crate::schema::BLOB_COLUMNS`]); `obs` hears of frames skipped and of the progress.
pub fn blobs_table(
    det: &mut Detector,
    conv: MomentConvention,
    frames: &[PathBuf],
    (output, format): (&Path, TableFormat),
    obs: &mut dyn PassObserver,
) -> Result<BlobsWritten, ReplayError> {
    let write_err = |source| ReplayError::Write {
        path: output.to_path_buf(),
        source,
    };
    let columns = BLOB_COLUMNS.iter().map(|s| s.to_string()).collect();
    let mut out = TableWriter::create(output, format, columns).map_err(write_err)?;
    let mut done = BlobsWritten::default();
    let mut blobs = Vec::new();
    let mut pass = Pass::open(frames, 25.0)?;
    while let Some(item) = pass.next(obs)? {
        let f = match item {
            Ok(f) => f,
            Err(e) => {
                obs.warn(&format!("{e}; skipped"));
                done.skipped += 1;
                continue;
            }
        };
        let d = det.detect_into(&f.image, &mut blobs);
        let level = d.level.map_or(f64::NAN, f64::from);
        for (k, b) in blobs.iter().enumerate() {
            let row = blob_row(k, b, conv, level, f.timestamp_s);
            out.write_row(&f.id, &row, "").map_err(write_err)?;
        }
        done.frames += 1;
        done.blobs += blobs.len();
    }
    out.finish().map_err(write_err)?;
    Ok(done)
}

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
