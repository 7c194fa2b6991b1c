//! Session folders: what `simulate` writes today and `record` will write later.
//!
//! ```text
//! SESSION/
//!   session.json      what produced it (format, version, sensor, protocol, seed, every setting)
//!   reference/        no-contact frames (PNG), for `calibrate`
//!   frames/           the frames (PNG)
//!   frames.csv        frame,index,timestamp_s,kind   (kind: reference | touch)
//!   labels.csv        frame,<targets with units>     (x_mm,y_mm,depth_mm… or force_n,fx_n…)
//!   truth.csv         frame,marker,x_px,y_px,area_px,fully_in_view,visible  (simulator only;
//!                     reference frames too)
//!   force.csv         timestamp_s,fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm (when a force sensor ran)
//! ```
//!
//! Rows are appended and flushed as frames are written, so a session that stops early is
//! readable up to its last complete row. The format is documented in `docs/session-format.md`.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::force::ForceSample;
use crate::table::{format_number, KeyedTable, TableError};

/// Identifies session descriptions.
pub const SESSION_FORMAT: &str = "visuotact-session";
/// Current session format version.
pub const SESSION_VERSION: u32 = 1;

/// One simulated marker's truth in one frame (a row of `truth.csv`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TruthRow {
    /// Exact centroid column of the shape drawn, pixels.
    pub x_px: f64,
    /// Exact centroid row, pixels.
    pub y_px: f64,
    /// Exact area, pixels.
    pub area_px: f64,
    /// Wholly inside the image (and the sensor's circular view, if any).
    pub fully_in_view: bool,
    /// In view and clear of every other marker: a blob of its own that tracking must find.
    pub visible: bool,
}

/// Writes one session folder.
pub struct SessionWriter {
    dir: PathBuf,
    frames: BufWriter<File>,
    labels: BufWriter<File>,
    truth: Option<BufWriter<File>>,
    force: Option<BufWriter<File>>,
    label_columns: usize,
}

fn create(path: &Path) -> std::io::Result<BufWriter<File>> {
    File::create(path)
        .map(BufWriter::new)
        .map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", path.display())))
}

impl SessionWriter {
    /// Creates `dir` (which must not hold a session already) with the label columns given.
    pub fn create(
        dir: &Path,
        label_columns: &[&str],
        with_truth: bool,
        with_force: bool,
    ) -> std::io::Result<Self> {
        if dir.join("session.json").exists() || dir.join("frames.csv").exists() {
            return Err(std::io::Error::new(
                std::io::ErrorKind::AlreadyExists,
                format!(
                    "{}: already holds a session; choose a new folder",
                    dir.display()
                ),
            ));
        }
        for sub in ["reference", "frames"] {
            let d = dir.join(sub);
            std::fs::create_dir_all(&d)
                .map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", d.display())))?;
        }
        let mut frames = create(&dir.join("frames.csv"))?;
        writeln!(frames, "frame,index,timestamp_s,kind")?;
        let mut labels = create(&dir.join("labels.csv"))?;
        writeln!(labels, "frame,{}", label_columns.join(","))?;
        let truth = if with_truth {
            let mut t = create(&dir.join("truth.csv"))?;
            writeln!(t, "frame,marker,x_px,y_px,area_px,fully_in_view,visible")?;
            Some(t)
        } else {
            None
        };
        let force = if with_force {
            let mut f = create(&dir.join("force.csv"))?;
            writeln!(f, "timestamp_s,fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm")?;
            Some(f)
        } else {
            None
        };
        frames.flush()?;
        labels.flush()?;
        Ok(Self {
            dir: dir.to_path_buf(),
            frames,
            labels,
            truth,
            force,
            label_columns: label_columns.len(),
        })
    }

    /// Path of a reference frame file.
    pub fn reference_path(&self, name: &str) -> PathBuf {
        self.dir.join("reference").join(name)
    }

    /// Path of a frame file.
    pub fn frame_path(&self, name: &str) -> PathBuf {
        self.dir.join("frames").join(name)
    }

    /// Records a reference frame already written to [`SessionWriter::reference_path`], with
    /// (simulator) per-marker truth: the rest positions.
    pub fn add_reference(
        &mut self,
        name: &str,
        index: usize,
        timestamp_s: f64,
        truth: &[TruthRow],
    ) -> std::io::Result<()> {
        writeln!(
            self.frames,
            "{name},{index},{},reference",
            format_number(timestamp_s)
        )?;
        self.write_truth(name, truth)?;
        self.frames.flush()
    }

