//! Matching reference markers to the blobs of a frame, frame by frame and order-free.
//!
//! Every frame is matched to the reference on its own (datasets of touches in random order need
//! that), in two steps:
//! 1. **Registration.** Every marker votes for the displacement of its nearest blob in a 2-D
//!    histogram; the densest cell, refined by the mean of its votes, is the overall motion (the
//!    still majority of a skin clamped at its frame, or a whole-sensor shift under half a pitch).
//! 2. **One-to-one assignment by region growing.** Markers whose blob is unambiguous after the
//!    overall motion (close, mutual nearest, no rival) are matched first. Then each unmatched
//!    marker next to matched ones is predicted from its matched neighbours' displacements (the
//!    skin moves smoothly) and takes the nearest free blob near that prediction, if no rival is
//!    nearly as close. A drag that moves markers under the tip by a whole pitch is followed from
//!    the still markers around it inwards; no marker is ever given a blob just because it is
//!    the nearest one to its rest position.
//!
//! Markers left without a blob are reported as [`MarkerStatus::Lost`], [`MarkerStatus::Merged`]
//! (their prediction falls on a blob already taken that is much bigger than one marker) or
//! [`MarkerStatus::Ambiguous`] (two free blobs equally plausible). Their feature cells stay
//! empty; other markers' columns never shift.

use serde::{Deserialize, Serialize};

use crate::blobs::Blob;

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
}

impl MarkerStatus {
    /// Name used in tables.
    pub fn name(self) -> &'static str {
        match self {
            MarkerStatus::Ok => "ok",
            MarkerStatus::Lost => "lost",
            MarkerStatus::Merged => "merged",
            MarkerStatus::Ambiguous => "ambiguous",
        }
    }
}

/// Tracker tuning, in units of the marker pitch.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TrackConfig {
    /// Largest displacement considered, in pitches.
    pub search_pitches: f64,
    /// Gate around a prediction within which a blob may be taken, in pitches.
    pub gate_pitches: f64,
    /// A rival blob closer than `ambiguity_ratio ×` the best distance makes a match ambiguous.
    pub ambiguity_ratio: f64,
    /// A taken blob at least this many times the marker's reference area counts as merged.
    pub merged_area_ratio: f64,
}

impl TrackConfig {
    /// Defaults that follow drags up to one pitch.
    pub const DEFAULT: Self = Self {
        search_pitches: 1.5,
        gate_pitches: 0.4,
        ambiguity_ratio: 1.25,
        merged_area_ratio: 1.6,
    };
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
    /// Neighbours of each marker in the reference (indices), nearest first.
    pub neighbours: Vec<Vec<usize>>,
    /// Typical spacing between neighbours in pixels.
    pub pitch_px: f64,
    /// For concentric rings, each ring's major axis in pixels: rings share a centre, so they
    /// are matched by size near the reference centre instead of by position.
    pub ring_sizes_px: Option<Vec<f64>>,
}

