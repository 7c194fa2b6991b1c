//! `visuotact run`: live estimation ([`visuotact_pipeline::runner`]) to standard output (JSON
//! lines), UDP and the dashboard's WebSocket, with latency measured per frame.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use visuotact_dashboard::DashboardSensor;
use visuotact_io::camera::CameraRequest;
use visuotact_pipeline::runner::{LineSink, RunConfig, UdpSink};
use visuotact_pipeline::several::{check_sensor_names, run_several, NamedSensor, RunFile};
use visuotact_pipeline::sink::FrameSink;
use visuotact_pipeline::{LiveConfig, LiveEstimator};
use visuotact_ros::{
    dds_sink, finish_dds, finish_foxglove, finish_mcap, foxglove_sink, mcap_sink, BagConfig,
    DdsConfig, DdsSink, FoxgloveConfig, FoxgloveSink, McapSink,
};

#[derive(clap::Args, Debug, Clone)]
pub(crate) struct Args {
    /// Model file; give it several times for an ensemble (mean and standard deviation).
    /// Without one, `run` reports contact and marker health only (needs --sensor).
    #[arg(long)]
    model: Vec<PathBuf>,
    /// Sensor file (default: the calibration stored in the first model).
    #[arg(long)]
    sensor: Option<PathBuf>,
    /// Frames are in order (video, camera): start each frame's tracking from the last one's
    /// marker positions (the reference stays the fallback).
    #[arg(long)]
    temporal: bool,
    /// Slip detection: every estimate carries `slip` (state and score; ROS 2 `NS/slip`), each
    /// contact followed as one sequence, a frame without contact `stick`. `builtin`: the
    /// built-in detector.
    #[arg(long, value_name = "slip.json|builtin")]
    slip: Option<PathBuf>,
    /// sim:iats, sim:cone, video:FILE, frames:DIR (or a path), camera:/dev/videoN.
    #[arg(long, required_unless_present = "sensors")]
    source: Option<String>,
    /// Several sensors in one run (a gripper's fingers): a TOML file with one `[[sensor]]`
    /// table each (`name`, `source`, and `sensor`, `model` files as the options say; paths
    /// relative to the working folder). Each sensor has its own source, queue and thread;
    /// JSON lines and UDP carry `"sensor": NAME`, bag, DDS, Foxglove and Rerun topics go
    /// under NS/NAME, the dashboard offers a choice of sensors, and the summary is per
    /// sensor. The other options apply to every sensor (simulated sources
    /// take seeds --seed, --seed + 1, …).
    #[arg(long, value_name = "FILE.toml", conflicts_with_all = ["source", "sensor", "model"])]
    sensors: Option<PathBuf>,
    /// Frame rate of simulated cameras and image sequences, frames per second.
    #[arg(long, default_value_t = 25.0)]
    fps: f64,
    /// Camera frame size, WxH (default: the largest offered up to 640×480).
    #[arg(long, value_name = "WxH")]
    camera_size: Option<String>,
    /// Camera pixel format: mjpeg or yuyv (default: MJPEG when offered).
    #[arg(long)]
    camera_format: Option<String>,
    /// Deliver frames as fast as they can be processed (soak tests), not at the camera rate;
    /// every frame is then estimated (the source waits instead of dropping).
    #[arg(long)]
    unpaced: bool,
    /// Stop after this many frames.
    #[arg(long)]
    max_frames: Option<u64>,
    /// Stop after this many seconds.
    #[arg(long)]
    duration_s: Option<f64>,
    /// Write JSON lines to standard output (`--quiet` to only print the summary).
    #[arg(long)]
    quiet: bool,
    /// Also send each estimate as a UDP datagram (JSON) to HOST:PORT.
    #[arg(long, value_name = "HOST:PORT")]
    udp: Option<String>,
    /// Serve the dashboard and the WebSocket (`/ws`) on this address (loopback by default).
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "127.0.0.1:8080")]
    serve: Option<String>,
    #[command(flatten)]
    bag: crate::args::BagArgs,
    /// Publish the same topics live over DDS (ROS 2 without ROS installed; `ros2 topic echo`
    /// sees them): on loopback unless --ros-network names an interface's address.
    #[arg(long)]
    ros2: bool,
    /// With --ros2: the DDS domain (ROS_DOMAIN_ID).
    #[arg(long, default_value_t = 0)]
    ros_domain_id: u16,
    /// With --ros2: publish on this interface's address (e.g. 192.168.1.20) instead of loopback.
    #[arg(long, value_name = "ADDR")]
    ros_network: Option<std::net::IpAddr>,
    /// Serve the same topics live to the Foxglove app (Open connection → Foxglove WebSocket,
    /// ws://ADDR) with the official Foxglove SDK; loopback port 8765 by default, port 0 picks
    /// a free one (printed).
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = visuotact_ros::FoxgloveConfig::DEFAULT_ADDR)]
    foxglove: Option<std::net::SocketAddr>,
    /// With --foxglove: the frames too (PNG CompressedImage; costs a PNG encoding per frame).
    #[arg(long, requires = "foxglove")]
    foxglove_images: bool,
    /// Log to Rerun: FILE.rrd writes a recording, HOST:PORT streams to a running viewer
    /// (`rerun`; 127.0.0.1:9876 when no value is given).
    #[arg(long, value_name = "ADDR|FILE.rrd", num_args = 0..=1, default_missing_value = visuotact_rerun::DEFAULT_VIEWER_ADDR)]
    rerun: Option<String>,
    /// With --rerun: the frames too (PNG; costs a PNG encoding per frame).
    #[arg(long, requires = "rerun")]
    rerun_images: bool,
    /// Frames the capture queue holds before dropping the oldest.
    #[arg(long, default_value_t = 2)]
    queue: usize,
    /// Contact when at least `--contact-markers` markers move more than this many times their
    /// calibration jitter …
    #[arg(long, default_value_t = 5.0)]
    contact_sigmas: f64,
    /// … and more than this many pixels, against the no-contact baseline.
    #[arg(long, default_value_t = 0.5)]
    contact_min_px: f64,
    /// Markers that must move for contact (one noisy or half-visible marker is not a touch).
    #[arg(long, default_value_t = 3)]
    contact_markers: usize,
    /// Re-zeroing rate: the baseline follows no-contact frames with this weight per frame
    /// (0 turns automatic re-zeroing off; the dashboard's button always works).
    #[arg(long, default_value_t = 0.05)]
    rezero_rate: f64,
    /// Simulated sources: seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Simulated sources: distinct frames cycled (the first 256 rendered before the run starts,
    /// later ones as the loop reaches them).
    #[arg(long, default_value_t = 100)]
    sim_frames: usize,
    /// Write the run's summary (latency, drops, counts) as JSON to this file.
    #[arg(long)]
    summary: Option<PathBuf>,
}

