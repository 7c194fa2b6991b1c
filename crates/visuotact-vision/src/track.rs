//! Matching reference markers to the blobs of a frame: every frame on its own (order-free), or
//! starting from the last frame's positions (video).
//!
//! Each frame is matched in four steps:
//! 1. **Registration.** Every marker votes for the displacement of its nearest blob in a 2-D
//!    histogram; the densest cell, refined by the mean of its votes, is the overall motion (the
//!    still majority of a skin clamped at its frame, or a whole-sensor shift under half a pitch).
//!    With a temporal prior the last frame's positions take its place.
//! 2. **Seeds.** Markers whose blob is unambiguous after the overall motion (close, mutual
//!    nearest, no rival) are matched; only the largest set of seeds whose displacements agree
//!    with their seeded neighbours is kept (seeds elsewhere may have taken a neighbour's blob
//!    where the skin moved far).
//! 3. **Growth from a local motion model.** The unmatched marker with the most matched
//!    neighbours is predicted from a weighted least-squares *affine* fit of their displacements
//!    (translation plus a 2 × 2 gradient, ridge-damped towards a pure translation when the
//!    neighbours are few or on one side): expansion under a round tip, compression, rotation and
//!    shear are all affine to first order, where the mean of the neighbours' motion is wrong
//!    exactly under the tip. The marker takes the nearest free blob within a gate of
//!    `gate_pitches` × its own spacing (scaled by the fit's local magnification) if no rival is
//!    nearly as close; its neighbours' support grows and they are tried next.
//! 4. **Verification.** A matched marker whose blob is far from what its matched neighbours
//!    predict (over `verify_pitches` × its spacing) is released and grown again once: a
//!    marker that took its neighbour's blob is corrected by the markers around it.
//! 5. **Doubt.** Where the skin moved by a lattice step or more (half a step where three or
//!    more markers are missing), markers missing inside the field leave the markers ahead of
//!    them [`MarkerStatus::Ambiguous`]: a patch dragged past a pitch can be matched a lattice
//!    step short with the gap at its back instead of its front, and nothing in one frame tells
//!    the two apart. A marker is reported lost rather than given a neighbour's blob (on the
//!    simulator's drags of 0.5–1.5 pitch, seeds 1–2: no
//!    wrong identity in 366 707 visible marker-frames, 272 without this step; none lost in
//!    frames moved by under a pitch). A chain of markers that could slide one lattice step into
//!    a hole about as smoothly is in doubt, and so are two parallel chains whose joint slide
//!    into two holes side by side is (two rows dragged together: each alone would leave a
//!    shear against the other). A pair split from one blob beside markers in doubt is in
//!    doubt too.
//!
//! No marker is ever given a blob just because it is the nearest one to its rest position.
//! Markers left without a blob are reported as [`MarkerStatus::Lost`], [`MarkerStatus::Merged`]
//! (their prediction falls on a blob already taken that is much bigger than one marker, or
//! a blob a quarter bigger than one lies within 0.6 spacing of two markers' predictions:
//! squeezed pins overlap, so their blob is less than two; its holder is merged too; order-free,
//! a blob 1.4 times its holder, or 1.3 times as swollen as the blobs around, or of two lobes,
//! within a spacing of a blobless neighbour's prediction is that neighbour's too, hidden under
//! it) or [`MarkerStatus::Ambiguous`] (two free blobs equally plausible); their feature cells
//! stay empty and other markers' columns never shift. Two merged markers whose blob has about
//! their two areas are split by the blob's second moments along its major axis
//! ([`MarkerStatus::Split`]: a position, no area; ≈ 0.4 px from the truth for two touching
//! discs of radius 10 px, test `a_merged_pair_is_split_by_its_moments`) — unless the blob has
//! no waist and the split would put them under 0.55 of their predictions' separation: that is
//! one marker stretched by a drag, and both stay merged.

use std::collections::BinaryHeap;

use serde::{Deserialize, Serialize};

use crate::assign::{assign_min_cost, Candidates};
use crate::blobs::Blob;
use crate::layout::k_nearest_all;

/// What happened to one reference marker in one frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MarkerStatus {
    /// Matched to exactly one blob.
    Ok,
    /// No blob near where the marker should be.
    Lost,
    /// Its blob merged with a neighbour's.
    Merged,
    /// Two or more blobs equally plausible.
    Ambiguous,
    /// Its blob merged with one neighbour's, and the pair was split by the blob's moments: the
    /// position is estimated ([`TrackResult::split_px`]), area and eccentricity are unknown.
    Split,
}

impl MarkerStatus {
    /// Every status.
    pub const ALL: [MarkerStatus; 5] = [
        MarkerStatus::Ok,
        MarkerStatus::Lost,
        MarkerStatus::Merged,
        MarkerStatus::Ambiguous,
        MarkerStatus::Split,
    ];

    /// Name used in tables.
    pub fn name(self) -> &'static str {
        match self {
            MarkerStatus::Ok => "ok",
            MarkerStatus::Lost => "lost",
            MarkerStatus::Merged => "merged",
            MarkerStatus::Ambiguous => "ambiguous",
            MarkerStatus::Split => "split",
        }
    }

    /// Whether the marker has a measured position this frame ([`MarkerStatus::Ok`] or
    /// [`MarkerStatus::Split`]).
    pub fn has_position(self) -> bool {
        matches!(self, MarkerStatus::Ok | MarkerStatus::Split)
    }
}

/// Tracker tuning, in units of each marker's spacing to its nearest neighbour.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TrackConfig {
    /// Largest overall motion the registration considers, in pitches.
    pub search_pitches: f64,
    /// Gate around a prediction within which a blob may be taken, in spacings.
    pub gate_pitches: f64,
    /// A rival blob closer than `ambiguity_ratio ×` the best distance makes a match ambiguous.
    pub ambiguity_ratio: f64,
    /// A taken blob at least this many times the marker's expected area counts as merged.
    pub merged_area_ratio: f64,
    /// A matched marker farther than this from its neighbours' prediction, in spacings, is
    /// released and grown again.
    pub verify_pitches: f64,
    /// Reach of the all-at-once reassignment around the overall motion, in spacings (the
    /// largest local displacement it can follow: a drag of a pitch plus the press).
    pub reassign_pitches: f64,
}

impl TrackConfig {
    /// Defaults that follow drags up to one pitch and presses to the skin's limit.
    pub const DEFAULT: Self = Self {
        search_pitches: 1.5,
        gate_pitches: 0.4,
        ambiguity_ratio: 1.25,
        merged_area_ratio: 1.6,
        verify_pitches: 0.35,
        reassign_pitches: 2.2,
    };
}

impl TrackConfig {
    /// Checks the settings: every reach positive and finite, the ratios above 1 (a ratio of
    /// 1 or less would call every match ambiguous or every blob merged).
    pub fn validate(&self) -> Result<(), crate::ConfigError> {
        for (name, v) in [
            ("search_pitches", self.search_pitches),
            ("gate_pitches", self.gate_pitches),
            ("verify_pitches", self.verify_pitches),
            ("reassign_pitches", self.reassign_pitches),
        ] {
            if !(v.is_finite() && v > 0.0 && v <= 100.0) {
                return Err(crate::ConfigError(format!(
                    "tracker {name} must be in (0, 100] spacings, got {v}"
                )));
            }
        }
        for (name, v) in [
            ("ambiguity_ratio", self.ambiguity_ratio),
            ("merged_area_ratio", self.merged_area_ratio),
        ] {
            if !(v.is_finite() && v > 1.0) {
                return Err(crate::ConfigError(format!(
                    "tracker {name} must be a finite ratio above 1, got {v}"
                )));
            }
        }
        Ok(())
    }
}

impl Default for TrackConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// The reference markers as the tracker needs them.
#[derive(Clone, Debug)]
pub struct TrackReference {
    /// Marker positions `(x, y)` in pixels.
    pub positions: Vec<(f64, f64)>,
    /// Reference areas in pixels.
    pub areas_px: Vec<f64>,
    /// Neighbours of each marker (indices): its 12 nearest within 2.5 × its spacing, plus every
    /// marker that counts it among theirs (the relation is symmetric).
    pub neighbours: Vec<Vec<usize>>,
    /// Each marker's distance to its nearest neighbour, pixels (the local pitch: a dome's or a
    /// wide-angle lens's pitch varies across the image).
    pub spacing_px: Vec<f64>,
    /// Median spacing, pixels.
    pub pitch_px: f64,
    /// For concentric rings, each ring's major axis in pixels: rings share a centre, so they
    /// are matched by size near the reference centre instead of by position.
    pub ring_sizes_px: Option<Vec<f64>>,
}

impl TrackReference {
    /// Builds neighbourhoods and spacings from positions and areas.
    pub fn new(positions: Vec<(f64, f64)>, areas_px: Vec<f64>) -> Self {
        let n = positions.len();
        let knn = if n > 1 {
            k_nearest_all(&positions, 12.min(n - 1))
        } else {
            vec![Vec::new(); n]
        };
        let spacing: Vec<f64> = knn
            .iter()
            .map(|v| v.first().map_or(f64::NAN, |x| x.1))
            .collect();
        let mut sorted: Vec<f64> = spacing.iter().copied().filter(|s| s.is_finite()).collect();
        sorted.sort_by(f64::total_cmp);
        let pitch_px = if sorted.is_empty() {
            // One marker: use its size as the scale.
            areas_px.first().map_or(10.0, |a| 2.0 * a.sqrt())
        } else {
            sorted[sorted.len() / 2]
        };
        let spacing_px: Vec<f64> = spacing
            .iter()
            .map(|s| if s.is_finite() { *s } else { pitch_px })
            .collect();
        let mut neighbours: Vec<Vec<usize>> = knn
            .iter()
            .enumerate()
            .map(|(i, v)| {
                v.iter()
                    .filter(|&&(_, d)| d < 2.5 * spacing_px[i])
                    .map(|&(j, _)| j)
                    .collect()
            })
            .collect();
        for i in 0..n {
            for k in 0..neighbours[i].len() {
                let j = neighbours[i][k];
                if !neighbours[j].contains(&i) {
                    neighbours[j].push(i);
                }
            }
        }
        Self {
            positions,
            areas_px,
            neighbours,
            spacing_px,
            pitch_px,
            ring_sizes_px: None,
        }
    }
}

/// The outcome for one frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TrackResult {
    /// Blob index per marker (`None` unless the status is [`MarkerStatus::Ok`]).
    pub assignment: Vec<Option<usize>>,
    /// Status per marker.
    pub status: Vec<MarkerStatus>,
    /// Overall motion found by the registration, in pixels.
    pub shift_px: (f64, f64),
    /// Blobs not given to any marker.
    pub spurious: usize,
    /// Estimated position of each [`MarkerStatus::Split`] marker (`None` for the others; empty
    /// when no marker was split).
    pub split_px: Vec<Option<(f64, f64)>>,
    /// Followed tracking: the blob centroid of each marker reported [`MarkerStatus::Merged`]
    /// because it held a swollen blob likely shared with a hidden neighbour (`None` for the
    /// others; empty when there is none). Not a measurement: only where the next frame starts
    /// looking for it ([`TrackResult::followed_px`]).
    pub held_px: Vec<Option<(f64, f64)>>,
}

impl TrackResult {
    /// Number of markers with a position: matched, or split from a merged pair.
    pub fn found(&self) -> usize {
        self.status.iter().filter(|s| s.has_position()).count()
    }

    /// Marker `i`'s position this frame: its blob's centroid, or its split estimate.
    pub fn position_px(&self, i: usize, blobs: &[Blob]) -> Option<(f64, f64)> {
        match self.assignment[i] {
            Some(j) => Some((blobs[j].x_px, blobs[j].y_px)),
            None => self.split_px.get(i).copied().flatten(),
        }
    }

    /// Where the next frame of a video starts looking for marker `i`: its
    /// [`TrackResult::position_px`], or the blob it held while reported merged
    /// ([`TrackResult::held_px`]).
    pub fn followed_px(&self, i: usize, blobs: &[Blob]) -> Option<(f64, f64)> {
        self.position_px(i, blobs)
            .or_else(|| self.held_px.get(i).copied().flatten())
    }
}

fn dist(a: (f64, f64), b: (f64, f64)) -> f64 {
    dist_sq(a, b).sqrt()
}

fn dist_sq(a: (f64, f64), b: (f64, f64)) -> f64 {
    (a.0 - b.0) * (a.0 - b.0) + (a.1 - b.1) * (a.1 - b.1)
}

/// Blob centroids bucketed on a square grid of cell size `cell` for near look-ups.
struct BlobIndex {
    cell: f64,
    x0: f64,
    y0: f64,
    nx: usize,
    ny: usize,
    starts: Vec<u32>,
    items: Vec<u32>,
    pts: Vec<(f64, f64)>,
}

