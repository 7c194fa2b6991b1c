//! The live runner: a source thread captures frames into a small queue that never holds stale
//! frames (when full, the oldest frame is dropped and counted); the [`LiveEstimator`] takes the
//! newest, and each estimate goes to the [`FrameSink`]s (standard output, UDP, a dashboard) with
//! its JSON line.
//!
//! Latency is measured per frame from the capture timestamp to the finished estimate, and the
//! processing time from the frame in memory to the estimate; both are summarised (median, p99)
//! in the [`RunSummary`]. Setting `stop` ends a run cleanly, as does a sink that asks to.

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use serde::Serialize;
use visuotact_io::camera::CameraRequest;
use visuotact_io::queue::{median_p99, Captured, LatestQueue};
use visuotact_io::source::SourceSpec;

use crate::live::{LiveEstimate, LiveEstimator, LiveFrame, MarkerView};
use crate::sink::{FrameSink, SinkError, SinkFrame};
use crate::source::{FrameSource, Next, Pacing, SourceConfig, SourceError};

/// Where frames come from and how fast.
#[derive(Clone, Debug)]
pub struct RunConfig {
    /// Frame source (`"sim:iats".into()`, or [`SourceSpec::parse`] of what a user wrote).
    pub source: SourceSpec,
    /// Frame rate of simulated cameras and image sequences, frames per second.
    pub fps: f64,
    /// The camera's size and format.
    pub camera: CameraRequest,
    /// Deliver frames as fast as they can be processed (every frame is then estimated: the
    /// source waits instead of dropping), not at the camera rate.
    pub unpaced: bool,
    /// Stop after this many frames.
    pub max_frames: Option<u64>,
    /// Stop after this many seconds.
    pub duration_s: Option<f64>,
    /// Frames the capture queue holds before dropping the oldest.
    pub queue: usize,
    /// Simulated sources: seed.
    pub seed: u64,
    /// Simulated sources: distinct frames cycled (the first [`SIM_FRAMES_UP_FRONT`] rendered
    /// before the run starts, the rest as they come round; at most [`MAX_SIM_FRAMES`]).
    pub sim_frames: usize,
}

pub use crate::source::SIM_FRAMES_UP_FRONT;

/// Most distinct frames a simulated source loops over.
pub const MAX_SIM_FRAMES: usize = 1_000_000;

/// Most frames the capture queue may hold (`run --queue`).
pub const MAX_QUEUE: usize = 1_000;

impl Default for RunConfig {
    fn default() -> Self {
        Self {
            source: "sim:iats".into(),
            fps: 25.0,
            camera: CameraRequest::default(),
            unpaced: false,
            max_frames: None,
            duration_s: None,
            queue: 2,
            seed: 1,
            sim_frames: 100,
        }
    }
}

impl RunConfig {
    /// Checks the rate, the duration (returned) and the counts before anything starts.
    pub fn validate(&self) -> Result<Option<Duration>, RunError> {
        crate::rate("fps", self.fps).map_err(RunError::Config)?;
        if self.max_frames == Some(0) || self.queue == 0 || self.sim_frames == 0 {
            return Err(RunError::Config(
                "max_frames, queue and sim_frames must be at least 1".into(),
            ));
        }
        if self.queue > MAX_QUEUE {
            return Err(RunError::Config(format!(
                "queue {}: at most {MAX_QUEUE} frames wait (each holds a whole image; a \
                 longer queue only adds latency)",
                self.queue
            )));
        }
        if self.sim_frames > MAX_SIM_FRAMES {
            return Err(RunError::Config(format!(
                "sim_frames {}: a simulated source loops over at most {MAX_SIM_FRAMES} frames",
                self.sim_frames
            )));
        }
        self.duration_s
            .map(|d| crate::seconds("duration_s", d))
            .transpose()
            .map_err(RunError::Config)
    }
}

