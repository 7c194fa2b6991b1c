//! Recording a session: a frame source plus an optional force source → a session folder,
//! written as it goes.
//!
//! Sources ([`SourceSpec`]): image files, folders or videos; a V4L2 camera; and the simulated
//! rigs `sim:cone` (seed 001's link pressed and released, its JR3 streaming over UDP to the
//! force receiver) and `sim:iats` (random touches), paced in real time. Force
//! ([`ForceSource`]): UDP packets (packed little-endian f64, [`ForceLayout`]) or a CSV table.
//!
//! The contract: every table row is written and flushed as it is produced and the files are
//! `fsync`ed every [`RecordConfig::sync_every_s`], so a crash or SIGKILL leaves every completed
//! row readable; [`RecordConfig::resume`] continues a stopped session (an unfinished last line
//! is cut off first). Setting the `stop` flag ends the recording cleanly. An unwritable folder
//! or a full disk is reported before recording starts. `session.json` says whether the
//! recording completed and what was lost (frames dropped or unreadable, force packets).

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use serde::Serialize;
use visuotact_image::RgbImage;
use visuotact_io::force::{
    to_recorder, ForceLayout, ForceReceiver, ForceSample, ForceTable, ReceiveStats,
};
use visuotact_io::frames::{write_png, FrameError};
use visuotact_io::session::{
    probe_writable, write_atomically, AppendLog, SessionDescription, SESSION_FORMAT,
    SESSION_VERSION,
};
use visuotact_io::source::SourceSpec;
use visuotact_io::table::{format_number, push_csv_row, TableError};

use crate::live::LiveFrame;
use crate::rig::{frame_seed, spawn_jr3, Jr3Stream, Rig};
use crate::schema::{feature_columns, feature_row_into, flags_of};
use crate::sink::{FrameSink, RecordedRow, SharedSink, SinkError, SinkFrame};
use crate::source::{FrameSource, Next, Pacing, SourceConfig, SourceError, SourceFrame};
use crate::{rate, seconds, Estimator, LiveConfig, LiveEstimate, LiveEstimator, PipelineError};
use visuotact_vision::features::MmColumns;

/// Where force samples come from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ForceSource {
    /// Listen for packets on this `HOST:PORT`.
    Udp(String),
    /// A force table already recorded.
    Csv(PathBuf),
}

impl std::fmt::Display for ForceSource {
    /// `udp:HOST:PORT` or `csv:FILE`, as [`ForceSource::parse`] reads it.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Udp(a) => write!(f, "udp:{a}"),
            Self::Csv(p) => write!(f, "csv:{}", p.display()),
        }
    }
}

visuotact_image::from_str_by_parse!(ForceSource, RecordError);

impl ForceSource {
    /// Parses `udp:HOST:PORT` or `csv:FILE`.
    pub fn parse(s: &str) -> Result<Self, RecordError> {
        if let Some(addr) = s.strip_prefix("udp:") {
            Ok(Self::Udp(addr.to_string()))
        } else if let Some(path) = s.strip_prefix("csv:") {
            Ok(Self::Csv(PathBuf::from(path)))
        } else {
            Err(RecordError::Config(format!(
                "force source {s:?}: expected udp:HOST:PORT or csv:FILE"
            )))
        }
    }
}

/// The simulated cone rig's press (`sim:cone`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ConeRigConfig {
    /// Press-and-release time, seconds.
    pub press_s: f64,
    /// No-contact time before and after the press, seconds.
    pub rest_s: f64,
    /// Peak force, N.
    pub max_force_n: f64,
}

impl Default for ConeRigConfig {
    fn default() -> Self {
        Self {
            press_s: 20.0,
            rest_s: 2.0,
            max_force_n: 10.0,
        }
    }
}

/// What to record and how.
#[derive(Clone, Debug)]
pub struct RecordConfig {
    /// Session folder to write.
    pub output: PathBuf,
    /// Frame source (`"sim:cone".into()`, or [`SourceSpec::parse`] of what a user wrote);
    /// `session.json` keeps it as text.
    pub source: SourceSpec,
    /// Frame rate of image folders and of the simulated camera, frames per second.
    pub fps: f64,
    /// Stop after this many seconds.
    pub duration_s: Option<f64>,
    /// Stop after this many frames.
    pub max_frames: Option<usize>,
    /// Force source.
    pub force: Option<ForceSource>,
    /// Fields of a force packet, in order.
    pub force_layout: ForceLayout,
    /// The force sensor's sample rate, Hz (counts lost packets; converts a counter field).
    pub force_rate_hz: f64,
    /// Keep every frame as PNG in `frames/`.
    pub save_frames: bool,
    /// `fsync` the session files this often, seconds.
    pub sync_every_s: f64,
    /// Continue a stopped session in the output folder.
    pub resume: bool,
    /// Simulated sources: random seed.
    pub seed: u64,
    /// `sim:cone`: the press.
    pub cone: ConeRigConfig,
    /// Simulated sources: no-contact reference frames written to `reference/` first.
    pub references: usize,
    /// The sensor file the estimator was built from (written to `session.json`).
    pub sensor_file: Option<PathBuf>,
    /// The model file the estimator was built from (written to `session.json`).
    pub model_file: Option<PathBuf>,
}

impl Default for RecordConfig {
    fn default() -> Self {
        Self {
            output: PathBuf::from("session"),
            source: "sim:iats".into(),
            fps: 25.0,
            duration_s: None,
            max_frames: None,
            force: None,
            force_layout: ForceLayout::default(),
            force_rate_hz: 1000.0,
            save_frames: false,
            sync_every_s: 1.0,
            resume: false,
            seed: 1,
            cone: ConeRigConfig::default(),
            references: 10,
            sensor_file: None,
            model_file: None,
        }
    }
}