impl BlobIndex {
    fn new(blobs: &[Blob], cell: f64) -> Self {
        let pts: Vec<(f64, f64)> = blobs.iter().map(|b| (b.x_px, b.y_px)).collect();
        let (mut x0, mut y0, mut x1, mut y1) = (
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        );
        for &(x, y) in &pts {
            x0 = x0.min(x);
            y0 = y0.min(y);
            x1 = x1.max(x);
            y1 = y1.max(y);
        }
        if pts.is_empty() {
            (x0, y0, x1, y1) = (0.0, 0.0, 0.0, 0.0);
        }
        let nx = ((x1 - x0) / cell).floor() as usize + 1;
        let ny = ((y1 - y0) / cell).floor() as usize + 1;
        let cell_of =
            |&(x, y): &(f64, f64)| ((y - y0) / cell) as usize * nx + ((x - x0) / cell) as usize;
        // Counting sort of blob indices by cell.
        let mut starts = vec![0u32; nx * ny + 1];
        for p in &pts {
            starts[cell_of(p) + 1] += 1;
        }
        for k in 1..starts.len() {
            starts[k] += starts[k - 1];
        }
        let mut fill = starts.clone();
        let mut items = vec![0u32; pts.len()];
        for (j, p) in pts.iter().enumerate() {
            let c = cell_of(p);
            items[fill[c] as usize] = j as u32;
            fill[c] += 1;
        }
        Self {
            cell,
            x0,
            y0,
            nx,
            ny,
            starts,
            items,
            pts,
        }
    }

    /// The blob nearest to `p` within `r` (ties to the lower index). Looks within one cell
    /// first: a blob found there is nearer than any outside it.
    fn nearest(&self, p: (f64, f64), r: f64) -> Option<usize> {
        let mut best: Option<(usize, f64)> = None;
        for radius in [r.min(self.cell), r] {
            self.near(p, radius, |j, d| {
                if best.is_none_or(|(bj, bd)| d < bd || (d == bd && j < bj)) {
                    best = Some((j, d));
                }
            });
            if best.is_some() || radius >= r {
                break;
            }
        }
        best.map(|(j, _)| j)
    }

    /// Calls `f(index, squared distance)` for every blob within `r` of `p`.
    fn near(&self, p: (f64, f64), r: f64, mut f: impl FnMut(usize, f64)) {
        if self.pts.is_empty() {
            return;
        }
        // Cell indices: truncating a non-negative value is its floor (and cheaper: without
        // SSE4.1, `floor` is a library call).
        let cx0 = ((p.0 - r - self.x0) / self.cell).max(0.0) as usize;
        let cy0 = ((p.1 - r - self.y0) / self.cell).max(0.0) as usize;
        let cx1 = (p.0 + r - self.x0) / self.cell;
        let cy1 = (p.1 + r - self.y0) / self.cell;
        if cx1 < 0.0 || cy1 < 0.0 {
            return;
        }
        let cx1 = (cx1 as usize).min(self.nx - 1);
        let cy1 = (cy1 as usize).min(self.ny - 1);
        for cy in cy0..=cy1 {
            for cx in cx0..=cx1 {
                let c = cy * self.nx + cx;
                for &j in &self.items[self.starts[c] as usize..self.starts[c + 1] as usize] {
                    let q = self.pts[j as usize];
                    let d2 = (q.0 - p.0) * (q.0 - p.0) + (q.1 - p.1) * (q.1 - p.1);
                    if d2 <= r * r {
                        f(j as usize, d2);
                    }
                }
            }
        }
    }
}

/// Overall motion: each marker votes for the displacement of the blob nearest to it, and the
/// densest cell of the vote histogram, refined by the mean of its votes, wins. A skin clamped
/// at its frame moves locally, so the still majority decides; a whole-sensor shift (a bumped
/// camera) is found when it is under half a pitch (a larger uniform shift of a lattice cannot be
/// told from a smaller one).
fn register(reference: &TrackReference, index: &BlobIndex, cfg: &TrackConfig) -> (f64, f64) {
    let p = reference.pitch_px;
    let range = cfg.search_pitches * p;
    let cell = p / 4.0;
    let nb = (2.0 * range / cell).ceil() as usize + 1;
    let mut votes = vec![0u32; nb * nb];
    let mut picks: Vec<(f64, f64)> = Vec::with_capacity(reference.positions.len());
    for &m in &reference.positions {
        if let Some(j) = index.nearest(m, range) {
            let q = index.pts[j];
            let d = (q.0 - m.0, q.1 - m.1);
            // `as usize` saturates negatives to 0, as it does their floor: the same cells as
            // `floor`, without its library call on baseline x86-64.
            let bx = ((d.0 + range) / cell) as usize;
            let by = ((d.1 + range) / cell) as usize;
            if bx < nb && by < nb {
                votes[by * nb + bx] += 1;
                picks.push(d);
            }
        }
    }
    // Densest 2 × 2 block (a vote cloud straddling a cell edge is not split), ties to the
    // smallest motion.
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

/// Nearest and second-nearest free blob to `p` within `gate`.
fn nearest_two(
    p: (f64, f64),
    index: &BlobIndex,
    taken: &[bool],
    gate: f64,
) -> (Option<(usize, f64)>, f64) {
    let mut best: Option<(usize, f64)> = None;
    let mut second = f64::INFINITY;
    // Squared distances throughout; one square root for each of the two results.
    index.near(p, 2.0 * gate, |j, d2| {
        if taken[j] {
            return;
        }
        match best {
            Some((_, bd)) if d2 >= bd => second = second.min(d2),
            _ => {
                if let Some((_, bd)) = best {
                    second = second.min(bd);
                }
                best = Some((j, d2));
            }
        }
    });
    let best = best.map(|(j, d2)| (j, d2.sqrt()));
    (best.filter(|&(_, d)| d <= gate), second.sqrt())
}

/// Concentric rings: each reference ring (smallest first) takes the free blob whose size and
/// centre are closest (cost `|Δmajor|/major + distance/major`), within 30 % in size and half its
/// major axis in position.
fn track_rings(reference: &TrackReference, sizes: &[f64], blobs: &[Blob]) -> TrackResult {
    let n = reference.positions.len();
    let mut taken = vec![false; blobs.len()];
    let mut assignment = vec![None; n];
    let mut status = vec![MarkerStatus::Lost; n];
    let majors: Vec<f64> = blobs
        .iter()
        .map(|b| b.shape(crate::blobs::MomentConvention::Pixel).major_axis_px)
        .collect();
    let (mut sx, mut sy, mut k) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let size = sizes[i].max(1.0);
        let p = reference.positions[i];
        let mut best: Option<(usize, f64)> = None;
        for (j, b) in blobs.iter().enumerate() {
            let d = dist(p, (b.x_px, b.y_px));
            let ds = (majors[j] - size).abs() / size;
            if taken[j] || ds > 0.3 || d > 0.5 * size {
                continue;
            }
            let cost = ds + d / size;
            if best.is_none_or(|(_, c)| cost < c) {
                best = Some((j, cost));
            }
        }
        if let Some((j, _)) = best {
            taken[j] = true;
            assignment[i] = Some(j);
            status[i] = MarkerStatus::Ok;
            sx += blobs[j].x_px - p.0;
            sy += blobs[j].y_px - p.1;
            k += 1.0;
        }
    }
    let shift_px = if k > 0.0 {
        (sx / k, sy / k)
    } else {
        (0.0, 0.0)
    };
    let spurious = taken.iter().filter(|t| !**t).count();
    TrackResult {
        assignment,
        status,
        shift_px,
        spurious,
        split_px: Vec::new(),
        held_px: Vec::new(),
    }
}

/// Cost of a marker left without a blob in the first reassignment round, in squared spacings:
/// more than a chain of shifts within reach, so every marker that has a blob gets one.
const FIRST_ROUND_LOST_COST: f64 = 100.0;

/// A local affine motion model around one marker.
#[derive(Clone, Copy, Debug)]
struct LocalMotion {
    /// Predicted displacement of the marker.
    disp: (f64, f64),
    /// Local magnification `sqrt(|det(I + G)|)`, clamped to 0.5..2.
    scale: f64,
}

/// Weighted least-squares affine fit of the displacements `disp` of the matched neighbours of
/// `i` (`anchors` their positions before the motion), ridge-damped towards a translation.
fn local_motion(
    i: usize,
    reference: &TrackReference,
    anchors: &[(f64, f64)],
    matched: &[bool],
    disp: &[(f64, f64)],
) -> Option<LocalMotion> {
    let s = reference.spacing_px[i];
    let ai = anchors[i];
    // Normal equations for [t, g1, g2] per axis: Σ w [1 o][1 o]ᵀ + diag(0, λ, λ).
    let (mut m00, mut m01, mut m02, mut m11, mut m12, mut m22) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut bx0, mut bx1, mut bx2) = (0.0, 0.0, 0.0);
    let (mut by0, mut by1, mut by2) = (0.0, 0.0, 0.0);
    let mut count = 0;
    for &k in &reference.neighbours[i] {
        if !matched[k] {
            continue;
        }
        let o = (anchors[k].0 - ai.0, anchors[k].1 - ai.1);
        let w = 1.0 / (o.0 * o.0 + o.1 * o.1 + 0.25 * s * s);
        let u = disp[k];
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
    Some(LocalMotion {
        disp: (tx, ty),
        scale: jac.abs().sqrt().clamp(0.5, 2.0),
    })
}

/// A slide into a hole that changes the energy by less than this (in squared spacings, a lost
/// marker costing 1) leaves its chain's markers in doubt ([`Matching::slide_chains`]).
const AMBIGUOUS_SLIDE: f64 = 0.5;

/// Two rows sliding together into two holes side by side (the holes moving to their other
/// ends, no free blob taken) that change the energy by less than this leave their markers in
/// doubt ([`Matching::slide_chains`]). Under [`AMBIGUOUS_SLIDE`], as a slide that only moves
/// the holes is weaker evidence of a drag than one that fills them from a spare blob: truly
/// ambiguous pairs measured 0.02–0.25, the lowest on a frame tracked right 0.43.
const AMBIGUOUS_ROWS_SLIDE: f64 = 0.35;

/// A slide into a hole that leaves the chain's last marker without a blob (squeezed out of
/// sight at the front of a drag) and changes the energy by less than this, in squared
/// spacings, leaves the chain's markers in doubt however little they moved
/// ([`Matching::slide_chains`]): read a step short, a row dragged past a pitch seems to have
/// moved little (GelSight variant 1, drag seed 12: a row at the top edge with its third marker
/// hidden). Measured on the drag matrix, seeds 1–12: wrong identities 23 → 18 for 389 more
/// lost marker-frames (2 %); at 0.5, 23 → 21 for 1 094 more, four of the new wrong ones on
/// TacTip. Seeds 13–16, held out: 3 → 2, 79 more lost. Followed, only chains through a marker
/// the prior frame did not see: on every chain the followed matrix fell 22 → 14 wrong, but the
/// zoo's built-up GelSight drag, which must be followed whole, lost a marker.
const SQUEEZED_OUT_SLIDE: f64 = 0.2;

/// A marker between a hole and a free blob that moved towards the blob by this many spacings
/// stays in doubt however little it moved ([`Matching::slide_chains`]).
const DRAGGED_TOWARDS: f64 = 0.2;

/// A blob within this many spacings of two markers' predictions, one of them missing, may be
/// both of theirs ([`Matching::crowded_onto`]).
const CROWDED: f64 = 0.6;

/// A blob shared by two squeezed markers is at least this many times the smaller marker's
/// area ([`Matching::crowded_onto`]).
const CROWDED_AREA: f64 = 1.25;

/// How near a blob the prediction of a marker unseen in the prior frame (made from its
/// neighbours' motion alone) may lie for the blob to be its as much as a neighbour's that was
/// unseen too, in spacings ([`doubt_reacquired_beside_unseen`]).
const UNSEEN_REACH: f64 = 0.75;

/// A blob at least this many times its holder's area (scaled by the local magnification) holds
/// more than one marker ([`Matching::holding_a_swollen_blob`]). Large dots dragged onto their
/// neighbours left blobs of 1.44–1.58 times a dot, the neighbour hidden; of the blobs that big
/// beside an unmatched neighbour on the drag matrix (seeds 1–8), 14 were a visible marker's own.
const SWOLLEN_AREA: f64 = 1.4;

/// A blob at least this many times its holder's area, over the median of the same ratio for
/// its matched lattice neighbours' blobs, also holds more than one marker
/// ([`Matching::holding_a_swollen_blob`]): blobs swell or shrink with the neighbourhood (the
/// local magnification, the threshold in a shaded patch), and one swollen against its own
/// neighbours is a sharper sign than against the magnification alone. On the drag matrix,
/// seeds 1–12, it takes wrong identities 27 → 23 beside [`SWOLLEN_AREA`] for 7 more lost
/// markers (of 19 702).
const SWOLLEN_BESIDE: f64 = 1.3;

/// A blob filling less of the ellipse with its second moments than this ([`ellipse_fill`]) is
/// two lobes ([`Matching::holding_a_swollen_blob`]): two markers that shrank under the contact
/// and touch hold one blob the size of one marker, its centroid neither's (dots variant 3, drag
/// seed 9: measured 8.4 px from its holder's centre, 8.1 from the hidden neighbour's).
const TWO_LOBES_FILL: f64 = 0.85;

