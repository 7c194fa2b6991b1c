//! visuotact: camera-based soft tactile sensors, frame → contact position, depth and force.
//!
//! One crate for the layers a program needs (the command line `visuotact` and the Python
//! package are built on the same ones):
//!
//! | module | what |
//! |---|---|
//! | [`image`] | RGB and grey images, frames |
//! | [`vision`] | calibration (presets, layouts), marker detection and tracking, per-frame features |
//! | [`nn`] | Levenberg–Marquardt and Bayesian-regularised networks, ensembles, model files |
//! | [`pipeline`] | frame → estimate ([`Estimator`]), live estimation ([`LiveEstimator`]) and the live runner with sinks, recording, replay, simulated sessions, data sets, evaluation |
//! | [`report`] | figures (SVG, PNG) and the papers' tables as text |
//! | [`signal`] | force filtering equal to scipy's `firwin` + `filtfilt`, bias removal, resampling |
//! | [`io`] | frame sources, tables, session folders, cameras |
//! | [`sim`] | simulated sensors with exact ground truth |
//!
//! Frame → estimate on a simulated sensor: calibrate on contact-free frames, extract features
//! of labelled presses, train a model on them, then estimate a press it has not seen.
//!
//! ```
//! use visuotact::nn::fit::{fit, quietly, FitConfig, FitData};
//! use visuotact::sim::iats::{render, IatsConfig, Touch};
//! use visuotact::vision::calibration::{calibrate, Preset};
//! use visuotact::vision::features::FIELD_COLUMNS;
//! use visuotact::Estimator;
//!
//! let cfg = IatsConfig::SEED000;
//! let frame = |t: &Touch, seed| render(&cfg, t, seed).unwrap().0;
//! let rest = [frame(&Touch::default(), 1), frame(&Touch::default(), 2)];
//! let (sensor, _) = calibrate([("a", &rest[0]), ("b", &rest[1])], &Preset::Iats.config()).unwrap();
//!
//! // Presses at the centre, 0.5 to 4 mm deep; the inputs: the field summary's columns.
//! let mut est = Estimator::from_sensor(sensor).unwrap();
//! let columns = est.feature_columns();
//! let field: Vec<usize> = FIELD_COLUMNS
//!     .iter()
//!     .map(|name| columns.iter().position(|c| c == name).unwrap())
//!     .collect();
//! let (mut x, mut t) = (Vec::new(), Vec::new());
//! for k in 0..8 {
//!     let depth_mm = 0.5 + 0.5 * k as f64;
//!     let press = Touch { x_mm: 30.0, y_mm: 22.5, depth_mm, ..Touch::default() };
//!     let f = est.features(&frame(&press, 10 + k)).unwrap();
//!     x.push(field.iter().map(|&i| f.values[i]).collect::<Vec<f64>>());
//!     t.push(vec![depth_mm]);
//! }
//! let names: Vec<String> = FIELD_COLUMNS.iter().map(|c| c.to_string()).collect();
//! let targets = ["depth_mm".to_string()];
//! let data = FitData { x: &x, t: &t, feature_columns: &names, targets: &targets };
//! let small = FitConfig { hidden: vec![3], ensemble: 1, max_epochs: 200, ..FitConfig::default() };
//! let model = fit(&data, &small, quietly).unwrap();
//!
//! // The estimator reads the model's columns from each frame; the estimate is read by name.
//! let mut est = est.with_model(model).unwrap();
//! let press = Touch { x_mm: 30.0, y_mm: 22.5, depth_mm: 2.25, ..Touch::default() };
//! let estimate = est.estimate(&frame(&press, 99)).unwrap();
//! let depth_mm = estimate.get("depth_mm").unwrap();
//! assert!((depth_mm - 2.25).abs() < 0.15, "{depth_mm}");
//! assert_eq!(estimate.markers_found, 117);
//! ```
//!
//! A live runner on a camera, each estimate a JSON line on standard output (the README's
//! example; a ROS node would give its own [`FrameSink`] that publishes):
//!
//! ```no_run
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use std::sync::{atomic::AtomicBool, Arc};
//! use visuotact::pipeline::runner::{run, LineSink, RunConfig};
//! use visuotact::{Estimator, LiveConfig, LiveEstimator};
//!
//! let sensor = visuotact::SensorCalibration::from_json(&std::fs::read_to_string("sensor.json")?, "sensor.json")?;
//! let mut live = LiveEstimator::new(Estimator::from_sensor(sensor)?, vec![], &LiveConfig::default())?;
//! let cfg = RunConfig { source: "camera:/dev/video0".into(), ..RunConfig::default() };
//! let mut out = LineSink(std::io::stdout());
//! run(&mut live, &cfg, &Arc::new(AtomicBool::new(false)), &mut [&mut out], |w| eprintln!("{w}"))?;
//! # Ok(())
//! # }
//! ```
//!
//! ## Modules and what each owns
//!
//! the layers above in one crate (`image`, `vision`, `nn`, `pipeline`, `report`, `signal`,
//! `io`, `sim`) with the common types at its root and a crate-level example going frame →
//! estimate; what a Rust program or a ROS node depends on

#[cfg(feature = "dashboard")]
pub use visuotact_dashboard as dashboard;
pub use visuotact_image as image;
pub use visuotact_io as io;
#[cfg(feature = "lerobot")]
pub use visuotact_lerobot as lerobot;
pub use visuotact_nn as nn;
pub use visuotact_pipeline as pipeline;
#[cfg(feature = "report")]
pub use visuotact_report as report;
#[cfg(feature = "ros")]
pub use visuotact_ros as ros;
pub use visuotact_signal as signal;
#[cfg(feature = "sim")]
pub use visuotact_sim as sim;
pub use visuotact_vision as vision;

pub use visuotact_pipeline::record::{record, RecordConfig};
pub use visuotact_pipeline::runner::RunConfig;
pub use visuotact_pipeline::sink::{FrameSink, SinkFrame};
pub use visuotact_pipeline::{Estimate, Estimator, LiveConfig, LiveEstimator, PipelineError};
pub use visuotact_vision::calibration::{Preset, SensorCalibration};
