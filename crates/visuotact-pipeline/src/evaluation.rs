//! Estimates against labels: the source documents' error figures per target (MSE, R, mean and
//! largest error, MPE, per-axis accuracy: [`visuotact_nn::metrics`]) and the contact distance D
//! over the rows both tables have, matched on `frame`; plus the points the regression plot and
//! the contact map draw. `visuotact eval` and `replay` print it; drawing lives with them.

use std::path::Path;

use visuotact_io::table::{KeyedTable, TableError};
use visuotact_nn::metrics::{pearson, target_errors, TargetErrors};

/// One touch on the contact map: actual and estimated (x, y, depth); depth NaN when absent.
pub type MapPoint = ([f64; 3], [f64; 3]);

/// The contact distance D between estimated and actual (x, y).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Distance {
    /// Mean over the matched rows, mm.
    pub mean: f64,
    /// Largest, mm.
    pub max: f64,
}

/// One target's figures and the (truth, estimate) pairs behind them.
#[derive(Clone, Debug, PartialEq)]
pub struct TargetEvaluation {
    /// The figures.
    pub errors: TargetErrors,
    /// (truth, estimate) per matched row where both are finite.
    pub points: Vec<(f64, f64)>,
    /// How the predictions' `<target>_std` agrees with the errors, when they have it.
    pub spread: Option<SpreadCheck>,
}

/// Whether a target's stated spread (`<target>_std`) tells the large errors from the small:
/// for a standard deviation of a normal error, 68 % of the errors lie within one and 95 %
/// within two.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct SpreadCheck {
    /// Rows with a finite estimate, label and spread.
    pub n: usize,
    /// Mean spread.
    pub mean_spread: f64,
    /// Fraction of rows whose |error| is at most the spread.
    pub within_one: f64,
    /// Fraction of rows whose |error| is at most twice the spread.
    pub within_two: f64,
    /// Pearson correlation of the spread and the |error| (0 when either does not vary).
    pub correlation: f64,
    /// Mean |error| of the quarter of rows with the largest spread.
    pub top_quarter_error: f64,
    /// Mean |error| of the other rows.
    pub rest_error: f64,
}

/// [`SpreadCheck`] of `(|error|, spread)` pairs (finite ones); `None` under 4 pairs.
pub fn spread_check(pairs: &[(f64, f64)]) -> Option<SpreadCheck> {
    let mut v: Vec<(f64, f64)> = pairs
        .iter()
        .copied()
        .filter(|(e, s)| e.is_finite() && s.is_finite())
        .collect();
    if v.len() < 4 {
        return None;
    }
    let n = v.len() as f64;
    let frac = |k: f64| v.iter().filter(|(e, s)| *e <= k * s).count() as f64 / n;
    let (within_one, within_two) = (frac(1.0), frac(2.0));
    let ms = v.iter().map(|p| p.1).sum::<f64>() / n;
    let correlation = pearson(&v);
    // Largest spread first; the top quarter at least one row.
    v.sort_by(|a, b| b.1.total_cmp(&a.1));
    let q = v.len().div_ceil(4);
    let mean = |p: &[(f64, f64)]| p.iter().map(|x| x.0).sum::<f64>() / p.len() as f64;
    Some(SpreadCheck {
        n: v.len(),
        mean_spread: ms,
        within_one,
        within_two,
        correlation,
        top_quarter_error: mean(&v[..q]),
        rest_error: mean(&v[q..]),
    })
}

/// Every target both tables have, and D when both have `x_mm` and `y_mm`.
#[derive(Clone, Debug, PartialEq)]
pub struct Evaluation {
    /// Per target, in the predictions' column order.
    pub targets: Vec<TargetEvaluation>,
    /// D, when both tables have contact positions and a row has both.
    pub distance_mm: Option<Distance>,
    /// Actual and estimated contact per matched row (for the contact map).
    pub map: Vec<MapPoint>,
    /// What was not scored and why: prediction rows without a label, rows without an
    /// estimate, prediction columns the labels lack.
    pub notes: Vec<String>,
}

/// Why there is nothing to evaluate.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum EvaluationError {
    /// A table does not read.
    #[error(transparent)]
    Read(#[from] TableError),
    /// No column of the predictions is a label.
    #[error("no target column of {predictions} is in {labels}")]
    NoTargets {
        /// The predictions' name.
        predictions: String,
        /// The labels' name.
        labels: String,
    },
}

