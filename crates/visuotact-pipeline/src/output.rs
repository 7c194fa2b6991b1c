//! A frame's parts and where they go: the one mapping every output shares. A live run's
//! estimate ([`LiveSink`]), a recording's rows as they are written ([`RecordingTarget`]) —
//! both [`FrameSink`]s — or a recorded session's tables
//! ([`crate::session_export`]) become [`FrameParts`] — the targets, the contact rule, the
//! measured force, the marker cloud, the image, the health, the slip state — and a
//! [`FrameTarget`] writes them: as ROS 2 messages into a bag, over DDS or to Foxglove (crate
//! `visuotact-ros`), as Rerun archetypes (crate `visuotact-rerun`). The values are those of
//! the JSON lines and the session's tables.

use std::ops::ControlFlow;
use std::path::PathBuf;

use visuotact_image::RgbImage;
use visuotact_io::force::ForceSample;
use visuotact_vision::calibration::SensorCalibration;

use crate::live::{Health, MarkerView, TargetEstimate};
use crate::session_export::{targets_from_row, MarkerColumns};
use crate::sink::{FrameSink, RecordedRow, SinkError, SinkFrame};
use crate::slip::SlipEstimate;
use crate::LiveEstimate;

/// Why a frame's parts could not be written.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// A file could not be read or written.
    #[error("{}: {}", .0.display(), .1)]
    Io(PathBuf, #[source] std::io::Error),
    /// The session's `frames.csv` lists no frame: there is nothing to export.
    #[error("{}: lists no frames: nothing to export", .0.display())]
    NoFrames(PathBuf),
    /// The progress callback stopped the export.
    #[error("stopped after {0} frames: nothing written")]
    Stopped(usize),
    /// A setting is out of range, or a sensor file or model does not read.
    #[error("{0}")]
    Config(String),
    /// A session table could not be read.
    #[error(transparent)]
    Table(#[from] visuotact_io::table::TableError),
    /// A frame could not be encoded.
    #[error("encoding a frame as PNG: {0}")]
    Encode(String),
    /// The target itself failed (a bag, DDS, Foxglove, a Rerun recording).
    #[error(transparent)]
    Target(Box<dyn std::error::Error + Send + Sync>),
}

impl OutputError {
    /// A target's own error.
    pub fn target(e: impl std::error::Error + Send + Sync + 'static) -> Self {
        OutputError::Target(Box::new(e))
    }
}

/// Where whole frames go: a ROS 2 target (crate `visuotact-ros`) or another format that takes
/// a frame's parts as they are (a Rerun recording).
pub trait FrameTarget {
    /// Writes one frame's parts under `cfg`'s namespace.
    fn write_frame(&mut self, cfg: &OutputConfig, frame: FrameParts<'_>)
        -> Result<(), OutputError>;
}

/// A frame as PNG bytes.
pub fn png_from_rgb(img: &RgbImage) -> Result<Vec<u8>, OutputError> {
    visuotact_io::frames::png_bytes_from_rgb(img).map_err(|e| OutputError::Encode(e.to_string()))
}

/// Where a frame's parts go: the namespace every output writes under (ROS 2 topics,
/// Rerun entities), the sensor's frame id and whether the frame's image goes too.
#[derive(Clone, Debug, PartialEq)]
pub struct OutputConfig {
    /// Namespace, e.g. `/visuotact` or `/left_finger`: ROS 2 topics and Rerun entities
    /// start with it.
    pub namespace: String,
    /// The sensor frame's `frame_id`.
    pub frame_id: String,
    /// Also send each frame's image (a PNG `CompressedImage`, a Rerun `EncodedImage`).
    pub images: bool,
}

impl Default for OutputConfig {
    fn default() -> Self {
        Self {
            namespace: "/visuotact".into(),
            frame_id: "visuotact".into(),
            images: true,
        }
    }
}

impl OutputConfig {
    /// Checks the namespace and frame: a namespace starts with `/` and holds letters, digits,
    /// `_` and `/` (ROS 2 name rules), a frame is not empty.
    pub fn validate(&self) -> Result<(), OutputError> {
        let ns = &self.namespace;
        let ok = ns.starts_with('/')
            && !ns.ends_with('/')
            && !ns.contains("//")
            && ns[1..]
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '/');
        if !ok {
            return Err(OutputError::Config(format!(
                "namespace {ns:?}: expected `/name` (letters, digits, `_`, `/`), e.g. /visuotact"
            )));
        }
        if self.frame_id.is_empty() {
            return Err(OutputError::Config("frame_id is empty".into()));
        }
        Ok(())
    }

    /// `NS/suffix`.
    pub fn topic(&self, suffix: &str) -> String {
        format!("{}/{suffix}", self.namespace)
    }

    /// The configuration of sensor `name` in a run of several: its topics under `NS/name`,
    /// its frame `frame_id_name`.
    pub fn for_sensor(&self, name: &str) -> Self {
        Self {
            namespace: format!("{}/{name}", self.namespace),
            frame_id: format!("{}_{name}", self.frame_id),
            images: self.images,
        }
    }
}

/// The configuration of each sensor a live sink has seen (made once per name): the base for
/// estimates without a sensor name, [`OutputConfig::for_sensor`] for those with one.
#[derive(Clone, Debug)]
pub struct SensorConfigs {
    base: OutputConfig,
    named: Vec<(String, OutputConfig)>,
}

impl SensorConfigs {
    /// Every sensor under `base`.
    pub fn new(base: OutputConfig) -> Self {
        Self {
            base,
            named: Vec::new(),
        }
    }

    /// The configuration for an estimate of `sensor`.
    pub fn get(&mut self, sensor: Option<&str>) -> &OutputConfig {
        let Some(name) = sensor else {
            return &self.base;
        };
        let at = match self.named.iter().position(|(n, _)| n == name) {
            Some(k) => k,
            None => {
                self.named
                    .push((name.to_string(), self.base.for_sensor(name)));
                self.named.len() - 1
            }
        };
        &self.named[at].1
    }
}

/// One marker of the cloud.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MarkerPoint {
    /// Reference position, pixels.
    pub x_px: f32,
    /// Reference position, pixels.
    pub y_px: f32,
    /// Displacement, pixels (NaN when lost).
    pub dx_px: f32,
    /// Displacement, pixels (NaN when lost).
    pub dy_px: f32,
    /// Found this frame.
    pub found: bool,
}