/// Why a run could not start.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// A setting is out of range.
    #[error("{0}")]
    Config(String),
    /// The source could not be opened.
    #[error(transparent)]
    Source(#[from] SourceError),
    /// A sink failed: the run stopped there (what the sinks wrote stays).
    #[error(transparent)]
    Sink(#[from] SinkError),
    /// The capture thread stopped unexpectedly.
    #[error("the capture thread stopped unexpectedly")]
    Capture,
    /// The source gave no frame (nothing readable, or stopped at once).
    #[error("{0}: the source gave no frame")]
    NoFrames(String),
    /// Frames came but none could be estimated: the run produced no result.
    #[error(
        "{source_name}: none of the {captured} frames captured could be estimated (first: {first})"
    )]
    NoEstimate {
        /// The source.
        source_name: String,
        /// Frames the source delivered.
        captured: u64,
        /// Why the first frame could not be estimated.
        first: String,
    },
}

/// JSON lines to a writer (standard output); a write error (the consumer went away, a closed
/// pipe) ends the run.
pub struct LineSink<W: std::io::Write>(pub W);

impl<W: std::io::Write> FrameSink for LineSink<W> {
    fn frame(&mut self, f: &SinkFrame<'_>) -> Result<ControlFlow<()>, SinkError> {
        let Some(json) = f.json else {
            return Ok(ControlFlow::Continue(()));
        };
        Ok(
            match writeln!(self.0, "{json}").and_then(|()| self.0.flush()) {
                Ok(()) => ControlFlow::Continue(()),
                Err(_) => ControlFlow::Break(()),
            },
        )
    }
}

/// One UDP datagram (the JSON line) per estimate, never blocking; send errors are counted.
pub struct UdpSink {
    socket: std::net::UdpSocket,
    /// Datagrams that could not be sent.
    pub errors: u64,
}

impl UdpSink {
    /// A sink sending to `addr` (`HOST:PORT`).
    pub fn connect(addr: &str) -> std::io::Result<Self> {
        let socket = std::net::UdpSocket::bind("0.0.0.0:0")?;
        socket.connect(addr).map_err(|e| {
            std::io::Error::new(e.kind(), format!("{addr}: cannot address it: {e}"))
        })?;
        socket.set_nonblocking(true)?;
        Ok(Self { socket, errors: 0 })
    }
}

impl FrameSink for UdpSink {
    fn frame(&mut self, f: &SinkFrame<'_>) -> Result<ControlFlow<()>, SinkError> {
        if let Some(json) = f.json {
            if self.socket.send(json.as_bytes()).is_err() {
                self.errors += 1;
            }
        }
        Ok(ControlFlow::Continue(()))
    }
}

/// What a run reports at the end.
#[derive(Clone, Debug, Default, Serialize)]
pub struct RunSummary {
    /// Frames the source delivered.
    pub frames_captured: u64,
    /// Frames estimated.
    pub frames_estimated: u64,
    /// Frames dropped by the queue (the estimator was behind).
    pub frames_dropped: u64,
    /// Estimates with contact.
    pub contact_frames: u64,
    /// Capture → estimate, ms: median.
    pub latency_ms_median: f64,
    /// Capture → estimate, ms: 99th percentile.
    pub latency_ms_p99: f64,
    /// Frame in memory → estimate, ms: median.
    pub processing_ms_median: f64,
    /// Frame in memory → estimate, ms: 99th percentile.
    pub processing_ms_p99: f64,
    /// UDP datagrams that could not be sent (filled in by the caller's sink).
    pub udp_send_errors: u64,
    /// Dashboard messages lost by slow clients (filled in by the caller).
    pub websocket_messages_dropped: u64,
    /// Wall-clock time, s.
    pub seconds: f64,
    /// Resident memory after the first 1 000 estimates, KiB.
    pub rss_kib_after_1000: Option<u64>,
    /// Largest resident memory seen (sampled every 1 000 estimates), KiB.
    pub max_rss_kib: Option<u64>,
}

