//! Lattice sites inside a numbered array where calibration saw no marker: a reference taken
//! in contact hides a pin under a crease, and the pin shows again when the crease moves.
//!
//! The array is a lattice, so such a pin has an owner before it is seen: the tracker follows
//! every unseen site as a marker of its own (absent at no cost, as a marker out of view; a
//! blob there is the pin's, not clutter a neighbour may take) and never reports it. Without
//! the site, a column next to the pin may take its blob, each marker the next one's, and
//! leave one blob over at the far end, a reading the energy cannot tell from the right one.

/// The unseen sites of a lattice numbered `sites[i]` (each marker's `(row, col)`), with
/// marker positions `positions_px` and steps `steps` to the neighbours around a site (in turn
/// around the circle, each step's opposite among them): every empty site that has numbered
/// sites on both sides along every axis of the lattice, with its position estimated from them.
///
/// The position is the mean of the midpoints of the opposite neighbours present; where no
/// opposite pair is present (a run of hidden pins), of the extrapolations from two markers in
/// line along a step. A site with neither is left out.
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
/// ```
pub fn unseen_sites(
    sites: &[(i64, i64)],
    positions_px: &[(f64, f64)],
    steps: &[(i64, i64)],
) -> Vec<((i64, i64), (f64, f64))> {
    use std::collections::HashMap;
    let at: HashMap<(i64, i64), usize> = sites.iter().enumerate().map(|(i, &s)| (s, i)).collect();
    let axes: Vec<(i64, i64)> = steps
        .iter()
        .copied()
        .filter(|&(r, c)| r > 0 || (r == 0 && c > 0))
        .collect();
    let (Some(r0), Some(r1)) = (
        sites.iter().map(|s| s.0).min(),
        sites.iter().map(|s| s.0).max(),
    ) else {
        return Vec::new();
    };
    let (c0, c1) = (
        sites.iter().map(|s| s.1).min().unwrap_or(0),
        sites.iter().map(|s| s.1).max().unwrap_or(0),
    );
    let span = (r1 - r0).max(c1 - c0) + 1;
    let pos = |s: (i64, i64)| at.get(&s).map(|&i| positions_px[i]);
    // Whether a numbered site lies somewhere along `d` from `s`.
    let numbered_along = |s: (i64, i64), d: (i64, i64)| {
        (1..=span).any(|k| at.contains_key(&(s.0 + k * d.0, s.1 + k * d.1)))
    };
    let mut unseen = Vec::new();
    for r in r0..=r1 {
        for c in c0..=c1 {
            let s = (r, c);
            // A site of the lattice: one step from a numbered site.
            let on_lattice = steps.iter().any(|d| at.contains_key(&(r + d.0, c + d.1)));
            if at.contains_key(&s) || !on_lattice {
                continue;
            }
            let inside = axes
                .iter()
                .all(|&d| numbered_along(s, d) && numbered_along(s, (-d.0, -d.1)));
            if !inside {
                continue;
            }
            let mids: Vec<(f64, f64)> = axes
                .iter()
                .filter_map(|&d| {
                    let (a, b) = (pos((r + d.0, c + d.1))?, pos((r - d.0, c - d.1))?);
                    Some((0.5 * (a.0 + b.0), 0.5 * (a.1 + b.1)))
                })
                .collect();
            let estimates = if mids.is_empty() {
                steps
                    .iter()
                    .filter_map(|&d| {
                        let a = pos((r + d.0, c + d.1))?;
                        let b = pos((r + 2 * d.0, c + 2 * d.1))?;
                        Some((2.0 * a.0 - b.0, 2.0 * a.1 - b.1))
                    })
                    .collect()
            } else {
                mids
            };
            if estimates.is_empty() {
                continue;
            }
            let k = estimates.len() as f64;
            let sum = estimates
                .iter()
                .fold((0.0, 0.0), |a, p| (a.0 + p.0, a.1 + p.1));
            unseen.push((s, (sum.0 / k, sum.1 / k)));
        }
    }
    unseen
}
