//! The one energy every decision of the tracker compares.
//!
//! A marker `i` taking blob `j` costs
//!
//! ```text
//! (|b_j − q_i| / (σ · s_i · m_i))²  +  (ln(A_j / (k · a_i · m_i²)) / σ_a,i)²
//! ```
//!
//! with `q_i` its prediction from its neighbours ([`super::predict`]), `s_i` its spacing
//! (the position's scale `σ · s_i · m_i` widened by the neighbours' spread about their affine
//! fit, that spread bounded by
//! [`TrackParams::spread_sigmas`](super::TrackParams::spread_sigmas) times the scale: a skin
//! does not tear, and a spread without bound would excuse a reading torn at its seam),
//! `m_i` the local magnification, `a_i` its area at rest and `k` the number of markers the
//! blob holds (1, or 2 when two markers squeezed together show as one blob, whose centroid is
//! then compared with their predictions' area-weighted mean; a blob smaller than expected
//! counts with three times the tolerance: markers shrink under a squeeze, only merges
//! grow); `σ` is
//! [`TrackParams::sigma_spacings`](super::TrackParams::sigma_spacings) and `σ_a,i` the area
//! tolerance [`TrackParams::area_sigma`](super::TrackParams::area_sigma) widened by the pixel
//! noise of a small marker's outline. A blob cut by the image border (dropped as cut, or kept
//! though it touches the border) carries no area or shape term; a blob of two lobes pays a
//! shape term (how far under 1 it fills its moments' ellipse, in the sensor's own markers'
//! shortfall at rest). What area and shape add together is bounded by a clutter's cost when
//! the blob holds at least the marker's area and no neighbour is without a blob: the rest of
//! the blob can then only be clutter joined to the marker (a speck, a line drawn across the
//! dot), not another marker, and the marker with its clutter costs no more than the two
//! apart (test `a_dot_joined_by_a_drawn_line_keeps_its_marker`). A weak motion prior adds
//! `(|b_j − o_i| / (M · s_i))²`, `o_i` where the starting motion puts the marker and `M`
//! [`TrackParams::motion_spacings`](super::TrackParams::motion_spacings): it decides between
//! readings the rest cannot tell apart (half a grid hidden, the other half read
//! where it is or a step along).
//! A marker taking no blob and a blob taken by no marker (clutter) each cost half of
//! `(gate / σ)²`, so that a blob at the gate is as likely the marker's as not; the marker's
//! half is scaled by how visible it is expected to be (0 outside the view, 1 a radius inside
//! it) where its neighbours or the starting motion put it, whichever is deeper inside — a
//! reading does not get to push markers out of the view for free; an unseen lattice site
//! ([`super::sites`]) is absent for free — and a blob cut by the
//! border is no clutter (it explains a marker leaving the view), nor, order-free, is a piece of
//! a marker's dot broken by the threshold or a line drawn across it: the marker is measured on
//! its pieces together where that costs less ([`super::pieces`]). The total is the energy;
//! the assignment minimises it and the ambiguity is a margin on it. Read a lattice step off, a
//! field leaves a row of markers at one edge without blobs or a row of blobs at the other edge
//! without markers: either costs.

use super::index::dist_sq;
use super::predict::Prediction;
use super::{TrackParams, TrackReference, View};
use crate::blobs::Blob;

/// The energy's terms for one frame.
#[derive(Clone, Copy)]
pub(super) struct Energy<'a> {
    pub reference: &'a TrackReference,
    pub params: &'a TrackParams,
    pub view: Option<View>,
}

