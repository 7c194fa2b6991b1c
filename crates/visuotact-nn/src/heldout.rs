//! How far off an estimate may be, learned from the training frames the networks did not train
//! on: every held-out training sample keeps its estimate (scaled targets) and its absolute error
//! (target units); a new frame's uncertainty per target is the root-mean-square error of the
//! [`HeldOutErrors::neighbours`] held-out samples whose estimates lie nearest its own
//! ([`crate::model::Model::estimate`] reports the larger of it and the ensemble's spread).
//!
//! An ensemble's spread says how much its networks disagree; it does not see what no network
//! can tell from the inputs. On the real 127-pin TacTip set the frames whose pins barely move
//! can come from shears ±1 mm apart: every network agrees on the same wrong shear there, so the
//! spread stays small (its correlation with the error is 0.10) while the error is large. The
//! held-out errors of training frames with the same estimate show it (correlation 0.5–0.6,
//! docs/benchmarks.md).
//!
//! The errors are those of the network(s) that held the sample out — one or two of an
//! ensemble, not its mean — so the figure leans to the cautious side. Estimates are compared in
//! the model's scaled target space ([-1, 1] per target), where every target weighs alike.
//!
//! ```
//! use visuotact_nn::heldout::{HeldOutErrors, LookupScratch};
//! // Held-out samples: estimates near -1 were off by 0.1, those near +1 by 2.0.
//! let est = vec![vec![-1.0], vec![-0.9], vec![-0.8], vec![0.8], vec![0.9], vec![1.0]];
//! let err = vec![vec![0.1], vec![0.1], vec![0.1], vec![2.0], vec![2.0], vec![2.0]];
//! let h = HeldOutErrors::with_neighbours(est, err, 3).unwrap();
//! let (mut scratch, mut out) = (LookupScratch::default(), Vec::new());
//! h.rms_error_into(&[0.95], &mut scratch, &mut out);
//! assert!((out[0] - 2.0).abs() < 1e-12);
//! h.rms_error_into(&[-0.95], &mut scratch, &mut out);
//! assert!((out[0] - 0.1).abs() < 1e-12);
//! ```

use serde::{Deserialize, Serialize};

/// Held-out samples averaged per estimate, at most.
pub const NEIGHBOURS: usize = 30;

/// Fewest held-out samples that make a lookup (fewer: the model keeps none, and `predict`
/// reports the ensemble's spread).
pub const MIN_HELD_OUT: usize = 30;

/// The held-out training samples' estimates and errors (see the module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeldOutErrors {
    /// Samples whose errors make one figure.
    pub neighbours: usize,
    /// Per held-out sample, its estimate in scaled targets.
    pub estimates: Vec<Vec<f64>>,
    /// Per held-out sample, its absolute error per target in target units.
    pub errors: Vec<Vec<f64>>,
}

/// Why a [`HeldOutErrors`] read from a file is unusable.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum HeldOutError {
    /// No neighbours, or more than there are samples.
    #[error("held-out errors: {neighbours} neighbours of {samples} samples")]
    Neighbours {
        /// Neighbours asked for.
        neighbours: usize,
        /// Samples held.
        samples: usize,
    },
    /// The error rows do not pair with the estimate rows.
    #[error("held-out errors: {estimates} estimates but {errors} errors")]
    Unpaired {
        /// Estimate rows.
        estimates: usize,
        /// Error rows.
        errors: usize,
    },
    /// A row of the wrong length or with a value that is not finite.
    #[error("held-out errors: row {row} has {values} values (expected {targets} finite ones)")]
    Row {
        /// The row (0-based, in the estimates and in the errors alike).
        row: usize,
        /// Values it has.
        values: usize,
        /// Targets the model has.
        targets: usize,
    },
}

/// The nearest samples found by one lookup, kept between frames.
#[derive(Clone, Debug, Default)]
pub struct LookupScratch {
    /// (squared distance, sample), the farthest first once full.
    near: Vec<(f64, usize)>,
}

impl HeldOutErrors {
    /// From `estimates` (scaled) and `errors` (target units), one row each per held-out sample,
    /// averaging [`NEIGHBOURS`] samples or a third of them when fewer; `None` under
    /// [`MIN_HELD_OUT`] samples.
    pub fn new(estimates: Vec<Vec<f64>>, errors: Vec<Vec<f64>>) -> Option<Self> {
        let k = NEIGHBOURS.min(estimates.len() / 3);
        if estimates.len() < MIN_HELD_OUT {
            return None;
        }
        Self::with_neighbours(estimates, errors, k)
    }

    /// As [`HeldOutErrors::new`] with `neighbours` chosen; `None` when there are fewer samples
    /// than neighbours, none, or the rows disagree in width.
    pub fn with_neighbours(
        estimates: Vec<Vec<f64>>,
        errors: Vec<Vec<f64>>,
        neighbours: usize,
    ) -> Option<Self> {
        let h = Self {
            neighbours,
            estimates,
            errors,
        };
        h.check(h.estimates.first().map_or(0, Vec::len)).ok()?;
        Some(h)
    }

