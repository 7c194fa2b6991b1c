//! Prediction: where each marker should be, from the markers already held.
//!
//! The skin's motion is smooth, so around any marker it is affine to first order (a press
//! expands, a drag shears, a twist rotates). A marker's position is predicted from a weighted
//! least-squares affine fit of its matched neighbours' displacements (translation plus a 2 × 2
//! gradient, ridge-damped towards a pure translation when the neighbours are few or on one
//! side); the fit's determinant gives the local magnification, which scales the gate and the
//! expected blob area. The neighbours are the reference layout's (its 12 nearest within 2.5
//! spacings): the lattice's topology, known at calibration, carries the prediction across a
//! field stretched by pitches, as a person reads it neighbour by neighbour.
//!
//! Before anything is held, a starting motion: order-free, the overall motion of the still
//! majority (a vote histogram of each marker's nearest blob); followed, the last frame's
//! positions.

use std::sync::Arc;

use super::index::{nearest_centroid, BlobIndex};
use super::TrackReference;

/// A prediction: position, local magnification and how far the neighbours it comes from
/// stray from one affine motion.
#[derive(Clone, Copy, Debug)]
pub(super) struct Prediction {
    /// Where the marker should be, pixels.
    pub at: (f64, f64),
    /// Local magnification.
    pub scale: f64,
    /// RMS residual of the neighbours' displacements about the fitted affine motion, pixels.
    pub spread_px: f64,
    /// Where the starting motion puts the marker (its anchor moved by the registration's
    /// shift), pixels: the origin of the motion prior.
    pub start: (f64, f64),
}

/// How many step directions the lattice has and, per marker, its neighbour one step along each.
pub(super) type LatticeSteps = (usize, Vec<Vec<Option<usize>>>);

/// A local affine motion model around one marker.
#[derive(Clone, Copy, Debug)]
pub(super) struct LocalMotion {
    /// Predicted displacement of the marker from its anchor.
    pub disp: (f64, f64),
    /// Local magnification `sqrt(|det(I + G)|)`, clamped to 0.5..2.
    pub scale: f64,
    /// Weighted RMS residual of the neighbours' displacements about the fit, pixels: how far
    /// the motion around the marker is from affine (0 for a rigid or uniformly stretched
    /// patch; a pitch where a drag shears the skin within a spacing).
    pub spread_px: f64,
}

/// Each marker's neighbours with their offsets from it before the motion (`anchors`) and
/// their weights in its affine fit, `1 / (|o|² + s²/4)` (`s` its spacing): fixed for a frame,
/// computed once.
#[derive(Debug)]
pub(super) struct Around {
    /// Where marker `i`'s entries start in `items` (`n + 1` offsets).
    start: Vec<usize>,
    /// (neighbour, offset, weight).
    items: Vec<(usize, (f64, f64), f64)>,
}

impl Around {
    /// Around `anchors`: the reference's own at rest ([`TrackReference`] computes them once),
    /// otherwise afresh.
    pub fn new(reference: &TrackReference, anchors: &[(f64, f64)]) -> Arc<Self> {
        if anchors == reference.positions.as_slice() {
            return Arc::clone(&reference.rest_around);
        }
        Arc::new(Self::from_parts(
            anchors,
            &reference.neighbours,
            &reference.spacing_px,
        ))
    }

    /// Around `anchors` with the layout's `neighbours` and `spacing_px`.
    pub fn from_parts(
        anchors: &[(f64, f64)],
        neighbours: &[Vec<usize>],
        spacing_px: &[f64],
    ) -> Self {
        let mut start = Vec::with_capacity(anchors.len() + 1);
        let mut items = Vec::new();
        for (i, ai) in anchors.iter().enumerate() {
            start.push(items.len());
            let s = spacing_px[i];
            items.extend(neighbours[i].iter().map(|&k| {
                let o = (anchors[k].0 - ai.0, anchors[k].1 - ai.1);
                (k, o, 1.0 / (o.0 * o.0 + o.1 * o.1 + 0.25 * s * s))
            }));
        }
        start.push(items.len());
        Self { start, items }
    }

