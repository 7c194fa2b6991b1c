//! Held-out figures for slip detection: cross-validation by group (leave one group — one
//! object — out), with beside the detector the baselines a user would try first on the same
//! folds: a threshold on the largest mean marker displacement, and a logistic regression on a
//! published field statistic (the displacement entropy and its rate).

use visuotact_nn::logistic::{fit_logistic, LogisticConfig};

use super::{
    fit_detector, SequenceEvidence, SlipDetector, SlipError, SlipSettings, SlipTruth, EVIDENCE_LEN,
    START_FRAMES,
};

/// Index of `max_shift_pitches` in the evidence.
const MAX_SHIFT: usize = 0;
/// Indices of `max_entropy_nats` and `max_rate_entropy_nats`.
const ENTROPY: [usize; 2] = [5, 2 * super::SIGNALS + 5];

/// Accuracy figures of one classifier.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Scores {
    /// Sequences answered.
    pub answered: usize,
    /// Share of sequences classified right.
    pub accuracy: f64,
    /// Mean of the share of slip sequences found and the share of the others left alone.
    pub balanced_accuracy: f64,
}

impl Scores {
    /// The scores of `predicted` against `truth`.
    pub fn of(predicted: &[bool], truth: &[bool]) -> Self {
        let count = |p: bool, t: bool| {
            predicted
                .iter()
                .zip(truth)
                .filter(|&(&a, &b)| a == p && b == t)
                .count() as f64
        };
        let (tp, tn, fp, fn_) = (
            count(true, true),
            count(false, false),
            count(true, false),
            count(false, true),
        );
        let rate = |a: f64, b: f64| if a + b > 0.0 { a / (a + b) } else { 0.0 };
        Self {
            answered: predicted.len(),
            accuracy: rate(tp + tn, fp + fn_),
            balanced_accuracy: 0.5 * (rate(tp, fn_) + rate(tn, fp)),
        }
    }
}

/// What [`cross_validate`] measured.
#[derive(Clone, Debug, PartialEq)]
pub struct CrossValidation {
    /// Folds (groups).
    pub folds: usize,
    /// The detector fitted on the other groups.
    pub fitted: Scores,
    /// The naive baseline: the best threshold on the largest mean displacement.
    pub largest_shift: Scores,
    /// The displacement entropy and its rate, logistic regression.
    pub entropy: Scores,
    /// `default` as it is, on every sequence (not held out when it was fitted on them).
    pub default: Option<Scores>,
    /// Each sequence's held-out score from the fitted detector.
    pub held_out_scores: Vec<f64>,
    /// Share of the held-out beginnings (every second) of sequences without slip that the
    /// fitted detector scored as slip: the live false alarms.
    pub false_alarms: f64,
    /// Share of the held-out sequences whose start ([`SequenceEvidence::start`]) the fitted
    /// detector scored as slip: alarms as a grasp begins (none where it reads a sequence only
    /// from a later frame, [`SlipDetector::min_frames`]).
    pub start_alarms: f64,
}

/// Leave-one-group-out figures on the sequences' `evidence` labelled `truth`, in `groups`, of
/// detectors fitted with `settings` (and of `default` as it is).
pub fn cross_validate(
    evidence: &[SequenceEvidence],
    truth: &[SlipTruth],
    groups: &[String],
    settings: &SlipSettings,
    default: Option<&SlipDetector>,
) -> Result<CrossValidation, SlipError> {
    let slip: Vec<bool> = truth.iter().map(|t| t.slip).collect();
    let slip = &slip[..];
    let mut names: Vec<&String> = groups.iter().collect();
    names.sort();
    names.dedup();
    let n = evidence.len();
    let whole: Vec<[f64; EVIDENCE_LEN]> = evidence.iter().map(|e| e.whole).collect();
    let (mut fitted, mut shift, mut entropy) = (vec![false; n], vec![false; n], vec![false; n]);
    let mut held_out_scores = vec![0.0; n];
    let (mut alarms, mut beginnings, mut starts) = (0usize, 0usize, 0usize);
    for g in &names {
        let train: Vec<usize> = (0..n).filter(|&i| &groups[i] != *g).collect();
        let test: Vec<usize> = (0..n).filter(|&i| &groups[i] == *g).collect();
        let ev: Vec<_> = train.iter().map(|&i| evidence[i].clone()).collect();
        let y: Vec<bool> = train.iter().map(|&i| slip[i]).collect();
        let t: Vec<SlipTruth> = train.iter().map(|&i| truth[i]).collect();
        let d = fit_detector(&ev, &t, settings)?;
        let ev_whole: Vec<_> = train.iter().map(|&i| whole[i]).collect();
        let cut = best_threshold(
            &train
                .iter()
                .map(|&i| whole[i][MAX_SHIFT])
                .collect::<Vec<_>>(),
            &y,
        );
        let ent = small_logistic(&ev_whole, &y);
        for &i in &test {
            let frames = evidence[i].frames;
            held_out_scores[i] = d.live_score(&whole[i], frames);
            let start = d.live_score(&evidence[i].start, START_FRAMES.min(frames));
            starts += usize::from(start >= d.threshold);
            fitted[i] = held_out_scores[i] >= d.threshold;
            shift[i] = (whole[i][MAX_SHIFT] >= cut.0) == cut.1;
            entropy[i] = ent(&whole[i]);
            if !slip[i] {
                beginnings += evidence[i].prefixes.len();
                alarms += evidence[i]
                    .prefixes
                    .iter()
                    .filter(|p| d.score(p) >= d.threshold)
                    .count();
            }
        }
    }
    let by_default = default.map(|d| {
        let p: Vec<bool> = whole
            .iter()
            .zip(evidence)
            .map(|(w, e)| d.live_score(w, e.frames) >= d.threshold)
            .collect();
        Scores::of(&p, slip)
    });
    Ok(CrossValidation {
        folds: names.len(),
        fitted: Scores::of(&fitted, slip),
        largest_shift: Scores::of(&shift, slip),
        entropy: Scores::of(&entropy, slip),
        default: by_default,
        held_out_scores,
        false_alarms: alarms as f64 / beginnings.max(1) as f64,
        start_alarms: starts as f64 / n.max(1) as f64,
    })
}

