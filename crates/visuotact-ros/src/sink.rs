//! Into a bag: [`McapSink`] is a [`LiveSink`] (a `FrameSink` of the live runner) whose target is a
//! bag, stamped on the wall clock (the time the sink was made plus the run's capture time);
//! [`McapRecorder`] is a [`RecordingTarget`] (a recording's `FrameSink`) whose target is a
//! bag, from the session's rows as they are written.

use std::path::{Path, PathBuf};

use visuotact_pipeline::output::{LiveSink, OutputConfig, RecordingTarget};
use visuotact_vision::calibration::SensorCalibration;

use crate::bag::{Bag, BagConfig};
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

/// A recording into a bag while it is recorded (`record --mcap`): what [`crate::export_mcap`]
/// writes from the finished session — estimates, marker cloud and health from the rows as they
/// are written, the frame as PNG, each force sample — stamped with the session's start plus its
/// clock. Like every bag, a killed recording leaves it readable up to its last chunk.
pub type McapRecorder = RecordingTarget<Bag>;

/// A bag at `path` ([`Bag::create`]) for a recording; `sensor` places the marker cloud (without
/// it there is none).
pub fn mcap_recorder(
    path: &Path,
    cfg: OutputConfig,
    bag: &BagConfig,
    sensor: Option<SensorCalibration>,
) -> Result<McapRecorder, RosError> {
    cfg.validate()?;
    Ok(RecordingTarget::new(Bag::create(path, bag)?, cfg, sensor)?)
}

/// Closes a recording's bag: its path and message count.
pub fn finish_recorder(recorder: McapRecorder) -> Result<(PathBuf, u64), RosError> {
    let bag = recorder.into_target();
    let n = bag.messages();
    Ok((bag.finish()?, n))
}
