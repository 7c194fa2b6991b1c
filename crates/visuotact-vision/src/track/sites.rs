//! Lattice sites inside a numbered array where calibration saw no marker: a reference taken
//! in contact hides a pin under a crease, and the pin shows again when the crease moves.
//!
//! The array is a lattice, so such a pin has an owner before it is seen: the tracker follows
//! every unseen site as a marker of its own (absent at no cost, as a marker out of view; a
//! blob there is the pin's, not clutter a neighbour may take) and never reports it. Without
//! the site, a column next to the pin may take its blob, each marker the next one's, and
//! leave one blob over at the far end, a reading the energy cannot tell from the right one.

use crate::layout::PARALLELOGRAM_TOLERANCE;

/// The unseen sites of a lattice numbered `sites[i]` (each marker's `(row, col)`), with
/// marker positions `positions_px` and steps `steps` to the neighbours around a site (in turn
/// around the circle, each step's opposite among them), each with its position.
///
/// A site is where a pin hides when the lattice places it there and no pin is seen there:
/// - numbered neighbours on both sides along at least two lattice axes, whose midpoints agree
///   within 0.3 of their spacing (the numbering's parallelogram tolerance: a smoothly
///   stretched lattice keeps them together; the position is their mean);
/// - no marker within half that spacing of it (a pin so near would be this site's, and the
///   gap a fault of the numbering, not a hidden pin).
///
/// ```
/// use visuotact_vision::track::unseen_sites;
/// // A 3 × 3 grid without its centre.
/// let steps = [(0, 1), (1, 0), (0, -1), (-1, 0)];
/// let mut sites = Vec::new();
/// let mut positions = Vec::new();
/// for r in 0..3i64 {
///     for c in 0..3i64 {
///         if (r, c) != (1, 1) {
///             sites.push((r, c));
///             positions.push((10.0 * c as f64, 10.0 * r as f64));
///         }
///     }
/// }
/// let unseen = unseen_sites(&sites, &positions, &steps);
/// assert_eq!(unseen, vec![((1, 1), (10.0, 10.0))]);
/// // A marker 3 px from the centre: the gap is the numbering's, not a hidden pin's.
/// positions.push((13.0, 10.0));
/// sites.push((5, 5));
/// assert!(unseen_sites(&sites, &positions, &steps).is_empty());
/// ```
pub fn unseen_sites(
    sites: &[(i64, i64)],
    positions_px: &[(f64, f64)],
    steps: &[(i64, i64)],
) -> Vec<((i64, i64), (f64, f64))> {
    use std::collections::{BTreeSet, HashMap};
    let at: HashMap<(i64, i64), usize> = sites.iter().enumerate().map(|(i, &s)| (s, i)).collect();
    let axes: Vec<(i64, i64)> = steps
        .iter()
        .copied()
        .filter(|&(r, c)| r > 0 || (r == 0 && c > 0))
        .collect();
    let pos = |s: (i64, i64)| at.get(&s).map(|&i| positions_px[i]);
    // Every empty site one step from a numbered one, in order.
    let candidates: BTreeSet<(i64, i64)> = sites
        .iter()
        .flat_map(|s| steps.iter().map(move |d| (s.0 + d.0, s.1 + d.1)))
        .filter(|s| !at.contains_key(s))
        .collect();
    let mut unseen = Vec::new();
    for s in candidates {
        // Per axis with both neighbours: their midpoint and half their distance (a spacing).
        let pairs: Vec<((f64, f64), f64)> = axes
            .iter()
            .filter_map(|&d| {
                let a = pos((s.0 + d.0, s.1 + d.1))?;
                let b = pos((s.0 - d.0, s.1 - d.1))?;
                let mid = (0.5 * (a.0 + b.0), 0.5 * (a.1 + b.1));
                Some((mid, 0.5 * (a.0 - b.0).hypot(a.1 - b.1)))
            })
            .collect();
        if pairs.len() < 2 {
            continue;
        }
        let k = pairs.len() as f64;
        let at_px = pairs
            .iter()
            .fold((0.0, 0.0), |a, p| (a.0 + p.0 .0 / k, a.1 + p.0 .1 / k));
        let spacing = pairs.iter().map(|p| p.1).sum::<f64>() / k;
        let dist = |p: (f64, f64)| (p.0 - at_px.0).hypot(p.1 - at_px.1);
        let agree = || {
            pairs
                .iter()
                .all(|p| dist(p.0) <= PARALLELOGRAM_TOLERANCE * spacing)
        };
        let empty = || positions_px.iter().all(|&p| dist(p) >= 0.5 * spacing);
        if agree() && empty() {
            unseen.push((s, at_px));
        }
    }
    unseen
}

#[cfg(test)]
mod tests {
    use super::unseen_sites;

    const GRID: [(i64, i64); 4] = [(0, 1), (1, 0), (0, -1), (-1, 0)];

    /// Lattice sites and their positions.
    type Numbered = (Vec<(i64, i64)>, Vec<(f64, f64)>);

    /// A 3 × 3 grid of pitch 10 without its centre, `moved` applied to each pin's position.
    fn ring(moved: impl Fn((i64, i64)) -> (f64, f64)) -> Numbered {
        let sites: Vec<(i64, i64)> = (0..9)
            .map(|k| (k / 3, k % 3))
            .filter(|&s| s != (1, 1))
            .collect();
        let positions = sites
            .iter()
            .map(|&s| {
                let d = moved(s);
                (10.0 * s.1 as f64 + d.0, 10.0 * s.0 as f64 + d.1)
            })
            .collect();
        (sites, positions)
    }

    /// Where the numbering is torn the two axes put the gap in different places: the gap is
    /// the numbering's, not a hidden pin's (a real 331-pin reference 2.2 mm deep has such
    /// gaps; followed as sites, they cost it 589 → 1 214 missing pin-frames).
    #[test]
    fn a_site_its_axes_disagree_on_is_no_hidden_pin() {
        // The row through the gap 8 px up: its midpoint is 0.4 spacing from the column's
        // mean with it.
        let (sites, positions) = ring(|s| if s.0 == 1 { (0.0, -8.0) } else { (0.0, 0.0) });
        assert!(unseen_sites(&sites, &positions, &GRID).is_empty());
        // 4 px: within 0.3 of the spacing, a smoothly stretched lattice.
        let (sites, positions) = ring(|s| if s.0 == 1 { (0.0, -4.0) } else { (0.0, 0.0) });
        let unseen = unseen_sites(&sites, &positions, &GRID);
        assert_eq!(unseen.len(), 1);
        assert_eq!(unseen[0].0, (1, 1));
        assert!((unseen[0].1 .1 - 8.0).abs() < 1e-9, "{unseen:?}");
    }

    /// One axis alone does not place a site (a run of gaps along a torn numbering).
    #[test]
    fn one_axis_alone_places_no_site() {
        let (mut sites, mut positions) = ring(|_| (0.0, 0.0));
        for gone in [(0, 1), (2, 1)] {
            let k = sites.iter().position(|&s| s == gone).unwrap();
            sites.remove(k);
            positions.remove(k);
        }
        let unseen = unseen_sites(&sites, &positions, &GRID);
        assert!(unseen.iter().all(|u| u.0 != (1, 1)), "{unseen:?}");
    }
}
