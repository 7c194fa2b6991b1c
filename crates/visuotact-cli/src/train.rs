//! `visuotact train`, `predict` and `eval`: networks from feature tables, estimates, and the
//! error figures of the source documents.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use visuotact_io::frames::FrameStream;
use visuotact_io::table::{KeyedTable, TableFormat, TableWriter};
use visuotact_nn::fit::{
    candidate_inputs, choose_inputs, column_kinds, components_from_name, fit_set, FieldInputs,
    FitConfig, FitData, FitError, InputSet, SELECTION_FOLDS,
};
use visuotact_nn::lm::Control;
use visuotact_nn::metrics::TargetErrors;
use visuotact_nn::mlp::{Algorithm, Mlp};
pub(crate) use visuotact_nn::model::is_marker_column;
use visuotact_nn::model::Model;
use visuotact_pipeline::evaluation::{evaluate_files, MapPoint};
pub(crate) use visuotact_pipeline::table::TrainingTable as Joined;
use visuotact_pipeline::table::{training_table, Incomplete, InputSources, JoinConfig, Named};
use visuotact_vision::features::{FeatureExtractor, FeatureSet, FIELD_COLUMNS};

#[derive(clap::Args, Debug)]
pub(crate) struct TrainArgs {
    #[command(flatten)]
    data: DataArgs,
    /// Hidden layer sizes, comma-separated (e.g. 20 or 20,20).
    #[arg(long, default_value = DEFAULT_HIDDEN)]
    hidden: String,
    /// Model file to write.
    #[arg(short, long)]
    output: PathBuf,
    /// Seed of the split and the initial weights.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Most epochs (trainlm: 1000).
    #[arg(long, default_value_t = 1000)]
    max_epochs: usize,
    #[command(flatten)]
    algorithm: AlgorithmArg,
    /// Train this many networks on other seeds and splits into one model file: estimates are
    /// their mean, with the standard deviation as the spread (`predict` writes `<target>_std`,
    /// `run` and its dashboard show it). 5 by default: on 280 simulated touches of four sensors
    /// it cut the contact error by 7–35 % against one network (docs/benchmarks.md).
    #[arg(long, value_name = "K", default_value_t = FitConfig::default().ensemble)]
    ensemble: usize,
    /// Sensor file to store in the model (the calibration the features came from).
    #[arg(long)]
    sensor: Option<PathBuf>,
}

/// The training objective and input reduction, shared by `train` and `sweep`.
#[derive(clap::Args, Debug, Clone)]
pub(crate) struct AlgorithmArg {
    /// trainbr (the default: Bayesian regularisation, LM on errors plus weights, every sample
    /// trains, no validation subset; on 280 simulated touches of four sensors it generalised
    /// best, docs/benchmarks.md) or trainlm (MATLAB's default: LM on the squared errors,
    /// 70/15/15 split, stopped by the validation subset).
    #[arg(long = "algorithm", default_value = FitConfig::default().algorithm.name(), value_parser = ["trainlm", "trainbr"])]
    pub(crate) name: String,
    /// Feed the network the K leading principal components of the scaled inputs (kept in the
    /// model file): auto (10 when there are over 20 inputs, otherwise the inputs themselves),
    /// 0 (the inputs themselves) or K.
    #[arg(long, value_name = "auto|K", default_value = "auto")]
    pub(crate) components: String,
    /// The field-summary columns of the feature table (`field_rms_px` … `field_spread_px`:
    /// how much the markers moved and where) as inputs: auto (the default: when there are
    /// over 20 markers' features, 5-fold cross-validation on the training frames chooses
    /// between the field summary beside the markers' principal components and the field
    /// summary alone, and the model file keeps both scores; which generalises better depends
    /// on the sensor: on 280 simulated touches of four sensors in three drawn variants each the
    /// default was 4.1–24× better in contact distance and 3.3–10× in depth than the best
    /// scikit-learn peer, and where both rules were measured it matched the better one,
    /// docs/benchmarks.md), yes (beside the markers' features), only (instead of them), or
    /// no. Tables extracted before the field summary existed have none.
    #[arg(long, value_name = "auto|yes|only|no", default_value = "auto", value_parser = ["auto", "yes", "only", "no"])]
    pub(crate) field: String,
}

