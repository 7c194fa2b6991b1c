//! The per-frame estimator ([`visuotact_pipeline::Estimator`]) built from the command line's
//! files: `record --model`, `replay`, `predict --sensor` and `run` share it, so the same frame
//! gives the same numbers in each.

use std::path::Path;

use anyhow::bail;
use visuotact_nn::model::Model;
pub(crate) use visuotact_pipeline::Estimator;

/// The sensor file at `sensor` (else the one stored in `model`) and the model.
fn calibration_of(
    sensor: Option<&Path>,
    model: Option<&Model>,
) -> anyhow::Result<Option<visuotact_vision::calibration::SensorCalibration>> {
    match (sensor, model) {
        (Some(p), _) => Ok(Some(crate::load_sensor(p)?)),
        (None, Some(m)) if m.sensor.is_none() => {
            bail!("the model holds no sensor calibration: give --sensor")
        }
        (None, Some(_)) => Ok(None),
        (None, None) => bail!("give --sensor (and --model for estimates)"),
    }
}

/// [`Estimator::new`] from a sensor file (or the model's calibration).
pub(crate) fn estimator(sensor: Option<&Path>, model: Option<Model>) -> anyhow::Result<Estimator> {
    let cal = calibration_of(sensor, model.as_ref())?;
    Ok(Estimator::new(cal, model)?)
}

/// [`Estimator::with_extra_inputs`] from a sensor file (or the model's calibration).
pub(crate) fn estimator_with_extra_inputs(
    sensor: Option<&Path>,
    model: Option<Model>,
) -> anyhow::Result<Estimator> {
    let cal = calibration_of(sensor, model.as_ref())?;
    Ok(Estimator::with_extra_inputs(cal, model)?)
}
