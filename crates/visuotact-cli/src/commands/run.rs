//! `visuotact run`: live estimation. A source thread captures frames into a small queue that
//! never holds stale frames (when full, the oldest frame is dropped and counted); the estimator
//! takes the newest, extracts features, re-zeroes them against the no-contact baseline, decides
//! contact, runs the model (or an ensemble: mean and standard deviation) and sends the estimate
//! to stdout (JSON lines), UDP and the dashboard's WebSocket.
//!
//! Latency is measured per frame from the capture timestamp to the finished estimate, and the
//! processing time from the frame in memory to the estimate; both are summarised (median, p99)
//! at the end and on the dashboard.

use std::io::Write;
use std::net::UdpSocket;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use serde::Serialize;
use visuotact_image::RgbImage;
use visuotact_io::camera::CameraRequest;
use visuotact_io::frames::FrameStream;
use visuotact_io::source::SourceSpec;

use visuotact_pipeline::queue::median_p99;
use visuotact_pipeline::{
    Captured, LatestQueue, LiveConfig, LiveEstimate, LiveEstimator, LiveFrame,
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
    /// sim:iats, sim:cone, video:FILE, frames:DIR (or a path), camera:/dev/videoN.
    #[arg(long)]
    source: String,
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
    /// Simulated sources: distinct frames rendered up front and cycled.
    #[arg(long, default_value_t = 100)]
    sim_frames: usize,
    /// Write the run's summary (latency, drops, counts) as JSON to this file.
    #[arg(long)]
    summary: Option<PathBuf>,
}

/// A frame source, opened (simulated frames rendered, files found) but not started.
enum Source {
    Sim(Vec<(String, Arc<RgbImage>)>),
    Camera(String),
    Stream(FrameStream),
}

impl Source {
    fn open(a: &Args) -> anyhow::Result<Self> {
        Ok(match SourceSpec::parse(&a.source) {
            SourceSpec::Sim(kind) => {
                let frames = visuotact_sim::rig::live_frames(&kind, a.sim_frames, a.seed)
                    .map_err(|e| anyhow::anyhow!("--source {e}"))?
                    .into_iter()
                    .map(|(id, img)| (id, Arc::new(img)))
                    .collect();
                Self::Sim(frames)
            }
            SourceSpec::Camera(dev) => Self::Camera(dev),
            SourceSpec::Frames(path) => Self::Stream(FrameStream::open(&[path], a.fps)?),
        })
    }

    /// Starts the capture thread; frames are paced on `clock` unless `--unpaced`.
    fn spawn(
        self,
        a: &Args,
        queue: Arc<LatestQueue<Captured>>,
        stop: Arc<AtomicBool>,
        clock: Instant,
    ) -> anyhow::Result<std::thread::JoinHandle<u64>> {
        let period = Duration::from_secs_f64(1.0 / a.fps);
        let paced = !a.unpaced;
        let max = a.max_frames.unwrap_or(u64::MAX);
        let pace = move |k: u64| {
            if paced {
                let due = period.mul_f64(k as f64);
                let el = clock.elapsed();
                if due > el {
                    std::thread::sleep(due - el);
                }
            }
        };
        // Paced sources behave like cameras (the oldest frame goes when the estimator is
        // behind); unpaced ones wait for it, so every frame is estimated.
        let push =
            move |queue: &LatestQueue<Captured>, id: String, k: u64, image: Arc<RgbImage>| {
                let captured = Instant::now();
                let c = Captured {
                    id,
                    index: k,
                    timestamp_s: (captured - clock).as_secs_f64(),
                    captured,
                    image,
                };
                if paced {
                    queue.push(c);
                } else {
                    queue.push_wait(c);
                }
            };
        Ok(match self {
            Self::Sim(frames) => std::thread::spawn(move || {
                let mut k = 0u64;
                while k < max && !stop.load(Ordering::Relaxed) {
                    pace(k);
                    let (id, img) = &frames[(k % frames.len() as u64) as usize];
                    // A camera's driver or decoder writes each frame just before it is
                    // delivered; so does the simulated camera (a copy, not a shared buffer).
                    push(
                        &queue,
                        format!("{id}#{k}"),
                        k,
                        Arc::new(RgbImage::clone(img)),
                    );
                    k += 1;
                }
                queue.close();
                k
            }),
            Self::Camera(dev) => {
                let req =
                    CameraRequest::parse(a.camera_size.as_deref(), a.camera_format.as_deref())
                        .map_err(|e| anyhow::anyhow!("--camera-size/--camera-format: {e}"))?;
                visuotact_io::camera::spawn(&dev, req, a.fps, queue, stop, clock, max)?
            }
            Self::Stream(stream) => std::thread::spawn(move || {
                let mut k = 0u64;
                for item in stream {
                    if k >= max || stop.load(Ordering::Relaxed) {
                        break;
                    }
                    let fr = match item {
                        Ok(f) => f,
                        Err(e) => {
                            eprintln!("warning: {e}; skipped");
                            continue;
                        }
                    };
                    pace(k);
                    push(&queue, fr.id, k, Arc::new(fr.image));
                    k += 1;
                }
                queue.close();
                k
            }),
        })
    }
}

/// What a run reports at the end.
#[derive(Clone, Debug, Default, Serialize)]
pub(crate) struct Summary {
    pub frames_captured: u64,
    pub frames_estimated: u64,
    pub frames_dropped: u64,
    pub contact_frames: u64,
    pub latency_ms_median: f64,
    pub latency_ms_p99: f64,
    pub processing_ms_median: f64,
    pub processing_ms_p99: f64,
    pub udp_send_errors: u64,
    pub websocket_messages_dropped: u64,
    pub seconds: f64,
    /// Resident memory after the first 1 000 estimates, KiB.
    pub rss_kib_after_1000: Option<u64>,
    /// Largest resident memory seen (sampled every 1 000 estimates), KiB.
    pub max_rss_kib: Option<u64>,
}

