//! Error figures in the source documents' terms: MSE and regression R (seed 000 Figs. 6–7),
//! mean and max absolute error and mean percentage error (seed 001 Table 5.1), per-axis
//! accuracy = 100 % − mean relative error (seed 000 Tables 2–3).
//!
//! Percentage errors explode where the truth is near zero (a 0.05 N error on a 0.01 N force is
//! 500 %), so the mean percentage error is taken over samples whose |truth| is at least
//! [`MPE_FLOOR_FRACTION`] of the largest |truth| — for seed 001's 10 N presses, frames of 1 N and
//! more. The floor used and the samples it kept are part of the result.

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
    /// Pearson correlation of estimates and truth (the "R" of MATLAB's regression plot); 0 when
    /// either does not vary (a constant target), where MATLAB gives NaN.
    pub r: f64,
    /// Mean absolute error.
    pub mean_abs: f64,
    /// Largest absolute error.
    pub max_abs: f64,
    /// Mean of |error| / |truth| over samples with |truth| ≥ `mpe_floor`, percent.
    pub mean_percentage_error: f64,
    /// The |truth| below which samples are left out of the percentage error.
    pub mpe_floor: f64,
    /// Samples in the percentage error.
    pub mpe_n: usize,
    /// 100 % minus the mean percentage error (seed 000's "accuracy").
    pub accuracy_percent: f64,
}

/// Fraction of the largest |truth| below which samples are left out of percentage errors.
pub const MPE_FLOOR_FRACTION: f64 = 0.1;

/// The Pearson correlation of the pairs' two values; 0 when either does not vary (no linear
/// relation to measure; never NaN: model files and JSON reports hold it) or there are none.
pub fn pearson(pairs: &[(f64, f64)]) -> f64 {
    let nf = pairs.len().max(1) as f64;
    let mean_a = pairs.iter().map(|p| p.0).sum::<f64>() / nf;
    let mean_b = pairs.iter().map(|p| p.1).sum::<f64>() / nf;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (a, b) in pairs {
        sab += (a - mean_a) * (b - mean_b);
        saa += (a - mean_a).powi(2);
        sbb += (b - mean_b).powi(2);
    }
    let s = saa.sqrt() * sbb.sqrt();
    if s > 0.0 {
        sab / s
    } else {
        0.0
    }
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
    let mpe_floor = MPE_FLOOR_FRACTION * pairs.iter().fold(0.0f64, |m, (_, t)| m.max(t.abs()));
    let rel: Vec<f64> = pairs
        .iter()
        .filter(|(_, t)| t.abs() >= mpe_floor && t.abs() > 1e-12)
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
        // No variation in the truth or the estimates: R = 0, where MATLAB gives NaN.
        r: pearson(&pairs),
        mean_abs: pairs.iter().map(|(a, b)| (a - b).abs()).sum::<f64>() / nf,
        max_abs: pairs.iter().fold(0.0f64, |m, (a, b)| m.max((a - b).abs())),
        mean_percentage_error: mpe,
        mpe_floor,
        mpe_n: rel.len(),
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

    #[test]
    fn percentage_error_leaves_out_near_zero_truth() {
        // Truth 0.01 is below 10 % of 10: its 100 % error is not averaged in; zero never is.
        let e = target_errors("force_n", &[0.02, 0.0, 5.5, 9.0], &[0.01, 0.0, 5.0, 10.0]);
        assert_eq!((e.mpe_floor, e.mpe_n), (1.0, 2));
        assert!((e.mean_percentage_error - 10.0).abs() < 1e-12);
        assert!((e.accuracy_percent - 90.0).abs() < 1e-12);
    }
}