/// Resident set size of this process, KiB (Linux; `None` elsewhere).
pub fn rss_kib() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    s.lines()
        .find(|l| l.starts_with("VmRSS:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()
}

impl RunConfig {
    /// The source as the run opens it: paced on the run's clock unless `unpaced` (a paced
    /// source behaves like a camera, whose oldest frame goes when the estimator is behind).
    pub fn source_config(&self) -> SourceConfig {
        SourceConfig {
            source: self.source.clone(),
            fps: self.fps,
            pacing: if self.unpaced {
                Pacing::Free
            } else {
                Pacing::Clock { drop_late: false }
            },
            camera: self.camera,
            camera_queue: self.queue,
            max_frames: self.max_frames,
            seed: self.seed,
            sim_frames: self.sim_frames,
        }
    }
}

/// Starts the capture thread: it moves the source's frames into `queue` (paced sources drop
/// the oldest frame when the estimator is behind, as a camera does; unpaced ones wait for
/// it, so every frame is estimated) until the source ends or `stop` is set, and returns how
/// many it delivered and how many the source itself dropped.
fn spawn_capture(
    mut source: FrameSource,
    paced: bool,
    queue: Arc<LatestQueue<Captured>>,
    (stop, clock): (Arc<AtomicBool>, Instant),
    warn: impl Fn(&str) + Send + 'static,
) -> JoinHandle<(u64, u64)> {
    std::thread::spawn(move || {
        let mut delivered = 0u64;
        while !stop.load(Ordering::Relaxed) {
            match source.next_frame() {
                Ok(Next::Frame(f)) => {
                    let c = Captured {
                        id: f.frame.id,
                        index: f.frame.index as u64,
                        timestamp_s: (f.delivered - clock).as_secs_f64(),
                        captured: f.delivered,
                        image: Arc::new(f.frame.image),
                    };
                    if paced {
                        queue.push(c);
                    } else {
                        queue.push_wait(c);
                    }
                    delivered += 1;
                }
                Ok(Next::Dropped) => {}
                Ok(Next::Unreadable(why)) => warn(&format!("{why}; skipped")),
                Ok(Next::End) => break,
                Err(e) => {
                    warn(&format!("{e}; the source stops"));
                    break;
                }
            }
        }
        queue.close();
        source.close();
        (delivered, source.dropped())
    })
}

/// Runs `live` over the source until it ends, a limit is reached, `stop` is set or a sink
/// breaks; `warn` hears of frames skipped.
pub fn run(
    live: &mut LiveEstimator,
    cfg: &RunConfig,
    stop: &Arc<AtomicBool>,
    sinks: &mut [&mut dyn FrameSink],
    warn: impl Fn(&str) + Send + Clone + 'static,
) -> Result<RunSummary, RunError> {
    let run_for = cfg.validate()?;
    let queue = Arc::new(LatestQueue::new(cfg.queue));
    let source = FrameSource::open(&cfg.source_config(), stop)?;
    let clock = source.clock();
    let on = (stop.clone(), clock);
    let capture = spawn_capture(source, !cfg.unpaced, queue.clone(), on, warn.clone());
    let deadline = run_for.and_then(|d| clock.checked_add(d));
    let mut stats = Stats::default();
    while let Some(cap) = queue.pop() {
        if deadline.is_some_and(|d| Instant::now() >= d) {
            stop.store(true, Ordering::Relaxed);
        }
        if estimate_one(live, cap, &queue, sinks, &mut stats, &warn).is_break() {
            // A sink asked to stop or failed: no sink hears a later frame.
            stop.store(true, Ordering::Relaxed);
            break;
        }
        if stop.load(Ordering::Relaxed) && deadline.is_some() {
            break;
        }
    }
    stop.store(true, Ordering::Relaxed);
    queue.close();
    let (captured, source_dropped) = capture.join().map_err(|_| RunError::Capture)?;
    if let Some(e) = stats.sink_error.take() {
        return Err(e.into());
    }
    if captured == 0 {
        return Err(RunError::NoFrames(cfg.source.to_string()));
    }
    if stats.latency_ms.is_empty() {
        if let Some(first) = stats.first_error.take() {
            return Err(RunError::NoEstimate {
                source_name: cfg.source.to_string(),
                captured,
                first,
            });
        }
    }
    Ok(stats.summary(captured, queue.dropped() + source_dropped, clock))
}

/// What the loop gathers for the summary.
#[derive(Default)]
struct Stats {
    latency_ms: Vec<f64>,
    processing_ms: Vec<f64>,
    contact: u64,
    rss_after_1000: Option<u64>,
    max_rss: u64,
    markers: Vec<MarkerView>,
    /// Why the first frame that could not be estimated could not.
    first_error: Option<String>,
    /// The first sink's failure (it stopped the run).
    sink_error: Option<SinkError>,
}

impl Stats {
    fn summary(mut self, captured: u64, dropped: u64, clock: Instant) -> RunSummary {
        let mut s = RunSummary {
            frames_captured: captured,
            frames_estimated: self.latency_ms.len() as u64,
            frames_dropped: dropped,
            contact_frames: self.contact,
            seconds: clock.elapsed().as_secs_f64(),
            rss_kib_after_1000: self.rss_after_1000,
            max_rss_kib: Some(self.max_rss.max(rss_kib().unwrap_or(0))),
            ..RunSummary::default()
        };
        (s.latency_ms_median, s.latency_ms_p99) = median_p99(&mut self.latency_ms);
        (s.processing_ms_median, s.processing_ms_p99) = median_p99(&mut self.processing_ms);
        s
    }
}

/// Estimates one captured frame and sends it to every sink.
fn estimate_one(
    live: &mut LiveEstimator,
    cap: Captured,
    queue: &LatestQueue<Captured>,
    sinks: &mut [&mut dyn FrameSink],
    stats: &mut Stats,
    warn: &impl Fn(&str),
) -> ControlFlow<()> {
    let t_proc = Instant::now();
    if sinks.iter_mut().any(|s| s.take_rezero()) {
        live.rezero_now();
        sinks.iter_mut().for_each(|s| s.rezero_applied());
    }
    let want_markers = sinks.iter().any(|s| s.wants_markers());
    let result = live.process(&cap.image, want_markers.then_some(&mut stats.markers));
    let done = Instant::now();
    let LiveFrame {
        contact,
        max_displacement_px,
        targets,
        health,
        slip,
    } = match result {
        Ok(r) => r,
        Err(e) => {
            let why = format!("frame {}: {e}", cap.id);
            warn(&why);
            stats.first_error.get_or_insert(why);
            return ControlFlow::Continue(());
        }
    };
    let e = LiveEstimate {
        sensor: live.sensor_name().map(str::to_string),
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
        slip,
        mm_per_px: live.calibration().mm_per_px(),
    };
    stats.latency_ms.push(e.latency_ms);
    stats.processing_ms.push(e.processing_ms);
    stats.contact += u64::from(contact);
    let n = stats.latency_ms.len();
    if n.is_multiple_of(1000) {
        let rss = rss_kib();
        if n == 1000 {
            stats.rss_after_1000 = rss;
        }
        stats.max_rss = stats.max_rss.max(rss.unwrap_or(0));
    }
    if sinks.is_empty() {
        return ControlFlow::Continue(());
    }
    // An estimate is plain numbers and strings: it always serialises (once, for every sink).
    let json = serde_json::to_string(&e).unwrap_or_default();
    let frame = SinkFrame {
        id: &e.frame,
        index: e.index,
        timestamp_s: e.timestamp_s,
        image: &cap.image,
        estimate: Some(&e),
        json: Some(&json),
        markers: want_markers.then_some(&stats.markers[..]),
        rows: None,
    };
    let mut flow = ControlFlow::Continue(());
    for s in sinks.iter_mut() {
        match s.frame(&frame) {
            Ok(ControlFlow::Continue(())) => {}
            Ok(ControlFlow::Break(())) => flow = ControlFlow::Break(()),
            Err(e) => {
                stats.sink_error.get_or_insert(e);
                flow = ControlFlow::Break(());
            }
        }
    }
    flow
}

#[cfg(all(test, not(feature = "sim")))]
mod tests {
    use std::sync::atomic::AtomicBool;
    use std::sync::Arc;

    use super::RunConfig;
    use crate::source::FrameSource;

    #[test]
    fn a_simulated_source_is_refused_without_the_simulator() {
        let cfg = RunConfig {
            source: "sim:iats".into(),
            ..RunConfig::default()
        };
        let stop = Arc::new(AtomicBool::new(false));
        let err = FrameSource::open(&cfg.source_config(), &stop)
            .err()
            .unwrap();
        assert!(
            err.to_string()
                .contains("sim:iats: this build has no simulator"),
            "{err}"
        );
    }
}
