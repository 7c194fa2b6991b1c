//! visuotact for Python: the library's calibration, per-frame estimator, training and filters
//! behind a small numpy API (`import visuotact`). Frames are `(H, W, 3)` or `(H, W)` `uint8`
//! arrays or image paths; features, labels and estimates are `float64` arrays. Errors are
//! `visuotact.VisuotactError` with the library's message. The GIL is released while frames
//! are processed and networks trained. Type stubs: `visuotact.pyi`.
//!
//! ## Modules and what each owns
//!
//! the Python package `visuotact` (pyo3 + maturin, abi3 ≥ 3.10): `Sensor` (calibrate, load,
//! extract), `Features`, `Model` (train, load, predict with the held-out error beside each estimate), `live`,
//! `filtfilt`, `simulate`, `VisuotactError`; type stubs `visuotact.pyi`; pytest in `tests/`
//! against the CLI and scipy
#![allow(
    unsafe_code,
    reason = "pyo3's macros expand to the C-API glue; this crate writes no unsafe code itself"
)]

use std::ops::ControlFlow;
use std::path::PathBuf;
use std::sync::Arc;

use numpy::{
    IntoPyArray, PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArrayDyn,
    PyUntypedArrayMethods,
};
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};
use visuotact_image::RgbImage;
use visuotact_io::frames::{read_image, FrameStream};
use visuotact_nn::fit::{quietly, FieldInputs, FitData};
use visuotact_nn::mlp::Algorithm;
use visuotact_nn::model::{is_marker_column, Model as NnModel};
use visuotact_nn::plan::{wanted_components, Plan, Wanted};
use visuotact_pipeline::slip::{
    detect, sequences_in, track_sequences, SlipConfig, SlipDetector, SlipMonitor,
};
use visuotact_pipeline::Estimator;
use visuotact_vision::calibration::{calibrate, Preset, SensorCalibration};
use visuotact_vision::features::{is_field_column, FrameFeatures};
use visuotact_vision::field::FieldDynamics;
use visuotact_vision::layout::LayoutChoice;
use visuotact_vision::options::Purpose;

create_exception!(
    visuotact,
    VisuotactError,
    PyException,
    "An error from visuotact; the message names the file, frame or column and what was expected."
);

/// A visuotact error as a Python exception.
fn error(e: impl std::fmt::Display) -> PyErr {
    VisuotactError::new_err(e.to_string())
}

/// An image from a numpy array (`(H, W, 3)` or `(H, W)` uint8) or a path.
fn rgb_from(frame: &Bound<'_, PyAny>) -> PyResult<RgbImage> {
    if frame.is_instance_of::<PyString>() || frame.hasattr("__fspath__")? {
        let path: PathBuf = frame.extract()?;
        return read_image(&path).map_err(error);
    }
    let a: PyReadonlyArrayDyn<'_, u8> = frame.extract().map_err(|_| {
        error("a frame must be a uint8 numpy array of shape (H, W, 3) or (H, W), or an image path")
    })?;
    let shape = a.shape().to_vec();
    let data: Vec<u8> = match a.as_slice() {
        Ok(s) => s.to_vec(),
        Err(_) => a.as_array().iter().copied().collect(),
    };
    match shape[..] {
        [h, w, 3] => RgbImage::from_vec(w, h, data).map_err(error),
        [h, w] => {
            RgbImage::from_vec(w, h, data.iter().flat_map(|&v| [v, v, v]).collect()).map_err(error)
        }
        _ => Err(error(format!(
            "a frame must have shape (H, W, 3) or (H, W), got {shape:?}"
        ))),
    }
}

/// A frame as a `(H, W, 3)` uint8 array.
fn array_from_rgb<'py>(py: Python<'py>, img: RgbImage) -> PyResult<Bound<'py, PyAny>> {
    let (w, h) = (img.width(), img.height());
    Ok(img
        .into_vec()
        .into_pyarray(py)
        .reshape([h, w, 3])?
        .into_any())
}

/// The rows of a 2-D float array.
fn rows_of(a: &PyReadonlyArray2<'_, f64>) -> Vec<Vec<f64>> {
    a.as_array().outer_iter().map(|r| r.to_vec()).collect()
}

/// A sensor calibration: where the markers are at rest, how to find them, their layout.
#[pyclass(module = "visuotact")]
struct Sensor {
    est: Estimator,
    /// The feature columns, shared with every [`Features`] (named once, not per frame).
    columns: Arc<[String]>,
}

