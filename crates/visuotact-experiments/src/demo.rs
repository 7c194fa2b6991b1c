//! Both source documents' experiments end to end on the simulator — simulate, calibrate,
//! extract, train (Levenberg–Marquardt), evaluate — as report structs beside the papers'
//! numbers (`visuotact demo` prints them). Frames stay in memory; nothing is written.
//!
//! Each experiment trains the paper's own network (trainlm, the paper's inputs) and
//! visuotact's default (what `visuotact train` builds with no options: trainbr, the field
//! summary beside the markers' principal components on wide sensors, an ensemble whose stated
//! spread — the held-out error nearest each estimate — is reported). Every random draw is seeded from [`DemoConfig::seed`].

use std::time::Instant;

use rayon::prelude::*;
use visuotact_image::RgbImage;
use visuotact_nn::fit::{
    ensemble_for, fit_choosing_ensemble, folds_trained, quietly, FitConfig, FitData, FitError,
    InputSet,
};
use visuotact_nn::metrics::{target_errors, TargetErrors};
use visuotact_nn::model::{EstimateError, Model};
use visuotact_nn::plan::{Plan, Wanted};
use visuotact_nn::sweep::{self, Sweep};
use visuotact_sim::cone::{ConeConfig, ConeLoad};
use visuotact_sim::iats::{IatsConfig, Touch};
use visuotact_sim::protocol::{self, ConePress, PressureGauge};
use visuotact_sim::rig::{frame_seed, GAUGE_SEED};
use visuotact_sim::SimError;
use visuotact_vision::calibration::{
    calibrate, CalibrationConfig, CalibrationError, SensorCalibration,
};
use visuotact_vision::detect::{Centroid, DetectorConfig};
use visuotact_vision::features::{FeatureExtractor, FeatureSet, FrameSizeError, FIELD_COLUMNS};
use visuotact_vision::layout::{Layout, LayoutChoice};
use visuotact_vision::preprocess::PreprocessConfig;

/// How big a demo to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DemoConfig {
    /// A smaller run: half the grid in each axis, shorter presses, sparser sweeps, and
    /// visuotact's default with fewer networks, epochs and folds (printed).
    pub quick: bool,
    /// Seed of the simulation, the splits and the weights.
    pub seed: u64,
}

impl Default for DemoConfig {
    fn default() -> Self {
        Self {
            quick: false,
            seed: 1,
        }
    }
}

mod torque;
pub use torque::{cone_torque, TorqueDemo};