    /// Marker `i`'s neighbours: (neighbour, offset, weight).
    pub fn of(&self, i: usize) -> &[(usize, (f64, f64), f64)] {
        &self.items[self.start[i]..self.start[i + 1]]
    }
}

/// Weighted least-squares affine fit of the displacements `disp` of the matched neighbours of
/// `i` (`around` their offsets and weights), ridge-damped towards a translation; the marker
/// itself never takes part (leave-one-out).
pub(super) fn local_motion(
    i: usize,
    reference: &TrackReference,
    around: &Around,
    matched: impl Fn(usize) -> bool,
    disp: &[(f64, f64)],
) -> Option<LocalMotion> {
    let s = reference.spacing_px[i];
    // Normal equations for [t, g1, g2] per axis: Σ w [1 o][1 o]ᵀ + diag(0, λ, λ).
    let (mut m00, mut m01, mut m02, mut m11, mut m12, mut m22) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut bx0, mut bx1, mut bx2) = (0.0, 0.0, 0.0);
    let (mut by0, mut by1, mut by2) = (0.0, 0.0, 0.0);
    let mut count = 0;
    // Each matched neighbour's offset from `i`, weight and displacement.
    let around = || {
        around
            .of(i)
            .iter()
            .filter(|e| matched(e.0))
            .map(|&(k, o, w)| (o, w, disp[k]))
    };
    for (o, w, u) in around() {
        m00 += w;
        m01 += w * o.0;
        m02 += w * o.1;
        m11 += w * o.0 * o.0;
        m12 += w * o.0 * o.1;
        m22 += w * o.1 * o.1;
        bx0 += w * u.0;
        bx1 += w * u.0 * o.0;
        bx2 += w * u.0 * o.1;
        by0 += w * u.1;
        by1 += w * u.1 * o.0;
        by2 += w * u.1 * o.1;
        count += 1;
    }
    if count == 0 {
        return None;
    }
    // Ridge: a third of a typical neighbour's leverage.
    let lambda = 0.3 * m00 * s * s;
    m11 += lambda;
    m22 += lambda;
    // Solve the symmetric 3 × 3 system by cofactors.
    let c00 = m11 * m22 - m12 * m12;
    let c01 = m02 * m12 - m01 * m22;
    let c02 = m01 * m12 - m02 * m11;
    let c11 = m00 * m22 - m02 * m02;
    let c12 = m01 * m02 - m00 * m12;
    let c22 = m00 * m11 - m01 * m01;
    let det = m00 * c00 + m01 * c01 + m02 * c02;
    if det.is_nan() || det.abs() <= 1e-300 {
        return None;
    }
    let solve = |b0: f64, b1: f64, b2: f64| {
        (
            (c00 * b0 + c01 * b1 + c02 * b2) / det,
            (c01 * b0 + c11 * b1 + c12 * b2) / det,
            (c02 * b0 + c12 * b1 + c22 * b2) / det,
        )
    };
    let (tx, gxx, gxy) = solve(bx0, bx1, bx2);
    let (ty, gyx, gyy) = solve(by0, by1, by2);
    let jac = (1.0 + gxx) * (1.0 + gyy) - gxy * gyx;
    // Residuals about the fit, weighted as the fit was; with fewer than four neighbours the
    // affine fit explains them by construction: no evidence of spread.
    let mut spread = 0.0;
    if count >= 4 {
        let (mut sw, mut sr) = (0.0, 0.0);
        for (o, w, u) in around() {
            let rx = u.0 - (tx + gxx * o.0 + gxy * o.1);
            let ry = u.1 - (ty + gyx * o.0 + gyy * o.1);
            sw += w;
            sr += w * (rx * rx + ry * ry);
        }
        spread = (sr / sw).sqrt();
    }
    Some(LocalMotion {
        disp: (tx, ty),
        scale: jac.abs().sqrt().clamp(0.5, 2.0),
        spread_px: spread,
    })
}

