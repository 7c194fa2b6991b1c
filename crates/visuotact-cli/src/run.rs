//! `visuotact run`: live estimation. A source thread captures frames into a small queue that
//! never holds stale frames (when full, the oldest frame is dropped and counted); the estimator
//! takes the newest, extracts features, re-zeroes them against the no-contact baseline, decides
//! contact, runs the model (or an ensemble: mean and standard deviation) and sends the estimate
//! to stdout (JSON lines), UDP and the dashboard's WebSocket.
//!
//! Latency is measured per frame from the capture timestamp to the finished estimate, and the
//! processing time from the frame in memory to the estimate; both are summarised (median, p99)
//! at the end and on the dashboard.

use std::collections::VecDeque;
use std::io::Write;
use std::net::UdpSocket;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use rayon::prelude::*;
use serde::Serialize;
use visuotact_image::RgbImage;
use visuotact_io::frames::FrameStream;
use visuotact_nn::model::Model;
use visuotact_vision::features::{FieldSummary, FIELD_COLUMNS};
use visuotact_vision::track::MarkerStatus;

use crate::live::Estimator;

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

/// A captured frame.
pub(crate) struct Captured {
    pub id: String,
    pub index: u64,
    /// Capture time on the run's clock, seconds.
    pub timestamp_s: f64,
    pub captured: Instant,
    pub image: Arc<RgbImage>,
}

/// A bounded queue that drops its oldest item when full: the estimator always gets the
/// freshest frames and never works through a backlog.
pub(crate) struct LatestQueue<T> {
    inner: Mutex<(VecDeque<T>, bool)>,
    ready: Condvar,
    cap: usize,
    dropped: AtomicU64,
}

impl<T> LatestQueue<T> {
    pub(crate) fn new(cap: usize) -> Self {
        Self {
            inner: Mutex::new((VecDeque::with_capacity(cap.max(1)), false)),
            ready: Condvar::new(),
            cap: cap.max(1),
            dropped: AtomicU64::new(0),
        }
    }

    /// Adds an item, dropping the oldest when full.
    pub(crate) fn push(&self, item: T) {
        let mut g = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        if g.0.len() >= self.cap {
            g.0.pop_front();
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
        g.0.push_back(item);
        self.ready.notify_one();
    }

    /// Adds an item, waiting while the queue is full (a source that must not lose frames:
    /// files and simulations run unpaced).
    pub(crate) fn push_wait(&self, item: T) {
        let mut g = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        while g.0.len() >= self.cap && !g.1 {
            g = self.ready.wait(g).unwrap_or_else(|e| e.into_inner());
        }
        g.0.push_back(item);
        self.ready.notify_all();
    }

    /// No more items will come.
    pub(crate) fn close(&self) {
        let mut g = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        g.1 = true;
        self.ready.notify_all();
    }

    /// The next item, waiting; `None` once closed and empty.
    pub(crate) fn pop(&self) -> Option<T> {
        let mut g = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        loop {
            if let Some(x) = g.0.pop_front() {
                self.ready.notify_all();
                return Some(x);
            }
            if g.1 {
                return None;
            }
            g = self.ready.wait(g).unwrap_or_else(|e| e.into_inner());
        }
    }

    /// Items dropped so far.
    pub(crate) fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

/// One target's estimate.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub(crate) struct TargetEstimate {
    pub name: String,
    pub value: f64,
    /// Standard deviation over the ensemble (absent with one model).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub std: Option<f64>,
}

/// Marker health counts.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub(crate) struct Health {
    pub ok: usize,
    pub lost: usize,
    pub merged: usize,
    pub ambiguous: usize,
    /// Markers split from a merged pair: a position, no area.
    pub split: usize,
    /// Inputs the model filled this frame (lost markers, from the markers found).
    pub filled: usize,
    /// Markers whose no-contact baseline moved away from the calibration.
    pub drifting: usize,
    /// The sensor's reference was taken under contact (`calibrate --reference lightest:N`
    /// on a data set with no contact-free frame): displacements are relative to a lightly
    /// pressed skin.
    pub reference_under_contact: bool,
}

