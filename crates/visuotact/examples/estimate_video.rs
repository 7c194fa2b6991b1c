//! Estimates every frame of a video (or a folder of images) with a trained model and prints one
//! line per frame: the frame, the markers found and each target by name.
//!
//! `cargo run --release -p visuotact --example estimate_video -- MODEL.json VIDEO [SENSOR.json]`
//!
//! The model must hold its sensor (`visuotact train --sensor`), or give the sensor file third.

use std::path::PathBuf;

use visuotact::io::frames::FrameStream;
use visuotact::nn::model::Model;
use visuotact::{Estimator, SensorCalibration};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [model, video, rest @ ..] = args.as_slice() else {
        return Err("usage: estimate_video MODEL.json VIDEO [SENSOR.json]".into());
    };
    let model = Model::from_json(&std::fs::read_to_string(model)?, model)?;
    let mut est = match rest.first() {
        Some(sensor) => {
            let sensor = SensorCalibration::from_json(&std::fs::read_to_string(sensor)?, sensor)?;
            Estimator::from_sensor(sensor)?.with_model(model)?
        }
        None => Estimator::from_model(model)?,
    };
    // Frames of a video follow each other: track from the last frame.
    est.set_temporal_prior(true);
    for frame in FrameStream::open(&[PathBuf::from(video)], 25.0)? {
        let frame = frame?;
        let e = est.estimate(&frame.image)?;
        let values: Vec<String> = e
            .iter()
            .map(|t| format!("{}={:.3}", t.name, t.value))
            .collect();
        match &e.no_estimate {
            None => println!(
                "{} {}/{} {}",
                frame.id,
                e.markers_found,
                e.markers,
                values.join(" ")
            ),
            Some(why) => println!(
                "{} {}/{} no estimate: {why}",
                frame.id, e.markers_found, e.markers
            ),
        }
    }
    Ok(())
}