/// Resident set size of this process, KiB (Linux).
pub(crate) fn rss_kib() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    s.lines()
        .find(|l| l.starts_with("VmRSS:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()
}

impl Args {
    fn live_config(&self) -> LiveConfig {
        LiveConfig {
            contact_sigmas: self.contact_sigmas,
            contact_min_px: self.contact_min_px,
            contact_markers: self.contact_markers,
            rezero_rate: self.rezero_rate,
        }
    }
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    if !(a.fps.is_finite() && a.fps > 0.0) {
        bail!("--fps must be a positive frame rate");
    }
    // A model file holding an ensemble counts as its networks (the spread is over all).
    let models = a
        .model
        .iter()
        .map(|p| crate::load_model(p))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut est = crate::estimator(a.sensor.as_deref(), models.first().cloned())?;
    est.set_temporal_prior(a.temporal);
    let mut live = LiveEstimator::new(est, models, &a.live_config())?;
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        let _ = ctrlc::set_handler(move || stop.store(true, Ordering::Relaxed));
    }
    let udp = match &a.udp {
        Some(addr) => {
            let s = UdpSocket::bind("0.0.0.0:0").context("cannot open a UDP socket")?;
            s.connect(addr)
                .with_context(|| format!("--udp {addr}: cannot address it"))?;
            s.set_nonblocking(true)?;
            Some(s)
        }
        None => None,
    };
    let dashboard = match &a.serve {
        Some(addr) => Some(
            visuotact_dashboard::Dashboard::start(addr, live.calibration(), live.target_names())
                .map_err(|e| anyhow::anyhow!("--serve {e}"))?,
        ),
        None => None,
    };
    let queue = Arc::new(LatestQueue::new(a.queue));
    let source = Source::open(a)?;
    let clock = Instant::now();
    let source = source.spawn(a, queue.clone(), stop.clone(), clock)?;
    let mut summary = Summary::default();
    let (mut lat, mut proc) = (Vec::new(), Vec::new());
    let mut markers = Vec::new();
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let deadline = a.duration_s.map(|d| clock + Duration::from_secs_f64(d));
    let mut max_rss = 0u64;
    while let Some(cap) = queue.pop() {
        if deadline.is_some_and(|d| Instant::now() >= d) {
            stop.store(true, Ordering::Relaxed);
        }
        let t_proc = Instant::now();
        if let Some(d) = dashboard.as_ref().filter(|d| d.take_rezero()) {
            live.rezero_now();
            d.rezero_applied();
        }
        let want_markers = dashboard.as_ref().is_some_and(|d| d.has_clients());
        let result = live.process(&cap.image, want_markers.then_some(&mut markers));
        let done = Instant::now();
        let LiveFrame {
            contact,
            max_displacement_px,
            targets,
            health,
        } = match result {
            Ok(r) => r,
            Err(e) => {
                eprintln!("warning: frame {}: {e}", cap.id);
                continue;
            }
        };
        let e = LiveEstimate {
            frame: cap.id,
            index: cap.index,
            timestamp_s: cap.timestamp_s,
            latency_ms: (done - cap.captured).as_secs_f64() * 1e3,
            processing_ms: (done - t_proc).as_secs_f64() * 1e3,
            contact,
            max_displacement_px,
            targets,
            health,
            dropped_frames: queue.dropped(),
        };
        lat.push(e.latency_ms);
        proc.push(e.processing_ms);
        summary.frames_estimated += 1;
        summary.contact_frames += u64::from(contact);
        let line = serde_json::to_string(&e)?;
        if !a.quiet {
            // A closed pipe (the consumer went away) ends the run cleanly.
            if writeln!(out, "{line}").and_then(|()| out.flush()).is_err() {
                stop.store(true, Ordering::Relaxed);
            }
        }
        if let Some(s) = &udp {
            if s.send(line.as_bytes()).is_err() {
                summary.udp_send_errors += 1;
            }
        }
        if let Some(d) = &dashboard {
            d.publish(&line, want_markers.then_some(&markers[..]), &cap.image);
        }
        if summary.frames_estimated % 1000 == 0 {
            let rss = rss_kib();
            if summary.frames_estimated == 1000 {
                summary.rss_kib_after_1000 = rss;
            }
            max_rss = max_rss.max(rss.unwrap_or(0));
        }
        if stop.load(Ordering::Relaxed) && deadline.is_some() {
            break;
        }
    }
    stop.store(true, Ordering::Relaxed);
    queue.close();
    summary.frames_captured = source
        .join()
        .map_err(|_| anyhow::anyhow!("the capture thread stopped unexpectedly"))?;
    summary.frames_dropped = queue.dropped();
    (summary.latency_ms_median, summary.latency_ms_p99) = median_p99(&mut lat);
    (summary.processing_ms_median, summary.processing_ms_p99) = median_p99(&mut proc);
    summary.seconds = clock.elapsed().as_secs_f64();
    summary.websocket_messages_dropped = dashboard.as_ref().map_or(0, |d| d.dropped());
    summary.max_rss_kib = Some(max_rss.max(rss_kib().unwrap_or(0)));
    drop(out);
    eprintln!(
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
    if let Some(p) = &a.summary {
        crate::write_atomically(p, &serde_json::to_string_pretty(&summary)?)?;
    }
    if let Some(d) = dashboard {
        d.stop();
    }
    Ok(())
}
