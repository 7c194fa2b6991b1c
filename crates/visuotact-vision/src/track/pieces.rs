//! One marker in pieces: a dot broken by the threshold, or by a line drawn across it.
//!
//! A free blob (no marker's, not cut by the border) is a piece of marker `i` when it lies, like
//! `i`'s own blob, nearer `i`'s prediction than any neighbour's, the two fit within one disc
//! of `i`'s expected area (their centroids' distance plus their radii within its diameter, the
//! radius allowed one area tolerance), and `i` taking both as one blob costs less than `i`
//! taking its own with the piece left as clutter: the energy's own choice between the two
//! readings (the pieces' union pays no shape term: the gap that broke them lies between them).
//! The marker is then measured on its pieces together ([`Blob::union`]); a piece is never
//! another marker's runner-up.

use super::index::dist;
use super::predict::Prediction;
use super::solve::Matching;
use crate::blobs::Blob;

/// Whether point `p` is nearer marker `i`'s prediction than any of its neighbours'.
pub(super) fn nearest_of(m: &Matching<'_>, i: usize, preds: &[Prediction], p: (f64, f64)) -> bool {
    let d = dist(p, preds[i].at);
    m.reference.neighbours[i]
        .iter()
        .all(|&k| dist(p, preds[k].at) > d)
}

/// Every marker's further pieces: (the marker's blob, a piece), at most two pieces a marker.
pub(super) fn find_pieces(m: &Matching<'_>, preds: &[Prediction]) -> Vec<(usize, usize)> {
    pieces_and_gain(m, preds).0
}

/// [`find_pieces`], and the energy they save: each marker measured on its pieces together
/// instead of its own blob with the pieces left as clutter.
pub(super) fn pieces_and_gain(
    m: &Matching<'_>,
    preds: &[Prediction],
) -> (Vec<(usize, usize)>, f64) {
    let mut saved = 0.0;
    let mut pieces = Vec::new();
    // A piece is a free blob: without one, there is none to look for.
    if (0..m.usable).all(|j| m.owner[j].is_some()) {
        return (pieces, saved);
    }
    let mut used = vec![false; m.blobs.len()];
    let clutter = m.energy.clutter_cost();
    let radius = |a: f64| (a / std::f64::consts::PI).sqrt();
    for (i, p) in preds.iter().enumerate() {
        let Some(j) = m.assignment[i].filter(|&j| !m.is_cut(j)) else {
            continue;
        };
        let mut whole = m.blobs[j];
        let expected = m.reference.areas_px[i] * p.scale * p.scale;
        let disc = 2.0 * radius(expected) * m.energy.params.area_sigma.exp();
        for k in 0..2 {
            // The marker's cost as it stands, computed only once a piece is in reach (the
            // energy asks this of every marker in every reading it compares).
            let mut now = None;
            let mut best: Option<(f64, usize, Blob)> = None;
            m.index.near(p.at, m.energy.gate_px(i, p), |j2, _| {
                if j2 >= m.usable || m.owner[j2].is_some() || used[j2] {
                    return;
                }
                let b2 = &m.blobs[j2];
                let span = dist((whole.x_px, whole.y_px), (b2.x_px, b2.y_px))
                    + radius(f64::from(whole.area_px))
                    + radius(f64::from(b2.area_px));
                if span > disc || !nearest_of(m, i, preds, (b2.x_px, b2.y_px)) {
                    return;
                }
                let now = *now.get_or_insert_with(|| {
                    if k == 0 {
                        m.energy.cost(i, p, &whole, false)
                    } else {
                        m.energy.pieces_cost(i, p, &whole)
                    }
                });
                let both = whole.union(b2);
                let gain = now + clutter - m.energy.pieces_cost(i, p, &both);
                if gain > 0.0 && best.as_ref().is_none_or(|b| gain > b.0) {
                    best = Some((gain, j2, both));
                }
            });
            let Some((gain, j2, both)) = best else { break };
            saved += gain;
            used[j2] = true;
            pieces.push((j, j2));
            whole = both;
        }
    }
    (pieces, saved)
}