impl TrackReference {
    /// Builds the neighbour lists (the 8 nearest within 2 pitches) from positions and areas.
    pub fn new(positions: Vec<(f64, f64)>, areas_px: Vec<f64>) -> Self {
        let n = positions.len();
        let mut neighbours = Vec::with_capacity(n);
        let mut nn = Vec::with_capacity(n);
        for i in 0..n {
            let mut d: Vec<(usize, f64)> = (0..n)
                .filter(|&j| j != i)
                .map(|j| (j, dist(positions[i], positions[j])))
                .collect();
            d.sort_by(|a, b| a.1.total_cmp(&b.1));
            if let Some(&(_, d0)) = d.first() {
                nn.push(d0);
            }
            neighbours.push(d);
        }
        nn.sort_by(f64::total_cmp);
        let pitch_px = if nn.is_empty() {
            // One marker: use its size as the scale.
            areas_px.first().map_or(10.0, |a| 2.0 * a.sqrt())
        } else {
            nn[nn.len() / 2]
        };
        let neighbours = neighbours
            .into_iter()
            .map(|d| {
                d.into_iter()
                    .take(8)
                    .filter(|&(_, dd)| dd < 2.0 * pitch_px)
                    .map(|(j, _)| j)
                    .collect()
            })
            .collect();
        Self {
            positions,
            areas_px,
            neighbours,
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
}

impl TrackResult {
    /// Number of markers matched.
    pub fn found(&self) -> usize {
        self.status
            .iter()
            .filter(|s| **s == MarkerStatus::Ok)
            .count()
    }
}

fn dist(a: (f64, f64), b: (f64, f64)) -> f64 {
    ((a.0 - b.0) * (a.0 - b.0) + (a.1 - b.1) * (a.1 - b.1)).sqrt()
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

    /// Calls `f(index, squared distance)` for every blob within `r` of `p`.
    fn near(&self, p: (f64, f64), r: f64, mut f: impl FnMut(usize, f64)) {
        if self.pts.is_empty() {
            return;
        }
        let cx0 = ((p.0 - r - self.x0) / self.cell).floor().max(0.0) as usize;
        let cy0 = ((p.1 - r - self.y0) / self.cell).floor().max(0.0) as usize;
        let cx1 = ((p.0 + r - self.x0) / self.cell).floor();
        let cy1 = ((p.1 + r - self.y0) / self.cell).floor();
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
        let mut nearest: Option<(usize, f64)> = None;
        index.near(m, range, |j, d| {
            if nearest.is_none_or(|(_, bd)| d < bd) {
                nearest = Some((j, d));
            }
        });
        if let Some((j, _)) = nearest {
            let q = index.pts[j];
            let d = (q.0 - m.0, q.1 - m.1);
            let bx = ((d.0 + range) / cell).floor() as usize;
            let by = ((d.1 + range) / cell).floor() as usize;
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
    }
}

/// Matches every reference marker to at most one blob of the frame.
pub fn track(reference: &TrackReference, blobs: &[Blob], cfg: &TrackConfig) -> TrackResult {
    if let Some(sizes) = &reference.ring_sizes_px {
        return track_rings(reference, sizes, blobs);
    }
    let n = reference.positions.len();
    let p = reference.pitch_px;
    let gate = cfg.gate_pitches * p;
    let index = BlobIndex::new(blobs, p.max(1.0));
    let shift = register(reference, &index, cfg);
    let mut assignment: Vec<Option<usize>> = vec![None; n];
    let mut disp: Vec<(f64, f64)> = vec![(0.0, 0.0); n];
    let mut taken = vec![false; blobs.len()];

    // Seeds: unambiguous, mutual nearest after the overall motion, within half the gate.
    let predicted: Vec<(f64, f64)> = reference
        .positions
        .iter()
        .map(|&(x, y)| (x + shift.0, y + shift.1))
        .collect();
    for i in 0..n {
        let (best, second) = nearest_two(predicted[i], &index, &taken, 0.5 * gate);
        let Some((j, d)) = best else { continue };
        if second < cfg.ambiguity_ratio * 2.0 * d.max(0.05 * p) {
            continue;
        }
        // Mutual: no other marker's prediction is closer to this blob.
        let bj = (blobs[j].x_px, blobs[j].y_px);
        let mutual = reference.neighbours[i]
            .iter()
            .all(|&k| dist(predicted[k], bj) > d);
        if mutual {
            assignment[i] = Some(j);
            taken[j] = true;
            disp[i] = (
                bj.0 - reference.positions[i].0,
                bj.1 - reference.positions[i].1,
            );
        }
    }
    // Keep the largest set of seeds whose displacements agree with their seeded neighbours (a
    // smooth field); seeds elsewhere may have taken a neighbour's blob in a drag zone, so they
    // are released and re-grown from the consistent set.
    let mut component = vec![usize::MAX; n];
    let mut sizes = Vec::new();
    for s0 in 0..n {
        if assignment[s0].is_none() || component[s0] != usize::MAX {
            continue;
        }
        let c = sizes.len();
        let mut stack = vec![s0];
        component[s0] = c;
        let mut size = 0;
        while let Some(i) = stack.pop() {
            size += 1;
            for &k in &reference.neighbours[i] {
                if assignment[k].is_some()
                    && component[k] == usize::MAX
                    && dist(disp[i], disp[k]) < 0.25 * p
                {
                    component[k] = c;
                    stack.push(k);
                }
            }
        }
        sizes.push(size);
    }
    if let Some(keep) = (0..sizes.len()).max_by_key(|&c| (sizes[c], usize::MAX - c)) {
        for i in 0..n {
            if let Some(j) = assignment[i] {
                if component[i] != keep {
                    assignment[i] = None;
                    taken[j] = false;
                }
            }
        }
    }
    // Region growing from matched markers.
    // Support (matched neighbours) at which the growth last failed for each marker (nothing
    // free, or rivals, near the prediction); it is tried again once more neighbours are matched.
    let mut failed_at: Vec<Option<usize>> = vec![None; n];
    loop {
        // Candidates: unmatched markers with matched neighbours, most support first.
        let mut cands: Vec<(usize, usize)> = (0..n)
            .filter(|&i| assignment[i].is_none())
            .map(|i| {
                (
                    i,
                    reference.neighbours[i]
                        .iter()
                        .filter(|&&k| assignment[k].is_some())
                        .count(),
                )
            })
            .filter(|&(i, c)| c > 0 && failed_at[i].is_none_or(|f| c > f))
            .collect();
        if cands.is_empty() {
            break;
        }
        cands.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
        let mut progress = false;
        let top = cands[0].1;
        for &(i, support) in cands.iter().take_while(|&&(_, c)| c == top) {
            // Inverse-distance weighted displacement of matched neighbours.
            let (mut sx, mut sy, mut sw) = (0.0, 0.0, 0.0);
            for &k in &reference.neighbours[i] {
                if assignment[k].is_some() {
                    let w = 1.0 / dist(reference.positions[i], reference.positions[k]).max(1e-6);
                    sx += w * disp[k].0;
                    sy += w * disp[k].1;
                    sw += w;
                }
            }
            let pred = (
                reference.positions[i].0 + sx / sw,
                reference.positions[i].1 + sy / sw,
            );
            let (best, second) = nearest_two(pred, &index, &taken, gate);
            match best {
                Some((j, d)) if second >= cfg.ambiguity_ratio * d.max(0.05 * p) => {
                    assignment[i] = Some(j);
                    taken[j] = true;
                    disp[i] = (
                        blobs[j].x_px - reference.positions[i].0,
                        blobs[j].y_px - reference.positions[i].1,
                    );
                    progress = true;
                }
                _ => {
                    failed_at[i] = Some(support);
                    progress = true;
                }
            }
        }
        if !progress {
            break;
        }
    }
    // Markers no growth reached (no matched neighbours at all) keep a plain gated look-up.
    for i in 0..n {
        if assignment[i].is_none() && failed_at[i].is_none() {
            let (best, second) = nearest_two(predicted[i], &index, &taken, gate);
            if let Some((j, d)) = best {
                if second >= cfg.ambiguity_ratio * d.max(0.05 * p) {
                    assignment[i] = Some(j);
                    taken[j] = true;
                }
            }
        }
    }
    // Classify the unmatched, and flag matched blobs that swallowed a neighbour.
    let mut status = vec![MarkerStatus::Ok; n];
    let mut merged_blob = vec![false; blobs.len()];
    for i in 0..n {
        if assignment[i].is_some() {
            continue;
        }
        let (sx, sy, sw) = reference.neighbours[i]
            .iter()
            .filter(|&&k| assignment[k].is_some())
            .fold((0.0, 0.0, 0.0), |acc, &k| {
                (acc.0 + disp[k].0, acc.1 + disp[k].1, acc.2 + 1.0)
            });
        let pred = if sw > 0.0 {
            (
                reference.positions[i].0 + sx / sw,
                reference.positions[i].1 + sy / sw,
            )
        } else {
            predicted[i]
        };
        // A blob covering the prediction and much larger than this marker: merged (with the
        // marker that took it, or with a neighbour that is also left without a blob).
        let merged_with = blobs.iter().enumerate().find(|(_, b)| {
            f64::from(b.area_px) >= cfg.merged_area_ratio * reference.areas_px[i]
                && pred.0 >= f64::from(b.bbox.x0) - 0.5
                && pred.0 <= f64::from(b.bbox.x1) - 0.5
                && pred.1 >= f64::from(b.bbox.y0) - 0.5
                && pred.1 <= f64::from(b.bbox.y1) - 0.5
        });
        status[i] = if let Some((j, _)) = merged_with {
            // The owner of that blob is merged too: its centroid is no longer its own.
            if let Some(owner) = assignment.iter().position(|a| *a == Some(j)) {
                status[owner] = MarkerStatus::Merged;
            }
            merged_blob[j] = true;
            MarkerStatus::Merged
        } else {
            let (best, second) = nearest_two(pred, &index, &taken, gate);
            match best {
                Some((_, d)) if second < cfg.ambiguity_ratio * d.max(0.05 * p) => {
                    MarkerStatus::Ambiguous
                }
                _ => MarkerStatus::Lost,
            }
        };
    }
    for i in 0..n {
        if status[i] != MarkerStatus::Ok {
            assignment[i] = None;
        }
    }
    let spurious = (0..blobs.len())
        .filter(|&j| !taken[j] && !merged_blob[j])
        .count();
    TrackResult {
        assignment,
        status,
        shift_px: shift,
        spurious,
    }
}