    fn write_truth(&mut self, name: &str, truth: &[TruthRow]) -> std::io::Result<()> {
        if let Some(t) = self.truth.as_mut() {
            for (k, r) in truth.iter().enumerate() {
                writeln!(
                    t,
                    "{name},{k},{:.6},{:.6},{:.4},{},{}",
                    r.x_px,
                    r.y_px,
                    r.area_px,
                    u8::from(r.fully_in_view),
                    u8::from(r.visible)
                )?;
            }
            t.flush()?;
        }
        Ok(())
    }

    /// Records a frame already written to [`SessionWriter::frame_path`], with its labels and
    /// (simulator) per-marker truth.
    pub fn add_frame(
        &mut self,
        name: &str,
        index: usize,
        timestamp_s: f64,
        labels: &[f64],
        truth: &[TruthRow],
    ) -> std::io::Result<()> {
        assert_eq!(
            labels.len(),
            self.label_columns,
            "one value per label column"
        );
        writeln!(
            self.frames,
            "{name},{index},{},touch",
            format_number(timestamp_s)
        )?;
        let cells: Vec<String> = labels.iter().map(|v| format_number(*v)).collect();
        writeln!(self.labels, "{name},{}", cells.join(","))?;
        self.write_truth(name, truth)?;
        self.frames.flush()?;
        self.labels.flush()
    }

    /// Appends force samples.
    pub fn add_force(&mut self, samples: &[ForceSample]) -> std::io::Result<()> {
        if let Some(f) = self.force.as_mut() {
            for s in samples {
                write!(f, "{:.6}", s.timestamp_s)?;
                for v in s.values {
                    write!(f, ",{v:.6}")?;
                }
                writeln!(f)?;
            }
            f.flush()?;
        }
        Ok(())
    }

    /// Writes `session.json` (pretty JSON of `description`, with format and version added).
    pub fn finish(self, mut description: serde_json::Value) -> std::io::Result<()> {
        if let Some(obj) = description.as_object_mut() {
            obj.insert("format".into(), SESSION_FORMAT.into());
            obj.insert("version".into(), SESSION_VERSION.into());
        }
        let text = serde_json::to_string_pretty(&description).map_err(std::io::Error::other)?;
        write_atomically(&self.dir.join("session.json"), &(text + "\n"))
    }
}

/// A table appended to while a recording runs: every line is written and flushed as it comes
/// (a killed process leaves every completed line readable), and the file is `fsync`ed at
/// intervals (a power cut loses at most the last interval).
pub struct AppendLog {
    out: BufWriter<File>,
    path: PathBuf,
    every: std::time::Duration,
    last_sync: std::time::Instant,
    lines: usize,
}

impl AppendLog {
    /// Opens `path` with its `header` line. New: creates it. `resume`: keeps its complete
    /// lines (cutting off an unfinished last line) and checks the header; returns them too.
    pub fn open(
        path: &Path,
        header: &str,
        resume: bool,
        sync_every: std::time::Duration,
    ) -> std::io::Result<(Self, String)> {
        let err =
            |e: std::io::Error| std::io::Error::new(e.kind(), format!("{}: {e}", path.display()));
        let mut kept = String::new();
        let file = if resume && path.exists() {
            let text = crate::read::text_of_file(path).map_err(err)?;
            let (complete, _) = crate::table::complete_lines(&text);
            let first = complete.lines().next().unwrap_or("");
            if !complete.is_empty() && first != header {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::InvalidData,
                    format!(
                        "{}: header {first:?} differs from {header:?}: resume with the same settings",
                        path.display()
                    ),
                ));
            }
            kept = complete.to_string();
            let f = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .open(path)
                .map_err(err)?;
            f.set_len(kept.len() as u64).map_err(err)?;
            let mut f = std::fs::OpenOptions::new()
                .append(true)
                .open(path)
                .map_err(err)?;
            if kept.is_empty() {
                writeln!(f, "{header}").map_err(err)?;
            }
            f
        } else {
            let mut f = File::create(path).map_err(err)?;
            writeln!(f, "{header}").map_err(err)?;
            f
        };
        let lines = kept.lines().count().saturating_sub(1);
        Ok((
            Self {
                out: BufWriter::new(file),
                path: path.to_path_buf(),
                every: sync_every,
                last_sync: std::time::Instant::now(),
                lines,
            },
            kept,
        ))
    }

    /// Appends one line (without its line end) and flushes it; syncs when the interval is up.
    pub fn line(&mut self, s: &str) -> std::io::Result<()> {
        let r = (|| {
            self.out.write_all(s.as_bytes())?;
            self.out.write_all(b"\n")?;
            self.out.flush()
        })();
        r.map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", self.path.display())))?;
        self.lines += 1;
        if self.last_sync.elapsed() >= self.every {
            self.sync()?;
        }
        Ok(())
    }

    /// Forces written lines to disk.
    pub fn sync(&mut self) -> std::io::Result<()> {
        self.out.flush()?;
        self.out
            .get_ref()
            .sync_data()
            .map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", self.path.display())))?;
        self.last_sync = std::time::Instant::now();
        Ok(())
    }

    /// Data lines in the file (header not counted).
    pub fn lines(&self) -> usize {
        self.lines
    }
}

