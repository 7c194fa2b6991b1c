//! Marker layouts: recognised from the marker centres of a reference frame, and numbered by one
//! documented rule per layout.
//!
//! | layout | recognised by | numbering (`row`, `col` in the sensor file) |
//! |---|---|---|
//! | [`Layout::Grid`] | two lattice directions among the neighbour links; a lattice walk with those steps numbers ≥ 90 % of the points | rows top to bottom, then columns left to right; `(row, col)` the lattice indices |
//! | [`Layout::Hex`] | three lattice directions closing a triangle (hexagonal or staggered arrays); a walk with the six steps numbers ≥ 90 % | rows along the lattice direction nearest the horizontal, top to bottom, then left to right; `col` in half-pitch steps, so it grows by 2 along a row and neighbours in adjacent rows differ by 1 |
//! | [`Layout::DotRings`] | the points lie on concentric circles around their centroid, each ring evenly filled | ring by ring from the centre out, then clockwise (on screen) from the dot nearest 12 o'clock; `(row, col)` = (ring, position in ring) |
//! | [`Layout::Irregular`] | anything else (random dot patterns) | top to bottom by centroid row, ties left to right; `(row, col)` the pitch-sized cell the marker lies in |
//! | [`Layout::Rings`] | nested blobs sharing a centre (annuli; seed 001), see [`annuli_share_centres`] | smallest first; `(0, k)` |
//!
//! The pitch is the median nearest-neighbour distance whatever the layout (for annuli, the
//! smallest gap between consecutive ring radii).
//!
//! The lattice walk does not assume a straight lattice: it starts at the point nearest the
//! centroid with the lattice directions of the whole set, and each point it reaches gets its own
//! basis, fitted to its links to points already numbered, which it hands on to its neighbours.
//! Lens distortion, a dome's foreshortening and a slightly rotated grid bend the lattice
//! gradually, and the walk follows them; a link is accepted only when it is within 0.3 of a
//! lattice step in both lattice coordinates. The walk decides whether the points are a lattice.
//! A hexagonal array is then numbered through its Delaunay triangles from the walk's first
//! triangle, by the parallelogram rule (`triangles`): the same around every loop, so a region
//! squeezed beyond the walk's tolerance (the crease at a deep contact's edge) is numbered like
//! the rest instead of being walked around.
//!
//! ```
//! use visuotact_vision::layout::{number_markers, Layout, LayoutChoice};
//! // A 3 × 2 grid given in scrambled order.
//! let pts = [(20.0, 10.0), (0.0, 0.0), (10.0, 10.0), (20.0, 0.0), (0.0, 10.0), (10.0, 0.0)];
//! let n = number_markers(&pts, LayoutChoice::Auto).unwrap();
//! assert_eq!(n.layout, Layout::Grid);
//! assert_eq!((n.rows, n.cols), (2, 3));
//! assert_eq!(n.order, vec![1, 5, 3, 4, 2, 0]);
//! ```

use std::collections::{HashMap, VecDeque};

use serde::{Deserialize, Serialize};

use crate::blobs::{Blob, MomentConvention};

mod triangles;

pub(crate) use triangles::PARALLELOGRAM_TOLERANCE;

/// How markers are laid out and numbered (the sensor file's `layout`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Layout {
    /// A lattice with two directions: rectangular (or oblique) grids (seed 000, GelSight, 9DTact).
    #[default]
    Grid,
    /// A lattice with three directions: hexagonal or staggered pin arrays (TacTip).
    Hex,
    /// Dots on concentric circles.
    DotRings,
    /// No lattice: random dot patterns.
    Irregular,
    /// Concentric rings or nested shapes: smallest first (seed 001's annuli).
    Rings,
}

impl Layout {
    /// Every layout.
    pub const ALL: [Layout; 5] = [
        Layout::Grid,
        Layout::Hex,
        Layout::DotRings,
        Layout::Irregular,
        Layout::Rings,
    ];

    /// The name in sensor files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Layout::Grid => "grid",
            Layout::Hex => "hex",
            Layout::DotRings => "dot-rings",
            Layout::Irregular => "irregular",
            Layout::Rings => "rings",
        }
    }

    /// What the layout is, in words.
    pub fn describe(self) -> &'static str {
        match self {
            Layout::Grid => "a rectangular grid",
            Layout::Hex => "a hexagonal (staggered) array",
            Layout::DotRings => "concentric rings of dots",
            Layout::Irregular => "an irregular dot pattern",
            Layout::Rings => "concentric annuli",
        }
    }

    /// A lattice's steps between neighbours in the sensor file's `(row, col)`, in turn around
    /// the circle (consecutive ones span a cell): a hexagonal array's six (`col` counts half
    /// pitches along a row, rows run down the image), a grid's four; none for the others.
    pub fn row_col_steps(self) -> &'static [(i64, i64)] {
        match self {
            Layout::Hex => &[(0, 2), (1, 1), (1, -1), (0, -2), (-1, -1), (-1, 1)],
            Layout::Grid => &[(0, 1), (1, 0), (0, -1), (-1, 0)],
            _ => &[],
        }
    }
}

/// Which layout calibration uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum LayoutChoice {
    /// Recognise it (rings → grid or hex → dot rings → irregular, the first that fits).
    #[default]
    Auto,
    /// This layout; refused when it does not fit the markers.
    Only(Layout),
}

visuotact_image::from_str_by_parse!(LayoutChoice, crate::ConfigError);

