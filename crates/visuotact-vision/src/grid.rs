//! Marker numbering: grid order (rows top to bottom, then columns left to right) for marker
//! lattices, size order for concentric rings.
//!
//! The lattice is recovered without assuming it is straight: the grid's rotation comes from the
//! nearest-neighbour directions (a 4-fold circular mean), the row and column pitches from the
//! neighbour vectors along each axis, and integer (row, column) indices are propagated from the
//! marker nearest the centre through neighbour links, one pitch at a time. Lens distortion bends
//! rows, but a single step between neighbours stays close to one pitch along one axis, so the
//! indices survive it. Points that no neighbour link reaches (specks, outliers) are left out.
//!
//! ```
//! use visuotact_vision::grid::lattice_from_points;
//! // A 3 × 2 grid given in scrambled order.
//! let pts = [(20.0, 10.0), (0.0, 0.0), (10.0, 10.0), (20.0, 0.0), (0.0, 10.0), (10.0, 0.0)];
//! let lat = lattice_from_points(&pts).unwrap();
//! assert_eq!((lat.rows, lat.cols), (2, 3));
//! assert_eq!(lat.order, vec![1, 5, 3, 4, 2, 0]);
//! ```

use std::collections::VecDeque;

use serde::{Deserialize, Serialize};

/// How markers are numbered.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Layout {
    /// A lattice of dots: rows top to bottom, then columns (seed 000, GelSight, 9DTact).
    #[default]
    Grid,
    /// Concentric rings or nested shapes: smallest first (seed 001's annuli).
    Rings,
}

/// A recovered lattice.
#[derive(Clone, Debug, PartialEq)]
pub struct Lattice {
    /// Indices into the input points, in grid order; points not on the lattice are absent.
    pub order: Vec<usize>,
    /// `(row, col)` of each point in `order`, 0-based from the top-left occupied cell.
    pub row_col: Vec<(u32, u32)>,
    /// Number of rows spanned.
    pub rows: u32,
    /// Number of columns spanned.
    pub cols: u32,
    /// Column pitch in pixels (along the rows).
    pub pitch_x_px: f64,
    /// Row pitch in pixels.
    pub pitch_y_px: f64,
    /// Grid rotation in radians (0: rows horizontal).
    pub angle_rad: f64,
    /// Input points left out (no consistent neighbour link, or a cell already taken).
    pub left_out: Vec<usize>,
}

/// Why no lattice could be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GridError {
    /// Fewer than two points.
    #[error("need at least 2 markers to build a grid, found {0}")]
    TooFew(usize),
    /// Points too close or all identical.
    #[error("markers have no measurable spacing")]
    NoSpacing,
}