/// Why a recording could not start or went wrong (rows already written stay on disk).
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// A setting is out of range or malformed.
    #[error("{0}")]
    Config(String),
    /// The folder holds a session and `resume` was not asked for.
    #[error("{}: already holds a session; resume it (--resume) or choose a new folder", .0.display())]
    Exists(PathBuf),
    /// Another recording is writing into the folder (it holds the session's lock).
    #[error("{}: another recording is writing into this session; wait for it to end or choose a new folder", .0.display())]
    Busy(PathBuf),
    /// `resume` was asked for and the folder holds no session.
    #[error("{}: no session to resume", .0.display())]
    NothingToResume(PathBuf),
    /// Reading or writing a file or socket (the message names it).
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// A frame could not be written.
    #[error(transparent)]
    Frames(#[from] FrameError),
    /// The frame source could not be opened or went wrong.
    #[error(transparent)]
    Source(#[from] SourceError),
    /// The simulated rig refused its settings.
    #[cfg(feature = "sim")]
    #[error(transparent)]
    Sim(#[from] visuotact_sim::SimError),
    /// The force table does not read.
    #[error(transparent)]
    ForceTable(#[from] TableError),
    /// A capture or force thread stopped unexpectedly.
    #[error("the {0} thread stopped unexpectedly")]
    Thread(&'static str),
    /// The estimator could not take the model.
    #[error(transparent)]
    Estimator(#[from] PipelineError),
    /// The [`FrameSink`] failed (its error, as it says it).
    #[error("{0}")]
    Observer(#[source] SinkError),
    /// A thread panicked while it held the [`FrameSink`].
    #[error("a thread panicked while writing")]
    ObserverPanicked,
    /// The recording ended without a frame written (the session says so too).
    #[error("nothing recorded: {0}")]
    NothingRecorded(String),
    /// Frames were recorded but the sensor processed none of them (a sensor of another
    /// camera); the frames stay in the session, which is not marked complete.
    #[error(
        "the sensor processed none of the {0} frames recorded (each is named in a warning); \
         frames.csv keeps them, features.csv has no row"
    )]
    NothingEstimated(usize),
}

/// What a recording did.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RecordSummary {
    /// Frames written by this run.
    pub written: usize,
    /// Frames in the session, earlier runs included.
    pub frames: usize,
    /// Frames lost: the simulated camera could not produce them in time, or the camera's
    /// driver dropped them while the recorder was behind.
    pub dropped: usize,
    /// Frames that could not be read (each reported through the warning callback).
    pub unreadable: usize,
    /// The force receiver's counts.
    pub force_packets: Option<ReceiveStats>,
    /// Force packets the simulated JR3 sent.
    pub force_packets_sent: Option<u64>,
    /// Wall-clock time, seconds.
    pub duration_s: f64,
    /// When the session began (its clock's zero) as UNIX time, s; a resumed session keeps
    /// its first run's.
    pub started_unix_s: f64,
}

/// A frame the recorder writes: from a simulated rig (with its labels), a file or a camera,
/// on the recorder's clock.
struct RecordedFrame {
    id: String,
    timestamp_s: f64,
    image: Arc<RgbImage>,
    labels: Vec<f64>,
}

/// The recording's [`FrameSink`], shared with the force receiver's thread.
pub type SharedObserver = SharedSink;

fn observe<T>(
    observer: Option<&SharedObserver>,
    f: impl FnOnce(&mut dyn FrameSink) -> Result<T, SinkError>,
) -> Result<Option<T>, RecordError> {
    let Some(o) = observer else {
        return Ok(None);
    };
    let mut guard = o.lock().map_err(|_| RecordError::ObserverPanicked)?;
    f(&mut *guard).map(Some).map_err(RecordError::Observer)
}

const FORCE_HEADER: &str = "timestamp_s,fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm,recv_s";

/// Records a session (see the module's documentation) until the source ends, a limit is
/// reached or `stop` is set. `estimator` adds `features.csv` (and `estimates.csv` with a
/// model); `warn` hears of frames skipped.
pub fn record(
    cfg: &RecordConfig,
    estimator: Option<Estimator>,
    stop: &Arc<AtomicBool>,
    warn: &mut dyn FnMut(&str),
) -> Result<RecordSummary, RecordError> {
    record_observed(cfg, estimator, stop, warn, None)
}

/// [`record`], with `observer` hearing of every frame and force sample as it is written.
pub fn record_observed(
    cfg: &RecordConfig,
    estimator: Option<Estimator>,
    stop: &Arc<AtomicBool>,
    warn: &mut dyn FnMut(&str),
    observer: Option<SharedObserver>,
) -> Result<RecordSummary, RecordError> {
    // The live loop's estimator, every frame estimated against the sensor's reference: a
    // session's rows are the frames' own.
    let mut estimator = estimator
        .map(|e| LiveEstimator::from_estimator(e, &LiveConfig::OFFLINE))
        .transpose()?;
    // Everything that can be checked is checked before anything is created: a corrected
    // re-run is never refused for a folder a failed one left behind.
    validate(cfg)?;
    let rig = match &cfg.source {
        SourceSpec::Sim(kind) => Some(rig_of(cfg, kind)?),
        _ => None,
    };
    let force_input = ForceInput::open(cfg)?;
    // The session's lock is held until the recording has concluded.
    let (created, _session_lock) = check(cfg)?;
    let mut tables = Tables::open(cfg, estimator.as_ref(), rig.as_ref())?;
    let mut summary = RecordSummary {
        started_unix_s: started_unix_s(cfg),
        ..RecordSummary::default()
    };
    describe(cfg, false, &summary)?;
    if let Some(r) = &rig {
        write_references(cfg, r)?;
    }
    let clock = Instant::now();
    if !cfg.resume {
        // The clock's zero is now, not when the folder was made (references take a while).
        summary.started_unix_s = started_unix_s(cfg);
        describe(cfg, false, &summary)?;
    }
    observe(observer.as_ref(), |o| o.start(summary.started_unix_s))?;
    let t_offset = tables.t_offset(cfg.fps);
    let force = ForceSide::start(
        cfg,
        force_input,
        rig.as_ref(),
        (clock, t_offset),
        (stop, observer.clone()),
    )?;
    let start = (tables.first_index as u64, t_offset);
    let mut frames = match open_frames(cfg, rig, clock, stop, start) {
        Ok(f) => f,
        Err(e) => {
            // Nothing was recorded: the force side stops and a folder this run made goes again,
            // so that the corrected run is not refused for it.
            stop.store(true, Ordering::Relaxed);
            let _ = force.finish();
            discard_unrecorded(cfg, created);
            return Err(e);
        }
    };
    let result = record_frames(
        cfg,
        &mut frames,
        (&mut tables, estimator.as_mut(), observer.as_ref()),
        (clock, t_offset, stop),
        &mut summary,
        warn,
    );
    // Stop the camera and the force side, whatever happened to the frames.
    stop.store(true, Ordering::Relaxed);
    frames.close();
    summary.dropped = usize::try_from(frames.dropped()).unwrap_or(usize::MAX);
    (summary.force_packets, summary.force_packets_sent) = force.finish()?;
    tables.sync()?;
    summary.frames = tables.first_index + summary.written;
    summary.duration_s = clock.elapsed().as_secs_f64();
    let none_estimated = estimator.is_some() && summary.written > 0 && tables.processed == 0;
    conclude(cfg, result, &summary, none_estimated, created)?;
    Ok(summary)
}

/// Writes the source's frames until it ends, a limit is reached or `stop` is set.
fn record_frames(
    cfg: &RecordConfig,
    frames: &mut FrameSource,
    (tables, mut estimator, observer): (
        &mut Tables,
        Option<&mut LiveEstimator>,
        Option<&SharedObserver>,
    ),
    (clock, t_offset, stop): (Instant, f64, &AtomicBool),
    summary: &mut RecordSummary,
    warn: &mut dyn FnMut(&str),
) -> Result<(), RecordError> {
    let mut k = tables.first_index;
    while !stop.load(Ordering::Relaxed)
        && cfg.max_frames.is_none_or(|m| summary.written < m)
        && cfg
            .duration_s
            .is_none_or(|d| clock.elapsed().as_secs_f64() < d)
    {
        let frame = match frames.next_frame()? {
            Next::Frame(f) => recorded(cfg, f, k, (clock, t_offset)),
            Next::Dropped => {
                k += 1;
                continue;
            }
            Next::Unreadable(why) => {
                warn(&format!("{why}; skipped"));
                summary.unreadable += 1;
                continue;
            }
            Next::End => break,
        };
        if tables.done.contains(&frame.id) {
            // Recorded before the stop this run resumes.
            continue;
        }
        let got = tables.write(cfg, estimator.as_deref_mut(), &frame, k, warn)?;
        summary.written += 1;
        if let Some(o) = observer {
            let estimate = got.map(|(f, ms)| LiveEstimate {
                sensor: None,
                frame: frame.id.clone(),
                index: k as u64,
                timestamp_s: frame.timestamp_s,
                latency_ms: ms,
                processing_ms: ms,
                contact: f.contact,
                max_displacement_px: f.max_displacement_px,
                targets: f.targets,
                health: f.health,
                dropped_frames: frames.dropped(),
                slip: f.slip,
                mm_per_px: estimator.as_ref().and_then(|e| e.calibration().mm_per_px()),
            });
            // An estimate is plain numbers and strings: it always serialises.
            let json = estimate
                .as_ref()
                .map(|e| serde_json::to_string(e).unwrap_or_default());
            let told = SinkFrame {
                id: &frame.id,
                index: k as u64,
                timestamp_s: frame.timestamp_s,
                image: &frame.image,
                estimate: estimate.as_ref(),
                json: json.as_deref(),
                markers: None,
                rows: Some(tables.row_of()),
            };
            if observe(Some(o), |o| o.frame(&told))?.is_some_and(|f| f.is_break()) {
                break;
            }
        }
        k += 1;
    }
    Ok(())
}

/// The end of a recording: `session.json` says how it went, and an error says what went
/// wrong. The first real error is the one reported (a full disk fails the frame before the
/// description): the description is still attempted, its own failure then secondary.
/// Complete only when something was recorded as asked.
fn conclude(
    cfg: &RecordConfig,
    result: Result<(), RecordError>,
    summary: &RecordSummary,
    none_estimated: bool,
    created: bool,
) -> Result<(), RecordError> {
    let described = describe(
        cfg,
        result.is_ok() && summary.written > 0 && !none_estimated,
        summary,
    );
    if result.is_err() && summary.written == 0 {
        discard_unrecorded(cfg, created);
    }
    result?;
    described?;
    if none_estimated {
        return Err(RecordError::NothingEstimated(summary.written));
    }
    if summary.written == 0 {
        // A session this run made and filled with nothing goes again, so that the corrected
        // run is not refused for it.
        discard_unrecorded(cfg, created);
        return Err(RecordError::NothingRecorded(if cfg.resume {
            format!(
                "the session already holds {} frames and the source gave no later one",
                summary.frames
            )
        } else {
            "the source gave no frame".to_string()
        }));
    }
    Ok(())
}

/// Removes the session folder this run made (`created`, not a resume) when it recorded
/// nothing: a half-made session would refuse the corrected run.
fn discard_unrecorded(cfg: &RecordConfig, created: bool) {
    if created && !cfg.resume {
        let _ = std::fs::remove_dir_all(&cfg.output);
    }
}

/// The session clock's zero as UNIX time: now; when resuming, the first run's value from its
/// `session.json` (a session written before this field existed: now, as a best guess).
fn started_unix_s(cfg: &RecordConfig) -> f64 {
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64());
    if !cfg.resume {
        return now;
    }
    SessionDescription::read(&cfg.output)
        .ok()
        .flatten()
        .and_then(|d| d.started_unix_s)
        .filter(|t| *t > 0.0)
        .unwrap_or(now)
}

/// Every number of the settings, checked before anything is created.
fn validate(cfg: &RecordConfig) -> Result<(), RecordError> {
    let check = |r: Result<(), String>| r.map_err(RecordError::Config);
    check(rate("fps", cfg.fps).map(drop))?;
    check(rate("force_rate_hz", cfg.force_rate_hz).map(drop))?;
    check(seconds("sync_every_s", cfg.sync_every_s).map(drop))?;
    if let Some(d) = cfg.duration_s {
        check(seconds("duration_s", d).map(drop))?;
        if d == 0.0 {
            return Err(RecordError::Config(
                "duration_s 0: a recording needs a positive duration".into(),
            ));
        }
    }
    if cfg.max_frames == Some(0) {
        return Err(RecordError::Config("max_frames must be at least 1".into()));
    }
    crate::rig::check_limits(cfg)
}

/// The session folder: refused when it holds a session and `resume` was not asked for (or
/// the other way round), then created and probed for space. Returns whether this run made it.
fn check(cfg: &RecordConfig) -> Result<(bool, std::fs::File), RecordError> {
    let out = &cfg.output;
    // A folder that is there is locked before it is looked at: a second recording (or a
    // resume) into a session being recorded is refused, not interleaved with it.
    let early = if out.is_dir() {
        Some(lock_session(out)?)
    } else {
        None
    };
    let exists = holds_session(out);
    if exists && !cfg.resume {
        return Err(RecordError::Exists(out.clone()));
    }
    if cfg.resume && !exists {
        return Err(RecordError::NothingToResume(out.clone()));
    }
    if cfg.resume {
        resumable(cfg)?;
    }
    let created = !out.exists();
    std::fs::create_dir_all(out).map_err(|e| {
        std::io::Error::new(
            e.kind(),
            format!("cannot create the session folder {}: {e}", out.display()),
        )
    })?;
    let lock = match early {
        Some(l) => l,
        None => lock_session(out)?,
    };
    if created && holds_session(out) {
        // Another recording made the folder and started writing in between.
        return Err(RecordError::Exists(out.clone()));
    }
    if let Err(e) = probe_writable(out, 1 << 20) {
        // A folder made only for this run goes again, so that the corrected run is not
        // refused; `remove_dir` leaves a folder that is not empty.
        if created {
            let _ = std::fs::remove_dir(out);
        }
        return Err(e.into());
    }
    if cfg.save_frames {
        std::fs::create_dir_all(out.join("frames"))?;
    }
    Ok((created, lock))
}

/// An exclusive advisory lock on session folder `dir`, held as long as the returned handle.
fn lock_session(dir: &Path) -> Result<std::fs::File, RecordError> {
    let f = std::fs::File::open(dir)?;
    match f.try_lock() {
        Ok(()) => Ok(f),
        Err(std::fs::TryLockError::WouldBlock) => Err(RecordError::Busy(dir.to_path_buf())),
        Err(std::fs::TryLockError::Error(e)) => Err(std::io::Error::new(
            e.kind(),
            format!("cannot lock the session folder {}: {e}", dir.display()),
        )
        .into()),
    }
}

/// A session may be resumed only by the recording that made it: its `session.json` must read
/// as a session description, and name the same source, force source, sensor and model files
/// and frame saving as `cfg` — else the new rows would join another recording's (or, without
/// the sensor, leave `features.csv` short of the frames).
fn resumable(cfg: &RecordConfig) -> Result<(), RecordError> {
    let refuse = |why: String| RecordError::Config(format!("cannot resume: {why}"));
    let d = SessionDescription::read(&cfg.output)
        .map_err(|e| refuse(e.to_string()))?
        .ok_or_else(|| refuse(format!("{} has no session.json", cfg.output.display())))?;
    let same_file = |was: &Option<PathBuf>, now: &Option<PathBuf>| match (was, now) {
        (None, None) => true,
        (Some(a), Some(b)) => {
            a == b
                || a.canonicalize()
                    .ok()
                    .is_some_and(|a| b.canonicalize().ok() == Some(a))
        }
        _ => false,
    };
    let shown = |v: &Option<String>| v.clone().unwrap_or_else(|| "none".into());
    let path_shown = |p: &Option<PathBuf>| {
        p.as_ref()
            .map_or_else(|| "none".into(), |p| p.display().to_string())
    };
    let force = cfg.force.as_ref().map(ForceSource::to_string);
    let differ: Vec<String> = [
        (
            "source",
            d.source.as_deref().map(SourceSpec::parse).as_ref() == Some(&cfg.source),
            shown(&d.source),
            cfg.source.to_string(),
        ),
        ("force", d.force == force, shown(&d.force), shown(&force)),
        (
            "sensor",
            same_file(&d.sensor_file, &cfg.sensor_file),
            path_shown(&d.sensor_file),
            path_shown(&cfg.sensor_file),
        ),
        (
            "model",
            same_file(&d.model_file, &cfg.model_file),
            path_shown(&d.model_file),
            path_shown(&cfg.model_file),
        ),
        (
            "save-frames",
            d.frames_saved == Some(cfg.save_frames),
            d.frames_saved
                .map_or_else(|| "unknown".into(), |b| b.to_string()),
            cfg.save_frames.to_string(),
        ),
    ]
    .into_iter()
    .filter(|(_, same, _, _)| !same)
    .map(|(name, _, was, now)| format!("{name} was {was}, now {now}"))
    .collect();
    if differ.is_empty() {
        Ok(())
    } else {
        Err(refuse(format!(
            "{}: it was recorded with other settings ({}); resume with the first run's",
            cfg.output.join("session.json").display(),
            differ.join("; ")
        )))
    }
}

#[cfg(feature = "sim")]
fn rig_of(cfg: &RecordConfig, kind: &str) -> Result<Rig, RecordError> {
    Ok(match kind {
        "cone" => Rig::cone(cfg.cone.press_s, cfg.cone.max_force_n, cfg.cone.rest_s)?,
        "iats" => Rig::iats(cfg.max_frames.unwrap_or(200).max(1), cfg.seed),
        other => {
            return Err(RecordError::Config(format!(
                "source sim:{other}: expected sim:cone or sim:iats"
            )))
        }
    })
}

#[cfg(not(feature = "sim"))]
fn rig_of(_: &RecordConfig, kind: &str) -> Result<Rig, RecordError> {
    Err(RecordError::Config(format!(
        "source sim:{kind}: {}",
        crate::rig::NO_SIMULATOR
    )))
}

/// `session.json`: the settings, whether the recording completed, and its counts.
fn describe(cfg: &RecordConfig, complete: bool, s: &RecordSummary) -> Result<(), RecordError> {
    #[derive(Serialize)]
    struct Description<'a> {
        format: &'a str,
        version: u32,
        recorded_by: String,
        source: String,
        fps: f64,
        force: Option<String>,
        force_layout: String,
        force_rate_hz: f64,
        force_clock: &'a str,
        sensor_file: &'a Option<PathBuf>,
        model_file: &'a Option<PathBuf>,
        frames_saved: bool,
        complete: bool,
        frames: usize,
        frames_dropped: usize,
        frames_unreadable: usize,
        force_packets: Option<ReceiveStats>,
        force_packets_sent_by_simulator: Option<u64>,
        duration_s: f64,
        started_unix_s: f64,
    }
    let d = Description {
        format: SESSION_FORMAT,
        version: SESSION_VERSION,
        recorded_by: format!("visuotact {} record", env!("CARGO_PKG_VERSION")),
        source: cfg.source.to_string(),
        fps: cfg.fps,
        force: cfg.force.as_ref().map(ForceSource::to_string),
        force_layout: cfg.force_layout.to_string(),
        force_rate_hz: cfg.force_rate_hz,
        force_clock: "timestamp_s is the force sender's clock; recv_s the recorder's",
        sensor_file: &cfg.sensor_file,
        model_file: &cfg.model_file,
        frames_saved: cfg.save_frames,
        complete,
        frames: s.frames,
        frames_dropped: s.dropped,
        frames_unreadable: s.unreadable,
        force_packets: s.force_packets,
        force_packets_sent_by_simulator: s.force_packets_sent,
        duration_s: s.duration_s,
        started_unix_s: s.started_unix_s,
    };
    let text = serde_json::to_string_pretty(&d).map_err(std::io::Error::other)? + "\n";
    Ok(write_atomically(&cfg.output.join("session.json"), &text)?)
}

/// Simulated rigs write their no-contact references first.
fn write_references(cfg: &RecordConfig, rig: &Rig) -> Result<(), RecordError> {
    if cfg.resume || cfg.references == 0 {
        return Ok(());
    }
    let dir = cfg.output.join("reference");
    std::fs::create_dir_all(&dir)?;
    for k in 0..cfg.references {
        let img = rig.reference(frame_seed(cfg.seed, 1_000_000 + k as u64))?;
        write_png(&dir.join(format!("ref_{k:04}.png")), &img)?;
    }
    Ok(())
}

/// The session's tables, open for appending.
struct Tables {
    frames: AppendLog,
    features: Option<AppendLog>,
    estimates: Option<AppendLog>,
    labels: Option<AppendLog>,
    /// Frame ids already recorded (resume skips them).
    done: HashSet<String>,
    /// The last recorded timestamp, s (−∞ in a new session).
    last_t: f64,
    /// Frames already in the session.
    first_index: usize,
    line: String,
    /// The estimates row of a frame without one (NaN per target).
    no_estimate: Vec<f64>,
    /// The value columns of `features.csv` and `estimates.csv`.
    feature_cols: Vec<String>,
    estimate_cols: Vec<String>,
    /// The last frame's rows (empty: none written).
    feature_row: Vec<f64>,
    /// The millimetre twins of the features (none without a sensor scale).
    mm: MmColumns,
    estimate_row: Vec<f64>,
    /// Frames of this run the estimator processed.
    processed: usize,
}

impl Tables {
    fn open(
        cfg: &RecordConfig,
        est: Option<&LiveEstimator>,
        rig: Option<&Rig>,
    ) -> Result<Self, RecordError> {
        let sync = seconds("sync_every_s", cfg.sync_every_s).map_err(RecordError::Config)?;
        let open = |name: &str, header: &str| {
            AppendLog::open(&cfg.output.join(name), header, cfg.resume, sync)
        };
        let (frames, kept) = open("frames.csv", "frame,index,timestamp_s,kind")?;
        let done = kept
            .lines()
            .skip(1)
            .filter_map(|l| l.split(',').next().map(str::to_string))
            .collect();
        let last_t = kept
            .lines()
            .skip(1)
            .filter_map(|l| l.split(',').nth(2)?.parse::<f64>().ok())
            .fold(f64::NEG_INFINITY, f64::max);
        let with_frame = |cols: &[String]| format!("frame,{},flags", cols.join(","));
        let feature_cols = est.map_or_else(Vec::new, |e| {
            let e = e.estimator();
            feature_columns(&e.feature_columns(), e.mm_columns())
        });
        let features = est
            .map(|_| open("features.csv", &with_frame(&feature_cols)))
            .transpose()?
            .map(|(log, _)| log);
        let estimate_cols = est.map_or_else(Vec::new, LiveEstimator::estimate_columns);
        let estimates = (!estimate_cols.is_empty())
            .then(|| open("estimates.csv", &with_frame(&estimate_cols)))
            .transpose()?
            .map(|(log, _)| log);
        let labels = rig
            .map(|r| {
                open(
                    "labels.csv",
                    &format!("frame,{}", r.label_columns().join(",")),
                )
            })
            .transpose()?
            .map(|(log, _)| log);
        // A resumed session goes on after its last frame's number (frames dropped before
        // the stop leave gaps: counting the kept rows would number a frame twice).
        let first_index = kept
            .lines()
            .skip(1)
            .filter_map(|l| l.split(',').nth(1)?.parse::<usize>().ok())
            .max()
            .map_or(frames.lines(), |last| (last + 1).max(frames.lines()));
        Ok(Self {
            first_index,
            frames,
            features,
            estimates,
            labels,
            done,
            last_t,
            line: String::new(),
            no_estimate: vec![f64::NAN; estimate_cols.len()],
            feature_cols,
            estimate_cols,
            feature_row: Vec::new(),
            mm: est
                .map(|e| e.estimator().mm_columns().clone())
                .unwrap_or_default(),
            estimate_row: Vec::new(),
            processed: 0,
        })
    }

    /// The session clock's start: a resumed session continues after its last frame.
    fn t_offset(&self, fps: f64) -> f64 {
        if self.last_t.is_finite() {
            self.last_t + 1.0 / fps
        } else {
            0.0
        }
    }

    /// Writes frame `k`: its PNG if asked, its features and estimate, labels and index row.
    /// Returns the estimator's result and the milliseconds it took, when it processed the
    /// frame.
    fn write(
        &mut self,
        cfg: &RecordConfig,
        est: Option<&mut LiveEstimator>,
        f: &RecordedFrame,
        k: usize,
        warn: &mut dyn FnMut(&str),
    ) -> Result<Option<(LiveFrame, f64)>, RecordError> {
        if cfg.save_frames {
            let name = if f.id.ends_with(".png") {
                f.id.clone()
            } else {
                format!("{}.png", f.id)
            };
            write_png(&cfg.output.join("frames").join(name), &f.image)?;
        }
        self.feature_row.clear();
        self.estimate_row.clear();
        let got = match est {
            Some(e) => self.write_estimate(e, f, warn)?,
            None => None,
        };
        if let Some(log) = self.labels.as_mut() {
            let cells: Vec<String> = f.labels.iter().map(|v| format_number(*v)).collect();
            log.line(&format!("{},{}", f.id, cells.join(",")))?;
        }
        self.frames.line(&format!(
            "{},{},{},touch",
            f.id,
            k,
            format_number(f.timestamp_s)
        ))?;
        Ok(got)
    }

    fn write_estimate(
        &mut self,
        e: &mut LiveEstimator,
        f: &RecordedFrame,
        warn: &mut dyn FnMut(&str),
    ) -> Result<Option<(LiveFrame, f64)>, RecordError> {
        let t0 = Instant::now();
        let got = match e.process(&f.image, None) {
            Ok(r) => r,
            Err(err) => {
                warn(&format!("frame {}: {err}", f.id));
                return Ok(None);
            }
        };
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        self.processed += 1;
        let n_markers = e.estimator().n_markers();
        let features = e.estimator().last_features();
        if let Some(log) = self.features.as_mut() {
            feature_row_into(
                &mut self.feature_row,
                f.timestamp_s,
                n_markers,
                features,
                &self.mm,
            );
            self.line.clear();
            push_csv_row(
                &mut self.line,
                &f.id,
                &self.feature_row,
                &flags_of(features),
            );
            log.line(&self.line)?;
        }
        if let Some(log) = self.estimates.as_mut() {
            self.line.clear();
            if got.targets.is_empty() {
                push_csv_row(&mut self.line, &f.id, &self.no_estimate, "missing features");
            } else {
                let targets = &got.targets;
                self.estimate_row.extend(targets.iter().map(|t| t.value));
                self.estimate_row
                    .extend(targets.iter().filter_map(|t| t.std));
                push_csv_row(&mut self.line, &f.id, &self.estimate_row, "");
            }
            log.line(&self.line)?;
        }
        Ok(Some((got, ms)))
    }

    /// The frame just written, as its rows say it.
    fn row_of(&self) -> RecordedRow<'_> {
        fn part<'a>(cols: &'a [String], row: &'a [f64]) -> Option<(&'a [String], &'a [f64])> {
            (!row.is_empty() && row.len() == cols.len()).then_some((cols, row))
        }
        RecordedRow {
            features: part(&self.feature_cols, &self.feature_row),
            estimates: part(&self.estimate_cols, &self.estimate_row),
        }
    }

    fn sync(&mut self) -> Result<(), RecordError> {
        for log in [
            Some(&mut self.frames),
            self.features.as_mut(),
            self.estimates.as_mut(),
            self.labels.as_mut(),
        ]
        .into_iter()
        .flatten()
        {
            log.sync()?;
        }
        Ok(())
    }
}