/// One estimate, as sent on every output.
#[derive(Clone, Debug, Serialize)]
pub(crate) struct Estimate {
    pub frame: String,
    pub index: u64,
    pub timestamp_s: f64,
    /// Capture → estimate, milliseconds.
    pub latency_ms: f64,
    /// Frame in memory → estimate, milliseconds.
    pub processing_ms: f64,
    pub contact: bool,
    /// Largest marker displacement from the baseline, pixels.
    pub max_displacement_px: f64,
    /// Targets (empty when there is no contact or a needed marker was lost).
    pub targets: Vec<TargetEstimate>,
    pub health: Health,
    /// Frames dropped by the capture queue so far.
    pub dropped_frames: u64,
}

/// Marker drawing data for the dashboard: position, displacement from the baseline, status.
#[derive(Clone, Debug, Serialize)]
pub(crate) struct MarkerView {
    pub x: f32,
    pub y: f32,
    pub dx: f32,
    pub dy: f32,
    pub ok: bool,
}

/// The per-frame estimator state: baseline, contact rule, ensemble.
pub(crate) struct LiveEstimator {
    /// The markers' rest positions (the field summary's centroid).
    rest_px: Vec<(f64, f64)>,
    est: Estimator,
    ensemble: Vec<Model>,
    cols: Vec<Vec<usize>>,
    baseline: Vec<f64>,
    jitter: Vec<f64>,
    /// Indices of each marker's dx and dy in the feature vector.
    xy: Vec<Option<(usize, usize)>>,
    /// Calibrated marker positions, pixels.
    marker_px: Vec<(f32, f32)>,
    contact_sigmas: f64,
    contact_min_px: f64,
    contact_markers: usize,
    rezero_rate: f64,
    zeroed: Vec<f64>,
}

