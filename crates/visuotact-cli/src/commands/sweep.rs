//! `visuotact sweep`: networks of many hidden sizes, several times each, on every core
//! ([`visuotact_nn::sweep`]) → sweep.csv, the best model, and the plot of mean performance
//! against size (seed 001 Figs. 4.8/4.11/4.13).
//!
//! On a cluster: `--shard K/N` trains one slice and writes `part-K-of-N.json`; `sweep merge
//! PARTS… -o DIR` writes what one machine would have (the same trainings with the same seeds);
//! `--slurm N` writes `sweep.sbatch` (an N-task array of shards), `merge.sbatch` and
//! `submit.sh`, which submits both, the merge after the array.

use std::path::PathBuf;

use anyhow::{bail, Context};
use visuotact_nn::fit::{FitConfig, FitData};
use visuotact_nn::sweep::{
    architectures, merge_parts, mse, scaled_mse, sweep_of, sweep_shard, Shard, Sweep, SweepPart,
    PART_FORMAT,
};
use visuotact_pipeline::table::TrainingTable;
use visuotact_report::figures::{PerformancePlot, SweepSurface};

use crate::args::{AlgorithmArg, DataArgs};
use crate::progress::Reporter;

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
    /// Output folder: sweep.csv, best_model.json, performance.svg and .png (and for two-layer
    /// sweeps surface.svg and .png, the mean test MSE over both sizes as a heat map).
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
    /// No progress lines (by default one every 2 s on stderr, also when it is not a terminal).
    #[arg(long, short)]
    quiet: bool,
    /// Train only this slice of the trainings (K of N, round robin) and write
    /// part-K-of-N.json into the output folder, for `sweep merge`.
    #[arg(long, value_name = "K/N", value_parser = Shard::parse)]
    shard: Option<Shard>,
    /// Write SLURM scripts for an N-task array of shards and their merge instead of training.
    #[arg(long, value_name = "N", conflicts_with = "shard")]
    slurm: Option<usize>,
    /// With --slurm: CPUs per array task.
    #[arg(long, default_value_t = 2)]
    slurm_cpus: usize,
}

/// `sweep merge` (the command line routes `sweep merge …` here, see
/// [`crate::route_sweep_merge`]).
#[derive(clap::Args, Debug)]
pub(crate) struct MergeArgs {
    /// Every part-K-of-N.json of the sweep.
    #[arg(required = true)]
    parts: Vec<PathBuf>,
    /// Output folder.
    #[arg(short, long)]
    output: PathBuf,
    /// Also keep the N best networks as ensemble/model_K.json.
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
    let mut most = 0;
    for hidden in archs {
        let cfg = FitConfig {
            hidden: hidden.clone(),
            ensemble: rayon::current_num_threads(),
            ..base.clone()
        };
        most = most.max(a.algorithm.check_memory(sizes, &cfg)?);
    }
    let at_once = rayon::current_num_threads();
    let what = format!("the largest architecture's trainings, {at_once} at once, need");
    crate::print::memory(&what, most);
    Ok(())
}