/// `train`'s hidden layers when not told otherwise ([`FitConfig::default`]'s, as text).
pub(crate) const DEFAULT_HIDDEN: &str = "20";

impl AlgorithmArg {
    pub(crate) fn algorithm(&self) -> Algorithm {
        Algorithm::from_name(&self.name).unwrap_or_default()
    }

    /// Whether the field summary is an input.
    pub(crate) fn field(&self) -> FieldInputs {
        FieldInputs::from_name(&self.field).unwrap_or(FieldInputs::Auto)
    }

    /// The number of components for `inputs` marker inputs (`None`: no projection).
    pub(crate) fn components(&self, inputs: usize) -> anyhow::Result<Option<usize>> {
        components_from_name(&self.components, inputs)
            .map_err(|e| anyhow::anyhow!("--components {e}"))
    }
}

/// The training data: features, labels, which targets, what to do with incomplete frames.
#[derive(clap::Args, Debug)]
pub(crate) struct DataArgs {
    /// Feature table from `extract` (per-marker columns `mNNN_…` are the inputs).
    #[arg(long)]
    pub(crate) features: PathBuf,
    /// Label table keyed by `frame` (a session's labels.csv).
    #[arg(long)]
    pub(crate) labels: PathBuf,
    /// Target columns of the labels, comma-separated (e.g. x_mm,y_mm,depth_mm).
    #[arg(long)]
    pub(crate) targets: String,
    #[command(flatten)]
    pub(crate) extra: ExtraInputs,
    /// Leave out frames with missing feature cells (lost markers) instead of filling them
    /// (models on principal components fill them from the markers found; others fail).
    #[arg(long)]
    pub(crate) drop_incomplete: bool,
}

/// Inputs besides the marker features, e.g. the reading of a pressure gauge on an inflatable
/// link: named columns of the feature table or of a readings table keyed by `frame`.
#[derive(clap::Args, Debug, Default)]
pub(crate) struct ExtraInputs {
    /// Extra input columns, comma-separated (e.g. gauge_kpa), looked up in the feature table,
    /// then in --readings.
    #[arg(long, value_name = "COLUMNS")]
    pub(crate) inputs: Option<String>,
    /// Table keyed by `frame` holding the extra inputs (a simulated cone session's labels.csv
    /// has the gauge reading `gauge_kpa`).
    #[arg(long, value_name = "TABLE", requires = "inputs")]
    pub(crate) readings: Option<PathBuf>,
}

impl ExtraInputs {
    /// The extra input names (empty without --inputs).
    fn names(&self) -> anyhow::Result<Vec<String>> {
        match &self.inputs {
            None => Ok(Vec::new()),
            Some(s) => {
                let names = column_names(s, "inputs")?;
                if let Some(c) = names.iter().find(|c| is_marker_column(c)) {
                    bail!("--inputs {c}: marker features are inputs already; name other columns");
                }
                Ok(names)
            }
        }
    }

    fn readings_table(&self) -> anyhow::Result<Option<KeyedTable>> {
        read_readings(self.readings.as_deref())
    }
}

/// A readings table keyed by `frame` (every column numeric), when one is given.
pub(crate) fn read_readings(path: Option<&Path>) -> anyhow::Result<Option<KeyedTable>> {
    Ok(path.map(|p| KeyedTable::read(p, &[])).transpose()?)
}

