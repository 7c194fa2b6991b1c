//! L2-regularised logistic regression by Newton's method: the small, inspectable classifier
//! the slip detector is fitted with.
//!
//! Contract: [`fit_logistic`] minimises `½ λ ‖w‖² + Σᵢ sᵢ ℓᵢ` with `ℓᵢ` the log-loss of sample
//! `i` and `sᵢ` its weight (1, or with [`LogisticConfig::balanced`] `n / (2 nₖ)` for its class
//! `k`, so that both classes weigh the same); the intercept is not penalised. This is
//! scikit-learn's `LogisticRegression(C = 1/λ, class_weight = None | "balanced")`, and the
//! tests match its coefficients to 1e-6. Each Newton step solves the penalised Hessian by
//! Cholesky (faer) and halves until the cost falls; it stops when the gradient's largest
//! component, or the cost a full step could still shed, is under the tolerance
//! ([`LogisticStop::Converged`]) or after
//! `max_iterations` — an outcome, not an error.

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};

/// How [`fit_logistic`] fits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogisticConfig {
    /// λ: the penalty on the squared weights (scikit-learn's `1 / C`).
    pub l2: f64,
    /// Weigh the two classes equally (scikit-learn's `class_weight = "balanced"`).
    pub balanced: bool,
    /// Newton steps at most.
    pub max_iterations: usize,
    /// Stop when no component of the gradient exceeds this, or when a full Newton step would
    /// lower the cost by less than this times the cost.
    pub tolerance: f64,
}

impl Default for LogisticConfig {
    /// scikit-learn's defaults (`C = 1`) with balanced classes.
    fn default() -> Self {
        Self {
            l2: 1.0,
            balanced: true,
            max_iterations: 100,
            tolerance: 1e-12,
        }
    }
}

/// Why [`fit_logistic`] stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LogisticStop {
    /// The gradient vanished to the tolerance.
    Converged,
    /// `max_iterations` Newton steps were taken.
    MaxIterations,
    /// No step along Newton's direction lowered the cost (at the floating-point limit).
    NoProgress,
}

/// What [`fit_logistic`] found.
#[derive(Clone, Debug, PartialEq)]
pub struct LogisticFit {
    /// One weight per input.
    pub weights: Vec<f64>,
    /// The intercept.
    pub bias: f64,
    /// Newton steps taken.
    pub iterations: usize,
    /// The final cost.
    pub cost: f64,
    /// Why it stopped.
    pub stop: LogisticStop,
}

impl LogisticFit {
    /// The probability of the positive class for inputs `x`.
    pub fn probability(&self, x: &[f64]) -> f64 {
        sigmoid(self.logit(x))
    }

    /// `w · x + b`.
    pub fn logit(&self, x: &[f64]) -> f64 {
        self.weights.iter().zip(x).map(|(w, v)| w * v).sum::<f64>() + self.bias
    }
}

/// The logistic function, computed without overflow.
pub fn sigmoid(z: f64) -> f64 {
    if z >= 0.0 {
        1.0 / (1.0 + (-z).exp())
    } else {
        let e = z.exp();
        e / (1.0 + e)
    }
}

/// `ln(1 + e^z)` without overflow.
fn softplus(z: f64) -> f64 {
    if z > 0.0 {
        z + (-z).exp().ln_1p()
    } else {
        z.exp().ln_1p()
    }
}

/// The logistic regression of `labels` on the rows `x` (each as long as the first).
pub fn fit_logistic(x: &[Vec<f64>], labels: &[bool], cfg: &LogisticConfig) -> LogisticFit {
    let d = x.first().map_or(0, Vec::len);
    let n = x.len().min(labels.len());
    let positives = labels[..n].iter().filter(|&&y| y).count();
    let weight = |y: bool| match (cfg.balanced, y) {
        (false, _) => 1.0,
        (true, true) => n as f64 / (2.0 * positives.max(1) as f64),
        (true, false) => n as f64 / (2.0 * (n - positives).max(1) as f64),
    };
    // Parameters θ = (w, b); rows extended with a 1.
    let mut theta = vec![0.0; d + 1];
    let cost = |t: &[f64]| {
        let mut c = 0.5 * cfg.l2 * t[..d].iter().map(|w| w * w).sum::<f64>();
        for (row, &y) in x.iter().zip(labels).take(n) {
            let z = row.iter().zip(t).map(|(v, w)| v * w).sum::<f64>() + t[d];
            c += weight(y) * softplus(if y { -z } else { z });
        }
        c
    };
    let mut now = cost(&theta);
    let mut stop = LogisticStop::MaxIterations;
    let mut iterations = 0;
    while iterations < cfg.max_iterations {
        let (g, h) = gradient_and_hessian(&x[..n], &labels[..n], &theta, &weight, cfg.l2);
        let step = match h.llt(Side::Lower) {
            Ok(llt) => llt.solve(&g),
            // Only without a penalty and with separable classes: a gradient step instead.
            Err(_) => g.clone(),
        };
        // Half the Newton decrement gᵀH⁻¹g: how much a full step can still lower the cost.
        let decrement = 0.5 * (0..=d).map(|i| g[(i, 0)] * step[(i, 0)]).sum::<f64>();
        if (0..=d).all(|i| g[(i, 0)].abs() <= cfg.tolerance)
            || decrement <= cfg.tolerance * now.abs().max(1.0)
        {
            stop = LogisticStop::Converged;
            break;
        }
        iterations += 1;
        let mut t = 1.0;
        let mut moved = false;
        while t > 1e-12 {
            let trial: Vec<f64> = (0..=d).map(|i| theta[i] - t * step[(i, 0)]).collect();
            let c = cost(&trial);
            if c <= now {
                moved = c < now || t == 1.0;
                theta = trial;
                now = c;
                break;
            }
            t *= 0.5;
        }
        if !moved {
            stop = LogisticStop::NoProgress;
            break;
        }
    }
    LogisticFit {
        bias: theta[d],
        weights: theta[..d].to_vec(),
        iterations,
        cost: now,
        stop,
    }
}

