//! Blob centroids bucketed on a square grid for near look-ups.

use crate::blobs::Blob;

pub(super) fn dist(a: (f64, f64), b: (f64, f64)) -> f64 {
    dist_sq(a, b).sqrt()
}

pub(super) fn dist_sq(a: (f64, f64), b: (f64, f64)) -> f64 {
    (a.0 - b.0) * (a.0 - b.0) + (a.1 - b.1) * (a.1 - b.1)
}

/// The point of `points` nearest their centroid (the first of equals; `None` without points).
pub(super) fn nearest_centroid(points: &[(f64, f64)]) -> Option<usize> {
    let n = points.len() as f64;
    let sum = points
        .iter()
        .fold((0.0, 0.0), |a, p| (a.0 + p.0, a.1 + p.1));
    let c = (sum.0 / n, sum.1 / n);
    (0..points.len()).min_by(|&a, &b| dist(points[a], c).total_cmp(&dist(points[b], c)))
}

/// The connected parts of the items `0..n` that are `member`s, two items linked when one is
/// among the other's `near` items and `linked(from, to)` holds: each part starts at its lowest
/// item and lists its members in the order a depth-first walk finds them; parts in the order
/// of their lowest items.
pub(super) fn parts<I: IntoIterator<Item = usize>>(
    n: usize,
    member: impl Fn(usize) -> bool,
    near: impl Fn(usize) -> I,
    linked: impl Fn(usize, usize) -> bool,
) -> Vec<Vec<usize>> {
    let mut seen = vec![false; n];
    let mut out = Vec::new();
    for s0 in 0..n {
        if seen[s0] || !member(s0) {
            continue;
        }
        seen[s0] = true;
        let (mut members, mut stack) = (vec![s0], vec![s0]);
        while let Some(i) = stack.pop() {
            for k in near(i) {
                if !seen[k] && member(k) && linked(i, k) {
                    seen[k] = true;
                    members.push(k);
                    stack.push(k);
                }
            }
        }
        out.push(members);
    }
    out
}

/// Blob centroids bucketed on a square grid of cell size `cell`.
pub(super) struct BlobIndex {
    cell: f64,
    x0: f64,
    y0: f64,
    nx: usize,
    ny: usize,
    starts: Vec<u32>,
    items: Vec<u32>,
    pub(super) pts: Vec<(f64, f64)>,
}

impl BlobIndex {
    pub(super) fn new(blobs: &[Blob], cell: f64) -> Self {
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

    /// The blob nearest to `p` within `r` (ties to the lower index).
    pub(super) fn nearest(&self, p: (f64, f64), r: f64) -> Option<usize> {
        let mut best: Option<(usize, f64)> = None;
        for radius in [r.min(0.5 * self.cell), r.min(self.cell), r] {
            self.near(p, radius, |j, d| {
                if best.is_none_or(|(bj, bd)| d < bd || (d == bd && j < bj)) {
                    best = Some((j, d));
                }
            });
            // A blob found within a radius is nearer than any outside it.
            if best.is_some() || radius >= r {
                break;
            }
        }
        best.map(|(j, _)| j)
    }

    /// Calls `f(index, squared distance)` for every blob within `r` of `p`.
    pub(super) fn near(&self, p: (f64, f64), r: f64, mut f: impl FnMut(usize, f64)) {
        if self.pts.is_empty() || !(p.0.is_finite() && p.1.is_finite()) {
            return;
        }
        // Truncating a non-negative value is its floor (and cheaper: without SSE4.1, `floor`
        // is a library call).
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
