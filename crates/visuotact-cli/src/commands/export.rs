//! `visuotact export`: sessions into the robot's formats — `mcap` writes a ROS 2 bag
//! ([`visuotact_ros::export_mcap`]), `rerun` a Rerun recording
//! ([`visuotact_rerun::export_rerun`]), `lerobot` a LeRobot v3.0 data set
//! ([`visuotact_lerobot::export_lerobot`]).

use std::path::{Path, PathBuf};

use visuotact_pipeline::output::OutputError;
use visuotact_pipeline::session_export::ExportConfig;
use visuotact_rerun::RerunError;
use visuotact_ros::RosError;

use crate::progress::Reporter;

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    #[command(subcommand)]
    format: Format,
}

#[derive(clap::Subcommand, Debug)]
enum Format {
    /// A session folder → an MCAP bag with the ROS 2 profile (estimates as WrenchStamped and
    /// PointStamped, force sensor, marker cloud, frames, diagnostics; topics in README "ROS 2").
    Mcap(Mcap),
    /// A session folder → a Rerun recording (FILE.rrd): frames, markers coloured by status
    /// with displacement arrows, estimates, force and health as time series on the `frame`
    /// and `capture_time` timelines (docs/cli.md "Rerun").
    Rerun(Mcap),
    /// Session folders → a LeRobot v3.0 data set, one episode per session (Parquet data with
    /// the tactile features, estimates and force as observation.* columns, the frames as MP4
    /// through ffmpeg, meta/info.json, episodes, tasks, stats; README "Data sets").
    Lerobot(Lerobot),
}

#[derive(clap::Args, Debug)]
struct Lerobot {
    /// Session folders, one episode each, in this order.
    #[arg(required = true)]
    sessions: Vec<PathBuf>,
    /// The data set's folder (must not exist).
    #[arg(short, long)]
    output: PathBuf,
    /// Frames per second (default: the first session's, from session.json or its frame times).
    #[arg(long)]
    fps: Option<u32>,
    /// The task of every episode, in words.
    #[arg(long, default_value = "touch the tactile sensor")]
    task: String,
    /// robot_type in meta/info.json.
    #[arg(long)]
    robot_type: Option<String>,
    /// No video feature (sessions recorded without --save-frames).
    #[arg(long)]
    no_video: bool,
    /// ffmpeg encoder: libsvtav1 (AV1, as LeRobot) or libx264 where AV1 is missing.
    #[arg(long, default_value = "libsvtav1")]
    encoder: String,
    /// No progress lines (by default one every 2 s on stderr, also when it is not a terminal).
    #[arg(long, short)]
    quiet: bool,
}

#[derive(clap::Args, Debug)]
struct Mcap {
    /// Session folder (from `record` or `simulate`).
    session: PathBuf,
    /// mcap: FILE.mcap for one file, any other name for a rosbag2 bag folder (NAME/NAME_0.mcap
    /// and metadata.yaml, as `ros2 bag play` reads it); rerun: FILE.rrd.
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    ros: crate::args::RosArgs,
    /// Sensor file for the marker cloud (default: the one session.json names).
    #[arg(long)]
    sensor: Option<PathBuf>,
    /// The session's start as UNIX time, seconds, added to its timestamps (default: the
    /// start `record` wrote in session.json; without one 0, the session's own seconds).
    #[arg(long)]
    start_unix_s: Option<f64>,
    /// Leave the frames out (no CompressedImage topic, no Rerun image).
    #[arg(long)]
    no_images: bool,
    /// No progress lines (by default one every 2 s on stderr, also when it is not a terminal).
    #[arg(long, short)]
    quiet: bool,
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    match &a.format {
        Format::Mcap(m) => mcap(m),
        Format::Rerun(m) => rerun(m),
        Format::Lerobot(l) => lerobot(l),
    }
}

/// A reporter for an export's frames, its first line printed.
fn reporter(quiet: bool) -> Reporter {
    let r = Reporter::new(quiet);
    r.stage("export");
    r
}