impl Args {
    fn live_config(&self) -> LiveConfig {
        LiveConfig {
            contact_sigmas: self.contact_sigmas,
            contact_min_px: self.contact_min_px,
            contact_markers: self.contact_markers,
            rezero_rate: self.rezero_rate,
            ..LiveConfig::LIVE
        }
    }

    fn run_config(&self) -> anyhow::Result<RunConfig> {
        Ok(RunConfig {
            source: self.source.as_deref().unwrap_or_default().into(),
            fps: self.fps,
            camera: CameraRequest::parse(
                self.camera_size.as_deref(),
                self.camera_format.as_deref(),
            )
            .map_err(|e| anyhow::anyhow!("--camera-size/--camera-format: {e}"))?,
            unpaced: self.unpaced,
            max_frames: self.max_frames,
            duration_s: self.duration_s,
            queue: self.queue,
            seed: self.seed,
            sim_frames: self.sim_frames,
        })
    }
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    if let Some(file) = &a.sensors {
        return several(a, file);
    }
    let cfg = a.run_config()?;
    cfg.validate()?;
    let mut inputs: Vec<&std::path::Path> = a.model.iter().map(PathBuf::as_path).collect();
    inputs.extend(a.sensor.as_deref());
    inputs.extend(a.source.as_deref().and_then(crate::args::source_path));
    let outputs: Vec<&std::path::Path> = [&a.summary, &a.bag.mcap]
        .into_iter()
        .filter_map(Option::as_deref)
        .collect();
    visuotact_io::guard::refuse_outputs_over_inputs(&outputs, &inputs)?;
    // A model file holding an ensemble counts as its networks (the spread is over all).
    let models = a
        .model
        .iter()
        .map(|p| crate::load_model(p))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut est = crate::estimator(a.sensor.as_deref(), models.first().cloned())?;
    est.set_temporal_prior(a.temporal);
    let mut live = LiveEstimator::new(est, models, &a.live_config())?;
    if let Some(p) = &a.slip {
        live.set_slip(crate::load_slip(p)?)?;
    }
    let stop = stop_on_ctrl_c();
    let dashboard = match &a.serve {
        Some(addr) => Some(
            visuotact_dashboard::Dashboard::start(addr, live.calibration(), live.target_names())
                .map_err(|e| anyhow::anyhow!("--serve {e}"))?,
        ),
        None => None,
    };
    let mut out = Outputs::open(a, dashboard, &[])?;
    let ran = visuotact_pipeline::runner::run(&mut live, &cfg, &stop, &mut out.sinks(), |w| {
        note!("warning: {w}")
    });
    // The outputs are closed whatever happened: what they hold stays readable.
    let finished = out.finish();
    let mut summary = ran?;
    let (udp_errors, dashboard) = finished?;
    summary.udp_send_errors = udp_errors;
    summary.websocket_messages_dropped = dashboard.as_ref().map_or(0, |d| d.dropped());
    print_summary(&summary);
    if let Some(p) = &a.summary {
        crate::write_atomically(p, &serde_json::to_string_pretty(&summary)?)?;
    }
    if let Some(d) = dashboard {
        d.stop();
    }
    Ok(())
}