impl Sensor {
    fn from_calibration(cal: SensorCalibration) -> PyResult<Self> {
        let est = Estimator::new(Some(cal), None).map_err(error)?;
        Ok(Self {
            columns: est.feature_columns().into(),
            est,
        })
    }
}

#[pymethods]
impl Sensor {
    /// Calibrates from contact-free frames (arrays or paths). `preset`: "auto" (from the
    /// markers' polarity in the first frame), "iats", "cone" or "dark-markers"; `layout`:
    /// "auto", "grid", "hex", "dot-rings", "rings" or "irregular". Keyword options change the
    /// preset's detector as `visuotact calibrate`'s options do: `channel` ("green",
    /// "luma601", "mean", "red", "blue"), `invert`, `threshold` ("otsu", "otsu-sampled",
    /// "adaptive" or a level in 0..1), `window`, `offset`, `open`, `close`, `morph_size`, `min_area`, `max_area`,
    /// `keep_border`, `centroid` ("grey", "weighted", "binary"), `roi` (x, y, w, h),
    /// `circle` (cx, cy, r).
    #[staticmethod]
    #[pyo3(signature = (frames, preset = "auto", layout = "auto", **options))]
    fn calibrate(
        py: Python<'_>,
        frames: Vec<Bound<'_, PyAny>>,
        preset: &str,
        layout: &str,
        options: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let images: Vec<RgbImage> = frames.iter().map(rgb_from).collect::<PyResult<_>>()?;
        // Ids as `visuotact calibrate` writes them: the file name, or the position.
        let ids: Vec<String> = frames
            .iter()
            .enumerate()
            .map(|(k, f)| {
                f.extract::<PathBuf>()
                    .ok()
                    .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
                    .unwrap_or_else(|| format!("frame {k}"))
            })
            .collect();
        let first = images
            .first()
            .ok_or_else(|| error("calibration needs at least one frame"))?;
        let mut o = detector_options(options)?;
        o.preset = match preset {
            "auto" => None,
            name => Some(Preset::from_name(name).ok_or_else(|| {
                error(format!(
                    "preset {name:?}: expected auto, {}",
                    Preset::ALL.map(Preset::name).join(", ")
                ))
            })?),
        };
        // As `visuotact calibrate` chooses: the preset, and the markers' size from the first
        // frame.
        let chosen = o
            .config_for_frames(Purpose::Tracking, || Some(first.clone()))
            .map_err(error)?;
        let cfg = visuotact_vision::calibration::CalibrationConfig {
            layout: LayoutChoice::parse(layout).map_err(error)?,
            detector: chosen.detector,
            features: chosen.features,
            ..chosen.preset.config()
        };
        let (mut cal, _) = py
            .detach(|| calibrate(ids.iter().map(String::as_str).zip(images.iter()), &cfg))
            .map_err(error)?;
        cal.marker_size = chosen.size;
        Self::from_calibration(cal)
    }

    /// Reads a sensor file written by `visuotact calibrate` or [`Sensor.save`].
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        let text = visuotact_io::read::text_of_file(&path)
            .map_err(|e| error(format!("{}: cannot read sensor file: {e}", path.display())))?;
        Self::from_calibration(
            SensorCalibration::from_json(&text, &path.display().to_string()).map_err(error)?,
        )
    }

    /// Writes the sensor file.
    fn save(&self, path: PathBuf) -> PyResult<()> {
        visuotact_io::session::write_atomically(&path, &self.est.calibration().to_json())
            .map_err(|e| error(e.to_string()))
    }

    /// The sensor file's JSON text.
    fn to_json(&self) -> String {
        self.est.calibration().to_json()
    }

    /// Markers in the calibration.
    #[getter]
    fn n_markers(&self) -> usize {
        self.est.n_markers()
    }

    /// Names of the feature values `extract` gives: per marker (`m017_dx_px`, …), then the
    /// field summary (`field_rms_px`, …).
    #[getter]
    fn feature_columns(&self) -> Vec<String> {
        self.columns.to_vec()
    }

    /// The features of one frame (array or path), against the calibration's reference.
    fn extract(&mut self, py: Python<'_>, frame: &Bound<'_, PyAny>) -> PyResult<Features> {
        let img = rgb_from(frame)?;
        let est = &mut self.est;
        let f = py.detach(|| est.features(&img).cloned()).map_err(error)?;
        Ok(Features {
            f,
            columns: Arc::clone(&self.columns),
        })
    }

    fn __repr__(&self) -> String {
        let c = self.est.calibration();
        format!(
            "Sensor({} markers, {}, {}×{} px)",
            self.est.n_markers(),
            c.layout.name(),
            c.image_width,
            c.image_height
        )
    }
}

