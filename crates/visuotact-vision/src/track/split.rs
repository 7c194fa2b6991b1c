//! Two markers on one blob, split by the blob's second moments; markers on cut blobs.

use super::ambiguity::elongation_cost;
use super::energy::{outline_noise, shape_cost};
use super::index::dist;
use super::predict::Prediction;
use super::solve::Matching;
use super::MarkerStatus;

/// Splits each blob holding exactly two merged markers (`on_blob`: blob, marker, prediction)
/// along its major axis as two discs of the markers' areas scaled by their magnification
/// ([`Blob::two_discs`](crate::blobs::Blob::two_discs); ≈ 0.4 px from the truth for
/// two touching discs of radius 10 px). Each split marker takes its side (the side its
/// prediction lies on) when the blob has the pair's area within one area tolerance (else the
/// moments are not two discs'), both positions lie within their markers' gates, the blob is as
/// long along the pair as two markers at their predicted separation (within the margin) or
/// shows a waist between two lobes (within one shape tolerance), and the pair read the other way round costs at least the margin more: it is
/// [`MarkerStatus::Split`], with a position and no area.
pub(super) fn split_pairs(
    m: &Matching<'_>,
    on_blob: &mut [(usize, usize, Prediction)],
    status: &mut [MarkerStatus],
) -> Vec<Option<(f64, f64)>> {
    let mut out: Vec<Option<(f64, f64)>> = Vec::new();
    on_blob.sort_by_key(|e| (e.0, e.1));
    for group in on_blob.chunk_by(|a, b| a.0 == b.0) {
        let [(j, i1, r1), (_, i2, r2)] = *group else {
            continue;
        };
        let (p1, s1, p2, s2) = (r1.at, r1.scale, r2.at, r2.scale);
        if m.is_cut(j) {
            continue;
        }
        let areas = &m.reference.areas_px;
        let b = &m.blobs[j];
        let (a1, a2) = (areas[i1] * s1 * s1, areas[i2] * s2 * s2);
        let a = a1 + a2;
        // The moments are those of two discs only when the blob has their two areas.
        let Some((d, u)) = b.two_discs(a1, a2) else {
            continue;
        };
        if m.energy.area_misfit(b, a).abs() > 1.0 {
            continue;
        }
        // Marker 1 on the +u side if its prediction is.
        let sign = if (p1.0 - p2.0) * u.0 + (p1.1 - p2.1) * u.1 >= 0.0 {
            1.0
        } else {
            -1.0
        };
        let c = (b.x_px, b.y_px);
        let q1 = (
            c.0 + sign * (a2 / a) * d * u.0,
            c.1 + sign * (a2 / a) * d * u.1,
        );
        let q2 = (
            c.0 - sign * (a1 / a) * d * u.0,
            c.1 - sign * (a1 / a) * d * u.1,
        );
        // Each half within its marker's gate, as any blob it takes.
        let near = |q: (f64, f64), r: &Prediction, i: usize| {
            m.energy.position_cost(i, dist(q, r.at), r) <= m.energy.gate_cost()
        };
        if !(near(q1, &r1, i1) && near(q2, &r2, i2)) {
            continue;
        }
        // Two markers much nearer together than predicted are a pair only with a waist
        // between them (the blob fills its ellipse less than one marker by over one
        // tolerance); a blob filling its ellipse may be one marker stretched, its partner
        // hidden elsewhere.
        let waist = shape_cost(b, a1.min(a2), m.reference.fill_sigma) > 1.0;
        let as_predicted =
            elongation_cost(&m.energy, b, (a1, p1), (a2, p2)) <= m.energy.params.margin;
        if !(waist || as_predicted) {
            continue;
        }
        // Which of the two is on which side must be clear by the margin: under a deep press
        // the predictions of a squeezed pair can cross.
        let e = &m.energy;
        let at = |i: usize, q: (f64, f64), r: &Prediction| e.position_cost(i, dist(q, r.at), r);
        let kept = at(i1, q1, &r1) + at(i2, q2, &r2);
        let swapped = at(i1, q2, &r1) + at(i2, q1, &r2);
        if swapped - kept < e.params.margin {
            continue;
        }
        if out.is_empty() {
            out = vec![None; status.len()];
        }
        for (i, q) in [(i1, q1), (i2, q2)] {
            out[i] = Some(q);
            status[i] = MarkerStatus::Split;
        }
    }
    out
}

/// A marker reported [`MarkerStatus::Ok`] on a blob cut by the border, or on a blob within its
/// radius of a circular view's rim, is partly out of view and its centroid is not its own: lost,
/// unless the blob's area is the whole marker's (its rest area swollen as its neighbours' blobs
/// are, median) within the pixel noise of its outline — it then only touches the edge.
pub(super) fn lose_cut(m: &Matching<'_>, status: &mut [MarkerStatus]) {
    for (i, st) in status.iter_mut().enumerate() {
        let Some(j) = m.assignment[i] else {
            continue;
        };
        let b = &m.blobs[j];
        let radius = (m.reference.areas_px[i] / std::f64::consts::PI).sqrt();
        // The rectangle's edge cuts blobs into the detector's cut list (or keeps them whole
        // when asked to); a circular view's rim cuts them here.
        let at_edge = m
            .energy
            .view
            .and_then(|v| v.circle)
            .is_some_and(|(c, r)| r - dist((b.x_px, b.y_px), c) < radius);
        if *st != MarkerStatus::Ok || !(m.is_cut(j) || at_edge) {
            continue;
        }
        // As big as its neighbours are now, relative to their rest (the light and the
        // magnification swell them alike).
        let mut swell: Vec<f64> = m.reference.neighbours[i]
            .iter()
            .filter_map(|&k| {
                m.assignment[k]
                    .filter(|&jk| !m.is_cut(jk))
                    .map(|jk| (k, jk))
            })
            .map(|(k, jk)| f64::from(m.blobs[jk].area_px) / m.reference.areas_px[k])
            .collect();
        swell.sort_by(f64::total_cmp);
        let expected = m.reference.areas_px[i] * swell.get(swell.len() / 2).unwrap_or(&1.0);
        let ratio = f64::from(b.area_px.max(1)) / expected;
        if ratio.ln().abs() > outline_noise(expected) {
            *st = MarkerStatus::Lost;
        }
    }
}
