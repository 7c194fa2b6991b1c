//! The `visuotact` command line: parses arguments and calls the library crates.
//!
//! `main` only calls [`run`]; each subcommand lives in its own module and returns
//! `anyhow::Result`, printed once here as `error: …` with exit code 1 (2 for usage errors).

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod bench;
mod blobs;
mod calibrate;
mod dataset;
mod demo;
mod extract;
mod force;
mod live;
mod pattern;
mod plot;
mod record;
mod replay;
mod run;
mod simulate;
mod sweep;
pub mod trackcheck;
mod train;

/// Camera-based soft tactile sensors: frames in, contact position, depth and force out.
#[derive(Parser, Debug)]
#[command(name = "visuotact", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Both papers' experiments end to end on the simulator, beside the papers' numbers.
    Demo(demo::Args),
    /// Average still no-contact frames into a reference and number its markers → sensor.json.
    Calibrate(calibrate::Args),
    /// Track every reference marker through frames → one feature row per frame.
    Extract(extract::Args),
    /// Detect blobs in frames and list them, one row per blob (no calibration needed).
    Blobs(blobs::Args),
    /// Time the in-memory frame → features pipeline, single-threaded.
    Bench(bench::Args),
    /// Render marker-grid test frames with exact truth (rest frames and touches).
    Pattern(pattern::Args),
    /// Simulate a sensor (iats, cone, or the zoo: tactip, gelsight, dots) through a protocol →
    /// a session folder with truth.
    Simulate(simulate::Args),
    /// Track simulated sensors (presets or drawn variants) in memory and compare every marker
    /// with the simulator's truth: lost visible markers, wrong identities, displacement error.
    CheckTracking(trackcheck::Args),
    /// Train a network (Levenberg–Marquardt) from features and labels → model.json.
    Train(train::TrainArgs),
    /// Train many hidden sizes × repeats on every core → sweep.csv, best model, plot.
    Sweep(sweep::Args),
    /// Run a model over a feature table → predictions.csv.
    Predict(train::PredictArgs),
    /// Error figures of predictions against labels (MSE, R, mean/max error, MPE, accuracy, D).
    Eval(train::EvalArgs),
    /// Force CSV → zero-phase low-passed, debiased CSV (and a before/after plot).
    Filter(force::FilterArgs),
    /// Session folders → features.csv + labels.csv for `train` (force filtered, debiased and
    /// aligned onto the frames).
    Dataset(dataset::Args),
    /// Frames (files, video, simulator) and force (UDP, CSV) → a session folder, written as it
    /// goes; `--resume` continues a stopped one.
    Record(record::Args),
    /// Run a model over a recorded session or video frame by frame → estimates (and errors).
    Replay(replay::Args),
    /// Live estimation: camera, video, frames or simulator → estimates on stdout (JSON lines),
    /// UDP and the dashboard (`--serve`), with latency measured per frame.
    Run(run::Args),
    /// List the V4L2 cameras (`/dev/videoN`) and their names.
    Cameras,
}

/// Runs the program with the process arguments.
pub fn run() -> ExitCode {
    run_with(std::env::args_os())
}

/// Runs the program with the given arguments (the first is the program name).
pub fn run_with<I, T>(args: I) -> ExitCode
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let cli = match Cli::try_parse_from(args) {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() {
                ExitCode::from(2)
            } else {
                ExitCode::SUCCESS
            };
        }
    };
    let result = match cli.command {
        Command::Demo(a) => demo::run(&a),
        Command::Calibrate(a) => calibrate::run(&a),
        Command::Extract(a) => extract::run(&a),
        Command::Blobs(a) => blobs::run(&a),
        Command::Bench(a) => bench::run(&a),
        Command::Pattern(a) => pattern::run(&a),
        Command::Simulate(a) => simulate::run(&a),
        Command::CheckTracking(a) => trackcheck::run(&a),
        Command::Train(a) => train::train(&a),
        Command::Sweep(a) => sweep::run(&a),
        Command::Predict(a) => train::predict(&a),
        Command::Eval(a) => train::eval(&a),
        Command::Filter(a) => force::filter(&a),
        Command::Dataset(a) => dataset::run(&a),
        Command::Record(a) => record::run(&a),
        Command::Replay(a) => replay::run(&a),
        Command::Run(a) => run::run(&a),
        Command::Cameras => {
            let list = visuotact_io::camera::list_devices();
            if list.is_empty() {
                println!("no V4L2 cameras (/sys/class/video4linux is empty)");
            }
            for (dev, name) in list {
                println!("{dev}\t{name}");
            }
            Ok(())
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// Reads a sensor file, naming it in errors.
pub(crate) fn load_sensor(
    path: &std::path::Path,
) -> anyhow::Result<visuotact_vision::calibration::SensorCalibration> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| anyhow::anyhow!("{}: cannot read sensor file: {e}", path.display()))?;
    visuotact_vision::calibration::SensorCalibration::from_json(&text, &path.display().to_string())
        .map_err(anyhow::Error::msg)
}

/// A sentence for the user when a sensor's reference was taken under contact (its health
/// flag), `None` otherwise.
pub(crate) fn reference_note(r: &visuotact_vision::calibration::ReferenceInfo) -> Option<String> {
    r.under_contact.then(|| {
        format!(
            "the sensor's reference was taken under contact ({} of {} frames chosen as the lightest, {:.2} px RMS from rest, {:.2} px at worst): displacements are relative to a lightly pressed skin",
            r.method,
            r.frames_considered,
            r.residual_px.unwrap_or(f64::NAN),
            r.residual_max_px.unwrap_or(f64::NAN)
        )
    })
}

/// Writes `text` to `path` through a temporary file and a rename, so a failure never leaves a
/// half-written file over a good one.
pub(crate) fn write_atomically(path: &std::path::Path, text: &str) -> anyhow::Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| anyhow::anyhow!("{}: {e}", dir.display()))?;
    }
    let tmp = path.with_extension("tmp~");
    std::fs::write(&tmp, text)
        .map_err(|e| anyhow::anyhow!("{}: cannot write: {e}", tmp.display()))?;
    std::fs::rename(&tmp, path)
        .map_err(|e| anyhow::anyhow!("{}: cannot write: {e}", path.display()))?;
    Ok(())
}