/// One frame's parts as every output takes them; absent parts write nothing.
#[derive(Clone, Debug, Default)]
pub struct FrameParts<'a> {
    /// Nanoseconds since the UNIX epoch.
    pub stamp_ns: u64,
    /// The frame's place in its run or session (`None` for a force sample between frames).
    pub index: Option<u64>,
    /// Estimated targets (`fx_n`, `x_mm`, `depth_mm`, …).
    pub targets: &'a [TargetEstimate],
    /// The contact rule's verdict (live).
    pub contact: Option<bool>,
    /// Measured force and torque.
    pub measured: Option<[f64; 6]>,
    /// Marker cloud.
    pub markers: Option<&'a [MarkerPoint]>,
    /// The sensor's scale: the marker cloud then also carries its displacements in mm.
    pub mm_per_px: Option<f64>,
    /// The frame, PNG-encoded.
    pub png: Option<Vec<u8>>,
    /// Marker health and the figures to report with it.
    pub health: Option<(&'a Health, Vec<(String, String)>)>,
    /// The slip score and state (live runs with a slip detector).
    pub slip: Option<SlipEstimate>,
}

/// The force/torque axes as target names.
pub const WRENCH_TARGETS: [&str; 6] = ["fx_n", "fy_n", "fz_n", "tx_nm", "ty_nm", "tz_nm"];

/// Nanoseconds since the UNIX epoch from seconds (clamped at 0).
pub fn ns_from_s(s: f64) -> u64 {
    if s.is_finite() && s > 0.0 {
        (s * 1e9).round() as u64
    } else {
        0
    }
}

/// A live run's estimates as frame parts into any [`FrameTarget`] — a ROS 2 bag, DDS or
/// Foxglove (crate `visuotact-ros`), a Rerun recording (crate `visuotact-rerun`) — stamped on
/// the wall clock: the time the sink was made plus the run's capture time. The first error
/// stops the run (the run returns it); [`LiveSink::finish_with`] closes the target.
pub struct LiveSink<P> {
    out: P,
    cfg: SensorConfigs,
    origin_ns: u64,
    markers: Vec<MarkerPoint>,
}

impl<P: FrameTarget> LiveSink<P> {
    /// Publishes to `out` under `cfg` (checked); stamps count from now.
    pub fn new(out: P, cfg: OutputConfig) -> Result<Self, OutputError> {
        cfg.validate()?;
        Ok(Self {
            out,
            cfg: SensorConfigs::new(cfg),
            origin_ns: unix_now_ns(),
            markers: Vec::new(),
        })
    }

    /// The target.
    pub fn target(&self) -> &P {
        &self.out
    }

    /// Closes the target with `close` and gives what it returned.
    pub fn finish_with<T, E>(self, close: impl FnOnce(P) -> Result<T, E>) -> Result<T, E> {
        close(self.out)
    }

    fn write(
        &mut self,
        e: &LiveEstimate,
        markers: Option<&[MarkerView]>,
        image: &RgbImage,
    ) -> Result<(), OutputError> {
        let stamp_ns = self.origin_ns + ns_from_s(e.timestamp_s);
        let cfg = self.cfg.get(e.sensor.as_deref());
        let frame = live_frame(cfg, stamp_ns, e, markers, image, &mut self.markers)?;
        self.out.write_frame(cfg, frame)
    }
}

/// Nanoseconds since the UNIX epoch, now.
fn unix_now_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
}