impl LayoutChoice {
    /// The names [`LayoutChoice::parse`] and `FromStr` read: `auto`, then every layout's.
    pub const NAMES: &'static [&'static str] =
        &["auto", "grid", "hex", "dot-rings", "irregular", "rings"];

    /// Parses `auto` or a layout name.
    pub fn parse(s: &str) -> Result<Self, crate::ConfigError> {
        if s == "auto" {
            return Ok(Self::Auto);
        }
        Layout::ALL
            .into_iter()
            .find(|l| l.name() == s)
            .map(Self::Only)
            .ok_or_else(|| {
                crate::ConfigError::unknown(
                    "layout",
                    s,
                    format!("auto, {}", Layout::ALL.map(Layout::name).join(", ")),
                )
            })
    }
}

/// Why markers could not be numbered.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LayoutError {
    /// Fewer than two points.
    #[error("need at least 2 markers to number them, found {0}")]
    TooFew(usize),
    /// Points too close or all identical.
    #[error("markers have no measurable spacing")]
    NoSpacing,
    /// The requested layout does not fit the markers.
    #[error("layout {layout} does not fit: {why}; the markers look like {seen} (use --layout auto or --layout {seen_name})", layout = .layout.name(), seen = .seen.describe(), seen_name = .seen.name())]
    DoesNotFit {
        /// The layout asked for.
        layout: Layout,
        /// What did not fit.
        why: String,
        /// What recognition finds instead.
        seen: Layout,
    },
}

/// Markers in numbering order.
#[derive(Clone, Debug, PartialEq)]
pub struct Numbering {
    /// The layout.
    pub layout: Layout,
    /// Indices into the input points, in numbering order; points left out are absent.
    pub order: Vec<usize>,
    /// `(row, col)` of each point in `order` (see the module table).
    pub row_col: Vec<(u32, u32)>,
    /// Rows spanned.
    pub rows: u32,
    /// Columns spanned.
    pub cols: u32,
    /// Median nearest-neighbour distance, pixels.
    pub pitch_px: f64,
    /// Input points left out (not on the lattice, or on a lattice site already taken).
    pub left_out: Vec<usize>,
    /// Per point in `order`, its neighbours as positions in `order` (lattice steps for
    /// lattices, otherwise the points within 1.5 × its nearest-neighbour distance), nearest
    /// first, at most 8.
    pub neighbours: Vec<Vec<u32>>,
}

/// The `k` nearest other points of each point, nearest first, with distances.
pub(crate) fn k_nearest_all(points: &[(f64, f64)], k: usize) -> Vec<Vec<(usize, f64)>> {
    // Sorted by x: scan outwards until the x gap exceeds the k-th best distance.
    let n = points.len();
    let mut by_x: Vec<usize> = (0..n).collect();
    by_x.sort_by(|&a, &b| points[a].0.total_cmp(&points[b].0));
    let mut rank = vec![0usize; n];
    for (r, &i) in by_x.iter().enumerate() {
        rank[i] = r;
    }
    let mut out = Vec::with_capacity(n);
    let mut best: Vec<(usize, f64)> = Vec::with_capacity(k + 1);
    for i in 0..n {
        best.clear();
        let p = points[i];
        let consider = |j: usize, best: &mut Vec<(usize, f64)>| -> bool {
            let q = points[j];
            let dx = q.0 - p.0;
            let worst = if best.len() == k {
                best[k - 1].1
            } else {
                f64::INFINITY
            };
            if dx.abs() > worst {
                return false;
            }
            let d = dx.hypot(q.1 - p.1);
            if d < worst {
                let at = best.partition_point(|&(_, e)| e <= d);
                best.insert(at, (j, d));
                best.truncate(k);
            }
            true
        };
        let r = rank[i];
        let (mut lo, mut hi) = (r, r + 1);
        let (mut go_lo, mut go_hi) = (true, true);
        while go_lo || go_hi {
            if go_lo {
                if lo == 0 {
                    go_lo = false;
                } else {
                    lo -= 1;
                    go_lo = consider(by_x[lo], &mut best);
                }
            }
            if go_hi {
                if hi >= n {
                    go_hi = false;
                } else {
                    go_hi = consider(by_x[hi], &mut best);
                    hi += 1;
                }
            }
        }
        out.push(best.clone());
    }
    out
}

