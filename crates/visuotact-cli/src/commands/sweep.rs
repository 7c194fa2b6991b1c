//! `visuotact sweep`: train networks of many hidden sizes, several times each with different
//! seeds, on every core; mean and best performance per size, the best model, and the plot of
//! mean performance against size (seed 001 Figs. 4.8/4.11/4.13).

use std::path::PathBuf;

use anyhow::{bail, Context};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use visuotact_nn::lm::Control;
use visuotact_nn::model::Model;
use visuotact_report::figures::PerformancePlot;

use crate::args::{AlgorithmArg, DataArgs};
use visuotact_nn::fit::{fit, FitConfig, FitData};
use visuotact_pipeline::table::TrainingTable;

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    #[command(flatten)]
    data: DataArgs,
    /// Hidden sizes: `1..40` (one layer), `1..20x1..20` (two layers), or a list `5,10,20`.
    #[arg(long, default_value = "1..20")]
    hidden: String,
    /// Trainings per size (different seeds).
    #[arg(long, default_value_t = 10)]
    repeats: usize,
    /// Output folder: sweep.csv, best_model.json, performance.svg and .png.
    #[arg(short, long)]
    output: PathBuf,
    /// Base seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Most epochs per training.
    #[arg(long, default_value_t = 1000)]
    max_epochs: usize,
    #[command(flatten)]
    algorithm: AlgorithmArg,
    /// Also keep the N best networks (by validation MSE) as ensemble/model_K.json, for
    /// `run --model …` several times (mean ± standard deviation).
    #[arg(long, value_name = "N", default_value_t = 0)]
    keep: usize,
}

fn range(s: &str) -> anyhow::Result<Vec<usize>> {
    let (a, b) = s
        .split_once("..")
        .with_context(|| format!("--hidden: {s:?} is not a range like 1..40"))?;
    let (a, b): (usize, usize) = (a.trim().parse()?, b.trim().parse()?);
    if a == 0 || b < a {
        bail!("--hidden: range {s:?} must be 1 ≤ start ≤ end");
    }
    Ok((a..=b).collect())
}

/// The architectures a `--hidden` spec names.
pub(crate) fn architectures(spec: &str) -> anyhow::Result<Vec<Vec<usize>>> {
    if let Some((l, r)) = spec.split_once('x') {
        let (a, b) = (range(l)?, range(r)?);
        return Ok(a
            .iter()
            .flat_map(|&i| b.iter().map(move |&j| vec![i, j]))
            .collect());
    }
    if spec.contains("..") {
        return Ok(range(spec)?.into_iter().map(|n| vec![n]).collect());
    }
    let v: Result<Vec<usize>, _> = spec.split(',').map(|p| p.trim().parse::<usize>()).collect();
    match v {
        Ok(v) if !v.is_empty() && !v.contains(&0) => Ok(v.into_iter().map(|n| vec![n]).collect()),
        _ => bail!("--hidden: {spec:?} is not a range (1..40, 1..20x1..20) or a list of sizes"),
    }
}

