//! `visuotact extract`: frames → one feature row per frame.

use std::path::PathBuf;

use anyhow::{bail, Context};
use visuotact_io::frames::FrameStream;
use visuotact_io::table::{TableFormat, TableWriter};
use visuotact_pipeline::schema::{feature_columns, feature_row_into, flags_of, missing_summary};
use visuotact_vision::features::{FeatureExtractor, FeatureSet, FrameFeatures};

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Sensor file from `calibrate`.
    #[arg(long)]
    sensor: PathBuf,
    /// Frames: image files, folders of images, or videos.
    #[arg(required = true)]
    frames: Vec<PathBuf>,
    /// Output table (`-` for standard output).
    #[arg(short, long)]
    output: PathBuf,
    /// Features per marker: a list of x, y, area, ecc (default: the sensor file's).
    #[arg(long)]
    features: Option<String>,
    /// Frames are in order (a video, frames in time order): start each frame's tracking from the last one's
    /// marker positions (the reference stays the fallback).
    #[arg(long)]
    temporal: bool,
    /// Table format: csv or jsonl.
    #[arg(long, default_value = "csv", value_parser = ["csv", "jsonl"])]
    format: String,
    /// Frame rate for image sequences (timestamps), frames per second.
    #[arg(long, default_value_t = 25.0)]
    fps: f64,
    /// Print at most this many per-frame warnings, one short line each (0: none); the summary
    /// always comes last.
    #[arg(long, default_value_t = 20)]
    max_warnings: usize,
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    if !(a.fps > 0.0 && a.fps.is_finite()) {
        bail!(
            "--fps must be a positive number of frames per second, got {}",
            a.fps
        );
    }
    let cal = crate::load_sensor(&a.sensor)?;
    let features = match &a.features {
        Some(f) => FeatureSet::parse(f).map_err(|e| anyhow::anyhow!("--features: {e}"))?,
        None => cal.features,
    };
    let n_markers = cal.markers.len();
    let mut ex = FeatureExtractor::new(cal, features).map_err(anyhow::Error::msg)?;
    ex.set_temporal_prior(a.temporal);
    let stream = FrameStream::open(&a.frames, a.fps)?;
    let format = TableFormat::from_name(&a.format).unwrap_or_default();
    let mut out = TableWriter::create(&a.output, format, feature_columns(&ex.column_names()))
        .with_context(|| format!("{}: cannot create output", a.output.display()))?;
    let (mut written, mut skipped, mut warned, mut incomplete, mut lost_total) =
        (0usize, 0usize, 0usize, 0usize, 0usize);
    let mut f = FrameFeatures::default();
    let mut row = Vec::new();
    let warn = |msg: String, warned: &mut usize| {
        if *warned < a.max_warnings {
            eprintln!("warning: {msg}");
        }
        *warned += 1;
    };
    for item in stream {
        let frame = match item {
            Ok(fr) => fr,
            Err(e) => {
                skipped += 1;
                warn(format!("{e}; skipped"), &mut warned);
                continue;
            }
        };
        if let Err(e) = ex.extract_into(&frame.image, &mut f) {
            skipped += 1;
            warn(format!("frame {}: {e}; skipped", frame.id), &mut warned);
            continue;
        }
        let missing = n_markers - f.found;
        if missing > 0 {
            incomplete += 1;
            lost_total += missing;
            let what = if missing * 2 >= n_markers {
                "; half or more: is the skin in view?"
            } else {
                ""
            };
            warn(
                format!(
                    "frame {}: {missing} of {n_markers} markers not found ({}){what}",
                    frame.id,
                    missing_summary(&f)
                ),
                &mut warned,
            );
        }
        feature_row_into(&mut row, frame.timestamp_s, n_markers, &f);
        out.write_row(&frame.id, &row, &flags_of(&f))
            .with_context(|| format!("{}: write failed", a.output.display()))?;
        written += 1;
    }
    if warned > a.max_warnings && a.max_warnings > 0 {
        eprintln!("… {} more warnings not shown", warned - a.max_warnings);
    }
    eprintln!(
        "extracted {written} frames ({} features each), skipped {skipped}; {incomplete} frames with missing markers ({lost_total} marker-frames)",
        features.per_marker() * n_markers
    );
    if let Some(note) = crate::reference_note(&ex.calibration().reference) {
        eprintln!("note: {note}");
    }
    if written == 0 {
        bail!("no frame could be processed");
    }
    Ok(())
}
