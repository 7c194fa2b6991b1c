//! `visuotact record`: a frame source plus an optional force source → a session folder, written
//! as it goes ([`visuotact_pipeline::record`]).
//!
//! Sources: `frames:DIR` or `video:FILE` (or bare paths), and the simulated rigs `sim:cone`
//! (the inflatable cone pressed and released, its JR3 streaming over UDP to `--force`) and
//! `sim:iats` (random touches), paced in real time. Force: `udp:HOST:PORT` (packed
//! little-endian f64, `--force-layout`) or `csv:FILE`.
//!
//! Every table row is written and flushed as it is produced and files are `fsync`ed every
//! `--sync-every-s`: a crash or SIGKILL leaves every completed row readable, and `--resume`
//! continues a stopped session (an unfinished last line is cut off first). Ctrl-C stops
//! cleanly. An unwritable folder or a full disk is reported before recording starts.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use std::sync::Mutex;
use visuotact_io::force::ForceLayout;

use visuotact_pipeline::record::{
    record_observed, ConeRigConfig, ForceSource, RecordConfig, SharedObserver,
};
use visuotact_ros::{finish_recorder, mcap_recorder, BagConfig};

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Session folder to write.
    #[arg(short, long)]
    output: PathBuf,
    /// Frame source: camera:/dev/videoN, frames:DIR, video:FILE, sim:cone, sim:iats, or
    /// image/video paths.
    #[arg(long)]
    source: String,
    /// Frame rate of image folders and of the simulated camera, frames per second.
    #[arg(long, default_value_t = 25.0)]
    fps: f64,
    /// Stop after this many seconds.
    #[arg(long)]
    duration_s: Option<f64>,
    /// Stop after this many frames.
    #[arg(long)]
    max_frames: Option<usize>,
    /// Force source: udp:HOST:PORT (listen there) or csv:FILE.
    #[arg(long)]
    force: Option<String>,
    /// Fields of a force packet, in order (packed little-endian f64).
    #[arg(long, default_value = "timestamp_s,fx,fy,fz,tx,ty,tz")]
    force_layout: String,
    /// The force sensor's sample rate, Hz (counts lost packets; converts a counter field).
    #[arg(long, default_value_t = 1000.0)]
    force_rate_hz: f64,
    /// Sensor file: also write each frame's features (features.csv).
    #[arg(long)]
    sensor: Option<PathBuf>,
    /// Frames are in order (video, camera): start each frame's tracking from the last one's
    /// marker positions (the reference stays the fallback).
    #[arg(long)]
    temporal: bool,
    /// Model: also estimate live (estimates.csv); uses the model's calibration without --sensor.
    #[arg(long)]
    model: Option<PathBuf>,
    /// Keep every frame as PNG in frames/ (for replay and re-extraction).
    #[arg(long)]
    save_frames: bool,
    /// fsync the session files this often, seconds.
    #[arg(long, default_value_t = 1.0)]
    sync_every_s: f64,
    /// Continue a stopped session in the output folder.
    #[arg(long)]
    resume: bool,
    /// sim sources: random seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// sim:cone: press-and-release time, seconds.
    #[arg(long, default_value_t = 20.0)]
    press_s: f64,
    /// sim:cone: no-contact time before and after the press, seconds.
    #[arg(long, default_value_t = 2.0)]
    rest_s: f64,
    /// sim:cone: peak force, N.
    #[arg(long, default_value_t = 10.0)]
    max_force_n: f64,
    /// sim sources: no-contact reference frames written to reference/ first.
    #[arg(long, default_value_t = 10)]
    references: usize,
    #[command(flatten)]
    bag: crate::args::BagArgs,
}

impl Args {
    fn config(&self) -> anyhow::Result<RecordConfig> {
        Ok(RecordConfig {
            output: self.output.clone(),
            source: self.source.as_str().into(),
            fps: self.fps,
            duration_s: self.duration_s,
            max_frames: self.max_frames,
            force: self.force.as_deref().map(ForceSource::parse).transpose()?,
            force_layout: ForceLayout::parse(&self.force_layout)
                .map_err(|e| anyhow::anyhow!("--force-layout: {e}"))?,
            force_rate_hz: self.force_rate_hz,
            save_frames: self.save_frames,
            sync_every_s: self.sync_every_s,
            resume: self.resume,
            seed: self.seed,
            cone: ConeRigConfig {
                press_s: self.press_s,
                rest_s: self.rest_s,
                max_force_n: self.max_force_n,
            },
            references: self.references,
            sensor_file: self.sensor.clone(),
            model_file: self.model.clone(),
        })
    }
}

fn warn(w: &str) {
    note!("warning: {w}");
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let cfg = a.config()?;
    let mut inputs: Vec<&std::path::Path> = a.model.iter().map(PathBuf::as_path).collect();
    inputs.extend(a.sensor.as_deref());
    inputs.extend(crate::args::source_path(&a.source));
    inputs.extend(a.force.as_deref().and_then(crate::args::source_path));
    let mut outputs = vec![a.output.as_path()];
    outputs.extend(a.bag.mcap.as_deref());
    visuotact_io::guard::refuse_outputs_over_inputs(&outputs, &inputs)?;
    let model = a.model.as_deref().map(crate::load_model).transpose()?;
    let estimator = if a.sensor.is_some() || model.is_some() {
        let mut e = crate::estimator(a.sensor.as_deref(), model)?;
        e.set_temporal_prior(a.temporal);
        Some(e)
    } else {
        None
    };
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        // A second handler cannot be installed in the same process (tests); that is fine.
        let _ = ctrlc::set_handler(move || stop.store(true, Ordering::Relaxed));
    }
    let bag = a
        .bag
        .mcap
        .as_deref()
        .map(|p| {
            let cal = estimator.as_ref().map(|e| e.calibration().clone());
            let ros = a.bag.ros.config(a.bag.mcap_images);
            mcap_recorder(p, ros, &BagConfig::default(), cal).map(Mutex::new)
        })
        .transpose()
        .map_err(|e| anyhow::anyhow!("--mcap {e}"))?
        .map(Arc::new);
    let observer = bag.clone().map(|b| b as SharedObserver);
    let recorded = record_observed(&cfg, estimator, &stop, &mut warn, observer);
    if let Some(b) = bag {
        let b = Arc::try_unwrap(b)
            .map_err(|_| anyhow::anyhow!("--mcap: the bag is still in use"))?
            .into_inner()
            .map_err(|_| anyhow::anyhow!("--mcap: a thread panicked while writing"))?;
        let (path, n) = finish_recorder(b).map_err(|e| anyhow::anyhow!("--mcap {e}"))?;
        if recorded.is_err() && n == 0 {
            // Refused before anything was recorded: the corrected re-run finds no bag in the
            // way.
            let _ = std::fs::remove_file(&path).or_else(|_| std::fs::remove_dir_all(&path));
        } else {
            note!("wrote {} ({n} messages)", path.display());
        }
    }
    let s = recorded?;
    note!(
        "recorded {} frames ({} dropped, {} unreadable) into {} in {:.1} s",
        s.written,
        s.dropped,
        s.unreadable,
        a.output.display(),
        s.duration_s
    );
    if let Some(s) = s.force_packets {
        note!(
            "force: {} packets, {} kept, {} malformed, {} duplicates, {} reordered, {} lost, {} implausible",
            s.packets, s.kept, s.malformed, s.duplicates, s.reordered, s.lost, s.rejected
        );
    }
    Ok(())
}
