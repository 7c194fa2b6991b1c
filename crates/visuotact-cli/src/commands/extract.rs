//! `visuotact extract`: frames → one feature row per frame.

use std::path::PathBuf;

use anyhow::bail;
use visuotact_io::table::TableFormat;
use visuotact_pipeline::extract::extract;
use visuotact_vision::features::{FeatureExtractor, FeatureSet};

use crate::progress::{pass_error, FramePass, Reporter};

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
    /// marker positions (the reference stays the fallback), and end each row with the displacement
    /// field's dynamics (the signals `slip detect` reads; docs/file-formats.md).
    #[arg(long)]
    temporal: bool,
    /// Table format: csv or jsonl.
    #[arg(long, default_value = "csv", value_parser = crate::args::choice::<TableFormat>(TableFormat::NAMES))]
    format: TableFormat,
    /// Frame rate for image sequences (timestamps), frames per second.
    #[arg(long, default_value_t = 25.0)]
    fps: f64,
    /// Print at most this many per-frame warnings, one short line each (0: none); the summary
    /// always comes last.
    #[arg(long, default_value_t = 20)]
    max_warnings: usize,
    /// No progress lines (by default one every 2 s on stderr, also when it is not a terminal).
    #[arg(long, short)]
    quiet: bool,
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    if !(a.fps > 0.0 && a.fps.is_finite()) {
        bail!(
            "--fps must be a positive number of frames per second, got {}",
            a.fps
        );
    }
    let mut inputs: Vec<&std::path::Path> = a.frames.iter().map(PathBuf::as_path).collect();
    inputs.push(&a.sensor);
    visuotact_io::guard::refuse_output_over_input(&a.output, &inputs)?;
    let cal = crate::load_sensor(&a.sensor)?;
    let features = match &a.features {
        Some(f) => FeatureSet::parse(f).map_err(|e| anyhow::anyhow!("--features: {e}"))?,
        None => cal.features,
    };
    let n_markers = cal.markers.len();
    let mut ex = FeatureExtractor::new(cal, features).map_err(anyhow::Error::msg)?;
    ex.set_temporal_prior(a.temporal);
    let format = a.format;
    let reporter = Reporter::new(a.quiet);
    reporter.stage("extract");
    let mut pass = FramePass::new(&reporter, a.max_warnings);
    let done = extract(&mut ex, &a.frames, a.fps, (&a.output, format), &mut pass)
        .map_err(|e| pass_error(e, &a.output))?;
    pass.print_unshown();
    note!(
        "extracted {} frames ({} features each), skipped {}; {} frames with missing markers ({} marker-frames)",
        done.written,
        features.per_marker() * n_markers,
        done.skipped,
        done.incomplete,
        done.lost
    );
    if let Some(note) = crate::reference_note(&ex.calibration().reference) {
        note!("note: {note}");
    }
    Ok(())
}