/// The frame side: a simulated rig paced on the recorder's clock (late frames dropped), files
/// as fast as they are written, or a camera capturing on its own thread into a drop-oldest
/// queue (timestamped on arrival).
fn open_frames(
    cfg: &RecordConfig,
    rig: Option<Rig>,
    clock: Instant,
    stop: &Arc<AtomicBool>,
    start: (u64, f64),
) -> Result<FrameSource, RecordError> {
    Ok(match rig {
        Some(rig) => FrameSource::rig((rig, cfg.seed), cfg.fps, clock, start),
        None => {
            let source = SourceConfig {
                source: cfg.source.clone(),
                fps: cfg.fps,
                pacing: Pacing::Free,
                camera_queue: 4,
                ..SourceConfig::default()
            };
            FrameSource::open(&source, stop)?
        }
    })
}

/// Frame `k` of the session as it is recorded: a camera's frames are named by their number
/// and timed by their arrival on the session's clock (`t_offset` later in a resumed session);
/// files and rigs keep their names and times.
fn recorded(
    cfg: &RecordConfig,
    f: SourceFrame,
    k: usize,
    (clock, t_offset): (Instant, f64),
) -> RecordedFrame {
    let SourceFrame {
        frame,
        labels,
        delivered,
    } = f;
    if matches!(cfg.source, SourceSpec::Camera(_)) {
        RecordedFrame {
            id: format!("frame_{k:06}.png"),
            timestamp_s: t_offset + delivered.saturating_duration_since(clock).as_secs_f64(),
            image: Arc::new(frame.image),
            labels,
        }
    } else {
        RecordedFrame {
            id: frame.id,
            timestamp_s: frame.timestamp_s,
            image: Arc::new(frame.image),
            labels,
        }
    }
}