/// Markers under this area at rest, in pixels, are not judged by their blob's outline
/// ([`TWO_LOBES_FILL`]): a pin of a few pixels fills its ellipse by the luck of its pixels (the
/// 128 × 128 TacTip's 4–15-px pins, drag matrix seeds 1–40: 351 more lost, no wrong identity
/// fewer).
const TWO_LOBES_MIN_AREA_PX: f64 = 50.0;

/// How near a swollen blob the prediction of a neighbour without a position may lie for the
/// blob to be partly that neighbour's, in the neighbour's spacings
/// ([`Matching::holding_a_swollen_blob`]). The prediction comes from neighbours that lag the
/// drag: the hidden dots' lay 0.79–1.0 spacing from the blob they shared on seeds 1–12, and
/// 1.02–1.05 on seeds 11, 17 and 21 (1.0 before: drag matrix seeds 1–24, wrong identities
/// 49 → 45 together with merged neighbours, 250 more lost of 43 053).
const SWOLLEN_REACH: f64 = 1.1;

/// A swollen blob up to this many of the hidden neighbour's spacings from its prediction is
/// also partly that neighbour's when it is at least [`SWOLLEN_FAR_BESIDE`] times its holder's
/// area over its neighbours' ([`Matching::holding_a_swollen_blob`]): a pair of dots dragged
/// together whose hidden dot's prediction lay 1.102 spacings off (held-out drag seed 43, the
/// visible dots moved 0.71 pitch) was read as the holder's alone. Nearer than
/// [`SWOLLEN_REACH`] the milder signs suffice.
const SWOLLEN_FAR_REACH: f64 = 1.25;

/// How swollen a blob beyond [`SWOLLEN_REACH`] must be against its holder's neighbours'
/// blobs, as [`SWOLLEN_BESIDE`] is within it: two whole dots on one blob.
const SWOLLEN_FAR_BESIDE: f64 = 1.8;

/// Holes this many spacings or more inside the view start pairs of parallel chains
/// ([`Matching::parallel_rows_in_doubt`]); one nearer the edge may simply be cut. One whole
/// spacing kept out the top row of a GelSight-like grid (its pins 25 px from the edge, 5 px in
/// radius), whose rows dragged to the side were read a step short: drag matrix seeds 1–24,
/// wrong identities 52 → 49, one more lost.
const EDGE_DEPTH: f64 = 0.5;

/// How near a blob a hole's prediction may lie for the marker holding it to be in doubt, in
/// the hole's spacings ([`Matching::holding_a_holes_blob`]). A hole's prediction comes from
/// neighbours that lag a drag, so it falls short: at 0.6 of the gate scaled by the local
/// magnification (before) a GelSight marker at the top edge kept the blob of a neighbour
/// whose prediction lay 0.54 spacing from it, against 0.66 from its own (drag seed 7), and two
/// small-TacTip pins in a 3.3 mm press kept their neighbours' (seed 6). Measured on the drag
/// matrix, seeds 1–8: wrong identities 12 → 9, lost +24 of 4 427 on seeds 1–2, none more in
/// frames moved under a pitch.
const HOLE_BLOB_REACH: f64 = 0.75;

/// How far from a hole a free blob leaves the markers between in doubt, in spacings.
const HOLE_REACH: f64 = 4.0;

/// A marker missing where its neighbours moved by at least this many spacings is a gap that
/// leaves the markers around it in doubt ([`doubt_around_gaps`]).
const GAP_MOTION: f64 = 0.4;

/// A frame none of whose matched markers moved this far beyond the overall motion, in
/// spacings, has no gaps in doubt ([`doubt_around_gaps`]).
const FRAME_MOTION: f64 = 1.0;

/// [`FRAME_MOTION`] in a frame where two markers fell on one blob with no waist that was not
/// split ([`gaps_frame_motion`]): a sign of a field read a lattice step short, the pair
/// on a single marker's blob. A TacTip rim dragged two pitches, its outer row pushed out of
/// the round view, was read a step short with its largest held motion 0.96–0.97 spacing
/// and such a pair inside. On the drag matrix at `--motion-limit 1`: seeds 9–24, wrong
/// identities 25 → 8 (TacTip 16 → 2, small TacTip 4 → 1), lost +136 of 31 116, none in
/// frames moved under a pitch; seeds 1–8, 20 more lost (dots), all beyond a pitch.
const WAISTLESS_FRAME_MOTION: f64 = 0.9;

/// A frame with this many gaps left without a blob ([`doubt_around_gaps`]) looks for gaps in
/// doubt once some matched marker moved [`MANY_GAPS_MOTION`] spacings, not [`FRAME_MOTION`]:
/// a field read a lattice step short leaves a gap at the back of every row it crossed, and its
/// held markers seem to have moved a step less than they did; a field really moved under a
/// pitch misses a marker or two (painted over, hidden under the tip). Markers in doubt on the
/// blob they hold (a chain that could slide, [`Matching::slide_chains`]) do not count: two
/// rows dragged side by side then put rows far from the drag in doubt
/// (`two_rows_dragged_past_a_pitch_are_in_doubt_not_read_a_step_short`). A small TacTip
/// dragged 2.2 pitches towards the view's edge was read a step short with five rows' back pins
/// lost and its largest held motion 0.9 spacing (drag seed 36); GelSight grids dragged 1.6–1.8
/// pitches likewise (seeds 28, 31, 37). Drag matrix at `--motion-limit 1` (2026-11-29, with
/// the far neighbours of [`gap_motion`]): seeds 25–40, wrong identities 25 → 2, lost 20 604 →
/// 20 807 of 2 936 994 visible marker-frames; seeds 1–24, 8 → 8, lost 43 811 → 44 113 of
/// 4 400 880; none more in frames moved under a pitch.
const MANY_GAPS: usize = 3;

/// See [`MANY_GAPS`].
const MANY_GAPS_MOTION: f64 = 0.5;

/// Radius of the doubt around such a gap, in spacings, per spacing of motion plus one.
const GAP_REACH: f64 = 2.0;

/// How far [`gap_motion`] looks for held markers, in spacings, when none a lattice step away
/// holds a blob.
const GAP_FAR: f64 = 2.0;

/// A marker merged on a blob: (blob, marker, predicted position, local magnification).
type OnBlob = (usize, usize, (f64, f64), f64);

/// The working state of one frame's matching.
struct Matching<'a> {
    reference: &'a TrackReference,
    blobs: &'a [Blob],
    index: BlobIndex,
    cfg: &'a TrackConfig,
    /// Where each marker was before the motion being followed (reference or prior).
    anchors: Vec<(f64, f64)>,
    view: Option<View>,
    assignment: Vec<Option<usize>>,
    disp: Vec<(f64, f64)>,
    taken: Vec<bool>,
    /// How many of each marker's neighbours hold a blob (kept by `take` and `release`; the
    /// neighbour relation is symmetric).
    support: Vec<u32>,
}