/// One frame's features: the row `extract` writes, and per-marker arrays.
#[pyclass(module = "visuotact")]
struct Features {
    f: FrameFeatures,
    columns: Arc<[String]>,
}

impl Features {
    /// Per-marker values of the column ending in `suffix` (NaN where absent or lost).
    fn per_marker<'py>(&self, py: Python<'py>, suffix: &str) -> Bound<'py, PyArray1<f64>> {
        let n = self.f.status.len();
        let mut v = vec![f64::NAN; n];
        for (c, x) in self.columns.iter().zip(&self.f.values) {
            if let Some(id) = c
                .strip_suffix(suffix)
                .and_then(|p| p.strip_prefix('m'))
                .and_then(|p| p.strip_suffix('_'))
                .and_then(|p| p.parse::<usize>().ok())
            {
                if id < n {
                    v[id] = *x;
                }
            }
        }
        v.into_pyarray(py)
    }
}

#[pymethods]
impl Features {
    /// The feature row (the columns of `columns`), NaN where a marker was lost.
    #[getter]
    fn values<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.f.values.clone().into_pyarray(py)
    }

    /// Names of `values`.
    #[getter]
    fn columns(&self) -> Vec<String> {
        self.columns.to_vec()
    }

    /// Displacement along x per marker, pixels.
    #[getter]
    fn dx<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.per_marker(py, "dx_px")
    }

    /// Displacement along y per marker, pixels.
    #[getter]
    fn dy<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.per_marker(py, "dy_px")
    }

    /// Area change per marker, pixels (NaN when the feature set has no area).
    #[getter]
    fn darea<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.per_marker(py, "darea_px")
    }

    /// Tracking status per marker: "ok", "lost", "merged", "ambiguous" or "split".
    #[getter]
    fn status(&self) -> Vec<&'static str> {
        self.f.status.iter().map(|s| s.name()).collect()
    }

    /// Markers matched in this frame.
    #[getter]
    fn found(&self) -> usize {
        self.f.found
    }

    fn __repr__(&self) -> String {
        format!(
            "Features({} of {} markers found, {} values)",
            self.f.found,
            self.f.status.len(),
            self.f.values.len()
        )
    }
}

/// A trained model: one network or an ensemble, with its input scaling and projection.
#[pyclass(module = "visuotact")]
struct Model {
    m: NnModel,
}

/// Which feature columns a training reads: `field` as `visuotact train --field`.
fn training_columns(columns: &[String], field: &str) -> PyResult<Vec<usize>> {
    let field = FieldInputs::from_name(field)
        .ok_or_else(|| error(format!("field {field:?}: expected auto, yes, only or no")))?
        .resolve(columns.iter().filter(|c| is_marker_column(c)).count());
    let keep = |c: &String| {
        if is_field_column(c) {
            field != FieldInputs::No
        } else if is_marker_column(c) {
            field != FieldInputs::Only
        } else {
            true
        }
    };
    let picked: Vec<usize> = (0..columns.len()).filter(|&i| keep(&columns[i])).collect();
    // The markers' features first: the projection reads them, the rest pass by it.
    let first_other = picked.iter().position(|&i| !is_marker_column(&columns[i]));
    if let Some(k) = first_other {
        if let Some(&late) = picked[k..].iter().find(|&&i| is_marker_column(&columns[i])) {
            return Err(error(format!(
                "column `{}` is a marker's feature after other inputs: put the markers' columns first",
                columns[late]
            )));
        }
    }
    Ok(picked)
}

