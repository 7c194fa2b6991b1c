//! `visuotact demo`: both source documents' experiments end to end on the simulator —
//! simulate, calibrate, extract, train (Levenberg–Marquardt), evaluate — printed beside the
//! papers' numbers. Frames stay in memory; nothing is written.

use std::time::Instant;

use anyhow::Context;
use rayon::prelude::*;
use visuotact_image::RgbImage;
use visuotact_nn::lm::Control;
use visuotact_nn::metrics::{target_errors, TargetErrors};
use visuotact_nn::model::Model;
use visuotact_sim::cone::{ConeConfig, ConeLoad};
use visuotact_sim::iats::{IatsConfig, Touch};
use visuotact_sim::protocol::{self, ConePress, PressureGauge};
use visuotact_vision::calibration::{calibrate, CalibrationConfig, SensorCalibration};
use visuotact_vision::detect::{Centroid, DetectorConfig};
use visuotact_vision::features::{FeatureExtractor, FeatureSet, FIELD_COLUMNS};
use visuotact_vision::layout::{Layout, LayoutChoice};
use visuotact_vision::preprocess::PreprocessConfig;

use crate::simulate::{frame_seed, GAUGE_SEED};
use crate::train::{fit_model, FitSpec};

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// A smaller run (under a minute): half the grid in each axis, shorter presses.
    #[arg(long)]
    quick: bool,
    /// Seed of the simulation, the splits and the weights.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

/// Seed 000 Table 3: actual (x, y, depth) and the paper's estimates.
const TABLE3: [([f64; 3], [f64; 3]); 6] = [
    ([56.0, 21.0, 4.0], [54.5, 21.1, 3.8]),
    ([16.0, 33.0, 4.0], [15.1, 33.7, 3.86]),
    ([12.0, 9.0, 1.0], [10.7, 8.98, 1.1]),
    ([56.0, 39.0, 2.0], [54.99, 40.43, 2.13]),
    ([40.0, 3.0, 5.0], [38.96, 2.7, 5.1]),
    ([32.0, 24.0, 3.0], [32.8, 22.4, 3.08]),
];

/// Features of frames rendered by `render(k)`, in parallel; `None` where markers were lost.
fn features_of(
    cal: &SensorCalibration,
    set: FeatureSet,
    n: usize,
    render: impl Fn(usize) -> anyhow::Result<RgbImage> + Sync,
) -> anyhow::Result<Vec<Option<Vec<f64>>>> {
    let ex = FeatureExtractor::new(cal.clone(), set).map_err(anyhow::Error::msg)?;
    (0..n)
        .into_par_iter()
        .map_with(ex, |ex, k| {
            let img = render(k)?;
            let mut f = ex.extract(&img)?;
            // The papers' inputs: the markers' features, without the field summary.
            f.values.truncate(f.values.len() - FIELD_COLUMNS.len());
            Ok(f.values.iter().all(|v| v.is_finite()).then_some(f.values))
        })
        .collect()
}

/// Trains on rows with features (the same path as `visuotact train`); returns the model
/// (which predicts in target units), its epochs and the training time in seconds.
fn fit(
    x: &[Vec<f64>],
    t: &[Vec<f64>],
    targets: &[&str],
    hidden: &[usize],
    seed: u64,
) -> anyhow::Result<(Model, usize, f64)> {
    let feature_columns: Vec<String> = (0..x[0].len()).map(|i| format!("f{i}")).collect();
    let targets: Vec<String> = targets.iter().map(|s| s.to_string()).collect();
    let spec = FitSpec {
        feature_columns: &feature_columns,
        targets: &targets,
        hidden,
        seed,
        max_epochs: 1000,
        algorithm: visuotact_nn::mlp::Algorithm::Trainlm,
        hold_out: false,
        components: None,
        passthrough: 0,
        ensemble: 1,
        sensor: None,
    };
    let t0 = Instant::now();
    let model = fit_model(x, t, spec, |_, _, _| Control::Continue)?;
    let epochs = model.training.epochs;
    Ok((model, epochs, t0.elapsed().as_secs_f64()))
}

fn row(e: &TargetErrors) -> String {
    format!(
        "mean {:.3}, max {:.3}, R {:.5}, accuracy {:.1} %",
        e.mean_abs, e.max_abs, e.r, e.accuracy_percent
    )
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let t_all = Instant::now();
    iats(a)?;
    cone(a)?;
    println!("\ndemo finished in {:.0} s", t_all.elapsed().as_secs_f64());
    Ok(())
}