impl DataArgs {
    /// The target names and the joined table; frames with missing inputs are kept (to be
    /// filled) when `fills(number of inputs)` says the model will fill them.
    pub(crate) fn load(
        &self,
        field: FieldInputs,
        fills: impl Fn(usize) -> bool,
    ) -> anyhow::Result<(Vec<String>, Joined)> {
        let targets = parse_targets(&self.targets)?;
        let f = KeyedTable::read(&self.features, &["flags"])?;
        let l = KeyedTable::read(&self.labels, &[])?;
        let readings = self.extra.readings_table()?;
        let (f_name, l_name) = (
            self.features.display().to_string(),
            self.labels.display().to_string(),
        );
        let r_name = self
            .extra
            .readings
            .as_ref()
            .map(|p| p.display().to_string());
        let extra = self.extra.names()?;
        let cfg = JoinConfig {
            targets: &targets,
            extra_inputs: &extra,
            field,
            incomplete: if self.drop_incomplete {
                Incomplete::Drop
            } else {
                Incomplete::FillIf(&fills)
            },
        };
        let j = training_table(
            Named {
                table: &f,
                name: &f_name,
            },
            Named {
                table: &l,
                name: &l_name,
            },
            readings
                .as_ref()
                .zip(r_name.as_deref())
                .map(|(table, name)| Named { table, name }),
            &cfg,
        )?;
        for note in &j.notes {
            eprintln!("{note}");
        }
        Ok((targets, j))
    }
}

pub(crate) fn parse_list<T: std::str::FromStr>(s: &str, what: &str) -> anyhow::Result<Vec<T>> {
    s.split(',')
        .map(|p| {
            p.trim()
                .parse::<T>()
                .map_err(|_| anyhow::anyhow!("--{what}: {p:?} is not valid"))
        })
        .collect()
}

pub(crate) fn parse_targets(s: &str) -> anyhow::Result<Vec<String>> {
    column_names(s, "targets")
}

/// Column names from the comma-separated list of option `--what` (at least one).
fn column_names(s: &str, what: &str) -> anyhow::Result<Vec<String>> {
    let names: Vec<String> = s
        .split(',')
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .collect();
    if names.is_empty() {
        bail!("--{what} is empty");
    }
    Ok(names)
}