#[pymethods]
impl Model {
    /// Trains on a feature table (`features`: samples × columns, NaN for lost markers) and
    /// labels (samples × targets), with `visuotact train`'s defaults: trainbr, one hidden
    /// layer of 20, 5 networks (from 1 000 samples 3, or 4 wide ones; `ensemble` fixes it);
    /// on wide sensors the field summary with 10 principal components of the markers'
    /// features, or the field summary alone, whichever 5-fold cross-validation prefers, and
    /// from 1 000 samples the wide network too, unless `hidden` or `algorithm` is given
    /// (`Model.selection` has the scores). `components`: "auto", 0 (none) or a count. The same
    /// plan as `visuotact train` (`visuotact_nn::plan::Plan`): the same table and arguments
    /// give the same model.
    #[staticmethod]
    #[pyo3(signature = (features, labels, columns, targets, hidden = None, algorithm = None, components = "auto".to_string(), field = "auto", ensemble = None, seed = 1, max_epochs = 1000, sensor = None))]
    #[allow(
        clippy::too_many_arguments,
        reason = "Python keyword arguments, each with a default"
    )]
    fn train(
        py: Python<'_>,
        features: PyReadonlyArray2<'_, f64>,
        labels: PyReadonlyArray2<'_, f64>,
        columns: Vec<String>,
        targets: Vec<String>,
        hidden: Option<Vec<usize>>,
        algorithm: Option<&str>,
        components: String,
        field: &str,
        ensemble: Option<usize>,
        seed: u64,
        max_epochs: usize,
        sensor: Option<&Sensor>,
    ) -> PyResult<Self> {
        if features.shape()[1] != columns.len() || labels.shape()[1] != targets.len() {
            return Err(error(format!(
                "features have {} columns for {} names, labels {} for {} targets",
                features.shape()[1],
                columns.len(),
                labels.shape()[1],
                targets.len()
            )));
        }
        let picked = training_columns(&columns, field)?;
        let names: Vec<String> = picked.iter().map(|&i| columns[i].clone()).collect();
        let x: Vec<Vec<f64>> = rows_of(&features)
            .into_iter()
            .map(|r| picked.iter().map(|&i| r[i]).collect())
            .collect();
        let t = rows_of(&labels);
        let markers = names.iter().filter(|c| is_marker_column(c)).count();
        let algorithm = algorithm
            .map(|a| {
                Algorithm::from_name(a).ok_or_else(|| {
                    error(format!(
                        "algorithm {a:?}: expected trainlm, trainbr or adam"
                    ))
                })
            })
            .transpose()?;
        let components = wanted_components(&components, markers)
            .map_err(|e| error(format!("components {e}")))?;
        let wanted = Wanted {
            hidden,
            algorithm,
            components,
            field: FieldInputs::from_name(field).unwrap_or(FieldInputs::Auto),
            ensemble,
            seed,
            max_epochs: Some(max_epochs),
            folds: None,
        };
        let plan = Plan::new(&names, x.len(), &wanted);
        let data = FitData {
            x: &x,
            t: &t,
            feature_columns: &names,
            targets: &targets,
        };
        let mut m = py.detach(|| plan.fit(&data, quietly)).map_err(error)?;
        if let Some(s) = sensor {
            m.sensor = Some(
                serde_json::from_str(&s.est.calibration().to_json())
                    .map_err(|e| error(format!("the sensor: {e}")))?,
            );
        }
        Ok(Self { m })
    }

    /// Reads a model file written by `visuotact train` or [`Model.save`].
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        let text = visuotact_io::read::text_of_file(&path)
            .map_err(|e| error(format!("{}: cannot read model: {e}", path.display())))?;
        Ok(Self {
            m: NnModel::from_json(&text, &path.display().to_string()).map_err(error)?,
        })
    }

    /// Writes the model file.
    fn save(&self, path: PathBuf) -> PyResult<()> {
        let json = self
            .m
            .to_checked_json(&path.display().to_string())
            .map_err(error)?;
        visuotact_io::session::write_atomically(&path, &json).map_err(|e| error(e.to_string()))
    }

    /// The model file's JSON text.
    fn to_json(&self) -> String {
        self.m.to_json()
    }

    /// The input columns, in order.
    #[getter]
    fn columns(&self) -> Vec<String> {
        self.m.feature_columns.clone()
    }

    /// The target columns.
    #[getter]
    fn targets(&self) -> Vec<String> {
        self.m.target_columns.clone()
    }

    /// The input sets training compared by cross-validation (empty when there was no
    /// choice): dicts with `inputs`, `error` (held-out squared error over the target's
    /// variance, mean over targets), `normalised_mse` per target, `folds` (how many folds' held
    /// out samples the score is over) and `chosen`.
    #[getter]
    fn selection<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        self.m
            .training
            .selection
            .iter()
            .map(|s| {
                let d = PyDict::new(py);
                d.set_item("inputs", &s.inputs)?;
                d.set_item("error", s.error)?;
                d.set_item("normalised_mse", s.normalised_mse.clone())?;
                d.set_item("folds", s.folds)?;
                d.set_item("chosen", s.chosen)?;
                Ok(d)
            })
            .collect()
    }

    /// Estimates for rows of the model's inputs (`columns` order; one row or samples × inputs;
    /// NaN for a lost marker's features, filled from the others): a dict of arrays, each
    /// target's mean, `<target>_std` (how far off it may be: the larger of the ensemble's standard deviation and
    /// the held-out RMS error of the training rows with the nearest estimates; 0 for one network
    /// without held-out rows) and `filled`
    /// (inputs filled per row). Rows that cannot be estimated (too many lost markers) are NaN.
    /// A wider table (e.g. every column `Sensor.extract` gives) is read by name: pass its
    /// `columns`, or pass a `Features` as it is.
    #[pyo3(signature = (features, columns = None))]
    fn predict<'py>(
        &self,
        py: Python<'py>,
        features: &Bound<'py, PyAny>,
        columns: Option<Vec<String>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let (rows, columns): (Vec<Vec<f64>>, Option<Vec<String>>) =
            if let Ok(f) = features.extract::<PyRef<'_, Features>>() {
                (vec![f.f.values.clone()], Some(f.columns.to_vec()))
            } else if let Ok(a) = features.extract::<PyReadonlyArray2<'_, f64>>() {
                (rows_of(&a), columns)
            } else {
                let a: PyReadonlyArray1<'_, f64> = features.extract().map_err(|_| {
                    error("features must be a Features or a float64 array of 1 or 2 dimensions")
                })?;
                (vec![a.as_array().to_vec()], columns)
            };
        let rows = match columns {
            Some(names) => {
                let picked = self.m.columns_in(&names).map_err(error)?;
                if let Some(r) = rows.iter().find(|r| r.len() != names.len()) {
                    return Err(error(format!(
                        "a row has {} values for {} column names",
                        r.len(),
                        names.len()
                    )));
                }
                rows.iter()
                    .map(|r| picked.iter().map(|&i| r[i]).collect())
                    .collect()
            }
            None => rows,
        };
        let width = self.m.feature_columns.len();
        if let Some(r) = rows.iter().find(|r| r.len() != width) {
            return Err(error(format!(
                "a row has {} values, the model reads {width} ({}…): pass columns= to pick them by name",
                r.len(),
                self.m.feature_columns.first().cloned().unwrap_or_default()
            )));
        }
        let m = &self.m;
        let k = m.target_columns.len();
        let (values, spread, filled) = py.detach(|| {
            let mut values = vec![f64::NAN; rows.len() * k];
            let mut spread = vec![f64::NAN; rows.len() * k];
            let mut filled = vec![-1i64; rows.len()];
            for (i, r) in rows.iter().enumerate() {
                if let Ok(e) = m.estimate(r) {
                    values[i * k..(i + 1) * k].copy_from_slice(&e.values);
                    let s = if e.spread.is_empty() {
                        vec![0.0; k]
                    } else {
                        e.spread
                    };
                    spread[i * k..(i + 1) * k].copy_from_slice(&s);
                    filled[i] = e.filled as i64;
                }
            }
            (values, spread, filled)
        });
        let out = PyDict::new(py);
        for (j, t) in m.target_columns.iter().enumerate() {
            let col = |v: &[f64]| -> Vec<f64> { (0..rows.len()).map(|i| v[i * k + j]).collect() };
            out.set_item(t, col(&values).into_pyarray(py))?;
            out.set_item(format!("{t}_std"), col(&spread).into_pyarray(py))?;
        }
        out.set_item("filled", filled.into_pyarray(py))?;
        Ok(out)
    }

    fn __repr__(&self) -> String {
        format!(
            "Model({} inputs → {}, {} network(s), {})",
            self.m.feature_columns.len(),
            self.m.target_columns.join(", "),
            self.m.networks().count(),
            self.m.training.algorithm
        )
    }
}