impl Matching<'_> {
    fn matched(&self) -> Vec<bool> {
        self.assignment.iter().map(Option::is_some).collect()
    }

    fn take(&mut self, i: usize, j: usize) {
        if self.assignment[i].replace(j).is_none() {
            for &k in &self.reference.neighbours[i] {
                self.support[k] += 1;
            }
        }
        self.taken[j] = true;
        let a = self.anchors[i];
        self.disp[i] = (self.blobs[j].x_px - a.0, self.blobs[j].y_px - a.1);
    }

    fn release(&mut self, i: usize) {
        if let Some(j) = self.assignment[i].take() {
            self.taken[j] = false;
            for &k in &self.reference.neighbours[i] {
                self.support[k] -= 1;
            }
        }
    }

    /// How many of `i`'s neighbours hold a blob.
    fn support(&self, i: usize) -> usize {
        self.support[i] as usize
    }

    /// Where `i` should be according to its matched neighbours, and the local magnification.
    fn predict(&self, i: usize, matched: &[bool]) -> Option<((f64, f64), f64)> {
        local_motion(i, self.reference, &self.anchors, matched, &self.disp).map(|m| {
            let a = self.anchors[i];
            ((a.0 + m.disp.0, a.1 + m.disp.1), m.scale)
        })
    }

    /// Seeds: markers with an unambiguous, mutually nearest blob near `predicted`.
    fn seed(&mut self, predicted: &[(f64, f64)]) {
        let n = predicted.len();
        let blobs = self.blobs;
        for i in 0..n {
            let s = self.reference.spacing_px[i];
            let gate = self.cfg.gate_pitches * s;
            let (best, second) = nearest_two(predicted[i], &self.index, &self.taken, 0.5 * gate);
            let Some((j, d)) = best else { continue };
            if second < self.cfg.ambiguity_ratio * 2.0 * d.max(0.05 * s) {
                continue;
            }
            // Mutual: no other marker's prediction is closer to this blob.
            let bj = (blobs[j].x_px, blobs[j].y_px);
            let mutual = self.reference.neighbours[i]
                .iter()
                .all(|&k| dist_sq(predicted[k], bj) > d * d);
            if mutual {
                self.take(i, j);
            }
        }
        // Keep the largest set of seeds whose displacements agree with their seeded neighbours.
        let mut component = vec![usize::MAX; n];
        let mut sizes = Vec::new();
        for s0 in 0..n {
            if self.assignment[s0].is_none() || component[s0] != usize::MAX {
                continue;
            }
            let c = sizes.len();
            let mut stack = vec![s0];
            component[s0] = c;
            let mut size = 0;
            while let Some(i) = stack.pop() {
                size += 1;
                for &k in &self.reference.neighbours[i] {
                    if self.assignment[k].is_some()
                        && component[k] == usize::MAX
                        && dist_sq(self.disp[i], self.disp[k])
                            < (0.25
                                * self.reference.spacing_px[i].min(self.reference.spacing_px[k]))
                            .powi(2)
                    {
                        component[k] = c;
                        stack.push(k);
                    }
                }
            }
            sizes.push(size);
        }
        if let Some(keep) = (0..sizes.len()).max_by_key(|&c| (sizes[c], usize::MAX - c)) {
            for (i, &c) in component.iter().enumerate() {
                if c != keep && self.assignment[i].is_some() {
                    self.release(i);
                }
            }
        }
    }

    /// Grows the matched set from matched markers into their neighbours, most supported first.
    fn grow(&mut self) {
        let n = self.assignment.len();
        let mut failed_at: Vec<Option<usize>> = vec![None; n];
        let mut heap: BinaryHeap<(usize, std::cmp::Reverse<usize>)> = (0..n)
            .filter(|&i| self.assignment[i].is_none())
            .map(|i| (self.support(i), std::cmp::Reverse(i)))
            .filter(|&(c, _)| c > 0)
            .collect();
        let mut matched = self.matched();
        while let Some((support, std::cmp::Reverse(i))) = heap.pop() {
            if self.assignment[i].is_some()
                || support != self.support(i)
                || failed_at[i].is_some_and(|f| support <= f)
            {
                continue;
            }
            let Some((pred, scale)) = self.predict(i, &matched) else {
                continue;
            };
            let s = self.reference.spacing_px[i];
            let gate = self.cfg.gate_pitches * s * scale.clamp(0.7, 1.6);
            let (best, second) = nearest_two(pred, &self.index, &self.taken, gate);
            match best {
                Some((j, d)) if second >= self.cfg.ambiguity_ratio * d.max(0.05 * s) => {
                    self.take(i, j);
                    matched[i] = true;
                    for &k in &self.reference.neighbours[i] {
                        if self.assignment[k].is_none() {
                            heap.push((self.support(k), std::cmp::Reverse(k)));
                        }
                    }
                }
                _ => failed_at[i] = Some(support),
            }
        }
    }

    /// Total squared residual (in spacings) of the matched markers against their neighbours'
    /// prediction, plus `lost_cost` per unmatched marker: lower is a smoother, fuller match.
    fn energy(&self, lost_cost: f64) -> f64 {
        let matched = self.matched();
        (0..self.assignment.len())
            .map(|i| match self.assignment[i] {
                None => lost_cost,
                Some(_) => self.residual(i, &matched).map_or(0.0, |r| r * r),
            })
            .sum()
    }

    /// Distance of marker `i`'s blob from its matched neighbours' prediction, in spacings.
    fn residual(&self, i: usize, matched: &[bool]) -> Option<f64> {
        let j = self.assignment[i]?;
        let (p, _) = self.predict(i, matched)?;
        let b = (self.blobs[j].x_px, self.blobs[j].y_px);
        Some(dist(b, p) / self.reference.spacing_px[i])
    }

    /// Re-matches every marker at once by minimum total squared distance to its prediction
    /// (one-to-one; quadratic costs prefer many small shifts to one long jump): first from the
    /// overall motion alone within `reassign_pitches`, a marker left without a blob costing
    /// more than any shift within reach; then from the local affine motion of the previous
    /// round's matches with a gate of one spacing (beyond it, no blob), until nothing changes.
    fn reassign(&mut self, predicted: &[(f64, f64)]) {
        let n = self.assignment.len();
        let mut cands = Candidates::default();
        let mut preds: Vec<((f64, f64), f64)> = predicted.iter().map(|&p| (p, 1.0)).collect();
        for round in 0..4 {
            let reach = if round == 0 {
                self.cfg.reassign_pitches
            } else {
                1.0
            };
            cands.clear();
            for (i, &((px, py), scale)) in preds.iter().enumerate() {
                let s = self.reference.spacing_px[i];
                let r = reach * s * scale.clamp(0.7, 1.6);
                let expected = self.reference.areas_px[i] * scale * scale;
                cands.begin_row();
                let blobs = self.blobs;
                let held = self.assignment[i];
                self.index.near((px, py), r, |j, d2| {
                    let a = f64::from(blobs[j].area_px);
                    let lo = if blobs[j].touches_border { 0.0 } else { 0.2 };
                    if held != Some(j) && a >= lo * expected && a <= 5.0 * expected {
                        cands.push_edge(j, d2 / (s * s));
                    }
                });
                // Later rounds refine: a marker keeps the blob it holds (whatever the distance)
                // unless another marker takes it, and never drops it for nothing.
                let keep = held.map(|j| {
                    let b = (blobs[j].x_px, blobs[j].y_px);
                    (dist(b, (px, py)) / s).powi(2)
                });
                if let Some((j, c)) = held.zip(keep) {
                    cands.push_edge(j, c);
                }
                // First round: every marker should have a blob (a hole costs more than any
                // chain of shifts within reach); later rounds: a blob beyond the gate is none.
                cands.end_row(if round == 0 {
                    FIRST_ROUND_LOST_COST
                } else {
                    (r / s).powi(2).max(keep.map_or(0.0, |c| 1.01 * c))
                });
            }
            let a = assign_min_cost(&cands, self.blobs.len());
            let changed = (0..n).any(|i| a.columns[i] != self.assignment[i]);
            for i in 0..n {
                self.release(i);
            }
            for (i, col) in a.columns.iter().enumerate() {
                if let Some(j) = *col {
                    self.take(i, j);
                }
            }
            if round > 0 && !changed {
                break;
            }
            let matched = self.matched();
            for (i, p) in preds.iter_mut().enumerate() {
                if let Some(q) = self.predict(i, &matched) {
                    *p = q;
                }
            }
        }
    }

    /// Squared residual of marker `i`'s blob against its matched neighbours' prediction, in
    /// spacings, capped at 2 (one wrong marker cannot dominate), 0 when it cannot be predicted.
    fn residual_sq(&self, i: usize, matched: &[bool]) -> f64 {
        self.residual(i, matched).map_or(0.0, |r| (r * r).min(2.0))
    }

    /// Sum of [`Matching::residual_sq`] over `set`, plus `lost_cost` per unmatched marker in it.
    fn local_energy(&self, set: &[usize], lost_cost: f64) -> f64 {
        let matched = self.matched();
        set.iter()
            .map(|&i| {
                if self.assignment[i].is_some() {
                    self.residual_sq(i, &matched)
                } else {
                    lost_cost
                }
            })
            .sum()
    }

    /// The neighbour of `k` whose reference offset is nearest `dir` (a lattice step), if it is
    /// within a third of a spacing of it.
    fn step_from(&self, k: usize, dir: (f64, f64)) -> Option<usize> {
        let xk = self.reference.positions[k];
        let want = (xk.0 + dir.0, xk.1 + dir.1);
        self.reference.neighbours[k]
            .iter()
            .copied()
            .map(|q| (q, dist(self.reference.positions[q], want)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .filter(|&(_, d)| d < self.reference.spacing_px[k] / 3.0)
            .map(|(q, _)| q)
    }

    /// Markers without a blob inside the matched region (three or more matched neighbours).
    fn holes(&self, matched: &[bool]) -> Vec<usize> {
        (0..matched.len())
            .filter(|&i| {
                !matched[i]
                    && self.reference.neighbours[i]
                        .iter()
                        .filter(|&&k| matched[k])
                        .count()
                        >= 3
            })
            .collect()
    }

    /// The chains a slide may move into hole `h`: `[h]`, and `[h, k1, k2, …]` (up to seven
    /// markers) stepping from each matched neighbour `k1` along the lattice step `h → k1`.
    fn chains_into(&self, h: usize, matched: &[bool]) -> Vec<Vec<usize>> {
        let mut out = vec![vec![h]];
        for &k1 in &self.reference.neighbours[h] {
            if !matched[k1] {
                continue;
            }
            let xh = self.reference.positions[h];
            let xk = self.reference.positions[k1];
            let dir = (xk.0 - xh.0, xk.1 - xh.1);
            if dir.0.hypot(dir.1) > 1.3 * self.reference.spacing_px[h] {
                continue;
            }
            let mut path = vec![h, k1];
            while path.len() <= 6 {
                out.push(path.clone());
                match self.step_from(path[path.len() - 1], dir) {
                    Some(q) if matched[q] && !path.contains(&q) => path.push(q),
                    _ => break,
                }
            }
            if path.len() > 6 {
                out.push(path);
            }
        }
        out
    }

    /// Pairs of chains of the same length stepping the same way from two holes that are lattice
    /// neighbours, both `inside` (`chains[k]`: [`Matching::chains_into`] of `holes[k]`;
    /// disjoint, two markers or more each).
    fn parallel_chains<'c>(
        &self,
        holes: &[usize],
        inside: &[bool],
        chains: &'c [Vec<Vec<usize>>],
    ) -> Vec<(&'c [usize], &'c [usize])> {
        let step = |path: &[usize]| {
            let (a, b) = (
                self.reference.positions[path[0]],
                self.reference.positions[path[1]],
            );
            (b.0 - a.0, b.1 - a.1)
        };
        let mut out = Vec::new();
        for (k1, &h1) in holes.iter().enumerate() {
            for (k2, &h2) in holes.iter().enumerate().skip(k1 + 1) {
                if !(inside[k1] && inside[k2] && self.reference.neighbours[h1].contains(&h2)) {
                    continue;
                }
                for p1 in &chains[k1] {
                    for p2 in &chains[k2] {
                        if p1.len() == p2.len()
                            && p1.len() >= 2
                            && dist(step(p1), step(p2)) < self.reference.spacing_px[h1] / 3.0
                            && !p1.iter().any(|i| p2.contains(i))
                        {
                            out.push((p1.as_slice(), p2.as_slice()));
                        }
                    }
                }
            }
        }
        out
    }

    /// Slides chains of assignments into holes: a marker without a blob inside the matched
    /// region takes its neighbour's blob, that neighbour the next one's along the same lattice
    /// step, and so on (up to six), the last taking a free blob near where its neighbours put
    /// it. A chain is applied when it lowers the energy (residuals around it, and one marker
    /// fewer without a blob); repeated while one helps. This undoes a shift by one lattice step
    /// that the matching followed into a region dragged or pushed by about a pitch.
    ///
    /// Returns the markers left in doubt, among those that moved by half a spacing or more:
    /// those of a chain ending on a free blob whose slide would change the energy by less than
    /// [`AMBIGUOUS_SLIDE`] either way — the field is then about as smooth with every blob of
    /// the chain moved one lattice step as without, and which marker holds which blob cannot
    /// be told (a drag of more than a pitch) — those of two or three parallel chains from holes
    /// side by side, [`EDGE_DEPTH`] spacings or more inside the view (a marker at the view's
    /// edge may simply be cut), whose joint slide changes it by less than
    /// [`AMBIGUOUS_ROWS_SLIDE`] (followed, with `prior`: only chains through a marker the prior
    /// frame did not see), and those [`Matching::between_holes_and_free_blobs`] (however little
    /// they seem to have moved) and [`Matching::holding_a_holes_blob`] find.
    fn slide_chains(&mut self, lost_cost: f64, prior: Option<&[Option<(f64, f64)>]>) -> Vec<usize> {
        for _ in 0..16 {
            let matched = self.matched();
            let mut best: Option<(f64, Vec<usize>, Option<usize>)> = None;
            for h in self.holes(&matched) {
                for path in self.chains_into(h, &matched) {
                    let Some((de, end, out)) = self.try_chain(&path, lost_cost) else {
                        continue;
                    };
                    // The hole alone must take a blob; a longer chain may push its last
                    // marker out of view.
                    let ends = end.is_some() || (out && path.len() > 1);
                    if ends && de < -1e-9 && best.as_ref().is_none_or(|b| de < b.0) {
                        best = Some((de, path, end));
                    }
                }
            }
            let Some((_, path, end)) = best else { break };
            self.apply_chain(&path, end);
        }
        let matched = self.matched();
        let holes = self.holes(&matched);
        let on_the_way = self.between_holes_and_free_blobs(&holes, &matched);
        let mut doubt = self.holding_a_holes_blob(&holes, &matched);
        doubt.extend(on_the_way.iter().map(|&(i, _)| i));
        // Each hole's chains, once (the single slides and the parallel pairs both try them).
        let chains: Vec<Vec<Vec<usize>>> = holes
            .iter()
            .map(|&h| self.chains_into(h, &matched))
            .collect();
        // Chains whose last marker the slide would leave without a blob, however little they
        // moved.
        let mut squeezed_out: Vec<usize> = Vec::new();
        for path in chains.iter().flatten().filter(|p| p.len() >= 2) {
            match self.try_chain(path, lost_cost) {
                Some((de, Some(_), _)) if de < AMBIGUOUS_SLIDE => {
                    doubt.extend_from_slice(&path[1..]);
                }
                // Followed, only through a marker the prior frame did not see (one seen a frame
                // ago does not jump a lattice step).
                Some((de, None, _))
                    if de < SQUEEZED_OUT_SLIDE
                        && prior.is_none_or(|p| path[1..].iter().any(|&i| p[i].is_none())) =>
                {
                    doubt.extend_from_slice(&path[1..]);
                    squeezed_out.extend_from_slice(&path[1..]);
                }
                _ => {}
            }
        }
        let (rows, slid_far) = self.parallel_rows_in_doubt(&holes, &chains, prior, lost_cost);
        doubt.extend(rows);
        // A marker that stayed within half a spacing of its rest position is not a lattice
        // step off — unless it lies between a hole and a free blob and moved towards the blob
        // by [`DRAGGED_TOWARDS`]: matched a lattice step short, a patch dragged by over a pitch
        // seems to have moved little. (With a temporal prior the motion counts from rest, not
        // from the last frame: markers squeezed together over many frames are as doubtful.)
        let dragged: Vec<usize> = on_the_way
            .iter()
            .filter(|&&(_, along)| along >= DRAGGED_TOWARDS)
            .map(|&(i, _)| i)
            .collect();
        doubt.retain(|&i| {
            let (a, r, d) = (self.anchors[i], self.reference.positions[i], self.disp[i]);
            let moved = (a.0 + d.0 - r.0).hypot(a.1 + d.1 - r.1);
            moved >= 0.5 * self.reference.spacing_px[i]
                || dragged.contains(&i)
                || slid_far.contains(&i)
                || squeezed_out.contains(&i)
        });
        doubt.sort_unstable();
        doubt.dedup();
        doubt
    }

    /// The markers of parallel chains from holes side by side — two, or three (two pairs
    /// sharing a chain) — whose joint slide changes the energy by less than
    /// [`AMBIGUOUS_ROWS_SLIDE`] ([`Matching::slide_chains`]; `chains[k]`:
    /// [`Matching::chains_into`] of `holes[k]`), and those of them the slid reading moves half
    /// a spacing (in doubt however little they seem to have moved). Three GelSight rows dragged
    /// 1.7 pitches and read a step short cost 0.76–1.26 to slide back two at a time and 0.28
    /// all three: drag matrix seeds 1–24, wrong identities 45 → 32 with three rows, 203 more
    /// lost of 43 303; held-out seeds 25–32 32 → 24, 88 more lost.
    fn parallel_rows_in_doubt(
        &mut self,
        holes: &[usize],
        chains: &[Vec<Vec<usize>>],
        prior: Option<&[Option<(f64, f64)>]>,
        lost_cost: f64,
    ) -> (Vec<usize>, Vec<usize>) {
        // Two holes side by side may be one slide of two rows: each row alone leaves a shear
        // between them that the slide of both together does not. Its markers are in doubt
        // when they moved half a spacing, or beyond the hole when one of two chain neighbours
        // would move half a spacing by taking the other's blob (a patch dragged by over a
        // pitch and read a step short seems to have moved little). Holes within `EDGE_DEPTH`
        // spacings of the view's edge start no pair (a marker there may simply be cut).
        // Followed, a marker seen in the prior frame does not jump a lattice step: only chains
        // through a marker the prior frame did not see (placed by its neighbours) may slide.
        let (mut doubt, mut slid_far) = (Vec::new(), Vec::new());
        let matched = self.matched();
        let inside: Vec<bool> = holes
            .iter()
            .map(|&h| {
                let at = self.predict(h, &matched).map_or(self.anchors[h], |p| p.0);
                self.view
                    .is_none_or(|v| v.depth_px(at) >= EDGE_DEPTH * self.reference.spacing_px[h])
            })
            .collect();
        let mut pairs = self.parallel_chains(holes, &inside, chains);
        if let Some(prior) = prior {
            pairs.retain(|(p1, p2)| p1[1..].iter().chain(&p2[1..]).any(|&i| prior[i].is_none()));
        }
        // Three rows side by side (two pairs sharing a chain) may slide together where no two
        // of them would.
        let mut groups: Vec<Vec<&[usize]>> = pairs.iter().map(|&(a, b)| vec![a, b]).collect();
        for (k, &p) in pairs.iter().enumerate() {
            groups.extend(
                pairs[k + 1..]
                    .iter()
                    .filter_map(|&q| three_rows(p, q))
                    .map(Vec::from),
            );
        }
        for group in groups {
            let (de, _) = self.try_chains(&group, lost_cost);
            if de < AMBIGUOUS_ROWS_SLIDE {
                for path in group {
                    doubt.extend_from_slice(&path[1..]);
                    // Beyond the hole: a marker that would take its neighbour's blob, and the
                    // neighbour whose blob it would take, when that moves it half a spacing.
                    for w in path[1..].windows(2) {
                        let r = self.reference.positions[w[0]];
                        let taken =
                            self.assignment[w[1]].map(|j| (self.blobs[j].x_px, self.blobs[j].y_px));
                        if taken
                            .is_some_and(|b| dist(b, r) >= 0.5 * self.reference.spacing_px[w[0]])
                        {
                            slid_far.extend_from_slice(w);
                        }
                    }
                }
            }
        }
        (doubt, slid_far)
    }

    /// The matched markers in doubt around `holes`: those whose blobs lie on the way from a
    /// hole (where its neighbours put it) to a free blob within [`HOLE_REACH`] spacings, and
    /// on the same way from the holes beside it — with holes at one end and spare blobs at the
    /// other, each blob between may belong to the next marker along (a patch dragged by over a
    /// pitch and matched one lattice step short). Each with how far it moved along that way,
    /// in spacings.
    fn between_holes_and_free_blobs(&self, holes: &[usize], matched: &[bool]) -> Vec<(usize, f64)> {
        let at: Vec<Option<((f64, f64), f64)>> =
            holes.iter().map(|&h| self.predict(h, matched)).collect();
        // (hole, the way from it to a free blob)
        let mut ways: Vec<(usize, (f64, f64))> = Vec::new();
        for (k, &h) in holes.iter().enumerate() {
            let Some((p, scale)) = at[k] else { continue };
            let reach = HOLE_REACH * self.reference.spacing_px[h] * scale;
            self.index.near(p, reach, |j, _| {
                if !self.taken[j] {
                    ways.push((k, (self.blobs[j].x_px - p.0, self.blobs[j].y_px - p.1)));
                }
            });
        }
        let mut out = Vec::new();
        for (k, &h) in holes.iter().enumerate() {
            let Some((p, scale)) = at[k] else { continue };
            let s = self.reference.spacing_px[h] * scale;
            for &(from, v) in &ways {
                let beside = at[from].is_some_and(|(q, _)| dist(p, q) < 1.5 * s);
                if from == k || beside {
                    self.push_on_segment(p, v, 0.5 * s, &mut out);
                }
            }
        }
        out
    }

    /// The matched markers holding a blob that fits a hole beside them about as well: the blob
    /// nearest where a hole's neighbours put it (within [`HOLE_BLOB_REACH`]) belongs to a
    /// neighbour whose own prediction is no nearer to it than
    /// [`TrackConfig::ambiguity_ratio`] times — the blob may be the hole's and the neighbour's
    /// own blob elsewhere or gone.
    fn holding_a_holes_blob(&self, holes: &[usize], matched: &[bool]) -> Vec<usize> {
        let mut owner: Vec<Option<usize>> = vec![None; self.blobs.len()];
        for (i, a) in self.assignment.iter().enumerate() {
            if let Some(j) = *a {
                owner[j] = Some(i);
            }
        }
        let mut out = Vec::new();
        for &h in holes {
            let Some((p, _)) = self.predict(h, matched) else {
                continue;
            };
            let gate = HOLE_BLOB_REACH * self.reference.spacing_px[h];
            let Some(j) = self.index.nearest(p, gate) else {
                continue;
            };
            let Some(k) = owner[j] else { continue };
            let b = (self.blobs[j].x_px, self.blobs[j].y_px);
            let own = self.predict(k, matched).map_or(0.0, |(q, _)| dist(b, q));
            if own * self.cfg.ambiguity_ratio >= dist(b, p) {
                out.push(k);
            }
        }
        out
    }

    /// Pushes the matched markers whose blobs lie within `width` of the segment from `p` along
    /// `v`, each with its displacement along `v` in spacings.
    fn push_on_segment(
        &self,
        p: (f64, f64),
        v: (f64, f64),
        width: f64,
        out: &mut Vec<(usize, f64)>,
    ) {
        let len2 = (v.0 * v.0 + v.1 * v.1).max(1e-12);
        for (i, a) in self.assignment.iter().enumerate() {
            let Some(j) = *a else { continue };
            let b = (self.blobs[j].x_px, self.blobs[j].y_px);
            let t = ((b.0 - p.0) * v.0 + (b.1 - p.1) * v.1) / len2;
            let on = (p.0 + t * v.0, p.1 + t * v.1);
            if (0.0..=1.0).contains(&t) && dist(b, on) < width {
                let d = self.disp[i];
                let along = (d.0 * v.0 + d.1 * v.1) / len2.sqrt() / self.reference.spacing_px[i];
                out.push((i, along));
            }
        }
    }

    /// The energy change of sliding `path` (see [`Matching::slide_chains`]), the free blob its
    /// last marker would take, and whether that marker, left without one, would be out of view.
    fn try_chain(&mut self, path: &[usize], lost_cost: f64) -> Option<(f64, Option<usize>, bool)> {
        let (de, ends) = self.try_chains(&[path], lost_cost);
        ends.first().map(|&(end, out)| (de, end, out))
    }

    /// The energy change of sliding every path of `paths` at once (disjoint chains, see
    /// [`Matching::slide_chains`]), and per path the free blob its last marker would take and
    /// whether that marker, left without one, would be out of view.
    fn try_chains(
        &mut self,
        paths: &[&[usize]],
        lost_cost: f64,
    ) -> (f64, Vec<(Option<usize>, bool)>) {
        let mut area: Vec<usize> = Vec::new();
        for &i in paths.iter().copied().flatten() {
            area.push(i);
            area.extend(self.reference.neighbours[i].iter().copied());
        }
        area.sort_unstable();
        area.dedup();
        let before = self.local_energy(&area, lost_cost);
        // Where the field put each last marker before the slide (as a position): a chain may
        // only push a marker out of view that the field already puts near the view's edge.
        let near_edge: Vec<bool> = {
            let matched = self.matched();
            paths
                .iter()
                .map(|path| {
                    let last = path[path.len() - 1];
                    let here = self.assignment[last]
                        .map(|j| (self.blobs[j].x_px, self.blobs[j].y_px))
                        .or_else(|| self.predict(last, &matched).map(|p| p.0));
                    self.view.zip(here).is_some_and(|(v, p)| {
                        v.depth_px(p) < 0.85 * self.reference.spacing_px[last]
                    })
                })
                .collect()
        };
        let saved: Vec<(usize, Option<usize>, (f64, f64))> = paths
            .iter()
            .copied()
            .flatten()
            .map(|&i| (i, self.assignment[i], self.disp[i]))
            .collect();
        for path in paths {
            self.shift_chain(path);
        }
        let matched = self.matched();
        let mut ends = Vec::with_capacity(paths.len());
        let mut explained = 0.0;
        for (path, near_edge) in paths.iter().zip(near_edge) {
            let last = path[path.len() - 1];
            // The last marker: the nearest free blob to its new prediction, within a spacing.
            let predicted_last = self.predict(last, &matched);
            let end = predicted_last.and_then(|(p, scale)| {
                let gate = self.reference.spacing_px[last] * scale.clamp(0.7, 1.6);
                nearest_two(p, &self.index, &self.taken, gate)
                    .0
                    .map(|(j, _)| j)
            });
            // Out of view: cut by the view's edge or beyond it, where its neighbours put it or
            // where the chain carries it (moved as the marker before it in the chain).
            let radius = (self.reference.areas_px[last] / std::f64::consts::PI).sqrt();
            let carried = (path.len() >= 2).then(|| {
                let d = self.disp[path[path.len() - 2]];
                let a = self.anchors[last];
                (a.0 + d.0, a.1 + d.1)
            });
            let out = near_edge
                && self.view.is_some_and(|v| {
                    predicted_last
                        .into_iter()
                        .chain(carried.map(|p| (p, 1.0)))
                        .any(|(p, scale)| v.depth_px(p) < radius * scale)
                });
            if let Some(j) = end {
                self.take(last, j);
            }
            // A hole moved out of the view is explained: it counts half (the slide must still
            // leave the field about as smooth).
            if end.is_none() && out {
                explained += 0.5 * lost_cost;
            }
            ends.push((end, out));
        }
        let after = self.local_energy(&area, lost_cost);
        // Restore.
        for &i in paths.iter().copied().flatten() {
            self.release(i);
        }
        for (i, a, d) in saved {
            if let Some(j) = a {
                self.take(i, j);
            }
            self.disp[i] = d;
        }
        (after - before - explained, ends)
    }

    /// Each marker of `path` takes the blob the next one holds; the last is left without one.
    fn shift_chain(&mut self, path: &[usize]) {
        let blobs_of: Vec<Option<usize>> = path.iter().map(|&i| self.assignment[i]).collect();
        for &i in path {
            self.release(i);
        }
        for (&i, next) in path.iter().zip(&blobs_of[1..]) {
            if let Some(j) = *next {
                self.take(i, j);
            }
        }
    }

    /// Slides `path` and gives its last marker `end`.
    fn apply_chain(&mut self, path: &[usize], end: Option<usize>) {
        self.shift_chain(path);
        if let Some(j) = end {
            self.take(path[path.len() - 1], j);
        }
    }

    /// Releases matched markers whose blob disagrees with their neighbours' prediction; returns
    /// how many were released.
    fn verify(&mut self) -> usize {
        let n = self.assignment.len();
        let matched = self.matched();
        let mut bad = Vec::new();
        for i in 0..n {
            let Some(j) = self.assignment[i] else {
                continue;
            };
            if self.support(i) < 3 {
                continue;
            }
            let Some((pred, scale)) = self.predict(i, &matched) else {
                continue;
            };
            let b = (self.blobs[j].x_px, self.blobs[j].y_px);
            if dist(b, pred) > self.cfg.verify_pitches * self.reference.spacing_px[i] * scale {
                bad.push(i);
            }
        }
        for &i in &bad {
            self.release(i);
        }
        bad.len()
    }
}

