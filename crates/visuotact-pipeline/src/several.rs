//! Several sensors in one run (a gripper's two fingers): each sensor keeps its own source,
//! capture queue, estimator and thread — [`crate::runner::run`] as for one sensor, so the
//! frames of two sources never meet — and every estimate, named by its sensor
//! ([`LiveEstimate::sensor`]), reaches the one set of sinks from the calling thread. Each
//! sensor's summary is its own (frames, drops, latency: per-sensor health).
//!
//! A sink that asks to re-zero re-zeroes every sensor; a sink that breaks, `stop`, or the end
//! of every source ends the run.

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, RecvTimeoutError, SyncSender};
use std::sync::Arc;
use std::time::Duration;

use serde::Serialize;
use visuotact_image::RgbImage;

use crate::live::{LiveEstimate, LiveEstimator, MarkerView};
use crate::runner::{run, RunConfig, RunError, RunSummary};
use crate::sink::{FrameSink, SinkError, SinkFrame};

/// One sensor of a run of several.
pub struct NamedSensor {
    /// Its name: the `sensor` of its JSON lines, its namespace in bags and DDS topics. Letters,
    /// digits and `_`, starting with a letter.
    pub name: String,
    /// Its estimator (sensor file and models).
    pub live: LiveEstimator,
    /// Its source and limits.
    pub cfg: RunConfig,
}

/// A sensor's part of a run of several.
#[derive(Clone, Debug, Default, Serialize)]
pub struct SensorSummary {
    /// The sensor's name.
    pub name: String,
    /// Its frames, drops and latency.
    #[serde(flatten)]
    pub summary: RunSummary,
}

/// Checks a sensor's name: letters, digits and `_`, starting with a letter (a ROS name).
pub fn check_sensor_name(name: &str) -> Result<(), RunError> {
    let mut chars = name.chars();
    let ok = chars.next().is_some_and(|c| c.is_ascii_alphabetic())
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_');
    if ok {
        Ok(())
    } else {
        Err(RunError::Config(format!(
            "sensor name {name:?}: expected letters, digits and _, starting with a letter (it names the sensor's topics)"
        )))
    }
}

/// Checks every name ([`check_sensor_name`]) and that none is given twice.
pub fn check_sensor_names(names: &[&str]) -> Result<(), RunError> {
    for (k, name) in names.iter().enumerate() {
        check_sensor_name(name)?;
        if names[..k].contains(name) {
            return Err(RunError::Config(format!(
                "sensor name {name:?} is given twice: every sensor needs its own"
            )));
        }
    }
    Ok(())
}

/// One estimate on its way from a sensor's thread to the sinks.
type Message = (LiveEstimate, String, Option<Vec<MarkerView>>, Arc<RgbImage>);

/// The sink of one sensor's thread: forwards every estimate to the calling thread.
struct Forward {
    tx: SyncSender<Message>,
    /// Whether some sink wants the markers now (a dashboard only while a client watches).
    markers: Arc<AtomicBool>,
    rezero: Arc<AtomicBool>,
}

impl FrameSink for Forward {
    fn wants_markers(&self) -> bool {
        self.markers.load(Ordering::Relaxed)
    }

    fn take_rezero(&mut self) -> bool {
        self.rezero.swap(false, Ordering::Relaxed)
    }

    fn frame(&mut self, f: &SinkFrame<'_>) -> Result<ControlFlow<()>, SinkError> {
        let (Some(estimate), Some(json)) = (f.estimate, f.json) else {
            return Ok(ControlFlow::Continue(()));
        };
        let m = (
            estimate.clone(),
            json.to_string(),
            f.markers.map(<[MarkerView]>::to_vec),
            f.image.clone(),
        );
        Ok(match self.tx.send(m) {
            Ok(()) => ControlFlow::Continue(()),
            Err(_) => ControlFlow::Break(()),
        })
    }
}

