//! Mini-batch Adam on the mean squared error plus an L2 weight penalty, stopped early on a
//! held-out subset: the trainer for tables too large for Levenberg–Marquardt's `JᵀJ`
//! (thousands of frames of hundreds of marker features into a wide network), as
//! scikit-learn's `MLPRegressor(solver="adam", early_stopping=True)`.
//!
//! Contract (Kingma & Ba 2015, with scikit-learn's loss and stopping):
//! - Each epoch visits the training samples once in a seeded random order, in batches of
//!   [`AdamConfig::batch`]. A batch's loss is `½·mean_b Σ_j (y_bj − t_bj)² + (l2 / 2B)·‖W‖²`
//!   (weights only, not biases; `B` the batch's size).
//! - Adam's moments with β₁ = 0.9, β₂ = 0.999, ε = 1e-8 and bias correction.
//! - After each epoch the validation MSE is taken. When it has not improved by
//!   [`AdamConfig::min_improvement`] (relative) for [`AdamConfig::patience`] epochs, the step
//!   is multiplied by [`AdamConfig::drop_factor`] and the count starts again, up to
//!   [`AdamConfig::step_drops`] times (Keras' `ReduceLROnPlateau`); after that, training stops.
//!   The best weights are kept. Without a validation subset the training MSE plays its part.
//!
//! The batched forward and backward passes are dense products (faer): a layer's weights,
//! stored row by row (`out × in`), are read in place as the column-major `in × out` matrix
//! `Wᵀ`, so `Z = A·Wᵀ` and the weight gradient `Aᵀ·Δ` lands in the parameter vector's own
//! layout. The gradient is checked against finite differences in the tests.

use faer::linalg::matmul::matmul;
use faer::prelude::ReborrowMut;
use faer::{Accum, Mat, MatMut, MatRef, Par};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::lm::Control;
use crate::mlp::Mlp;
use crate::tansig::tansig_of_sum_in_place;

/// Adam's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdamConfig {
    /// Step size.
    pub learning_rate: f64,
    /// Samples per batch (the whole training subset when it has fewer).
    pub batch: usize,
    /// L2 penalty on the weights (scikit-learn's `alpha`).
    pub l2: f64,
    /// Most epochs.
    pub max_epochs: usize,
    /// Epochs without a better validation error before stopping.
    pub patience: usize,
    /// Relative improvement of the validation error that counts as better.
    pub min_improvement: f64,
    /// How many times a settled validation error lowers the step before training stops.
    pub step_drops: usize,
    /// What each drop multiplies the step by.
    pub drop_factor: f64,
}

impl AdamConfig {
    /// Step 3e-3, batches of 200, L2 0.1, up to 200 epochs (scikit-learn's `max_iter`), after
    /// 20 epochs without 1e-4 better the step drops tenfold, twice, then training stops: on the
    /// real 127-pin TacTip set these beat scikit-learn's step 1e-3, L2 1 and patience 10 by
    /// 10–25 % per target, the larger step halves the epochs, and the two drops took another
    /// 2–10 % off every target on three seeds (docs/benchmarks.md).
    pub const DEFAULT: Self = Self {
        learning_rate: 3e-3,
        batch: 200,
        l2: 0.1,
        max_epochs: 200,
        patience: 20,
        min_improvement: 1e-4,
        step_drops: 2,
        drop_factor: 0.1,
    };
}

impl Default for AdamConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Why Adam stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AdamStop {
    /// The validation error stopped improving.
    Settled,
    /// [`AdamConfig::max_epochs`] reached.
    MaxEpochs,
    /// The callback asked to stop.
    Callback,
    /// The loss became infinite or NaN; the best weights before it are kept.
    NonFinite,
}

/// What the callback sees after each epoch.
#[derive(Clone, Copy, Debug)]
pub struct AdamProgress {
    /// Epochs done.
    pub epoch: usize,
    /// Mean squared error of the training batches during the epoch (scaled targets).
    pub train_mse: f64,
    /// Validation MSE after the epoch (NaN without a validation subset).
    pub validation_mse: f64,
}

/// The result of a run.
#[derive(Clone, Debug, PartialEq)]
pub struct AdamOutcome {
    /// The best parameters (lowest validation, else training, error).
    pub params: Vec<f64>,
    /// Epochs done.
    pub epochs: usize,
    /// The epoch of the kept parameters.
    pub best_epoch: usize,
    /// Why it stopped.
    pub stop: AdamStop,
}

