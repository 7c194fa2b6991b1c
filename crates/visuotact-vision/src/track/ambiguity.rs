//! Statuses from the energy: merges as a hypothesis, ambiguity as a margin.
//!
//! - **Merged**: a marker left without a blob whose prediction falls on a blob another marker
//!   holds (or that a blobless neighbour's prediction falls on too) is compared under two
//!   hypotheses — the blob is one marker's and the other is lost, or the blob holds both
//!   (its centroid at their predictions' area-weighted mean, its area their sum). When the
//!   pair costs at least the margin less, both are [`MarkerStatus::Merged`].
//! - **Ambiguous**: a matched marker is compared with its runners-up — taking another blob
//!   within its gate (a free one, or another marker's, that marker then taking its best
//!   alternative: its own next blob, a swap, or nothing) — and with the merge hypothesis for its
//!   blob. When one costs less than [`TrackParams::margin`](super::TrackParams::margin) more
//!   than the best, which blob is the marker's cannot be told: it is ambiguous (no position).
//!
//! Nothing else puts a marker in doubt.

use super::energy::Energy;
use super::index::dist;
use super::pieces::nearest_of;
use super::predict::Prediction;
use super::solve::Matching;
use super::MarkerStatus;
use crate::blobs::Blob;

/// Statuses and the merged markers' blobs.
pub(super) struct Classified {
    pub status: Vec<MarkerStatus>,
    /// Markers merged on each blob: (blob, marker, prediction).
    pub on_blob: Vec<(usize, usize, Prediction)>,
}

/// Where a blob holding both `i` and `k` is expected: their predictions' mean weighted by
/// their expected areas (returned too).
fn pair_centre(
    m: &Matching<'_>,
    (i, pi): (usize, Prediction),
    (k, pk): (usize, Prediction),
) -> ((f64, f64), f64, f64) {
    let areas = &m.reference.areas_px;
    let (ai, ak) = (
        areas[i] * pi.scale * pi.scale,
        areas[k] * pk.scale * pk.scale,
    );
    let w = ai + ak;
    let centre = (
        (ai * pi.at.0 + ak * pk.at.0) / w,
        (ai * pi.at.1 + ak * pk.at.1) / w,
    );
    (centre, ai, ak)
}

/// The cost of blob `j` holding both `i` and `k`.
fn pair_cost(
    m: &Matching<'_>,
    (i, pi): (usize, Prediction),
    (k, pk): (usize, Prediction),
    j: usize,
) -> f64 {
    let (centre, ai, ak) = pair_centre(m, (i, pi), (k, pk));
    let w = ai + ak;
    let b = &m.blobs[j];
    let d = (b.x_px - centre.0).hypot(b.y_px - centre.1);
    let e: &Energy<'_> = &m.energy;
    // A pair's blob has the area of two: here shrinking counts as much as growing.
    let area = if m.is_cut(j) {
        0.0
    } else {
        e.area_misfit(b, w).powi(2)
    };
    let elongation = if m.is_cut(j) {
        0.0
    } else {
        elongation_cost(e, b, (ai, pi.at), (ak, pk.at))
    };
    e.position_cost(i, d, &pi) + area + elongation
}

/// How unlike two markers of areas `ai`, `ak` predicted at `pi`, `pk` blob `b` is along the line
/// between them: two discs whose centres lie `s` apart have, along that line, the variance
/// `(ai² + ak²)/(4π(ai + ak)) + s²·ai·ak/(ai + ak)²`; the blob's, against it, with twice the
/// area's tolerance (a variance scales as an area). Squared, in tolerances.
pub(super) fn elongation_cost(
    e: &Energy<'_>,
    b: &Blob,
    (ai, pi): (f64, (f64, f64)),
    (ak, pk): (f64, (f64, f64)),
) -> f64 {
    let along = (pk.0 - pi.0, pk.1 - pi.1);
    let sep = along.0.hypot(along.1);
    if sep <= 0.0 {
        return 0.0;
    }
    let w = ai + ak;
    let u = (along.0 / sep, along.1 / sep);
    let var = b.mu20_px2 * u.0 * u.0 + 2.0 * b.mu11_px2 * u.0 * u.1 + b.mu02_px2 * u.1 * u.1;
    let expected =
        (ai * ai + ak * ak) / (4.0 * std::f64::consts::PI * w) + sep * sep * ai * ak / (w * w);
    (((var + 1.0 / 12.0) / expected).ln() / (2.0 * e.params.area_sigma)).powi(2)
}