/// Tells every sink one sensor's estimate (a re-zero a sink asks for goes to every sensor's
/// `rezero` flag first); the first failure is kept in `error`. Returns whether a sink asked
/// to stop (or failed).
fn tell_sinks(
    sinks: &mut [&mut dyn FrameSink],
    (estimate, json, views, image): &Message,
    rezero: &[Arc<AtomicBool>],
    error: &mut Option<SinkError>,
) -> bool {
    if sinks.iter_mut().any(|s| s.take_rezero()) {
        rezero.iter().for_each(|r| r.store(true, Ordering::Relaxed));
        sinks.iter_mut().for_each(|s| s.rezero_applied());
    }
    let frame = SinkFrame {
        id: &estimate.frame,
        index: estimate.index,
        timestamp_s: estimate.timestamp_s,
        image,
        estimate: Some(estimate),
        json: Some(json),
        markers: views.as_deref(),
        rows: None,
    };
    let mut stop = false;
    for s in sinks.iter_mut() {
        match s.frame(&frame) {
            Ok(flow) => stop |= flow.is_break(),
            Err(e) => {
                error.get_or_insert(e);
                stop = true;
            }
        }
    }
    stop
}

/// Runs every sensor of `sensors` at once until each source ends, a limit is reached, `stop`
/// is set or a sink breaks; each sensor's estimates carry its name. `warn` hears of frames
/// skipped, prefixed by the sensor's name. The first sensor's error, if any, ends the run
/// (the others are stopped).
pub fn run_several(
    sensors: &mut [NamedSensor],
    stop: &Arc<AtomicBool>,
    sinks: &mut [&mut dyn FrameSink],
    warn: impl Fn(&str) + Send + Clone + 'static,
) -> Result<Vec<SensorSummary>, RunError> {
    if sensors.is_empty() {
        return Err(RunError::Config("no sensor to run".into()));
    }
    let names: Vec<&str> = sensors.iter().map(|s| s.name.as_str()).collect();
    check_sensor_names(&names)?;
    for s in sensors.iter() {
        s.cfg.validate()?;
    }
    let markers = Arc::new(AtomicBool::new(sinks.iter().any(|s| s.wants_markers())));
    let rezero: Vec<Arc<AtomicBool>> = sensors
        .iter()
        .map(|_| Arc::new(AtomicBool::new(false)))
        .collect();
    let names: Vec<String> = sensors.iter().map(|s| s.name.clone()).collect();
    // Each sensor stops on its own flag (a runner sets its flag when its source ends, which
    // must not end the others); `stop`, a breaking sink or a failed sensor sets them all.
    let own_stop: Vec<Arc<AtomicBool>> = sensors
        .iter()
        .map(|_| Arc::new(AtomicBool::new(false)))
        .collect();
    let failed = Arc::new(AtomicBool::new(false));
    let (tx, rx) = sync_channel::<Message>(64);
    let mut sink_error = None;
    // Once a sink asked to stop or failed, no sink hears a later estimate.
    let mut told_to_stop = false;
    std::thread::scope(|scope| {
        let threads: Vec<_> = sensors
            .iter_mut()
            .zip(rezero.iter().zip(&own_stop))
            .map(|(s, (rz, own))| {
                let NamedSensor { name, live, cfg } = s;
                live.set_sensor_name(name);
                let mut forward = Forward {
                    tx: tx.clone(),
                    markers: markers.clone(),
                    rezero: rz.clone(),
                };
                let (own, failed) = (own.clone(), failed.clone());
                let (warn, prefix) = (warn.clone(), name.clone());
                scope.spawn(move || {
                    let said = move |w: &str| warn(&format!("{prefix}: {w}"));
                    let r = run(live, cfg, &own, &mut [&mut forward], said);
                    if r.is_err() {
                        failed.store(true, Ordering::Relaxed);
                    }
                    r
                })
            })
            .collect();
        drop(tx);
        // Until every sensor's thread has ended (each holds a sender); a stop is passed on
        // within a tenth of a second.
        loop {
            match rx.recv_timeout(Duration::from_millis(100)) {
                Ok(_) if told_to_stop => {}
                Ok(message) => {
                    if tell_sinks(sinks, &message, &rezero, &mut sink_error) {
                        told_to_stop = true;
                        stop.store(true, Ordering::Relaxed);
                    }
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
            markers.store(sinks.iter().any(|s| s.wants_markers()), Ordering::Relaxed);
            if stop.load(Ordering::Relaxed) || failed.load(Ordering::Relaxed) {
                own_stop
                    .iter()
                    .for_each(|s| s.store(true, Ordering::Relaxed));
            }
        }
        let summaries = names
            .into_iter()
            .zip(threads)
            .map(|(name, t)| {
                let summary = t.join().map_err(|_| RunError::Capture)??;
                Ok(SensorSummary { name, summary })
            })
            .collect();
        match sink_error {
            Some(e) => Err(e.into()),
            None => summaries,
        }
    })
}

/// A run file (`run --sensors run.toml`): one `[[sensor]]` table per sensor.
///
/// ```toml
/// [[sensor]]
/// name = "left"
/// source = "sim:iats"
///
/// [[sensor]]
/// name = "right"
/// source = "camera:/dev/video2"
/// sensor = "right.json"
/// model = ["right_model.json"]
/// ```
#[derive(Clone, Debug, Default, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunFile {
    /// The sensors, in order.
    #[serde(default)]
    pub sensor: Vec<SensorEntry>,
}

/// Most sensors one run file may name: each holds its own capture queue and estimator, and a
/// simulated one renders [`crate::runner::SIM_FRAMES_UP_FRONT`] frames before the run (about
/// 77 MB at 640 × 480), so a run of many stays within a workstation's memory. A gripper or a
/// hand has a few to a dozen.
pub const MAX_RUN_SENSORS: usize = 32;

/// Why a run file does not describe a run.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum RunFileError {
    /// Not TOML of the run file's shape.
    #[error("{0}")]
    Syntax(String),
    /// No `[[sensor]]` table.
    #[error("no [[sensor]] table (each needs name and source)")]
    NoSensor,
    /// More sensors than [`MAX_RUN_SENSORS`].
    #[error("{0} sensors: at most {MAX_RUN_SENSORS} in one run (each holds its own frames and estimator)")]
    TooMany(usize),
}

