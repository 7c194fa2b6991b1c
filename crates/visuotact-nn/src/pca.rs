//! Input reduction: a principal-component projection of the (scaled) inputs, kept in the model
//! file.
//!
//! A marker sensor's displacement field is smooth, so hundreds of per-marker features carry a
//! few dozen independent numbers; a network fed the leading components has far fewer weights to
//! fit from a few hundred touches. The components are the eigenvectors of the inputs' sample
//! covariance with the largest eigenvalues (faer's self-adjoint eigendecomposition), signs fixed
//! so that each component's largest entry is positive; the scores are mapped to [−1, 1]
//! (`mapminmax`) for the network.

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};
use serde::{Deserialize, Serialize};

use crate::mlp::MinMax;

/// Scaled inputs → leading principal-component scores in [−1, 1].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Projection {
    /// Mean of each input over the training samples.
    pub mean: Vec<f64>,
    /// The components, one row per component (unit length), largest variance first.
    pub components: Vec<Vec<f64>>,
    /// Fraction of the inputs' total variance the components hold.
    pub explained: f64,
    /// Score scaling (mapminmax over the training scores).
    pub score_scaling: MinMax,
}

/// Why principal components could not be taken or applied.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ProjectionError {
    /// Fewer than two samples, or samples of no input.
    #[error("principal components need at least 2 samples of 1 input, got {samples} of {inputs}")]
    TooFew {
        /// Samples given.
        samples: usize,
        /// Inputs per sample.
        inputs: usize,
    },
    /// More components asked for than the data have, or none.
    #[error("asked for {asked} components of {inputs} inputs and {samples} samples: at most {}", inputs.min(samples))]
    Components {
        /// Components asked for.
        asked: usize,
        /// Inputs per sample.
        inputs: usize,
        /// Samples given.
        samples: usize,
    },
    /// faer's eigendecomposition of the covariance failed (its error, as faer words it).
    #[error("eigendecomposition failed ({0})")]
    Eigen(String),
    /// A sample has so many inputs missing that fewer are left than components.
    #[error("sample {0} has fewer inputs left than components")]
    Sparse(usize),
}

impl Projection {
    /// The `k` leading components of `rows` (samples × inputs); an error when there are too
    /// few samples or inputs, or the eigendecomposition fails.
    pub fn fit(rows: &[Vec<f64>], k: usize) -> Result<Self, ProjectionError> {
        let (n, f) = (rows.len(), rows.first().map_or(0, Vec::len));
        if n < 2 || f == 0 {
            return Err(ProjectionError::TooFew {
                samples: n,
                inputs: f,
            });
        }
        if k == 0 || k > f.min(n) {
            return Err(ProjectionError::Components {
                asked: k,
                inputs: f,
                samples: n,
            });
        }
        let (mean, values, vectors) = eigen(rows)?;
        let total: f64 = values.iter().map(|v| v.max(0.0)).sum();
        let components: Vec<Vec<f64>> = (0..k)
            .map(|c| {
                let mut v = vectors[c].clone();
                let big = v
                    .iter()
                    .fold(0.0f64, |m, x| if x.abs() > m.abs() { *x } else { m });
                if big < 0.0 {
                    v.iter_mut().for_each(|x| *x = -*x);
                }
                v
            })
            .collect();
        let explained = if total > 0.0 {
            values[..k].iter().map(|v| v.max(0.0)).sum::<f64>() / total
        } else {
            1.0
        };
        let raw = Self {
            mean,
            components,
            explained,
            score_scaling: MinMax {
                min: vec![-1.0; k],
                max: vec![1.0; k],
            },
        };
        let scores: Vec<Vec<f64>> = rows.iter().map(|r| raw.scores(r)).collect();
        Ok(Self {
            score_scaling: MinMax::fit(&scores),
            ..raw
        })
    }

    /// Fractions of the total variance of `rows` along each principal component, largest
    /// first.
    pub fn variance_fractions(rows: &[Vec<f64>]) -> Result<Vec<f64>, ProjectionError> {
        let (_, values, _) = eigen(rows)?;
        let total: f64 = values.iter().map(|v| v.max(0.0)).sum();
        Ok(values
            .iter()
            .map(|v| if total > 0.0 { v.max(0.0) / total } else { 0.0 })
            .collect())
    }

    /// Number of inputs it reads.
    pub fn inputs(&self) -> usize {
        self.mean.len()
    }