/// Reads and evaluates a predictions table (`predict`'s output; a `flags` text column is
/// skipped) against a labels table, both keyed by `frame`.
pub fn evaluate_files(predictions: &Path, labels: &Path) -> Result<Evaluation, EvaluationError> {
    let mut torn = Vec::new();
    let p = KeyedTable::read_noting(predictions, &["flags"], &mut torn)?;
    let l = KeyedTable::read_noting(labels, &[], &mut torn)?;
    let mut e = evaluate(&p, &l).ok_or_else(|| EvaluationError::NoTargets {
        predictions: predictions.display().to_string(),
        labels: labels.display().to_string(),
    })?;
    e.notes.splice(0..0, torn);
    Ok(e)
}

/// Evaluates `p` against `l` on the rows whose `frame` both have; `None` when no column of
/// `p` is in `l` with a matched row.
pub fn evaluate(p: &KeyedTable, l: &KeyedTable) -> Option<Evaluation> {
    let by_key = l.rows_by_key();
    // (row of p, row of l) for every frame both have.
    let matched: Vec<(usize, usize)> = p
        .keys
        .iter()
        .enumerate()
        .filter_map(|(r, key)| by_key.get(key.as_str()).map(|&li| (r, li)))
        .collect();
    let targets: Vec<TargetEvaluation> = p
        .columns
        .iter()
        .enumerate()
        .filter_map(|(j, name)| {
            let lj = l.column(name)?;
            let pv: Vec<f64> = matched.iter().map(|&(r, _)| p.rows[r][j]).collect();
            let lv: Vec<f64> = matched.iter().map(|&(_, li)| l.rows[li][lj]).collect();
            let errors = target_errors(name, &pv, &lv);
            let points = lv
                .iter()
                .zip(&pv)
                .filter(|(t, e)| t.is_finite() && e.is_finite())
                .map(|(t, e)| (*t, *e))
                .collect();
            let spread = p.column(&format!("{name}_std")).and_then(|sj| {
                let pairs: Vec<(f64, f64)> = matched
                    .iter()
                    .zip(&lv)
                    .map(|(&(r, _), t)| ((p.rows[r][j] - t).abs(), p.rows[r][sj]))
                    .collect();
                spread_check(&pairs)
            });
            (errors.n > 0).then_some(TargetEvaluation {
                errors,
                points,
                spread,
            })
        })
        .collect();
    if targets.is_empty() {
        return None;
    }
    let mut map = Vec::new();
    let mut distances = Vec::new();
    let columns = (
        p.column("x_mm"),
        p.column("y_mm"),
        l.column("x_mm"),
        l.column("y_mm"),
    );
    if let (Some(xi), Some(yi), Some(lx), Some(ly)) = columns {
        let (pd, ld) = (p.column("depth_mm"), l.column("depth_mm"));
        let depth = |row: &[f64], c: Option<usize>| c.map_or(f64::NAN, |c| row[c]);
        for &(r, li) in &matched {
            let (pr, lr) = (&p.rows[r], &l.rows[li]);
            let d = (pr[xi] - lr[lx]).hypot(pr[yi] - lr[ly]);
            if d.is_finite() {
                distances.push(d);
                map.push((
                    [lr[lx], lr[ly], depth(lr, ld)],
                    [pr[xi], pr[yi], depth(pr, pd)],
                ));
            }
        }
    }
    let distance_mm = (!distances.is_empty()).then(|| Distance {
        mean: distances.iter().sum::<f64>() / distances.len() as f64,
        max: distances.iter().fold(0.0f64, |m, d| m.max(*d)),
    });
    let notes = coverage_notes(p, l, matched.len(), &targets);
    Some(Evaluation {
        targets,
        distance_mm,
        map,
        notes,
    })
}