fn k_nearest(points: &[(f64, f64)], i: usize, k: usize) -> Vec<(usize, f64)> {
    let (x, y) = points[i];
    let mut d: Vec<(usize, f64)> = points
        .iter()
        .enumerate()
        .filter(|&(j, _)| j != i)
        .map(|(j, &(px, py))| (j, ((px - x).powi(2) + (py - y).powi(2)).sqrt()))
        .collect();
    d.sort_by(|a, b| a.1.total_cmp(&b.1));
    d.truncate(k);
    d
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Recovers the lattice of `points` (pixel `(x, y)` positions).
pub fn lattice_from_points(points: &[(f64, f64)]) -> Result<Lattice, GridError> {
    let n = points.len();
    if n < 2 {
        return Err(GridError::TooFew(n));
    }
    let neighbours: Vec<Vec<(usize, f64)>> = (0..n).map(|i| k_nearest(points, i, 8)).collect();
    let mut nn: Vec<f64> = neighbours.iter().map(|v| v[0].1).collect();
    let pitch = median(&mut nn);
    if pitch.is_nan() || pitch <= 1e-9 {
        return Err(GridError::NoSpacing);
    }
    // Grid rotation: 4-fold circular mean of the short neighbour directions.
    let (mut c4, mut s4) = (0.0, 0.0);
    for (i, nb) in neighbours.iter().enumerate() {
        for &(j, d) in nb.iter().filter(|&&(_, d)| d < 1.3 * pitch) {
            let a = (points[j].1 - points[i].1).atan2(points[j].0 - points[i].0);
            c4 += (4.0 * a).cos();
            s4 += (4.0 * a).sin();
            let _ = d;
        }
    }
    let angle = s4.atan2(c4) / 4.0;
    let u = (angle.cos(), angle.sin());
    let v = (-angle.sin(), angle.cos());
    // Pitch along each axis from neighbour vectors within 25° of it.
    let (mut px, mut py) = (Vec::new(), Vec::new());
    let cos25 = 25f64.to_radians().cos();
    for (i, nb) in neighbours.iter().enumerate() {
        for &(j, d) in nb.iter().filter(|&&(_, d)| d < 2.0 * pitch) {
            let dx = points[j].0 - points[i].0;
            let dy = points[j].1 - points[i].1;
            let a = (dx * u.0 + dy * u.1).abs();
            let b = (dx * v.0 + dy * v.1).abs();
            if a >= cos25 * d {
                px.push(a);
            } else if b >= cos25 * d {
                py.push(b);
            }
        }
    }
    // Only the shortest vectors along each axis are single steps: keep those below 1.5× the
    // smallest-quartile value before taking the median.
    let step = |v: &mut Vec<f64>| -> f64 {
        if v.is_empty() {
            return pitch;
        }
        v.sort_by(f64::total_cmp);
        let q = v[v.len() / 4];
        let mut short: Vec<f64> = v.iter().copied().filter(|&x| x < 1.5 * q).collect();
        median(&mut short)
    };
    let pitch_x = step(&mut px);
    let pitch_y = step(&mut py);

    // Breadth-first propagation of integer indices from the point nearest the centroid.
    let cx = points.iter().map(|p| p.0).sum::<f64>() / n as f64;
    let cy = points.iter().map(|p| p.1).sum::<f64>() / n as f64;
    let start = (0..n)
        .min_by(|&a, &b| {
            let da = (points[a].0 - cx).powi(2) + (points[a].1 - cy).powi(2);
            let db = (points[b].0 - cx).powi(2) + (points[b].1 - cy).powi(2);
            da.total_cmp(&db)
        })
        .unwrap_or(0);
    // Start from the largest connected set of consistent links: try the centre first, then any
    // point not yet reached, and keep the biggest component.
    let mut best: Vec<Option<(i64, i64)>> = vec![None; n];
    let mut best_count = 0usize;
    let mut tried = vec![false; n];
    let mut seeds: Vec<usize> = vec![start];
    seeds.extend((0..n).filter(|&i| i != start));
    for seed in seeds {
        if tried[seed] {
            continue;
        }
        let mut idx: Vec<Option<(i64, i64)>> = vec![None; n];
        idx[seed] = Some((0, 0));
        let mut queue = VecDeque::from([seed]);
        let mut count = 1;
        while let Some(i) = queue.pop_front() {
            tried[i] = true;
            let (ii, jj) = idx[i].unwrap_or((0, 0));
            for &(j, d) in &neighbours[i] {
                if d > 1.6 * pitch_x.max(pitch_y) {
                    continue;
                }
                let dx = points[j].0 - points[i].0;
                let dy = points[j].1 - points[i].1;
                let a = (dx * u.0 + dy * u.1) / pitch_x;
                let b = (dx * v.0 + dy * v.1) / pitch_y;
                let (ra, rb) = (a.round(), b.round());
                let one_step = (ra.abs() + rb.abs()) as i64 == 1;
                if !one_step || (a - ra).abs() > 0.35 || (b - rb).abs() > 0.35 {
                    continue;
                }
                if idx[j].is_none() {
                    idx[j] = Some((ii + ra as i64, jj + rb as i64));
                    count += 1;
                    queue.push_back(j);
                }
            }
        }
        if count > best_count {
            best_count = count;
            best = idx;
        }
        if best_count * 2 > n {
            break;
        }
    }
    let (mut mi, mut mj) = (i64::MAX, i64::MAX);
    let (mut xi, mut xj) = (i64::MIN, i64::MIN);
    for &(i, j) in best.iter().flatten() {
        mi = mi.min(i);
        mj = mj.min(j);
        xi = xi.max(i);
        xj = xj.max(j);
    }
    let mut cells: Vec<(u32, u32, usize)> = best
        .iter()
        .enumerate()
        .filter_map(|(p, c)| c.map(|(i, j)| ((j - mj) as u32, (i - mi) as u32, p)))
        .collect();
    cells.sort();
    let mut order = Vec::with_capacity(cells.len());
    let mut row_col = Vec::with_capacity(cells.len());
    let mut left_out: Vec<usize> = (0..n).filter(|&p| best[p].is_none()).collect();
    for (k, &(r, c, p)) in cells.iter().enumerate() {
        if k > 0 && (cells[k - 1].0, cells[k - 1].1) == (r, c) {
            left_out.push(p);
            continue;
        }
        order.push(p);
        row_col.push((r, c));
    }
    left_out.sort_unstable();
    Ok(Lattice {
        order,
        row_col,
        rows: (xj - mj + 1).max(0) as u32,
        cols: (xi - mi + 1).max(0) as u32,
        pitch_x_px: pitch_x,
        pitch_y_px: pitch_y,
        angle_rad: angle,
        left_out,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotated_distorted_grid_with_outlier() {
        // 13 × 9 grid, rotated 5°, with barrel distortion and one speck between markers.
        let mut pts = Vec::new();
        let (c, s) = (5f64.to_radians().cos(), 5f64.to_radians().sin());
        for r in 0..9 {
            for col in 0..13 {
                let x = (f64::from(col) - 6.0) * 40.0;
                let y = (f64::from(r) - 4.0) * 45.0;
                let r2 = (x * x + y * y) / 300f64.powi(2);
                let k = 1.0 - 0.08 * r2;
                pts.push((320.0 + k * (c * x - s * y), 240.0 + k * (s * x + c * y)));
            }
        }
        // Shuffle deterministically.
        let mut shuffled: Vec<usize> = (0..pts.len()).collect();
        shuffled.sort_by_key(|&i| (i * 37) % 117);
        let mut input: Vec<(f64, f64)> = shuffled.iter().map(|&i| pts[i]).collect();
        input.push((320.0 + 20.0, 240.0 + 21.0));
        let lat = lattice_from_points(&input).unwrap();
        assert_eq!((lat.rows, lat.cols), (9, 13));
        assert_eq!(lat.order.len(), 117);
        assert_eq!(lat.left_out, vec![117]);
        for (k, &p) in lat.order.iter().enumerate() {
            assert_eq!(shuffled[p], k, "marker {k} out of order");
            assert_eq!(lat.row_col[k], ((k / 13) as u32, (k % 13) as u32));
        }
        assert!((lat.angle_rad.to_degrees() - 5.0).abs() < 1.0);
    }

    #[test]
    fn too_few_points() {
        assert_eq!(
            lattice_from_points(&[(1.0, 1.0)]),
            Err(GridError::TooFew(1))
        );
        assert_eq!(
            lattice_from_points(&[(1.0, 1.0), (1.0, 1.0)]),
            Err(GridError::NoSpacing)
        );
    }
}