/// The ROS 2 outputs asked for: the bag (`--mcap`) and the live DDS topics (`--ros2`).
fn ros_sinks(a: &Args, sensors: &[String]) -> anyhow::Result<(Option<McapSink>, Option<DdsSink>)> {
    let mcap = a
        .bag
        .mcap
        .as_deref()
        .map(|p| {
            mcap_sink(
                p,
                a.bag.ros.config(a.bag.mcap_images),
                &BagConfig::default(),
            )
        })
        .transpose()
        .map_err(|e| anyhow::anyhow!("--mcap {e}"))?;
    let dds = a
        .ros2
        .then(|| {
            dds_sink(&DdsConfig {
                ros: a.bag.ros.config(false),
                domain_id: a.ros_domain_id,
                network: a.ros_network,
                sensors: sensors.to_vec(),
            })
        })
        .transpose()
        .map_err(|e| anyhow::anyhow!("--ros2 {e}"))?;
    Ok((mcap, dds))
}

fn finish_ros_sinks(mcap: Option<McapSink>, dds: Option<DdsSink>) -> anyhow::Result<()> {
    if let Some(m) = mcap {
        let (path, n) = finish_mcap(m).map_err(|e| anyhow::anyhow!("--mcap {e}"))?;
        note!("wrote {} ({n} messages)", path.display());
    }
    if let Some(d) = dds {
        let n = finish_dds(d).map_err(|e| anyhow::anyhow!("--ros2 {e}"))?;
        note!("published {n} messages over DDS");
    }
    Ok(())
}

fn print_summary(summary: &visuotact_pipeline::runner::RunSummary) {
    note!(
        "{} frames captured, {} estimated ({} with contact), {} dropped in {:.1} s; latency median {:.3} ms, p99 {:.3} ms; processing median {:.3} ms, p99 {:.3} ms; UDP errors {}, WebSocket messages dropped {}",
        summary.frames_captured,
        summary.frames_estimated,
        summary.contact_frames,
        summary.frames_dropped,
        summary.seconds,
        summary.latency_ms_median,
        summary.latency_ms_p99,
        summary.processing_ms_median,
        summary.processing_ms_p99,
        summary.udp_send_errors,
        summary.websocket_messages_dropped
    );
}