fn iats(a: &Args) -> anyhow::Result<()> {
    let cfg = IatsConfig::SEED000;
    println!("== Seed 000: image-based areal touch sensor (117 markers, 60 × 45 mm) ==");
    let t0 = Instant::now();
    let rest: Vec<RgbImage> = (0..5)
        .map(|k| {
            visuotact_sim::iats::render(&cfg, &Touch::default(), frame_seed(a.seed, k)).map(|r| r.0)
        })
        .collect::<Result<_, _>>()
        .map_err(anyhow::Error::msg)?;
    let ids: Vec<String> = (0..rest.len()).map(|k| format!("ref{k}")).collect();
    // As `calibrate` does by default: grey-level centroids.
    let det = DetectorConfig {
        preprocess: PreprocessConfig::IATS,
        centroid: Centroid::Grey,
        ..Default::default()
    };
    let (cal, _) = calibrate(
        ids.iter().map(String::as_str).zip(rest.iter()),
        &CalibrationConfig {
            detector: det,
            layout: LayoutChoice::Auto,
            features: FeatureSet::IATS,
            ..Default::default()
        },
    )?;
    let mut grid = protocol::iats_grid();
    if a.quick {
        grid.retain(|t| (t.x_mm / 4.0) as usize % 2 == 0 && (t.y_mm / 3.0) as usize % 2 == 0);
    }
    let render = |t: &Touch, k: u64| {
        visuotact_sim::iats::render(&cfg, t, frame_seed(a.seed, k))
            .map(|r| r.0)
            .map_err(anyhow::Error::msg)
    };
    let train_f = features_of(&cal, FeatureSet::IATS, grid.len(), |k| {
        render(&grid[k], 100 + k as u64)
    })?;
    let (mut x, mut t) = (Vec::new(), Vec::new());
    for (f, touch) in train_f.iter().zip(&grid) {
        if let Some(f) = f {
            x.push(f.clone());
            t.push(vec![touch.x_mm, touch.y_mm, touch.depth_mm]);
        }
    }
    println!(
        "calibrated {} markers; grid protocol: {} touches, {} with every marker found ({:.1} s)",
        cal.markers.len(),
        grid.len(),
        x.len(),
        t0.elapsed().as_secs_f64()
    );
    // Seed 000's architecture: five hidden layers of 20.
    let hidden = [20; 5];
    let (model, epochs, secs) = fit(&x, &t, &["x_mm", "y_mm", "depth_mm"], &hidden, a.seed)?;
    let predict = |f: &[f64]| model.predict(f);
    println!("trained 351 → 20 → 20 → 20 → 20 → 20 → 3 by Levenberg–Marquardt: {epochs} epochs in {secs:.1} s (seed 000: 13 h 20 min)");

    // Table 3: six touches anywhere.
    let t3: Vec<Touch> = TABLE3
        .iter()
        .map(|(p, _)| Touch {
            x_mm: p[0],
            y_mm: p[1],
            depth_mm: p[2],
            ..Touch::default()
        })
        .collect();
    let f3 = features_of(&cal, FeatureSet::IATS, t3.len(), |k| {
        render(&t3[k], 50_000 + k as u64)
    })?;
    println!(
        "\nTable 3 layout: actual | visuotact estimate | error || paper's estimate | paper's error"
    );
    for (k, ((actual, paper), f)) in TABLE3.iter().zip(&f3).enumerate() {
        let Some(f) = f else {
            println!("{}  markers lost", k + 1);
            continue;
        };
        let e = predict(f);
        let d = (e[0] - actual[0]).hypot(e[1] - actual[1]);
        let pd = (paper[0] - actual[0]).hypot(paper[1] - actual[1]);
        println!(
            "{}  X {:>4} Y {:>4} Depth {} | X {:6.2} Y {:6.2} Depth {:5.2} | D {:4.2} mm, depth {:4.2} mm || X {:5.2} Y {:5.2} Depth {:4.2} | D {:4.2} mm, depth {:4.2} mm",
            k + 1,
            actual[0],
            actual[1],
            actual[2],
            e[0],
            e[1],
            e[2],
            d,
            (e[2] - actual[2]).abs(),
            paper[0],
            paper[1],
            paper[2],
            pd,
            (paper[2] - actual[2]).abs()
        );
    }
    // Random touches: the accuracy figures of the paper's conclusions.
    let n_test = if a.quick { 100 } else { 300 };
    let test = protocol::iats_random(&cfg, n_test, a.seed ^ 0x7E57);
    let ft = features_of(&cal, FeatureSet::IATS, test.len(), |k| {
        render(&test[k], 60_000 + k as u64)
    })?;
    let mut est: [Vec<f64>; 3] = Default::default();
    let mut tru: [Vec<f64>; 3] = Default::default();
    let mut dist = Vec::new();
    for (f, touch) in ft.iter().zip(&test) {
        let Some(f) = f else { continue };
        let e = predict(f);
        let truth = [touch.x_mm, touch.y_mm, touch.depth_mm];
        for j in 0..3 {
            est[j].push(e[j]);
            tru[j].push(truth[j]);
        }
        dist.push((e[0] - truth[0]).hypot(e[1] - truth[1]));
    }
    let names = ["x_mm", "y_mm", "depth_mm"];
    let errs: Vec<TargetErrors> = (0..3)
        .map(|j| target_errors(names[j], &est[j], &tru[j]))
        .collect();
    println!("\n{} random touches (not in training):", dist.len());
    println!(
        "  X:     {}   | paper: mean 1.84 mm, accuracy 86.7 %",
        row(&errs[0])
    );
    println!(
        "  Y:     {}   | paper: mean 0.9 mm, accuracy 96.5 %",
        row(&errs[1])
    );
    println!(
        "  depth: {}   | paper: mean 0.2 mm, accuracy 94.9 %",
        row(&errs[2])
    );
    let dmean = dist.iter().sum::<f64>() / dist.len().max(1) as f64;
    let dmax = dist.iter().fold(0.0f64, |m, v| m.max(*v));
    println!("  D:     mean {dmean:.3} mm, max {dmax:.3} mm   | paper: up to 3.24 mm (Table 2)");
    Ok(())
}

