//! `visuotact export`: sessions into the robot's formats — `mcap` writes a ROS 2 bag
//! ([`visuotact_ros::export_mcap`]).

use std::path::PathBuf;

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
}

#[derive(clap::Args, Debug)]
struct Mcap {
    /// Session folder (from `record` or `simulate`).
    session: PathBuf,
    /// FILE.mcap for one file; any other name for a rosbag2 bag folder (NAME/NAME_0.mcap and
    /// metadata.yaml, as `ros2 bag play` reads it).
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
    /// Leave the frames out (no CompressedImage topic).
    #[arg(long)]
    no_images: bool,
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let Format::Mcap(m) = &a.format;
    let cfg = visuotact_ros::ExportConfig {
        ros: m.ros.config(!m.no_images),
        sensor: m.sensor.clone(),
        start_unix_s: m.start_unix_s,
        ..Default::default()
    };
    let bar = indicatif::ProgressBar::new(0);
    let s = visuotact_ros::export_mcap(&m.session, &m.output, &cfg, &mut |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    })?;
    bar.finish_and_clear();
    for n in &s.notes {
        eprintln!("note: {}: {n}", m.session.display());
    }
    eprintln!(
        "wrote {} ({} frames, {} messages)",
        s.path.display(),
        s.frames,
        s.messages
    );
    Ok(())
}
