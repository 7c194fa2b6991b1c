//! `visuotact train`: a network (or an ensemble) from a feature table and labels → model.json
//! ([`visuotact_nn::fit`]), its inputs chosen by cross-validation on wide sensors.

use std::path::PathBuf;

use anyhow::bail;
use visuotact_nn::fit::{
    choose_inputs, fit_set, folds_trained, with_held_out_errors, FitConfig, FitData, InputScore,
    InputSet, ONE_FOLD_RESOLUTION,
};
use visuotact_nn::model::Model;
use visuotact_nn::plan::{Plan, Wanted};
use visuotact_pipeline::table::TrainingTable;

use crate::args::{parse_list, AlgorithmArg, DataArgs};
use crate::fit_error;
use crate::progress::Reporter;

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    #[command(flatten)]
    data: DataArgs,
    /// Hidden layer sizes, comma-separated (e.g. 20 or 20,20). Default: one layer of 20, and on
    /// tables of 1 000 frames or more the wide network (Adam) is a candidate too; set, it is
    /// what trains (docs/cli.md).
    #[arg(long)]
    hidden: Option<String>,
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
    /// their mean. The spread beside each (`predict` writes `<target>_std`, `run` and its
    /// dashboard show it) is the larger of the networks' standard deviation and the held-out
    /// RMS error of the training frames whose estimates lie nearest (samples the networks' or
    /// the input choice's folds held out). By default 5 (on 280 simulated touches of four sensors
    /// it cut the contact error by 7–35 % against one network); on tables of 1 000 frames or
    /// more 3 Levenberg–Marquardt networks or 4 wide ones (docs/benchmarks.md).
    #[arg(long, value_name = "K")]
    ensemble: Option<usize>,
    /// Sensor file to store in the model (the calibration the features came from).
    #[arg(long)]
    sensor: Option<PathBuf>,
    /// No progress lines (by default one every 2 s on stderr, also when it is not a terminal).
    #[arg(long, short)]
    quiet: bool,
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let hidden = match &a.hidden {
        Some(h) => {
            let hidden: Vec<usize> = parse_list(h, "hidden")?;
            if hidden.is_empty() || hidden.contains(&0) {
                bail!("--hidden needs positive layer sizes, got {h:?}");
            }
            Some(hidden)
        }
        None => None,
    };
    check_output(a)?;
    let sensor = match &a.sensor {
        Some(p) => Some(serde_json::to_value(crate::load_sensor(p)?)?),
        None => None,
    };
    let (targets, data) = a.data.load(a.algorithm.field(), |n| {
        matches!(a.algorithm.components(n), Ok(Some(_)))
    })?;
    let wanted = Wanted {
        hidden,
        algorithm: a.algorithm.name,
        components: a.algorithm.wanted_components(data.marker_inputs())?,
        field: a.algorithm.field(),
        ensemble: a.ensemble,
        seed: a.seed,
        max_epochs: Some(a.max_epochs),
        folds: None,
    };
    let TrainingTable {
        x,
        t,
        feature_columns,
        ..
    } = data;
    let t0 = std::time::Instant::now();
    let plan = Plan::new(&feature_columns, x.len(), &wanted);
    let data = FitData {
        x: &x,
        t: &t,
        feature_columns: &feature_columns,
        targets: &targets,
    };
    check_memory(a, &data, &plan)?;
    let reporter = Reporter::new(a.quiet);
    let (best, mut selection) = choose(&data, &plan, &reporter)?;
    interrupted(&reporter)?;
    let set = &plan.sets[best];
    let cfg = FitConfig {
        ensemble: plan.networks(set, x.len()),
        ..plan.cfg.clone()
    };
    note!(
        "training {}, {}) on {} frames, {} network{}",
        set.network_in_words(&cfg.hidden, targets.len()),
        set.algorithm(cfg.algorithm).name(),
        x.len(),
        cfg.ensemble,
        if cfg.ensemble == 1 {
            ""
        } else {
            "s in parallel"
        }
    );
    reporter.stage("training");
    let mut model = fit_set(&data, set, &cfg, |p: &_| reporter.training(p)).map_err(fit_error)?;
    interrupted(&reporter)?;
    with_held_out_errors(&mut model, &mut selection, &t);
    model.training.selection = selection;
    model.sensor = sensor;
    let json = model.to_checked_json(&a.output.display().to_string())?;
    crate::write_atomically(&a.output, &json)?;
    print_trained(&model, &targets, t0.elapsed().as_secs_f64());
    note!("wrote {}", a.output.display());
    Ok(())
}

