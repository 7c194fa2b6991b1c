//! A recorded or simulated session folder as frame parts, into any [`FrameTarget`] (a ROS 2
//! bag, a Rerun recording): its estimates (`estimates.csv`), the measured force (`force.csv`,
//! each sample at its own time), the markers (`features.csv` with the sensor file's reference
//! positions), marker health and the saved frames (`frames/`, the PNG bytes as they are), all
//! stamped with the session's timestamps plus [`ExportConfig::start_unix_s`]. Values are
//! copied, not recomputed: the output says what the session's tables say.

use std::collections::HashMap;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use visuotact_io::force::ForceTable;
use visuotact_io::session::{frame_index, IndexedFrame, SessionDescription};
use visuotact_io::table::KeyedTable;
use visuotact_vision::calibration::SensorCalibration;

use crate::live::{Health, TargetEstimate};
use crate::output::{ns_from_s, FrameParts, FrameTarget, MarkerPoint, OutputConfig, OutputError};

/// How a session is exported.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ExportConfig {
    /// Namespace, frame id and whether the saved frames go too.
    pub output: OutputConfig,
    /// Sensor file for the marker cloud (default: the one `session.json` names, if it exists).
    pub sensor: Option<PathBuf>,
    /// The session's start as UNIX time, seconds, added to its timestamps (`None`: the
    /// `started_unix_s` of its `session.json`, which `record` writes; without one 0, the stamps
    /// then the session's own seconds).
    pub start_unix_s: Option<f64>,
}

/// The session's per-frame tables, keyed by frame.
struct SessionTables {
    frames: Vec<IndexedFrame>,
    /// Per frame, whether its PNG is in `frames/` (all false when images are not wanted).
    has_png: Vec<bool>,
    estimates: Option<(KeyedTable, HashMap<String, usize>)>,
    features: Option<(KeyedTable, HashMap<String, usize>)>,
    markers: MarkerColumns,
    force: Option<ForceTable>,
}

/// A marker's reference position (pixels) and the columns of its dx and dy.
#[derive(Clone, Copy, Debug)]
struct MarkerColumn {
    x_px: f32,
    y_px: f32,
    dxy: Option<(usize, usize)>,
}

/// Where a feature row holds each marker's displacement and the health counts, with the
/// markers' reference positions: the map from `features.csv` rows to the marker cloud.
#[derive(Clone, Debug, Default)]
pub struct MarkerColumns {
    markers: Vec<MarkerColumn>,
    n_found: Option<usize>,
    n_markers: Option<usize>,
    mm_per_px: Option<f64>,
}

impl MarkerColumns {
    /// The map for `columns` (a feature table's value columns) and the sensor's markers.
    pub fn new(cal: &SensorCalibration, columns: &[String]) -> Self {
        let col = |n: &str| columns.iter().position(|c| c == n);
        Self {
            markers: cal
                .markers
                .iter()
                .map(|m| {
                    let dxy = col(&format!("m{:03}_dx_px", m.id))
                        .zip(col(&format!("m{:03}_dy_px", m.id)));
                    MarkerColumn {
                        x_px: m.x_px as f32,
                        y_px: m.y_px as f32,
                        dxy,
                    }
                })
                .collect(),
            n_found: col("n_found"),
            n_markers: col("n_markers"),
            mm_per_px: cal.mm_per_px(),
        }
    }

    /// The sensor's scale (`calibrate --pitch-mm`), if it has one.
    pub fn mm_per_px(&self) -> Option<f64> {
        self.mm_per_px
    }

    /// Whether there are markers to publish.
    pub fn is_empty(&self) -> bool {
        self.markers.is_empty()
    }

    /// A feature row's marker cloud into `out`, and its health (`None`: the row has no
    /// counts).
    pub fn cloud_from_row(&self, row: &[f64], out: &mut Vec<MarkerPoint>) -> Option<Health> {
        out.clear();
        for &MarkerColumn { x_px, y_px, dxy } in &self.markers {
            let (dx, dy) = dxy.map_or((f64::NAN, f64::NAN), |(i, j)| (row[i], row[j]));
            let found = dx.is_finite() && dy.is_finite();
            out.push(MarkerPoint {
                x_px,
                y_px,
                dx_px: dx as f32,
                dy_px: dy as f32,
                found,
            });
        }
        let count = |i: Option<usize>| {
            i.map(|i| row[i])
                .filter(|v| v.is_finite() && *v >= 0.0)
                .map(|v| v as usize)
        };
        let (found, total) = (count(self.n_found)?, count(self.n_markers)?);
        Some(Health {
            ok: found,
            lost: total.saturating_sub(found),
            ..Health::default()
        })
    }
}

/// An estimates row as targets: every finite value whose column is not a spread (`_std`).
pub fn targets_from_row(columns: &[String], row: &[f64]) -> Vec<TargetEstimate> {
    columns
        .iter()
        .zip(row)
        .filter(|(c, v)| !c.ends_with("_std") && v.is_finite())
        .map(|(c, &value)| TargetEstimate {
            name: c.clone(),
            value,
            std: None,
        })
        .collect()
}