/// Why a demo stopped.
#[derive(Debug, thiserror::Error)]
pub enum DemoError {
    /// The simulator refused a frame.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// Calibration failed on the rest frames.
    #[error("{what} calibration: {source}")]
    Calibration {
        /// Which sensor.
        what: &'static str,
        /// Why.
        source: CalibrationError,
    },
    /// The feature extractor refused the calibration.
    #[error(transparent)]
    Features(#[from] visuotact_vision::ConfigError),
    /// A frame's size differs from the reference's.
    #[error(transparent)]
    FrameSize(#[from] FrameSizeError),
    /// A training failed.
    #[error(transparent)]
    Fit(#[from] FitError),
    /// A model does not read the demo's columns.
    #[error(transparent)]
    Model(#[from] EstimateError),
    /// Something the experiment needs was not in its frames.
    #[error("not found: {0}")]
    Missing(String),
}

/// Seed 000 Table 3: actual (x, y, depth) and the paper's estimates.
pub const TABLE3: [([f64; 3], [f64; 3]); 6] = [
    ([56.0, 21.0, 4.0], [54.5, 21.1, 3.8]),
    ([16.0, 33.0, 4.0], [15.1, 33.7, 3.86]),
    ([12.0, 9.0, 1.0], [10.7, 8.98, 1.1]),
    ([56.0, 39.0, 2.0], [54.99, 40.43, 2.13]),
    ([40.0, 3.0, 5.0], [38.96, 2.7, 5.1]),
    ([32.0, 24.0, 3.0], [32.8, 22.4, 3.08]),
];

/// A trained model and how it went.
#[derive(Clone, Debug)]
pub struct Trained {
    /// The model (predicts in target units).
    pub model: Model,
    /// Training time, s.
    pub train_s: f64,
    /// The inputs chosen, in words, with the cross-validated error of each set compared.
    pub inputs: String,
}

/// One row of Table 3: the paper's touch, its estimate, and visuotact's.
#[derive(Clone, Debug)]
pub struct Table3Row {
    /// Actual x, y, depth, mm.
    pub actual: [f64; 3],
    /// The paper's estimate.
    pub paper: [f64; 3],
    /// visuotact's default: values and its stated spread (`<target>_std`), or why there is none.
    pub estimate: Result<([f64; 3], [f64; 3]), String>,
}

/// Seed 000's experiment.
#[derive(Clone, Debug)]
pub struct IatsDemo {
    /// The default's settings differ from `visuotact train`'s for `--quick` (see
    /// [`DemoConfig::quick`]): they, in words; empty for the full run.
    pub quick_note: String,
    /// Markers calibrated.
    pub markers: usize,
    /// Grid touches trained on.
    pub grid_touches: usize,
    /// Of them, frames with every marker found (the paper's inputs).
    pub complete_frames: usize,
    /// Frames visuotact's default trains on (any marker found).
    pub default_frames: usize,
    /// Simulating and calibrating, s.
    pub setup_s: f64,
    /// Seed 000's network (351 → 20 ×5 → 3, trainlm).
    pub paper: Trained,
    /// visuotact's default.
    pub default: Trained,
    /// The default's hidden layers.
    pub default_hidden: Vec<usize>,
    /// Table 3's six touches.
    pub table3: Vec<Table3Row>,
    /// Random touches (not in training).
    pub random_touches: usize,
    /// The default's errors on them per target (x, y, depth).
    pub errors: Vec<TargetErrors>,
    /// The default's mean spread per target.
    pub mean_spread: Vec<f64>,
    /// Contact distance D: mean and largest, mm.
    pub distance_mm: (f64, f64),
    /// Random touches with every marker found (the paper's network reads only those).
    pub paper_frames: usize,
    /// The paper's network on them: D mean and max, depth mean error, mm.
    pub paper_distance_mm: (f64, f64),
    /// The paper's network's mean depth error, mm.
    pub paper_depth_mm: f64,
    /// The default's random touches: actual and estimated (x, y, depth), mm.
    pub random_points: Vec<([f64; 3], [f64; 3])>,
}

/// The best network of a sweep of architectures.
#[derive(Clone, Debug)]
pub struct SweepBest {
    /// Inputs, in words (`rings`, `rings + gauge`).
    pub inputs: &'static str,
    /// Number of inputs.
    pub n_inputs: usize,
    /// Its hidden layers' neurons.
    pub hidden: Vec<usize>,
    /// Its test MSE, N².
    pub test_mse: f64,
    /// The sweep's time, s.
    pub secs: f64,
    /// (hidden neurons, mean test MSE, best test MSE) per size of a one-layer sweep: its
    /// figure (empty for other sweeps).
    pub curve: Vec<(f64, f64, f64)>,
}

/// One row of Table 5.1: a model, its inputs, its errors on a press.
#[derive(Clone, Debug)]
pub struct ConeRow {
    /// Which model, on which press.
    pub what: String,
    /// Its inputs, in words.
    pub inputs: &'static str,
    /// Force errors.
    pub errors: TargetErrors,
    /// Actual and estimated force per frame, N.
    pub points: Vec<(f64, f64)>,
}

/// Seed 001's experiment.
#[derive(Clone, Debug)]
pub struct ConeDemo {
    /// Rings calibrated.
    pub rings: usize,
    /// Frames trained on.
    pub train_frames: usize,
    /// The paper's 6 → 20 → 1 network, one training.
    pub one_network: Trained,
    /// Repeats per size in the sweeps.
    pub repeats: u64,
    /// The sweeps' best networks.
    pub sweeps: Vec<SweepBest>,
    /// Table 5.1's rows.
    pub rows: Vec<ConeRow>,
    /// The force below which MPE leaves frames out, N.
    pub mpe_floor_n: f64,
    /// How much lower the link's pressure is at the later press, %.
    pub pressure_drop_percent: f64,
}

/// Features of frames rendered by `render(k)`, in parallel: the markers' features (NaN where
/// a marker was lost), then the field summary.
fn features_of(
    cal: &SensorCalibration,
    set: FeatureSet,
    n: usize,
    render: impl Fn(usize) -> Result<RgbImage, SimError> + Sync,
) -> Result<Vec<Vec<f64>>, DemoError> {
    let ex = FeatureExtractor::new(cal.clone(), set)?;
    (0..n)
        .into_par_iter()
        .map_with(ex, |ex, k| Ok(ex.extract(&render(k)?)?.values))
        .collect()
}

/// The papers' inputs: the markers' features without the field summary, where every marker
/// was found.
fn complete_markers(f: &[f64]) -> Option<Vec<f64>> {
    let markers = &f[..f.len() - FIELD_COLUMNS.len()];
    markers
        .iter()
        .all(|v| v.is_finite())
        .then(|| markers.to_vec())
}

/// Trains on `x` (the same path as `visuotact train`). `columns` names the inputs, the
/// markers' features first; `sets` the input sets to choose between by `folds`-fold
/// cross-validation (none: all columns).
fn train(
    x: &[Vec<f64>],
    t: &[Vec<f64>],
    columns: &[String],
    targets: &[&str],
    cfg: &FitConfig,
    (sets, folds): (&[InputSet], usize),
) -> Result<Trained, DemoError> {
    let targets: Vec<String> = targets.iter().map(|s| s.to_string()).collect();
    let data = FitData {
        x,
        t,
        feature_columns: columns,
        targets: &targets,
    };
    let t0 = Instant::now();
    let ensemble = |set: &InputSet| ensemble_for(x.len(), set, cfg);
    let model = fit_choosing_ensemble(&data, cfg, (sets, folds), ensemble, quietly)?;
    let inputs = inputs_of(&model, (sets, folds), x.len());
    Ok(Trained {
        model,
        train_s: t0.elapsed().as_secs_f64(),
        inputs,
    })
}

/// No input sets to choose between: [`train`] reads every column.
const EVERY_COLUMN: (&[InputSet], usize) = (&[], 0);

/// The input sets and folds of `plan`, as [`train`] takes them.
fn choice(plan: &Plan) -> (&[InputSet], usize) {
    (&plan.sets, plan.folds)
}

/// Networks in a quick demo's default ensemble (the full run trains `visuotact train`'s).
const QUICK_ENSEMBLE: usize = 2;
/// Folds of a quick demo's input selection.
const QUICK_FOLDS: usize = 3;
/// Most epochs of a quick demo's default networks.
const QUICK_EPOCHS: usize = 200;

/// How a quick run's defaults differ from `visuotact train`'s, in words (empty otherwise).
fn quick_note(a: &DemoConfig) -> String {
    if a.quick {
        format!(
            "; --quick: {QUICK_ENSEMBLE} networks of at most {QUICK_EPOCHS} epochs, {QUICK_FOLDS} folds"
        )
    } else {
        String::new()
    }
}

/// `visuotact train`'s [`Plan`] for `columns` (markers' features first, then the rest);
/// `--quick` trains [`QUICK_ENSEMBLE`] networks of at most [`QUICK_EPOCHS`] epochs and chooses
/// the inputs by [`QUICK_FOLDS`] folds — the demo prints how many networks, epochs and folds it
/// used.
fn default_config(columns: &[String], samples: usize, a: &DemoConfig) -> Plan {
    let wanted = if a.quick {
        Wanted {
            ensemble: Some(FitConfig::default().ensemble.min(QUICK_ENSEMBLE)),
            max_epochs: Some(FitConfig::default().max_epochs.min(QUICK_EPOCHS)),
            folds: Some(QUICK_FOLDS),
            seed: a.seed,
            ..Wanted::default()
        }
    } else {
        Wanted {
            seed: a.seed,
            ..Wanted::default()
        }
    };
    Plan::new(columns, samples, &wanted)
}

/// `model`'s inputs picked by name from rows whose columns are `columns` (the model may read
/// a subset: the input set training chose).
fn inputs_of_rows(
    model: &Model,
    columns: &[String],
) -> Result<impl Fn(&[f64]) -> Vec<f64>, DemoError> {
    let picks = model.columns_in(columns)?;
    Ok(move |row: &[f64]| picks.iter().map(|&i| row[i]).collect())
}

/// The inputs `model` was trained on (from `samples` samples), in words.
fn inputs_of(model: &Model, (sets, folds): (&[InputSet], usize), samples: usize) -> String {
    let selection = &model.training.selection;
    let how = if folds_trained(samples, folds) == folds {
        format!("{folds}-fold cross-validation")
    } else if selection.iter().any(|s| s.folds == folds) {
        format!("one network each on a held-out fold of {folds}, the closest on all {folds}")
    } else {
        format!("one network each on a held-out fold of {folds}")
    };
    match selection.iter().find(|s| s.chosen) {
        Some(chosen) => format!(
            "{} (chosen by {how}; held-out error / variance {})",
            chosen.inputs,
            selection
                .iter()
                .map(|s| format!("{:.2e}", s.error))
                .collect::<Vec<_>>()
                .join(" vs ")
        ),
        None => sets.first().map_or(String::new(), |s| s.name.clone()),
    }
}

/// The papers' way with `hidden` layers.
fn paper_config(hidden: &[usize], seed: u64) -> FitConfig {
    FitConfig {
        seed,
        ..FitConfig::paper(hidden)
    }
}

/// Mean and largest value (0 and 0 for none).
fn mean_max(v: &[f64]) -> (f64, f64) {
    (
        v.iter().sum::<f64>() / v.len().max(1) as f64,
        v.iter().fold(0.0f64, |m, x| m.max(*x)),
    )
}

/// Calibrates on five rendered rest frames.
fn calibrate_rest(
    what: &'static str,
    rest: &[RgbImage],
    cfg: &CalibrationConfig,
) -> Result<SensorCalibration, DemoError> {
    let ids: Vec<String> = (0..rest.len()).map(|k| format!("ref{k}")).collect();
    calibrate(ids.iter().map(String::as_str).zip(rest.iter()), cfg)
        .map(|(cal, _)| cal)
        .map_err(|source| DemoError::Calibration { what, source })
}

/// Seed 000's sensor calibrated from contact-free frames as `calibrate` does by default
/// (grey-level centroids).
fn iats_calibration(rest: &[RgbImage]) -> Result<SensorCalibration, DemoError> {
    calibrate_rest(
        "iats",
        rest,
        &CalibrationConfig {
            detector: DetectorConfig {
                preprocess: PreprocessConfig::IATS,
                centroid: Centroid::Grey,
                ..Default::default()
            },
            layout: LayoutChoice::Auto,
            features: FeatureSet::IATS,
            ..Default::default()
        },
    )
}

/// Seed 000's experiment: the grid protocol trains, Table 3 and random touches test.
pub fn iats(a: &DemoConfig) -> Result<IatsDemo, DemoError> {
    let cfg = IatsConfig::SEED000;
    let t0 = Instant::now();
    let render = |t: &Touch, k: u64| {
        visuotact_sim::iats::render(&cfg, t, frame_seed(a.seed, k)).map(|r| r.0)
    };
    let rest: Vec<RgbImage> = (0..5)
        .map(|k| render(&Touch::default(), k))
        .collect::<Result<_, _>>()?;
    let cal = iats_calibration(&rest)?;
    let mut grid = protocol::iats_grid();
    if a.quick {
        grid.retain(|t| {
            ((t.x_mm / 4.0) as usize).is_multiple_of(2)
                && ((t.y_mm / 3.0) as usize).is_multiple_of(2)
        });
    }
    let train_f = features_of(&cal, FeatureSet::IATS, grid.len(), |k| {
        render(&grid[k], 100 + k as u64)
    })?;
    let truth = |t: &Touch| vec![t.x_mm, t.y_mm, t.depth_mm];
    // Seed 000's inputs: frames with every marker found; visuotact's: every frame, lost markers
    // filled from their neighbours, with the field summary.
    let (x, t): (Vec<_>, Vec<_>) = train_f
        .iter()
        .zip(&grid)
        .filter_map(|(f, touch)| Some((complete_markers(f)?, truth(touch))))
        .unzip();
    let (xd, td): (Vec<_>, Vec<_>) = train_f
        .iter()
        .zip(&grid)
        .filter(|(f, _)| f.iter().any(|v| v.is_finite()))
        .map(|(f, touch)| (f.clone(), truth(touch)))
        .unzip();
    let setup_s = t0.elapsed().as_secs_f64();
    let columns = FeatureExtractor::new(cal.clone(), FeatureSet::IATS)?.column_names();
    let targets = ["x_mm", "y_mm", "depth_mm"];
    // Seed 000's architecture and trainer: five hidden layers of 20, trainlm.
    let marker_columns = &columns[..columns.len() - FIELD_COLUMNS.len()];
    let paper = train(
        &x,
        &t,
        marker_columns,
        &targets,
        &paper_config(&[20; 5], a.seed),
        EVERY_COLUMN,
    )?;
    let defaults = default_config(&columns, xd.len(), a);
    let default = train(
        &xd,
        &td,
        &columns,
        &targets,
        &defaults.cfg,
        choice(&defaults),
    )?;
    let mut demo = IatsDemo {
        quick_note: quick_note(a),
        markers: cal.markers.len(),
        grid_touches: grid.len(),
        complete_frames: x.len(),
        default_frames: xd.len(),
        setup_s,
        paper,
        default,
        default_hidden: defaults.cfg.hidden,
        table3: Vec::new(),
        random_touches: 0,
        errors: Vec::new(),
        mean_spread: Vec::new(),
        distance_mm: (0.0, 0.0),
        paper_frames: 0,
        paper_distance_mm: (0.0, 0.0),
        paper_depth_mm: 0.0,
        random_points: Vec::new(),
    };
    iats_table3(a, &cal, &columns, &mut demo)?;
    iats_random(a, &cal, &columns, &mut demo)?;
    Ok(demo)
}

/// Table 3: six touches anywhere, estimated by the default.
fn iats_table3(
    a: &DemoConfig,
    cal: &SensorCalibration,
    columns: &[String],
    demo: &mut IatsDemo,
) -> Result<(), DemoError> {
    let cfg = IatsConfig::SEED000;
    let model = &demo.default.model;
    let pick = inputs_of_rows(model, columns)?;
    let f3 = features_of(cal, FeatureSet::IATS, TABLE3.len(), |k| {
        let p = TABLE3[k].0;
        let touch = Touch {
            x_mm: p[0],
            y_mm: p[1],
            depth_mm: p[2],
            ..Touch::default()
        };
        visuotact_sim::iats::render(&cfg, &touch, frame_seed(a.seed, 50_000 + k as u64))
            .map(|r| r.0)
    })?;
    demo.table3 = TABLE3
        .iter()
        .zip(&f3)
        .map(|(&(actual, paper), f)| Table3Row {
            actual,
            paper,
            estimate: model
                .estimate(&pick(f))
                .map(|e| {
                    let at = |v: &[f64], j: usize| v.get(j).copied().unwrap_or(0.0);
                    (
                        [0, 1, 2].map(|j| at(&e.values, j)),
                        [0, 1, 2].map(|j| at(&e.spread, j)),
                    )
                })
                .map_err(|why| why.to_string()),
        })
        .collect();
    Ok(())
}

/// Random touches: the accuracy figures of the paper's conclusions, for the default and for
/// the paper's network.
fn iats_random(
    a: &DemoConfig,
    cal: &SensorCalibration,
    columns: &[String],
    demo: &mut IatsDemo,
) -> Result<(), DemoError> {
    let cfg = IatsConfig::SEED000;
    let test = protocol::iats_random(&cfg, if a.quick { 100 } else { 300 }, a.seed ^ 0x7E57);
    let ft = features_of(cal, FeatureSet::IATS, test.len(), |k| {
        visuotact_sim::iats::render(&cfg, &test[k], frame_seed(a.seed, 60_000 + k as u64))
            .map(|r| r.0)
    })?;
    let (model, paper) = (&demo.default.model, &demo.paper.model);
    let pick = inputs_of_rows(model, columns)?;
    let (mut est, mut tru): ([Vec<f64>; 3], [Vec<f64>; 3]) = Default::default();
    let (mut dist, mut spreads) = (Vec::new(), Vec::new());
    let (mut paper_d, mut paper_depth) = (Vec::new(), Vec::new());
    let mut points = Vec::new();
    for (f, touch) in ft.iter().zip(&test) {
        let truth = [touch.x_mm, touch.y_mm, touch.depth_mm];
        if let Some(m) = complete_markers(f) {
            let e = paper.predict(&m);
            paper_d.push((e[0] - truth[0]).hypot(e[1] - truth[1]));
            paper_depth.push((e[2] - truth[2]).abs());
        }
        let Ok(e) = model.estimate(&pick(f)) else {
            continue;
        };
        for j in 0..3 {
            est[j].push(e.values[j]);
            tru[j].push(truth[j]);
        }
        points.push((truth, [e.values[0], e.values[1], e.values[2]]));
        dist.push((e.values[0] - truth[0]).hypot(e.values[1] - truth[1]));
        spreads.push(e.spread);
    }
    let names = ["x_mm", "y_mm", "depth_mm"];
    demo.random_touches = test.len();
    demo.errors = (0..3)
        .map(|j| target_errors(names[j], &est[j], &tru[j]))
        .collect();
    demo.mean_spread = (0..3)
        .map(|j| {
            let v: Vec<f64> = spreads.iter().filter_map(|s| s.get(j).copied()).collect();
            mean_max(&v).0
        })
        .collect();
    demo.distance_mm = mean_max(&dist);
    demo.paper_frames = paper_d.len();
    demo.paper_distance_mm = mean_max(&paper_d);
    demo.paper_depth_mm = mean_max(&paper_depth).0;
    demo.random_points = points;
    Ok(())
}

/// Frames of the cone experiment: rows per frame (`None` where a ring was lost), with and
/// without the gauge, and the loads behind them.
struct ConeFrames {
    rings: Vec<Option<Vec<f64>>>,
    with_gauge: Vec<Option<Vec<f64>>>,
    loads: Vec<ConeLoad>,
}

impl ConeFrames {
    /// Training rows of `with_gauge` or not: inputs and the force.
    fn rows(&self, gauge: bool) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
        let feats = if gauge { &self.with_gauge } else { &self.rings };
        feats
            .iter()
            .zip(&self.loads)
            .filter_map(|(f, l)| f.as_ref().map(|f| (f.clone(), vec![l.force_n])))
            .unzip()
    }
}

/// Frames per second of the cone's camera: 25, as seed 001's; a quick run films every other
/// frame.
fn cone_fps(a: &DemoConfig) -> f64 {
    if a.quick {
        12.5
    } else {
        25.0
    }
}

/// One press of the cone at `azimuth_rad` starting at `t0` s, rendered from frame `base` on.
fn cone_press(
    a: &DemoConfig,
    cal: &SensorCalibration,
    press: &ConePress,
    t0: f64,
    base: u64,
) -> Result<ConeFrames, DemoError> {
    let (cfg, fps) = (ConeConfig::SEED001, cone_fps(a));
    let n = (press.duration_s * fps) as usize;
    let loads: Vec<ConeLoad> = (0..n)
        .map(|k| press.load_at(&cfg, k as f64 / fps, t0))
        .collect();
    let rings: Vec<Option<Vec<f64>>> = features_of(cal, FeatureSet::CONE, n, |k| {
        visuotact_sim::cone::render(&cfg, &loads[k], frame_seed(a.seed, base + k as u64))
            .map(|r| r.0)
    })?
    .iter()
    .map(|f| complete_markers(f))
    .collect();
    // The link's pressure gauge, read with every frame: an input the paper did not use.
    let with_gauge = rings
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let p = PressureGauge::SEED001.reading_kpa(
                &press.drift,
                cfg.pressure_kpa,
                t0 + k as f64 / fps,
                frame_seed(a.seed ^ GAUGE_SEED, base + k as u64),
            );
            f.as_ref().map(|f| [&f[..], &[p]].concat())
        })
        .collect();
    Ok(ConeFrames {
        rings,
        with_gauge,
        loads,
    })
}

/// A model's force errors over frames whose rows have the columns `names`, and its (actual,
/// estimated) forces.
fn errors_on(
    model: &Model,
    names: &[String],
    frames: &ConeFrames,
    gauge: bool,
) -> Result<(TargetErrors, Vec<(f64, f64)>), DemoError> {
    let pick = inputs_of_rows(model, names)?;
    let feats = if gauge {
        &frames.with_gauge
    } else {
        &frames.rings
    };
    let (mut est, mut tru) = (Vec::new(), Vec::new());
    for (f, l) in feats.iter().zip(&frames.loads) {
        if let Some(f) = f {
            est.push(model.predict(&pick(f))[0]);
            tru.push(l.force_n);
        }
    }
    let points = tru.iter().copied().zip(est.iter().copied()).collect();
    Ok((target_errors("force_n", &est, &tru), points))
}

/// A sweep's outcome: the best network (lowest test MSE, the paper's way), its hidden layers,
/// the sweep's time (s), and every architecture's figures ([`Sweep`]).
struct Swept {
    best: Model,
    hidden: Vec<usize>,
    secs: f64,
    sweep: Sweep,
}

/// Seed 001's own protocol: every architecture of `archs` × `repeats` trainings (each repeat
/// on its own seed, the same for every architecture), the best net kept (lowest test MSE).
fn best_of_sweep(
    a: &DemoConfig,
    (x, t): (&[Vec<f64>], &[Vec<f64>]),
    columns: &[String],
    (archs, repeats): (&[Vec<usize>], u64),
) -> Result<Swept, DemoError> {
    let t_sweep = Instant::now();
    let trained: Vec<sweep::Trained> = sweep::jobs(archs.len(), repeats as usize)
        .into_par_iter()
        .map(|(arch, repeat)| {
            let cfg = paper_config(&archs[arch], a.seed + 7919 * repeat as u64);
            let model = train(x, t, columns, &["force_n"], &cfg, EVERY_COLUMN)?.model;
            Ok(sweep::Trained {
                arch,
                repeat,
                model,
            })
        })
        .collect::<Result<_, DemoError>>()?;
    let sweep = sweep::sweep_of(archs, trained);
    let (i, best) = sweep
        .models
        .iter()
        .min_by(|p, q| sweep::mse(&p.1, 2).total_cmp(&sweep::mse(&q.1, 2)))
        .ok_or(FitError::Empty {
            samples: x.len(),
            inputs: columns.len(),
            targets: 1,
        })?;
    Ok(Swept {
        best: best.clone(),
        hidden: archs[*i].clone(),
        secs: t_sweep.elapsed().as_secs_f64(),
        sweep,
    })
}

/// One hidden layer of 1..=`most` neurons, every `step`-th size (and `most`).
fn one_layer_archs(most: usize, step: usize) -> Vec<Vec<usize>> {
    let mut sizes: Vec<usize> = (1..=most).step_by(step.max(1)).collect();
    if sizes.last() != Some(&most) {
        sizes.push(most);
    }
    sizes.into_iter().map(|h| vec![h]).collect()
}

impl Swept {
    fn summary(&self, inputs: &'static str, n_inputs: usize) -> SweepBest {
        SweepBest {
            inputs,
            n_inputs,
            hidden: self.hidden.clone(),
            test_mse: sweep::mse(&self.best, 2),
            secs: self.secs,
            // The performance figure's points: for one-layer sweeps only.
            curve: if self.sweep.rows.iter().all(|r| r.hidden.len() == 1) {
                self.sweep.points()
            } else {
                Vec::new()
            },
        }
    }
}

/// A cone calibrated as seed 001's (annuli, weighted centroids) on five rest frames rendered
/// from frame `base` on; the frames too.
fn calibrated_cone(
    a: &DemoConfig,
    cfg: &ConeConfig,
    (what, base): (&'static str, u64),
) -> Result<(SensorCalibration, Vec<RgbImage>), DemoError> {
    let rest: Vec<RgbImage> = (0..5)
        .map(|k| {
            let load = ConeLoad::none(cfg.pressure_kpa);
            visuotact_sim::cone::render(cfg, &load, frame_seed(a.seed, base + k)).map(|r| r.0)
        })
        .collect::<Result<_, _>>()?;
    let cal = calibrate_rest(
        what,
        &rest,
        &CalibrationConfig {
            detector: DetectorConfig {
                preprocess: PreprocessConfig::CONE,
                centroid: Centroid::Weighted,
                ..Default::default()
            },
            layout: LayoutChoice::Only(Layout::Rings),
            features: FeatureSet::CONE,
            ..Default::default()
        },
    )?;
    Ok((cal, rest))
}

/// The markers' feature columns of a calibration (no field summary).
fn marker_columns(cal: &SensorCalibration) -> Result<Vec<String>, DemoError> {
    let mut columns = FeatureExtractor::new(cal.clone(), FeatureSet::CONE)?.column_names();
    columns.truncate(columns.len() - FIELD_COLUMNS.len());
    Ok(columns)
}

/// The cone calibrated on five rest frames, and its columns without and with the gauge.
fn cone_calibration(
    a: &DemoConfig,
) -> Result<(SensorCalibration, Vec<String>, Vec<String>), DemoError> {
    let (cal, _) = calibrated_cone(a, &ConeConfig::SEED001, ("cone", 200_000))?;
    let columns = marker_columns(&cal)?;
    let gauge_columns = [&columns[..], &["gauge_kpa".to_string()]].concat();
    Ok((cal, columns, gauge_columns))
}

/// Seed 001's experiment: one press trains, a later press in another state of the link tests.
pub fn cone(a: &DemoConfig) -> Result<ConeDemo, DemoError> {
    let press = ConePress {
        duration_s: if a.quick { 10.0 } else { 20.0 },
        ..ConePress::SEED001
    };
    let (cal, columns, gauge_columns) = cone_calibration(a)?;
    // Two presses: one to train on, one (later, the link softer) to test.
    let first = cone_press(a, &cal, &press, 0.0, 210_000)?;
    let later = cone_press(a, &cal, &press, press.duration_s + 5.0, 220_000)?;
    cone_table(
        a,
        cal.markers.len(),
        &columns,
        &gauge_columns,
        &first,
        &later,
    )
}

/// The best two-layer network of a 1..n × 1..n sweep.
#[derive(Clone, Debug)]
pub struct SurfaceBest {
    /// The sweep's best network and time.
    pub best: SweepBest,
    /// (first layer, second layer, mean test MSE) per architecture: the surface figure.
    pub cells: Vec<(usize, usize, f64)>,
}

/// Seed 001's experiment with rotation (Table 5.2): the force turns once about the link's
/// axis during each press.
#[derive(Clone, Debug)]
pub struct RotationDemo {
    /// Frames trained on.
    pub train_frames: usize,
    /// Repeats per architecture.
    pub repeats: u64,
    /// The one-layer sweeps (1..100 neurons; every size in the full run), rings and rings +
    /// gauge.
    pub one_layer: Vec<SweepBest>,
    /// The two-layer sweeps (1..20 × 1..20), rings and rings + gauge.
    pub two_layer: Vec<SurfaceBest>,
    /// Table 5.2's rows.
    pub rows: Vec<ConeRow>,
}

/// Seed 001's press with rotation: a one-layer sweep of 1..100 neurons and a two-layer sweep
/// of 1..20 × 1..20, with and without the gauge, the best of each over its own press (the
/// paper's way) and on a later press.
pub fn cone_rotation(a: &DemoConfig) -> Result<RotationDemo, DemoError> {
    let press = ConePress {
        duration_s: if a.quick { 10.0 } else { 20.0 },
        rotate: true,
        ..ConePress::SEED001
    };
    let (cal, columns, gauge_columns) = cone_calibration(a)?;
    let first = cone_press(a, &cal, &press, 0.0, 230_000)?;
    let later = cone_press(a, &cal, &press, press.duration_s + 5.0, 240_000)?;
    // The full run sweeps as the paper did; the quick one every few sizes, once each.
    let (step1, step2, repeats): (usize, usize, u64) = if a.quick { (9, 4, 1) } else { (1, 1, 2) };
    let one = one_layer_archs(100, step1);
    let sizes2: Vec<usize> = (1..=20).step_by(step2).collect();
    let two: Vec<Vec<usize>> = sizes2
        .iter()
        .flat_map(|&h1| sizes2.iter().map(move |&h2| vec![h1, h2]))
        .collect();
    let mut demo = RotationDemo {
        train_frames: 0,
        repeats,
        one_layer: Vec::new(),
        two_layer: Vec::new(),
        rows: Vec::new(),
    };
    for (inputs, names) in [("rings", &columns), ("rings + gauge", &gauge_columns)] {
        let gauge = inputs == "rings + gauge";
        let (x, t) = first.rows(gauge);
        demo.train_frames = x.len();
        let s1 = best_of_sweep(a, (&x, &t), names, (&one, repeats))?;
        let s2 = best_of_sweep(a, (&x, &t), names, (&two, repeats))?;
        for (what, sw) in [
            ("1 layer, best of 1..100", &s1),
            ("2 layers, best of 1..20 × 1..20", &s2),
        ] {
            for (when, frames) in [("own press", &first), ("later press", &later)] {
                let (errors, points) = errors_on(&sw.best, names, frames, gauge)?;
                let hidden: Vec<String> = sw.hidden.iter().map(ToString::to_string).collect();
                demo.rows.push(ConeRow {
                    what: format!("{what} ({}), {when}", hidden.join("-")),
                    inputs,
                    errors,
                    points,
                });
            }
        }
        demo.one_layer.push(s1.summary(inputs, names.len()));
        let cells = s2
            .sweep
            .rows
            .iter()
            .map(|r| (r.hidden[0], r.hidden[1], r.test_mse.0))
            .collect();
        let best = s2.summary(inputs, names.len());
        demo.two_layer.push(SurfaceBest { best, cells });
    }
    Ok(demo)
}

/// Trains the cone's models and fills Table 5.1.
fn cone_table(
    a: &DemoConfig,
    rings: usize,
    columns: &[String],
    gauge_columns: &[String],
    first: &ConeFrames,
    later: &ConeFrames,
) -> Result<ConeDemo, DemoError> {
    let ((x, t), (xg, tg)) = (first.rows(false), first.rows(true));
    let force = ["force_n"];
    let one = train(
        &x,
        &t,
        columns,
        &force,
        &paper_config(&[20], a.seed),
        EVERY_COLUMN,
    )?;
    let d = default_config(columns, x.len(), a);
    let default = train(&x, &t, columns, &force, &d.cfg, choice(&d))?.model;
    let dg = default_config(gauge_columns, xg.len(), a);
    let default_g = train(&xg, &tg, gauge_columns, &force, &dg.cfg, choice(&dg))?.model;
    let repeats: u64 = if a.quick { 2 } else { 5 };
    let archs = one_layer_archs(40, 1);
    let sw = best_of_sweep(a, (&x, &t), columns, (&archs, repeats))?;
    let sw_g = best_of_sweep(a, (&xg, &tg), gauge_columns, (&archs, repeats))?;
    let (best, best_g) = (&sw.best, &sw_g.best);
    let sweeps = vec![
        sw.summary("rings", columns.len()),
        sw_g.summary("rings + gauge", gauge_columns.len()),
    ];
    let own = "best of sweep, over its own press (paper's way)";
    let unseen = "best of sweep, on a later press (unseen)";
    let default_row = format!(
        "visuotact's default ({} × {}), later press",
        default.training.algorithm,
        default.networks().count()
    );
    let row = |what: &str, inputs, m: &Model, frames: &ConeFrames| {
        let gauge = inputs == "rings + gauge";
        let names = if gauge { gauge_columns } else { columns };
        let (errors, points) = errors_on(m, names, frames, gauge)?;
        Ok::<_, DemoError>(ConeRow {
            what: what.to_string(),
            inputs,
            errors,
            points,
        })
    };
    let one_later = row(
        "6 → 20 → 1, one training, on the later press",
        "rings",
        &one.model,
        later,
    )?;
    let rows = vec![
        row(own, "rings", best, first)?,
        row(unseen, "rings", best, later)?,
        one_later.clone(),
        row(&default_row, "rings", &default, later)?,
        row(own, "rings + gauge", best_g, first)?,
        row(unseen, "rings + gauge", best_g, later)?,
        row(&default_row, "rings + gauge", &default_g, later)?,
    ];
    Ok(ConeDemo {
        rings,
        train_frames: x.len(),
        one_network: one,
        repeats,
        sweeps,
        rows,
        mpe_floor_n: one_later.errors.mpe_floor,
        pressure_drop_percent: 100.0
            * (1.0 - later.loads[0].pressure_kpa / first.loads[0].pressure_kpa),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    /// The demo trains by `visuotact train`'s plan: its own training path and the plan's fit
    /// give the same model file, full and quick.
    #[test]
    fn the_demo_trains_as_the_plan_does() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let x: Vec<Vec<f64>> = (0..60)
            .map(|_| (0..4).map(|_| rng.random_range(-1.0..1.0)).collect())
            .collect();
        let t: Vec<Vec<f64>> = x.iter().map(|r| vec![r[0] * r[1] + r[2]]).collect();
        let columns: Vec<String> = (0..2)
            .flat_map(|i| [format!("m{i:03}_dx_px"), format!("m{i:03}_dy_px")])
            .collect();
        for quick in [false, true] {
            let a = DemoConfig { quick, seed: 4 };
            let plan = default_config(&columns, x.len(), &a);
            let demo = train(&x, &t, &columns, &["y"], &plan.cfg, choice(&plan))
                .unwrap()
                .model;
            let targets = vec!["y".to_string()];
            let data = FitData {
                x: &x,
                t: &t,
                feature_columns: &columns,
                targets: &targets,
            };
            let planned = plan.fit(&data, quietly).unwrap();
            assert_eq!(demo.to_json(), planned.to_json(), "quick {quick}");
        }
    }
}
