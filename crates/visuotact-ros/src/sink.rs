//! Live into a bag or any other ROS 2 target: [`LiveSink`] is a [`Sink`] of the live runner
//! that publishes each estimate as ROS 2 messages ([`crate::topics`]), stamped on the wall
//! clock (the time the sink was made plus the run's capture time); [`McapSink`] is the one
//! into a bag. [`McapRecorder`] does the same for a recording, from the session's rows as they
//! are written.

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use visuotact_image::RgbImage;
use visuotact_io::force::ForceSample;
use visuotact_pipeline::live::MarkerView;
use visuotact_pipeline::record::{ObserverError, RecordObserver, RecordedRow};
use visuotact_pipeline::runner::Sink;
use visuotact_pipeline::LiveEstimate;

use visuotact_vision::calibration::SensorCalibration;

use crate::bag::{Bag, BagConfig};
use crate::export::{targets_from_row, MarkerColumns};
use crate::topics::{
    ns_from_s, write_frame, FrameMessages, FrameTarget, MarkerPoint, RosConfig, SensorConfigs,
};
use crate::RosError;

/// A live run's estimates as ROS 2 messages ([`crate::topics`]) into any [`FrameTarget`] —
/// a bag ([`McapSink`]), DDS ([`crate::DdsSink`]), Foxglove ([`crate::FoxgloveSink`]), a
/// Rerun recording (crate `visuotact-rerun`) —
/// stamped on the wall clock: the time the sink was made plus the run's capture time. The
/// first error stops the run and is returned by the target's `finish`.
pub struct LiveSink<P> {
    out: P,
    cfg: SensorConfigs,
    origin_ns: u64,
    markers: Vec<MarkerPoint>,
    error: Option<RosError>,
}

impl<P: FrameTarget> LiveSink<P> {
    /// Publishes to `out` under `cfg` (checked); stamps count from now.
    pub fn new(out: P, cfg: RosConfig) -> Result<Self, RosError> {
        cfg.validate()?;
        Ok(Self {
            out,
            cfg: SensorConfigs::new(cfg),
            origin_ns: unix_now_ns(),
            markers: Vec::new(),
            error: None,
        })
    }

    /// The target.
    pub fn target(&self) -> &P {
        &self.out
    }

    /// Closes the target with `close`, then gives the run's first error if there was one,
    /// else what `close` returned (the target is closed either way).
    pub fn finish_with<T>(
        self,
        close: impl FnOnce(P) -> Result<T, RosError>,
    ) -> Result<T, RosError> {
        let closed = close(self.out);
        match self.error {
            Some(e) => Err(e),
            None => closed,
        }
    }

    fn write(
        &mut self,
        e: &LiveEstimate,
        markers: Option<&[MarkerView]>,
        image: &RgbImage,
    ) -> Result<(), RosError> {
        let stamp_ns = self.origin_ns + ns_from_s(e.timestamp_s);
        let cfg = self.cfg.get(e.sensor.as_deref());
        let frame = live_frame(cfg, stamp_ns, e, markers, image, &mut self.markers)?;
        self.out.write_frame(cfg, frame)
    }
}

/// Writes a live run's estimates into an MCAP bag.
pub type McapSink = LiveSink<Bag>;

impl LiveSink<Bag> {
    /// A bag at `path` ([`Bag::create`]); stamps count from now.
    pub fn create(path: &Path, cfg: RosConfig, bag: &BagConfig) -> Result<Self, RosError> {
        cfg.validate()?;
        Self::new(Bag::create(path, bag)?, cfg)
    }

    /// Closes the bag; the first write error of the run, if any, instead.
    pub fn finish(self) -> Result<(PathBuf, u64), RosError> {
        self.finish_with(|bag| {
            let n = bag.messages();
            Ok((bag.finish()?, n))
        })
    }
}

/// Nanoseconds since the UNIX epoch, now.
pub(crate) fn unix_now_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
}