/// The part of the image where markers can be seen: a rectangle (the image or its region of
/// interest), optionally cut to a circle (a circular view).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Left edge, pixels (pixel centres at integers: the first column spans −0.5..0.5).
    pub x0: f64,
    /// Top edge, pixels.
    pub y0: f64,
    /// Right edge, pixels.
    pub x1: f64,
    /// Bottom edge, pixels.
    pub y1: f64,
    /// Centre and radius of the circular view, pixels.
    pub circle: Option<((f64, f64), f64)>,
}

impl View {
    /// How far `p` lies inside the view (distance to its nearest edge; negative outside).
    pub fn depth_px(&self, p: (f64, f64)) -> f64 {
        let mut d = (p.0 - self.x0)
            .min(self.x1 - p.0)
            .min(p.1 - self.y0)
            .min(self.y1 - p.1);
        if let Some((c, r)) = self.circle {
            d = d.min(r - dist(p, c));
        }
        d
    }
}

/// What the tracker may use besides the blobs.
#[derive(Clone, Copy, Debug, Default)]
pub struct TrackHints<'a> {
    /// The last `cut` blobs are markers cut by the image border (dropped by the blob filter):
    /// a marker that takes one left the view and is reported lost, never measured — unless the
    /// blob is as big as the marker at rest within the pixel noise of its outline (it touches
    /// the edge without being cut by it).
    pub cut: usize,
    /// Each marker's position in an earlier frame of the same video (`None` for markers it did
    /// not have): tracking starts from there instead of from the reference.
    pub prior: Option<&'a [Option<(f64, f64)>]>,
    /// Where markers can be seen: a marker whose neighbours put it outside has left the view,
    /// which explains its having no blob.
    pub view: Option<View>,
}

/// Matches every reference marker to at most one blob of the frame, each frame on its own.
pub fn track(reference: &TrackReference, blobs: &[Blob], cfg: &TrackConfig) -> TrackResult {
    track_with(reference, blobs, cfg, TrackHints::default())
}