/// The force side: a receiver thread writing `force.csv`, and the simulated JR3 feeding it.
struct ForceSide {
    receiver: Option<JoinHandle<Result<ReceiveStats, std::io::Error>>>,
    jr3: Option<JoinHandle<u64>>,
    stop: Arc<AtomicBool>,
}

/// The force source, opened before the session folder is touched: a busy port or a bad
/// table is reported first.
enum ForceInput {
    None,
    Udp(Box<ForceReceiver>),
    Csv(ForceTable),
}

impl ForceInput {
    fn open(cfg: &RecordConfig) -> Result<Self, RecordError> {
        Ok(match &cfg.force {
            None => Self::None,
            Some(ForceSource::Udp(addr)) => Self::Udp(Box::new(ForceReceiver::bind(
                addr,
                cfg.force_layout.clone(),
                Some(cfg.force_rate_hz),
            )?)),
            Some(ForceSource::Csv(p)) => Self::Csv(ForceTable::read(p)?),
        })
    }
}

impl ForceSide {
    fn start(
        cfg: &RecordConfig,
        input: ForceInput,
        rig: Option<&Rig>,
        (clock, t_offset): (Instant, f64),
        (stop, observer): (&Arc<AtomicBool>, Option<SharedObserver>),
    ) -> Result<Self, RecordError> {
        let mut side = Self {
            receiver: None,
            jr3: None,
            stop: Arc::new(AtomicBool::new(false)),
        };
        let sync = seconds("sync_every_s", cfg.sync_every_s).map_err(RecordError::Config)?;
        let path = cfg.output.join("force.csv");
        match input {
            ForceInput::None => {}
            ForceInput::Udp(rx) => {
                let bound = rx.local_addr()?.to_string();
                let (log, _) = AppendLog::open(&path, FORCE_HEADER, cfg.resume, sync)?;
                let on = (clock, t_offset, side.stop.clone());
                side.receiver = Some(spawn_receiver(*rx, log, on, observer));
                if let Some(r) = rig {
                    let t_end = r
                        .total_s(cfg.fps)
                        .min(cfg.duration_s.map_or(f64::INFINITY, |d| t_offset + d));
                    let sim_clock = Duration::try_from_secs_f64(t_offset)
                        .ok()
                        .and_then(|d| clock.checked_sub(d))
                        .unwrap_or(clock);
                    let stream = Jr3Stream {
                        addr: &bound,
                        layout: cfg.force_layout.clone(),
                        rate_hz: cfg.force_rate_hz,
                        seed: cfg.seed,
                        clock: sim_clock,
                        t_from: t_offset,
                        t_end,
                    };
                    side.jr3 = spawn_jr3(r, stream, stop.clone())?;
                }
            }
            ForceInput::Csv(t) => {
                let (mut log, _) = AppendLog::open(&path, FORCE_HEADER, cfg.resume, sync)?;
                for (ts, v) in t.timestamp_s.iter().zip(&t.values) {
                    let cells: Vec<String> = v.iter().map(|x| format_number(*x)).collect();
                    let ts_cell = format_number(*ts);
                    log.line(&format!("{ts_cell},{},{ts_cell}", cells.join(",")))?;
                    let sample = ForceSample {
                        timestamp_s: *ts,
                        values: *v,
                    };
                    observe(observer.as_ref(), |o| o.force(&sample))?;
                }
                log.sync()?;
            }
        }
        Ok(side)
    }