    /// Number of scores it gives.
    pub fn outputs(&self) -> usize {
        self.components.len()
    }

    fn scores(&self, row: &[f64]) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.components.len());
        self.scores_into(row, &mut out);
        out
    }

    fn scores_into(&self, row: &[f64], out: &mut Vec<f64>) {
        out.clear();
        out.extend(self.components.iter().map(|c| {
            c.iter()
                .zip(row.iter().zip(&self.mean))
                .map(|(w, (x, m))| w * (x - m))
                .sum::<f64>()
        }));
    }

    /// The network inputs for one row of scaled inputs.
    pub fn apply(&self, row: &[f64]) -> Vec<f64> {
        let (mut scores, mut out) = (Vec::new(), Vec::new());
        self.apply_into(row, &mut scores, &mut out);
        out
    }

    /// [`Projection::apply`] into `out`, with `scores` as scratch: allocation-free once both
    /// have held a row.
    pub fn apply_into(&self, row: &[f64], scores: &mut Vec<f64>, out: &mut Vec<f64>) {
        self.scores_into(row, scores);
        self.score_scaling.apply_into(scores, out);
    }

    /// The network inputs for a row with missing (NaN) inputs: the scores whose reconstruction
    /// fits the inputs present best in the least-squares sense (a smooth displacement field
    /// spreads every component over many markers, so a few lost ones barely change them).
    /// Equal to [`Projection::apply`] on a complete row; `None` when fewer inputs are present
    /// than components.
    pub fn apply_partial(&self, row: &[f64]) -> Option<Vec<f64>> {
        if row.iter().all(|v| !v.is_nan()) {
            return Some(self.apply(row));
        }
        self.partial_scores(row)
            .map(|z| self.score_scaling.apply(&z))
    }

    /// Fills the missing (NaN) inputs of `row` with their reconstruction from the scores that
    /// fit the inputs present ([`Projection::apply_partial`]'s): `mean + Σ zₖ·componentₖ`.
    /// The inputs present are left as they are; `false` (and `row` unchanged) when fewer
    /// inputs are present than components.
    pub fn fill_missing(&self, row: &mut [f64]) -> bool {
        if row.iter().all(|v| !v.is_nan()) {
            return true;
        }
        let Some(z) = self.partial_scores(row) else {
            return false;
        };
        for (i, v) in row.iter_mut().enumerate().filter(|(_, v)| v.is_nan()) {
            *v = self.mean[i]
                + z.iter()
                    .zip(&self.components)
                    .map(|(zk, c)| zk * c[i])
                    .sum::<f64>();
        }
        true
    }

    /// The unscaled scores that fit the inputs present of `row` best; `None` when fewer are
    /// present than components or the fit is not finite.
    fn partial_scores(&self, row: &[f64]) -> Option<Vec<f64>> {
        let present: Vec<usize> = (0..row.len()).filter(|&i| !row[i].is_nan()).collect();
        let k = self.outputs();
        if present.len() < k {
            return None;
        }
        // Normal equations (W_o W_oᵀ) z = W_o (x_o − μ_o) over the present inputs o.
        let gram = Mat::<f64>::from_fn(k, k, |a, b| {
            present
                .iter()
                .map(|&i| self.components[a][i] * self.components[b][i])
                .sum()
        });
        let rhs = Mat::<f64>::from_fn(k, 1, |a, _| {
            present
                .iter()
                .map(|&i| self.components[a][i] * (row[i] - self.mean[i]))
                .sum()
        });
        let z = gram.partial_piv_lu().solve(&rhs);
        let z: Vec<f64> = (0..k).map(|a| z[(a, 0)]).collect();
        z.iter().all(|v| v.is_finite()).then_some(z)
    }
}

/// Mean, eigenvalues (largest first) and eigenvectors of the sample covariance of `rows`.
type Eigen = (Vec<f64>, Vec<f64>, Vec<Vec<f64>>);

