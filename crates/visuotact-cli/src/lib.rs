//! The `visuotact` command line: parses arguments and calls the library crates. `main` only
//! calls [`run`]; each subcommand lives in `commands/` and returns `anyhow::Result`, printed
//! once here as `error: …` with exit code 1 (2 for usage errors).
//!
//! ## Modules and what each owns
//!
//! the `visuotact` command line, `commands/<name>.rs` per subcommand (`demo`, `calibrate`,
//! `extract`, `blobs`, `bench`, `simulate`, `check-tracking`, `train`, `sweep`, `predict`,
//! `eval`, `pattern`, `filter`, `record`, `dataset`, `replay`, `run`, `cameras`): options → the
//! library's config → one library call → printed result. Shared option groups in `args`
//! (detection, force cleaning, training), file loading in `files`, shared printing in `print`,
//! progress lines and Ctrl-C for long steps in `progress`; command modules never import each
//! other

use std::process::ExitCode;

use clap::{Parser, Subcommand};

// First: the line macros are in scope in every module below.
#[macro_use]
mod say;
mod args;
mod commands;
mod files;
mod print;
mod progress;
mod slurm;

use commands::{
    bench, blobs, calibrate, dataset, demo, eval, export, extract, filter, pattern, predict,
    record, replay, run, simulate, slip, sweep, trackcheck, train,
};
pub(crate) use files::{
    estimator, fit_error, load_model, load_sensor, load_slip, reference_note, write_atomically,
};

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
    Train(train::Args),
    /// Train many hidden sizes × repeats on every core → sweep.csv, best model, plot (`sweep
    /// merge` joins the parts of `--shard K/N`; `--slurm N` writes a cluster's scripts).
    Sweep(sweep::Args),
    /// Parts from `sweep --shard K/N` → sweep.csv, best model, plot, as one machine's; called
    /// as `visuotact sweep merge PARTS… -o DIR`.
    #[command(name = "sweep-merge", hide = true)]
    SweepMerge(sweep::MergeArgs),
    /// Run a model over a feature table → predictions.csv.
    Predict(predict::Args),
    /// Error figures of predictions against labels (MSE, R, mean/max error, MPE, accuracy, D).
    Eval(eval::Args),
    /// Force CSV → zero-phase low-passed, debiased CSV (and a before/after plot).
    Filter(filter::Args),
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
    /// Slip over time from the marker field: `slip fit` a detector on labelled videos, `slip
    /// detect` each video's verdict and onset.
    Slip(slip::Args),
    /// Sessions into the robot's formats: `export mcap` (a ROS 2 bag).
    Export(export::Args),
    /// List the V4L2 cameras (`/dev/videoN`) and their names.
    Cameras,
}

/// Runs the program with the process arguments.
pub fn run() -> ExitCode {
    run_with(std::env::args_os())
}

/// `sweep merge …` as the hidden command `sweep-merge …`: clap checks `sweep`'s required
/// arguments (its training data) even before a subcommand, so the merge is its own command
/// that the user still calls `sweep merge`.
pub(crate) fn route_sweep_merge<I, T>(args: I) -> Vec<std::ffi::OsString>
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString>,
{
    let mut v: Vec<std::ffi::OsString> = args.into_iter().map(Into::into).collect();
    if let Some(k) = v.iter().position(|a| a == "sweep") {
        if v.get(k + 1).is_some_and(|a| a == "merge") {
            v[k] = "sweep-merge".into();
            v.remove(k + 1);
        }
    }
    v
}

/// Runs the program with the given arguments (the first is the program name).
pub fn run_with<I, T>(args: I) -> ExitCode
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let cli = match Cli::try_parse_from(route_sweep_merge(args)) {
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
        Command::Train(a) => train::run(&a),
        Command::Sweep(a) => sweep::run(&a),
        Command::SweepMerge(a) => sweep::merge(&a),
        Command::Predict(a) => predict::run(&a),
        Command::Eval(a) => eval::run(&a),
        Command::Filter(a) => filter::run(&a),
        Command::Dataset(a) => dataset::run(&a),
        Command::Record(a) => record::run(&a),
        Command::Replay(a) => replay::run(&a),
        Command::Run(a) => run::run(&a),
        Command::Export(a) => export::run(&a),
        Command::Slip(a) => slip::run(&a),
        Command::Cameras => {
            let list = visuotact_io::camera::list_devices();
            if list.is_empty() {
                say!("no V4L2 cameras (/sys/class/video4linux is empty)");
            }
            for (dev, name) in list {
                say!("{dev}\t{name}");
            }
            Ok(())
        }
    };
    // Output that did not arrive is not a success.
    let result = result.and_then(|()| match say::stdout_failure() {
        Some(e) => Err(anyhow::anyhow!("cannot write to standard output: {e}")),
        None => Ok(()),
    });
    match result {
        Ok(()) => ExitCode::SUCCESS,
        // `visuotact extract -o - | head`: the reader had what it wanted.
        Err(e) if closed_pipe(&e) => ExitCode::SUCCESS,
        Err(e) => {
            note!("error: {}", message(&e));
            ExitCode::FAILURE
        }
    }
}

/// Whether `e` is the reader of an output having gone (a closed pipe): not a failure.
fn closed_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// An error and its causes, each said once: library errors already name their cause, so a
/// cause whose text is in the message so far is not repeated.
fn message(e: &anyhow::Error) -> String {
    let mut msg = e.to_string();
    for cause in e.chain().skip(1) {
        let c = cause.to_string();
        if !msg.contains(&c) {
            msg.push_str(": ");
            msg.push_str(&c);
        }
    }
    msg
}