/// States the memory the training needs (refused over the limit) and warns of constant
/// targets.
fn check_memory(a: &Args, data: &FitData<'_>, plan: &Plan) -> anyhow::Result<()> {
    let widest = plan
        .sets
        .iter()
        .filter(|s| !s.wide)
        .map(InputSet::network_inputs)
        .max()
        .unwrap_or(0);
    let need = a
        .algorithm
        .check_memory((widest, data.x.len(), data.targets.len()), &plan.cfg)?;
    crate::print::memory("this training needs", need);
    for c in data.constant_targets() {
        note!("warning: target `{c}` has the same value in every frame: nothing to learn about it (its R is 0)");
    }
    Ok(())
}

/// The model file is none of the inputs and can be written, checked before any training.
fn check_output(a: &Args) -> anyhow::Result<()> {
    let mut inputs = vec![a.data.features.as_path(), a.data.labels.as_path()];
    inputs.extend(a.sensor.as_deref());
    inputs.extend(a.data.extra.readings.as_deref());
    visuotact_io::guard::refuse_output_over_input(&a.output, &inputs)?;
    Ok(visuotact_io::guard::check_writable(&a.output)?)
}

/// Refuses to go on after Ctrl-C: nothing is written.
fn interrupted(reporter: &Reporter) -> anyhow::Result<()> {
    if reporter.interrupted() {
        bail!("interrupted (Ctrl-C): no model written");
    }
    Ok(())
}

/// Chooses the input set by cross-validation when there is a choice, saying so.
fn choose(
    data: &FitData<'_>,
    plan: &Plan,
    reporter: &Reporter,
) -> anyhow::Result<(usize, Vec<InputScore>)> {
    let (cfg, sets) = (&plan.cfg, plan.sets.as_slice());
    if sets.len() > 1 {
        let folds = folds_trained(data.x.len(), plan.folds);
        note!(
            "choosing the inputs by {}: {}",
            if folds == plan.folds {
                format!(
                    "{}-fold cross-validation (one network per fold)",
                    plan.folds
                )
            } else {
                format!(
                    "one network each, scored on a fifth of the {} frames held out (sets \
                     within {:.0} % of the best then on all {} fifths)",
                    data.x.len(),
                    100.0 * (ONE_FOLD_RESOLUTION - 1.0),
                    plan.folds
                )
            },
            sets.iter()
                .map(|s| s.name.as_str())
                .collect::<Vec<_>>()
                .join(" or ")
        );
        reporter.stage("choosing the inputs");
    }
    let (best, selection) =
        choose_inputs(data, cfg, sets, plan.folds, |p: &_| reporter.training(p))
            .map_err(fit_error)?;
    let all_folds = selection.iter().any(|s| s.folds == plan.folds);
    for score in &selection {
        note!(
            "  {} {}: held-out error / variance {:.3e}{} (per target {})",
            if score.chosen { "chose" } else { "     " },
            score.inputs,
            score.error,
            if all_folds && score.folds < plan.folds {
                format!(" on {} fold", score.folds)
            } else {
                String::new()
            },
            score
                .normalised_mse
                .iter()
                .map(|e| format!("{e:.3e}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }

    Ok((best, selection))
}

/// How training went: epochs, why it stopped, and each target's figures per subset.
fn print_trained(model: &Model, targets: &[String], secs: f64) {
    let tr = &model.training;
    note!(
        "trained ({}) in {:.2} s: {} epochs (best {}), stopped by {}",
        tr.algorithm,
        secs,
        tr.epochs,
        tr.best_epoch,
        tr.stop
    );
    if let Some(e) = &tr.evidence {
        note!(
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
        note!(
            "  {name}: mse train {}, validation {}, test {}; R train {}, validation {}, test {}",
            cell(&tr.mse[0], j, false),
            cell(&tr.mse[1], j, false),
            cell(&tr.mse[2], j, false),
            cell(&tr.r[0], j, true),
            cell(&tr.r[1], j, true),
            cell(&tr.r[2], j, true)
        );
    }
    if let Some(words) = model.spread_in_words() {
        note!("spread (<target>_std): {words}");
    }
}
