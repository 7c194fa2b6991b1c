//! Reading the files commands share (sensor and model files) and writing results safely; the
//! per-frame estimator built from them.

use std::path::Path;

use anyhow::{bail, Context};
use visuotact_nn::fit::FitError;
use visuotact_nn::model::Model;
use visuotact_pipeline::slip::SlipDetector;
use visuotact_pipeline::Estimator;
use visuotact_vision::calibration::{ReferenceInfo, SensorCalibration};

/// Reads a sensor file, naming it in errors.
pub(crate) fn load_sensor(path: &Path) -> anyhow::Result<SensorCalibration> {
    let text = visuotact_io::read::text_of_file(path)
        .map_err(|e| anyhow::anyhow!("{}: cannot read sensor file: {e}", path.display()))?;
    SensorCalibration::from_json(&text, &path.display().to_string()).map_err(anyhow::Error::msg)
}

/// The slip detector at `p`, or the built-in one for `builtin`.
pub(crate) fn load_slip(p: &Path) -> anyhow::Result<SlipDetector> {
    Ok(SlipDetector::load(p)?)
}

/// Reads a model file, naming it in errors.
pub(crate) fn load_model(path: &Path) -> anyhow::Result<Model> {
    let text = visuotact_io::read::text_of_file(path)
        .with_context(|| format!("{}: cannot read model file", path.display()))?;
    Model::from_json(&text, &path.display().to_string()).map_err(anyhow::Error::msg)
}

/// A sentence for the user when a sensor's reference was taken under contact (its health
/// flag), `None` otherwise.
pub(crate) fn reference_note(r: &ReferenceInfo) -> Option<String> {
    r.under_contact.then(|| {
        format!(
            "the sensor's reference was taken under contact ({} of {} frames chosen as the lightest, {:.2} px RMS from rest, {:.2} px at worst): displacements are relative to a lightly pressed skin",
            r.method,
            r.frames_considered,
            r.residual_px.unwrap_or(f64::NAN),
            r.residual_max_px.unwrap_or(f64::NAN)
        )
    })
}

/// Writes `text` to `path` through a temporary file and a rename
/// ([`visuotact_io::session::write_atomically`]).
pub(crate) fn write_atomically(path: &Path, text: &str) -> anyhow::Result<()> {
    Ok(visuotact_io::session::write_atomically(path, text)?)
}

/// A training error in the command line's words (the projection is `--components`).
pub(crate) fn fit_error(e: FitError) -> anyhow::Error {
    match e {
        FitError::Projection(m) => anyhow::anyhow!("--components: {m}"),
        e => e.into(),
    }
}

/// The sensor file at `sensor` (else the one stored in `model`).
fn calibration_of(
    sensor: Option<&Path>,
    model: Option<&Model>,
) -> anyhow::Result<Option<SensorCalibration>> {
    match (sensor, model) {
        (Some(p), _) => Ok(Some(load_sensor(p)?)),
        (None, Some(m)) if m.sensor.is_none() => {
            bail!("the model holds no sensor calibration: give --sensor")
        }
        (None, Some(_)) => Ok(None),
        (None, None) => bail!("give --sensor (and --model for estimates)"),
    }
}

/// [`Estimator::new`] from a sensor file (or the model's calibration): `record --model`,
/// `predict --sensor` and `run` share it, so the same frame gives the same numbers in each.
pub(crate) fn estimator(sensor: Option<&Path>, model: Option<Model>) -> anyhow::Result<Estimator> {
    let cal = calibration_of(sensor, model.as_ref())?;
    Ok(Estimator::new(cal, model)?)
}