/// Estimates frame by frame from a source: yields dicts with `frame`, `index`,
/// `timestamp_s`, `found` and `estimate` (a dict of target → value, with `<target>_std` for
/// an ensemble or a model with held-out rows; `None`, with `why`, when the frame has none).
#[pyclass(module = "visuotact", unsendable)]
struct Live {
    stream: FrameStream,
    est: Estimator,
    /// The estimate's columns (targets, then spreads).
    targets: Vec<String>,
    /// The slip detector following the frames, and its displacement buffer.
    slip: Option<SlipMonitor>,
}

#[pymethods]
impl Live {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__<'py>(&mut self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(item) = self.stream.next() else {
            return Ok(None);
        };
        let frame = item.map_err(error)?;
        let set = self.est.feature_set();
        let (found, estimate, slip) = {
            let (f, e) = self
                .est
                .estimate_with(&frame.image, &[])
                .map_err(|e| error(format!("frame {}: {e}", frame.id)))?;
            let slip = self.slip.as_mut().map(|m| {
                m.observe_frame(&frame.image);
                (m.estimate_features(f, set), m.field().signals())
            });
            (f.found, e.map(|r| r.map_err(|why| why.to_string())), slip)
        };
        let d = PyDict::new(py);
        d.set_item("frame", &frame.id)?;
        d.set_item("index", frame.index)?;
        d.set_item("timestamp_s", frame.timestamp_s)?;
        d.set_item("found", found)?;
        match slip {
            Some((e, signals)) => {
                let sd = PyDict::new(py);
                sd.set_item("state", e.state.name())?;
                sd.set_item("score", e.score)?;
                let field = PyDict::new(py);
                for (name, v) in FieldDynamics::NAMES.iter().zip(signals) {
                    field.set_item(*name, v)?;
                }
                sd.set_item("field", field)?;
                d.set_item("slip", sd)?;
            }
            None => d.set_item("slip", py.None())?,
        }
        match estimate.unwrap_or_else(|| Err("no model".to_string())) {
            Ok(e) => {
                let est = PyDict::new(py);
                for (t, v) in self.targets.iter().zip(e.into_row()) {
                    est.set_item(t, v)?;
                }
                d.set_item("estimate", est)?;
                d.set_item("why", py.None())?;
            }
            Err(why) => {
                d.set_item("estimate", py.None())?;
                d.set_item("why", why)?;
            }
        }
        Ok(Some(d))
    }
}