/// Where each marker starts from the last frame's positions `p`: its own, or for a marker the
/// last frame did not have, where its neighbours' motion since the reference puts it.
fn anchors_from_prior(reference: &TrackReference, p: &[Option<(f64, f64)>]) -> Vec<(f64, f64)> {
    (0..reference.positions.len())
        .map(|i| {
            let r = reference.positions[i];
            p[i].unwrap_or_else(|| {
                let (mut sx, mut sy, mut k) = (0.0, 0.0, 0.0);
                for &j in &reference.neighbours[i] {
                    if let Some(q) = p[j] {
                        let rj = reference.positions[j];
                        sx += q.0 - rj.0;
                        sy += q.1 - rj.1;
                        k += 1.0;
                    }
                }
                if k > 0.0 {
                    (r.0 + sx / k, r.1 + sy / k)
                } else {
                    r
                }
            })
        })
        .collect()
}

/// The unmatched markers' statuses, the blobs that swallowed a neighbour, and (blob, marker,
/// predicted position, local magnification) of every merged marker.
struct Classified {
    status: Vec<MarkerStatus>,
    merged_blob: Vec<bool>,
    on_blob: Vec<OnBlob>,
}

impl Matching<'_> {
    /// A marker without a blob, or a blob without a marker: the growth may have followed a
    /// lattice-shifted path (a region dragged by about a pitch leaves a hole at one end and a
    /// spare blob at the other). Matches everything at once instead; keeps whichever result
    /// matches more markers (then the smoother one).
    fn rematch_if_better(&mut self, predicted: &[(f64, f64)]) {
        let m = self;
        if m.assignment.iter().any(Option::is_none) || m.taken.iter().any(|t| !t) {
            let lost_cost = 1.0;
            let before = (
                m.assignment.clone(),
                m.disp.clone(),
                m.taken.clone(),
                m.support.clone(),
            );
            let found = |m: &Matching<'_>| m.assignment.iter().filter(|a| a.is_some()).count();
            let (found_before, e_before) = (found(m), m.energy(lost_cost));
            m.reassign(predicted);
            let found_after = found(m);
            let better = found_after > found_before
                || (found_after == found_before && m.energy(lost_cost) < e_before);
            if better {
                // The reassignment fills holes from afar: a marker it gave a blob its neighbours
                // do not agree with (a piece of a neighbour's blob) is released and grown again.
                if m.verify() > 0 {
                    m.grow();
                }
            } else {
                (m.assignment, m.disp, m.taken, m.support) = before;
            }
        }
    }

    /// Markers no growth reached (no matched neighbours at all) keep a plain gated look-up.
    fn look_up_unreached(&mut self, predicted: &[(f64, f64)]) {
        let (reference, cfg) = (self.reference, self.cfg);
        for (i, &p) in predicted.iter().enumerate() {
            if self.assignment[i].is_none() && self.support(i) == 0 {
                let s = reference.spacing_px[i];
                let (best, second) = nearest_two(p, &self.index, &self.taken, cfg.gate_pitches * s);
                if let Some((j, d)) = best {
                    if second >= cfg.ambiguity_ratio * d.max(0.05 * s) {
                        self.take(i, j);
                    }
                }
            }
        }
    }

    /// The taken blob unmatched marker `i` (predicted at `pred`, local magnification `scale`)
    /// shares with its owner when the two are squeezed together: the blob nearest `pred` is
    /// within [`CROWDED`] spacings of it, no free blob is as near, the blob is within
    /// [`CROWDED`] spacings of the owner's own prediction too (one blob between two markers
    /// predicted closer than a lattice step allows), and the blob is bigger than either marker by
    /// [`CROWDED_AREA`] — pins squeezed under a deep press overlap and hide each other, so
    /// their blob is not twice a pin, but a marker whose neighbour vanished behind it keeps
    /// its own size.
    fn crowded_onto(
        &self,
        i: usize,
        (pred, scale): ((f64, f64), f64),
        owner: &[Option<usize>],
        matched: &[bool],
    ) -> Option<usize> {
        let reach = CROWDED * self.reference.spacing_px[i];
        let j = self.index.nearest(pred, reach)?;
        let k = owner[j]?;
        let b = (self.blobs[j].x_px, self.blobs[j].y_px);
        if nearest_two(pred, &self.index, &self.taken, dist(b, pred))
            .0
            .is_some()
        {
            return None;
        }
        let (pk, _) = self.predict(k, matched)?;
        let areas = &self.reference.areas_px;
        let bigger = CROWDED_AREA * areas[k].min(areas[i]) * scale * scale;
        (dist(pk, b) < reach && f64::from(self.blobs[j].area_px) >= bigger).then_some(j)
    }

    /// The markers (reported [`MarkerStatus::Ok`] in `status`) holding a swollen blob (at
    /// least [`SWOLLEN_AREA`] times their area scaled by the local magnification, or
    /// [`SWOLLEN_BESIDE`] times their area scaled as their neighbours' blobs are, or of two
    /// lobes, [`TWO_LOBES_FILL`]), within [`SWOLLEN_REACH`] spacings of the prediction of a
    /// neighbour left without a position (no blob, or one in doubt or merged), or within
    /// [`SWOLLEN_FAR_REACH`] if [`SWOLLEN_FAR_BESIDE`] times as swollen as its neighbours'
    /// blobs: the blob is likely both of theirs (a marker dragged onto the next one and hidden
    /// behind it), and its centroid neither's, though well under the merged size. (A neighbour
    /// in doubt or merged holds a blob that is not its own; drag matrix seeds 1–16, wrong
    /// identities 20 → 18 for 255 more lost of 27 478.)
    fn holding_a_swollen_blob(&self, status: &[MarkerStatus]) -> Vec<usize> {
        let matched = self.matched();
        let mut out = Vec::new();
        for k in (0..status.len()).filter(|&k| {
            self.assignment[k].is_none()
                || matches!(status[k], MarkerStatus::Ambiguous | MarkerStatus::Merged)
        }) {
            let Some((pk, _)) = self.predict(k, &matched) else {
                continue;
            };
            let reach = SWOLLEN_REACH * self.reference.spacing_px[k];
            let far = SWOLLEN_FAR_REACH * self.reference.spacing_px[k];
            for &i in &self.reference.neighbours[k] {
                let Some(j) = self.assignment[i] else {
                    continue;
                };
                let b = &self.blobs[j];
                let d = dist((b.x_px, b.y_px), pk);
                if status[i] != MarkerStatus::Ok || d > far || out.contains(&i) {
                    continue;
                }
                let ratio = f64::from(b.area_px) / self.reference.areas_px[i];
                let swollen_beside = |factor: f64| {
                    self.neighbours_area_ratio(i, status)
                        .is_some_and(|r| ratio >= factor * r)
                };
                let swollen = if d <= reach {
                    let scale = self.predict(i, &matched).map_or(1.0, |(_, s)| s);
                    ratio >= SWOLLEN_AREA * scale * scale
                        || swollen_beside(SWOLLEN_BESIDE)
                        || (self.reference.areas_px[i] >= TWO_LOBES_MIN_AREA_PX
                            && ellipse_fill(b) < TWO_LOBES_FILL)
                } else {
                    // Beyond `reach` only a blob of two whole markers against its neighbours'.
                    swollen_beside(SWOLLEN_FAR_BESIDE)
                };
                if swollen {
                    out.push(i);
                }
            }
        }
        out
    }

    /// The median, over `i`'s lattice neighbours matched and reported [`MarkerStatus::Ok`], of
    /// their blob's area over their area at rest (`None` without such neighbours).
    fn neighbours_area_ratio(&self, i: usize, status: &[MarkerStatus]) -> Option<f64> {
        let mut ratios: Vec<f64> = lattice_steps(self.reference, &self.anchors, i)
            .filter(|&n| status[n] == MarkerStatus::Ok)
            .filter_map(|n| {
                let j = self.assignment[n]?;
                Some(f64::from(self.blobs[j].area_px) / self.reference.areas_px[n])
            })
            .collect();
        // The upper median (`layout::median` averages the middle two of an even count: 3 more
        // markers lost on the drag matrix, measured).
        ratios.sort_by(f64::total_cmp);
        ratios.get(ratios.len() / 2).copied()
    }

    /// Classifies the unmatched markers: merged (a blob covering the prediction and much
    /// larger than the marker), ambiguous or lost.
    fn classify_unmatched(&self, predicted: &[(f64, f64)], usable: usize) -> Classified {
        let (m, reference, blobs, cfg) = (self, self.reference, self.blobs, self.cfg);
        let n = reference.positions.len();
        let mut status = vec![MarkerStatus::Ok; n];
        let mut merged_blob = vec![false; blobs.len()];
        // (blob, marker, predicted position, local magnification) of every merged marker.
        let mut on_blob: Vec<OnBlob> = Vec::new();
        let matched = m.matched();
        // The marker holding each blob.
        let mut owner: Vec<Option<usize>> = vec![None; blobs.len()];
        for (i, a) in m.assignment.iter().enumerate() {
            if let Some(j) = *a {
                owner[j] = Some(i);
            }
        }
        for i in 0..n {
            if m.assignment[i].is_some() {
                continue;
            }
            let (pred, scale) = m.predict(i, &matched).unwrap_or((predicted[i], 1.0));
            let expected_area = reference.areas_px[i] * scale * scale;
            // A blob covering the prediction and much larger than this marker: merged (with the
            // marker that took it, or with a neighbour that is also left without a blob).
            // The prediction may miss a merged blob's box by a little: the pair's centroid sits
            // between the two markers.
            let margin = 0.3 * reference.spacing_px[i] - 0.5;
            let merged_with = blobs[..usable]
                .iter()
                .enumerate()
                .find(|&(j, b)| {
                    let owner_area =
                        owner[j].map_or(expected_area, |k| reference.areas_px[k] * scale * scale);
                    f64::from(b.area_px) >= cfg.merged_area_ratio * expected_area.min(owner_area)
                        && pred.0 >= f64::from(b.bbox.x0) - margin
                        && pred.0 <= f64::from(b.bbox.x1) + margin - 1.0
                        && pred.1 >= f64::from(b.bbox.y0) - margin
                        && pred.1 <= f64::from(b.bbox.y1) + margin - 1.0
                })
                .or_else(|| {
                    m.crowded_onto(i, (pred, scale), &owner, &matched)
                        .map(|j| (j, &blobs[j]))
                });
            status[i] = if let Some((j, _)) = merged_with {
                // The owner of that blob is merged too: its centroid is no longer its own.
                if let Some(k) = owner[j] {
                    status[k] = MarkerStatus::Merged;
                    let (pk, sk) = m.predict(k, &matched).unwrap_or((predicted[k], 1.0));
                    on_blob.push((j, k, pk, sk));
                }
                on_blob.push((j, i, pred, scale));
                merged_blob[j] = true;
                MarkerStatus::Merged
            } else {
                let s = reference.spacing_px[i];
                let (best, second) = nearest_two(pred, &m.index, &m.taken, cfg.gate_pitches * s);
                match best {
                    Some((_, d)) if second < cfg.ambiguity_ratio * d.max(0.05 * s) => {
                        MarkerStatus::Ambiguous
                    }
                    _ => MarkerStatus::Lost,
                }
            };
        }
        Classified {
            status,
            merged_blob,
            on_blob,
        }
    }
}

/// Matches every reference marker to at most one blob of the frame, with `hints`: markers cut
/// by the border, and a temporal prior (without one, tracking starts from the reference after
/// the registration's overall motion).
pub fn track_with(
    reference: &TrackReference,
    blobs: &[Blob],
    cfg: &TrackConfig,
    hints: TrackHints<'_>,
) -> TrackResult {
    let usable = blobs.len() - hints.cut.min(blobs.len());
    if let Some(sizes) = &reference.ring_sizes_px {
        return track_rings(reference, sizes, &blobs[..usable]);
    }
    let n = reference.positions.len();
    // Followed: a temporal prior with a position (or none) for every marker.
    let prior = hints.prior.filter(|p| p.len() == n);
    let index = BlobIndex::new(blobs, reference.pitch_px.max(1.0));
    let (anchors, shift) = match prior {
        Some(p) => {
            let a = anchors_from_prior(reference, p);
            (a, (0.0, 0.0))
        }
        _ => (
            reference.positions.clone(),
            register(reference, &index, cfg),
        ),
    };
    let mut m = Matching {
        reference,
        blobs,
        index,
        cfg,
        anchors,
        view: hints.view,
        assignment: vec![None; n],
        disp: vec![(0.0, 0.0); n],
        taken: vec![false; blobs.len()],
        support: vec![0; n],
    };
    let predicted: Vec<(f64, f64)> = m
        .anchors
        .iter()
        .map(|&(x, y)| (x + shift.0, y + shift.1))
        .collect();
    m.seed(&predicted);
    m.grow();
    if m.verify() > 0 {
        m.grow();
    }
    m.rematch_if_better(&predicted);
    let doubtful = m.slide_chains(1.0, prior);

    m.look_up_unreached(&predicted);
    // Classify the unmatched, and flag matched blobs that swallowed a neighbour.
    let Classified {
        mut status,
        merged_blob,
        mut on_blob,
    } = m.classify_unmatched(&predicted, usable);
    let (mut split_px, stretched) =
        split_pairs(reference, blobs, cfg, &mut on_blob, prior, &mut status);
    lose_cut(&m, usable, &mut status);
    let held = put_in_doubt(
        &m,
        (&doubtful, &stretched),
        &predicted,
        prior,
        (shift, usable, &on_blob),
        &mut status,
    );
    for i in stretched {
        if status[i] == MarkerStatus::Merged {
            split_px[i] = None;
        }
    }
    let held_px = held_positions(&m, &held);
    let mut assignment = m.assignment;
    for (a, st) in assignment.iter_mut().zip(&status) {
        if *st != MarkerStatus::Ok {
            *a = None;
        }
    }
    TrackResult {
        assignment,
        status,
        shift_px: shift,
        spurious: (0..usable)
            .filter(|&j| !m.taken[j] && !merged_blob[j])
            .count(),
        split_px,
        held_px,
    }
}