impl RunFile {
    /// Parses and checks the text of a run file: at least one sensor, at most
    /// [`MAX_RUN_SENSORS`].
    pub fn from_toml(text: &str) -> Result<Self, RunFileError> {
        let plan: Self = toml::from_str(text).map_err(|e| RunFileError::Syntax(e.to_string()))?;
        match plan.sensor.len() {
            0 => Err(RunFileError::NoSensor),
            n if n > MAX_RUN_SENSORS => Err(RunFileError::TooMany(n)),
            _ => Ok(plan),
        }
    }
}

/// One sensor of a run file. Paths are as on the command line (relative to the working
/// folder).
#[derive(Clone, Debug, Default, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorEntry {
    /// Its name ([`check_sensor_name`]).
    pub name: String,
    /// Its source, as `run --source` reads it (`sim:iats`, `camera:/dev/video2`, …).
    pub source: String,
    /// Its sensor file (default: the one stored in its first model).
    #[serde(default)]
    pub sensor: Option<std::path::PathBuf>,
    /// Its model files (several: one ensemble); none: contact and marker health only.
    #[serde(default)]
    pub model: Vec<std::path::PathBuf>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run file names one to [`MAX_RUN_SENSORS`] sensors; more is refused before anything is
    /// opened (was: no cap, each simulated entry ~77 MB).
    #[test]
    fn a_run_file_names_one_to_the_most_sensors() {
        let entries = |n: usize| -> String {
            (0..n)
                .map(|k| format!("[[sensor]]\nname = \"s{k}\"\nsource = \"sim:iats\"\n"))
                .collect()
        };
        assert_eq!(RunFile::from_toml(""), Err(RunFileError::NoSensor));
        assert_eq!(
            RunFile::from_toml(&entries(2)).unwrap().sensor[1].name,
            "s1"
        );
        assert_eq!(
            RunFile::from_toml(&entries(MAX_RUN_SENSORS))
                .unwrap()
                .sensor
                .len(),
            MAX_RUN_SENSORS
        );
        assert_eq!(
            RunFile::from_toml(&entries(MAX_RUN_SENSORS + 1)),
            Err(RunFileError::TooMany(MAX_RUN_SENSORS + 1))
        );
        assert!(matches!(
            RunFile::from_toml("[[sensor]]\nname = \"a\"\nsource = \"sim:iats\"\nspeed = 3\n"),
            Err(RunFileError::Syntax(e)) if e.contains("speed")
        ));
    }
}
