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
    // Normal equations for [t, g1, g2] per axis: Σ w [1 o][1 o]ᵀ + diag(0, λ, λ); with the
    // weighted squares of the displacements, the residuals' sum in the same pass. The
    // displacements are taken relative to the first neighbour's (a translation, which the
    // fit absorbs), so that the squares stay small beside the residuals.
    let (mut m00, mut m01, mut m02, mut m11, mut m12, mut m22) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut bx0, mut bx1, mut bx2) = (0.0, 0.0, 0.0);
    let (mut by0, mut by1, mut by2) = (0.0, 0.0, 0.0);
    let (mut uxx, mut uyy) = (0.0, 0.0);
    let mut origin = None;
    let mut count = 0;
    for &(k, o, w) in around.of(i) {
        if !matched(k) {
            continue;
        }
        let c = *origin.get_or_insert(disp[k]);
        let u = (disp[k].0 - c.0, disp[k].1 - c.1);
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
        uxx += w * u.0 * u.0;
        uyy += w * u.1 * u.1;
        count += 1;
    }
    // No neighbour held: no prediction.
    let c = origin?;
    // Ridge: a third of a typical neighbour's leverage.
    let lambda = 0.3 * m00 * s * s;
    let (r11, r22) = (m11 + lambda, m22 + lambda);
    // Solve the symmetric 3 × 3 system by cofactors.
    let c00 = r11 * r22 - m12 * m12;
    let c01 = m02 * m12 - m01 * r22;
    let c02 = m01 * m12 - m02 * r11;
    let c11 = m00 * r22 - m02 * m02;
    let c12 = m01 * m02 - m00 * m12;
    let c22 = m00 * r11 - m01 * m01;
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
    // Residuals about the fit, weighted as the fit was (Σ w (u − aᵀφ)² = Σ w u² − 2 aᵀb +
    // aᵀ M a, M without the ridge); with fewer than four neighbours the affine fit explains
    // them by construction: no evidence of spread.
    let mut spread = 0.0;
    if count >= 4 {
        let residual = |(t, g1, g2): (f64, f64, f64), (b0, b1, b2): (f64, f64, f64), uu: f64| {
            let quad = t * (m00 * t + 2.0 * (m01 * g1 + m02 * g2))
                + g1 * (m11 * g1 + 2.0 * m12 * g2)
                + m22 * g2 * g2;
            uu - 2.0 * (t * b0 + g1 * b1 + g2 * b2) + quad
        };
        let sr = residual((tx, gxx, gxy), (bx0, bx1, bx2), uxx)
            + residual((ty, gyx, gyy), (by0, by1, by2), uyy);
        spread = (sr.max(0.0) / m00).sqrt();
    }
    let (tx, ty) = (tx + c.0, ty + c.1);
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
    use super::{local_motion, Around};

    /// An `n` × `n` grid of markers `step` apart (x, y), each of 12 px², and its reference.
    fn grid(n: u32, step: (f64, f64)) -> (Vec<(f64, f64)>, TrackReference) {
        let positions: Vec<(f64, f64)> = (0..n)
            .flat_map(|r| (0..n).map(move |c| (step.0 * f64::from(c), step.1 * f64::from(r))))
            .collect();
        let r = TrackReference::new(positions.clone(), vec![12.0; positions.len()]);
        (positions, r)
    }

    /// The ridge-damped affine fit of the displacements `disp` of `items` (neighbour, offset,
    /// weight), solved by Cramer's rule: `[t, g1, g2]` for x and for y.
    fn fit_directly(
        items: &[(usize, (f64, f64), f64)],
        disp: &[(f64, f64)],
        s: f64,
    ) -> ([f64; 3], [f64; 3]) {
        let mut a = [[0.0; 3]; 3];
        let (mut bx, mut by) = ([0.0; 3], [0.0; 3]);
        for &(k, o, w) in items {
            let phi = [1.0, o.0, o.1];
            for (row, &pr) in phi.iter().enumerate() {
                for (cell, &pc) in a[row].iter_mut().zip(&phi) {
                    *cell += w * pr * pc;
                }
                bx[row] += w * pr * disp[k].0;
                by[row] += w * pr * disp[k].1;
            }
        }
        let lambda = 0.3 * a[0][0] * s * s;
        a[1][1] += lambda;
        a[2][2] += lambda;
        let det = |m: [[f64; 3]; 3]| {
            m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
        };
        let solve = |b: [f64; 3]| {
            let mut x = [0.0; 3];
            for (col, xc) in x.iter_mut().enumerate() {
                let mut m = a;
                for (row, &br) in m.iter_mut().zip(&b) {
                    row[col] = br;
                }
                *xc = det(m) / det(a);
            }
            x
        };
        (solve(bx), solve(by))
    }

    /// The affine fit's residual spread, computed in one pass from sums, against the residuals
    /// summed directly (a field far from the origin, as a slide of pitches moves it, plus a
    /// shear, a twist and seeded noise); and a translation, predicted exactly with no spread.
    #[test]
    fn the_fits_spread_matches_the_residuals_summed_directly() {
        let (positions, r) = grid(5, (10.0, 10.0));
        let around = Around::new(&r, &positions);
        let centre = 12;
        // A translation far from the origin (a slide of pitches): read exactly, no spread.
        let moved: Vec<(f64, f64)> = vec![(80.0, -35.0); positions.len()];
        let m = local_motion(centre, &r, &around, |k| k != centre, &moved).unwrap();
        assert!(m.spread_px < 1e-6, "{m:?}");
        assert!(
            (m.disp.0 - 80.0).abs() < 1e-9 && (m.disp.1 + 35.0).abs() < 1e-9,
            "{m:?}"
        );
        // An affine field, the ridge pulling its gradient towards none, plus noise.
        let affine = |p: (f64, f64)| (80.0 + 0.02 * p.0 - 0.05 * p.1, -35.0 + 0.05 * p.0);
        let disp: Vec<(f64, f64)> = positions.iter().map(|&p| affine(p)).collect();
        // Noise (a seeded linear congruential sequence, ±1 px): the spread against a fit
        // recomputed here, its residuals summed one by one.
        let mut state = 12_345_u64;
        let mut noise = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let disp: Vec<(f64, f64)> = disp
            .iter()
            .map(|d| (d.0 + noise(), d.1 + noise()))
            .collect();
        let m = local_motion(centre, &r, &around, |k| k != centre, &disp).unwrap();
        // The same fit, solved here with the ridge, then the residuals summed directly.
        let items = around.of(centre);
        let (fx, fy) = fit_directly(items, &disp, r.spacing_px[centre]);
        let (mut sw, mut sr) = (0.0, 0.0);
        for &(k, o, w) in items {
            let rx = disp[k].0 - (fx[0] + fx[1] * o.0 + fx[2] * o.1);
            let ry = disp[k].1 - (fy[0] + fy[1] * o.0 + fy[2] * o.1);
            sw += w;
            sr += w * (rx * rx + ry * ry);
        }
        let spread = (sr / sw).sqrt();
        assert!(spread > 0.3, "{spread}");
        assert!(
            (m.spread_px - spread).abs() < 1e-9,
            "{} against {spread}",
            m.spread_px
        );
        assert!(
            (m.disp.0 - fx[0]).abs() < 1e-9 && (m.disp.1 - fy[0]).abs() < 1e-9,
            "{m:?}"
        );
    }

    /// A grid stretched half as far again across its rows as along them (a reference taken
    /// under a drag): the central marker's neighbours within 1.3 spacings lie along the rows
    /// only. The steps still span both axes, each both ways, so that a reading shifted a row
    /// or a column either way can be shifted back.
    #[test]
    fn a_stretched_reference_keeps_both_axes_both_ways() {
        let (positions, r) = grid(7, (10.0, 15.0));
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
