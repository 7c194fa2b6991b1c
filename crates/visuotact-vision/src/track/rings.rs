//! Concentric rings (an inflatable cone's annuli): matched by size, not position.

use super::index::dist;
use super::{MarkerStatus, TrackReference, TrackResult};
use crate::blobs::Blob;

/// Concentric rings: each reference ring (smallest first) takes the free blob whose size and
/// centre are closest (cost `|Δmajor|/major + distance/major`), within 30 % in size and half its
/// major axis in position.
pub(super) fn track_rings(
    reference: &TrackReference,
    sizes: &[f64],
    blobs: &[Blob],
) -> TrackResult {
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
        pieces: Vec::new(),
        searched_again: false,
    }
}