fn keyed(t: KeyedTable) -> (KeyedTable, HashMap<String, usize>) {
    let index = t
        .keys
        .iter()
        .enumerate()
        .map(|(i, k)| (k.clone(), i))
        .collect();
    (t, index)
}

fn optional_table(
    session: &Path,
    name: &str,
    text: &[&str],
    notes: &mut Vec<String>,
) -> Result<Option<KeyedTable>, OutputError> {
    let p = session.join(name);
    if !p.is_file() {
        notes.push(format!("no {name}"));
        return Ok(None);
    }
    Ok(Some(KeyedTable::read_noting(&p, text, notes)?))
}

/// The session's description (`None`: it has no `session.json`); one that does not read is
/// an error naming it.
fn described(session: &Path) -> Result<Option<SessionDescription>, OutputError> {
    SessionDescription::read(session).map_err(|e| OutputError::Config(e.to_string()))
}

/// The sensor file the export was given or the session names, else the calibration held by
/// the model the session was recorded with.
fn sensor_of(session: &Path, cfg: &ExportConfig) -> Result<Option<SensorCalibration>, OutputError> {
    let file =
        |p: &Path| visuotact_io::read::text_of_file(p).map_err(|e| OutputError::Io(p.into(), e));
    let sensor_file = |p: &Path| {
        SensorCalibration::from_json(&file(p)?, &p.display().to_string())
            .map(Some)
            .map_err(|e| OutputError::Config(e.to_string()))
    };
    if let Some(p) = &cfg.sensor {
        return sensor_file(p);
    }
    let Some(d) = described(session)? else {
        return Ok(None);
    };
    if let Some(p) = d.sensor_file.filter(|p| p.is_file()) {
        return sensor_file(&p);
    }
    let Some(p) = d.model_file.filter(|p| p.is_file()) else {
        return Ok(None);
    };
    let model = visuotact_nn::model::Model::from_json(&file(&p)?, &p.display().to_string())
        .map_err(|e| OutputError::Config(e.to_string()))?;
    crate::sensor_of_model(&model).map_err(|e| OutputError::Config(format!("{}: {e}", p.display())))
}

fn read_tables(
    session: &Path,
    cfg: &ExportConfig,
    notes: &mut Vec<String>,
) -> Result<SessionTables, OutputError> {
    let frames = frame_index(session, notes)?;
    if frames.is_empty() {
        return Err(OutputError::NoFrames(session.join("frames.csv")));
    }
    let estimates = optional_table(session, "estimates.csv", &["flags"], notes)?.map(keyed);
    let features = optional_table(session, "features.csv", &["flags"], notes)?.map(keyed);
    let force_path = session.join("force.csv");
    let force = if force_path.is_file() {
        // Wrenches are stamped on the frames' clock, not the sender's.
        let mut f = ForceTable::read_noting(&force_path, notes)?;
        f.onto_recorder_clock();
        f.check_meets_frames(&force_path, visuotact_io::session::frames_span_s(&frames))?;
        Some(f)
    } else {
        notes.push("no force.csv".into());
        None
    };
    let has_png = frames_with_png(session, &frames, cfg.output.images, notes);
    let mut markers = MarkerColumns::default();
    if let Some((f, _)) = &features {
        match sensor_of(session, cfg)? {
            Some(cal) => markers = MarkerColumns::new(&cal, &f.columns),
            None => notes.push("no sensor file or model with one: no marker cloud".into()),
        }
    }
    Ok(SessionTables {
        frames,
        has_png,
        estimates,
        features,
        markers,
        force,
    })
}

/// Which touch frames have their PNG in `frames/`, when images are wanted; what is missing is
/// said in `notes` (no `frames/`: recorded without `--save-frames`; some frames missing: how
/// many, written without their image). Reference frames are never exported as images.
fn frames_with_png(
    session: &Path,
    frames: &[IndexedFrame],
    images: bool,
    notes: &mut Vec<String>,
) -> Vec<bool> {
    if !images {
        return vec![false; frames.len()];
    }
    let dir = session.join("frames");
    if !dir.is_dir() {
        notes.push("no frames/ (recorded without --save-frames): no images".into());
        return vec![false; frames.len()];
    }
    let has: Vec<bool> = frames
        .iter()
        .map(|f| !f.reference && dir.join(&f.name).is_file())
        .collect();
    let touch = frames.iter().filter(|f| !f.reference).count();
    let missing = touch - has.iter().filter(|&&h| h).count();
    if missing > 0 {
        notes.push(format!(
            "{missing} of the {touch} frames listed in frames.csv are not in frames/: written without their image"
        ));
    }
    has
}

fn targets_of(est: &(KeyedTable, HashMap<String, usize>), frame: &str) -> Vec<TargetEstimate> {
    let (t, index) = est;
    index
        .get(frame)
        .map(|&row| targets_from_row(&t.columns, &t.rows[row]))
        .unwrap_or_default()
}