/// What marker `k` (predicted `pk`, its [`Matching::predict_or_start`], now on `not`) can
/// do instead, relative to its cost now: another free blob (which stops being clutter),
/// `swap` (the blob the marker taking `not` gives up), or nothing. Returns the change and
/// whether it swapped.
fn instead(m: &Matching<'_>, k: usize, pk: Prediction, not: usize, swap: usize) -> (f64, bool) {
    let now = cost_of(m, k, pk, not);
    let clutter = m.energy.clutter_cost();
    let mut best = (m.energy.lost_cost_at(k, &pk) - now, false);
    m.each_candidate(k, |j, cost| {
        let c = if j == swap {
            (cost - now, true)
        } else if j != not && m.owner[j].is_none() && j < m.usable {
            (cost - clutter - now, false)
        } else {
            return;
        };
        if c.0 < best.0 {
            best = c;
        }
    });
    best
}

/// The cost of marker `i` (predicted `p`, its [`Matching::predict_or_start`]) taking blob
/// `j`: from its candidates when `j` is one of them.
fn cost_of(m: &Matching<'_>, i: usize, p: Prediction, j: usize) -> f64 {
    let mut cost = None;
    m.each_candidate(i, |j2, c| {
        if j2 == j {
            cost = Some(c);
        }
    });
    cost.unwrap_or_else(|| m.cost(i, p, j))
}

/// How much more than its current reading marker `i`'s best runner-up costs: `i` taking
/// another free blob, or another marker's blob (that marker doing its best instead), or
/// nothing; its blob then becomes clutter or goes to the blobless marker it suits best.
/// `preds` are every marker's [`Matching::predict_or_start`].
fn runner_up_margin(
    m: &Matching<'_>,
    i: usize,
    preds: &[Prediction],
    blobless: &[usize],
    pieces: &[(usize, usize)],
) -> f64 {
    let Some(j) = m.assignment[i] else {
        return f64::INFINITY;
    };
    let pi = preds[i];
    let c0 = cost_of(m, i, pi, j);
    let clutter = m.energy.clutter_cost();
    // What becomes of `j` once `i` leaves it.
    let mut left = clutter;
    let bj = (m.blobs[j].x_px, m.blobs[j].y_px);
    for &h in blobless {
        let ph = preds[h];
        if (bj.0 - ph.at.0).hypot(bj.1 - ph.at.1) <= m.energy.gate_px(h, &ph) {
            left = left.min(m.cost(h, ph, j) - m.energy.lost_cost_at(h, &ph));
        }
    }
    // Given up to a blobless marker only: dropping a blob nobody else wants is the energy's
    // own choice, not a rival reading.
    let mut margin = if left < clutter {
        m.energy.lost_cost_at(i, &pi) - c0 + left
    } else {
        f64::INFINITY
    };
    // Whether the marker's own blob lies nearer its prediction than any neighbour's (asked
    // only of a free blob near it).
    let mut own_cell: Option<bool> = None;
    m.each_candidate(i, |j2, cost| {
        if j2 == j || j2 >= m.usable {
            return;
        }
        let c1 = cost - c0;
        let extra = match m.owner[j2] {
            // A piece of the marker's own dot, or a free blob within the prediction's
            // uncertainty of its blob, both nearer its prediction than any neighbour's, with
            // no blobless marker to take its own: taking it moves the marker by less than its
            // position can be told, it does not change who the marker is.
            None if pieces.contains(&(j, j2))
                || (dist(m.index.pts[j2], bj) < m.energy.sigma_px(i, &pi)
                    && *own_cell.get_or_insert_with(|| nearest_of(m, i, preds, bj))
                    && nearest_of(m, i, preds, m.index.pts[j2])) =>
            {
                return
            }
            None => c1 - clutter + left,
            Some(k) => {
                let (change, swapped) = instead(m, k, preds[k], j2, j);
                c1 + change + if swapped { 0.0 } else { left }
            }
        };
        margin = margin.min(extra);
    });
    margin
}