/// The error of an export stopped by Ctrl-C.
fn interrupted(frames: usize, out: &Path) -> anyhow::Error {
    anyhow::anyhow!(
        "interrupted (Ctrl-C) after {frames} frames: {} not written",
        out.display()
    )
}

fn lerobot(l: &Lerobot) -> anyhow::Result<()> {
    let inputs: Vec<&Path> = l.sessions.iter().map(PathBuf::as_path).collect();
    visuotact_io::guard::refuse_output_over_input(&l.output, &inputs)?;
    let cfg = visuotact_lerobot::LeRobotConfig {
        fps: l.fps,
        task: l.task.clone(),
        robot_type: l.robot_type.clone(),
        video: (!l.no_video).then(|| visuotact_lerobot::VideoConfig {
            encoder: l.encoder.clone(),
            ..Default::default()
        }),
    };
    let r = reporter(l.quiet);
    let s = visuotact_lerobot::export_lerobot(&l.sessions, &l.output, &cfg, &mut |done, total| {
        r.items(done, Some(total), "frames")
    })
    .map_err(|e| match e {
        visuotact_lerobot::LeRobotError::Stopped(n) => interrupted(n, &l.output),
        e => e.into(),
    })?;
    for n in &s.notes {
        note!("note: {n}");
    }
    note!(
        "wrote {} ({} episodes, {} frames at {} fps; {})",
        s.path.display(),
        s.episodes,
        s.frames,
        s.fps,
        s.features.join(", ")
    );
    Ok(())
}

/// The export's settings, its output checked not to overwrite an input.
fn session_export(m: &Mcap) -> anyhow::Result<ExportConfig> {
    let mut inputs = vec![m.session.as_path()];
    inputs.extend(m.sensor.as_deref());
    visuotact_io::guard::refuse_output_over_input(&m.output, &inputs)?;
    Ok(ExportConfig {
        output: m.ros.config(!m.no_images),
        sensor: m.sensor.clone(),
        start_unix_s: m.start_unix_s,
    })
}

/// An export's error (`stopped`: the frames written when Ctrl-C stopped it, which then says
/// what was not written).
fn export_error(e: impl Into<anyhow::Error>, stopped: Option<usize>, m: &Mcap) -> anyhow::Error {
    match stopped {
        Some(n) => interrupted(n, &m.output),
        None => e.into(),
    }
}

/// What the session lacked, one note each.
fn session_notes(m: &Mcap, notes: &[String]) {
    for n in notes {
        note!("note: {}: {n}", m.session.display());
    }
}

fn rerun(m: &Mcap) -> anyhow::Result<()> {
    let cfg = session_export(m)?;
    let r = reporter(m.quiet);
    let s = visuotact_rerun::export_rerun(&m.session, &m.output, &cfg, &mut |done, total| {
        r.items(done, Some(total), "frames")
    })
    .map_err(|e| {
        let stopped = match &e {
            RerunError::Output(OutputError::Stopped(n)) => Some(*n),
            _ => None,
        };
        export_error(e, stopped, m)
    })?;
    session_notes(m, &s.notes);
    note!("wrote {} ({} frames)", s.path.display(), s.frames);
    Ok(())
}

fn mcap(m: &Mcap) -> anyhow::Result<()> {
    let cfg = session_export(m)?;
    let r = reporter(m.quiet);
    let bag = visuotact_ros::BagConfig::default();
    let s = visuotact_ros::export_mcap(&m.session, &m.output, (&cfg, &bag), &mut |done, total| {
        r.items(done, Some(total), "frames")
    })
    .map_err(|e| {
        let stopped = match &e {
            RosError::Output(OutputError::Stopped(n)) => Some(*n),
            _ => None,
        };
        export_error(e, stopped, m)
    })?;
    session_notes(m, &s.notes);
    note!(
        "wrote {} ({} frames, {} messages)",
        s.path.display(),
        s.frames,
        s.messages
    );
    Ok(())
}