/// Puts in doubt every [`MarkerStatus::Split`] marker a lattice step from an
/// [`MarkerStatus::Ambiguous`] one (repeated, so both of a pair go): which two markers share a
/// blob rests on the same lattice steps as the identities in doubt beside it (a pin split from
/// its neighbour's blob in a patch matched a lattice step short).
fn doubt_split_beside_doubt(
    reference: &TrackReference,
    anchors: &[(f64, f64)],
    status: &mut [MarkerStatus],
) {
    loop {
        let doubtful: Vec<usize> = (0..status.len())
            .filter(|&i| {
                status[i] == MarkerStatus::Split
                    && lattice_steps(reference, anchors, i)
                        .any(|k| status[k] == MarkerStatus::Ambiguous)
            })
            .collect();
        if doubtful.is_empty() {
            return;
        }
        for i in doubtful {
            status[i] = MarkerStatus::Ambiguous;
        }
    }
}

/// A marker that took a blob cut by the border (from `usable` on) has left the view: lost —
/// unless the blob is as big as the marker at rest, scaled by the local magnification of its
/// neighbours' motion, within the pixel noise of its outline ([`whole`]): then nothing of it is
/// missing (a marker ending a pixel short of a circular mask's edge touches it). Scaled, as a
/// pin half out of view under a deep press has swollen beyond its size at rest (small TacTip,
/// drag seed 35: a pin centred 1.9 px outside the mask, its cut blob 11 px against 13 at rest
/// and 19 swollen, was measured 3.2 px off; drag matrix seeds 1–40: wrong identities 68 → 63,
/// 20 fewer lost).
fn lose_cut(m: &Matching<'_>, usable: usize, status: &mut [MarkerStatus]) {
    // Most frames have no marker on a cut blob: the matched set only for those that do.
    let mut matched: Option<Vec<bool>> = None;
    for (i, (st, a)) in status.iter_mut().zip(&m.assignment).enumerate() {
        let Some(j) = a.filter(|&j| j >= usable) else {
            continue;
        };
        let matched = matched.get_or_insert_with(|| m.matched());
        let s = m.predict(i, matched).map_or(1.0, |(_, s)| s);
        if !whole(m.blobs[j].area_px, m.reference.areas_px[i] * s * s, m.cfg) {
            *st = MarkerStatus::Lost;
        }
    }
}

/// The three chains of two pairs of parallel chains that share exactly one chain, the shared
/// one in the middle (`None` when they share none, or the other two overlap).
fn three_rows<'c>(
    (a, b): (&'c [usize], &'c [usize]),
    (c, d): (&'c [usize], &'c [usize]),
) -> Option<[&'c [usize]; 3]> {
    let (middle, x) = if a == c || a == d {
        (a, b)
    } else if b == c || b == d {
        (b, a)
    } else {
        return None;
    };
    let y = if middle == c { d } else { c };
    (x != y && !x.iter().any(|i| y.contains(i))).then_some([x, middle, y])
}

/// Puts in doubt ([`MarkerStatus::Ambiguous`]) the matched markers that `doubtful` (the chain
/// slides') names, then those [`doubt_around_gaps`] (order-free matching only: a temporal prior
/// follows a drag step by step), [`doubt_split_beside_doubt`] and, when followed (`prior`: the
/// markers' positions in the prior frame), [`doubt_reacquired_beside_unseen`] find; then
/// reports [`MarkerStatus::Merged`] the pairs split from one `stretched` marker
/// ([`one_stretched_marker`]) and, order-free, last, the markers
/// [`Matching::holding_a_swollen_blob`] finds — followed too, where those are returned: the
/// next frame starts from the blob they held ([`TrackResult::held_px`]). `on_blob` (the
/// markers merged on each blob) sets the motion a frame needs for gaps
/// ([`gaps_frame_motion`]).
fn put_in_doubt(
    m: &Matching<'_>,
    (doubtful, stretched): (&[usize], &[usize]),
    predicted: &[(f64, f64)],
    prior: Option<&[Option<(f64, f64)>]>,
    (shift, usable, on_blob): ((f64, f64), usize, &[OnBlob]),
    status: &mut [MarkerStatus],
) -> Vec<usize> {
    let reference = m.reference;
    for &i in doubtful {
        if status[i] == MarkerStatus::Ok {
            status[i] = MarkerStatus::Ambiguous;
        }
    }
    let gaps = prior.is_none().then(|| {
        // `on_blob` is sorted by blob (`split_pairs`); a split leaves no status Ok to doubt.
        let frame_motion = gaps_frame_motion(m, on_blob, status, shift);
        doubt_around_gaps(reference, m, status, (shift, usable, frame_motion))
    });
    for i in gaps.into_iter().flatten() {
        status[i] = MarkerStatus::Ambiguous;
    }
    doubt_split_beside_doubt(reference, &m.anchors, status);
    // After the gaps, which they would widen: split, their neighbours saw them.
    for &i in stretched {
        if status[i] == MarkerStatus::Split {
            status[i] = MarkerStatus::Merged;
        }
    }
    if let Some(prior) = prior {
        doubt_reacquired_beside_unseen(m, prior, predicted, status);
    }
    // After the gaps, which a merged marker would widen. Followed, the marker's track goes on
    // from its blob: predicted from its neighbours alone the next frame swapped more
    // identities (22 → 27 on the followed drag matrix); and only in frames moved a pitch from
    // rest (one GelSight dot merged in a frame moved 0.98 pitch, drag matrix seed 4).
    let moved = prior.is_none() || moved_from_rest(m, status, FRAME_MOTION);
    let held = if moved {
        m.holding_a_swollen_blob(status)
    } else {
        Vec::new()
    };
    for &i in &held {
        status[i] = MarkerStatus::Merged;
    }
    held
}

/// [`TrackResult::held_px`]: the blob centroid of each of the markers `held` (empty when none).
fn held_positions(m: &Matching<'_>, held: &[usize]) -> Vec<Option<(f64, f64)>> {
    if held.is_empty() {
        return Vec::new();
    }
    let mut out = vec![None; m.assignment.len()];
    for &i in held {
        out[i] = m.assignment[i].map(|j| (m.blobs[j].x_px, m.blobs[j].y_px));
    }
    out
}

/// Whether some marker reported [`MarkerStatus::Ok`] holds a blob `spacings` of its spacings
/// or more from its reference position.
fn moved_from_rest(m: &Matching<'_>, status: &[MarkerStatus], spacings: f64) -> bool {
    (0..status.len()).any(|k| {
        let step = spacings * m.reference.spacing_px[k];
        status[k] == MarkerStatus::Ok
            && m.assignment[k].is_some_and(|j| {
                let b = &m.blobs[j];
                dist_sq((b.x_px, b.y_px), m.reference.positions[k]) >= step * step
            })
    })
}

/// Followed tracking: puts in doubt ([`MarkerStatus::Ambiguous`]) a marker that had no
/// position in the prior frame and takes a blob now, when a lattice neighbour that had none
/// either is still without a blob of its own and its prediction lies within [`UNSEEN_REACH`]
/// spacings of that blob. Both predictions come from their neighbours' motion alone (the two
/// were lost or merged a frame ago), and which of the two the blob shows no test can tell: at
/// the front of a drag a pin hidden behind its neighbour otherwise takes the neighbour's blob,
/// a lattice step off, and holds it frame after frame.
fn doubt_reacquired_beside_unseen(
    m: &Matching<'_>,
    prior: &[Option<(f64, f64)>],
    predicted: &[(f64, f64)],
    status: &mut [MarkerStatus],
) {
    let reference = m.reference;
    let unseen = |k: usize| prior[k].is_none();
    let doubtful: Vec<usize> = (0..status.len())
        .filter(|&i| status[i] == MarkerStatus::Ok && unseen(i))
        .filter_map(|i| m.assignment[i].map(|j| (i, j)))
        .filter(|&(i, j)| {
            let b = (m.blobs[j].x_px, m.blobs[j].y_px);
            lattice_steps(reference, &m.anchors, i).any(|k| {
                unseen(k)
                    && m.assignment[k].is_none()
                    && dist(predicted[k], b) < UNSEEN_REACH * reference.spacing_px[k]
            })
        })
        .map(|(i, _)| i)
        .collect();
    for i in doubtful {
        status[i] = MarkerStatus::Ambiguous;
    }
}

/// Whether a blob of `area_px` cut by the border is still a whole marker of `rest_area_px`:
/// no smaller than the marker at rest by more than the square root of its outline's length in
/// pixels (about how much a marker's pixel count varies from frame to frame; 3 px for a 6-px
/// pin, 8 px for a 400-px marker, whose centroid a cut of that size moves by 0.2 px), and not
/// so big that it holds more than the marker (a merged blob, or a sensor's rim cut by the
/// frame).
fn whole(area_px: u32, rest_area_px: f64, cfg: &TrackConfig) -> bool {
    let outline_px = 2.0 * (std::f64::consts::PI * rest_area_px).sqrt();
    let a = f64::from(area_px);
    a >= rest_area_px - outline_px.sqrt() && a < cfg.merged_area_ratio * rest_area_px
}

/// The markers in doubt around gaps in a moving field. A gap is a marker without a position
/// (lost, ambiguous or merged) inside the field (two or more reference neighbours a lattice
/// step away) beside a matched neighbour that moved by [`GAP_MOTION`] spacings or more beyond
/// the overall motion. Every matched marker a lattice step from the gap, and every one within
/// `GAP_REACH × (1 + motion)` spacings ahead of it (along its neighbours' mean motion; `motion`
/// the largest), is put in doubt; so is a matched marker none of whose neighbours a lattice
/// step away holds a blob outside the doubt (it took its blob on its own). Only in frames
/// where some matched marker moved by `frame_motion` spacings ([`gaps_frame_motion`]), or by
/// [`MANY_GAPS_MOTION`] in a frame with [`MANY_GAPS`] gaps: a lattice-step error needs a
/// lattice step of motion.
///
/// Why: a patch dragged by over a pitch loses markers where the skin bunches up ahead of the
/// drag; the matching can then put the patch one lattice step short, with the missing marker
/// at the back of it instead of the front, and the field is about as smooth either way — no
/// local test tells the two apart. On the simulator's drags (`check-tracking --protocol drag`,
/// four sensor families, 0.5–1.5 pitch) the wrong identities lie ahead of such gaps, and no
/// frame moved by under a pitch loses a marker to this rule. A gap its neighbours moved out to
/// within a spacing of the view's edge, or on a blob cut by the border, is a marker leaving
/// the view, not a gap.
fn doubt_around_gaps(
    reference: &TrackReference,
    m: &Matching<'_>,
    status: &[MarkerStatus],
    (shift, usable, frame_motion): ((f64, f64), usize, f64),
) -> Vec<usize> {
    let held = |k: usize| m.assignment[k].is_some() && status[k] == MarkerStatus::Ok;
    // The largest motion of a held marker beyond the overall motion, in spacings (one pass).
    let largest = (0..status.len())
        .filter(|&k| held(k))
        .map(|k| dist_sq(m.disp[k], shift).sqrt() / reference.spacing_px[k])
        .fold(0.0, f64::max);
    if largest < frame_motion.min(MANY_GAPS_MOTION) {
        return Vec::new();
    }
    let gaps: Vec<(usize, f64, (f64, f64))> = status
        .iter()
        .enumerate()
        .filter(|&(g, st)| !st.has_position() && m.assignment[g].is_none_or(|j| j < usable))
        .filter_map(|(g, _)| {
            gap_motion(reference, m, g, shift, &held).map(|(motion, dir)| (g, motion, dir))
        })
        .collect();
    // Markers the matching left without a blob: those put in doubt on the blob they hold (a
    // chain that could slide) are no sign of a slide across rows.
    let blobless = gaps.iter().filter(|e| m.assignment[e.0].is_none()).count();
    if largest < frame_motion && blobless < MANY_GAPS {
        return Vec::new();
    }
    let matched = m.matched();
    let mut out = Vec::new();
    for &(g, motion, dir) in &gaps {
        // Where its neighbours put it: a marker pushed out to the edge of the view has left it.
        let s = reference.spacing_px[g];
        let at = m.anchors[g];
        let leaving = m
            .view
            .zip(m.predict(g, &matched))
            .is_some_and(|(v, (p, _))| {
                let before = v.depth_px((at.0 + shift.0, at.1 + shift.1));
                v.depth_px(p) < s && v.depth_px(p) < before - 0.25 * s
            });
        if leaving {
            continue;
        }
        let (near, reach) = (NEIGHBOUR_STEP * s, GAP_REACH * (1.0 + motion) * s);
        out.extend((0..status.len()).filter(|&i| {
            let o = (m.anchors[i].0 - at.0, m.anchors[i].1 - at.1);
            let d2 = o.0 * o.0 + o.1 * o.1;
            let ahead = o.0 * dir.0 + o.1 * dir.1 >= 0.0;
            held(i) && (d2 <= near * near || (d2 <= reach * reach && ahead))
        }));
    }
    out.sort_unstable();
    out.dedup();
    let alone = alone_beside_doubt(reference, m, &held, &out);
    out.extend(alone);
    out.sort_unstable();
    out
}