/// The blobs blobless marker `i` may share, with the marker it would share each with: the one
/// nearest its prediction (its holder, or a blobless neighbour nearest it too), a free one
/// nearest the mean of its and a blobless neighbour's predictions, and those of its
/// neighbours within half again its gate (a hidden marker's prediction lags).
fn shared_blobs(
    m: &Matching<'_>,
    i: usize,
    preds: &[Prediction],
    nearest: &[Option<usize>],
) -> Vec<(usize, usize)> {
    let mut shared: Vec<(usize, usize)> = Vec::new();
    if let Some(j) = nearest[i] {
        let partner = m.owner[j].or_else(|| {
            m.reference.neighbours[i]
                .iter()
                .copied()
                .find(|&k| k > i && nearest[k] == Some(j))
        });
        shared.extend(partner.map(|k| (j, k)));
    }
    for &k in &m.reference.neighbours[i] {
        if k > i && m.assignment[k].is_none() {
            // Two blobless neighbours may share a free blob that lies between them, nearer
            // their predictions' area-weighted mean (where the pair's centroid is expected)
            // than either prediction.
            let (mean, _, _) = pair_centre(m, (i, preds[i]), (k, preds[k]));
            if let Some(j) = m.index.nearest(mean, m.energy.gate_px(i, &preds[i])) {
                if j < m.usable && m.owner[j].is_none() && !shared.contains(&(j, k)) {
                    shared.push((j, k));
                }
            }
        }
        if let Some(j) = m.assignment[k] {
            let b = (m.blobs[j].x_px, m.blobs[j].y_px);
            let d = (b.0 - preds[i].at.0).hypot(b.1 - preds[i].at.1);
            if d <= 1.5 * m.energy.gate_px(i, &preds[i]) && !shared.contains(&(j, k)) {
                shared.push((j, k));
            }
        }
    }
    shared
}

/// Classifies every marker of the final assignment.
pub(super) fn classify(
    m: &Matching<'_>,
    preds: &[Prediction],
    pieces: &[(usize, usize)],
) -> Classified {
    let n = m.assignment.len();
    let margin = m.energy.params.margin;
    let mut status: Vec<MarkerStatus> = m
        .assignment
        .iter()
        .map(|a| {
            if a.is_some() {
                MarkerStatus::Ok
            } else {
                MarkerStatus::Lost
            }
        })
        .collect();
    let mut on_blob = Vec::new();
    // The blob nearest each blobless marker's prediction, within its gate.
    let nearest: Vec<Option<usize>> = (0..n)
        .map(|i| {
            (m.assignment[i].is_none())
                .then(|| m.index.nearest(preds[i].at, m.energy.gate_px(i, &preds[i])))
                .flatten()
        })
        .collect();
    for i in 0..n {
        if m.assignment[i].is_some() {
            continue;
        }
        let lost_i = m.energy.lost_cost_at(i, &preds[i]);
        if lost_i <= 0.0 {
            continue;
        }
        let shared = shared_blobs(m, i, preds, &nearest);
        // Apart: `i` lost, or on the free blob that suits it best (no longer clutter).
        let mut alone_i = lost_i;
        m.index
            .near(preds[i].at, m.energy.gate_px(i, &preds[i]), |f, _| {
                if f < m.usable && m.owner[f].is_none() {
                    alone_i = alone_i.min(m.cost(i, preds[i], f) - m.energy.clutter_cost());
                }
            });
        // The pair reading that gains most against `i` and its partner apart.
        let best = shared
            .into_iter()
            .map(|(j, k)| {
                let apart = alone_i
                    + match m.assignment[k] {
                        Some(_) => m.cost(k, preds[k], j),
                        // The blob was clutter.
                        None => m.energy.unmatched_cost_at(k, &preds[k]),
                    };
                let together = pair_cost(m, (i, preds[i]), (k, preds[k]), j);
                (together - apart, j, k)
            })
            .min_by(|a, b| a.0.total_cmp(&b.0));
        let Some((gain, j, k)) = best else { continue };
        // A third marker whose prediction falls on the blob makes the pair itself uncertain.
        let third = (0..n).any(|x| x != i && x != k && nearest[x] == Some(j));
        if gain <= -margin && !third {
            for (q, p) in [(i, preds[i]), (k, preds[k])] {
                if !on_blob
                    .iter()
                    .any(|e: &(usize, usize, Prediction)| e.1 == q)
                {
                    on_blob.push((j, q, p));
                }
                status[q] = MarkerStatus::Merged;
            }
        } else if gain < margin && status[k] == MarkerStatus::Ok {
            // Whether the blob is one marker's or two's cannot be told.
            status[k] = MarkerStatus::Ambiguous;
        }
    }
    let blobless: Vec<usize> = (0..n)
        .filter(|&h| status[h] == MarkerStatus::Lost && m.energy.lost_cost_at(h, &preds[h]) > 0.0)
        .collect();
    for (i, st) in status.iter_mut().enumerate() {
        if *st == MarkerStatus::Ok && runner_up_margin(m, i, preds, &blobless, pieces) < margin {
            *st = MarkerStatus::Ambiguous;
        }
    }
    Classified { status, on_blob }
}