/// Overall motion of the still majority: each marker votes for the displacement of the blob
/// nearest to it (within 1.5 pitches), and the densest cell of the vote histogram, refined by
/// the mean of its votes, wins; ties go to the smallest motion. Only a starting point: a field
/// moved by pitches is followed from there by the growth and the lattice-offset search.
pub(super) fn register(reference: &TrackReference, index: &BlobIndex) -> (f64, f64) {
    let p = reference.pitch_px;
    let range = 1.5 * p;
    let cell = p / 4.0;
    let nb = (2.0 * range / cell).ceil() as usize + 1;
    let mut votes = vec![0u32; nb * nb];
    let mut picks: Vec<(f64, f64)> = Vec::with_capacity(reference.positions.len());
    for &m in &reference.positions {
        if let Some(j) = index.nearest(m, range) {
            let q = index.pts[j];
            let d = (q.0 - m.0, q.1 - m.1);
            // `as usize` saturates negatives to 0, as their floor would.
            let bx = ((d.0 + range) / cell) as usize;
            let by = ((d.1 + range) / cell) as usize;
            if bx < nb && by < nb {
                votes[by * nb + bx] += 1;
                picks.push(d);
            }
        }
    }
    // Densest 2 × 2 block (a vote cloud straddling a cell edge is not split).
    let mut best = (0u32, f64::INFINITY, 0.0, 0.0);
    for by in 0..nb.saturating_sub(1) {
        for bx in 0..nb.saturating_sub(1) {
            let s = votes[by * nb + bx]
                + votes[by * nb + bx + 1]
                + votes[(by + 1) * nb + bx]
                + votes[(by + 1) * nb + bx + 1];
            let cx = (bx as f64 + 1.0) * cell - range;
            let cy = (by as f64 + 1.0) * cell - range;
            let r = cx * cx + cy * cy;
            if s > best.0 || (s == best.0 && r < best.1) {
                best = (s, r, cx, cy);
            }
        }
    }
    if best.0 == 0 {
        return (0.0, 0.0);
    }
    let (cx, cy) = (best.2, best.3);
    let inliers: Vec<&(f64, f64)> = picks
        .iter()
        .filter(|d| (d.0 - cx).abs() <= cell && (d.1 - cy).abs() <= cell)
        .collect();
    let k = inliers.len() as f64;
    (
        inliers.iter().map(|d| d.0).sum::<f64>() / k,
        inliers.iter().map(|d| d.1).sum::<f64>() / k,
    )
}

/// Where each marker starts from the last frame's positions `p`: its own, or for a marker the
/// last frame did not have, where the local affine motion of its neighbours since the
/// reference puts it (the reference position when none of them was seen either).
pub(super) fn anchors_from_prior(
    reference: &TrackReference,
    p: &[Option<(f64, f64)>],
) -> Vec<(f64, f64)> {
    let rest = &reference.positions;
    let moved: Vec<(f64, f64)> = rest
        .iter()
        .zip(p)
        .map(|(r, q)| q.map_or((0.0, 0.0), |q| (q.0 - r.0, q.1 - r.1)))
        .collect();
    let around = Around::new(reference, rest);
    (0..rest.len())
        .map(|i| {
            p[i].unwrap_or_else(|| {
                local_motion(i, reference, &around, |k| p[k].is_some(), &moved)
                    .map_or(rest[i], |m| (rest[i].0 + m.disp.0, rest[i].1 + m.disp.1))
            })
        })
        .collect()
}

