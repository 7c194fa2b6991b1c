//! `visuotact replay`: a trained model run over a recorded session (or a video, or frames)
//! frame by frame, as the live loop would — seed 001's Neural Network Testing Model. Writes
//! the estimates and, when labels exist, their error figures. Inputs of the model besides the
//! marker features (a pressure gauge's reading) come from a table keyed by frame.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use visuotact_io::frames::FrameStream;
use visuotact_io::table::{KeyedTable, TableFormat, TableWriter};

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Model from `train` or `sweep`.
    #[arg(long)]
    model: PathBuf,
    /// Sensor file (default: the calibration stored in the model).
    #[arg(long)]
    sensor: Option<PathBuf>,
    /// Frames are in order (video, camera): start each frame's tracking from the last one's
    /// marker positions (the reference stays the fallback).
    #[arg(long)]
    temporal: bool,
    /// A session folder (its frames/, in frames.csv order), or videos / images / folders.
    #[arg(required = true)]
    input: Vec<PathBuf>,
    /// Estimates table.
    #[arg(short, long)]
    output: PathBuf,
    /// Labels to score against (default: the session's labels.csv, if any).
    #[arg(long)]
    labels: Option<PathBuf>,
    /// Frame rate of image sequences, frames per second.
    #[arg(long, default_value_t = 25.0)]
    fps: f64,
    /// Table keyed by `frame` with the model's inputs besides the marker features (e.g. a
    /// pressure gauge's `gauge_kpa`; default: the session's labels.csv when the model has such
    /// inputs).
    #[arg(long, value_name = "TABLE")]
    readings: Option<PathBuf>,
}

/// The extra inputs of each frame, from a table keyed by `frame`.
struct Readings {
    table: KeyedTable,
    columns: Vec<usize>,
}

impl Readings {
    /// Finds `names` in the table at `path`.
    fn open(path: &Path, names: &[String]) -> anyhow::Result<Self> {
        let table = KeyedTable::read(path, &[]).map_err(anyhow::Error::msg)?;
        let columns = names
            .iter()
            .map(|c| {
                table.column(c).with_context(|| {
                    format!("{}: no column `{c}`, an input of the model", path.display())
                })
            })
            .collect::<anyhow::Result<_>>()?;
        Ok(Self { table, columns })
    }
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let model = crate::load_model(&a.model)?;
    let mut est = crate::estimator_with_extra_inputs(a.sensor.as_deref(), Some(model))?;
    est.set_temporal_prior(a.temporal);
    let session =
        (a.input.len() == 1 && a.input[0].join("frames.csv").is_file()).then(|| a.input[0].clone());
    let extra = est.extra_inputs().to_vec();
    let readings = if extra.is_empty() {
        None
    } else {
        let path = a
            .readings
            .clone()
            .or_else(|| session.as_ref().map(|s| s.join("labels.csv")))
            .filter(|p| p.is_file())
            .with_context(|| {
                format!(
                    "the model {} needs {} besides the marker features: give --readings TABLE (keyed by frame)",
                    a.model.display(),
                    extra.join(", ")
                )
            })?;
        Some(Readings::open(&path, &extra)?)
    };
    let by_key = readings.as_ref().map(|r| r.table.rows_by_key());
    let mut extra_values = Vec::with_capacity(extra.len());
    // A session's frames in recorded order; anything else as given.
    let paths: Vec<PathBuf> = match &session {
        Some(s) => {
            let t =
                KeyedTable::read(&s.join("frames.csv"), &["kind"]).map_err(anyhow::Error::msg)?;
            let frames: Vec<PathBuf> = t
                .keys
                .iter()
                .map(|k| s.join("frames").join(k))
                .filter(|p| p.is_file())
                .collect();
            if frames.is_empty() {
                bail!(
                    "{}: no saved frames (record with --save-frames to replay a session)",
                    s.display()
                );
            }
            frames
        }
        None => a.input.clone(),
    };
    let targets = est.target_columns();
    let mut out = TableWriter::create(&a.output, TableFormat::Csv, targets.clone())
        .with_context(|| format!("{}: cannot create", a.output.display()))?;
    let nan = vec![f64::NAN; targets.len()];
    let (mut n, mut missing) = (0usize, 0usize);
    let t0 = std::time::Instant::now();
    for item in FrameStream::open(&paths, a.fps)? {
        let frame = match item {
            Ok(f) => f,
            Err(e) => {
                eprintln!("warning: {e}; skipped");
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
        match est.process_with(&frame.image, &extra_values) {
            Ok((_, Some(v))) => out.write_row(&frame.id, &v, "")?,
            Ok((_, None)) => {
                missing += 1;
                out.write_row(&frame.id, &nan, "missing features")?;
            }
            Err(e) => {
                missing += 1;
                out.write_row(&frame.id, &nan, &format!("error: {e}"))?;
            }
        }
        n += 1;
    }
    drop(out);
    let secs = t0.elapsed().as_secs_f64();
    eprintln!(
        "replayed {n} frames in {secs:.2} s ({:.2} ms per frame, decoding included); {missing} without an estimate; wrote {}",
        1e3 * secs / n.max(1) as f64,
        a.output.display()
    );
    let labels = a
        .labels
        .clone()
        .or_else(|| session.map(|s| s.join("labels.csv")))
        .filter(|p| p.is_file());
    if let Some(l) = labels {
        crate::print::evaluation(&a.output, &l, false, None, None)?;
    }
    Ok(())
}