/// The matched markers outside `doubt` (sorted) none of whose neighbours a lattice step away
/// holds a blob outside it.
fn alone_beside_doubt(
    reference: &TrackReference,
    m: &Matching<'_>,
    held: &impl Fn(usize) -> bool,
    doubt: &[usize],
) -> Vec<usize> {
    let in_doubt = |k: usize| doubt.binary_search(&k).is_ok();
    (0..m.assignment.len())
        .filter(|&i| held(i) && !in_doubt(i))
        .filter(|&i| {
            let mut steps = lattice_steps(reference, &m.anchors, i).peekable();
            steps.peek().is_some() && steps.all(|k| !held(k) || in_doubt(k))
        })
        .collect()
}

/// A lattice step, in spacings: the neighbours of a marker that are this close.
const NEIGHBOUR_STEP: f64 = 1.3;

/// The neighbours of `i` a lattice step away (within [`NEIGHBOUR_STEP`] of its spacing) at
/// `anchors`.
fn lattice_steps<'r>(
    reference: &'r TrackReference,
    anchors: &'r [(f64, f64)],
    i: usize,
) -> impl Iterator<Item = usize> + 'r {
    let near = NEIGHBOUR_STEP * reference.spacing_px[i];
    reference.neighbours[i]
        .iter()
        .copied()
        .filter(move |&k| dist_sq(anchors[k], anchors[i]) <= near * near)
}

/// The motion around gap `g` when it is a gap (see [`doubt_around_gaps`]): the largest motion
/// of its matched neighbours a lattice step away, in spacings, and the direction of their mean
/// motion. The markers that lag a lattice step behind a drag seem to have moved little, so
/// the largest motion beside the gap counts, not the mean. When none of its neighbours a
/// lattice step away holds a blob, those within [`GAP_FAR`] spacings count: a small TacTip
/// dragged 2.6 pitches across its outer ring was read a step short with the ring's pins lost
/// and no held marker a lattice step from them (drag seed 25: 7 wrong identities → 0).
fn gap_motion(
    reference: &TrackReference,
    m: &Matching<'_>,
    g: usize,
    shift: (f64, f64),
    held: &impl Fn(usize) -> bool,
) -> Option<(f64, (f64, f64))> {
    // (markers, held, largest motion in spacings, sum of the held markers' motion)
    let tally = |ks: &mut dyn Iterator<Item = usize>| {
        let (mut all, mut count, mut max, mut sum) = (0usize, 0usize, 0.0f64, (0.0, 0.0));
        for k in ks {
            all += 1;
            if held(k) {
                let d = (m.disp[k].0 - shift.0, m.disp[k].1 - shift.1);
                count += 1;
                max = max.max(d.0.hypot(d.1) / reference.spacing_px[k]);
                sum = (sum.0 + d.0, sum.1 + d.1);
            }
        }
        (all, count, max, sum)
    };
    // Its nearest neighbours only: a marker at the edge of the view has matched markers two
    // steps inwards, but is not inside the field.
    let steps = tally(&mut lattice_steps(reference, &m.anchors, g));
    let (all, count, max, sum) = if steps.1 == 0 && steps.0 >= 1 {
        // Every lattice neighbour without a blob too (the back of a field read a step short,
        // or a TacTip's outer ring, sparser than the rings inside it): the held markers within
        // `GAP_FAR` spacings.
        let far = GAP_FAR * reference.spacing_px[g];
        tally(
            &mut reference.neighbours[g]
                .iter()
                .copied()
                .filter(|&k| dist_sq(m.anchors[k], m.anchors[g]) <= far * far),
        )
    } else {
        steps
    };
    (all >= 2 && count >= 1 && max >= GAP_MOTION).then_some((max, sum))
}

/// A blob with at least this share of the area of the ellipse with its second moments
/// ([`ellipse_fill`]) has no waist between two lobes ([`one_stretched_marker`]): an ellipse
/// fills all of it, two touching discs 0.89. On the drag matrix (seeds 1–24) the merged pairs
/// split right measured 0.58–0.91 with a waist, the stretched single markers 0.995–1.0.
const NO_WAIST_FILL: f64 = 0.95;

/// Two markers split from a blob with no waist closer than this share of their predictions'
/// separation are one marker stretched by a drag, not two ([`one_stretched_marker`]). On the
/// drag matrix (seeds 1–24) the waistless blobs split right had 0.55–0.92; those split between
/// one stretched dot and a neighbour hidden elsewhere 0.22–0.53.
const STRETCHED_SEPARATION: f64 = 0.55;

/// Whether a blob that moments would split into two markers `d` px apart, predicted `d_pred`
/// px apart, is rather one marker stretched to twice its area: a dot dragged along its
/// neighbour's direction grows to the size of two without a waist, and its split would give
/// the neighbour (hidden elsewhere) a position a lattice step off. Two markers merged under a
/// press show a waist, or lie about as far apart as their predictions.
fn one_stretched_marker(b: &Blob, d: f64, d_pred: f64) -> bool {
    ellipse_fill(b) >= NO_WAIST_FILL && d < STRETCHED_SEPARATION * d_pred
}

/// The share of the ellipse with a blob's second moments (`4π·√(λ1·λ2)`, each variance widened
/// by the pixel's own 1/12) that its area fills: 1 for an ellipse, 0.89 for two touching
/// equal discs, less for two lobes joined by a thinner bridge.
fn ellipse_fill(b: &Blob) -> f64 {
    let pixel = 1.0 / 12.0;
    let (xx, xy, yy) = (b.mu20_px2 + pixel, b.mu11_px2, b.mu02_px2 + pixel);
    let ellipse_px = 4.0 * std::f64::consts::PI * (xx * yy - xy * xy).max(0.0).sqrt();
    f64::from(b.area_px) / ellipse_px
}

/// The motion, in spacings, some held marker must show for [`doubt_around_gaps`] to look at a
/// frame, from the blobs with no waist ([`NO_WAIST_FILL`]: one marker's blob) that two or more
/// markers fell on (`on_blob`, sorted by blob): 0 (any frame) when such a blob, split or not,
/// lies [`FRAME_MOTION`] spacings or more beyond the overall `shift` from one of them — one of
/// the two has moved a lattice step, whichever the blob is, though read a step short the held
/// markers seem to have moved less; [`WAISTLESS_FRAME_MOTION`] when such a blob was not split;
/// else [`FRAME_MOTION`].
///
/// The first case: a GelSight grid dragged 1.6–1.7 pitches, its front bunched into two-lobed
/// blobs and its last dot stretched, was read a step short with its largest held motion under
/// 0.9 spacing and the stretched dot claimed by two (drag seeds 29 and 32). Drag matrix at
/// `--motion-limit 1` (2026-11-29): seeds 25–40, wrong identities 32 → 25 (GelSight 14 → 7),
/// lost +48 of 20 556, none in frames moved under a pitch; seeds 1–24, wrong identities 8 → 8,
/// lost +157 of 43 654, 15 of them in frames moved under a pitch (dots variant 3, seed 4), all
/// where a hidden dot moved beyond one.
fn gaps_frame_motion(
    m: &Matching<'_>,
    on_blob: &[OnBlob],
    status: &[MarkerStatus],
    shift: (f64, f64),
) -> f64 {
    let mut motion = FRAME_MOTION;
    for g in on_blob.chunk_by(|a, b| a.0 == b.0) {
        let b = &m.blobs[g[0].0];
        if g.len() < 2 || ellipse_fill(b) < NO_WAIST_FILL {
            continue;
        }
        let a_step_off = g.iter().any(|&(_, i, _, _)| {
            let (x, y) = m.anchors[i];
            let step = FRAME_MOTION * m.reference.spacing_px[i];
            dist_sq((b.x_px, b.y_px), (x + shift.0, y + shift.1)) >= step * step
        });
        if a_step_off {
            return 0.0;
        }
        if g.iter().all(|e| status[e.1] != MarkerStatus::Split) {
            motion = WAISTLESS_FRAME_MOTION;
        }
    }
    motion
}

/// Splits blobs that exactly two merged markers fell on, when the blob's area is about theirs
/// together: two markers of areas `a1`, `a2` (discs: variance `a/4π` along any axis) whose
/// centres are `d` apart along the blob's major axis give the blob a variance of
/// `(a1·σ1² + a2·σ2²)/a + a1·a2·d²/a²` along it, which gives `d`; the blob's centroid is the
/// area-weighted mean of the two centres. Each marker goes to the side its prediction lies on,
/// and the split is kept only if both estimates stay within the gate of their predictions —
/// and, followed (`prior`: the markers' positions in the prior frame), only if the prior frame
/// saw both: otherwise their predictions come from the neighbours alone and can cross under a
/// deep press (the drag matrix followed frame by frame: wrong identities 26 → 22, lost 42 →
/// 46, none more in frames moved under a pitch). Returns the positions (empty when nothing
/// was split) and marks those markers [`MarkerStatus::Split`]; and the pairs split from a blob
/// that is rather one marker stretched by a drag ([`one_stretched_marker`]), which the caller
/// merges once the doubt around gaps is settled (as split pairs, their neighbours saw them).
fn split_pairs(
    reference: &TrackReference,
    blobs: &[Blob],
    cfg: &TrackConfig,
    on_blob: &mut [OnBlob],
    prior: Option<&[Option<(f64, f64)>]>,
    status: &mut [MarkerStatus],
) -> (Vec<Option<(f64, f64)>>, Vec<usize>) {
    let mut out: Vec<Option<(f64, f64)>> = Vec::new();
    let mut stretched = Vec::new();
    on_blob.sort_by_key(|e| (e.0, e.1));
    for group in on_blob.chunk_by(|a, b| a.0 == b.0) {
        let [(j, i1, p1, s1), (_, i2, p2, s2)] = *group else {
            continue;
        };
        // Followed, a pair the prior frame did not see both of has predictions from its
        // neighbours alone, which under a deep press can cross: it stays merged.
        if i1 == i2 || prior.is_some_and(|p| p[i1].is_none() || p[i2].is_none()) {
            continue;
        }
        let b = &blobs[j];
        let (a1, a2) = (
            reference.areas_px[i1] * s1 * s1,
            reference.areas_px[i2] * s2 * s2,
        );
        let a = a1 + a2;
        let area = f64::from(b.area_px);
        if !(0.7 * a..=1.4 * a).contains(&area) {
            continue;
        }
        // The major axis and the variance along it.
        let (xx, xy, yy) = (b.mu20_px2, b.mu11_px2, b.mu02_px2);
        let half = 0.5 * (xx + yy);
        let root = (0.25 * (xx - yy) * (xx - yy) + xy * xy).sqrt();
        let l1 = half + root;
        let theta = 0.5 * (2.0 * xy).atan2(xx - yy);
        let u = (theta.cos(), theta.sin());
        let own = (a1 * a1 + a2 * a2) / (4.0 * std::f64::consts::PI * a);
        let d2 = (l1 - own) * a * a / (a1 * a2);
        if d2.is_nan() || d2 <= 0.0 {
            continue;
        }
        let d = d2.sqrt();
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
        let near = |q: (f64, f64), p: (f64, f64), i: usize, s: f64| {
            dist(q, p) <= cfg.gate_pitches * reference.spacing_px[i] * s
        };
        if !(near(q1, p1, i1, s1) && near(q2, p2, i2, s2)) {
            continue;
        }
        if out.is_empty() {
            out = vec![None; status.len()];
        }
        for (i, q) in [(i1, q1), (i2, q2)] {
            out[i] = Some(q);
            status[i] = MarkerStatus::Split;
        }
        if one_stretched_marker(b, d, dist(p1, p2)) {
            stretched.extend([i1, i2]);
        }
    }
    (out, stretched)
}
