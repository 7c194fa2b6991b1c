//! visuotact in [Rerun](https://rerun.io): a live run (`run --rerun`) or a recorded session
//! (`export rerun`) as a Rerun recording — an `.rrd` file or a viewer over gRPC — through the
//! official `rerun` crate (0.24, the version LeRobot pins its viewer to).
//!
//! ## What is logged
//!
//! Under the run's namespace `NS` (`/visuotact`, or `/visuotact/NAME` per sensor of a run of
//! several), on two timelines: `frame` (the frame's index) and `capture_time` (its stamp, on the
//! wall clock for a live run, the session's start plus its seconds for an export):
//!
//! | entity | archetype | content |
//! |---|---|---|
//! | `NS/image` | `EncodedImage` | the frame, PNG (live with `--rerun-images`; export: the saved frame) |
//! | `NS/image/markers` | `Points2D` | each marker where it is now (reference + displacement), pixels; green found, red lost (at its reference position) |
//! | `NS/image/displacement` | `Arrows2D` | each found marker's displacement from its reference position, pixels |
//! | `NS/estimate/NAME` | `Scalars` | each estimated target (`x_mm`, `depth_mm`, `fz_n`, …) |
//! | `NS/force/AXIS` | `Scalars` | the force/torque sensor (`fx_n` … `tz_nm`), each sample at its own time (no `frame`) |
//! | `NS/contact` | `Scalars` | the live contact rule, 1 or 0 |
//! | `NS/slip`, `NS/slip/state` | `Scalars` | the slip score (0 to 1) and state (0 stick, 1 incipient, 2 slip): live runs with `--slip` |
//! | `NS/health/found`, `NS/health/lost` | `Scalars` | markers found and lost |
//!
//! The parts are the frame parts every other output writes ([`FrameParts`]): the values
//! are those of the JSON lines, the bags and the session's tables. Test:
//! `crates/visuotact-cli/tests/rerun.rs` reads the files back with the `rerun-sdk` Python
//! package's dataframe API and compares them with the session tables.
//!
//! ## Modules and what each owns
//!
//! One file: [`RerunTarget`] (a [`FrameTarget`]: frame parts → Rerun archetypes), the live
//! sink [`RerunSink`] and [`export_rerun`]. Depends on pipeline (frame parts, the live sink,
//! the session export); no clap.

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use rerun::{Arrows2D, Color, EncodedImage, Points2D, RecordingStream, Scalars};
use visuotact_pipeline::output::{
    FrameParts, FrameTarget, LiveSink, OutputConfig, OutputError, WRENCH_TARGETS,
};
use visuotact_pipeline::session_export::{ExportConfig, SessionExport};

/// The application id the recordings carry.
pub const APPLICATION_ID: &str = "visuotact";

/// The viewer's default gRPC address (`rerun` listens here when started without options).
pub const DEFAULT_VIEWER_ADDR: &str = "127.0.0.1:9876";

/// Where a recording goes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RerunOutput {
    /// An `.rrd` file.
    File(PathBuf),
    /// A running viewer at `HOST:PORT` (gRPC).
    Viewer(String),
}

impl RerunOutput {
    /// `FILE.rrd` is a file, `HOST:PORT` (a numeric port; empty for the default) a viewer;
    /// anything else — `model.json`, a typo — is refused with what was expected, never looked
    /// up as a host name.
    pub fn parse(s: &str) -> Result<Self, BadOutput> {
        if Path::new(s)
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("rrd"))
        {
            Ok(RerunOutput::File(PathBuf::from(s)))
        } else if s.is_empty() {
            Ok(RerunOutput::Viewer(DEFAULT_VIEWER_ADDR.to_string()))
        } else if s
            .rsplit_once(':')
            .is_some_and(|(host, port)| !host.is_empty() && port.parse::<u16>().is_ok())
        {
            Ok(RerunOutput::Viewer(s.to_string()))
        } else {
            Err(BadOutput(s.to_string()))
        }
    }
}

/// A recording output that is neither `FILE.rrd` nor `HOST:PORT`.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("expects a recording file FILE.rrd or a viewer's HOST:PORT, got `{0}`")]
pub struct BadOutput(pub String);