fn mean_of(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

/// Mean over targets of a subset's MSE in mapminmax space (each target's MSE over its half
/// range squared): every target counts alike whatever its unit.
fn scaled_mse(m: &Model, subset: usize) -> f64 {
    let ts = &m.target_scaling;
    let v: Vec<f64> = m.training.mse[subset]
        .iter()
        .enumerate()
        .map(|(j, e)| {
            let half = 0.5 * (ts.max[j] - ts.min[j]);
            if half > 0.0 {
                e / (half * half)
            } else {
                *e
            }
        })
        .collect();
    mean_of(&v)
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let archs = architectures(&a.hidden)?;
    if a.repeats == 0 {
        bail!("--repeats must be at least 1");
    }
    let (targets, data) = a.data.load(a.algorithm.field(), |n| {
        matches!(a.algorithm.components(n), Ok(Some(_)))
    })?;
    std::fs::create_dir_all(&a.output)
        .with_context(|| format!("{}: cannot create folder", a.output.display()))?;
    let components = a.algorithm.components(data.marker_inputs())?;
    let TrainingTable {
        x,
        t,
        feature_columns,
        passthrough,
        ..
    } = data;
    let jobs: Vec<(usize, usize)> = (0..archs.len())
        .flat_map(|k| (0..a.repeats).map(move |r| (k, r)))
        .collect();
    let bar = ProgressBar::new(jobs.len() as u64);
    bar.set_style(
        ProgressStyle::with_template(
            "{bar:40} {pos}/{len} trainings, {elapsed} elapsed, ~{eta} left",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let t0 = std::time::Instant::now();
    // Every (size, repeat) on the rayon pool: all cores.
    let results: Vec<(usize, Model)> = jobs
        .par_iter()
        .map(|&(k, r)| {
            let cfg = FitConfig {
                hidden: archs[k].clone(),
                seed: a.seed.wrapping_add(1000 * r as u64 + k as u64),
                max_epochs: a.max_epochs,
                algorithm: a.algorithm.algorithm(),
                hold_out: true,
                components,
                passthrough,
                ensemble: 1,
            };
            let data = FitData {
                x: &x,
                t: &t,
                feature_columns: &feature_columns,
                targets: &targets,
            };
            let m = fit(&data, &cfg, |_, _, _| Control::Continue).map_err(crate::fit_error);
            bar.inc(1);
            m.map(|m| (k, m))
        })
        .collect::<Result<_, _>>()?;
    bar.finish_and_clear();
    // Performance in units: the mean over targets of the MSE in each target's own units (a
    // target in degrees drowns one in millimetres) — reported. Selection: the same on scaled
    // targets (mapminmax space, each target's MSE over its half range squared), so every
    // target counts alike.
    let perf = |m: &Model, subset: usize| mean_of(&m.training.mse[subset]);
    let mut rows = String::from("hidden,repeats,mean_test_mse,best_test_mse,mean_validation_mse,best_validation_mse,mean_epochs,mean_test_mse_scaled,best_test_mse_scaled,mean_validation_mse_scaled,best_validation_mse_scaled\n");
    let mut points = Vec::new();
    for (k, arch) in archs.iter().enumerate() {
        let ms: Vec<&Model> = results
            .iter()
            .filter(|(kk, _)| *kk == k)
            .map(|(_, m)| m)
            .collect();
        let test: Vec<f64> = ms.iter().map(|m| perf(m, 2)).collect();
        let val: Vec<f64> = ms.iter().map(|m| perf(m, 1)).collect();
        let test_s: Vec<f64> = ms.iter().map(|m| scaled_mse(m, 2)).collect();
        let val_s: Vec<f64> = ms.iter().map(|m| scaled_mse(m, 1)).collect();
        let epochs: Vec<f64> = ms.iter().map(|m| m.training.epochs as f64).collect();
        let name = arch
            .iter()
            .map(usize::to_string)
            .collect::<Vec<_>>()
            .join("x");
        let best = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
        rows.push_str(&format!(
            "{name},{},{},{},{},{},{},{},{},{},{}\n",
            ms.len(),
            mean_of(&test),
            best(&test),
            mean_of(&val),
            best(&val),
            mean_of(&epochs),
            mean_of(&test_s),
            best(&test_s),
            mean_of(&val_s),
            best(&val_s)
        ));
        points.push((
            arch.iter().sum::<usize>() as f64,
            mean_of(&test),
            best(&test),
        ));
    }
    crate::write_atomically(&a.output.join("sweep.csv"), &rows)?;
    let (_, best_model) = results
        .iter()
        .min_by(|p, q| scaled_mse(&p.1, 1).total_cmp(&scaled_mse(&q.1, 1)))
        .context("no training ran")?;
    crate::write_atomically(&a.output.join("best_model.json"), &best_model.to_json())?;
    if a.keep > 0 {
        let mut ranked: Vec<&Model> = results.iter().map(|r| &r.1).collect();
        ranked.sort_by(|p, q| scaled_mse(p, 1).total_cmp(&scaled_mse(q, 1)));
        for (k, m) in ranked.iter().take(a.keep).enumerate() {
            let p = a
                .output
                .join("ensemble")
                .join(format!("model_{}.json", k + 1));
            crate::write_atomically(&p, &m.to_json())?;
        }
        eprintln!(
            "kept the {} best networks in {}/ensemble/",
            a.keep.min(ranked.len()),
            a.output.display()
        );
    }
    visuotact_report::save_both(
        &PerformancePlot {
            points: &points,
            targets: &targets,
        },
        &a.output.join("performance"),
    )
    .context("performance plot")?;
    eprintln!(
        "{} trainings of {} architectures in {:.1} s; best (by scaled validation MSE {:.4e}): hidden {:?}, validation MSE {:.4e}, test MSE {:.4e} (target units)",
        results.len(),
        archs.len(),
        t0.elapsed().as_secs_f64(),
        scaled_mse(best_model, 1),
        &best_model.net.sizes[1..best_model.net.sizes.len() - 1],
        perf(best_model, 1),
        perf(best_model, 2)
    );
    eprintln!(
        "wrote {}/sweep.csv, best_model.json, performance.svg, performance.png",
        a.output.display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::architectures;

    #[test]
    fn hidden_specs() {
        assert_eq!(
            architectures("1..3").unwrap(),
            vec![vec![1], vec![2], vec![3]]
        );
        assert_eq!(
            architectures("1..2x3..4").unwrap(),
            vec![vec![1, 3], vec![1, 4], vec![2, 3], vec![2, 4]]
        );
        assert_eq!(architectures("5,10").unwrap(), vec![vec![5], vec![10]]);
        assert!(
            architectures("0..3").is_err()
                && architectures("4..2").is_err()
                && architectures("a").is_err()
        );
    }
}

#[cfg(test)]
mod selection_tests {
    use super::*;
    use visuotact_nn::mlp::{MinMax, Mlp};
    use visuotact_nn::model::TrainingSummary;

    fn model(val_mse: [f64; 2]) -> Model {
        Model {
            format: visuotact_nn::model::MODEL_FORMAT.to_string(),
            version: visuotact_nn::model::MODEL_VERSION,
            net: Mlp::nguyen_widrow(&[1, 1, 2], 1),
            members: Vec::new(),
            input_scaling: MinMax {
                min: vec![0.0],
                max: vec![1.0],
            },
            projection: None,
            passthrough: 0,
            // Target 0 spans 0..1000 (say mN), target 1 spans 0..1 (say mm).
            target_scaling: MinMax {
                min: vec![0.0, 0.0],
                max: vec![1000.0, 1.0],
            },
            feature_columns: vec!["f".into()],
            target_columns: vec!["a".into(), "b".into()],
            training: TrainingSummary {
                epochs: 1,
                best_epoch: 1,
                stop: String::new(),
                samples: [1, 1, 1],
                mse: [vec![], val_mse.to_vec(), vec![]],
                r: [vec![], vec![], vec![]],
                seed: 1,
                algorithm: "trainlm".into(),
                evidence: None,
                selection: Vec::new(),
            },
            sensor: None,
        }
    }

    #[test]
    fn selection_weighs_every_target_alike_whatever_its_unit() {
        // A: 1 % of range off on the big target, 63 % on the small one; B: 10 % and 6 %.
        let (a, b) = (model([100.0, 0.1]), model([10_000.0, 0.001]));
        // In target units A looks 100× better: the big target's unit drowns the other.
        assert!(mean_of(&a.training.mse[1]) < mean_of(&b.training.mse[1]));
        // Scaled, B is better on the whole: (0.04 + 0.004) / 2 against (0.0004 + 0.4) / 2.
        assert!((scaled_mse(&b, 1) - 0.022).abs() < 1e-12);
        assert!((scaled_mse(&a, 1) - 0.2002).abs() < 1e-12);
    }
}