/// Frames from `source` (an image, a folder of images in natural order, a video, or a list
/// of them) through `model` (with `sensor`, or the calibration stored in the model): an
/// iterator of estimate dicts. Without a model it yields features counts only. With `slip`
/// (`"builtin"` or a file from `visuotact slip fit`) each dict's `slip` holds the `state`, the
/// `score` and the displacement `field`'s ten signals the detector read (by name).
#[pyfunction]
#[pyo3(signature = (source, model = None, sensor = None, fps = 25.0, temporal = false, slip = None))]
fn live(
    source: &Bound<'_, PyAny>,
    model: Option<&Model>,
    sensor: Option<&Sensor>,
    fps: f64,
    temporal: bool,
    slip: Option<&str>,
) -> PyResult<Live> {
    let paths: Vec<PathBuf> = match source.extract::<PathBuf>() {
        Ok(p) => vec![p],
        Err(_) => source.extract()?,
    };
    let stream = FrameStream::open(&paths, fps).map_err(error)?;
    let cal = sensor.map(|s| s.est.calibration().clone());
    let mut est = Estimator::new(cal, model.map(|m| m.m.clone())).map_err(error)?;
    est.set_temporal_prior(temporal);
    let slip = slip
        .map(|p| {
            let d = SlipDetector::load(std::path::Path::new(p)).map_err(error)?;
            SlipMonitor::for_estimator(d, &est).map_err(error)
        })
        .transpose()?;
    Ok(Live {
        stream,
        targets: est.target_columns(),
        est,
        slip,
    })
}

/// Each video's slip verdict (videos, or folders searched for videos): a list of dicts with
/// `video`, `slip` (bool), `onset_s` (`None` without slip) and `score`; each video calibrates
/// its reference from its first `calibration_frames` frames unless `sensor` is given.
/// `detector`: a file from `visuotact slip fit`, or `"builtin"`.
#[pyfunction]
#[pyo3(signature = (videos, detector = "builtin", sensor = None, calibration_frames = 5))]
fn slip_detect<'py>(
    py: Python<'py>,
    videos: &Bound<'py, PyAny>,
    detector: &str,
    sensor: Option<&Sensor>,
    calibration_frames: usize,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let paths: Vec<PathBuf> = match videos.extract::<PathBuf>() {
        Ok(p) => vec![p],
        Err(_) => videos.extract()?,
    };
    let det = SlipDetector::load(std::path::Path::new(detector)).map_err(error)?;
    let paths = sequences_in(&paths).map_err(error)?;
    let cal = sensor.map(|s| s.est.calibration().clone());
    let cfg = SlipConfig {
        calibration_frames: calibration_frames.max(1),
        imprint: det.reads_imprint(),
        ..SlipConfig::default()
    };
    let seqs = py
        .detach(|| {
            track_sequences(&paths, cal.as_ref(), &cfg, &|_, _| {
                std::ops::ControlFlow::Continue(())
            })
        })
        .map_err(error)?;
    let mut out = Vec::with_capacity(seqs.len());
    for (p, q) in paths.iter().zip(&seqs) {
        let v = detect(q, &det);
        let d = PyDict::new(py);
        d.set_item("video", p)?;
        d.set_item("slip", v.slip)?;
        d.set_item("onset_s", v.onset_s)?;
        d.set_item("score", v.score)?;
        out.push(d);
    }
    Ok(out)
}