    /// Waits for the simulator, lets the last packets arrive, stops the receiver: its counts
    /// and the packets the simulator sent.
    fn finish(self) -> Result<(Option<ReceiveStats>, Option<u64>), RecordError> {
        let sent = self.jr3.and_then(|h| h.join().ok());
        std::thread::sleep(Duration::from_millis(100));
        self.stop.store(true, Ordering::Relaxed);
        let stats = match self.receiver {
            Some(h) => Some(
                h.join()
                    .map_err(|_| RecordError::Thread("force receiver"))??,
            ),
            None => None,
        };
        Ok((stats, sent))
    }
}

/// Receives force packets into `force.csv` until `stop`.
fn spawn_receiver(
    mut rx: ForceReceiver,
    mut log: AppendLog,
    (clock, t_offset, stop): (Instant, f64, Arc<AtomicBool>),
    observer: Option<SharedObserver>,
) -> JoinHandle<Result<ReceiveStats, std::io::Error>> {
    std::thread::spawn(move || {
        let mut line = String::new();
        // The sender's clock onto the recorder's, as `ForceTable::recorder_times_s` maps it
        // from the finished table: observers (a live bag) stamp what an export stamps.
        let mut least = f64::INFINITY;
        loop {
            let got = rx.recv(Duration::from_millis(50), || {
                t_offset + clock.elapsed().as_secs_f64()
            })?;
            if let Some(r) = got {
                // Shortest round-trip numbers: the table holds the sample exactly.
                line.clear();
                line.push_str(&format_number(r.sample.timestamp_s));
                for v in r.sample.values {
                    line.push(',');
                    line.push_str(&format_number(v));
                }
                line.push(',');
                line.push_str(&format_number(r.recv_s));
                log.line(&line)?;
                let offset = to_recorder(r.sample.timestamp_s, r.recv_s, &mut least);
                let sample = ForceSample {
                    timestamp_s: r.sample.timestamp_s + offset,
                    values: r.sample.values,
                };
                observe(observer.as_ref(), |o| o.force(&sample)).map_err(std::io::Error::other)?;
            }
            // Checked after every packet too: a sender that never pauses must not keep the
            // recording open (it ran 20.8 s for `--duration-s 2`).
            if stop.load(Ordering::Relaxed) {
                break;
            }
        }
        log.sync()?;
        Ok(rx.stats())
    })
}

