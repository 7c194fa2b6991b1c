//! `visuotact train`: a network (or an ensemble) from a feature table and labels → model.json
//! ([`visuotact_nn::fit`]), its inputs chosen by cross-validation on wide sensors.

use std::path::PathBuf;

use anyhow::bail;
use visuotact_nn::fit::{
    candidate_inputs, choose_inputs, column_kinds, fit_set, FitConfig, FitData, InputScore,
    InputSet, SELECTION_FOLDS,
};
use visuotact_nn::lm::Control;
use visuotact_nn::model::Model;
use visuotact_pipeline::table::TrainingTable;
use visuotact_vision::features::FIELD_COLUMNS;

use crate::args::{parse_list, AlgorithmArg, DataArgs, DEFAULT_HIDDEN};
use crate::fit_error;

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
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

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let hidden: Vec<usize> = parse_list(&a.hidden, "hidden")?;
    if hidden.is_empty() || hidden.contains(&0) {
        bail!("--hidden needs positive layer sizes, got {:?}", a.hidden);
    }
    check_output(a)?;
    let sensor = match &a.sensor {
        Some(p) => Some(serde_json::to_value(crate::load_sensor(p)?)?),
        None => None,
    };
    let (targets, data) = a.data.load(a.algorithm.field(), |n| {
        matches!(a.algorithm.components(n), Ok(Some(_)))
    })?;
    let components = a.algorithm.components(data.marker_inputs())?;
    let TrainingTable {
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
    let widest = sets.iter().map(InputSet::network_inputs).max().unwrap_or(0);
    let need = a
        .algorithm
        .check_memory((widest, x.len(), targets.len()), &cfg)?;
    crate::print::memory("this training needs", need);
    for c in data.constant_targets() {
        eprintln!("warning: target `{c}` has the same value in every frame: nothing to learn about it (its R is 0)");
    }
    let (best, selection) = choose(&data, &cfg, &sets)?;
    let set = &sets[best];
    eprintln!(
        "training {}, {}) on {} frames",
        set.network_in_words(&cfg.hidden, targets.len()),
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
    let json = model.to_checked_json(&a.output.display().to_string())?;
    crate::write_atomically(&a.output, &json)?;
    print_trained(&model, &targets, t0.elapsed().as_secs_f64());
    eprintln!("wrote {}", a.output.display());
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

/// Chooses the input set by cross-validation when there is a choice, saying so.
fn choose(
    data: &FitData<'_>,
    cfg: &FitConfig,
    sets: &[InputSet],
) -> anyhow::Result<(usize, Vec<InputScore>)> {
    if sets.len() > 1 {
        eprintln!(
            "choosing the inputs by {SELECTION_FOLDS}-fold cross-validation (one network per fold): {}",
            sets.iter()
                .map(|s| s.name.as_str())
                .collect::<Vec<_>>()
                .join(" or ")
        );
    }
    let (best, selection) = choose_inputs(data, cfg, sets, SELECTION_FOLDS).map_err(fit_error)?;
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

    Ok((best, selection))
}

/// How training went: epochs, why it stopped, and each target's figures per subset.
fn print_trained(model: &Model, targets: &[String], secs: f64) {
    let tr = &model.training;
    eprintln!(
        "trained ({}) in {:.2} s: {} epochs (best {}), stopped by {}",
        tr.algorithm, secs, tr.epochs, tr.best_epoch, tr.stop
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
