//! Session folders: what `simulate` writes today and `record` will write later.
//!
//! ```text
//! SESSION/
//!   session.json      what produced it (format, version, sensor, protocol, seed, every setting)
//!   reference/        no-contact frames (PNG), for `calibrate`
//!   frames/           the frames (PNG)
//!   frames.csv        frame,index,timestamp_s,kind   (kind: reference | touch)
//!   labels.csv        frame,<targets with units>     (x_mm,y_mm,depth_mm… or force_n,fx_n…)
//!   truth.csv         frame,marker,x_px,y_px,area_px,fully_in_view  (simulator only)
//!   force.csv         timestamp_s,fx_n,fy_n,fz_n,tx_nm,ty_nm,tz_nm (when a force sensor ran)
//! ```
//!
//! Rows are appended and flushed as frames are written, so a session that stops early is
//! readable up to its last complete row. The format is documented in `docs/session-format.md`.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::force::ForceSample;
use crate::table::format_number;

/// Identifies session descriptions.
pub const SESSION_FORMAT: &str = "visuotact-session";
/// Current session format version.
pub const SESSION_VERSION: u32 = 1;

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
            writeln!(t, "frame,marker,x_px,y_px,area_px,fully_in_view")?;
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

    /// Records a reference frame already written to [`SessionWriter::reference_path`].
    pub fn add_reference(
        &mut self,
        name: &str,
        index: usize,
        timestamp_s: f64,
    ) -> std::io::Result<()> {
        writeln!(
            self.frames,
            "{name},{index},{},reference",
            format_number(timestamp_s)
        )?;
        self.frames.flush()
    }

    /// Records a frame already written to [`SessionWriter::frame_path`], with its labels and
    /// (simulator) per-marker truth `(x_px, y_px, area_px, fully_in_view)`.
    pub fn add_frame(
        &mut self,
        name: &str,
        index: usize,
        timestamp_s: f64,
        labels: &[f64],
        truth: &[(f64, f64, f64, bool)],
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
        if let Some(t) = self.truth.as_mut() {
            for (k, (x, y, a, inside)) in truth.iter().enumerate() {
                writeln!(t, "{name},{k},{x:.6},{y:.6},{a:.4},{}", u8::from(*inside))?;
            }
            t.flush()?;
        }
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
        std::fs::write(self.dir.join("session.json"), text + "\n")
    }
}