/// Whether `dir` holds a recorded session (its frame index or description).
pub fn holds_session(dir: &Path) -> bool {
    dir.join("frames.csv").exists() || dir.join("session.json").exists()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A session being recorded is locked: a second recording or a resume into it is refused
    /// by name (was: two writers interleaving rows), and the folder is free again after.
    #[test]
    fn a_session_being_recorded_is_refused_to_a_second_writer() {
        let dir = std::env::temp_dir().join(format!("vt-rec-lock-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let cfg = RecordConfig {
            output: dir.clone(),
            ..RecordConfig::default()
        };
        let (created, held) = check(&cfg).unwrap();
        assert!(created);
        std::fs::write(dir.join("frames.csv"), "frame,index,timestamp_s,kind\n").unwrap();
        for resume in [false, true] {
            let again = RecordConfig {
                resume,
                ..cfg.clone()
            };
            let e = check(&again).unwrap_err();
            assert!(matches!(e, RecordError::Busy(_)), "{e}");
            assert!(e.to_string().contains("another recording"), "{e}");
        }
        drop(held);
        let e = check(&cfg).unwrap_err();
        assert!(matches!(e, RecordError::Exists(_)), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A force sender that never pauses (a real F/T box streams at 1 kHz and up) does not keep
    /// the receiver, and so the recording, open once it is told to stop: it was only asked
    /// when a wait for a packet timed out (20.8 s for a 2-second recording).
    #[test]
    fn a_streaming_force_sender_does_not_hold_the_receiver_open() {
        let rx = ForceReceiver::bind("127.0.0.1:0", ForceLayout::default(), None).unwrap();
        let to = rx.local_addr().unwrap();
        let dir = std::env::temp_dir().join(format!("vt-rec-stream-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let every = Duration::from_secs(1);
        let (log, _) = AppendLog::open(&dir.join("force.csv"), FORCE_HEADER, false, every).unwrap();
        let sending = Arc::new(AtomicBool::new(true));
        let sender = {
            let sending = sending.clone();
            std::thread::spawn(move || {
                let sock = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
                let layout = ForceLayout::default();
                // Up to 20 s of samples at ~2 kHz, on the sender's own clock.
                for i in 0..40_000u64 {
                    if !sending.load(Ordering::Relaxed) {
                        return true;
                    }
                    let s = ForceSample {
                        timestamp_s: 1000.0 + i as f64 * 5e-4,
                        values: [0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
                    };
                    let _ = sock.send_to(&layout.encode(&s, i), to);
                    std::thread::sleep(Duration::from_micros(500));
                }
                false
            })
        };
        let stop = Arc::new(AtomicBool::new(false));
        let receiver = spawn_receiver(rx, log, (Instant::now(), 0.0, stop.clone()), None);
        std::thread::sleep(Duration::from_millis(300));
        stop.store(true, Ordering::Relaxed);
        let stats = receiver.join().unwrap().unwrap();
        // The receiver returned while the sender was still streaming.
        sending.store(false, Ordering::Relaxed);
        assert!(
            sender.join().unwrap(),
            "the sender ran out before the receiver stopped"
        );
        assert!(stats.kept > 0, "{stats:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
