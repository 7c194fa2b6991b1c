//! Times LM iterations on seed 000's network (351 inputs, five hidden layers of 20, 3 outputs,
//! all 1 280 samples in the fit: 3 840 residuals, as the numpy trainlm peer; up to 16
//! iterations, as many as the peer's 45 s give it; median time per iteration and residual
//! evaluations per iteration) and trains seed
//! 001's 6→20→1 on 2 000 samples:
//! `cargo run --release -p visuotact-nn --example lm_speed`

use std::time::Instant;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use visuotact_nn::lm::Control;
use visuotact_nn::mlp::{train, Mlp, TrainConfig};

fn data(n: usize, d_in: usize, d_out: usize, seed: u64) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let teacher = Mlp::nguyen_widrow(&[d_in, 8, d_out], seed + 1);
    let x: Vec<Vec<f64>> = (0..n)
        .map(|_| (0..d_in).map(|_| rng.random_range(-1.0..1.0)).collect())
        .collect();
    let t = x.iter().map(|xi| teacher.forward(xi)).collect();
    (x, t)
}

fn main() {
    let (x, t) = data(2000, 6, 1, 11);
    let mut net = Mlp::nguyen_widrow(&[6, 20, 1], 1);
    let t0 = Instant::now();
    let out = train(&mut net, &x, &t, &TrainConfig::TRAINLM, |_, _, _| {
        Control::Continue
    });
    println!(
        "6→20→1, 2000 samples: {:.3} s, {} epochs, stop {:?} (validation stop {}), test MSE {:.2e}",
        t0.elapsed().as_secs_f64(),
        out.lm.iterations,
        out.lm.reason,
        out.validation_stop,
        out.mse[2]
    );

    let (x, t) = data(1280, 351, 3, 21);
    let sizes = [351, 20, 20, 20, 20, 20, 3];
    let mut net = Mlp::nguyen_widrow(&sizes, 1);
    let mut times = Vec::new();
    let mut last = Instant::now();
    // All 1 280 samples in the fit (3 840 residuals) and 16 iterations, as the peer's.
    let cfg = TrainConfig {
        trainer: TrainConfig::TRAINLM.trainer.with_max_epochs(16),
        split: [1.0, 0.0, 0.0],
        ..TrainConfig::TRAINLM
    };
    let t0 = Instant::now();
    let out = train(&mut net, &x, &t, &cfg, |_, _, _| {
        times.push(last.elapsed().as_secs_f64());
        last = Instant::now();
        Control::Continue
    });
    let mut sorted = times.clone();
    sorted.sort_by(f64::total_cmp);
    println!(
        "351→5×20→3 ({} weights), 1280 samples, 3840 residuals: median {:.3} s per iteration, {:.2} residual evaluations per iteration; {} iterations in {:.2} s, per iteration {:?} s",
        Mlp::n_params_for(&sizes),
        sorted.get(sorted.len() / 2).copied().unwrap_or(f64::NAN),
        (out.lm.evaluations - 1) as f64 / out.lm.iterations.max(1) as f64,
        out.lm.iterations,
        t0.elapsed().as_secs_f64(),
        times
            .iter()
            .map(|t| (t * 100.0).round() / 100.0)
            .collect::<Vec<_>>()
    );
}