/// Zero-phase filtering, equal to `scipy.signal.filtfilt(b, a, x)` (odd padding of
/// `3·max(len(a), len(b))` samples).
#[pyfunction]
fn filtfilt<'py>(
    py: Python<'py>,
    b: PyReadonlyArray1<'py, f64>,
    a: PyReadonlyArray1<'py, f64>,
    x: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let (b, a, x) = (
        b.as_array().to_vec(),
        a.as_array().to_vec(),
        x.as_array().to_vec(),
    );
    let y = py
        .detach(|| {
            visuotact_signal::fir::filtfilt(
                &b,
                &a,
                &x,
                &visuotact_signal::fir::FiltFiltOptions::default(),
            )
        })
        .map_err(error)?;
    Ok(y.into_pyarray(py))
}

/// One simulated frame of seed 000's touch sensor (`variant` 0: the preset; others draw its
/// parameters) pressed at (`x_mm`, `y_mm`) by `depth_mm` (0: no contact), with its noise
/// from `seed`: a `(H, W, 3)` uint8 array.
#[pyfunction]
#[pyo3(signature = (x_mm = 0.0, y_mm = 0.0, depth_mm = 0.0, seed = 1))]
fn simulate<'py>(
    py: Python<'py>,
    x_mm: f64,
    y_mm: f64,
    depth_mm: f64,
    seed: u64,
) -> PyResult<Bound<'py, PyAny>> {
    use visuotact_sim::iats::{render, IatsConfig, Touch};
    let touch = Touch {
        x_mm,
        y_mm,
        depth_mm,
        ..Touch::default()
    };
    let img = py
        .detach(|| render(&IatsConfig::SEED000, &touch, seed))
        .map_err(error)?
        .0;
    array_from_rgb(py, img)
}

/// A `progress(done, total)` callback for an export run without the GIL; an exception it
/// raises is printed, not propagated (the export goes on).
fn progress_of(cb: Option<Py<PyAny>>) -> impl FnMut(usize, usize) -> ControlFlow<()> + Send {
    move |done, total| {
        Python::attach(|py| {
            // Ctrl-C (KeyboardInterrupt) or a callback that raises stops the export, which
            // then leaves nothing behind.
            if py.check_signals().is_err() {
                return ControlFlow::Break(());
            }
            if let Some(cb) = &cb {
                if let Err(e) = cb.call1(py, (done, total)) {
                    e.print(py);
                    return ControlFlow::Break(());
                }
            }
            ControlFlow::Continue(())
        })
    }
}

/// A recorded session into an MCAP bag with the ROS 2 profile (`output` ending in `.mcap`:
/// one file; otherwise a rosbag2 folder): a dict of what was written.
#[pyfunction]
#[pyo3(signature = (session, output, namespace = "/visuotact".to_string(), frame_id = "visuotact".to_string(), sensor = None, start_unix_s = None, images = true, progress = None))]
#[allow(
    clippy::too_many_arguments,
    reason = "Python keyword arguments, each with a default"
)]
fn export_mcap<'py>(
    py: Python<'py>,
    session: PathBuf,
    output: PathBuf,
    namespace: String,
    frame_id: String,
    sensor: Option<PathBuf>,
    start_unix_s: Option<f64>,
    images: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let cfg = visuotact_pipeline::session_export::ExportConfig {
        output: visuotact_pipeline::output::OutputConfig {
            namespace,
            frame_id,
            images,
        },
        sensor,
        start_unix_s,
    };
    let bag = visuotact_ros::BagConfig::default();
    let mut cb = progress_of(progress);
    let s = py
        .detach(|| visuotact_ros::export_mcap(&session, &output, (&cfg, &bag), &mut cb))
        .map_err(error)?;
    let d = PyDict::new(py);
    d.set_item("path", s.path)?;
    d.set_item("frames", s.frames)?;
    d.set_item("messages", s.messages)?;
    d.set_item("notes", s.notes)?;
    Ok(d)
}