/// Lattice steps of markers without a numbered lattice (a hexagonal array takes its own,
/// [`super::TrackReference::take_lattice`]): the directions of the first ring of neighbours
/// around the marker nearest the layout's centre (four on a grid), each taken both ways (and
/// the ring widened up to 1.9 spacings while that gives fewer than four), as unit-spacing
/// vectors in turn around the circle, and per marker the neighbour one step away in each
/// (`None` at the layout's edge, or where none lies within 25° of the step and 1.9 spacings).
pub(super) fn lattice_steps(
    positions: &[(f64, f64)],
    neighbours: &[Vec<usize>],
    spacing_px: &[f64],
) -> LatticeSteps {
    let n = positions.len();
    if n < 3 {
        return (0, vec![Vec::new(); n]);
    }
    let centre = nearest_centroid(positions).unwrap_or(0);
    let s0 = spacing_px[centre];
    let max_turn = 25f64.to_radians();
    // Whether two directions (vectors) lie within `max_turn` of each other.
    let within = |a: (f64, f64), b: (f64, f64)| {
        let turn = (a.1.atan2(a.0) - b.1.atan2(b.0) + std::f64::consts::PI)
            .rem_euclid(std::f64::consts::TAU)
            - std::f64::consts::PI;
        turn.abs() < max_turn
    };
    // The central marker's neighbours within 1.3 spacings, each step taken both ways; where
    // that leaves fewer than four steps (two axes both ways; a reference taken in contact,
    // stretched across the centre), within up to 1.9 spacings: a reading shifted along any
    // axis must be shiftable back.
    let mut dirs: Vec<(f64, f64)> = Vec::new();
    for reach in [1.3, 1.6, 1.9] {
        dirs = neighbours[centre]
            .iter()
            .map(|&k| {
                (
                    (positions[k].0 - positions[centre].0) / s0,
                    (positions[k].1 - positions[centre].1) / s0,
                )
            })
            .filter(|d| d.0.hypot(d.1) < reach)
            .take(8)
            .collect();
        for k in 0..dirs.len() {
            let back = (-dirs[k].0, -dirs[k].1);
            if !dirs.iter().any(|&d| within(d, back)) {
                dirs.push(back);
            }
        }
        if dirs.len() >= 4 {
            break;
        }
    }
    // In turn around the circle: consecutive steps span the lattice's cells.
    dirs.sort_by(|a, b| a.1.atan2(a.0).total_cmp(&b.1.atan2(b.0)));
    // Per marker, the nearest neighbour (within 1.9 spacings) whose direction is within 25°
    // of each step's: a wide-angle lens shrinks the lattice towards the rim more across than
    // along the radius, so a step may be well over the nearest spacing.
    let steps = (0..n)
        .map(|i| {
            let s = spacing_px[i];
            dirs.iter()
                .map(|&d| {
                    neighbours[i]
                        .iter()
                        .filter_map(|&q| {
                            let o = (
                                positions[q].0 - positions[i].0,
                                positions[q].1 - positions[i].1,
                            );
                            let len = o.0.hypot(o.1);
                            (len < 1.9 * s && within(o, d)).then_some((q, len))
                        })
                        .min_by(|a, b| a.1.total_cmp(&b.1))
                        .map(|(q, _)| q)
                })
                .collect()
        })
        .collect();
    (dirs.len(), steps)
}

#[cfg(test)]
mod tests {
    use super::super::TrackReference;

    /// A grid stretched half as far again across its rows as along them (a reference taken
    /// under a drag): the central marker's neighbours within 1.3 spacings lie along the rows
    /// only. The steps still span both axes, each both ways, so that a reading shifted a row
    /// or a column either way can be shifted back.
    #[test]
    fn a_stretched_reference_keeps_both_axes_both_ways() {
        let positions: Vec<(f64, f64)> = (0..7)
            .flat_map(|r| (0..7).map(move |c| (10.0 * f64::from(c), 15.0 * f64::from(r))))
            .collect();
        let r = TrackReference::new(positions.clone(), vec![12.0; positions.len()]);
        assert_eq!(r.lattice_dirs, 4);
        let centre = 3 * 7 + 3;
        let mut to: Vec<(i64, i64)> = r.lattice_steps[centre]
            .iter()
            .map(|k| {
                let k = k.expect("the centre has a neighbour every way");
                let d = (
                    positions[k].0 - positions[centre].0,
                    positions[k].1 - positions[centre].1,
                );
                ((d.0 / 10.0).round() as i64, (d.1 / 15.0).round() as i64)
            })
            .collect();
        to.sort_unstable();
        assert_eq!(to, [(-1, 0), (0, -1), (0, 1), (1, 0)]);
        // A corner has no neighbour beyond the grid's edge.
        assert_eq!(r.lattice_steps[0].iter().filter(|k| k.is_none()).count(), 2);
    }
}