/// A live estimate's messages: targets, the contact rule, the marker cloud (kept in `cloud`),
/// the frame as PNG when asked, and the health with the run's latency and drops.
fn live_frame<'a>(
    cfg: &OutputConfig,
    stamp_ns: u64,
    e: &'a LiveEstimate,
    markers: Option<&[MarkerView]>,
    image: &RgbImage,
    cloud: &'a mut Vec<MarkerPoint>,
) -> Result<FrameParts<'a>, OutputError> {
    if let Some(m) = markers {
        cloud.clear();
        cloud.extend(m.iter().map(|v| MarkerPoint {
            x_px: v.x,
            y_px: v.y,
            dx_px: if v.ok { v.dx } else { f32::NAN },
            dy_px: if v.ok { v.dy } else { f32::NAN },
            found: v.ok,
        }));
    }
    let png = if cfg.images {
        Some(png_from_rgb(image)?)
    } else {
        None
    };
    let values = vec![
        ("latency_ms".to_string(), format!("{:.3}", e.latency_ms)),
        ("dropped_frames".to_string(), e.dropped_frames.to_string()),
    ];
    Ok(FrameParts {
        stamp_ns,
        index: Some(e.index),
        targets: &e.targets,
        contact: Some(e.contact),
        measured: None,
        markers: markers.map(|_| &cloud[..]),
        mm_per_px: e.mm_per_px,
        png,
        health: Some((&e.health, values)),
        slip: e.slip,
    })
}

impl<P: FrameTarget> FrameSink for LiveSink<P> {
    fn wants_markers(&self) -> bool {
        true
    }

    fn frame(&mut self, f: &SinkFrame<'_>) -> Result<ControlFlow<()>, SinkError> {
        if let Some(e) = f.estimate {
            self.write(e, f.markers, f.image)?;
        }
        Ok(ControlFlow::Continue(()))
    }
}

/// A recording into any [`FrameTarget`] while it is recorded: a [`FrameSink`] that writes
/// what [`crate::session_export`] reads from the finished session — estimates, marker
/// cloud and health from the rows as they are written, the frame as PNG, each force sample —
/// stamped with the session's start plus its clock.
pub struct RecordingTarget<T> {
    out: T,
    cfg: OutputConfig,
    sensor: Option<SensorCalibration>,
    /// Built from the first feature row's columns.
    columns: Option<MarkerColumns>,
    cloud: Vec<MarkerPoint>,
    origin_unix_s: f64,
}

impl<T: FrameTarget> RecordingTarget<T> {
    /// Into `out` under `cfg` (checked); `sensor` places the marker cloud (without it there is
    /// none).
    pub fn new(
        out: T,
        cfg: OutputConfig,
        sensor: Option<SensorCalibration>,
    ) -> Result<Self, OutputError> {
        cfg.validate()?;
        Ok(Self {
            out,
            cfg,
            sensor,
            columns: None,
            cloud: Vec::new(),
            origin_unix_s: 0.0,
        })
    }

    /// The target, to close it.
    pub fn into_target(self) -> T {
        self.out
    }

    fn write_row(&mut self, f: &SinkFrame<'_>, row: RecordedRow<'_>) -> Result<(), OutputError> {
        let targets = row
            .estimates
            .map(|(c, r)| targets_from_row(c, r))
            .unwrap_or_default();
        let mut health = None;
        if let (Some((cols, values)), Some(cal)) = (row.features, &self.sensor) {
            let columns = self
                .columns
                .get_or_insert_with(|| MarkerColumns::new(cal, cols));
            health = columns.cloud_from_row(values, &mut self.cloud);
        }
        let png = if self.cfg.images {
            Some(png_from_rgb(f.image)?)
        } else {
            None
        };
        let has_cloud = health.is_some() && !self.cloud.is_empty();
        let frame = FrameParts {
            stamp_ns: ns_from_s(self.origin_unix_s + f.timestamp_s),
            targets: &targets,
            markers: has_cloud.then_some(&self.cloud[..]),
            mm_per_px: self.columns.as_ref().and_then(MarkerColumns::mm_per_px),
            health: health.as_ref().map(|h| (h, Vec::new())),
            png,
            ..FrameParts::default()
        };
        self.out.write_frame(&self.cfg, frame)
    }
}

impl<T: FrameTarget> FrameSink for RecordingTarget<T> {
    fn start(&mut self, started_unix_s: f64) -> Result<(), SinkError> {
        self.origin_unix_s = started_unix_s;
        Ok(())
    }

    fn frame(&mut self, f: &SinkFrame<'_>) -> Result<ControlFlow<()>, SinkError> {
        if let Some(row) = f.rows {
            self.write_row(f, row)?;
        }
        Ok(ControlFlow::Continue(()))
    }

    fn force(&mut self, sample: &ForceSample) -> Result<(), SinkError> {
        let frame = FrameParts {
            stamp_ns: ns_from_s(self.origin_unix_s + sample.timestamp_s),
            measured: Some(sample.values),
            ..FrameParts::default()
        };
        Ok(self.out.write_frame(&self.cfg, frame)?)
    }
}