impl LiveEstimator {
    pub(crate) fn new(a: &Args, models: Vec<Model>) -> anyhow::Result<Self> {
        let mut est = crate::live::estimator(a.sensor.as_deref(), models.first().cloned())?;
        est.set_temporal_prior(a.temporal);
        let names = est.feature_columns();
        let cols = models
            .iter()
            .enumerate()
            .map(|(k, m)| {
                est.columns_of(m)
                    .with_context(|| format!("model {} of the ensemble", k + 1))
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
        if models
            .iter()
            .any(|m| m.target_columns != models[0].target_columns)
        {
            bail!("the ensemble's models estimate different targets");
        }
        let set = est.feature_set();
        let per_marker = [set.dx, set.dy, set.area, set.eccentricity]
            .iter()
            .filter(|b| **b)
            .count();
        let cal = est.calibration();
        let xy = (0..cal.markers.len())
            .map(|m| (set.dx && set.dy).then_some((m * per_marker, m * per_marker + 1)))
            .collect();
        let marker_px: Vec<(f32, f32)> = cal
            .markers
            .iter()
            .map(|m| (m.x_px as f32, m.y_px as f32))
            .collect();
        let jitter: Vec<f64> = cal
            .markers
            .iter()
            .map(|m| m.jitter_px.unwrap_or(0.0))
            .collect();
        let rest_px = cal.markers.iter().map(|m| (m.x_px, m.y_px)).collect();
        Ok(Self {
            rest_px,
            baseline: vec![0.0; names.len()],
            est,
            ensemble: models,
            cols,
            jitter,
            xy,
            marker_px,
            contact_sigmas: a.contact_sigmas,
            contact_min_px: a.contact_min_px,
            contact_markers: a.contact_markers.max(1),
            rezero_rate: a.rezero_rate,
            zeroed: Vec::new(),
        })
    }

    pub(crate) fn target_names(&self) -> Vec<String> {
        self.ensemble
            .first()
            .map(|m| m.target_columns.clone())
            .unwrap_or_default()
    }

    /// Sets the baseline to the current frame's features (the re-zero button).
    pub(crate) fn rezero_now(&mut self) {
        let n = self.marker_values();
        for (b, z) in self.baseline[..n].iter_mut().zip(&self.zeroed) {
            if z.is_finite() {
                *b += z;
            }
        }
    }

    /// How many feature values are the markers' (the field summary follows them).
    fn marker_values(&self) -> usize {
        self.baseline.len().saturating_sub(FIELD_COLUMNS.len())
    }

    /// Processes one frame; `markers` gets the drawing data when asked for.
    pub(crate) fn process(
        &mut self,
        img: &RgbImage,
        markers: Option<&mut Vec<MarkerView>>,
    ) -> anyhow::Result<(bool, f64, Vec<TargetEstimate>, Health)> {
        let under_contact = self.est.calibration().reference.under_contact;
        // Features only: the ensemble below predicts on the re-zeroed ones.
        let f = self.est.features(img)?;
        // Re-zeroed features.
        self.zeroed.clear();
        self.zeroed
            .extend(f.values.iter().zip(&self.baseline).map(|(v, b)| v - b));
        // The field summary of the re-zeroed displacements (the baseline never moves it).
        // (`f` still borrows the estimator: the count is taken from the baseline directly.)
        let n = self.baseline.len().saturating_sub(FIELD_COLUMNS.len());
        if self.zeroed.len() == n + FIELD_COLUMNS.len() && self.xy.iter().all(Option::is_some) {
            let zeroed = &self.zeroed;
            let field = FieldSummary::of(self.rest_px.iter().zip(&self.xy).map(|(&p, xy)| {
                let d = xy
                    .map(|(ix, iy)| (zeroed[ix], zeroed[iy]))
                    .filter(|d| d.0.is_finite() && d.1.is_finite());
                (p, d)
            }));
            self.zeroed[n..].copy_from_slice(&field.map_or([f64::NAN; 6], |f| f.values()));
        }
        let mut health = Health {
            reference_under_contact: under_contact,
            ..Health::default()
        };
        let mut max_disp = 0.0f64;
        let mut moved = 0usize;
        for (m, st) in f.status.iter().enumerate() {
            match st {
                MarkerStatus::Ok => health.ok += 1,
                MarkerStatus::Lost => health.lost += 1,
                MarkerStatus::Merged => health.merged += 1,
                MarkerStatus::Ambiguous => health.ambiguous += 1,
                MarkerStatus::Split => health.split += 1,
            }
            if let Some((ix, iy)) = self.xy[m] {
                let (dx, dy) = (self.zeroed[ix], self.zeroed[iy]);
                let d = dx.hypot(dy);
                if d.is_finite() {
                    max_disp = max_disp.max(d);
                    if d > self
                        .contact_min_px
                        .max(self.contact_sigmas * self.jitter[m])
                    {
                        moved += 1;
                    }
                }
                let drift = self.baseline[ix].hypot(self.baseline[iy]);
                if drift > 0.5f64.max(3.0 * self.jitter[m]) {
                    health.drifting += 1;
                }
            }
        }
        let contact = moved >= self.contact_markers.min(self.marker_px.len().max(1));
        if let Some(out) = markers {
            out.clear();
            for (m, &(x, y)) in self.marker_px.iter().enumerate() {
                let (dx, dy) =
                    self.xy[m].map_or((0.0, 0.0), |(ix, iy)| (self.zeroed[ix], self.zeroed[iy]));
                out.push(MarkerView {
                    x,
                    y,
                    dx: if dx.is_finite() { dx as f32 } else { 0.0 },
                    dy: if dy.is_finite() { dy as f32 } else { 0.0 },
                    ok: f.status[m].has_position(),
                });
            }
        }
        // No contact: follow the rest position (automatic re-zeroing), report no targets.
        if !contact {
            if self.rezero_rate > 0.0 {
                let n = self.marker_values();
                for (b, z) in self.baseline[..n].iter_mut().zip(&self.zeroed) {
                    if z.is_finite() {
                        *b += self.rezero_rate * z;
                    }
                }
            }
            return Ok((false, max_disp, Vec::new(), health));
        }
        let Some(first) = self.ensemble.first() else {
            return Ok((true, max_disp, Vec::new(), health));
        };
        let names = &first.target_columns;
        let mut sums = vec![0.0; names.len()];
        let mut sq = vec![0.0; names.len()];
        let mut x = Vec::with_capacity(self.cols[0].len());
        let mut networks = 0usize;
        for (m, cols) in self.ensemble.iter().zip(&self.cols) {
            x.clear();
            x.extend(cols.iter().map(|&c| self.zeroed[c]));
            // Lost markers are filled by models on principal components; otherwise (or with
            // too many lost) no estimate this frame.
            if x.iter().any(|v| v.is_infinite()) {
                return Ok((true, max_disp, Vec::new(), health));
            }
            // Every network of every model file counts in the ensemble; each file scales and
            // projects its inputs once for all its networks.
            let Ok((outs, filled)) = m.estimate_each(&x) else {
                return Ok((true, max_disp, Vec::new(), health));
            };
            health.filled = health.filled.max(filled);
            for o in &outs {
                for (k, v) in o.iter().enumerate() {
                    sums[k] += v;
                    sq[k] += v * v;
                }
            }
            networks += outs.len();
        }
        let n = networks as f64;
        let targets = names
            .iter()
            .enumerate()
            .map(|(k, name)| {
                let mean = sums[k] / n;
                TargetEstimate {
                    name: name.clone(),
                    value: mean,
                    std: (networks > 1)
                        .then(|| ((sq[k] / n - mean * mean).max(0.0) * n / (n - 1.0)).sqrt()),
                }
            })
            .collect();
        Ok((true, max_disp, targets, health))
    }

    pub(crate) fn calibration(&self) -> &visuotact_vision::calibration::SensorCalibration {
        self.est.calibration()
    }
}

/// Frames of a simulated sensor: rendered once, in parallel, then cycled with fresh timestamps.
fn sim_frames(kind: &str, n: usize, seed: u64) -> anyhow::Result<Vec<(String, RgbImage)>> {
    use visuotact_sim::cone::{ConeConfig, ConeLoad};
    use visuotact_sim::iats::{IatsConfig, Touch};
    use visuotact_sim::protocol::ConePress;
    let n = n.max(2);
    match kind {
        "iats" => {
            let cfg = IatsConfig::SEED000;
            let touches = visuotact_sim::protocol::iats_random(&cfg, n, seed);
            // A cycle: 40 % of the frames without contact, then touches.
            (0..n)
                .into_par_iter()
                .map(|k| {
                    let t = if k < n * 2 / 5 {
                        Touch::default()
                    } else {
                        touches[k]
                    };
                    let img = visuotact_sim::iats::render(&cfg, &t, seed ^ (k as u64) << 20)
                        .map_err(anyhow::Error::msg)?
                        .0;
                    Ok((format!("iats_{k:04}"), img))
                })
                .collect()
        }
        "cone" => {
            let cfg = ConeConfig::SEED001;
            let press = ConePress {
                duration_s: 1.0,
                ..ConePress::SEED001
            };
            (0..n)
                .into_par_iter()
                .map(|k| {
                    // First 30 % at rest, then one press and release.
                    let u = k as f64 / n as f64;
                    let load = if u < 0.3 {
                        ConeLoad::none(cfg.pressure_kpa)
                    } else {
                        ConeLoad {
                            pressure_kpa: cfg.pressure_kpa,
                            ..press.load_at(&cfg, (u - 0.3) / 0.7, 0.0)
                        }
                    };
                    let img = visuotact_sim::cone::render(&cfg, &load, seed ^ (k as u64) << 20)
                        .map_err(anyhow::Error::msg)?
                        .0;
                    Ok((format!("cone_{k:04}"), img))
                })
                .collect()
        }
        other => bail!("--source sim:{other}: expected sim:iats or sim:cone"),
    }
}

/// A frame source, opened (simulated frames rendered, files found) but not started.
enum Source {
    Sim(Vec<(String, Arc<RgbImage>)>),
    Camera(String),
    Stream(FrameStream),
}

impl Source {
    fn open(a: &Args) -> anyhow::Result<Self> {
        if let Some(kind) = a.source.strip_prefix("sim:") {
            let frames = sim_frames(kind, a.sim_frames, a.seed)?
                .into_iter()
                .map(|(id, img)| (id, Arc::new(img)))
                .collect();
            return Ok(Self::Sim(frames));
        }
        if let Some(dev) = a.source.strip_prefix("camera:") {
            return Ok(Self::Camera(dev.to_string()));
        }
        let spec = a
            .source
            .strip_prefix("frames:")
            .or_else(|| a.source.strip_prefix("video:"))
            .unwrap_or(&a.source);
        Ok(Self::Stream(FrameStream::open(
            &[PathBuf::from(spec)],
            a.fps,
        )?))
    }

    /// Starts the capture thread; frames are paced on `clock` unless `--unpaced`.
    fn spawn(
        self,
        a: &Args,
        queue: Arc<LatestQueue<Captured>>,
        stop: Arc<AtomicBool>,
        clock: Instant,
    ) -> anyhow::Result<std::thread::JoinHandle<anyhow::Result<u64>>> {
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
                Ok(k)
            }),
            Self::Camera(dev) => {
                let req = crate::camera::CameraRequest::parse(
                    a.camera_size.as_deref(),
                    a.camera_format.as_deref(),
                )?;
                crate::camera::spawn(&dev, req, a.fps, queue, stop, clock, max)?
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
                Ok(k)
            }),
        })
    }
}

