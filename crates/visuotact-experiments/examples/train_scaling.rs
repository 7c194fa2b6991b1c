//! Seconds per epoch and peak memory of the 117-marker membrane paper's network (351 → 5 × 20 → 3, trainlm, the
//! 70/15/15 split) on `FRAMES` simulated IATS touches: each frame's features are the true
//! displacement and area change of its 117 markers from the simulator (`iats::markers`,
//! no rendering), its targets the touch's x, y and depth.
//!
//! `cargo run --release -p visuotact-experiments --example train_scaling -- FRAMES [EPOCHS]
//! [--whole-jacobian]` prints the memory estimate, each epoch's training MSE (17 digits, to
//! compare the two paths), the median seconds per epoch and the peak resident memory
//! (VmHWM). `--whole-jacobian` holds the whole Jacobian as before blocks.

use std::time::Instant;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use visuotact_nn::fit::{training_memory_bytes, FitConfig};
use visuotact_nn::lm::{Control, LmConfig};
use visuotact_nn::mlp::{train, LmTraining, MinMax, Mlp, TrainConfig, Trainer};
use visuotact_sim::iats::{markers, IatsConfig, Touch};

/// Features (dx, dy, d-area per marker) and targets (x, y, depth) of `n` seeded touches.
fn touches(n: usize) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let cfg = IatsConfig::SEED000;
    let reference: Vec<_> = markers(&cfg, &Touch::default())
        .into_iter()
        .map(|(_, m)| m)
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(2026);
    let mut x = Vec::with_capacity(n);
    let mut t = Vec::with_capacity(n);
    for _ in 0..n {
        let touch = Touch {
            x_mm: rng.random_range(0.0..cfg.span_x_mm),
            y_mm: rng.random_range(0.0..cfg.span_y_mm),
            depth_mm: rng.random_range(0.2..cfg.max_depth_mm),
            ..Touch::default()
        };
        let row: Vec<f64> = markers(&cfg, &touch)
            .iter()
            .zip(&reference)
            .flat_map(|((_, m), r)| [m.x_px - r.x_px, m.y_px - r.y_px, m.area_px - r.area_px])
            .collect();
        x.push(row);
        t.push(vec![touch.x_mm, touch.y_mm, touch.depth_mm]);
    }
    (x, t)
}

/// Peak resident memory of this process, MiB (Linux `VmHWM`).
fn peak_rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let whole_jacobian = args.iter().any(|a| a == "--whole-jacobian");
    let numbers: Vec<usize> = args.iter().filter_map(|a| a.parse().ok()).collect();
    let frames = numbers.first().copied().unwrap_or(1000);
    let epochs = numbers.get(1).copied().unwrap_or(3);
    let (x, t) = touches(frames);
    let (sx, st) = (MinMax::fit(&x), MinMax::fit(&t));
    let x: Vec<Vec<f64>> = x.iter().map(|r| sx.apply(r)).collect();
    let t: Vec<Vec<f64>> = t.iter().map(|r| st.apply(r)).collect();
    let hidden = vec![20; 5];
    let sizes: Vec<usize> = [351].into_iter().chain(hidden.clone()).chain([3]).collect();
    let cfg = TrainConfig {
        trainer: Trainer::Lm(LmTraining {
            lm: LmConfig {
                max_iterations: epochs,
                ..LmConfig::TRAINLM
            },
            max_fail: usize::MAX,
            whole_jacobian,
        }),
        ..TrainConfig::TRAINLM
    };
    let train_samples = (frames as f64 * 0.7).round() as usize;
    let fit_cfg = FitConfig {
        hidden,
        ensemble: 1,
        ..FitConfig::default()
    };
    let estimate = training_memory_bytes(351, train_samples, 3, &fit_cfg);
    println!(
        "{frames} frames ({train_samples} training: {} residuals, {} weights), {} path; estimated training memory {:.0} MiB; RSS before training {:.0} MiB",
        train_samples * 3,
        Mlp::n_params_for(&sizes),
        if whole_jacobian { "whole-Jacobian" } else { "blocked" },
        estimate as f64 / f64::from(1 << 20),
        peak_rss_mib().unwrap_or(f64::NAN)
    );
    let mut net = Mlp::nguyen_widrow(&sizes, 1);
    let mut times = Vec::new();
    let mut last = Instant::now();
    let out = train(&mut net, &x, &t, &cfg, |epoch, train_mse, _| {
        let dt = last.elapsed().as_secs_f64();
        println!("epoch {epoch}: {dt:.2} s, training MSE {train_mse:.17e}");
        times.push(dt);
        last = Instant::now();
        Control::Continue
    });
    times.sort_by(f64::total_cmp);
    println!(
        "median {:.2} s per epoch over {} epochs ({:.2} μ-trials per epoch); peak RSS {:.0} MiB",
        times.get(times.len() / 2).copied().unwrap_or(f64::NAN),
        out.lm.iterations,
        (out.lm.evaluations - 1) as f64 / out.lm.iterations.max(1) as f64,
        peak_rss_mib().unwrap_or(f64::NAN)
    );
}