/// What must agree between the parts of one sweep.
fn sweep_id(a: &Args) -> String {
    format!(
        "hidden {} repeats {} seed {} max_epochs {} algorithm {:?} data {:?}",
        a.hidden, a.repeats, a.seed, a.max_epochs, a.algorithm, a.data
    )
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let output = a.output.as_path();
    let archs = architectures(&a.hidden).map_err(|e| anyhow::anyhow!("--hidden: {e}"))?;
    if a.repeats == 0 {
        bail!("--repeats must be at least 1");
    }
    if let Some(n) = a.slurm {
        return crate::slurm::write_scripts(output, n, a.slurm_cpus, a.keep);
    }
    let (targets, data) = a.data.load(a.algorithm.field(), |n| {
        matches!(a.algorithm.components(n), Ok(Some(_)))
    })?;
    std::fs::create_dir_all(output)
        .with_context(|| format!("{}: cannot create folder", output.display()))?;
    let components = a.algorithm.components(data.marker_inputs())?;
    let TrainingTable {
        x,
        t,
        feature_columns,
        passthrough,
        ..
    } = data;
    let shard = a.shard.unwrap_or(Shard::ALL);
    let n_jobs = (0..archs.len() * a.repeats)
        .filter(|&j| shard.takes(j))
        .count();
    let reporter = Reporter::new(a.quiet);
    note!("sweep: {n_jobs} trainings");
    reporter.stage("sweep");
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
    let trained = sweep_shard(&data, &archs, a.repeats, &base, shard, |p: &_| {
        reporter.training(p)
    })
    .map_err(crate::fit_error)?;
    if reporter.interrupted() {
        bail!("interrupted (Ctrl-C): nothing written");
    }
    if a.shard.is_some() {
        return write_part(a, (output, shard), &targets, trained, t0);
    }
    let s = sweep_of(&archs, trained);
    write_outputs(output, a.keep, &s, &targets)?;
    note!(
        "{} trainings of {} architectures in {:.1} s",
        s.models.len(),
        archs.len(),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

fn write_part(
    a: &Args,
    (output, shard): (&std::path::Path, Shard),
    targets: &[String],
    trained: Vec<visuotact_nn::sweep::Trained>,
    t0: std::time::Instant,
) -> anyhow::Result<()> {
    let n = trained.len();
    let part = SweepPart {
        format: PART_FORMAT.into(),
        sweep: sweep_id(a),
        hidden: a.hidden.clone(),
        targets: targets.to_vec(),
        shard,
        trained,
    };
    let path = output.join(format!("part-{}-of-{}.json", shard.index, shard.count));
    crate::write_atomically(&path, &serde_json::to_string(&part)?)?;
    note!(
        "shard {}/{}: {n} trainings in {:.1} s; wrote {}",
        shard.index,
        shard.count,
        t0.elapsed().as_secs_f64(),
        path.display()
    );
    Ok(())
}

/// `sweep merge PARTS… -o DIR`.
pub(crate) fn merge(m: &MergeArgs) -> anyhow::Result<()> {
    let mut parts = Vec::new();
    for p in &m.parts {
        let text = visuotact_io::read::text_of_file(p)
            .with_context(|| format!("{}: cannot read", p.display()))?;
        let part: SweepPart = serde_json::from_str(&text)
            .with_context(|| format!("{}: not a sweep part", p.display()))?;
        parts.push((p.display().to_string(), part));
    }
    let (hidden, targets) = (parts[0].1.hidden.clone(), parts[0].1.targets.clone());
    let archs = architectures(&hidden).map_err(|e| anyhow::anyhow!("{e}"))?;
    let trained = merge_parts(parts)?;
    std::fs::create_dir_all(&m.output)
        .with_context(|| format!("{}: cannot create folder", m.output.display()))?;
    let s = sweep_of(&archs, trained);
    write_outputs(&m.output, m.keep, &s, &targets)?;
    note!(
        "merged {} parts: {} trainings",
        m.parts.len(),
        s.models.len()
    );
    Ok(())
}

/// sweep.csv, best_model.json, the kept ensemble and the performance plot.
fn write_outputs(
    output: &std::path::Path,
    keep: usize,
    s: &Sweep,
    targets: &[String],
) -> anyhow::Result<()> {
    crate::write_atomically(&output.join("sweep.csv"), &s.to_csv())?;
    let ranked = s.ranked();
    let best = *ranked.first().context("no training ran")?;
    let best_file = output.join("best_model.json");
    let json = best.to_checked_json(&best_file.display().to_string())?;
    crate::write_atomically(&best_file, &json)?;
    if keep > 0 {
        for (k, m) in ranked.iter().take(keep).enumerate() {
            let p = output
                .join("ensemble")
                .join(format!("model_{}.json", k + 1));
            crate::write_atomically(&p, &m.to_checked_json(&p.display().to_string())?)?;
        }
        note!(
            "kept the {} best networks in {}/ensemble/",
            keep.min(ranked.len()),
            output.display()
        );
    }
    let points = s.points();
    let plot = PerformancePlot {
        points: &points,
        targets,
    };
    visuotact_report::save_both(&plot, &output.join("performance")).context("performance plot")?;
    let two_layers = !s.rows.is_empty() && s.rows.iter().all(|r| r.hidden.len() == 2);
    if two_layers {
        let cells: Vec<(usize, usize, f64)> = s
            .rows
            .iter()
            .map(|r| (r.hidden[0], r.hidden[1], r.test_mse.0))
            .collect();
        let surface = SweepSurface {
            cells: &cells,
            targets,
        };
        visuotact_report::save_both(&surface, &output.join("surface")).context("surface plot")?;
    }
    note!(
        "best (by scaled validation MSE {:.4e}): hidden {:?}, validation MSE {:.4e}, test MSE {:.4e} (target units)",
        scaled_mse(best, 1),
        &best.net.sizes[1..best.net.sizes.len() - 1],
        mse(best, 1),
        mse(best, 2)
    );
    note!(
        "wrote {}/sweep.csv, best_model.json, performance.svg, performance.png{}",
        output.display(),
        if two_layers {
            ", surface.svg, surface.png"
        } else {
            ""
        }
    );
    Ok(())
}
