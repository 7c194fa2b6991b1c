//! Live into a bag: [`McapSink`] is a [`LiveSink`] (a `Sink` of the live runner) whose target
//! is a bag, stamped on the wall clock (the time the sink was made plus the run's capture
//! time). [`McapRecorder`] does the same for a recording, from the session's rows as they are
//! written.

use std::path::{Path, PathBuf};

use visuotact_io::force::ForceSample;
use visuotact_pipeline::output::{
    ns_from_s, png_from_rgb, FrameParts, LiveSink, MarkerPoint, OutputConfig,
};
use visuotact_pipeline::record::{ObserverError, RecordObserver, RecordedRow};
use visuotact_pipeline::session_export::{targets_from_row, MarkerColumns};
use visuotact_vision::calibration::SensorCalibration;

use crate::bag::{Bag, BagConfig};
use crate::topics::write_frame;
use crate::RosError;

/// Writes a live run's estimates into an MCAP bag.
pub type McapSink = LiveSink<Bag>;

/// A bag at `path` ([`Bag::create`]) for a live run; stamps count from now.
pub fn mcap_sink(path: &Path, cfg: OutputConfig, bag: &BagConfig) -> Result<McapSink, RosError> {
    cfg.validate()?;
    Ok(LiveSink::new(Bag::create(path, bag)?, cfg)?)
}

/// Closes the bag: its path and message count, or the run's first write error.
pub fn finish_mcap(sink: McapSink) -> Result<(PathBuf, u64), RosError> {
    sink.finish_with(|bag| {
        let n = bag.messages();
        Ok((bag.finish()?, n))
    })
}

/// A recording into a bag while it is recorded (`record --mcap`): a [`RecordObserver`] that
/// writes what [`crate::export_mcap`] writes from the finished session — estimates, marker
/// cloud and health from the rows as they are written, the frame as PNG, each force sample —
/// stamped with the session's start plus its clock. Like every bag, a killed recording leaves
/// it readable up to its last chunk.
pub struct McapRecorder {
    bag: Bag,
    cfg: OutputConfig,
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
        cfg: OutputConfig,
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
            Some(png_from_rgb(row.image)?)
        } else {
            None
        };
        let has_cloud = health.is_some() && !self.cloud.is_empty();
        let frame = FrameParts {
            stamp_ns: ns_from_s(self.origin_unix_s + row.timestamp_s),
            targets: &targets,
            markers: has_cloud.then_some(&self.cloud[..]),
            mm_per_px: self.columns.as_ref().and_then(MarkerColumns::mm_per_px),
            health: health.as_ref().map(|h| (h, Vec::new())),
            png,
            ..FrameParts::default()
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
        let frame = FrameParts {
            stamp_ns: ns_from_s(self.origin_unix_s + sample.timestamp_s),
            measured: Some(sample.values),
            ..FrameParts::default()
        };
        Ok(write_frame(&mut self.bag, &self.cfg, frame)?)
    }
}