/// Checks that `dir` can take a recording: writes and removes a probe of `bytes` bytes, so
/// an unwritable folder or a full disk is reported before anything is recorded.
pub fn probe_writable(dir: &Path, bytes: usize) -> std::io::Result<()> {
    probe_file(&dir.join(".visuotact-probe"), bytes)
}

fn probe_file(path: &Path, bytes: usize) -> std::io::Result<()> {
    let explain = |e: std::io::Error| {
        let why = if e.raw_os_error() == Some(28) {
            "the disk is full".to_string()
        } else {
            e.to_string()
        };
        std::io::Error::new(
            e.kind(),
            format!("cannot record into {}: {why}", path.display()),
        )
    };
    let mut f = File::create(path).map_err(explain)?;
    let written = f.write_all(&vec![0u8; bytes]).and_then(|()| f.sync_all());
    drop(f);
    // Removed whether the write worked or not: a failed probe leaves nothing behind.
    let removed = if path.is_file() {
        std::fs::remove_file(path)
    } else {
        Ok(())
    };
    written.map_err(explain)?;
    removed.map_err(explain)
}

/// Writes `text` to `path` as one [`crate::output::OutputFile`]: a failure never leaves a
/// half-written file over a good one, nor writes through a link. Creates the parent folder;
/// errors name the file.
pub fn write_atomically(path: &Path, text: &str) -> std::io::Result<()> {
    crate::output::write_whole(path, text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A session is a closed world: a `frames.csv` row naming a file outside `frames/` (a
    /// folder, `..`, an absolute path, a link out of the session) or stamped NaN is an error
    /// naming the row; plain names and links inside the session read.
    #[test]
    fn frame_index_refuses_paths_leaving_the_session() {
        let root = std::env::temp_dir().join(format!("vt-closed-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let dir = root.join("s");
        std::fs::create_dir_all(dir.join("frames")).unwrap();
        std::fs::write(root.join("secret.png"), b"x").unwrap();
        std::fs::write(dir.join("frames").join("a.png"), b"x").unwrap();
        std::os::unix::fs::symlink(root.join("secret.png"), dir.join("frames").join("out.png"))
            .unwrap();
        std::os::unix::fs::symlink(dir.join("frames").join("a.png"), dir.join("frames/in.png"))
            .unwrap();
        let header = "frame,index,timestamp_s,kind\n";
        let write = |row: &str| {
            std::fs::write(
                dir.join("frames.csv"),
                format!("{header}a.png,0,0,touch\n{row}\n"),
            )
            .unwrap()
        };
        for (row, why) in [
            ("../../secret.png,1,0.1,touch", "plain file name"),
            ("/etc/passwd,1,0.1,touch", "plain file name"),
            ("sub/a.png,1,0.1,touch", "plain file name"),
            ("..,1,0.1,touch", "plain file name"),
            ("out.png,1,0.1,touch", "outside the session"),
            ("in.png,1,nan,touch", "not a finite"),
        ] {
            write(row);
            let e = frame_index(&dir, &mut Vec::new()).unwrap_err();
            assert_eq!(e.line, Some(3), "{row}: {e}");
            assert!(e.to_string().contains(why), "{row}: {e}");
        }
        write("in.png,1,0.1,touch");
        let mut notes = Vec::new();
        let frames = frame_index(&dir, &mut notes).unwrap();
        assert_eq!(frames.len(), 2);
        assert_eq!(frames[1].name, "in.png");
        assert!(notes.is_empty(), "{notes:?}");
        // A row a recorder was killed in the middle of is left out and said.
        let text = std::fs::read_to_string(dir.join("frames.csv")).unwrap();
        std::fs::write(dir.join("frames.csv"), format!("{text}in2.png,2,0.")).unwrap();
        assert_eq!(frame_index(&dir, &mut notes).unwrap().len(), 2);
        assert!(
            notes[0].ends_with("frames.csv: an unfinished last line (no line end) was left out"),
            "{notes:?}"
        );
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn append_logs_resume_after_a_partial_line() {
        let dir = std::env::temp_dir().join(format!("vt-append-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("t.csv");
        let every = std::time::Duration::from_secs(1);
        let (mut log, _) = AppendLog::open(&p, "a,b", false, every).unwrap();
        log.line("1,2").unwrap();
        log.line("3,4").unwrap();
        drop(log);
        // A writer killed mid-line.
        std::fs::OpenOptions::new()
            .append(true)
            .open(&p)
            .unwrap()
            .write_all(b"5,")
            .unwrap();
        let (mut log, kept) = AppendLog::open(&p, "a,b", true, every).unwrap();
        assert_eq!((kept.as_str(), log.lines()), ("a,b\n1,2\n3,4\n", 2));
        log.line("5,6").unwrap();
        log.sync().unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "a,b\n1,2\n3,4\n5,6\n");
        assert!(AppendLog::open(&p, "a,c", true, every).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn full_disks_and_unwritable_places_are_reported() {
        let e = probe_file(Path::new("/dev/full"), 4096).unwrap_err();
        assert!(e.to_string().contains("the disk is full"), "{e}");
        let e = probe_writable(Path::new("/proc/version"), 16).unwrap_err();
        assert!(e.to_string().contains("cannot record into"), "{e}");
    }
}

/// One row of a session's `frames.csv`.
#[derive(Clone, Debug, PartialEq)]
pub struct IndexedFrame {
    /// The frame's name (its PNG under `frames/`, or `reference/` for a reference frame).
    pub name: String,
    /// Its time on the session clock, s.
    pub timestamp_s: f64,
    /// A no-contact reference frame (`kind` = `reference`).
    pub reference: bool,
}

/// The first and last of `frames`' times, seconds on the recorder's clock (infinities, the
/// wrong way round, for none).
pub fn frames_span_s(frames: &[IndexedFrame]) -> (f64, f64) {
    frames
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), f| {
            (lo.min(f.timestamp_s), hi.max(f.timestamp_s))
        })
}

/// A session's frames in recorded order, from its `frames.csv`; an unfinished last line left
/// out (a recorder killed mid-row) is said in `notes`.
pub fn frame_index(dir: &Path, notes: &mut Vec<String>) -> Result<Vec<IndexedFrame>, TableError> {
    let path = dir.join("frames.csv");
    let t = KeyedTable::read_noting(&path, &["kind"], notes)?;
    let ts = t
        .column("timestamp_s")
        .ok_or_else(|| TableError::new(&path, Some(1), "no timestamp_s column".into()))?;
    let mut out = Vec::with_capacity(t.keys.len());
    for (k, ((name, row), text)) in t.keys.iter().zip(&t.rows).zip(&t.text).enumerate() {
        let line = Some(k + 2);
        let reference = text.first().is_some_and(|c| c == "reference");
        let folder = if reference { "reference" } else { "frames" };
        inside_session(dir, folder, name)
            .map_err(|why| TableError::new(&path, line, format!("frame {name:?}: {why}")))?;
        if !row[ts].is_finite() {
            return Err(TableError::new(
                &path,
                line,
                format!("frame {name:?}: timestamp_s is not a finite number of seconds"),
            ));
        }
        out.push(IndexedFrame {
            name: name.clone(),
            timestamp_s: row[ts],
            reference,
        });
    }
    Ok(out)
}

/// Checks that frame `name` of a session names a file of `dir/folder` itself: one plain file
/// name (no folder, no `..`, not absolute), and, when it is a link, one that stays inside the
/// session. A session is a closed world: nothing it lists may make a reader open a file
/// outside it.
fn inside_session(dir: &Path, folder: &str, name: &str) -> Result<(), String> {
    let mut parts = Path::new(name).components();
    let plain = matches!(
        (parts.next(), parts.next()),
        (Some(std::path::Component::Normal(_)), None)
    );
    if !plain || name.contains('\\') {
        return Err(format!(
            "expected a plain file name inside the session's {folder}/ (no folder, no `..`, \
             not absolute)"
        ));
    }
    let file = dir.join(folder).join(name);
    let is_link = std::fs::symlink_metadata(&file).is_ok_and(|m| m.file_type().is_symlink());
    if is_link {
        let (Ok(target), Ok(root)) = (file.canonicalize(), dir.canonicalize()) else {
            return Err("a link that does not resolve".into());
        };
        if !target.starts_with(&root) {
            return Err(format!(
                "a link to {} outside the session",
                target.display()
            ));
        }
    }
    Ok(())
}

/// What a session's `session.json` says, as the tools that read sessions use it. Every field
/// is optional — `simulate` and `record` write different sets, and older sessions lack some —
/// but one that is there has the right type and a possible value.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SessionDescription {
    /// The camera's frame rate, frames per second.
    pub fps: Option<f64>,
    /// The frame source `record` was given (`sim:iats`, a folder, a camera).
    pub source: Option<String>,
    /// The force source (`udp:ADDR`, `csv:PATH`).
    pub force: Option<String>,
    /// The sensor file the recording's estimator was built from.
    pub sensor_file: Option<PathBuf>,
    /// The model file the recording's estimator was built from.
    pub model_file: Option<PathBuf>,
    /// Whether `record` kept every frame in `frames/`.
    pub frames_saved: Option<bool>,
    /// Whether the recording did all it was asked.
    pub complete: Option<bool>,
    /// Frames after the references.
    pub frames: Option<u64>,
    /// The session clock's zero as UNIX time, s.
    pub started_unix_s: Option<f64>,
    /// The whole object, for fields this struct does not name.
    pub raw: serde_json::Map<String, serde_json::Value>,
}

/// Why a `session.json` does not read.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{source_name}: {why}")]
pub struct DescriptionError {
    /// The file (or what the text came from).
    pub source_name: String,
    /// What is wrong with it.
    pub why: String,
}

impl SessionDescription {
    /// Parses a description's text; `source` names it in errors.
    pub fn from_json(text: &str, source: &str) -> Result<Self, DescriptionError> {
        let bad = |why: String| DescriptionError {
            source_name: source.to_string(),
            why,
        };
        let raw = match serde_json::from_str(text) {
            Ok(serde_json::Value::Object(m)) => m,
            Ok(_) => return Err(bad("expected a JSON object".into())),
            Err(e) => return Err(bad(format!("not a session description: {e}"))),
        };
        if let Some(f) = raw.get("format") {
            if f != SESSION_FORMAT {
                return Err(bad(format!("format is {f}, expected {SESSION_FORMAT:?}")));
            }
        }
        let text_of = |k: &str| match raw.get(k) {
            None | Some(serde_json::Value::Null) => Ok(None),
            Some(serde_json::Value::String(v)) => Ok(Some(v.clone())),
            Some(v) => Err(bad(format!("{k} is {v}, expected a string"))),
        };
        let bool_of = |k: &str| match raw.get(k) {
            None | Some(serde_json::Value::Null) => Ok(None),
            Some(serde_json::Value::Bool(v)) => Ok(Some(*v)),
            Some(v) => Err(bad(format!("{k} is {v}, expected true or false"))),
        };
        let number_of = |k: &str, ok: &dyn Fn(f64) -> bool, expected: &str| match raw.get(k) {
            None | Some(serde_json::Value::Null) => Ok(None),
            Some(v) => match v.as_f64().filter(|x| ok(*x)) {
                Some(x) => Ok(Some(x)),
                None => Err(bad(format!("{k} is {v}, expected {expected}"))),
            },
        };
        let frames = match raw.get("frames") {
            None | Some(serde_json::Value::Null) => None,
            Some(v) => Some(
                v.as_u64()
                    .ok_or_else(|| bad(format!("frames is {v}, expected a count")))?,
            ),
        };
        Ok(Self {
            fps: number_of(
                "fps",
                &|x| x.is_finite() && x > 0.0 && x <= 1e4,
                "a frame rate in (0, 10000]",
            )?,
            source: text_of("source")?,
            force: text_of("force")?,
            sensor_file: text_of("sensor_file")?.map(PathBuf::from),
            model_file: text_of("model_file")?.map(PathBuf::from),
            frames_saved: bool_of("frames_saved")?,
            complete: bool_of("complete")?,
            frames,
            started_unix_s: number_of(
                "started_unix_s",
                &|x| x.is_finite() && (0.0..=crate::force::PLAUSIBLE_TIME_S).contains(&x),
                "a UNIX time in seconds",
            )?,
            raw,
        })
    }

    /// The description of the session in `dir`: `Ok(None)` when it has no `session.json`.
    pub fn read(dir: &Path) -> Result<Option<Self>, DescriptionError> {
        let path = dir.join("session.json");
        if !path.exists() {
            return Ok(None);
        }
        let name = path.display().to_string();
        let text = crate::read::text_of_file(&path).map_err(|e| DescriptionError {
            source_name: name.clone(),
            why: e.to_string(),
        })?;
        Self::from_json(&text, &name).map(Some)
    }

    /// A line for an export's notes when the session is not whole: `record` stopped before it
    /// did all it was asked (killed, a full disk, a source that failed).
    pub fn incomplete_note(&self) -> Option<String> {
        (self.complete == Some(false)).then(|| {
            format!(
                "session.json says the recording did not complete ({} frames recorded)",
                self.frames
                    .map_or_else(|| "unknown".into(), |n| n.to_string())
            )
        })
    }
}

#[cfg(test)]
mod description_tests {
    use super::*;

    #[test]
    fn a_failed_atomic_write_leaves_neither_a_part_nor_a_torn_file() {
        let d = std::env::temp_dir().join(format!("vt-atomic-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(d.join("busy").join("inside")).unwrap();
        // The target is a folder: the rename fails after the temporary was written.
        let e = write_atomically(&d.join("busy"), "text").unwrap_err();
        assert!(e.to_string().contains("busy"), "{e}");
        let left: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(left, vec![std::ffi::OsString::from("busy")]);
        // Two targets differing only in extension do not share a temporary.
        write_atomically(&d.join("a.json"), "1").unwrap();
        write_atomically(&d.join("a.csv"), "2").unwrap();
        assert_eq!(std::fs::read_to_string(d.join("a.json")).unwrap(), "1");
        assert_eq!(std::fs::read_to_string(d.join("a.csv")).unwrap(), "2");
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn descriptions_read_typed_fields_and_refuse_wrong_ones_by_name() {
        let d = SessionDescription::from_json(
            r#"{"format":"visuotact-session","fps":25,"source":"sim:iats","sensor_file":"s.json",
                "model_file":null,"frames_saved":true,"complete":false,"frames":12,
                "started_unix_s":1.7e9,"seed":3}"#,
            "session.json",
        )
        .unwrap();
        assert_eq!(d.fps, Some(25.0));
        assert_eq!(d.sensor_file, Some(PathBuf::from("s.json")));
        assert_eq!((&d.model_file, d.frames_saved), (&None, Some(true)));
        assert_eq!((d.complete, d.frames), (Some(false), Some(12)));
        assert_eq!(d.raw["seed"], 3);
        assert!(d.incomplete_note().unwrap().contains("12 frames"));
        assert_eq!(SessionDescription::from_json("{}", "s").unwrap().fps, None);
        for (text, says) in [
            (r#"{"fps":"x""#, "not a session description"),
            ("[1]", "expected a JSON object"),
            (r#"{"format":"other"}"#, "format is"),
            (r#"{"fps":0}"#, "fps is 0"),
            (r#"{"fps":1e300}"#, "fps is"),
            (r#"{"complete":"yes"}"#, "expected true or false"),
            (r#"{"frames":-1}"#, "expected a count"),
            (r#"{"source":7}"#, "expected a string"),
            (r#"{"started_unix_s":-5}"#, "UNIX time"),
        ] {
            let e = SessionDescription::from_json(text, "a/session.json")
                .unwrap_err()
                .to_string();
            assert!(
                e.starts_with("a/session.json: ") && e.contains(says),
                "{text}: {e}"
            );
        }
    }
}