/// A live estimate's messages: targets, the contact rule, the marker cloud (kept in `cloud`),
/// the frame as PNG when asked, and the health with the run's latency and drops.
pub(crate) fn live_frame<'a>(
    cfg: &RosConfig,
    stamp_ns: u64,
    e: &'a LiveEstimate,
    markers: Option<&[MarkerView]>,
    image: &RgbImage,
    cloud: &'a mut Vec<MarkerPoint>,
) -> Result<FrameMessages<'a>, RosError> {
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
        Some(crate::png_from_rgb(image)?)
    } else {
        None
    };
    let values = vec![
        ("latency_ms".to_string(), format!("{:.3}", e.latency_ms)),
        ("dropped_frames".to_string(), e.dropped_frames.to_string()),
    ];
    Ok(FrameMessages {
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

impl<P: FrameTarget> Sink for LiveSink<P> {
    fn wants_markers(&self) -> bool {
        true
    }

    fn send(
        &mut self,
        estimate: &LiveEstimate,
        _json: &str,
        markers: Option<&[MarkerView]>,
        image: &Arc<RgbImage>,
    ) -> ControlFlow<()> {
        match self.write(estimate, markers, image) {
            Ok(()) => ControlFlow::Continue(()),
            Err(e) => {
                self.error = Some(e);
                ControlFlow::Break(())
            }
        }
    }
}

/// A recording into a bag while it is recorded (`record --mcap`): a [`RecordObserver`] that
/// writes what [`crate::export_mcap`] writes from the finished session — estimates, marker
/// cloud and health from the rows as they are written, the frame as PNG, each force sample —
/// stamped with the session's start plus its clock. Like every bag, a killed recording leaves
/// it readable up to its last chunk.
pub struct McapRecorder {
    bag: Bag,
    cfg: RosConfig,
    sensor: Option<SensorCalibration>,
    /// Built from the first feature row's columns.
    columns: Option<MarkerColumns>,
    cloud: Vec<MarkerPoint>,
    origin_unix_s: f64,
}

impl McapRecorder {
    /// A bag at `path` ([`Bag::create`]); `sensor` places the marker cloud (without it there
    /// is none).
    pub fn create(
        path: &Path,
        cfg: RosConfig,
        bag: &BagConfig,
        sensor: Option<SensorCalibration>,
    ) -> Result<Self, RosError> {
        cfg.validate()?;
        Ok(Self {
            bag: Bag::create(path, bag)?,
            cfg,
            sensor,
            columns: None,
            cloud: Vec::new(),
            origin_unix_s: 0.0,
        })
    }

    /// Closes the bag: its path and message count.
    pub fn finish(self) -> Result<(PathBuf, u64), RosError> {
        let n = self.bag.messages();
        Ok((self.bag.finish()?, n))
    }

    fn write_row(&mut self, row: &RecordedRow<'_>) -> Result<(), RosError> {
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
            Some(crate::png_from_rgb(row.image)?)
        } else {
            None
        };
        let has_cloud = health.is_some() && !self.cloud.is_empty();
        let frame = FrameMessages {
            stamp_ns: ns_from_s(self.origin_unix_s + row.timestamp_s),
            targets: &targets,
            markers: has_cloud.then_some(&self.cloud[..]),
            mm_per_px: self.columns.as_ref().and_then(MarkerColumns::mm_per_px),
            health: health.as_ref().map(|h| (h, Vec::new())),
            png,
            ..FrameMessages::default()
        };
        write_frame(&mut self.bag, &self.cfg, frame)
    }
}

impl RecordObserver for McapRecorder {
    fn start(&mut self, started_unix_s: f64) -> Result<(), ObserverError> {
        self.origin_unix_s = started_unix_s;
        Ok(())
    }

    fn frame(&mut self, row: &RecordedRow<'_>) -> Result<(), ObserverError> {
        Ok(self.write_row(row)?)
    }

    fn force(&mut self, sample: &ForceSample) -> Result<(), ObserverError> {
        let frame = FrameMessages {
            stamp_ns: ns_from_s(self.origin_unix_s + sample.timestamp_s),
            measured: Some(sample.values),
            ..FrameMessages::default()
        };
        Ok(write_frame(&mut self.bag, &self.cfg, frame)?)
    }
}