fn eigen(rows: &[Vec<f64>]) -> Result<Eigen, ProjectionError> {
    let (n, f) = (rows.len(), rows.first().map_or(0, Vec::len));
    if n < 2 || f == 0 {
        return Err(ProjectionError::TooFew {
            samples: n,
            inputs: f,
        });
    }
    let mean: Vec<f64> = (0..f)
        .map(|j| rows.iter().map(|r| r[j]).sum::<f64>() / n as f64)
        .collect();
    let xc = Mat::<f64>::from_fn(n, f, |i, j| rows[i][j] - mean[j]);
    let cov = xc.transpose() * &xc * (1.0 / (n - 1) as f64);
    let evd = cov
        .self_adjoint_eigen(Side::Lower)
        .map_err(|e| ProjectionError::Eigen(format!("{e:?}")))?;
    let (s, u) = (evd.S(), evd.U());
    // faer sorts eigenvalues in nondecreasing order: take them from the end.
    let values: Vec<f64> = (0..f).rev().map(|i| s[i]).collect();
    let vectors: Vec<Vec<f64>> = (0..f)
        .rev()
        .map(|c| (0..f).map(|r| u[(r, c)]).collect())
        .collect();
    Ok((mean, values, vectors))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_on_a_line_have_one_component() {
        // Inputs (t, 2t, −t) + tiny noise: one component holds all the variance.
        let rows: Vec<Vec<f64>> = (0..20)
            .map(|i| {
                let t = f64::from(i) / 10.0 - 1.0;
                let e = 1e-6 * f64::from(i % 3);
                vec![t + e, 2.0 * t, -t]
            })
            .collect();
        let p = Projection::fit(&rows, 1).unwrap();
        assert!(p.explained > 0.999_999, "{}", p.explained);
        let c = &p.components[0];
        let want = [1.0, 2.0, -1.0].map(|v: f64| v / 6f64.sqrt());
        for (a, b) in c.iter().zip(want) {
            assert!((a - b).abs() < 1e-5, "{c:?}");
        }
        // Scores span [−1, 1] over the training rows and follow t.
        let s: Vec<f64> = rows.iter().map(|r| p.apply(r)[0]).collect();
        assert!(
            (s[0] + 1.0).abs() < 1e-9 && (s[19] - 1.0).abs() < 1e-9,
            "{s:?}"
        );
        let f = Projection::variance_fractions(&rows).unwrap();
        assert!(f[0] > 0.999_999 && f[1] < 1e-6);
    }

    #[test]
    fn a_missing_input_is_recovered_from_the_others() {
        // A smooth field: 12 inputs driven by 2 latent numbers; one input lost.
        let rows: Vec<Vec<f64>> = (0..40)
            .map(|s| {
                let (a, b) = ((f64::from(s) * 0.37).sin(), (f64::from(s) * 0.23).cos());
                (0..12)
                    .map(|i| a * (f64::from(i) * 0.5).cos() + b * (f64::from(i) * 0.3).sin())
                    .collect()
            })
            .collect();
        let p = Projection::fit(&rows, 2).unwrap();
        for r in &rows[..5] {
            let mut lost = r.clone();
            lost[4] = f64::NAN;
            lost[9] = f64::NAN;
            let (full, part) = (p.apply(r), p.apply_partial(&lost).unwrap());
            for (a, b) in full.iter().zip(&part) {
                assert!((a - b).abs() < 1e-9, "{full:?} vs {part:?}");
            }
        }
        assert_eq!(p.apply_partial(&rows[0]).unwrap(), p.apply(&rows[0]));
        // The lost inputs themselves come back, the others are left as they are.
        for r in &rows[5..10] {
            let mut lost = r.clone();
            lost[2] = f64::NAN;
            lost[11] = f64::NAN;
            assert!(p.fill_missing(&mut lost));
            for (i, (a, b)) in r.iter().zip(&lost).enumerate() {
                assert!((a - b).abs() < 1e-9, "input {i}: {a} filled as {b}");
            }
        }
        // Fewer inputs present than components: nothing to solve.
        let mut almost = vec![f64::NAN; 12];
        almost[0] = 1.0;
        assert!(p.apply_partial(&almost).is_none());
        assert!(!p.fill_missing(&mut almost) && almost[1].is_nan());
    }

    #[test]
    fn impossible_requests_are_errors() {
        let rows = vec![vec![1.0, 2.0], vec![2.0, 1.0], vec![0.0, 0.5]];
        assert!(Projection::fit(&rows, 0).is_err());
        assert!(Projection::fit(&rows, 3).is_err());
        assert!(Projection::fit(&rows[..1], 1).is_err());
        assert_eq!(Projection::fit(&rows, 2).unwrap().outputs(), 2);
    }
}
