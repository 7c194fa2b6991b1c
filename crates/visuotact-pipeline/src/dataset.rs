//! Recorded sessions → one training table: per session its frames' features (the session's
//! `features.csv`, written by `record --sensor`, or extracted from its `frames/` with a sensor
//! calibration) joined on `frame` with labels — from its force record (cleaned by
//! [`visuotact_signal::clean`], resampled onto the frame times with a latency offset) or,
//! without one, from its `labels.csv`. Force samples received over the network carry the
//! sender's clock and the recorder's receive time (`recv_s`); they are put on the recorder's
//! clock by [`ForceTable::onto_recorder_clock`] (the least `recv_s − timestamp_s` seen so far),
//! the one mapping the exports and `record --mcap` use too.
//! `visuotact dataset` writes the result as two tables.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use visuotact_io::force::{ForceTable, AXES};
use visuotact_io::frames::FrameStream;
use visuotact_io::table::{KeyedTable, TableError};
use visuotact_nn::model::is_marker_column;
use visuotact_signal::align::{AlignError, Resampler};
use visuotact_signal::clean::{clean, CleanConfig, CleanError, Cleaned};
use visuotact_vision::calibration::SensorCalibration;
use visuotact_vision::features::is_field_column;

use crate::Estimator;

/// How sessions become a table.
#[derive(Clone, Debug, PartialEq)]
pub struct DatasetConfig {
    /// Latency correction, seconds: a frame at time t is labelled with the force at t + this.
    pub latency_s: f64,
    /// Longest run of missing force samples to interpolate across, seconds; frames inside a
    /// longer gap get no label.
    pub max_gap_s: f64,
    /// How force records are cleaned.
    pub clean: CleanConfig,
}

impl DatasetConfig {
    /// Checks the times: a latency within ±10 s (a camera's or force sensor's delay is
    /// milliseconds; NaN would label nothing), a gap limit from 0 to 10 s.
    pub fn validate(&self) -> Result<(), DatasetError> {
        if !(self.latency_s.is_finite() && self.latency_s.abs() <= 10.0) {
            return Err(DatasetError::Config(format!(
                "latency_s must be within ±10 s, got {}",
                self.latency_s
            )));
        }
        if !(self.max_gap_s.is_finite() && (0.0..=10.0).contains(&self.max_gap_s)) {
            return Err(DatasetError::Config(format!(
                "max_gap_s must be in 0..10 s, got {}",
                self.max_gap_s
            )));
        }
        Ok(())
    }
}

impl Default for DatasetConfig {
    /// No latency correction, gaps up to 50 ms bridged, [`CleanConfig::default`].
    fn default() -> Self {
        Self {
            latency_s: 0.0,
            max_gap_s: 0.05,
            clean: CleanConfig::default(),
        }
    }
}

/// The table: one row per labelled frame of every session.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Dataset {
    /// Each row's frame (`SESSION/frame` when there was more than one session).
    pub keys: Vec<String>,
    /// Feature columns: the markers' features, then the field summary when the sessions have it.
    pub feature_columns: Vec<String>,
    /// Label columns (`force_n, fx_n, fy_n, fz_n` from force records).
    pub label_columns: Vec<String>,
    /// Features per row.
    pub features: Vec<Vec<f64>>,
    /// Labels per row.
    pub labels: Vec<Vec<f64>>,
    /// What was left out or repaired, one line each, naming the session or file.
    pub notes: Vec<String>,
}