/// `run --sensors FILE`: every sensor of the run file at once, into the same outputs.
fn several(a: &Args, file: &std::path::Path) -> anyhow::Result<()> {
    // A regular file only: a FIFO or a device would block the run before it starts.
    let text = visuotact_io::read::text_of_file(file)
        .map_err(|e| anyhow::anyhow!("--sensors {}: {e}", file.display()))?;
    let plan = RunFile::from_toml(&text)
        .map_err(|e| anyhow::anyhow!("--sensors {}: {e}", file.display()))?;
    let mut inputs: Vec<&std::path::Path> = vec![file];
    for s in &plan.sensor {
        inputs.extend(s.model.iter().map(PathBuf::as_path));
        inputs.extend(s.sensor.as_deref());
        inputs.extend(crate::args::source_path(&s.source));
    }
    let outputs: Vec<&std::path::Path> = [&a.summary, &a.bag.mcap]
        .into_iter()
        .filter_map(Option::as_deref)
        .collect();
    visuotact_io::guard::refuse_outputs_over_inputs(&outputs, &inputs)?;
    let mut sensors = named_sensors(a, file, &plan)?;
    let stop = stop_on_ctrl_c();
    let dashboard = match &a.serve {
        Some(addr) => {
            let shown: Vec<DashboardSensor<'_>> = sensors
                .iter()
                .map(|s| DashboardSensor {
                    name: &s.name,
                    calibration: s.live.calibration(),
                    targets: s.live.target_names(),
                })
                .collect();
            Some(
                visuotact_dashboard::Dashboard::start_several(addr, &shown)
                    .map_err(|e| anyhow::anyhow!("--serve {e}"))?,
            )
        }
        None => None,
    };
    let names: Vec<String> = sensors.iter().map(|s| s.name.clone()).collect();
    let mut out = Outputs::open(a, dashboard, &names)?;
    let ran = run_several(&mut sensors, &stop, &mut out.sinks(), |w| {
        note!("warning: {w}")
    });
    let finished = out.finish();
    let mut summaries = ran?;
    let (udp_errors, _) = finished?;
    for s in &mut summaries {
        s.summary.udp_send_errors = udp_errors;
        note!("sensor {}:", s.name);
        print_summary(&s.summary);
    }
    if let Some(p) = &a.summary {
        let json = serde_json::json!({ "sensors": summaries });
        crate::write_atomically(p, &serde_json::to_string_pretty(&json)?)?;
    }
    Ok(())
}

/// The sensors of run file `plan` (read from `file`), each with its estimator and source; an
/// error names the file and the sensor.
fn named_sensors(
    a: &Args,
    file: &std::path::Path,
    plan: &RunFile,
) -> anyhow::Result<Vec<NamedSensor>> {
    let names: Vec<&str> = plan.sensor.iter().map(|s| s.name.as_str()).collect();
    check_sensor_names(&names).map_err(|e| anyhow::anyhow!("--sensors {}: {e}", file.display()))?;
    let mut sensors = Vec::with_capacity(plan.sensor.len());
    for (k, s) in plan.sensor.iter().enumerate() {
        let at = |e: &dyn std::fmt::Display| {
            anyhow::anyhow!("--sensors {}: sensor {:?}: {e}", file.display(), s.name)
        };
        let models = s
            .model
            .iter()
            .map(|p| crate::load_model(p))
            .collect::<anyhow::Result<Vec<_>>>()
            .map_err(|e| at(&e))?;
        let mut est =
            crate::estimator(s.sensor.as_deref(), models.first().cloned()).map_err(|e| at(&e))?;
        est.set_temporal_prior(a.temporal);
        let mut live = LiveEstimator::new(est, models, &a.live_config()).map_err(|e| at(&e))?;
        if let Some(p) = &a.slip {
            live.set_slip(crate::load_slip(p)?).map_err(|e| at(&e))?;
        }
        let cfg = RunConfig {
            source: s.source.as_str().into(),
            seed: a.seed.wrapping_add(k as u64),
            ..a.run_config()?
        };
        cfg.validate().map_err(|e| at(&e))?;
        sensors.push(NamedSensor {
            name: s.name.clone(),
            live,
            cfg,
        });
    }
    Ok(sensors)
}

/// A flag that Ctrl-C sets: the run then ends cleanly.
fn stop_on_ctrl_c() -> Arc<AtomicBool> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let _ = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed));
    stop
}