impl Energy<'_> {
    /// The cost of a blob at the gate: that of a marker without a blob wholly in view plus
    /// that of a blob without a marker.
    pub fn gate_cost(&self) -> f64 {
        (self.params.gate_spacings / self.params.sigma_spacings).powi(2)
    }

    /// The most a blob's size and shape may cost one marker when no neighbour without a blob
    /// could be its other part: the blob is then at worst the marker joined by clutter, and
    /// costs no more than that clutter alone (a binarised TacTip pin frays in contact into a
    /// pin with a tail, filling 0.8 of its ellipse; a line drawn across a dot joins it).
    pub fn speck_cost(&self) -> f64 {
        self.clutter_cost()
    }

    /// The cost of a blob taken by no marker (clutter).
    pub fn clutter_cost(&self) -> f64 {
        0.5 * self.gate_cost()
    }

    /// The cost of marker `i` without a blob where its neighbours put it (`at`): half the gate
    /// cost times how far the marker is inside the view, in radii (0 at or beyond its edge, 1
    /// a radius inside). An unseen lattice site's costs nothing: its pin was hidden at rest.
    pub fn lost_cost_at(&self, i: usize, p: &Prediction) -> f64 {
        if self.reference.is_unseen(i) {
            return 0.0;
        }
        let seen = self.view.map_or(1.0, |v| {
            let r = (self.reference.areas_px[i] / std::f64::consts::PI).sqrt() * p.scale;
            let depth = v.depth_px(p.at).max(v.depth_px(p.start));
            (depth / r.max(0.5)).clamp(0.0, 1.0)
        });
        0.5 * self.gate_cost() * seen
    }

    /// The cost of leaving marker `i` without a blob when it could take one: its lost cost
    /// plus the clutter the blob becomes.
    pub fn unmatched_cost_at(&self, i: usize, p: &Prediction) -> f64 {
        self.lost_cost_at(i, p) + self.clutter_cost()
    }

    /// The prediction's uncertainty, pixels: σ spacings scaled by the magnification, widened
    /// by how far the neighbours' motion strays from affine, that spread counting up to
    /// [`TrackParams::spread_sigmas`](super::TrackParams::spread_sigmas) times σ. A skin does not
    /// tear: a spread that widened without bound would excuse a reading torn by a lattice step
    /// at its seam (a region read a step off would cost little more than the right reading).
    pub fn sigma_px(&self, i: usize, p: &Prediction) -> f64 {
        self.sigma_sq_px2(i, p).sqrt()
    }

    /// [`Energy::sigma_px`] squared (what the position term divides by: no square root).
    fn sigma_sq_px2(&self, i: usize, p: &Prediction) -> f64 {
        let s = self.params.sigma_spacings * self.reference.spacing_px[i] * p.scale;
        let spread = p.spread_px.min(s * self.params.spread_sigmas);
        // An unseen site's rest position is a guess from its neighbours: its pin lies within
        // half a spacing of it (nearer another site, it would be that site's).
        let rest = if self.reference.is_unseen(i) {
            0.5 * self.reference.spacing_px[i] * p.scale
        } else {
            0.0
        };
        s * s + spread * spread + rest * rest
    }

    /// The position term: `(distance / σ_px)²`.
    pub fn position_cost(&self, i: usize, d_px: f64, p: &Prediction) -> f64 {
        self.position_cost_sq(i, d_px * d_px, p)
    }

    /// [`Energy::position_cost`] from the squared distance.
    fn position_cost_sq(&self, i: usize, d_sq_px2: f64, p: &Prediction) -> f64 {
        d_sq_px2 / self.sigma_sq_px2(i, p)
    }

    /// How far blob `b`'s area is from `expected_px`, in area tolerances (signed: negative
    /// when smaller). The tolerance is [`TrackParams::area_sigma`](super::TrackParams) widened
    /// by the pixel noise of the marker's outline (about the square root of its length).
    pub fn area_misfit(&self, b: &Blob, expected_px: f64) -> f64 {
        let a = self.params.area_sigma;
        log_area_ratio(b, expected_px) / (a * a + outline_noise_sq(expected_px)).sqrt()
    }

    /// The area term of blob `b` holding markers of expected total area `expected_px`, its
    /// outline's squared relative noise `noise_sq` ([`outline_noise`] squared): the squared
    /// [`Energy::area_misfit`] (0 for a blob cut by the border). A marker squeezed at the edge
    /// of a contact, or in the shade, shrinks to a sliver of itself; only a merge makes one
    /// grow: shrinking is three times as likely.
    fn area_cost(&self, b: &Blob, expected_px: f64, noise_sq: f64) -> f64 {
        if expected_px <= 0.0 {
            return 0.0;
        }
        let a = self.params.area_sigma;
        let l = log_area_ratio(b, expected_px);
        let z_sq = l * l / (a * a + noise_sq);
        if l < 0.0 {
            z_sq / 9.0
        } else {
            z_sq
        }
    }

    /// The cost of marker `i`, predicted at `pred` with magnification `scale`, taking `b`
    /// alone: position, area and shape (a blob of two lobes is not one marker).
    pub fn cost(&self, i: usize, p: &Prediction, b: &Blob, cut: bool) -> f64 {
        let short = if cut { 0.0 } else { fill_short(b) };
        self.cost_with(i, p, b, cut, (short, || f64::INFINITY))
    }

    /// [`Energy::cost`] with the blob's [`fill_short`] given (computed once per blob) and
    /// what its size and shape add bounded by `clutter_cap()` when the blob holds at least
    /// the marker's area ([`Energy::speck_cost`] where no second marker can be the blob's
    /// other part, infinite otherwise; asked only when the bound would matter).
    pub fn cost_with(
        &self,
        i: usize,
        p: &Prediction,
        b: &Blob,
        cut: bool,
        (short, clutter_cap): (f64, impl FnOnce() -> f64),
    ) -> f64 {
        let expected = self.reference.areas_px[i] * p.scale * p.scale;
        let form = if cut {
            0.0
        } else {
            let f = self.reference.fill_sigma;
            let noise_sq = outline_noise_sq(expected.max(1.0));
            let area_noise_sq = if expected >= 1.0 {
                noise_sq
            } else {
                outline_noise_sq(expected)
            };
            let form =
                short * short / (f * f + noise_sq) + self.area_cost(b, expected, area_noise_sq);
            // A marker joined by clutter (a speck, a line drawn across it) holds at least the
            // marker's own area: what its size and shape add is then at most the clutter's
            // own cost.
            if f64::from(b.area_px) >= expected && form > self.speck_cost() {
                form.min(clutter_cap())
            } else {
                form
            }
        };
        let at = (b.x_px, b.y_px);
        self.position_cost_sq(i, dist_sq(at, p.at), p)
            + form
            + self.motion_cost_sq(i, dist_sq(at, p.start))
    }

    /// The cost of marker `i` taking `b`, the union of pieces of its dot: position and area
    /// as [`Energy::cost`], no shape term (the pieces leave the gap that broke them between
    /// them; that they are one marker's is the pieces' own test).
    pub fn pieces_cost(&self, i: usize, p: &Prediction, b: &Blob) -> f64 {
        self.cost_with(i, p, b, false, (0.0, || f64::INFINITY))
    }

    /// The motion prior: a marker the squared distance `moved_sq_px2` from where the starting
    /// motion puts it (the reference after the registration's overall shift, or its last
    /// position when followed) costs `moved² / (M · s_i)²`, `M`
    /// [`TrackParams::motion_spacings`](super::TrackParams::motion_spacings). Weak (a pitch costs
    /// 1/16), it decides between readings the rest of the energy cannot tell apart, such as
    /// half a grid hidden and the visible half read where it is or a step along.
    fn motion_cost_sq(&self, i: usize, moved_sq_px2: f64) -> f64 {
        let scale = self.params.motion_spacings * self.reference.spacing_px[i];
        moved_sq_px2 / (scale * scale)
    }

    /// The gate around marker `i`'s prediction, pixels: `gate / σ` of its uncertainties.
    pub fn gate_px(&self, i: usize, p: &Prediction) -> f64 {
        self.params.gate_spacings / self.params.sigma_spacings * self.sigma_px(i, p)
    }
}