/// Why the sessions could not be joined.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    /// A file could not be read.
    #[error("{}: {why}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        why: String,
    },
    /// A table does not read.
    #[error(transparent)]
    Table(#[from] TableError),
    /// A session lacks what it needs.
    #[error("{}: {what}", path.display())]
    Missing {
        /// The session or file.
        path: PathBuf,
        /// What is missing.
        what: String,
    },
    /// A session's columns differ from the first session's.
    #[error("{}: its {which} columns differ from the first session's{hint}", session.display())]
    Columns {
        /// The session.
        session: PathBuf,
        /// `feature` or `label`.
        which: &'static str,
        /// What to do about it.
        hint: &'static str,
    },
    /// A setting is out of range.
    #[error("{0}")]
    Config(String),
    /// A force record could not be cleaned.
    #[error("{}: {source}", path.display())]
    Force {
        /// The force record.
        path: PathBuf,
        /// Why.
        source: CleanError,
    },
    /// A force record's times do not map onto the frames'.
    #[error("{}: {source}", path.display())]
    Align {
        /// The force record.
        path: PathBuf,
        /// Why.
        source: AlignError,
    },
    /// The sensor calibration cannot extract features.
    #[error("features: {0}")]
    Features(#[from] crate::PipelineError),
}

/// One session's columns and rows.
struct Session {
    feature_columns: Vec<String>,
    label_columns: Vec<String>,
    rows: Vec<(String, Vec<f64>, Vec<f64>)>,
}

/// Joins `sessions` into one table; `sensor` extracts the features of sessions without a
/// `features.csv`.
pub fn build(
    sessions: &[PathBuf],
    sensor: Option<&SensorCalibration>,
    cfg: &DatasetConfig,
) -> Result<Dataset, DatasetError> {
    cfg.validate()?;
    let many = sessions.len() > 1;
    let mut out = Dataset::default();
    for (i, s) in sessions.iter().enumerate() {
        let one = session(s, sensor, cfg, &mut out.notes)?;
        if i == 0 {
            out.feature_columns = one.feature_columns;
            out.label_columns = one.label_columns;
        } else if one.feature_columns != out.feature_columns {
            return Err(DatasetError::Columns {
                session: s.clone(),
                which: "feature",
                hint: "; use one sensor file",
            });
        } else if one.label_columns != out.label_columns {
            return Err(DatasetError::Columns {
                session: s.clone(),
                which: "label",
                hint: "",
            });
        }
        let prefix = s
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        for (k, f, l) in one.rows {
            out.keys
                .push(if many { format!("{prefix}/{k}") } else { k });
            out.features.push(f);
            out.labels.push(l);
        }
    }
    Ok(out)
}

/// Touch frames of a session and their timestamps, from frames.csv.
fn touch_frames(
    session: &Path,
    notes: &mut Vec<String>,
) -> Result<Vec<(String, f64)>, DatasetError> {
    Ok(visuotact_io::session::frame_index(session, notes)?
        .into_iter()
        .filter(|f| !f.reference)
        .map(|f| (f.name, f.timestamp_s))
        .collect())
}

/// Column names and each frame's values.
type Columns = (Vec<String>, HashMap<String, Vec<f64>>);

fn session(
    s: &Path,
    sensor: Option<&SensorCalibration>,
    cfg: &DatasetConfig,
    notes: &mut Vec<String>,
) -> Result<Session, DatasetError> {
    let frames = touch_frames(s, notes)?;
    let (feature_columns, features) = if s.join("features.csv").exists() {
        features_from_table(&s.join("features.csv"), notes)?
    } else {
        let sensor = sensor.ok_or_else(|| DatasetError::Missing {
            path: s.to_path_buf(),
            what: "no features.csv; give a sensor file to extract features from its frames"
                .to_string(),
        })?;
        extract(sensor, &s.join("frames"), notes)?
    };
    let (label_columns, labels) = if s.join("force.csv").exists() {
        labels_from_force(&s.join("force.csv"), &frames, cfg, notes)?
    } else if s.join("labels.csv").exists() {
        let t = KeyedTable::read_noting(&s.join("labels.csv"), &[], notes)?;
        let m = t.keys.iter().cloned().zip(t.rows.iter().cloned()).collect();
        (t.columns.clone(), m)
    } else {
        return Err(DatasetError::Missing {
            path: s.to_path_buf(),
            what: "neither force.csv nor labels.csv: nothing to label frames with".to_string(),
        });
    };
    let mut rows = Vec::new();
    let mut unlabelled = 0;
    for (k, _) in &frames {
        match (features.get(k), labels.get(k)) {
            (Some(f), Some(l)) => rows.push((k.clone(), f.clone(), l.clone())),
            _ => unlabelled += 1,
        }
    }
    if unlabelled > 0 {
        notes.push(format!(
            "{}: {unlabelled} frames without both features and labels left out",
            s.display()
        ));
    }
    Ok(Session {
        feature_columns,
        label_columns,
        rows,
    })
}

/// The markers' features and the field summary of a feature table.
fn features_from_table(path: &Path, notes: &mut Vec<String>) -> Result<Columns, DatasetError> {
    let t = KeyedTable::read_noting(path, &["flags"], notes)?;
    let idx: Vec<usize> = (0..t.columns.len())
        .filter(|&i| is_marker_column(&t.columns[i]) || is_field_column(&t.columns[i]))
        .collect();
    Ok((
        idx.iter().map(|&i| t.columns[i].clone()).collect(),
        t.keys
            .iter()
            .zip(&t.rows)
            .map(|(k, r)| (k.clone(), idx.iter().map(|&i| r[i]).collect()))
            .collect(),
    ))
}

/// Cleans a force table ([`clean`]): sorted, repeats dropped (counted), gaps filled on a
/// uniform grid at the median sample interval, low-passed and debiased, bias detected on the
/// force axes it has. Returns the cleaned record and the repeats dropped.
pub fn clean_table(
    table: &mut ForceTable,
    cfg: &CleanConfig,
) -> Result<(Cleaned, usize), CleanError> {
    let duplicates = table.sort_dedup();
    let channels: Vec<Vec<f64>> = (0..6).map(|k| table.axis(k)).collect();
    let detect: Vec<usize> = (0..3).filter(|&k| table.present[k]).collect();
    Ok((
        clean(&table.timestamp_s, &channels, &detect, cfg)?,
        duplicates,
    ))
}

/// Force labels of `frames` from the force record at `path`.
fn labels_from_force(
    path: &Path,
    frames: &[(String, f64)],
    cfg: &DatasetConfig,
    notes: &mut Vec<String>,
) -> Result<Columns, DatasetError> {
    let mut table = ForceTable::read_noting(path, notes)?;
    // Only the force axes the record has: an absent one is not a measured zero.
    let axes: Vec<usize> = (0..3).filter(|&k| table.present[k]).collect();
    if axes.is_empty() {
        return Err(DatasetError::Missing {
            path: path.to_path_buf(),
            what: "no force column (fx_n, fy_n or fz_n)".into(),
        });
    }
    if axes.len() < 3 {
        let names: Vec<&str> = axes.iter().map(|&k| AXES[k]).collect();
        notes.push(format!(
            "{}: only {} recorded: force_n is their magnitude, the other axes are no labels",
            path.display(),
            names.join(", ")
        ));
    }
    // Sender clock → recorder clock, as the exports and `record --mcap` map it.
    table.onto_recorder_clock();
    let (c, _) = clean_table(&mut table, &cfg.clean).map_err(|source| DatasetError::Force {
        path: path.to_path_buf(),
        source,
    })?;
    let times: Vec<f64> = frames.iter().map(|(_, t)| *t).collect();
    let rs = Resampler::new(
        &c.t,
        &times,
        cfg.latency_s,
        cfg.max_gap_s.max(1.5 / c.rate_hz),
    )
    .map_err(|source| DatasetError::Align {
        path: path.to_path_buf(),
        source,
    })?;
    let magnitude: Vec<f64> = (0..c.t.len())
        .map(|i| {
            axes.iter()
                .map(|&k| c.clean[k][i].powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .collect();
    let cols: Vec<Vec<Option<f64>>> = std::iter::once(rs.apply(&magnitude))
        .chain(axes.iter().map(|&k| rs.apply(&c.clean[k])))
        .collect();
    if rs.missing() > 0 {
        notes.push(format!(
            "{}: {} frames outside the force record or in a gap get no label",
            path.display(),
            rs.missing()
        ));
    }
    let mut m = HashMap::new();
    for (i, (k, _)) in frames.iter().enumerate() {
        if let Some(row) = cols.iter().map(|c| c[i]).collect::<Option<Vec<f64>>>() {
            m.insert(k.clone(), row);
        }
    }
    Ok((
        std::iter::once("force_n")
            .chain(axes.iter().map(|&k| AXES[k]))
            .map(String::from)
            .collect(),
        m,
    ))
}

/// Features of every frame in `dir`, extracted with `sensor` (by the pipeline's
/// [`Estimator`], as `extract` and `record` do).
fn extract(
    sensor: &SensorCalibration,
    dir: &Path,
    notes: &mut Vec<String>,
) -> Result<Columns, DatasetError> {
    let mut est =
        Estimator::new(Some(sensor.clone()), None).map_err(|e| DatasetError::Missing {
            path: dir.to_path_buf(),
            what: e.to_string(),
        })?;
    let mm = est.mm_columns().clone();
    let mut cols = est.feature_columns();
    cols.extend(mm.names().iter().cloned());
    let mut out = HashMap::new();
    let stream = FrameStream::open(&[dir.to_path_buf()], 25.0).map_err(|e| DatasetError::Read {
        path: dir.to_path_buf(),
        why: e.to_string(),
    })?;
    let mut markerless = 0usize;
    for item in stream {
        match item {
            Ok(frame) => match est.features(&frame.image) {
                // No marker of the sensor found: a row of empty cells trains nothing.
                Ok(f) if f.found == 0 => markerless += 1,
                Ok(f) => {
                    let mut row = f.values.clone();
                    mm.values_into(&f.values, &mut row);
                    out.insert(frame.id, row);
                }
                Err(e) => notes.push(format!("frame {}: {e}; skipped", frame.id)),
            },
            Err(e) => notes.push(format!("{e}; skipped")),
        }
    }
    if out.is_empty() && markerless > 0 {
        return Err(DatasetError::Missing {
            path: dir.to_path_buf(),
            what: format!(
                "the sensor file finds none of its markers in any of the {markerless} frames: \
                 expected the sensor calibrated on this session's camera"
            ),
        });
    }
    if markerless > 0 {
        notes.push(format!(
            "{}: {markerless} frames with none of the sensor's markers; skipped",
            dir.display()
        ));
    }
    Ok((cols, out))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A session folder written by hand: 5 touch frames at 0.5 s steps (and a reference
    /// frame), features with the field summary and a flags column, and a 1 kHz force record
    /// whose fz ramps at 1 N/s from 0 s with no offset.
    fn session_dir(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("visuotact-dataset-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        let mut frames = String::from("frame,timestamp_s,kind\nref.png,0,reference\n");
        let mut feats = String::from("frame,n_found,m000_dx_px,m000_dy_px,field_rms_px,flags\n");
        for k in 0..5 {
            let t = 1.0 + 0.5 * f64::from(k);
            frames.push_str(&format!("f{k}.png,{t},touch\n"));
            feats.push_str(&format!("f{k}.png,1,{k},0.5,{t},\n"));
        }
        std::fs::write(d.join("frames.csv"), frames).unwrap();
        std::fs::write(d.join("features.csv"), feats).unwrap();
        let mut force = String::from("timestamp_s,fx_n,fy_n,fz_n\n");
        for i in 0..5000 {
            let t = f64::from(i) / 1000.0;
            force.push_str(&format!("{t},0,0,{t}\n"));
        }
        std::fs::write(d.join("force.csv"), force).unwrap();
        d
    }

    /// The defaults without bias removal: a test's ramp is its own truth.
    fn no_bias_removal() -> DatasetConfig {
        DatasetConfig {
            clean: CleanConfig {
                bias: visuotact_signal::clean::BiasRemoval::None,
                ..CleanConfig::default()
            },
            ..DatasetConfig::default()
        }
    }

    #[test]
    fn a_force_record_without_some_axes_labels_only_those_it_has() {
        let d = session_dir("axes");
        let mut force = String::from("timestamp_s,fz_n\n");
        for i in 0..5000 {
            let t = f64::from(i) / 1000.0;
            force.push_str(&format!("{t},{t}\n"));
        }
        std::fs::write(d.join("force.csv"), force).unwrap();
        let cfg = no_bias_removal();
        let ds = build(std::slice::from_ref(&d), None, &cfg).unwrap();
        assert_eq!(ds.label_columns, ["force_n", "fz_n"]);
        assert!((ds.labels[2][1] - 2.0).abs() < 1e-3, "{:?}", ds.labels[2]);
        assert!(
            ds.notes.iter().any(|n| n.contains("only fz_n recorded")),
            "{:?}",
            ds.notes
        );
        std::fs::write(d.join("force.csv"), "timestamp_s,tz_nm\n0,1\n").unwrap();
        let e = build(std::slice::from_ref(&d), None, &cfg)
            .unwrap_err()
            .to_string();
        assert!(e.contains("no force column"), "{e}");
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn frames_get_the_force_at_their_time_plus_the_latency() {
        let d = session_dir("latency");
        let cfg = DatasetConfig {
            latency_s: 0.1,
            ..no_bias_removal()
        };
        let ds = build(std::slice::from_ref(&d), None, &cfg).unwrap();
        assert_eq!(ds.keys, ["f0.png", "f1.png", "f2.png", "f3.png", "f4.png"]);
        assert_eq!(
            ds.feature_columns,
            ["m000_dx_px", "m000_dy_px", "field_rms_px"]
        );
        assert_eq!(ds.label_columns, ["force_n", "fx_n", "fy_n", "fz_n"]);
        for (k, l) in ds.labels.iter().enumerate() {
            // A ramp passes the low-pass unchanged away from the record's ends.
            let want = 1.1 + 0.5 * k as f64;
            assert!(
                (l[3] - want).abs() < 1e-3 && (l[0] - want).abs() < 1e-3,
                "{k}: {l:?}"
            );
        }
        assert_eq!(ds.features[2], [2.0, 0.5, 2.0]);
        assert!(ds.notes.is_empty(), "{:?}", ds.notes);
        let _ = std::fs::remove_dir_all(d);
    }

    /// A force sensor stamping its own clock (from 1 000 s) with receive times on the
    /// recorder's, the first packet late: frames get the force of the sample received at their
    /// time less the least delay (2 ms), i.e. the exports' mapping.
    #[test]
    fn a_senders_clock_is_put_on_the_recorders_as_the_exports_put_it() {
        let d = session_dir("sender-clock");
        let mut force = String::from("timestamp_s,fx_n,fy_n,fz_n,recv_s\n");
        for i in 0..5000 {
            let t = f64::from(i) / 1000.0;
            let delay_s = if i == 0 { 0.05 } else { 0.002 };
            force.push_str(&format!("{},0,0,{t},{}\n", 1000.0 + t, t + delay_s));
        }
        std::fs::write(d.join("force.csv"), force).unwrap();
        let cfg = no_bias_removal();
        let ds = build(std::slice::from_ref(&d), None, &cfg).unwrap();
        assert_eq!(ds.keys.len(), 5, "{:?}", ds.notes);
        for (k, l) in ds.labels.iter().enumerate() {
            let want = 1.0 + 0.5 * k as f64 - 0.002;
            assert!((l[3] - want).abs() < 1e-3, "{k}: {l:?}");
        }
        let _ = std::fs::remove_dir_all(d);
    }

    #[test]
    fn a_session_with_nothing_to_label_says_so() {
        let d = session_dir("unlabelled");
        std::fs::remove_file(d.join("force.csv")).unwrap();
        let err = build(std::slice::from_ref(&d), None, &DatasetConfig::default()).unwrap_err();
        assert!(
            err.to_string().contains("neither force.csv nor labels.csv"),
            "{err}"
        );
        std::fs::remove_file(d.join("features.csv")).unwrap();
        std::fs::write(d.join("labels.csv"), "frame,x_mm\nf0.png,1\n").unwrap();
        let err = build(std::slice::from_ref(&d), None, &DatasetConfig::default()).unwrap_err();
        assert!(err.to_string().contains("give a sensor file"), "{err}");
        let _ = std::fs::remove_dir_all(d);
    }

    /// A sensor file from another camera finds none of its markers in the session's frames:
    /// an error naming the folder, not a table of empty rows; frames without a marker beside
    /// ones with markers are left out with a note.
    #[test]
    fn a_sensor_that_finds_no_marker_is_refused() {
        use visuotact_sim::pattern::{render_grid, GridPattern};
        use visuotact_vision::calibration::{calibrate, Preset};
        let pattern = GridPattern::IATS;
        let rest = render_grid(&pattern, None, 1).0;
        let (sensor, _) = calibrate([("rest", &rest)], &Preset::Iats.config()).unwrap();
        let d = session_dir("no-marker");
        std::fs::remove_file(d.join("features.csv")).unwrap();
        std::fs::remove_file(d.join("force.csv")).unwrap();
        std::fs::write(d.join("labels.csv"), "frame,x_mm\nf0.png,1\nf1.png,2\n").unwrap();
        std::fs::create_dir_all(d.join("frames")).unwrap();
        let dark = visuotact_image::RgbImage::new(rest.width(), rest.height());
        for k in 0..5 {
            visuotact_io::frames::write_png(&d.join(format!("frames/f{k}.png")), &dark).unwrap();
        }
        let cfg = DatasetConfig::default();
        let err = build(std::slice::from_ref(&d), Some(&sensor), &cfg).unwrap_err();
        assert!(
            err.to_string()
                .contains("none of its markers in any of the 5 frames"),
            "{err}"
        );
        visuotact_io::frames::write_png(&d.join("frames/f0.png"), &rest).unwrap();
        let ds = build(std::slice::from_ref(&d), Some(&sensor), &cfg).unwrap();
        assert_eq!(ds.keys, vec!["f0.png".to_string()]);
        assert!(
            ds.notes.iter().any(|n| n.contains("4 frames with none")),
            "{:?}",
            ds.notes
        );
        let _ = std::fs::remove_dir_all(d);
    }
}
