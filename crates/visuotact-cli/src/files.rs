//! Reading the files commands share (sensor and model files) and writing results safely; the
//! per-frame estimator built from them.

use std::path::Path;

use anyhow::{bail, Context};
use visuotact_nn::fit::FitError;
use visuotact_nn::model::Model;
use visuotact_pipeline::Estimator;
use visuotact_vision::calibration::{ReferenceInfo, SensorCalibration};

/// Reads a sensor file, naming it in errors.
pub(crate) fn load_sensor(path: &Path) -> anyhow::Result<SensorCalibration> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| anyhow::anyhow!("{}: cannot read sensor file: {e}", path.display()))?;
    SensorCalibration::from_json(&text, &path.display().to_string()).map_err(anyhow::Error::msg)
}

/// Reads a model file, naming it in errors.
pub(crate) fn load_model(path: &Path) -> anyhow::Result<Model> {
    let text = std::fs::read_to_string(path)
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

/// [`Estimator::with_extra_inputs`] from a sensor file (or the model's calibration).
pub(crate) fn estimator_with_extra_inputs(
    sensor: Option<&Path>,
    model: Option<Model>,
) -> anyhow::Result<Estimator> {
    let cal = calibration_of(sensor, model.as_ref())?;
    Ok(Estimator::with_extra_inputs(cal, model)?)
}

/// `p` made absolute with links resolved as far as it exists (the output usually does not).
fn resolved(p: &Path) -> std::path::PathBuf {
    if let Ok(c) = p.canonicalize() {
        return c;
    }
    match (p.parent(), p.file_name()) {
        (Some(dir), Some(name)) if !dir.as_os_str().is_empty() => resolved(dir).join(name),
        _ => std::env::current_dir().map_or_else(|_| p.to_path_buf(), |d| d.join(p)),
    }
}

/// The files of a session folder (`record`, `simulate`) that hold what was measured.
const SESSION_FILES: [&str; 8] = [
    "session.json",
    "frames.csv",
    "labels.csv",
    "truth.csv",
    "force.csv",
    "features.csv",
    "estimates.csv",
    "references.csv",
];

/// Refuses to write `output` over one of `inputs` (the same file or folder once paths are
/// resolved) or over a session's own files when an input is a session folder: a command never
/// destroys what it reads.
pub(crate) fn refuse_output_over_input(output: &Path, inputs: &[&Path]) -> anyhow::Result<()> {
    let out = resolved(output);
    if let Some(i) = inputs.iter().find(|i| resolved(i) == out) {
        bail!(
            "{}: the output is the input {}; choose another output",
            output.display(),
            i.display()
        );
    }
    let session_file = |i: &&&Path| {
        let dir = resolved(i);
        dir.join("frames.csv").is_file()
            && out.parent() == Some(dir.as_path())
            && SESSION_FILES
                .iter()
                .any(|f| out.file_name() == Some(f.as_ref()))
    };
    if let Some(i) = inputs.iter().find(session_file) {
        bail!(
            "{}: would overwrite the session {}'s own file; choose another output",
            output.display(),
            i.display()
        );
    }
    Ok(())
}

/// Checks that `output` can be written before any work: its folder is created and a probe
/// written and removed beside it; the error names the real path.
pub(crate) fn check_writable(output: &Path) -> anyhow::Result<()> {
    if output == Path::new("-") {
        return Ok(());
    }
    if let Some(dir) = output.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .map_err(|e| anyhow::anyhow!("{}: cannot create its folder: {e}", output.display()))?;
    }
    let probe = output.with_extension("probe~");
    std::fs::write(&probe, b"")
        .and_then(|()| std::fs::remove_file(&probe))
        .map_err(|e| anyhow::anyhow!("{}: cannot write here: {e}", output.display()))
}

/// Memory available to a new allocation now, bytes (Linux `MemAvailable`; `None` elsewhere).
pub(crate) fn available_memory_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let kib: u64 = text
        .lines()
        .find(|l| l.starts_with("MemAvailable:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()?;
    Some(kib * 1024)
}
