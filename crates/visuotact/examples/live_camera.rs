//! A live camera to JSON lines on standard output for a number of seconds: the live runner
//! with its no-contact baseline, contact rule and marker health, as `visuotact run` does.
//!
//! `cargo run --release -p visuotact --example live_camera -- SENSOR.json [MODEL.json] [/dev/video0] [SECONDS]`

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use visuotact::io::source::SourceSpec;
use visuotact::nn::model::Model;
use visuotact::pipeline::runner::{run, LineSink, RunConfig};
use visuotact::{Estimator, LiveConfig, LiveEstimator, SensorCalibration};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(sensor) = args.first() else {
        return Err("usage: live_camera SENSOR.json [MODEL.json] [/dev/videoN] [SECONDS]".into());
    };
    let sensor = SensorCalibration::from_json(&std::fs::read_to_string(sensor)?, sensor)?;
    let mut est = Estimator::from_sensor(sensor)?;
    // With a model the features are the ones it reads; the live estimator runs it (a list of
    // models is an ensemble).
    let mut models = Vec::new();
    if let Some(path) = args.get(1).filter(|a| a.ends_with(".json")) {
        let model = Model::from_json(&std::fs::read_to_string(path)?, path)?;
        est = est.with_model(model.clone())?;
        models.push(model);
    }
    let device = args.iter().find(|a| a.starts_with("/dev/")).cloned();
    let seconds: f64 = args.last().and_then(|a| a.parse().ok()).unwrap_or(10.0);
    let mut live = LiveEstimator::new(est, models, &LiveConfig::default())?;
    let cfg = RunConfig {
        source: SourceSpec::Camera(device.unwrap_or_else(|| "/dev/video0".into())),
        duration_s: Some(seconds),
        ..RunConfig::default()
    };
    let stop = Arc::new(AtomicBool::new(false));
    let mut out = LineSink(std::io::stdout());
    let summary = run(&mut live, &cfg, &stop, &mut [&mut out], |w| {
        eprintln!("{w}")
    })?;
    stop.store(true, Ordering::Relaxed);
    eprintln!(
        "{} frames estimated, {} dropped",
        summary.frames_estimated, summary.frames_dropped
    );
    Ok(())
}
