//! `visuotact dataset`: session folders → one features table and one labels table for `train`.
//!
//! Per session: features from its `features.csv` (written by `record --sensor`) or extracted
//! from its `frames/` with `--sensor`; labels from its force record (low-passed with `filtfilt`,
//! debiased, resampled onto the frame times with a latency offset) or, without one, from its
//! `labels.csv`. Force samples received over the network carry the sender's clock and the
//! recorder's receive time (`recv_s`); the sender's clock is mapped onto the recorder's by the
//! smallest `recv_s − timestamp_s` (the least-delayed packet).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use visuotact_io::force::ForceTable;
use visuotact_io::frames::FrameStream;
use visuotact_io::table::{format_number, KeyedTable};
use visuotact_signal::align::Resampler;
use visuotact_vision::features::{FeatureExtractor, FrameFeatures};

use crate::force::{magnitude, ForceArgs};

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Session folders (`simulate` or `record`).
    #[arg(required = true)]
    sessions: Vec<PathBuf>,
    /// Output folder: features.csv and labels.csv, keyed by `frame` (`SESSION/frame` when
    /// more than one session is given).
    #[arg(short, long)]
    output: PathBuf,
    /// Sensor file, to extract features from sessions' frames (needed when a session has no
    /// features.csv).
    #[arg(long)]
    sensor: Option<PathBuf>,
    /// Latency correction, seconds: a frame at time t is labelled with the force at t + this.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    latency_s: f64,
    /// Longest run of missing force samples to interpolate across, seconds; frames inside a
    /// longer gap get no label.
    #[arg(long, default_value_t = 0.05)]
    max_gap_s: f64,
    #[command(flatten)]
    force: ForceArgs,
}

/// Column names and each frame's values.
type Columns = (Vec<String>, HashMap<String, Vec<f64>>);

/// One session's rows.
struct Rows {
    keys: Vec<String>,
    features: Vec<Vec<f64>>,
    labels: Vec<Vec<f64>>,
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let many = a.sessions.len() > 1;
    let mut feature_cols: Option<Vec<String>> = None;
    let mut label_cols: Option<Vec<String>> = None;
    let mut all = Rows {
        keys: Vec::new(),
        features: Vec::new(),
        labels: Vec::new(),
    };
    for s in &a.sessions {
        let (fcols, lcols, rows) = session_rows(a, s)?;
        if *feature_cols.get_or_insert_with(|| fcols.clone()) != fcols {
            bail!(
                "{}: its feature columns differ from the first session's; use one sensor file",
                s.display()
            );
        }
        if *label_cols.get_or_insert_with(|| lcols.clone()) != lcols {
            bail!(
                "{}: its label columns differ from the first session's",
                s.display()
            );
        }
        let prefix = s
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        for k in rows.keys {
            all.keys
                .push(if many { format!("{prefix}/{k}") } else { k });
        }
        all.features.extend(rows.features);
        all.labels.extend(rows.labels);
    }
    let write = |name: &str, cols: &[String], rows: &[Vec<f64>]| -> anyhow::Result<()> {
        let mut text = format!("frame,{}\n", cols.join(","));
        for (k, r) in all.keys.iter().zip(rows) {
            text.push_str(k);
            for v in r {
                text.push(',');
                text.push_str(&format_number(*v));
            }
            text.push('\n');
        }
        crate::write_atomically(&a.output.join(name), &text)
    };
    write(
        "features.csv",
        feature_cols.as_deref().unwrap_or_default(),
        &all.features,
    )?;
    write(
        "labels.csv",
        label_cols.as_deref().unwrap_or_default(),
        &all.labels,
    )?;
    eprintln!(
        "wrote {} rows to {}/features.csv and labels.csv",
        all.keys.len(),
        a.output.display()
    );
    Ok(())
}

/// Touch frames of a session and their timestamps, from frames.csv.
fn touch_frames(session: &Path) -> anyhow::Result<Vec<(String, f64)>> {
    let p = session.join("frames.csv");
    let t = KeyedTable::read(&p, &["kind"]).map_err(anyhow::Error::msg)?;
    let ts = t
        .column("timestamp_s")
        .with_context(|| format!("{}: no timestamp_s column", p.display()))?;
    Ok(t.keys
        .iter()
        .zip(&t.rows)
        .zip(&t.text)
        .filter(|(_, kind)| kind[0] != "reference")
        .map(|((k, r), _)| (k.clone(), r[ts]))
        .collect())
}