/// Recorded sessions (one episode each) into a new LeRobot v3.0 data set at `output`: a dict
/// of what was written.
#[pyfunction]
#[pyo3(signature = (sessions, output, fps = None, task = "touch the tactile sensor".to_string(), robot_type = None, video = true, encoder = "libsvtav1".to_string(), progress = None))]
#[allow(
    clippy::too_many_arguments,
    reason = "Python keyword arguments, each with a default"
)]
fn export_lerobot<'py>(
    py: Python<'py>,
    sessions: Vec<PathBuf>,
    output: PathBuf,
    fps: Option<u32>,
    task: String,
    robot_type: Option<String>,
    video: bool,
    encoder: String,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let cfg = visuotact_lerobot::LeRobotConfig {
        fps,
        task,
        robot_type,
        video: video.then(|| visuotact_lerobot::VideoConfig {
            encoder,
            ..Default::default()
        }),
    };
    let mut cb = progress_of(progress);
    let s = py
        .detach(|| visuotact_lerobot::export_lerobot(&sessions, &output, &cfg, &mut cb))
        .map_err(error)?;
    let d = PyDict::new(py);
    d.set_item("path", s.path)?;
    d.set_item("episodes", s.episodes)?;
    d.set_item("frames", s.frames)?;
    d.set_item("fps", s.fps)?;
    d.set_item("features", s.features)?;
    d.set_item("notes", s.notes)?;
    Ok(d)
}

/// The detector options of `Sensor.calibrate`'s keyword arguments; an unknown one is an
/// error naming it.
fn detector_options(
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<visuotact_vision::options::DetectorOptions> {
    use visuotact_vision::blobs::Connectivity;
    use visuotact_vision::detect::Centroid;
    use visuotact_vision::options::ThresholdChoice;
    use visuotact_vision::preprocess::{Channel, CircleMask, Roi};
    let mut o = visuotact_vision::options::DetectorOptions::default();
    let Some(options) = options else {
        return Ok(o);
    };
    for (k, v) in options.iter() {
        let key: String = k.extract()?;
        match key.as_str() {
            "channel" => {
                let c: String = v.extract()?;
                o.channel =
                    Some(Channel::from_name(&c).ok_or_else(|| error(format!("channel {c:?}")))?);
            }
            "invert" => o.invert = Some(v.extract()?),
            "open" => o.open = Some(v.extract()?),
            "close" => o.close = Some(v.extract()?),
            "keep_border" => o.keep_border = v.extract()?,
            "threshold" => {
                o.threshold = Some(match v.extract::<f64>() {
                    Ok(level) => ThresholdChoice::Fixed(level),
                    Err(_) => ThresholdChoice::parse(&v.extract::<String>()?).map_err(error)?,
                });
            }
            "window" => o.window_px = Some(v.extract()?),
            "offset" => o.offset = Some(v.extract()?),
            "morph_size" => o.morph_size = Some(v.extract()?),
            "min_area" => o.min_area_px = Some(v.extract()?),
            "max_area" => o.max_area_px = Some(v.extract()?),
            "connectivity" => {
                o.connectivity = match v.extract::<u8>()? {
                    4 => Connectivity::Four,
                    8 => Connectivity::Eight,
                    n => return Err(error(format!("connectivity {n}: expected 4 or 8"))),
                };
            }
            "centroid" => {
                o.centroid = Some(match v.extract::<String>()?.as_str() {
                    "grey" => Centroid::Grey,
                    "weighted" => Centroid::Weighted,
                    "binary" => Centroid::Binary,
                    c => {
                        return Err(error(format!(
                            "centroid {c:?}: expected grey, weighted or binary"
                        )))
                    }
                });
            }
            "roi" => {
                let (x, y, width, height): (usize, usize, usize, usize) = v.extract()?;
                o.roi = Some(Roi {
                    x,
                    y,
                    width,
                    height,
                });
            }
            "circle" => {
                let (cx_px, cy_px, radius_px): (f64, f64, f64) = v.extract()?;
                o.circle = Some(CircleMask {
                    cx_px,
                    cy_px,
                    radius_px,
                });
            }
            other => return Err(error(format!("unknown calibration option `{other}`"))),
        }
    }
    Ok(o)
}

/// The module.
#[pymodule]
fn visuotact(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("VisuotactError", m.py().get_type::<VisuotactError>())?;
    m.add_class::<Sensor>()?;
    m.add_class::<Features>()?;
    m.add_class::<Model>()?;
    m.add_class::<Live>()?;
    m.add_function(wrap_pyfunction!(live, m)?)?;
    m.add_function(wrap_pyfunction!(slip_detect, m)?)?;
    m.add_function(wrap_pyfunction!(filtfilt, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(export_mcap, m)?)?;
    m.add_function(wrap_pyfunction!(export_lerobot, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
