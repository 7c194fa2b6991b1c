//! `visuotact replay`: a trained model run over a recorded session (or a video, or frames)
//! frame by frame, as the live loop would ([`visuotact_pipeline::replay`]); the estimates and,
//! when labels exist, their error figures.

use std::path::PathBuf;

use visuotact_pipeline::replay::{replay, ReplayConfig, ReplayError};
use visuotact_pipeline::{LiveConfig, LiveEstimator};

use crate::progress::{pass_error, FramePass, Reporter};

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
    /// Slip detection: the table ends with `slip_score` and `slip_state` (0 stick, 1
    /// incipient, 2 slip), the replay followed as one sequence. `builtin`: the built-in detector.
    #[arg(long, value_name = "slip.json|builtin")]
    slip: Option<PathBuf>,
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
    /// Estimate as `run` does: only frames in contact get an estimate (the others are flagged
    /// `no contact`), from a baseline that follows the skin's drift between contacts. By
    /// default every frame is estimated against the sensor's reference.
    #[arg(long)]
    live_rules: bool,
    /// No progress lines (by default one every 2 s on stderr, also when it is not a terminal).
    #[arg(long, short)]
    quiet: bool,
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let mut inputs: Vec<&std::path::Path> = a.input.iter().map(PathBuf::as_path).collect();
    inputs.push(&a.model);
    inputs.extend(a.sensor.as_deref());
    inputs.extend(a.labels.as_deref());
    inputs.extend(a.readings.as_deref());
    visuotact_io::guard::refuse_output_over_input(&a.output, &inputs)?;
    let model = crate::load_model(&a.model)?;
    let sensor = a.sensor.as_deref().map(crate::load_sensor).transpose()?;
    let mut est = visuotact_pipeline::Estimator::with_extra_inputs(sensor, Some(model))?;
    est.set_temporal_prior(a.temporal);
    let rules = if a.live_rules {
        LiveConfig::LIVE
    } else {
        LiveConfig::OFFLINE
    };
    let mut live = LiveEstimator::from_estimator(est, &rules)?;
    let cfg = ReplayConfig {
        inputs: a.input.clone(),
        output: a.output.clone(),
        fps: a.fps,
        readings: a.readings.clone(),
        slip: a.slip.as_ref().map(|p| crate::load_slip(p)).transpose()?,
    };
    let reporter = Reporter::new(a.quiet);
    reporter.stage("replay");
    let mut pass = FramePass::new(&reporter, usize::MAX);
    let done = replay(&mut live, &cfg, &mut pass).map_err(|e| match e {
        ReplayError::NoReadings(names) => anyhow::anyhow!(
            "the model {} needs {names} besides the marker features: give --readings TABLE (keyed by frame)",
            a.model.display()
        ),
        e => pass_error(e, &a.output),
    })?;
    note!(
        "replayed {} frames in {:.2} s ({:.2} ms per frame, decoding included); {} without an estimate; wrote {}",
        done.frames,
        done.seconds,
        1e3 * done.seconds / done.frames.max(1) as f64,
        done.missing,
        a.output.display()
    );
    let labels = a
        .labels
        .clone()
        .or_else(|| done.session.map(|s| s.join("labels.csv")))
        .filter(|p| p.is_file());
    if let Some(l) = labels {
        crate::print::evaluation(&a.output, &l, false, None, None, None)?;
    }
    Ok(())
}