/// Samples given as rows of scaled inputs and targets.
#[derive(Clone, Copy, Debug)]
pub struct Samples<'a> {
    /// Inputs, one row per sample.
    pub x: &'a [&'a [f64]],
    /// Targets, one row per sample.
    pub t: &'a [&'a [f64]],
}

/// Activations and sensitivities of one batch, kept between batches.
struct Batch {
    /// Per layer, the batch's activations (`B × size`), inputs first — those transposed
    /// (`size × B`, one sample per column) so that loading a sample is one contiguous copy.
    acts: Vec<Mat<f64>>,
    /// Per layer, the sensitivities to its pre-activations (`B × size`), after the inputs.
    deltas: Vec<Mat<f64>>,
}

impl Batch {
    fn new(sizes: &[usize], rows: usize) -> Self {
        Self {
            acts: sizes
                .iter()
                .enumerate()
                .map(|(l, &s)| {
                    if l == 0 {
                        Mat::zeros(s, rows)
                    } else {
                        Mat::zeros(rows, s)
                    }
                })
                .collect(),
            deltas: sizes[1..].iter().map(|&s| Mat::zeros(rows, s)).collect(),
        }
    }

    /// Layer `l`'s activations of the first `rows` samples (`rows × size`).
    fn layer(acts: &[Mat<f64>], l: usize, rows: usize) -> MatRef<'_, f64> {
        if l == 0 {
            acts[0].as_ref().subcols(0, rows).transpose()
        } else {
            acts[l].as_ref().subrows(0, rows)
        }
    }

    /// Forward pass over `rows` samples whose inputs are in `acts[0]`'s first columns.
    fn forward(&mut self, net: &Mlp, p: &[f64], rows: usize) {
        let layers = net.sizes.len() - 1;
        let mut off = 0;
        for l in 0..layers {
            let (n_in, n_out) = (net.sizes[l], net.sizes[l + 1]);
            let wt = MatRef::from_column_major_slice(&p[off..off + n_in * n_out], n_in, n_out);
            let b = &p[off + n_in * n_out..off + n_in * n_out + n_out];
            off += n_in * n_out + n_out;
            let (prev, next) = self.acts.split_at_mut(l + 1);
            let a = Self::layer(prev, l, rows);
            let z = &mut next[0];
            matmul(
                z.as_mut().subrows_mut(0, rows),
                Accum::Replace,
                a,
                wt,
                1.0,
                Par::Seq,
            );
            let hidden = l + 1 < layers;
            for (o, &bo) in b.iter().enumerate() {
                let col = &mut z.col_as_slice_mut(o)[..rows];
                if hidden {
                    tansig_of_sum_in_place(col, bo);
                } else {
                    col.iter_mut().for_each(|v| *v += bo);
                }
            }
        }
    }

    /// Gradient of `½·mean_b Σ_j (y − t)²` (plus `l2/(2B)·‖W‖²`) into `grad`, after
    /// [`Batch::forward`]; returns the batch's sum of squared errors.
    fn backward(&mut self, net: &Mlp, p: &[f64], t: &[&[f64]], l2: f64, grad: &mut [f64]) -> f64 {
        let rows = t.len();
        let layers = net.sizes.len() - 1;
        let scale = 1.0 / rows as f64;
        let mut sse = 0.0;
        {
            let y = self.acts[layers].as_ref();
            let mut d = self.deltas[layers - 1].as_mut();
            for (s, ts) in t.iter().enumerate() {
                for (j, &tj) in ts.iter().enumerate() {
                    let e = y[(s, j)] - tj;
                    sse += e * e;
                    d[(s, j)] = e * scale;
                }
            }
        }
        let offs = offsets(&net.sizes);
        for l in (0..layers).rev() {
            let (n_in, n_out, off) = (net.sizes[l], net.sizes[l + 1], offs[l]);
            let (w_grad, rest) = grad[off..].split_at_mut(n_in * n_out);
            let d = self.deltas[l].as_ref().subrows(0, rows);
            let a = Self::layer(&self.acts, l, rows);
            let gw = MatMut::from_column_major_slice_mut(w_grad, n_in, n_out);
            matmul(gw, Accum::Replace, a.transpose(), d, 1.0, Par::Seq);
            for (o, g) in rest[..n_out].iter_mut().enumerate() {
                *g = d.col(o).iter().sum();
            }
            let w = &p[off..off + n_in * n_out];
            for (g, &wi) in w_grad.iter_mut().zip(w) {
                *g += l2 * scale * wi;
            }
            if l > 0 {
                let wt = MatRef::from_column_major_slice(w, n_in, n_out);
                let (lower, upper) = self.deltas.split_at_mut(l);
                let mut prev = lower[l - 1].as_mut().subrows_mut(0, rows);
                let d = upper[0].as_ref().subrows(0, rows);
                matmul(
                    prev.rb_mut(),
                    Accum::Replace,
                    d,
                    wt.transpose(),
                    1.0,
                    Par::Seq,
                );
                let a = self.acts[l].as_ref().subrows(0, rows);
                for i in 0..n_in {
                    for (v, &ai) in prev.rb_mut().col_mut(i).iter_mut().zip(a.col(i).iter()) {
                        *v *= 1.0 - ai * ai;
                    }
                }
            }
        }
        sse
    }

    /// Copies the inputs of `ids` into the first columns of `acts[0]`.
    fn load(&mut self, x: &[&[f64]], ids: &[usize]) {
        for (r, &i) in ids.iter().enumerate() {
            self.acts[0].col_as_slice_mut(r).copy_from_slice(x[i]);
        }
    }
}