/// The median of `v` (sorted in place; the mean of the middle two of an even count; NaN when
/// empty).
///
/// ```
/// let mut v = [3.0, 1.0, 4.0, 2.0];
/// assert_eq!(visuotact_vision::layout::median(&mut v), 2.5);
/// assert!(visuotact_vision::layout::median(&mut []).is_nan());
/// ```
pub fn median(v: &mut [f64]) -> f64 {
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

/// Whether blobs are nested shapes sharing centres (annuli): at least half of them have their
/// centroid within a quarter of another, larger blob's major axis of that blob's centroid and
/// inside its bounding box.
pub fn annuli_share_centres(blobs: &[Blob]) -> bool {
    if blobs.len() < 2 {
        return false;
    }
    let majors: Vec<f64> = blobs
        .iter()
        .map(|b| b.shape(MomentConvention::Pixel).major_axis_px)
        .collect();
    let nested = blobs
        .iter()
        .enumerate()
        .filter(|&(i, a)| {
            blobs.iter().enumerate().any(|(j, b)| {
                j != i
                    && majors[j] > majors[i]
                    && (a.x_px - b.x_px).hypot(a.y_px - b.y_px) < 0.25 * majors[j]
                    && a.bbox.x0 >= b.bbox.x0
                    && a.bbox.x1 <= b.bbox.x1
                    && a.bbox.y0 >= b.bbox.y0
                    && a.bbox.y1 <= b.bbox.y1
            }) || blobs.iter().enumerate().any(|(j, b)| {
                j != i
                    && majors[j] < majors[i]
                    && (a.x_px - b.x_px).hypot(a.y_px - b.y_px) < 0.25 * majors[i]
                    && b.bbox.x0 >= a.bbox.x0
                    && b.bbox.x1 <= a.bbox.x1
                    && b.bbox.y0 >= a.bbox.y0
                    && b.bbox.y1 <= a.bbox.y1
            })
        })
        .count();
    2 * nested >= blobs.len()
}

/// Lattice directions found among the neighbour links: unit vectors with their weight relative
/// to the strongest, strongest first.
fn lattice_directions(points: &[(f64, f64)], nbrs: &[Vec<(usize, f64)>]) -> Vec<((f64, f64), f64)> {
    // Histogram of link directions folded to 0..180°, one-degree bins, each of the six
    // nearest links weighted by (nearest distance / length)².
    let mut hist = [0.0f64; 180];
    for (i, nb) in nbrs.iter().enumerate() {
        let Some(&(_, d0)) = nb.first() else { continue };
        for &(j, d) in nb.iter().take(6) {
            let a = (points[j].1 - points[i].1)
                .atan2(points[j].0 - points[i].0)
                .to_degrees()
                .rem_euclid(180.0);
            let w = (d0 / d.max(1e-9)).powi(2);
            hist[(a as usize).min(179)] += w;
        }
    }
    // Circular smoothing with a ±4° triangle.
    let mut smooth = [0.0f64; 180];
    for (b, s) in smooth.iter_mut().enumerate() {
        for o in -4i32..=4 {
            let k = (b as i32 + o).rem_euclid(180) as usize;
            *s += hist[k] * f64::from(5 - o.abs());
        }
    }
    let top = smooth.iter().copied().fold(0.0, f64::max);
    if top <= 0.0 {
        return Vec::new();
    }
    let mut peaks: Vec<(f64, usize)> = (0..180)
        .filter(|&b| {
            let s = smooth[b];
            s >= 0.35 * top
                && (1..=12).all(|o| {
                    let l = smooth[(b + 180 - o) % 180];
                    let r = smooth[(b + o) % 180];
                    s >= l && s > r
                })
        })
        .map(|b| (smooth[b], b))
        .collect();
    peaks.sort_by(|a, b| b.0.total_cmp(&a.0));
    peaks
        .into_iter()
        .map(|(w, b)| {
            // Refine by the weighted mean of the raw bins within ±6° (doubled angles would be
            // needed only across the 0/180 seam, handled by unwrapping around the peak).
            let (mut sw, mut sa) = (0.0, 0.0);
            for o in -6i32..=6 {
                let k = (b as i32 + o).rem_euclid(180) as usize;
                sw += hist[k];
                sa += hist[k] * (b as f64 + f64::from(o) + 0.5);
            }
            let a = (if sw > 0.0 { sa / sw } else { b as f64 + 0.5 }).to_radians();
            ((a.cos(), a.sin()), w / top)
        })
        .collect()
}

/// A lattice step and the pixel offset it spans.
type StepOffset = ((i64, i64), (f64, f64));

/// A 2 × 2 basis: the two lattice step vectors as columns.
#[derive(Clone, Copy, Debug)]
struct Basis {
    a1: (f64, f64),
    a2: (f64, f64),
}

impl Basis {
    /// Lattice coordinates of a pixel offset.
    fn coords(&self, d: (f64, f64)) -> Option<(f64, f64)> {
        let det = self.a1.0 * self.a2.1 - self.a2.0 * self.a1.1;
        if det.abs() < 1e-12 {
            return None;
        }
        Some((
            (d.0 * self.a2.1 - d.1 * self.a2.0) / det,
            (self.a1.0 * d.1 - self.a1.1 * d.0) / det,
        ))
    }

    fn step(&self, s: (i64, i64)) -> (f64, f64) {
        (
            s.0 as f64 * self.a1.0 + s.1 as f64 * self.a2.0,
            s.0 as f64 * self.a1.1 + s.1 as f64 * self.a2.1,
        )
    }

    /// Least-squares basis from (lattice step, pixel offset) pairs; `None` when the steps do
    /// not span the plane.
    fn fit(pairs: &[StepOffset]) -> Option<Self> {
        // Solve B · S = P in the least-squares sense: B = (P Sᵀ)(S Sᵀ)⁻¹.
        let (mut s11, mut s12, mut s22) = (0.0, 0.0, 0.0);
        let (mut p11, mut p12, mut p21, mut p22) = (0.0, 0.0, 0.0, 0.0);
        for &((m, n), (dx, dy)) in pairs {
            let (m, n) = (m as f64, n as f64);
            s11 += m * m;
            s12 += m * n;
            s22 += n * n;
            p11 += dx * m;
            p12 += dx * n;
            p21 += dy * m;
            p22 += dy * n;
        }
        let det = s11 * s22 - s12 * s12;
        if det < 0.5 {
            return None;
        }
        let (i11, i12, i22) = (s22 / det, -s12 / det, s11 / det);
        Some(Self {
            a1: (p11 * i11 + p12 * i12, p21 * i11 + p22 * i12),
            a2: (p11 * i12 + p12 * i22, p21 * i12 + p22 * i22),
        })
    }
}

const GRID_STEPS: [(i64, i64); 4] = [(1, 0), (-1, 0), (0, 1), (0, -1)];
pub(crate) const HEX_STEPS: [(i64, i64); 6] = [(1, 0), (-1, 0), (0, 1), (0, -1), (-1, 1), (1, -1)];

/// A lattice walk's result: integer coordinates per point.
struct Walk {
    coords: Vec<Option<(i64, i64)>>,
    count: usize,
}

/// Walks the lattice from `start` with the initial basis `b0`, accepting links within 0.3 of one
/// of `steps` in both coordinates.
fn walk(
    points: &[(f64, f64)],
    nbrs: &[Vec<(usize, f64)>],
    start: usize,
    b0: Basis,
    steps: &[(i64, i64)],
) -> Walk {
    let mut coords = vec![None; points.len()];
    coords[start] = Some((0, 0));
    walk_on(points, nbrs, coords, &[start], b0, steps)
}

/// Goes on numbering from the points `coords` holds, `from` first, by the walk of [`walk`]:
/// each point reached gets its own basis, fitted to its links to numbered points (else `b0`),
/// and numbers its unnumbered neighbours one lattice step away.
fn walk_on(
    points: &[(f64, f64)],
    nbrs: &[Vec<(usize, f64)>],
    mut coords: Vec<Option<(i64, i64)>>,
    from: &[usize],
    b0: Basis,
    steps: &[(i64, i64)],
) -> Walk {
    let n = points.len();
    let mut basis: Vec<Option<Basis>> = vec![None; n];
    let mut site: HashMap<(i64, i64), usize> = HashMap::with_capacity(n);
    for (p, c) in coords.iter().enumerate() {
        if let Some(c) = c {
            site.insert(*c, p);
        }
    }
    let mut queue: VecDeque<usize> = from.iter().copied().collect();
    queue.extend((0..n).filter(|p| coords[*p].is_some() && !from.contains(p)));
    let mut count = site.len();
    let mut pairs = Vec::with_capacity(8);
    while let Some(i) = queue.pop_front() {
        let ci = coords[i].unwrap_or((0, 0));
        // This point's own basis: fitted to its links to numbered neighbours, or inherited.
        let mut b = basis[i].unwrap_or(b0);
        pairs.clear();
        for &(j, _) in &nbrs[i] {
            if let Some(cj) = coords[j] {
                let s = (cj.0 - ci.0, cj.1 - ci.1);
                if steps.contains(&s) {
                    pairs.push((s, (points[j].0 - points[i].0, points[j].1 - points[i].1)));
                }
            }
        }
        if let Some(f) = Basis::fit(&pairs) {
            b = f;
        }
        basis[i] = Some(b);
        let reach = 1.6
            * steps
                .iter()
                .map(|&s| {
                    let v = b.step(s);
                    v.0.hypot(v.1)
                })
                .fold(0.0, f64::max);
        for &(j, d) in &nbrs[i] {
            if d > reach || coords[j].is_some() {
                continue;
            }
            let off = (points[j].0 - points[i].0, points[j].1 - points[i].1);
            let Some((m, k)) = b.coords(off) else {
                continue;
            };
            let s = (m.round() as i64, k.round() as i64);
            if !steps.contains(&s) || (m - s.0 as f64).abs() > 0.3 || (k - s.1 as f64).abs() > 0.3 {
                continue;
            }
            let cj = (ci.0 + s.0, ci.1 + s.1);
            if site.contains_key(&cj) {
                continue;
            }
            site.insert(cj, j);
            coords[j] = Some(cj);
            basis[j] = Some(b);
            count += 1;
            queue.push_back(j);
        }
    }
    Walk { coords, count }
}

/// The point nearest the centroid of all points.
fn central_point(points: &[(f64, f64)]) -> usize {
    let n = points.len() as f64;
    let cx = points.iter().map(|p| p.0).sum::<f64>() / n;
    let cy = points.iter().map(|p| p.1).sum::<f64>() / n;
    (0..points.len())
        .min_by(|&a, &b| {
            let da = (points[a].0 - cx).powi(2) + (points[a].1 - cy).powi(2);
            let db = (points[b].0 - cx).powi(2) + (points[b].1 - cy).powi(2);
            da.total_cmp(&db)
        })
        .unwrap_or(0)
}

/// The start point's link along unit direction `u` (either sense): its length, or `None`.
fn link_along(
    points: &[(f64, f64)],
    nbrs: &[Vec<(usize, f64)>],
    i: usize,
    u: (f64, f64),
) -> Option<f64> {
    nbrs[i]
        .iter()
        .take(8)
        .filter(|&&(j, d)| {
            let dx = points[j].0 - points[i].0;
            let dy = points[j].1 - points[i].1;
            (dx * u.0 + dy * u.1).abs() >= 15f64.to_radians().cos() * d
        })
        .map(|&(_, d)| d)
        .next()
}

/// A lattice fit: its numbering and its basis kind.
struct LatticeFit {
    layout: Layout,
    /// The numbering: the walk's, and for a hexagonal array its triangles' (see
    /// [`triangles`]).
    walk: Walk,
    /// Points the walk alone numbered, by lengths and angles: whether the points are a lattice
    /// at all (the triangles also number rings of dots, which are not).
    walked: usize,
}

/// Tries the grid (two directions) or hex (three) lattice on the points.
fn fit_lattice(
    points: &[(f64, f64)],
    nbrs: &[Vec<(usize, f64)>],
    layout: Layout,
    pitch: f64,
) -> Option<LatticeFit> {
    let weighted = lattice_directions(points, nbrs);
    // Hexagonal: three directions of comparable strength (a rectangular grid's diagonals are
    // a quarter of its axes' strength).
    let hexagonal = weighted.len() >= 3 && weighted[2].1 >= 0.5;
    let dirs: Vec<(f64, f64)> = weighted.iter().map(|d| d.0).collect();
    let start = central_point(points);
    // Orient: a1 nearest the horizontal pointing right; the others pointing down.
    let right = |u: (f64, f64)| if u.0 < 0.0 { (-u.0, -u.1) } else { u };
    let down = |u: (f64, f64)| if u.1 < 0.0 { (-u.0, -u.1) } else { u };
    let len = |u: (f64, f64)| link_along(points, nbrs, start, u).unwrap_or(pitch);
    match layout {
        Layout::Grid => {
            // Three comparable directions are a hexagonal array, not a grid (an oblique basis
            // would number it, but not as rows and columns).
            if dirs.len() < 2 || hexagonal {
                return None;
            }
            let (mut u1, mut u2) = (dirs[0], dirs[1]);
            if u2.1.abs() < u1.1.abs() {
                std::mem::swap(&mut u1, &mut u2);
            }
            let (u1, u2) = (right(u1), down(u2));
            let (l1, l2) = (len(u1), len(u2));
            let basis = Basis {
                a1: (u1.0 * l1, u1.1 * l1),
                a2: (u2.0 * l2, u2.1 * l2),
            };
            let walk = walk(points, nbrs, start, basis, &GRID_STEPS);
            Some(LatticeFit {
                layout,
                walked: walk.count,
                walk,
            })
        }
        Layout::Hex => {
            if !hexagonal {
                return None;
            }
            let mut d: Vec<(f64, f64)> = dirs[..3].to_vec();
            d.sort_by(|a, b| a.1.abs().total_cmp(&b.1.abs()));
            let u1 = right(d[0]);
            let (mut u2, mut u3) = (down(d[1]), down(d[2]));
            // a2 leans right, a3 = a2 − a1 leans left.
            if u2.0 < u3.0 {
                std::mem::swap(&mut u2, &mut u3);
            }
            let (l1, l2, l3) = (len(u1), len(u2), len(u3));
            let a1 = (u1.0 * l1, u1.1 * l1);
            let a2 = (u2.0 * l2, u2.1 * l2);
            let a3 = (u3.0 * l3, u3.1 * l3);
            // The three must close: a2 − a1 ≈ a3.
            let miss = (a2.0 - a1.0 - a3.0).hypot(a2.1 - a1.1 - a3.1);
            if miss > 0.3 * l1.max(l2).max(l3) {
                return None;
            }
            let basis = Basis { a1, a2 };
            let walked = walk(points, nbrs, start, basis, &HEX_STEPS);
            let metric = walked.count;
            // The walk's numbering around the start, carried through the lattice triangles
            // (the same around every loop), then walked on to points no triangle reaches.
            let walk = triangles::numbered_by_triangles(points, &walked.coords, start, &HEX_STEPS)
                .map_or(walked, |c| {
                    walk_on(points, nbrs, c, &[start], basis, &HEX_STEPS)
                });
            Some(LatticeFit {
                layout,
                walk,
                walked: metric,
            })
        }
        _ => None,
    }
}

/// Dot rings: per point its ring index and angle, or `None` when the points are not rings.
struct RingsFit {
    ring: Vec<usize>,
    angle: Vec<f64>,
    rings: usize,
}

/// Concentric circles of dots around the centroid: the sorted radii split into rings at gaps
/// over half a pitch; each ring must have radius spread under 0.15 pitch, evenly spaced dots
/// (angular gaps within 25 % of their mean) and at least 6 dots (or 1 at the centre).
fn fit_dot_rings(points: &[(f64, f64)], pitch: f64) -> Result<RingsFit, String> {
    let n = points.len();
    let cx = points.iter().map(|p| p.0).sum::<f64>() / n as f64;
    let cy = points.iter().map(|p| p.1).sum::<f64>() / n as f64;
    let mut by_r: Vec<(f64, usize)> = points
        .iter()
        .enumerate()
        .map(|(i, p)| ((p.0 - cx).hypot(p.1 - cy), i))
        .collect();
    by_r.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut ring = vec![0usize; n];
    let mut angle = vec![0.0f64; n];
    let mut k = 0;
    let mut start = 0;
    while start < n {
        let mut end = start + 1;
        while end < n && by_r[end].0 - by_r[end - 1].0 < 0.5 * pitch {
            end += 1;
        }
        let members = &by_r[start..end];
        let spread = members.last().map_or(0.0, |l| l.0) - members[0].0;
        let r_mean = members.iter().map(|m| m.0).sum::<f64>() / members.len() as f64;
        if members.len() == 1 && r_mean < 0.5 * pitch {
            // The centre dot.
        } else if members.len() < 6 {
            return Err(format!(
                "a ring of radius {r_mean:.1} px has only {} dots",
                members.len()
            ));
        } else if spread > 0.15 * pitch {
            return Err(format!(
                "the dots at radius {r_mean:.1} px spread over {spread:.1} px radially"
            ));
        } else {
            let mut a: Vec<f64> = members
                .iter()
                .map(|&(_, i)| (points[i].1 - cy).atan2(points[i].0 - cx))
                .collect();
            a.sort_by(f64::total_cmp);
            let m = a.len();
            let gaps: Vec<f64> = (0..m)
                .map(|q| {
                    if q + 1 < m {
                        a[q + 1] - a[q]
                    } else {
                        a[0] + std::f64::consts::TAU - a[q]
                    }
                })
                .collect();
            let mean = std::f64::consts::TAU / m as f64;
            if gaps.iter().any(|g| (g - mean).abs() > 0.25 * mean) {
                return Err(format!(
                    "the dots at radius {r_mean:.1} px are not evenly spaced around it"
                ));
            }
        }
        for &(_, i) in members {
            ring[i] = k;
            // Clockwise on screen from 12 o'clock: y grows downwards.
            angle[i] = (points[i].0 - cx).atan2(-(points[i].1 - cy));
        }
        k += 1;
        start = end;
    }
    Ok(RingsFit {
        ring,
        angle,
        rings: k,
    })
}

/// Neighbours within 1.5 × each point's nearest distance (at most 8), as positions in `order`.
fn near_neighbours(
    order: &[usize],
    nbrs: &[Vec<(usize, f64)>],
    keep: impl Fn(usize, usize) -> bool,
) -> Vec<Vec<u32>> {
    let mut pos = vec![u32::MAX; nbrs.len()];
    for (k, &i) in order.iter().enumerate() {
        pos[i] = k as u32;
    }
    order
        .iter()
        .map(|&i| {
            let d0 = nbrs[i].first().map_or(0.0, |x| x.1);
            nbrs[i]
                .iter()
                .filter(|&&(j, d)| d <= 1.5 * d0 && pos[j] != u32::MAX && keep(i, j))
                .take(8)
                .map(|&(j, _)| pos[j])
                .collect()
        })
        .collect()
}

/// Numbers the marker centres `points` (pixel `(x, y)`) by `choice`. [`Layout::Rings`] needs
/// blob sizes and is numbered by the calibration; asked for here it is refused.
pub fn number_markers(
    points: &[(f64, f64)],
    choice: LayoutChoice,
) -> Result<Numbering, LayoutError> {
    let n = points.len();
    if n < 2 {
        return Err(LayoutError::TooFew(n));
    }
    let nbrs = k_nearest_all(points, 12.min(n - 1));
    let mut nn: Vec<f64> = nbrs.iter().map(|v| v[0].1).collect();
    let pitch = median(&mut nn);
    if pitch.is_nan() || pitch <= 1e-9 {
        return Err(LayoutError::NoSpacing);
    }
    let lattice =
        |layout| fit_lattice(points, &nbrs, layout, pitch).filter(|f| 10 * f.walk.count >= 9 * n);
    let fit_of = |layout: Layout| -> Option<Numbering> {
        match layout {
            Layout::Grid | Layout::Hex => {
                lattice(layout).map(|f| lattice_numbering(points, &nbrs, f, pitch))
            }
            Layout::DotRings => fit_dot_rings(points, pitch)
                .ok()
                .map(|r| rings_numbering(points, &nbrs, &r, pitch)),
            Layout::Irregular => Some(irregular_numbering(points, &nbrs, pitch)),
            Layout::Rings => None,
        }
    };
    let recognised = || -> Numbering {
        // A lattice with three directions that numbers as many points as two is hexagonal.
        let hex = lattice(Layout::Hex);
        let grid = lattice(Layout::Grid);
        let best = match (hex, grid) {
            (Some(h), Some(g)) => Some(if h.walk.count >= g.walk.count { h } else { g }),
            (h, g) => h.or(g),
        };
        if let Some(f) = best {
            if f.walked == n || fit_dot_rings(points, pitch).is_err() {
                return lattice_numbering(points, &nbrs, f, pitch);
            }
        }
        if let Ok(r) = fit_dot_rings(points, pitch) {
            return rings_numbering(points, &nbrs, &r, pitch);
        }
        irregular_numbering(points, &nbrs, pitch)
    };
    match choice {
        LayoutChoice::Auto => Ok(recognised()),
        LayoutChoice::Only(layout) => fit_of(layout).ok_or_else(|| {
            let why = match layout {
                Layout::Grid | Layout::Hex => {
                    let got = fit_lattice(points, &nbrs, layout, pitch).map_or(0, |f| f.walk.count);
                    format!(
                        "only {got} of {n} markers lie on {} (90 % needed)",
                        layout.describe()
                    )
                }
                Layout::DotRings => fit_dot_rings(points, pitch).err().unwrap_or_default(),
                Layout::Rings => format!("no two of the {n} blobs share a centre"),
                Layout::Irregular => String::new(),
            };
            LayoutError::DoesNotFit {
                layout,
                why,
                seen: recognised().layout,
            }
        }),
    }
}

fn lattice_numbering(
    points: &[(f64, f64)],
    nbrs: &[Vec<(usize, f64)>],
    fit: LatticeFit,
    pitch: f64,
) -> Numbering {
    let coords = &fit.walk.coords;
    // Hex: rows are lines of constant j (along a1); the column counts half pitches along the
    // row, 2i + j. Grid: (j, i).
    let rc = |(i, j): (i64, i64)| match fit.layout {
        Layout::Hex => (j, 2 * i + j),
        _ => (j, i),
    };
    let mut cells: Vec<(i64, i64, usize)> = coords
        .iter()
        .enumerate()
        .filter_map(|(p, c)| c.map(|c| (rc(c).0, rc(c).1, p)))
        .collect();
    let r0 = cells.iter().map(|c| c.0).min().unwrap_or(0);
    let c0 = cells.iter().map(|c| c.1).min().unwrap_or(0);
    let r1 = cells.iter().map(|c| c.0).max().unwrap_or(0);
    let c1 = cells.iter().map(|c| c.1).max().unwrap_or(0);
    cells.sort();
    let order: Vec<usize> = cells.iter().map(|c| c.2).collect();
    let row_col = cells
        .iter()
        .map(|c| ((c.0 - r0) as u32, (c.1 - c0) as u32))
        .collect();
    let steps: &[(i64, i64)] = if fit.layout == Layout::Hex {
        &HEX_STEPS
    } else {
        &GRID_STEPS
    };
    let neighbours = near_neighbours(&order, nbrs, |i, j| match (coords[i], coords[j]) {
        (Some(a), Some(b)) => steps.contains(&(b.0 - a.0, b.1 - a.1)),
        _ => false,
    });
    Numbering {
        layout: fit.layout,
        left_out: (0..points.len()).filter(|&p| coords[p].is_none()).collect(),
        order,
        row_col,
        rows: (r1 - r0 + 1) as u32,
        cols: (c1 - c0 + 1) as u32,
        pitch_px: pitch,
        neighbours,
    }
}

fn rings_numbering(
    points: &[(f64, f64)],
    nbrs: &[Vec<(usize, f64)>],
    fit: &RingsFit,
    pitch: f64,
) -> Numbering {
    let mut order: Vec<usize> = Vec::with_capacity(points.len());
    let mut row_col = Vec::with_capacity(points.len());
    let mut cols = 0;
    for k in 0..fit.rings {
        let mut members: Vec<usize> = (0..points.len()).filter(|&i| fit.ring[i] == k).collect();
        // From the dot nearest 12 o'clock (angles in −π..π, 0 at 12 o'clock), clockwise.
        let first = members
            .iter()
            .copied()
            .min_by(|&a, &b| fit.angle[a].abs().total_cmp(&fit.angle[b].abs()))
            .unwrap_or(0);
        let a0 = fit.angle[first];
        members.sort_by(|&a, &b| {
            let ka = (fit.angle[a] - a0).rem_euclid(std::f64::consts::TAU);
            let kb = (fit.angle[b] - a0).rem_euclid(std::f64::consts::TAU);
            ka.total_cmp(&kb)
        });
        cols = cols.max(members.len() as u32);
        for (q, &i) in members.iter().enumerate() {
            order.push(i);
            row_col.push((k as u32, q as u32));
        }
    }
    let neighbours = near_neighbours(&order, nbrs, |_, _| true);
    Numbering {
        layout: Layout::DotRings,
        order,
        row_col,
        rows: fit.rings as u32,
        cols,
        pitch_px: pitch,
        left_out: Vec::new(),
        neighbours,
    }
}

fn irregular_numbering(points: &[(f64, f64)], nbrs: &[Vec<(usize, f64)>], pitch: f64) -> Numbering {
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by(|&a, &b| {
        points[a]
            .1
            .total_cmp(&points[b].1)
            .then(points[a].0.total_cmp(&points[b].0))
    });
    let x0 = points.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
    let y0 = points.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
    let row_col: Vec<(u32, u32)> = order
        .iter()
        .map(|&i| {
            (
                ((points[i].1 - y0) / pitch) as u32,
                ((points[i].0 - x0) / pitch) as u32,
            )
        })
        .collect();
    let rows = row_col.iter().map(|c| c.0 + 1).max().unwrap_or(0);
    let cols = row_col.iter().map(|c| c.1 + 1).max().unwrap_or(0);
    let neighbours = near_neighbours(&order, nbrs, |_, _| true);
    Numbering {
        layout: Layout::Irregular,
        order,
        row_col,
        rows,
        cols,
        pitch_px: pitch,
        left_out: Vec::new(),
        neighbours,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic shuffle.
    fn shuffled(pts: &[(f64, f64)]) -> (Vec<(f64, f64)>, Vec<usize>) {
        let mut idx: Vec<usize> = (0..pts.len()).collect();
        idx.sort_by_key(|&i| (i * 7919 + 13) % pts.len().max(1) * 1000 + i);
        (idx.iter().map(|&i| pts[i]).collect(), idx)
    }

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
        let (mut input, idx) = shuffled(&pts);
        input.push((320.0 + 20.0, 240.0 + 21.0));
        let n = number_markers(&input, LayoutChoice::Auto).unwrap();
        assert_eq!(n.layout, Layout::Grid);
        assert_eq!((n.rows, n.cols), (9, 13));
        assert_eq!(n.order.len(), 117);
        assert_eq!(n.left_out, vec![117]);
        for (k, &p) in n.order.iter().enumerate() {
            assert_eq!(idx[p], k, "marker {k} out of order");
            assert_eq!(n.row_col[k], ((k / 13) as u32, (k % 13) as u32));
        }
        // Interior markers have their four lattice neighbours.
        assert_eq!(n.neighbours[13 + 1].len(), 4);
    }

    #[test]
    fn hexagonal_array_in_a_circle() {
        // A hexagonal array of pitch 20 cut to a disc, rotated 12°.
        let (c, s) = (12f64.to_radians().cos(), 12f64.to_radians().sin());
        let mut pts = Vec::new();
        for j in -12i32..=12 {
            for i in -12i32..=12 {
                let x = (f64::from(i) + 0.5 * f64::from(j.rem_euclid(2))) * 20.0;
                let y = f64::from(j) * 20.0 * 3f64.sqrt() / 2.0;
                if x.hypot(y) <= 200.0 {
                    pts.push((320.0 + c * x - s * y, 240.0 + s * x + c * y));
                }
            }
        }
        let (input, _) = shuffled(&pts);
        let n = number_markers(&input, LayoutChoice::Auto).unwrap();
        assert_eq!(n.layout, Layout::Hex);
        assert_eq!(n.order.len(), pts.len());
        assert!((n.pitch_px - 20.0).abs() < 1e-9);
        // Rows top to bottom, columns left to right, and half-pitch column steps along a row.
        for w in n.order.windows(2).zip(n.row_col.windows(2)) {
            let ((a, b), (ra, rb)) = ((w.0[0], w.0[1]), (w.1[0], w.1[1]));
            if ra.0 == rb.0 {
                assert_eq!(rb.1, ra.1 + 2);
                assert!(input[b].0 > input[a].0);
            } else {
                assert_eq!(rb.0, ra.0 + 1);
            }
        }
        // Interior pins have six neighbours.
        assert!(n.neighbours.iter().filter(|v| v.len() == 6).count() > pts.len() / 2);
        // Forcing a rectangular grid on it is refused, naming what it is.
        let e = number_markers(&input, LayoutChoice::Only(Layout::Grid)).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("hexagonal"), "{msg}");
    }

    /// A hexagonal patch (side 8, 217 pins, pitch 20) bent like a dome's rim and squeezed
    /// across a crease to 0.45 of its pitch, as at the edge of a deep contact: numbered as
    /// one lattice, every pin at its own lattice site (rows of 9 … 17 … 9).
    #[test]
    fn a_squeezed_hexagonal_array_is_numbered_as_one_lattice() {
        let mut pts = Vec::new();
        let mut truth = Vec::new();
        for j in -8i64..=8 {
            for i in -8i64..=8 {
                if (i + j).abs() > 8 {
                    continue;
                }
                let x = (i as f64 + 0.5 * j as f64) * 20.0;
                let y = j as f64 * 20.0 * 3f64.sqrt() / 2.0;
                // The crease: x squeezed around x = 30 (local scale 1 − 11/20); the rim bent.
                let x2 = x - 11.0 * (((x - 30.0) / 20.0).tanh());
                let y2 = y + 0.0008 * x2 * x2;
                pts.push((400.0 + x2, 300.0 + y2));
                truth.push((j, 2 * i + j));
            }
        }
        let (input, idx) = shuffled(&pts);
        let n = number_markers(&input, LayoutChoice::Only(Layout::Hex)).unwrap();
        assert_eq!(n.order.len(), pts.len(), "left out: {:?}", n.left_out);
        assert_eq!(n.rows, 17);
        // Each pin's (row, col) is its lattice site, up to one offset for all.
        let site = |k: usize| truth[idx[n.order[k]]];
        let (r0, c0) = (
            site(0).0 - i64::from(n.row_col[0].0),
            site(0).1 - i64::from(n.row_col[0].1),
        );
        for (k, &(r, c)) in n.row_col.iter().enumerate() {
            assert_eq!(site(k), (i64::from(r) + r0, i64::from(c) + c0), "pin {k}");
        }
    }

    #[test]
    fn dot_rings_in_polar_order() {
        let mut pts = vec![(300.0, 200.0)];
        for k in 1..=4 {
            let m = 6 * k;
            for q in 0..m {
                let t = 0.3 + q as f64 * std::f64::consts::TAU / m as f64;
                let r = 25.0 * k as f64;
                pts.push((300.0 + r * t.cos(), 200.0 + r * t.sin()));
            }
        }
        let (input, _) = shuffled(&pts);
        let n = number_markers(&input, LayoutChoice::Auto).unwrap();
        assert_eq!(n.layout, Layout::DotRings);
        assert_eq!(n.rows, 5);
        assert_eq!(n.order.len(), pts.len());
        assert_eq!(input[n.order[0]], (300.0, 200.0));
        // Ring 1 starts at the dot nearest 12 o'clock and goes clockwise on screen.
        let ring1: Vec<(f64, f64)> = n.order[1..7].iter().map(|&i| input[i]).collect();
        let ang = |p: (f64, f64)| (p.0 - 300.0).atan2(-(p.1 - 200.0));
        let a0 = ang(ring1[0]);
        assert!(ring1.iter().all(|&p| ang(p).abs() >= a0.abs() - 1e-9));
        for w in ring1.windows(2) {
            let d = (ang(w[1]) - ang(w[0])).rem_euclid(std::f64::consts::TAU);
            assert!((d - std::f64::consts::TAU / 6.0).abs() < 1e-6, "{d}");
        }
    }

    #[test]
    fn random_dots_are_irregular_and_lattices_refuse_them() {
        let mut s = 99u64;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut pts: Vec<(f64, f64)> = Vec::new();
        while pts.len() < 150 {
            let q = (20.0 + 600.0 * next(), 20.0 + 440.0 * next());
            if pts.iter().all(|p| (p.0 - q.0).hypot(p.1 - q.1) > 25.0) {
                pts.push(q);
            }
        }
        let n = number_markers(&pts, LayoutChoice::Auto).unwrap();
        assert_eq!(n.layout, Layout::Irregular);
        assert_eq!(n.order.len(), 150);
        for w in n.order.windows(2) {
            assert!(pts[w[0]].1 <= pts[w[1]].1);
        }
        for l in [Layout::Grid, Layout::Hex, Layout::DotRings, Layout::Rings] {
            let e = number_markers(&pts, LayoutChoice::Only(l)).unwrap_err();
            assert!(
                matches!(
                    e,
                    LayoutError::DoesNotFit {
                        seen: Layout::Irregular,
                        ..
                    }
                ),
                "{l:?}: {e}"
            );
        }
    }

    #[test]
    fn too_few_points() {
        assert_eq!(
            number_markers(&[(1.0, 1.0)], LayoutChoice::Auto),
            Err(LayoutError::TooFew(1))
        );
        assert_eq!(
            number_markers(&[(1.0, 1.0), (1.0, 1.0)], LayoutChoice::Auto),
            Err(LayoutError::NoSpacing)
        );
    }

    #[test]
    fn nearest_neighbours_match_brute_force() {
        let pts: Vec<(f64, f64)> = (0..200)
            .map(|i| {
                let t = f64::from(i);
                ((t * 37.3) % 301.0, (t * 91.7) % 211.0)
            })
            .collect();
        let fast = k_nearest_all(&pts, 7);
        for (i, f) in fast.iter().enumerate() {
            let mut d: Vec<f64> = (0..pts.len())
                .filter(|&j| j != i)
                .map(|j| (pts[j].0 - pts[i].0).hypot(pts[j].1 - pts[i].1))
                .collect();
            d.sort_by(f64::total_cmp);
            let got: Vec<f64> = f.iter().map(|x| x.1).collect();
            assert_eq!(got, d[..7].to_vec());
        }
    }
}