fn session_rows(a: &Args, s: &Path) -> anyhow::Result<(Vec<String>, Vec<String>, Rows)> {
    let frames = touch_frames(s)?;
    // Features.
    let (fcols, feats): Columns = if s.join("features.csv").exists() {
        let t =
            KeyedTable::read(&s.join("features.csv"), &["flags"]).map_err(anyhow::Error::msg)?;
        let idx: Vec<usize> = (0..t.columns.len())
            .filter(|&i| t.columns[i].starts_with('m') && t.columns[i].contains('_'))
            .collect();
        (
            idx.iter().map(|&i| t.columns[i].clone()).collect(),
            t.keys
                .iter()
                .zip(&t.rows)
                .map(|(k, r)| (k.clone(), idx.iter().map(|&i| r[i]).collect()))
                .collect(),
        )
    } else {
        let sensor = a.sensor.as_ref().with_context(|| {
            format!(
                "{}: no features.csv; give --sensor to extract features from its frames",
                s.display()
            )
        })?;
        extract(sensor, &s.join("frames"))?
    };
    // Labels.
    let force_path = s.join("force.csv");
    let (lcols, labels): Columns = if force_path.exists() {
        let table = ForceTable::read(&force_path).map_err(anyhow::Error::msg)?;
        if table.dropped_partial_line {
            eprintln!(
                "note: {}: an unfinished last line was left out",
                force_path.display()
            );
        }
        // Sender clock → recorder clock.
        let offset = table.recv_s.as_ref().map_or(0.0, |r| {
            r.iter()
                .zip(&table.timestamp_s)
                .map(|(r, t)| r - t)
                .fold(f64::INFINITY, f64::min)
        });
        let p = a.force.process(table, &force_path.display().to_string())?;
        let times: Vec<f64> = frames.iter().map(|(_, t)| t - offset).collect();
        let rs = Resampler::new(&p.t, &times, a.latency_s, a.max_gap_s.max(1.5 / p.rate_hz))
            .map_err(|e| anyhow::anyhow!("{}: {e}", force_path.display()))?;
        let mag: Vec<f64> = (0..p.t.len()).map(|i| magnitude(&p, i)).collect();
        let cols = [
            rs.apply(&mag),
            rs.apply(&p.clean[0]),
            rs.apply(&p.clean[1]),
            rs.apply(&p.clean[2]),
        ];
        if rs.missing() > 0 {
            eprintln!(
                "note: {}: {} frames outside the force record or in a gap get no label",
                s.display(),
                rs.missing()
            );
        }
        let mut m = HashMap::new();
        for (i, (k, _)) in frames.iter().enumerate() {
            if let (Some(f), Some(x), Some(y), Some(z)) =
                (cols[0][i], cols[1][i], cols[2][i], cols[3][i])
            {
                m.insert(k.clone(), vec![f, x, y, z]);
            }
        }
        (
            ["force_n", "fx_n", "fy_n", "fz_n"]
                .map(String::from)
                .to_vec(),
            m,
        )
    } else if s.join("labels.csv").exists() {
        let t = KeyedTable::read(&s.join("labels.csv"), &[]).map_err(anyhow::Error::msg)?;
        let m = t.keys.iter().cloned().zip(t.rows.iter().cloned()).collect();
        (t.columns.clone(), m)
    } else {
        bail!(
            "{}: neither force.csv nor labels.csv: nothing to label frames with",
            s.display()
        );
    };
    let mut rows = Rows {
        keys: Vec::new(),
        features: Vec::new(),
        labels: Vec::new(),
    };
    let mut unlabelled = 0;
    for (k, _) in &frames {
        match (feats.get(k), labels.get(k)) {
            (Some(f), Some(l)) => {
                rows.keys.push(k.clone());
                rows.features.push(f.clone());
                rows.labels.push(l.clone());
            }
            _ => unlabelled += 1,
        }
    }
    if unlabelled > 0 {
        eprintln!(
            "note: {}: {unlabelled} frames without both features and labels left out",
            s.display()
        );
    }
    Ok((fcols, lcols, rows))
}

/// Marker features of every frame in `dir`, extracted with `sensor`.
fn extract(sensor: &Path, dir: &Path) -> anyhow::Result<Columns> {
    let cal = crate::load_sensor(sensor)?;
    let set = cal.features;
    let mut ex = FeatureExtractor::new(cal, set).map_err(anyhow::Error::msg)?;
    let cols = ex.column_names();
    let mut out = HashMap::new();
    let mut f = FrameFeatures::default();
    for item in FrameStream::open(&[dir.to_path_buf()], 25.0)? {
        let frame = match item {
            Ok(fr) => fr,
            Err(e) => {
                eprintln!("warning: {e}; skipped");
                continue;
            }
        };
        match ex.extract_into(&frame.image, &mut f) {
            Ok(()) => {
                out.insert(frame.id, f.values.clone());
            }
            Err(e) => eprintln!("warning: frame {}: {e}; skipped", frame.id),
        }
    }
    Ok((cols, out))
}