/// Where a run's estimates go: JSON lines on standard output (unless `--quiet`), `--udp`,
/// the dashboard, `--mcap`, `--ros2`, `--foxglove` and `--rerun`.
struct Outputs {
    stdout: Option<LineSink<std::io::BufWriter<std::io::StdoutLock<'static>>>>,
    udp: Option<UdpSink>,
    dashboard: Option<visuotact_dashboard::Dashboard>,
    mcap: Option<McapSink>,
    dds: Option<DdsSink>,
    foxglove: Option<FoxgloveSink>,
    rerun: Option<visuotact_rerun::RerunSink>,
}

impl Outputs {
    /// The outputs `a` asks for, with `dashboard` when one is served, for `sensors` (the names
    /// in a run of several, else empty).
    fn open(
        a: &Args,
        dashboard: Option<visuotact_dashboard::Dashboard>,
        sensors: &[String],
    ) -> anyhow::Result<Self> {
        let udp = a
            .udp
            .as_deref()
            .map(UdpSink::connect)
            .transpose()
            .map_err(|e| anyhow::anyhow!("--udp {e}"))?;
        let (mcap, dds) = ros_sinks(a, sensors)?;
        let foxglove = a
            .foxglove
            .map(|addr| {
                foxglove_sink(&FoxgloveConfig {
                    ros: a.bag.ros.config(a.foxglove_images),
                    addr,
                    sensors: sensors.to_vec(),
                    ..FoxgloveConfig::default()
                })
            })
            .transpose()
            .map_err(|e| anyhow::anyhow!("--foxglove {e}"))?;
        if let Some(f) = &foxglove {
            note!(
                "foxglove: serving ws://{} (Foxglove: Open connection → Foxglove WebSocket)",
                f.target().addr()
            );
        }
        let rerun = a
            .rerun
            .as_deref()
            .map(|o| -> anyhow::Result<_> {
                let output = visuotact_rerun::RerunOutput::parse(o)?;
                Ok(visuotact_rerun::rerun_sink(
                    output,
                    a.bag.ros.config(a.rerun_images),
                )?)
            })
            .transpose()
            .map_err(|e| anyhow::anyhow!("--rerun {e}"))?;
        let stdout =
            (!a.quiet).then(|| LineSink(std::io::BufWriter::new(std::io::stdout().lock())));
        Ok(Self {
            stdout,
            udp,
            dashboard,
            mcap,
            dds,
            foxglove,
            rerun,
        })
    }

    /// Every output as a sink of the runner.
    fn sinks(&mut self) -> Vec<&mut dyn FrameSink> {
        let mut sinks: Vec<&mut dyn FrameSink> = Vec::new();
        if let Some(s) = self.stdout.as_mut() {
            sinks.push(s);
        }
        if let Some(s) = self.udp.as_mut() {
            sinks.push(s);
        }
        if let Some(d) = self.dashboard.as_mut() {
            sinks.push(d);
        }
        if let Some(m) = self.mcap.as_mut() {
            sinks.push(m);
        }
        if let Some(d) = self.dds.as_mut() {
            sinks.push(d);
        }
        if let Some(f) = self.foxglove.as_mut() {
            sinks.push(f);
        }
        if let Some(r) = self.rerun.as_mut() {
            sinks.push(r);
        }
        sinks
    }

    /// Flushes standard output and closes the bag and the DDS participant: the UDP datagrams
    /// that could not be sent, and the dashboard (still serving).
    fn finish(self) -> anyhow::Result<(u64, Option<visuotact_dashboard::Dashboard>)> {
        drop(self.stdout);
        finish_ros_sinks(self.mcap, self.dds)?;
        if let Some(f) = self.foxglove {
            let n = finish_foxglove(f).map_err(|e| anyhow::anyhow!("--foxglove {e}"))?;
            note!("served {n} messages to Foxglove");
        }
        if let Some(r) = self.rerun {
            let n = visuotact_rerun::finish_sink(r).map_err(|e| anyhow::anyhow!("--rerun {e}"))?;
            note!("logged {n} frames to Rerun");
        }
        Ok((self.udp.map_or(0, |u| u.errors), self.dashboard))
    }
}
