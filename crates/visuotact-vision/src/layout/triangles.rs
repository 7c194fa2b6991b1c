//! A hexagonal array numbered by its triangles: lattice coordinates carried from triangle to
//! triangle by the parallelogram rule.
//!
//! The Delaunay triangles of a hexagonal array are its lattice triangles, however smoothly the
//! array is stretched, sheared or bent (a dome, a lens, a skin pressed and dragged): a
//! triangle's shape changes long before its neighbours change. Two lattice triangles sharing
//! the edge `u v` form a rhombus, so the far corner of the second is `u + v − x`, with `x` the
//! first's third corner. Numbering spreads from one triangle of the walk's numbering through
//! every lattice triangle, and so is the same around every loop of triangles: a region where
//! the array is squeezed (the crease at a contact's edge, pins 0.6 pitch apart) is numbered
//! like the rest instead of being walked around, which left a row's worth of pins out where the
//! two sides of the walk met.
//!
//! The rule holds when the two triangles are a lattice parallelogram, so each step checks that
//! their corners in pixels are one: `u + v − x` lands within [`PARALLELOGRAM_TOLERANCE`] of
//! the quadrilateral's mean side from `w`. A smooth stretch keeps a parallelogram one to second
//! order; the triangles that span a missing pin, the slivers along the array's rim and a
//! pair whose diagonal the triangulation flipped (where the rim is sheared) are not one.

use std::collections::{HashMap, VecDeque};

use delaunator::{triangulate, Point, EMPTY};

/// How far the fourth corner may be from the parallelogram of the other three, in the
/// quadrilateral's mean side (the walk's link tolerance is 0.3 of a lattice step).
pub(crate) const PARALLELOGRAM_TOLERANCE: f64 = 0.3;

/// The lattice coordinates of `points` spread from `seed` (the walk's numbering, of which one
/// triangle is taken: one around `start` whose corners are one of `steps` apart) through the
/// lattice triangles; `None` when no such triangle is found.
pub(super) fn numbered_by_triangles(
    points: &[(f64, f64)],
    seed: &[Option<(i64, i64)>],
    start: usize,
    steps: &[(i64, i64)],
) -> Option<Vec<Option<(i64, i64)>>> {
    let pts: Vec<Point> = points.iter().map(|&(x, y)| Point { x, y }).collect();
    let tri = triangulate(&pts);
    let corners = &tri.triangles;
    let step_apart = |a: usize, b: usize| match (seed[a], seed[b]) {
        (Some(p), Some(q)) => steps.contains(&(q.0 - p.0, q.1 - p.1)),
        _ => false,
    };
    let first = (0..corners.len() / 3).find(|&t| {
        let [a, b, c] = [corners[3 * t], corners[3 * t + 1], corners[3 * t + 2]];
        [a, b, c].contains(&start) && step_apart(a, b) && step_apart(b, c) && step_apart(c, a)
    })?;
    let mut coords = vec![None; points.len()];
    let mut site = HashMap::new();
    for k in 0..3 {
        let p = corners[3 * first + k];
        coords[p] = seed[p];
        site.insert(seed[p]?, p);
    }
    let mut seen = vec![false; corners.len() / 3];
    seen[first] = true;
    let mut queue = VecDeque::from([first]);
    while let Some(t) = queue.pop_front() {
        for e in 3 * t..3 * t + 3 {
            let across = tri.halfedges[e];
            if across == EMPTY || seen[across / 3] {
                continue;
            }
            let (u, v, x) = (corners[e], corners[next(e)], corners[next(next(e))]);
            let w = corners[next(next(across))];
            if !parallelogram(points, u, v, x, w) {
                continue;
            }
            let (Some(cu), Some(cv), Some(cx)) = (coords[u], coords[v], coords[x]) else {
                continue;
            };
            let cw = (cu.0 + cv.0 - cx.0, cu.1 + cv.1 - cx.1);
            match coords[w] {
                Some(c) if c != cw => continue,
                Some(_) => {}
                None => {
                    if site.contains_key(&cw) {
                        continue;
                    }
                    site.insert(cw, w);
                    coords[w] = Some(cw);
                }
            }
            seen[across / 3] = true;
            queue.push_back(across / 3);
        }
    }
    Some(coords)
}

