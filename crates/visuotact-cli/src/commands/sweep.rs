//! `visuotact sweep`: networks of many hidden sizes, several times each, on every core
//! ([`visuotact_nn::sweep`]) → sweep.csv, the best model, and the plot of mean performance
//! against size (seed 001 Figs. 4.8/4.11/4.13).

use std::path::PathBuf;

use anyhow::{bail, Context};
use indicatif::{ProgressBar, ProgressStyle};
use visuotact_nn::fit::{FitConfig, FitData};
use visuotact_nn::sweep::{architectures, mse, scaled_mse, sweep};
use visuotact_pipeline::table::TrainingTable;
use visuotact_report::figures::PerformancePlot;

use crate::args::{AlgorithmArg, DataArgs};

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

/// Every architecture's trainings, as many at once as there are cores, must fit in memory.
fn check_memory(
    a: &Args,
    archs: &[Vec<usize>],
    base: &FitConfig,
    sizes: (usize, usize, usize),
) -> anyhow::Result<()> {
    for hidden in archs {
        let cfg = FitConfig {
            hidden: hidden.clone(),
            ensemble: rayon::current_num_threads(),
            ..base.clone()
        };
        a.algorithm.check_memory(sizes, &cfg)?;
    }
    Ok(())
}

fn progress_bar(len: u64) -> ProgressBar {
    let bar = ProgressBar::new(len);
    bar.set_style(
        ProgressStyle::with_template(
            "{bar:40} {pos}/{len} trainings, {elapsed} elapsed, ~{eta} left",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let archs = architectures(&a.hidden).map_err(|e| anyhow::anyhow!("--hidden: {e}"))?;
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
    let bar = progress_bar((archs.len() * a.repeats) as u64);
    let t0 = std::time::Instant::now();
    let base = FitConfig {
        seed: a.seed,
        max_epochs: a.max_epochs,
        algorithm: a.algorithm.algorithm(),
        components,
        passthrough,
        ..FitConfig::default()
    };
    let data = FitData {
        x: &x,
        t: &t,
        feature_columns: &feature_columns,
        targets: &targets,
    };
    let inputs = components.map_or(feature_columns.len(), |k| k + passthrough);
    check_memory(a, &archs, &base, (inputs, x.len(), targets.len()))?;
    let s = sweep(&data, &archs, a.repeats, &base, || bar.inc(1)).map_err(crate::fit_error)?;
    bar.finish_and_clear();
    crate::write_atomically(&a.output.join("sweep.csv"), &s.to_csv())?;
    let ranked = s.ranked();
    let best = *ranked.first().context("no training ran")?;
    let best_file = a.output.join("best_model.json");
    let json = best.to_checked_json(&best_file.display().to_string())?;
    crate::write_atomically(&best_file, &json)?;
    if a.keep > 0 {
        for (k, m) in ranked.iter().take(a.keep).enumerate() {
            let p = a
                .output
                .join("ensemble")
                .join(format!("model_{}.json", k + 1));
            crate::write_atomically(&p, &m.to_checked_json(&p.display().to_string())?)?;
        }
        eprintln!(
            "kept the {} best networks in {}/ensemble/",
            a.keep.min(ranked.len()),
            a.output.display()
        );
    }
    let points = s.points();
    let plot = PerformancePlot {
        points: &points,
        targets: &targets,
    };
    visuotact_report::save_both(&plot, &a.output.join("performance"))
        .context("performance plot")?;
    eprintln!(
        "{} trainings of {} architectures in {:.1} s; best (by scaled validation MSE {:.4e}): hidden {:?}, validation MSE {:.4e}, test MSE {:.4e} (target units)",
        s.models.len(),
        archs.len(),
        t0.elapsed().as_secs_f64(),
        scaled_mse(best, 1),
        &best.net.sizes[1..best.net.sizes.len() - 1],
        mse(best, 1),
        mse(best, 2)
    );
    eprintln!(
        "wrote {}/sweep.csv, best_model.json, performance.svg, performance.png",
        a.output.display()
    );
    Ok(())
}