pub(crate) fn train(a: &TrainArgs) -> anyhow::Result<()> {
    let hidden: Vec<usize> = parse_list(&a.hidden, "hidden")?;
    if hidden.is_empty() || hidden.contains(&0) {
        bail!("--hidden needs positive layer sizes, got {:?}", a.hidden);
    }
    let sensor = match &a.sensor {
        Some(p) => Some(serde_json::to_value(crate::load_sensor(p)?)?),
        None => None,
    };
    let (targets, data) = a.data.load(a.algorithm.field(), |n| {
        matches!(a.algorithm.components(n), Ok(Some(_)))
    })?;
    let components = a.algorithm.components(data.marker_inputs())?;
    let Joined {
        x,
        t,
        feature_columns,
        passthrough,
        ..
    } = data;
    let sets = candidate_inputs(
        &column_kinds(&feature_columns, &FIELD_COLUMNS),
        components,
        a.algorithm.field(),
    );
    let t0 = std::time::Instant::now();
    let cfg = FitConfig {
        hidden,
        seed: a.seed,
        max_epochs: a.max_epochs,
        algorithm: a.algorithm.algorithm(),
        hold_out: false,
        components,
        passthrough,
        ensemble: a.ensemble,
    };
    let data = FitData {
        x: &x,
        t: &t,
        feature_columns: &feature_columns,
        targets: &targets,
    };
    if sets.len() > 1 {
        eprintln!(
            "choosing the inputs by {SELECTION_FOLDS}-fold cross-validation (one network per fold): {}",
            sets.iter()
                .map(|s| s.name.as_str())
                .collect::<Vec<_>>()
                .join(" or ")
        );
    }
    let (best, selection) =
        choose_inputs(&data, &cfg, &sets, SELECTION_FOLDS).map_err(fit_error)?;
    for score in &selection {
        eprintln!(
            "  {} {}: held-out error / variance {:.3e} (per target {})",
            if score.chosen { "chose" } else { "     " },
            score.inputs,
            score.error,
            score
                .normalised_mse
                .iter()
                .map(|e| format!("{e:.3e}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let set = &sets[best];
    eprintln!(
        "training {} → {} → {} ({} weights, {}) on {} frames",
        inputs_in_words(set),
        cfg.hidden
            .iter()
            .map(usize::to_string)
            .collect::<Vec<_>>()
            .join(" → "),
        targets.len(),
        Mlp::n_params_for(
            &[
                &[set
                    .components
                    .map_or(set.columns.len(), |k| k + set.passthrough)][..],
                &cfg.hidden,
                &[targets.len()]
            ]
            .concat()
        ),
        a.algorithm.name,
        x.len()
    );
    let mut model = fit_set(&data, set, &cfg, |epoch, train_mse, val_mse| {
        if epoch % 10 == 0 {
            if val_mse.is_nan() {
                eprintln!("epoch {epoch}: mse train {train_mse:.3e} (scaled)");
            } else {
                eprintln!(
                    "epoch {epoch}: mse train {train_mse:.3e}, validation {val_mse:.3e} (scaled)"
                );
            }
        }
        Control::Continue
    })
    .map_err(fit_error)?;
    model.training.selection = selection;
    model.sensor = sensor;
    crate::write_atomically(&a.output, &model.to_json())?;
    let tr = &model.training;
    eprintln!(
        "trained ({}) in {:.2} s: {} epochs (best {}), stopped by {}",
        tr.algorithm,
        t0.elapsed().as_secs_f64(),
        tr.epochs,
        tr.best_epoch,
        tr.stop
    );
    if let Some(e) = &tr.evidence {
        eprintln!(
            "  effective parameters γ {:.1} of {} (α {:.3e}, β {:.3e})",
            e.gamma,
            model.net.params.len(),
            e.alpha,
            e.beta
        );
    }
    let cell = |v: &[f64], j: usize, r: bool| {
        v.get(j).map_or("–".to_string(), |x| {
            if r {
                format!("{x:.5}")
            } else {
                format!("{x:.4e}")
            }
        })
    };
    for (j, name) in targets.iter().enumerate() {
        eprintln!(
            "  {name}: mse train {}, validation {}, test {}; R train {}, validation {}, test {}",
            cell(&tr.mse[0], j, false),
            cell(&tr.mse[1], j, false),
            cell(&tr.mse[2], j, false),
            cell(&tr.r[0], j, true),
            cell(&tr.r[1], j, true),
            cell(&tr.r[2], j, true)
        );
    }
    eprintln!("wrote {}", a.output.display());
    Ok(())
}

#[derive(clap::Args, Debug)]
pub(crate) struct PredictArgs {
    /// Model file from `train`.
    #[arg(long)]
    model: PathBuf,
    /// Feature table from `extract` (or give --sensor and frames).
    #[arg(long, conflicts_with_all = ["sensor", "frames"])]
    features: Option<PathBuf>,
    /// Sensor file: extract features from FRAMES with it, then estimate.
    #[arg(long, requires = "frames")]
    sensor: Option<PathBuf>,
    /// Frames (image files, folders, videos) when --sensor is given.
    frames: Vec<PathBuf>,
    /// Table keyed by `frame` holding inputs of the model that are not in the feature table
    /// (e.g. a pressure gauge's `gauge_kpa`).
    #[arg(long, value_name = "TABLE", requires = "features")]
    readings: Option<PathBuf>,
    /// Output table (`-` for standard output).
    #[arg(short, long)]
    output: PathBuf,
}

/// A training error in the command line's words (the projection is `--components`).
/// How many inputs `set` reads and how they reach the network, in words.
fn inputs_in_words(set: &InputSet) -> String {
    let n = set.columns.len();
    match set.components {
        None => n.to_string(),
        Some(k) => format!(
            "{n} inputs (the markers' {} as {k} principal components{})",
            n - set.passthrough,
            if set.passthrough > 0 {
                format!(", {} more as they are", set.passthrough)
            } else {
                String::new()
            }
        ),
    }
}

pub(crate) fn fit_error(e: FitError) -> anyhow::Error {
    match e {
        FitError::Projection(m) => anyhow::anyhow!("--components: {m}"),
        e => e.into(),
    }
}

/// The feature set a model's input columns need ([`visuotact_pipeline::feature_set_of`]).
pub(crate) fn feature_set_of(columns: &[String]) -> anyhow::Result<FeatureSet> {
    Ok(visuotact_pipeline::feature_set_of(columns)?)
}

/// Features of frames extracted with a sensor file, as a keyed table.
fn features_from_frames(
    sensor: &Path,
    frames: &[PathBuf],
    columns: &[String],
) -> anyhow::Result<KeyedTable> {
    let cal = crate::load_sensor(sensor)?;
    let mut ex =
        FeatureExtractor::new(cal, feature_set_of(columns)?).map_err(anyhow::Error::msg)?;
    let names = ex.column_names();
    let (mut keys, mut rows) = (Vec::new(), Vec::new());
    for item in FrameStream::open(frames, 25.0)? {
        let frame = match item {
            Ok(f) => f,
            Err(e) => {
                eprintln!("warning: {e}; skipped");
                continue;
            }
        };
        match ex.extract(&frame.image) {
            Ok(f) => {
                keys.push(frame.id);
                rows.push(f.values);
            }
            Err(e) => eprintln!("warning: frame {}: {e}; skipped", frame.id),
        }
    }
    let n_rows = rows.len();
    Ok(KeyedTable {
        columns: names,
        keys,
        text: vec![Vec::new(); n_rows],
        rows,
        dropped_partial_line: false,
    })
}

pub(crate) fn load_model(path: &Path) -> anyhow::Result<Model> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read model file", path.display()))?;
    Model::from_json(&text, &path.display().to_string()).map_err(anyhow::Error::msg)
}

pub(crate) fn predict(a: &PredictArgs) -> anyhow::Result<()> {
    let model = load_model(&a.model)?;
    let (f, source) = match (&a.features, &a.sensor) {
        (Some(p), _) => (
            KeyedTable::read(p, &["flags"]).map_err(anyhow::Error::msg)?,
            p.display().to_string(),
        ),
        (None, Some(sensor)) => (
            features_from_frames(sensor, &a.frames, &model.feature_columns)?,
            format!("frames read with {}", sensor.display()),
        ),
        (None, None) => bail!("give --features TABLE, or --sensor SENSOR FRAMES..."),
    };
    let readings = read_readings(a.readings.as_deref())?;
    let r_name = a.readings.as_ref().map(|p| p.display().to_string());
    let sources = InputSources::new(
        &model.feature_columns,
        Named {
            table: &f,
            name: &source,
        },
        readings
            .as_ref()
            .zip(r_name.as_deref())
            .map(|(table, name)| Named { table, name }),
        &format!(
            "the model {} was trained on other inputs",
            a.model.display()
        ),
    )?;
    // An ensemble also writes each target's spread (standard deviation over its networks).
    let columns = model.estimate_columns();
    let width = columns.len();
    let mut out = TableWriter::create(&a.output, TableFormat::Csv, columns)?;
    let (mut written, mut missing, mut filled) = (0, 0, 0);
    let mut x = Vec::with_capacity(model.feature_columns.len());
    for (r, key) in f.keys.iter().enumerate() {
        sources.row_into(r, &mut x);
        // Lost markers are filled by a model on principal components; a missing reading, too
        // many lost markers or a model without components: no estimate rather than a wrong one,
        // and the reason in the flags.
        match model.estimate(&x) {
            Ok(e) => {
                let note = if e.filled > 0 {
                    filled += 1;
                    format!("filled {} inputs", e.filled)
                } else {
                    String::new()
                };
                out.write_row(key, &e.into_row(), &note)?;
                written += 1;
            }
            Err(why) => {
                out.write_row(key, &vec![f64::NAN; width], &why.to_string())?;
                missing += 1;
            }
        }
    }
    let filled_note = if filled > 0 {
        format!(" ({filled} with lost markers filled)")
    } else {
        String::new()
    };
    eprintln!("{written} estimates{filled_note}, {missing} frames without");
    Ok(())
}

#[derive(clap::Args, Debug)]
pub(crate) struct EvalArgs {
    /// Predictions from `predict`.
    #[arg(long)]
    predictions: PathBuf,
    /// Labels keyed by `frame`.
    #[arg(long)]
    labels: PathBuf,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// Also draw the regression plot (estimate against truth, one panel per target), as SVG or
    /// PNG by the file's extension.
    #[arg(long, value_name = "FILE.svg|FILE.png")]
    plot: Option<PathBuf>,
    /// Also draw the contact map (seed 000 Fig. 10): actual and estimated contact points
    /// (`x_mm`, `y_mm`), joined, circle size ∝ depth (`depth_mm`, when present); SVG or PNG.
    #[arg(long, value_name = "FILE.svg|FILE.png")]
    map: Option<PathBuf>,
}

/// Seed 000 Fig. 10: actual contact points (rings) and estimates (discs), joined; radius ∝
/// depth; y down, as the marker coordinates.
struct ContactMap<'a> {
    points: &'a [MapPoint],
    distance_mean_mm: f64,
}

impl crate::plot::Figure for ContactMap<'_> {
    fn size(&self) -> (u32, u32) {
        (800, 640)
    }

    fn draw<DB: plotters::prelude::DrawingBackend>(
        &self,
        root: &plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String> {
        use crate::plot::{finite_range, padded, text};
        use plotters::prelude::*;
        root.fill(&WHITE).map_err(text)?;
        let pts = self.points;
        let (x_lo, x_hi) = padded(
            finite_range(pts.iter().flat_map(|(a, e)| [a[0], e[0]])).unwrap_or((0.0, 1.0)),
            0.04,
        );
        let (y_lo, y_hi) = padded(
            finite_range(pts.iter().flat_map(|(a, e)| [a[1], e[1]])).unwrap_or((0.0, 1.0)),
            0.04,
        );
        let depth_max = pts
            .iter()
            .flat_map(|(a, e)| [a[2], e[2]])
            .filter(|d| d.is_finite())
            .fold(0.0f64, |m, d| m.max(d.abs()));
        let radius = |d: f64| -> i32 {
            if d.is_finite() && depth_max > 0.0 {
                (2.0 + 10.0 * (d.abs() / depth_max)).round() as i32
            } else {
                4
            }
        };
        let depth_note = if depth_max > 0.0 {
            ", radius ∝ depth"
        } else {
            ""
        };
        let mut chart = ChartBuilder::on(root)
            .caption(
                format!(
                    "contact map: actual (rings) and estimated (discs){depth_note}; D mean {:.3} mm",
                    self.distance_mean_mm
                ),
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(x_lo..x_hi, y_hi..y_lo)
            .map_err(text)?;
        chart
            .configure_mesh()
            .x_desc("x, mm")
            .y_desc("y, mm")
            .draw()
            .map_err(text)?;
        chart
            .draw_series(pts.iter().map(|(a, e)| {
                PathElement::new([(a[0], a[1]), (e[0], e[1])], RED.mix(0.6).stroke_width(1))
            }))
            .map_err(text)?;
        chart
            .draw_series(
                pts.iter()
                    .map(|(a, _)| Circle::new((a[0], a[1]), radius(a[2]), BLACK.stroke_width(1))),
            )
            .map_err(text)?;
        chart
            .draw_series(
                pts.iter()
                    .map(|(_, e)| Circle::new((e[0], e[1]), radius(e[2]), BLUE.mix(0.45).filled())),
            )
            .map_err(text)?;
        Ok(())
    }
}

/// One regression panel: target name, (truth, estimate) pairs, R.
type Panel = (String, Vec<(f64, f64)>, f64);

/// Estimates against truth, one panel per target, with the y = x line and R.
struct RegressionPlot<'a>(&'a [Panel]);

impl crate::plot::Figure for RegressionPlot<'_> {
    fn size(&self) -> (u32, u32) {
        (420 * self.0.len().max(1) as u32, 420)
    }

    fn draw<DB: plotters::prelude::DrawingBackend>(
        &self,
        root: &plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String> {
        use crate::plot::text;
        use plotters::prelude::*;
        root.fill(&WHITE).map_err(text)?;
        for (area, (name, pts, r)) in root
            .split_evenly((1, self.0.len().max(1)))
            .iter()
            .zip(self.0)
        {
            let (lo, hi) = crate::plot::padded(
                crate::plot::finite_range(pts.iter().flat_map(|p| [p.0, p.1]))
                    .unwrap_or((0.0, 1.0)),
                0.05,
            );
            let mut chart = ChartBuilder::on(area)
                .caption(format!("{name}: R = {r:.5}"), ("sans-serif", 18))
                .margin(10)
                .x_label_area_size(35)
                .y_label_area_size(50)
                .build_cartesian_2d(lo..hi, lo..hi)
                .map_err(text)?;
            chart
                .configure_mesh()
                .x_desc("target")
                .y_desc("estimate")
                .draw()
                .map_err(text)?;
            chart
                .draw_series(LineSeries::new([(lo, lo), (hi, hi)], &BLACK))
                .map_err(text)?;
            chart
                .draw_series(
                    pts.iter()
                        .map(|&(t, e)| Circle::new((t, e), 2, BLUE.mix(0.5).filled())),
                )
                .map_err(text)?;
        }
        Ok(())
    }
}

pub(crate) fn eval(a: &EvalArgs) -> anyhow::Result<()> {
    evaluate(
        &a.predictions,
        &a.labels,
        a.json,
        a.plot.as_deref(),
        a.map.as_deref(),
    )
}

/// Prints the error figures of a predictions table against a labels table
/// ([`visuotact_pipeline::evaluation`]) and draws the figures asked for.
pub(crate) fn evaluate(
    predictions: &Path,
    labels: &Path,
    json: bool,
    plot: Option<&Path>,
    map: Option<&Path>,
) -> anyhow::Result<()> {
    let e = evaluate_files(predictions, labels)?;
    if let Some(path) = plot {
        let panels: Vec<Panel> = e
            .targets
            .iter()
            .map(|t| (t.errors.target.clone(), t.points.clone(), t.errors.r))
            .collect();
        crate::plot::save(&RegressionPlot(&panels), path)?;
        eprintln!("wrote {}", path.display());
    }
    if let Some(path) = map {
        let Some(d) = e.distance_mm else {
            bail!(
                "--map needs contact positions: columns x_mm and y_mm in both {} and {}",
                predictions.display(),
                labels.display()
            );
        };
        let figure = ContactMap {
            points: &e.map,
            distance_mean_mm: d.mean,
        };
        crate::plot::save(&figure, path)?;
        eprintln!("wrote {}", path.display());
    }
    let figures: Vec<&TargetErrors> = e.targets.iter().map(|t| &t.errors).collect();
    if json {
        let v = serde_json::json!({
            "targets": figures,
            "distance_mm": e.distance_mm,
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    println!(
        "{:<12} {:>6} {:>11} {:>8} {:>10} {:>10} {:>8} {:>9}",
        "target", "n", "mse", "R", "mean |e|", "max |e|", "MPE %", "acc. %"
    );
    for f in &figures {
        println!(
            "{:<12} {:>6} {:>11.4e} {:>8.5} {:>10.4} {:>10.4} {:>8.2} {:>9.2}",
            f.target,
            f.n,
            f.mse,
            f.r,
            f.mean_abs,
            f.max_abs,
            f.mean_percentage_error,
            f.accuracy_percent
        );
    }
    if let Some(d) = e.distance_mm {
        println!(
            "distance D (x, y): mean {:.3} mm, max {:.3} mm",
            d.mean, d.max
        );
    }
    println!(
        "MPE and accuracy over samples with |target| ≥ {:.0} % of the largest |target|",
        100.0 * visuotact_nn::metrics::MPE_FLOOR_FRACTION
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_hidden_layers_are_the_librarys() {
        let parsed: Vec<usize> = parse_list(DEFAULT_HIDDEN, "hidden").unwrap();
        assert_eq!(parsed, FitConfig::default().hidden);
    }
}