/// The cost's gradient and Hessian at `theta` (weights, then the intercept).
fn gradient_and_hessian(
    x: &[Vec<f64>],
    labels: &[bool],
    theta: &[f64],
    weight: &dyn Fn(bool) -> f64,
    l2: f64,
) -> (Mat<f64>, Mat<f64>) {
    let d = theta.len() - 1;
    let mut g = Mat::<f64>::zeros(d + 1, 1);
    let mut h = Mat::<f64>::zeros(d + 1, d + 1);
    for (row, &y) in x.iter().zip(labels) {
        let z = row.iter().zip(theta).map(|(v, w)| v * w).sum::<f64>() + theta[d];
        let p = sigmoid(z);
        let s = weight(y);
        let r = s * (p - f64::from(u8::from(y)));
        let c = s * p * (1.0 - p);
        for i in 0..=d {
            let xi = if i < d { row[i] } else { 1.0 };
            g[(i, 0)] += r * xi;
            for j in 0..=i {
                let xj = if j < d { row[j] } else { 1.0 };
                h[(i, j)] += c * xi * xj;
            }
        }
    }
    for i in 0..=d {
        if i < d {
            g[(i, 0)] += l2 * theta[i];
            h[(i, i)] += l2;
        }
        for j in 0..i {
            h[(j, i)] = h[(i, j)];
        }
    }
    (g, h)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data() -> Vec<Vec<f64>> {
        [
            [0.1, 1.2],
            [0.5, 0.3],
            [1.5, -0.2],
            [2.0, 1.0],
            [-0.7, 0.4],
            [0.9, 2.1],
            [1.2, 0.8],
            [-1.1, -0.5],
            [0.3, -1.3],
            [2.4, 0.2],
            [-0.2, 0.9],
            [1.7, 1.6],
        ]
        .iter()
        .map(|r| r.to_vec())
        .collect()
    }

    fn labels(s: &str) -> Vec<bool> {
        s.chars().map(|c| c == '1').collect()
    }

    /// scikit-learn 1.9.1, `LogisticRegression(C=1.0, class_weight=…, tol=1e-12)`.
    #[test]
    fn matches_scikit_learn_with_and_without_balanced_classes() {
        let cases = [
            (
                "001101000111",
                false,
                [0.99566379, 0.59610754],
                -1.0797244643826938,
            ),
            (
                "001101000111",
                true,
                [0.99566379, 0.59610754],
                -1.0797244643826938,
            ),
            (
                "001101000001",
                true,
                [0.98260813, 0.69065724],
                -1.4656696033012329,
            ),
        ];
        for (y, balanced, w, b) in cases {
            let cfg = LogisticConfig {
                balanced,
                ..LogisticConfig::default()
            };
            let f = fit_logistic(&data(), &labels(y), &cfg);
            assert_eq!(f.stop, LogisticStop::Converged, "{y}");
            assert!(f.iterations < 20);
            for (a, e) in f.weights.iter().zip(w) {
                assert!((a - e).abs() < 1e-6, "{y}: {:?} against {w:?}", f.weights);
            }
            assert!((f.bias - b).abs() < 1e-6, "{y}: {} against {b}", f.bias);
        }
    }

    #[test]
    fn separable_classes_without_a_penalty_stop_as_an_outcome() {
        let x: Vec<Vec<f64>> = (0..6).map(|i| vec![f64::from(i)]).collect();
        let cfg = LogisticConfig {
            l2: 0.0,
            max_iterations: 30,
            ..LogisticConfig::default()
        };
        // The weights grow without bound; the fit ends as an outcome with finite numbers.
        let f = fit_logistic(&x, &labels("000111"), &cfg);
        assert!(f.iterations <= 30);
        assert!(f.probability(&[5.0]) > 0.99 && f.probability(&[0.0]) < 0.01);
        assert!(f.cost.is_finite() && f.weights[0].is_finite());
    }

    #[test]
    fn sigmoid_does_not_overflow() {
        assert_eq!(sigmoid(1000.0), 1.0);
        assert_eq!(sigmoid(-1000.0), 0.0);
        assert!((sigmoid(0.0) - 0.5).abs() < 1e-15);
        assert!((softplus(800.0) - 800.0).abs() < 1e-9 && softplus(-800.0) >= 0.0);
    }
}