/// A frame's marker cloud and health from the feature table.
fn markers_of(t: &SessionTables, frame: &str, out: &mut Vec<MarkerPoint>) -> Option<Health> {
    let (f, index) = t.features.as_ref()?;
    t.markers.cloud_from_row(&f.rows[*index.get(frame)?], out)
}

/// Writes the force samples stamped before `until_s` (all with `None`), from `next` on.
fn write_force<W: FrameTarget>(
    bag: &mut W,
    (output, start_unix_s): (&OutputConfig, f64),
    force: &ForceTable,
    next: &mut usize,
    until_s: Option<f64>,
) -> Result<(), OutputError> {
    while let Some(&t) = force.timestamp_s.get(*next) {
        if until_s.is_some_and(|u| t > u) {
            break;
        }
        let frame = FrameParts {
            stamp_ns: ns_from_s(start_unix_s + t),
            measured: Some(force.values[*next]),
            ..FrameParts::default()
        };
        bag.write_frame(output, frame)?;
        *next += 1;
    }
    Ok(())
}

/// A session read for export: its tables, its start as UNIX time and what it lacks; written
/// into any [`FrameTarget`] by [`SessionExport::write_to`].
pub struct SessionExport {
    session: PathBuf,
    tables: SessionTables,
    start_unix_s: f64,
    notes: Vec<String>,
}

impl SessionExport {
    /// Reads `session`'s tables (and the sensor file for the markers) under `cfg`.
    pub fn read(session: &Path, cfg: &ExportConfig) -> Result<Self, OutputError> {
        cfg.output.validate()?;
        let description = described(session)?;
        let start_unix_s = cfg.start_unix_s.unwrap_or_else(|| {
            description
                .as_ref()
                .and_then(|d| d.started_unix_s)
                .unwrap_or(0.0)
        });
        if !start_unix_s.is_finite() || start_unix_s < 0.0 {
            return Err(OutputError::Config(format!(
                "start_unix_s {start_unix_s}: expected a UNIX time in seconds, 0 or more"
            )));
        }
        let mut notes: Vec<String> = description
            .and_then(|d| d.incomplete_note())
            .into_iter()
            .collect();
        let tables = read_tables(session, cfg, &mut notes)?;
        Ok(Self {
            session: session.to_path_buf(),
            tables,
            start_unix_s,
            notes,
        })
    }

    /// Frames in the session.
    pub fn frames(&self) -> usize {
        self.tables.frames.len()
    }

    /// Parts of the session that are not there (said, not an error).
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// Writes every frame and force sample into `target`, in time order; `progress(done,
    /// total)` hears of each frame and may stop ([`OutputError::Stopped`]).
    pub fn write_to<W: FrameTarget>(
        &self,
        target: &mut W,
        cfg: &ExportConfig,
        progress: &mut dyn FnMut(usize, usize) -> ControlFlow<()>,
    ) -> Result<(), OutputError> {
        write_session(
            target,
            &self.session,
            cfg,
            (&self.tables, self.start_unix_s),
            progress,
        )
    }
}

/// Writes every frame of `session` (its tables `t`) and the force samples into `bag`.
fn write_session<W: FrameTarget>(
    bag: &mut W,
    session: &Path,
    cfg: &ExportConfig,
    (t, start_unix_s): (&SessionTables, f64),
    progress: &mut dyn FnMut(usize, usize) -> ControlFlow<()>,
) -> Result<(), OutputError> {
    let (mut next_force, mut markers) = (0, Vec::new());
    let total = t.frames.len();
    for (k, f) in t.frames.iter().enumerate() {
        let (frame, time_s) = (&f.name, f.timestamp_s);
        if let Some(force) = &t.force {
            write_force(
                bag,
                (&cfg.output, start_unix_s),
                force,
                &mut next_force,
                Some(time_s),
            )?;
        }
        let targets = t
            .estimates
            .as_ref()
            .map(|e| targets_of(e, frame))
            .unwrap_or_default();
        let health = markers_of(t, frame, &mut markers);
        // A frame there when the export began and gone now is damage, not a note.
        let png_path = session.join("frames").join(frame);
        let png = if t.has_png[k] {
            Some(std::fs::read(&png_path).map_err(|e| OutputError::Io(png_path.clone(), e))?)
        } else {
            None
        };
        let msgs = FrameParts {
            stamp_ns: ns_from_s(start_unix_s + time_s),
            index: Some(k as u64),
            targets: &targets,
            markers: (health.is_some() && !t.markers.is_empty()).then_some(&markers[..]),
            mm_per_px: t.markers.mm_per_px(),
            health: health.as_ref().map(|h| (h, Vec::new())),
            png,
            ..FrameParts::default()
        };
        bag.write_frame(&cfg.output, msgs)?;
        if progress(k + 1, total).is_break() {
            return Err(OutputError::Stopped(k + 1));
        }
    }
    if let Some(force) = &t.force {
        write_force(
            bag,
            (&cfg.output, start_unix_s),
            force,
            &mut next_force,
            None,
        )?;
    }
    Ok(())
}