/// The next half-edge of a half-edge's triangle.
fn next(e: usize) -> usize {
    if e % 3 == 2 {
        e - 2
    } else {
        e + 1
    }
}

/// Whether `u x v w` is a parallelogram in pixels (`u + v − x` near `w`).
fn parallelogram(points: &[(f64, f64)], u: usize, v: usize, x: usize, w: usize) -> bool {
    let [pu, pv, px, pw] = [points[u], points[v], points[x], points[w]];
    let len = |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).hypot(a.1 - b.1);
    let side = (len(pu, px) + len(pv, px) + len(pu, pw) + len(pv, pw)) / 4.0;
    let miss = (pu.0 + pv.0 - px.0 - pw.0).hypot(pu.1 + pv.1 - px.1 - pw.1);
    miss <= PARALLELOGRAM_TOLERANCE * side
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout::HEX_STEPS;

    /// Pixel positions and their lattice sites.
    type Patch = (Vec<(f64, f64)>, Vec<(i64, i64)>);

    /// A hexagonal patch of side 6 (127 pins, pitch 20) under `map`, with its lattice sites,
    /// leaving out the sites `holes`.
    fn patch(map: impl Fn(f64, f64) -> (f64, f64), holes: &[(i64, i64)]) -> Patch {
        let (mut pts, mut sites) = (Vec::new(), Vec::new());
        for j in -6i64..=6 {
            for i in -6i64..=6 {
                if (i + j).abs() > 6 || holes.contains(&(i, j)) {
                    continue;
                }
                let x = (i as f64 + 0.5 * j as f64) * 20.0;
                let y = j as f64 * 20.0 * 3f64.sqrt() / 2.0;
                pts.push(map(x, y));
                sites.push((i, j));
            }
        }
        (pts, sites)
    }

    fn numbered(pts: &[(f64, f64)], sites: &[(i64, i64)]) -> Vec<Option<(i64, i64)>> {
        let seed: Vec<Option<(i64, i64)>> = sites.iter().copied().map(Some).collect();
        let start = sites.iter().position(|&s| s == (0, 0)).unwrap();
        numbered_by_triangles(pts, &seed, start, &HEX_STEPS).unwrap()
    }

    /// The pitch grows from 0.4 to 1.6 times across the patch and the rows bend: every pin
    /// gets its own site from one triangle's numbering (the lattice walk of [`super`] does not
    /// even take these points for a lattice).
    #[test]
    fn a_patch_stretched_fourfold_across_is_numbered_from_one_triangle() {
        let (pts, sites) = patch(
            |x, y| (300.0 + x + 0.005 * x * x / 2.0, 300.0 + y + 0.003 * x * y),
            &[],
        );
        let got = numbered(&pts, &sites);
        for (k, s) in sites.iter().enumerate() {
            assert_eq!(got[k], Some(*s), "pin {k} at {:?}", pts[k]);
        }
    }

    /// Missing pins (inside and on the rim) leave triangles that span them, which are no
    /// lattice parallelograms: the pins around keep their sites, none takes a missing one.
    #[test]
    fn missing_pins_leave_the_numbering_whole() {
        let holes = [(1, 1), (2, 1), (-3, 0), (6, -3), (0, -6), (-4, 5)];
        let (pts, sites) = patch(|x, y| (300.0 + x, 300.0 + y), &holes);
        let got = numbered(&pts, &sites);
        for (k, s) in sites.iter().enumerate() {
            assert_eq!(got[k], Some(*s), "pin {k} at {:?}", pts[k]);
        }
    }
}