/// Offsets of each layer's parameters.
fn offsets(sizes: &[usize]) -> Vec<usize> {
    let mut offs = Vec::with_capacity(sizes.len() - 1);
    let mut off = 0;
    for w in sizes.windows(2) {
        offs.push(off);
        off += w[0] * w[1] + w[1];
    }
    offs
}

/// Whether parameter `k` of a network with `sizes` is a weight (not a bias).
fn weight_mask(sizes: &[usize]) -> Vec<bool> {
    let mut mask = Vec::with_capacity(Mlp::n_params_for(sizes));
    for w in sizes.windows(2) {
        mask.extend(std::iter::repeat_n(true, w[0] * w[1]));
        mask.extend(std::iter::repeat_n(false, w[1]));
    }
    mask
}

/// The mean squared error (over samples and targets) of `net` with parameters `p` on
/// `samples`, in batches through `batch`.
fn batched_mse(net: &Mlp, p: &[f64], samples: Samples<'_>, batch: &mut Batch) -> f64 {
    let n = samples.x.len();
    if n == 0 {
        return f64::NAN;
    }
    let cap = batch.acts[0].ncols();
    let layers = net.sizes.len() - 1;
    let mut sum = 0.0;
    let ids: Vec<usize> = (0..n).collect();
    for chunk in ids.chunks(cap) {
        batch.load(samples.x, chunk);
        batch.forward(net, p, chunk.len());
        let y = batch.acts[layers].as_ref();
        for (r, &i) in chunk.iter().enumerate() {
            for (j, &tj) in samples.t[i].iter().enumerate() {
                sum += (y[(r, j)] - tj).powi(2);
            }
        }
    }
    sum / (n * net.sizes[layers]) as f64
}

/// The gradient of one batch's loss (see the module doc) at `p` over all of `samples`, and the
/// loss: for tests and checks.
pub fn batch_gradient(net: &Mlp, p: &[f64], samples: Samples<'_>, l2: f64) -> (f64, Vec<f64>) {
    let n = samples.x.len();
    let mut batch = Batch::new(&net.sizes, n);
    let ids: Vec<usize> = (0..n).collect();
    batch.load(samples.x, &ids);
    batch.forward(net, p, n);
    let mut grad = vec![0.0; p.len()];
    let sse = batch.backward(net, p, samples.t, l2, &mut grad);
    let ssw: f64 = p
        .iter()
        .zip(weight_mask(&net.sizes))
        .filter(|(_, w)| *w)
        .map(|(v, _)| v * v)
        .sum();
    (0.5 * (sse + l2 * ssw) / n as f64, grad)
}

/// Adam's moment estimates.
struct Moments {
    m: Vec<f64>,
    v: Vec<f64>,
    steps: i32,
}

impl Moments {
    const BETA1: f64 = 0.9;
    const BETA2: f64 = 0.999;
    const EPS: f64 = 1e-8;

    /// One Adam step of `p` along `grad`.
    fn step(&mut self, p: &mut [f64], grad: &[f64], lr: f64) {
        self.steps += 1;
        let c1 = 1.0 - Self::BETA1.powi(self.steps);
        let c2 = 1.0 - Self::BETA2.powi(self.steps);
        let rate = lr * c2.sqrt() / c1;
        for ((pi, &g), (m, v)) in p
            .iter_mut()
            .zip(grad)
            .zip(self.m.iter_mut().zip(self.v.iter_mut()))
        {
            *m = Self::BETA1 * *m + (1.0 - Self::BETA1) * g;
            *v = Self::BETA2 * *v + (1.0 - Self::BETA2) * g * g;
            *pi -= rate * *m / (v.sqrt() + Self::EPS);
        }
    }
}