/// Median and 99th percentile of `v` (sorted in place).
pub(crate) fn median_p99(v: &mut [f64]) -> (f64, f64) {
    if v.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
    (at(0.5), at(0.99))
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

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    if !(a.fps.is_finite() && a.fps > 0.0) {
        bail!("--fps must be a positive frame rate");
    }
    // A model file holding an ensemble counts as its networks (the spread is over all).
    let models = a
        .model
        .iter()
        .map(|p| crate::train::load_model(p))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut live = LiveEstimator::new(a, models)?;
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
        Some(addr) => Some(crate::dashboard::Dashboard::start(
            addr,
            live.calibration(),
            live.target_names(),
        )?),
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
        let (contact, max_disp, targets, health) = match result {
            Ok(r) => r,
            Err(e) => {
                eprintln!("warning: frame {}: {e}", cap.id);
                continue;
            }
        };
        let e = Estimate {
            frame: cap.id,
            index: cap.index,
            timestamp_s: cap.timestamp_s,
            latency_ms: (done - cap.captured).as_secs_f64() * 1e3,
            processing_ms: (done - t_proc).as_secs_f64() * 1e3,
            contact,
            max_displacement_px: max_disp,
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
        .map_err(|_| anyhow::anyhow!("the capture thread stopped unexpectedly"))??;
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_queue_keeps_the_newest_and_counts_drops() {
        let q = LatestQueue::new(2);
        for k in 0..5 {
            q.push(k);
        }
        q.close();
        assert_eq!(
            (q.pop(), q.pop(), q.pop(), q.dropped()),
            (Some(3), Some(4), None, 3)
        );
    }

    #[test]
    fn percentiles() {
        let mut v: Vec<f64> = (1..=100).map(f64::from).rev().collect();
        let (m, p) = median_p99(&mut v);
        assert_eq!((m.round(), p), (51.0, 99.0));
    }
}