fn cone(a: &Args) -> anyhow::Result<()> {
    let cfg = ConeConfig::SEED001;
    println!("\n== Seed 001: inflatable link (cone, three annuli, JR3 force) ==");
    let fps = 25.0;
    let duration = if a.quick { 10.0 } else { 20.0 };
    let press = ConePress {
        duration_s: duration,
        ..ConePress::SEED001
    };
    let render = |load: &ConeLoad, k: u64| {
        visuotact_sim::cone::render(&cfg, load, frame_seed(a.seed, k))
            .map(|r| r.0)
            .map_err(anyhow::Error::msg)
    };
    let rest: Vec<RgbImage> = (0..5)
        .map(|k| render(&ConeLoad::none(cfg.pressure_kpa), 200_000 + k))
        .collect::<anyhow::Result<_>>()?;
    let ids: Vec<String> = (0..rest.len()).map(|k| format!("ref{k}")).collect();
    let det = DetectorConfig {
        preprocess: PreprocessConfig::CONE,
        centroid: Centroid::Weighted,
        ..Default::default()
    };
    let (cal, _) = calibrate(
        ids.iter().map(String::as_str).zip(rest.iter()),
        &CalibrationConfig {
            detector: det,
            layout: LayoutChoice::Only(Layout::Rings),
            features: FeatureSet::CONE,
            ..Default::default()
        },
    )
    .context("cone calibration")?;
    // Two presses: one to train on, one (another direction) to test.
    let n = (duration * fps) as usize;
    let loads = |azimuth: f64, t0: f64| -> Vec<ConeLoad> {
        let p = ConePress {
            azimuth_rad: azimuth,
            ..press
        };
        (0..n)
            .map(|k| p.load_at(&cfg, k as f64 / fps, t0))
            .collect()
    };
    let train_loads = loads(0.0, 0.0);
    let test_loads = loads(0.0, duration + 5.0);
    let ftr = features_of(&cal, FeatureSet::CONE, n, |k| {
        render(&train_loads[k], 210_000 + k as u64)
    })?;
    let fte = features_of(&cal, FeatureSet::CONE, n, |k| {
        render(&test_loads[k], 220_000 + k as u64)
    })?;
    // The link's pressure gauge, read with every frame: an input the paper did not use.
    let gauge = |loads: &[ConeLoad], t0: f64, base: u64| -> Vec<f64> {
        (0..loads.len())
            .map(|k| {
                PressureGauge::SEED001.reading_kpa(
                    &press.drift,
                    cfg.pressure_kpa,
                    t0 + k as f64 / fps,
                    frame_seed(a.seed ^ GAUGE_SEED, base + k as u64),
                )
            })
            .collect()
    };
    let with_gauge = |feats: &[Option<Vec<f64>>], g: &[f64]| -> Vec<Option<Vec<f64>>> {
        feats
            .iter()
            .zip(g)
            .map(|(f, &p)| {
                f.as_ref().map(|f| {
                    let mut v = f.clone();
                    v.push(p);
                    v
                })
            })
            .collect()
    };
    let gtr = with_gauge(&ftr, &gauge(&train_loads, 0.0, 210_000));
    let gte = with_gauge(&fte, &gauge(&test_loads, duration + 5.0, 220_000));
    let rows = |feats: &[Option<Vec<f64>>]| -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
        feats
            .iter()
            .zip(&train_loads)
            .filter_map(|(f, l)| f.as_ref().map(|f| (f.clone(), vec![l.force_n])))
            .unzip()
    };
    let (x, t) = rows(&ftr);
    let (xg, tg) = rows(&gtr);
    let (model, epochs, secs) = fit(&x, &t, &["force_n"], &[20], a.seed)?;
    println!(
        "calibrated {} rings (the outermost is cut by the image border); trained 6 → 20 → 1 on {} frames: {epochs} epochs in {secs:.2} s",
        cal.markers.len(),
        x.len()
    );
    let errors_on = |model: &Model, feats: &[Option<Vec<f64>>], loads: &[ConeLoad]| {
        let (mut est, mut tru) = (Vec::new(), Vec::new());
        for (f, l) in feats.iter().zip(loads) {
            if let Some(f) = f {
                est.push(model.predict(f)[0]);
                tru.push(l.force_n);
            }
        }
        target_errors("force_n", &est, &tru)
    };
    let unseen = errors_on(&model, &fte, &test_loads);
    // Seed 001's own protocol: 1..40 neurons × repeats, the best net kept (lowest test MSE),
    // then run by the Neural Network Testing Model over the recorded press.
    let repeats: u64 = if a.quick { 2 } else { 5 };
    let best_of_sweep = |x: &[Vec<f64>], t: &[Vec<f64>]| -> anyhow::Result<(Model, usize, f64)> {
        let t_sweep = Instant::now();
        let runs: Vec<(Model, usize)> = (1..=40usize)
            .flat_map(|h| (0..repeats).map(move |r| (h, r)))
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|(h, r)| fit(x, t, &["force_n"], &[h], a.seed + 7919 * r).map(|f| (f.0, h)))
            .collect::<anyhow::Result<_>>()?;
        let (best, h) = runs
            .into_iter()
            .min_by(|p, q| p.0.training.mse[2][0].total_cmp(&q.0.training.mse[2][0]))
            .context("no training ran")?;
        Ok((best, h, t_sweep.elapsed().as_secs_f64()))
    };
    let (best, best_h, sweep_s) = best_of_sweep(&x, &t)?;
    let (best_g, best_gh, sweep_gs) = best_of_sweep(&xg, &tg)?;
    for (inputs, n_in, (m, h, secs)) in [
        ("rings", 6, (&best, best_h, sweep_s)),
        ("rings + gauge", 7, (&best_g, best_gh, sweep_gs)),
    ] {
        println!(
            "sweep 1..40 neurons × {repeats}, inputs {inputs}, in {secs:.1} s: best {n_in} → {h} → 1 (test MSE {:.4})",
            m.training.mse[2][0]
        );
    }
    println!(
        "\nTable 5.1 layout: visuotact | paper (no rotation)\n  {:<48} {:<14} {:>8} {:>8} {:>8} {:>7}",
        "", "inputs", "mean N", "max N", "MPE %", "R"
    );
    let line = |what: &str, inputs: &str, e: &TargetErrors| {
        println!(
            "  {what:<48} {inputs:<14} {:>8.3} {:>8.3} {:>8.2} {:>7.5}",
            e.mean_abs, e.max_abs, e.mean_percentage_error, e.r
        );
    };
    let own = "best of sweep, over its own press (paper's way)";
    let later = "best of sweep, on a later press (unseen)";
    line(own, "rings", &errors_on(&best, &ftr, &train_loads));
    line(later, "rings", &errors_on(&best, &fte, &test_loads));
    line(
        "6 → 20 → 1, one training, on the later press",
        "rings",
        &unseen,
    );
    line(
        own,
        "rings + gauge",
        &errors_on(&best_g, &gtr, &train_loads),
    );
    line(
        later,
        "rings + gauge",
        &errors_on(&best_g, &gte, &test_loads),
    );
    println!(
        "  {:<48} {:<14} {:>8.3} {:>8.3} {:>8.2}",
        "paper (best of sweep, Testing Model)", "rings", 0.051, 0.531, 1.25
    );
    println!(
        "  (MPE over frames ≥ {:.2} N; the later press starts 5 s after the first ends, with the link's pressure {:.1} % lower;",
        unseen.mpe_floor,
        100.0 * (1.0 - test_loads[0].pressure_kpa / train_loads[0].pressure_kpa)
    );
    println!(
        "   gauge: the link's pressure through a {} s lag with {} kPa noise, read with each frame)",
        PressureGauge::SEED001.time_constant_s,
        PressureGauge::SEED001.noise_kpa
    );
    Ok(())
}