/// Why a recording could not be made, written or closed.
#[derive(Debug, thiserror::Error)]
pub enum RerunError {
    /// A file could not be read or written.
    #[error("{}: {}", .0.display(), .1)]
    Io(PathBuf, #[source] std::io::Error),
    /// The output exists already.
    #[error("{}: already exists; choose a new name", .0.display())]
    Exists(PathBuf),
    /// The Rerun SDK failed, or the recording did not read back whole.
    #[error("Rerun: {0}")]
    Recording(String),
    /// Reading the session or writing a frame's parts failed.
    #[error(transparent)]
    Output(#[from] OutputError),
}

fn target_err(e: impl std::fmt::Display) -> RerunError {
    RerunError::Recording(e.to_string())
}

/// A Rerun recording stream taking frame parts.
pub struct RerunTarget {
    rec: RecordingStream,
    output: RerunOutput,
    /// A file output's temporary file, renamed onto it when the recording is whole.
    temp: Option<visuotact_io::output::TempBeside>,
    /// Frames logged.
    pub frames: u64,
}

impl RerunTarget {
    /// A recording into `output`: a new `.rrd` file (an existing one is refused), written
    /// under a temporary name beside it and renamed when whole ([`RerunTarget::finish`]), or a
    /// viewer.
    pub fn open(output: RerunOutput) -> Result<Self, RerunError> {
        let builder = rerun::RecordingStreamBuilder::new(APPLICATION_ID);
        let mut temp = None;
        let rec = match &output {
            RerunOutput::File(p) => {
                if p.symlink_metadata().is_ok() {
                    return Err(RerunError::Exists(p.clone()));
                }
                let t = visuotact_io::output::TempBeside::new(p)
                    .map_err(|e| RerunError::Io(p.clone(), e))?;
                let rec = builder
                    .save(t.path())
                    .map_err(|e| target_err(format!("{}: {e}", p.display())))?;
                temp = Some(t);
                rec
            }
            RerunOutput::Viewer(addr) => builder
                .connect_grpc_opts(
                    format!("rerun+http://{addr}/proxy"),
                    rerun::default_flush_timeout(),
                )
                .map_err(|e| target_err(format!("viewer at {addr}: {e}")))?,
        };
        Ok(Self {
            rec,
            output,
            temp,
            frames: 0,
        })
    }

    /// Closes the recording without keeping it: a file output's temporary file is removed.
    pub fn abandon(self) {
        self.rec.disconnect();
    }

    /// Where the recording goes.
    pub fn output(&self) -> &RerunOutput {
        &self.output
    }

    /// Flushes and closes the recording; a file is read back whole and only then renamed onto
    /// its name (otherwise the temporary file is removed and nothing is left there).
    pub fn finish(self) -> Result<u64, RerunError> {
        self.rec.flush_blocking();
        self.rec.disconnect();
        if let (RerunOutput::File(p), Some(t)) = (self.output, self.temp) {
            verify_recording(t.path(), &p)?;
            t.land(&p).map_err(|e| RerunError::Io(p.clone(), e))?;
        }
        Ok(self.frames)
    }

    fn log(&self, path: String, what: &impl rerun::AsComponents) -> Result<(), RerunError> {
        self.rec.log(path, what).map_err(target_err)
    }
}

/// Green for a found marker, red for a lost one (RGB).
const FOUND: [u8; 3] = [40, 200, 80];
const LOST: [u8; 3] = [230, 50, 50];

fn colour([r, g, b]: [u8; 3]) -> Color {
    Color::from_rgb(r, g, b)
}

impl FrameTarget for RerunTarget {
    fn write_frame(&mut self, cfg: &OutputConfig, f: FrameParts<'_>) -> Result<(), OutputError> {
        self.write_parts(cfg, f).map_err(OutputError::target)
    }
}

impl RerunTarget {
    fn write_parts(&mut self, cfg: &OutputConfig, f: FrameParts<'_>) -> Result<(), RerunError> {
        let ns = cfg.namespace.trim_end_matches('/');
        match f.index {
            Some(k) => self
                .rec
                .set_time_sequence("frame", i64::try_from(k).unwrap_or(i64::MAX)),
            None => self.rec.disable_timeline("frame"),
        }
        self.rec.set_timestamp_nanos_since_epoch(
            "capture_time",
            i64::try_from(f.stamp_ns).unwrap_or(i64::MAX),
        );
        if let Some(png) = f.png {
            self.log(
                format!("{ns}/image"),
                &EncodedImage::from_file_contents(png),
            )?;
        }
        if let Some(markers) = f.markers {
            let at = markers.iter().map(|m| {
                if m.found {
                    (m.x_px + m.dx_px, m.y_px + m.dy_px)
                } else {
                    (m.x_px, m.y_px)
                }
            });
            let colours = markers
                .iter()
                .map(|m| colour(if m.found { FOUND } else { LOST }));
            self.log(
                format!("{ns}/image/markers"),
                &Points2D::new(at).with_colors(colours).with_radii([2.0]),
            )?;
            let found = markers.iter().filter(|m| m.found);
            self.log(
                format!("{ns}/image/displacement"),
                &Arrows2D::from_vectors(found.clone().map(|m| (m.dx_px, m.dy_px)))
                    .with_origins(found.map(|m| (m.x_px, m.y_px)))
                    .with_colors([colour(FOUND)]),
            )?;
        }
        for t in f.targets {
            self.log(
                format!("{ns}/estimate/{}", t.name),
                &Scalars::single(t.value),
            )?;
        }
        if let Some(w) = f.measured {
            for (axis, v) in WRENCH_TARGETS.iter().zip(w) {
                if v.is_finite() {
                    self.log(format!("{ns}/force/{axis}"), &Scalars::single(v))?;
                }
            }
        }
        if let Some(c) = f.contact {
            self.log(
                format!("{ns}/contact"),
                &Scalars::single(f64::from(u8::from(c))),
            )?;
        }
        if let Some(s) = f.slip {
            self.log(format!("{ns}/slip"), &Scalars::single(s.score))?;
            let code = f64::from(s.state as u8);
            self.log(format!("{ns}/slip/state"), &Scalars::single(code))?;
        }
        if let Some((h, _)) = &f.health {
            self.log(format!("{ns}/health/found"), &Scalars::single(h.ok as f64))?;
            self.log(format!("{ns}/health/lost"), &Scalars::single(h.lost as f64))?;
        }
        if f.index.is_some() {
            self.frames += 1;
        }
        Ok(())
    }
}

/// A live run's estimates logged to Rerun: a [`LiveSink`] (a `Sink` of the live runner),
/// stamped on the wall clock.
pub type RerunSink = LiveSink<RerunTarget>;

/// A live run into `output` under `cfg` (`cfg.images`: the frames too, PNG-encoded).
pub fn rerun_sink(output: RerunOutput, cfg: OutputConfig) -> Result<RerunSink, RerunError> {
    Ok(LiveSink::new(RerunTarget::open(output)?, cfg)?)
}

/// Closes a live run's recording: frames logged, or the run's first error.
pub fn finish_sink(sink: RerunSink) -> Result<u64, RerunError> {
    sink.finish_with(RerunTarget::finish)
}

/// What an export wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct RerunExport {
    /// The `.rrd` file.
    pub path: PathBuf,
    /// Frames logged.
    pub frames: u64,
    /// Parts of the session that were not there.
    pub notes: Vec<String>,
}

/// Reads the recording file at `p` back to its end: the SDK's file sink reports a failed write
/// (a full disk, a file-size limit) only in its log, so a file that does not decode whole — up
/// to its last byte, ending in the stream's end marker (a 16-byte header of kind 0, length 0) —
/// is the error here, never "wrote x.rrd". `p` is read; errors give it `name`. Returns the
/// messages it holds.
fn verify_recording(p: &Path, name: &Path) -> Result<u64, RerunError> {
    use rerun::external::re_log_encoding::decoder::Decoder;
    use std::io::{Read, Seek};
    let bad = |why: String| target_err(format!("{}: {why}", name.display()));
    let open = || std::fs::File::open(p).map_err(|e| bad(format!("nothing was written ({e})")));
    let mut file = open()?;
    let len = file.metadata().map_err(|e| bad(e.to_string()))?.len();
    let mut tail = [0xffu8; 16];
    if len >= 16 {
        file.seek(std::io::SeekFrom::End(-16))
            .and_then(|_| file.read_exact(&mut tail))
            .map_err(|e| bad(e.to_string()))?;
    }
    let mut decoder = Decoder::new(std::io::BufReader::new(open()?))
        .map_err(|e| bad(format!("not a whole recording (a full disk?): {e}")))?;
    let mut messages = 0u64;
    for m in decoder.by_ref() {
        let _message = m.map_err(|e| bad(format!("after {messages} messages: {e}")))?;
        messages += 1;
    }
    if messages == 0 {
        return Err(bad("nothing was written".into()));
    }
    if decoder.size_bytes() != len || tail != [0u8; 16] {
        return Err(bad(format!(
            "the recording breaks off after {messages} messages (a full disk?)"
        )));
    }
    Ok(messages)
}

/// Exports `session` into a new `.rrd` file at `out`, the parts `export mcap` writes
/// ([`SessionExport`]); `progress(done, total)` may stop it ([`OutputError::Stopped`]). A failed
/// or stopped export removes the file.
pub fn export_rerun(
    session: &Path,
    out: &Path,
    cfg: &ExportConfig,
    progress: &mut dyn FnMut(usize, usize) -> ControlFlow<()>,
) -> Result<RerunExport, RerunError> {
    let plan = SessionExport::read(session, cfg)?;
    let mut target = RerunTarget::open(RerunOutput::File(out.to_path_buf()))?;
    // A failed or stopped export never renames its temporary file onto `out`: nothing to remove.
    let frames = match plan.write_to(&mut target, cfg, progress) {
        Ok(_) => target.finish()?,
        Err(e) => {
            target.abandon();
            return Err(e.into());
        }
    };
    Ok(RerunExport {
        path: out.to_path_buf(),
        frames,
        notes: plan.notes().to_vec(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_output_is_a_recording_file_or_a_viewer_address_never_a_guess() {
        assert_eq!(
            RerunOutput::parse("run.RRD"),
            Ok(RerunOutput::File("run.RRD".into()))
        );
        assert_eq!(
            RerunOutput::parse(""),
            Ok(RerunOutput::Viewer(DEFAULT_VIEWER_ADDR.into()))
        );
        assert_eq!(
            RerunOutput::parse("viewer.lan:9876"),
            Ok(RerunOutput::Viewer("viewer.lan:9876".into()))
        );
        for typo in [
            "model.json",
            "localhost",
            ":9876",
            "host:port",
            "host:99999",
        ] {
            let e = RerunOutput::parse(typo).unwrap_err().to_string();
            assert!(e.contains("FILE.rrd") && e.contains(typo), "{e}");
        }
    }
}