/// The relative noise of the area of a blob of `area_px` from the pixels of its outline (about
/// the square root of the outline's length, over the area).
pub(super) fn outline_noise(area_px: f64) -> f64 {
    outline_noise_sq(area_px).sqrt()
}

/// [`outline_noise`] squared: the outline's length over the squared area (one square root).
fn outline_noise_sq(area_px: f64) -> f64 {
    2.0 * (std::f64::consts::PI * area_px).sqrt() / (area_px * area_px)
}

/// The logarithm of blob `b`'s area (at least a pixel) over `expected_px`.
fn log_area_ratio(b: &Blob, expected_px: f64) -> f64 {
    (f64::from(b.area_px.max(1)) / expected_px).ln()
}

/// The share of the ellipse with a blob's second moments (`4π·√(λ1·λ2)`, each variance
/// widened by the pixel's own 1/12) that its area fills: 1 for an ellipse, 0.89 for two
/// touching equal discs, less for two lobes joined by a thinner bridge.
pub(crate) fn ellipse_fill(b: &Blob) -> f64 {
    let pixel = 1.0 / 12.0;
    let (xx, xy, yy) = (b.mu20_px2 + pixel, b.mu11_px2, b.mu02_px2 + pixel);
    fill_of(f64::from(b.area_px), xx * yy - xy * xy)
}

/// The share of its moments' ellipse a blob of `area_px` fills, `det_px4` the determinant of
/// its covariance (`λ1·λ2`, each variance counting the pixel as a unit square).
pub(super) fn fill_of(area_px: f64, det_px4: f64) -> f64 {
    area_px / (4.0 * std::f64::consts::PI * det_px4.max(0.0).sqrt())
}

/// The shape term of blob `b` read as one marker of `one_px` expected: one marker fills its
/// ellipse (1 for a disc); two lobes joined by a waist fill less (0.89 for two touching equal
/// discs), each `fill_sigma` (the sensor's own markers' shortfall at rest,
/// [`TrackReference::fill_sigma`](super::TrackReference::fill_sigma), widened by the outline's
/// pixel noise as the area's tolerance is) under 1 counting against it. Two markers' blob may
/// fill anything from that to 1 (overlapping discs): the shape says nothing against a pair,
/// whose separation the elongation term weighs.
pub(super) fn shape_cost(b: &Blob, one_px: f64, fill_sigma: f64) -> f64 {
    let short = fill_short(b);
    short * short / (fill_sigma * fill_sigma + outline_noise_sq(one_px.max(1.0)))
}

/// How far under 1 blob `b` fills its moments' ellipse ([`ellipse_fill`]; 0 at or over 1).
pub(super) fn fill_short(b: &Blob) -> f64 {
    (1.0 - ellipse_fill(b)).max(0.0)
}