/// Trains `net`'s parameters from `p0` on `train`, stopping on `validation` (may be empty),
/// calling `callback` after every epoch; the batches' order is seeded by `seed`.
pub fn minimize_adam(
    net: &Mlp,
    p0: &[f64],
    (train, validation): (Samples<'_>, Samples<'_>),
    cfg: &AdamConfig,
    seed: u64,
    mut callback: impl FnMut(&AdamProgress) -> Control,
) -> AdamOutcome {
    let n = train.x.len();
    let bsize = cfg.batch.clamp(1, n.max(1));
    let mut batch = Batch::new(&net.sizes, bsize);
    let mut p = p0.to_vec();
    let mut grad = vec![0.0; p.len()];
    let mut moments = Moments {
        m: vec![0.0; p.len()],
        v: vec![0.0; p.len()],
        steps: 0,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xADA3);
    let mut order: Vec<usize> = (0..n).collect();
    let outputs = net.sizes[net.sizes.len() - 1];
    let mut best = (f64::INFINITY, p.clone(), 0usize);
    let mut since_best = 0;
    let mut stop = AdamStop::MaxEpochs;
    let mut epochs = 0;
    let (mut step, mut drops_left) = (cfg.learning_rate, cfg.step_drops);
    while epochs < cfg.max_epochs && n > 0 {
        for i in (1..n).rev() {
            order.swap(i, rng.random_range(0..=i));
        }
        let mut sse = 0.0;
        for ids in order.chunks(bsize) {
            batch.load(train.x, ids);
            batch.forward(net, &p, ids.len());
            let t: Vec<&[f64]> = ids.iter().map(|&i| train.t[i]).collect();
            sse += batch.backward(net, &p, &t, cfg.l2, &mut grad);
            moments.step(&mut p, &grad, step);
        }
        epochs += 1;
        let train_mse = sse / (n * outputs) as f64;
        let validation_mse = batched_mse(net, &p, validation, &mut batch);
        let score = if validation.x.is_empty() {
            train_mse
        } else {
            validation_mse
        };
        if !score.is_finite() {
            stop = AdamStop::NonFinite;
            break;
        }
        if score < best.0 * (1.0 - cfg.min_improvement) {
            since_best = 0;
        } else {
            since_best += 1;
        }
        if score < best.0 {
            best = (score, p.clone(), epochs);
        }
        let progress = AdamProgress {
            epoch: epochs,
            train_mse,
            validation_mse,
        };
        if callback(&progress) == Control::Stop {
            stop = AdamStop::Callback;
            break;
        }
        if since_best >= cfg.patience {
            if drops_left == 0 {
                stop = AdamStop::Settled;
                break;
            }
            drops_left -= 1;
            step *= cfg.drop_factor;
            since_best = 0;
        }
    }
    if best.0.is_infinite() {
        best.1 = p0.to_vec();
    }
    AdamOutcome {
        params: best.1,
        epochs,
        best_epoch: best.2,
        stop,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(n: usize) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
        let x: Vec<Vec<f64>> = (0..n)
            .map(|i| {
                let a = (i as f64 * 0.37).sin();
                let b = (i as f64 * 0.91).cos();
                vec![a, b, a * b]
            })
            .collect();
        let t = x
            .iter()
            .map(|r| vec![(r[0] + 0.5 * r[1]).tanh(), r[0] * r[1] - 0.2])
            .collect();
        (x, t)
    }

    fn rows(v: &[Vec<f64>]) -> Vec<&[f64]> {
        v.iter().map(Vec::as_slice).collect()
    }

    #[test]
    fn the_gradient_matches_central_differences() {
        let (x, t) = table(17);
        let (xr, tr) = (rows(&x), rows(&t));
        let s = Samples { x: &xr, t: &tr };
        for sizes in [vec![3, 5, 2], vec![3, 4, 3, 2]] {
            let net = Mlp::glorot(&sizes, 3);
            let (_, g) = batch_gradient(&net, &net.params, s, 0.3);
            for k in 0..net.params.len() {
                let h = 1e-6;
                let mut p = net.params.clone();
                p[k] += h;
                let (up, _) = batch_gradient(&net, &p, s, 0.3);
                p[k] -= 2.0 * h;
                let (down, _) = batch_gradient(&net, &p, s, 0.3);
                let fd = (up - down) / (2.0 * h);
                assert!(
                    (fd - g[k]).abs() <= 1e-7 * (1.0 + fd.abs()),
                    "{sizes:?} parameter {k}: {fd} by differences, {} by back-propagation",
                    g[k]
                );
            }
        }
    }

    #[test]
    fn the_batched_forward_pass_equals_the_per_sample_one() {
        let (x, t) = table(9);
        let (xr, tr) = (rows(&x), rows(&t));
        let net = Mlp::glorot(&[3, 6, 4, 2], 5);
        let mut batch = Batch::new(&net.sizes, 4);
        let mse = batched_mse(&net, &net.params, Samples { x: &xr, t: &tr }, &mut batch);
        let direct: f64 = x
            .iter()
            .zip(&t)
            .flat_map(|(xi, ti)| {
                let y = net.forward(xi);
                y.into_iter().zip(ti.clone()).map(|(a, b)| (a - b).powi(2))
            })
            .sum::<f64>()
            / 18.0;
        assert!((mse - direct).abs() < 1e-14, "{mse} vs {direct}");
    }

    /// The first 340 rows to fit, the rest to validate.
    fn fit_and_validation<'a>(
        x: &'a [&'a [f64]],
        t: &'a [&'a [f64]],
    ) -> (Samples<'a>, Samples<'a>) {
        let ((fit_x, val_x), (fit_t, val_t)) = (x.split_at(340), t.split_at(340));
        (
            Samples { x: fit_x, t: fit_t },
            Samples { x: val_x, t: val_t },
        )
    }

    #[test]
    fn training_fits_a_smooth_function_and_is_deterministic() {
        let (x, t) = table(400);
        let (xr, tr) = (rows(&x), rows(&t));
        let data = fit_and_validation(&xr, &tr);
        let net = Mlp::glorot(&[3, 16, 2], 1);
        let cfg = AdamConfig {
            learning_rate: 1e-2,
            batch: 32,
            l2: 1e-4,
            max_epochs: 300,
            ..AdamConfig::DEFAULT
        };
        let mut seen = 0;
        let a = minimize_adam(&net, &net.params, data, &cfg, 7, |p| {
            seen = p.epoch;
            Control::Continue
        });
        let b = minimize_adam(&net, &net.params, data, &cfg, 7, |_| Control::Continue);
        assert_eq!(a, b);
        assert_eq!(seen, a.epochs);
        let start = batched_mse(&net, &net.params, data.1, &mut Batch::new(&net.sizes, 8));
        let end = batched_mse(&net, &a.params, data.1, &mut Batch::new(&net.sizes, 8));
        assert!(end < 0.02 * start, "validation MSE {start} → {end}");
        assert!(a.best_epoch <= a.epochs && a.best_epoch > 0);
    }

    #[test]
    fn a_settled_error_drops_the_step_before_stopping() {
        let (x, t) = table(400);
        let (xr, tr) = (rows(&x), rows(&t));
        let data = fit_and_validation(&xr, &tr);
        let net = Mlp::glorot(&[3, 16, 2], 1);
        let run = |step_drops| {
            let cfg = AdamConfig {
                learning_rate: 3e-2,
                batch: 32,
                l2: 1e-4,
                max_epochs: 2000,
                patience: 10,
                step_drops,
                ..AdamConfig::DEFAULT
            };
            let out = minimize_adam(&net, &net.params, data, &cfg, 3, |_| Control::Continue);
            let mse = batched_mse(&net, &out.params, data.1, &mut Batch::new(&net.sizes, 8));
            (out, mse)
        };
        let (flat, flat_mse) = run(0);
        let (dropped, dropped_mse) = run(2);
        assert_eq!(flat.stop, AdamStop::Settled);
        assert_eq!(dropped.stop, AdamStop::Settled);
        // The same batches up to the first settle, then at least `patience` more epochs per drop.
        assert!(
            dropped.epochs >= flat.epochs + 20,
            "{} vs {}",
            dropped.epochs,
            flat.epochs
        );
        assert!(
            dropped_mse < flat_mse,
            "validation MSE {flat_mse} → {dropped_mse}"
        );
    }

    #[test]
    fn the_callback_stops_it_and_the_best_weights_are_kept() {
        let (x, t) = table(50);
        let (xr, tr) = (rows(&x), rows(&t));
        let net = Mlp::glorot(&[3, 4, 2], 2);
        let s = Samples { x: &xr, t: &tr };
        let none = Samples { x: &[], t: &[] };
        let out = minimize_adam(&net, &net.params, (s, none), &AdamConfig::DEFAULT, 1, |p| {
            if p.epoch == 3 {
                Control::Stop
            } else {
                Control::Continue
            }
        });
        assert_eq!((out.epochs, out.stop), (3, AdamStop::Callback));
        assert!(out.best_epoch <= 3 && out.best_epoch >= 1);
    }
}