    /// Whether the table is usable for a model with `targets` targets; the error says what is
    /// wrong.
    pub fn check(&self, targets: usize) -> Result<(), HeldOutError> {
        if self.neighbours == 0 || self.estimates.len() < self.neighbours {
            return Err(HeldOutError::Neighbours {
                neighbours: self.neighbours,
                samples: self.estimates.len(),
            });
        }
        if self.errors.len() != self.estimates.len() {
            return Err(HeldOutError::Unpaired {
                estimates: self.estimates.len(),
                errors: self.errors.len(),
            });
        }
        let rows = self.estimates.iter().chain(&self.errors);
        if let Some((i, r)) = rows
            .enumerate()
            .find(|(_, r)| r.len() != targets || r.iter().any(|v| !v.is_finite()))
        {
            return Err(HeldOutError::Row {
                row: i % self.estimates.len(),
                values: r.len(),
                targets,
            });
        }
        Ok(())
    }

    /// Per target, the root-mean-square held-out error of the [`HeldOutErrors::neighbours`]
    /// samples whose estimates are nearest `estimate` (scaled targets), into `out`. Allocates
    /// nothing once `scratch` and `out` have held one lookup.
    pub fn rms_error_into(
        &self,
        estimate: &[f64],
        scratch: &mut LookupScratch,
        out: &mut Vec<f64>,
    ) {
        let k = self.neighbours;
        let near = &mut scratch.near;
        near.clear();
        for (i, e) in self.estimates.iter().enumerate() {
            let d: f64 = e.iter().zip(estimate).map(|(a, b)| (a - b) * (a - b)).sum();
            if near.len() < k {
                near.push((d, i));
                if near.len() == k {
                    // Farthest first from now on.
                    let far = farthest(near);
                    near.swap(0, far);
                }
            } else if d < near[0].0 {
                near[0] = (d, i);
                let far = farthest(near);
                near.swap(0, far);
            }
        }
        out.clear();
        let width = self.errors.first().map_or(0, Vec::len);
        let n = near.len().max(1) as f64;
        out.extend((0..width).map(|j| {
            let ss: f64 = near.iter().map(|&(_, i)| self.errors[i][j].powi(2)).sum();
            (ss / n).sqrt()
        }));
    }
}

/// Where the largest distance of `near` sits.
fn farthest(near: &[(f64, usize)]) -> usize {
    near.iter()
        .enumerate()
        .max_by(|a, b| a.1 .0.total_cmp(&b.1 .0))
        .map_or(0, |(i, _)| i)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The k nearest by brute force: every distance sorted.
    fn brute(h: &HeldOutErrors, q: &[f64]) -> Vec<f64> {
        let mut d: Vec<(f64, usize)> = h
            .estimates
            .iter()
            .enumerate()
            .map(|(i, e)| (e.iter().zip(q).map(|(a, b)| (a - b).powi(2)).sum(), i))
            .collect();
        d.sort_by(|a, b| a.0.total_cmp(&b.0));
        let k = h.neighbours;
        (0..h.errors[0].len())
            .map(|j| {
                let ss: f64 = d[..k].iter().map(|&(_, i)| h.errors[i][j].powi(2)).sum();
                (ss / k as f64).sqrt()
            })
            .collect()
    }

    #[test]
    fn the_lookup_matches_sorting_every_distance() {
        // 200 samples of 2 targets on a seeded pseudo-random walk; distinct distances.
        let mut s = 0x1234_5678_u64;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s % 10_000) as f64 / 5_000.0 - 1.0
        };
        let est: Vec<Vec<f64>> = (0..200).map(|_| vec![next(), next()]).collect();
        let err: Vec<Vec<f64>> = (0..200).map(|_| vec![next().abs(), next().abs()]).collect();
        let h = HeldOutErrors::new(est, err).unwrap();
        assert_eq!(h.neighbours, NEIGHBOURS);
        let (mut scratch, mut out) = (LookupScratch::default(), Vec::new());
        for q in [[0.0, 0.0], [0.9, -0.9], [-1.0, 0.3], [2.0, 2.0]] {
            h.rms_error_into(&q, &mut scratch, &mut out);
            let want = brute(&h, &q);
            for (a, b) in out.iter().zip(&want) {
                assert!((a - b).abs() < 1e-12, "{q:?}: {out:?} vs {want:?}");
            }
        }
    }

    #[test]
    fn too_few_samples_or_ragged_rows_make_no_table() {
        let row = |v: f64| vec![v, v];
        let few: Vec<Vec<f64>> = (0..MIN_HELD_OUT - 1).map(|i| row(i as f64)).collect();
        assert!(HeldOutErrors::new(few.clone(), few).is_none());
        let enough: Vec<Vec<f64>> = (0..MIN_HELD_OUT).map(|i| row(i as f64)).collect();
        let h = HeldOutErrors::new(enough.clone(), enough.clone()).unwrap();
        assert_eq!(h.neighbours, MIN_HELD_OUT / 3);
        let mut ragged = enough.clone();
        ragged[4] = vec![1.0];
        assert!(HeldOutErrors::new(enough.clone(), ragged).is_none());
        let mut nan = enough.clone();
        nan[2][1] = f64::NAN;
        assert!(HeldOutErrors::new(nan, enough.clone()).is_none());
        // A file's table for another number of targets is refused, with the row.
        let e = h.check(3).unwrap_err();
        assert!(e.to_string().contains("row 0 has 2 values"), "{e}");
    }
}