/// The held-out figures of grasps seen by several sensors: each sequence takes its grasp's
/// [`super::fused_score`] of the held-out scores (`grasp_of[i]`: sequence `i`'s grasp), slip
/// at or above `threshold`. Every sequence of a grasp must be in the same fold (a group holds
/// whole grasps), as grouping by object gives.
pub fn fused_scores(
    cv: &CrossValidation,
    truth: &[SlipTruth],
    grasp_of: &[usize],
    threshold: f64,
) -> Scores {
    let n = cv.held_out_scores.len();
    let predicted: Vec<bool> = (0..n)
        .map(|i| {
            let same = (0..n).filter(|&j| grasp_of[j] == grasp_of[i]);
            super::fused_score(same.map(|j| cv.held_out_scores[j])) >= threshold
        })
        .collect();
    let slip: Vec<bool> = truth.iter().map(|t| t.slip).collect();
    Scores::of(&predicted, &slip)
}

/// The threshold on `x` (and whether slip lies at or above it) of best balanced accuracy.
fn best_threshold(x: &[f64], y: &[bool]) -> (f64, bool) {
    let mut cuts: Vec<f64> = x.to_vec();
    cuts.sort_by(f64::total_cmp);
    let mut best = (f64::NEG_INFINITY, (0.0, true));
    for w in cuts.windows(2) {
        let c = 0.5 * (w[0] + w[1]);
        for above in [true, false] {
            let p: Vec<bool> = x.iter().map(|&v| (v >= c) == above).collect();
            let b = Scores::of(&p, y).balanced_accuracy;
            if b > best.0 {
                best = (b, (c, above));
            }
        }
    }
    best.1
}

/// A logistic regression on the entropy statistics of `ev`, standardised on them.
fn small_logistic(ev: &[[f64; EVIDENCE_LEN]], y: &[bool]) -> impl Fn(&[f64; EVIDENCE_LEN]) -> bool {
    let n = ev.len().max(1) as f64;
    let stats: Vec<(f64, f64)> = ENTROPY
        .iter()
        .map(|&j| {
            let m = ev.iter().map(|e| e[j]).sum::<f64>() / n;
            let s = (ev.iter().map(|e| (e[j] - m).powi(2)).sum::<f64>() / n).sqrt();
            (m, if s > 1e-18 { s } else { 1.0 })
        })
        .collect();
    let row = move |e: &[f64; EVIDENCE_LEN]| -> Vec<f64> {
        ENTROPY
            .iter()
            .zip(&stats)
            .map(|(&j, (m, s))| (e[j] - m) / s)
            .collect()
    };
    let rows: Vec<Vec<f64>> = ev.iter().map(&row).collect();
    let fit = fit_logistic(&rows, y, &LogisticConfig::default());
    move |e| fit.probability(&row(e)) >= 0.5
}

/// The cross-validation as a table, one row per sequence: `video,slip,group,frames,held_out_score`
/// and the 33 statistics of its evidence ([`super::SlipEvidence::names`]), to see which
/// sequences the held-out detector gets wrong and why.
pub fn cv_table(
    rows: &[(&std::path::Path, &SlipTruth, &str, usize)],
    cv: &CrossValidation,
    evidence: &[SequenceEvidence],
) -> String {
    use std::fmt::Write as _;
    let mut s = String::from("video,slip,group,frames,held_out_score");
    for n in super::SlipEvidence::names() {
        let _ = write!(s, ",{n}");
    }
    s.push('\n');
    for ((&(video, truth, group, frames), score), e) in
        rows.iter().zip(&cv.held_out_scores).zip(evidence)
    {
        let _ = write!(
            s,
            "{},{},{group},{frames},{score:.6}",
            video.display(),
            u8::from(truth.slip)
        );
        for v in e.whole {
            let _ = write!(s, ",{v:.6}");
        }
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn balanced_accuracy_weighs_both_classes() {
        let t = [true, true, false, false, false, false];
        let s = Scores::of(&[true, false, false, false, false, false], &t);
        assert!((s.accuracy - 5.0 / 6.0).abs() < 1e-12);
        assert!((s.balanced_accuracy - 0.75).abs() < 1e-12);
        assert_eq!(Scores::of(&[false; 6], &t).balanced_accuracy, 0.5);
    }

    #[test]
    fn the_threshold_baseline_finds_the_cut_and_its_side() {
        let x = [0.1, 0.2, 0.3, 0.9, 1.0, 1.1];
        let y = [true, true, true, false, false, false];
        let (c, above) = best_threshold(&x, &y);
        assert!(!above && (c - 0.6).abs() < 1e-12, "{c} {above}");
    }
}
