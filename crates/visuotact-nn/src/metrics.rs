//! Error figures in the source documents' terms: MSE and regression R (seed 000 Figs. 6–7),
//! mean and max absolute error and mean percentage error (seed 001 Table 5.1), per-axis
//! accuracy = 100 % − mean relative error (seed 000 Tables 2–3).

use serde::Serialize;

/// Error figures of one target.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TargetErrors {
    /// Target name with unit.
    pub target: String,
    /// Samples compared.
    pub n: usize,
    /// Mean squared error.
    pub mse: f64,
    /// Pearson correlation of estimates and truth (the "R" of MATLAB's regression plot).
    pub r: f64,
    /// Mean absolute error.
    pub mean_abs: f64,
    /// Largest absolute error.
    pub max_abs: f64,
    /// Mean of |error| / |truth| over samples with non-zero truth, percent.
    pub mean_percentage_error: f64,
    /// 100 % minus the mean percentage error (seed 000's "accuracy").
    pub accuracy_percent: f64,
}

/// Figures for estimates `est` against `truth` (pairs with a NaN are left out).
pub fn target_errors(target: &str, est: &[f64], truth: &[f64]) -> TargetErrors {
    let pairs: Vec<(f64, f64)> = est
        .iter()
        .zip(truth)
        .map(|(a, b)| (*a, *b))
        .filter(|(a, b)| a.is_finite() && b.is_finite())
        .collect();
    let n = pairs.len();
    let nf = n.max(1) as f64;
    let mean_p = pairs.iter().map(|p| p.0).sum::<f64>() / nf;
    let mean_t = pairs.iter().map(|p| p.1).sum::<f64>() / nf;
    let cov: f64 = pairs.iter().map(|(a, b)| (a - mean_p) * (b - mean_t)).sum();
    let sp = pairs
        .iter()
        .map(|(a, _)| (a - mean_p).powi(2))
        .sum::<f64>()
        .sqrt();
    let st = pairs
        .iter()
        .map(|(_, b)| (b - mean_t).powi(2))
        .sum::<f64>()
        .sqrt();
    let rel: Vec<f64> = pairs
        .iter()
        .filter(|(_, t)| t.abs() > 1e-12)
        .map(|(e, t)| ((e - t) / t).abs())
        .collect();
    let mpe = if rel.is_empty() {
        f64::NAN
    } else {
        100.0 * rel.iter().sum::<f64>() / rel.len() as f64
    };
    TargetErrors {
        target: target.to_string(),
        n,
        mse: pairs.iter().map(|(a, b)| (a - b) * (a - b)).sum::<f64>() / nf,
        r: cov / (sp * st),
        mean_abs: pairs.iter().map(|(a, b)| (a - b).abs()).sum::<f64>() / nf,
        max_abs: pairs.iter().fold(0.0f64, |m, (a, b)| m.max((a - b).abs())),
        mean_percentage_error: mpe,
        accuracy_percent: 100.0 - mpe,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figures_of_a_known_case() {
        let e = target_errors("x_mm", &[1.0, 2.0, 4.0], &[1.0, 2.0, 2.0]);
        assert_eq!(e.n, 3);
        assert!((e.mse - 4.0 / 3.0).abs() < 1e-12);
        assert_eq!((e.mean_abs, e.max_abs), (2.0 / 3.0, 2.0));
        assert!((e.mean_percentage_error - 100.0 / 3.0).abs() < 1e-12);
        // Deviations (−4, −1, 5)/3 and (−2, 1, 1)/3: R = 12 / sqrt(42 · 6).
        assert!((e.r - 12.0 / 252f64.sqrt()).abs() < 1e-12);
    }
}