/// What an evaluation left out, in counts: nothing is skipped without a word.
fn coverage_notes(
    p: &KeyedTable,
    l: &KeyedTable,
    matched: usize,
    targets: &[TargetEvaluation],
) -> Vec<String> {
    let mut notes = Vec::new();
    if matched < p.keys.len() {
        notes.push(format!(
            "{} of {} prediction rows have no label and were not scored",
            p.keys.len() - matched,
            p.keys.len()
        ));
    }
    for t in targets.iter().filter(|t| t.errors.n < matched) {
        notes.push(format!(
            "{}: {} of {matched} labelled rows have no estimate (or no label value) and were not scored",
            t.errors.target,
            matched - t.errors.n
        ));
    }
    for c in p.columns.iter().filter(|c| !c.ends_with("_std")) {
        if l.column(c).is_none() {
            notes.push(format!(
                "prediction column `{c}` is not in the labels: not scored"
            ));
        }
    }
    notes
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(columns: &[&str], rows: &[(&str, &[f64])]) -> KeyedTable {
        KeyedTable {
            columns: columns.iter().map(|c| c.to_string()).collect(),
            keys: rows.iter().map(|(k, _)| k.to_string()).collect(),
            rows: rows.iter().map(|(_, r)| r.to_vec()).collect(),
            text: vec![Vec::new(); rows.len()],
            dropped_partial_line: false,
        }
    }

    #[test]
    fn rows_are_matched_by_frame_and_d_is_the_planar_distance() {
        // Predictions for frames a, b, c (c has no label); labels in another order.
        let p = table(
            &["x_mm", "y_mm", "extra"],
            &[
                ("a", &[3.0, 4.0, 1.0]),
                ("b", &[1.0, 1.0, 1.0]),
                ("c", &[9.0, 9.0, 9.0]),
            ],
        );
        let l = table(
            &["y_mm", "x_mm", "depth_mm"],
            &[("b", &[1.0, 1.0, 2.0]), ("a", &[0.0, 0.0, 1.0])],
        );
        let e = evaluate(&p, &l).unwrap();
        assert_eq!(e.targets.len(), 2);
        assert_eq!(e.targets[0].errors.target, "x_mm");
        assert_eq!(e.targets[0].errors.n, 2);
        assert_eq!(e.targets[0].points, [(0.0, 3.0), (1.0, 1.0)]);
        let d = e.distance_mm.unwrap();
        assert_eq!((d.mean, d.max), (2.5, 5.0));
        assert_eq!(e.map[0].0, [0.0, 0.0, 1.0]);
        assert!(e.map[0].1[2].is_nan(), "the predictions have no depth");
        // What was not scored is said, in counts.
        assert_eq!(
            e.notes,
            [
                "1 of 3 prediction rows have no label and were not scored",
                "prediction column `extra` is not in the labels: not scored"
            ]
        );
        assert!(e.targets[0].spread.is_none(), "no x_mm_std column");
        // Nothing in common: no evaluation.
        let other = table(&["force_n"], &[("a", &[1.0])]);
        assert!(evaluate(&p, &other).is_none());
    }

    #[test]
    fn the_spread_check_counts_errors_within_one_and_two_spreads() {
        // |error|, spread: the two largest spreads hold the two largest errors.
        let pairs = [
            (0.1, 0.2),
            (0.3, 0.2),
            (0.5, 0.2),
            (2.0, 1.5),
            (4.0, 1.5),
            (0.05, 0.2),
            (f64::NAN, 1.0),
        ];
        let c = spread_check(&pairs).unwrap();
        assert_eq!(c.n, 6);
        assert!(
            (c.within_one - 2.0 / 6.0).abs() < 1e-12,
            "0.1 and 0.05: {c:?}"
        );
        assert!(
            (c.within_two - 4.0 / 6.0).abs() < 1e-12,
            "and 0.3 and 2.0: {c:?}"
        );
        assert!((c.mean_spread - 3.8 / 6.0).abs() < 1e-12);
        assert!(
            (c.top_quarter_error - 3.0).abs() < 1e-12,
            "2.0 and 4.0: {c:?}"
        );
        assert!((c.rest_error - 0.2375).abs() < 1e-12);
        assert!(c.correlation > 0.8, "{c:?}");
        assert!(spread_check(&pairs[..3]).is_none());
        // Read from tables: the column beside the target.
        let p = table(
            &["y_mm", "y_mm_std"],
            &[
                ("a", &[1.0, 0.5]),
                ("b", &[2.0, 0.5]),
                ("c", &[3.0, 2.0]),
                ("d", &[0.0, 0.1]),
            ],
        );
        let l = table(
            &["y_mm"],
            &[("a", &[1.2]), ("b", &[2.0]), ("c", &[0.0]), ("d", &[0.5])],
        );
        let s = evaluate(&p, &l).unwrap().targets[0].spread.unwrap();
        assert_eq!(s.n, 4);
        assert!((s.within_one - 0.5).abs() < 1e-12, "a and b: {s:?}");
        assert!(
            (s.within_two - 0.75).abs() < 1e-12,
            "c is 3 off at 2 (within two), d 0.5 off at 0.1: {s:?}"
        );
    }
}
