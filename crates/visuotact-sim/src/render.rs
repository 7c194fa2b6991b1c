//! Anti-aliased rasterisation of ellipses and annuli into a floating-point canvas.
//!
//! Pixel `(x, y)` covers the square `[x − ½, x + ½] × [y − ½, y + ½]` (centres at integers, as
//! the vision pipeline measures). Pixels well inside or outside a shape get coverage 1 or 0;
//! pixels near its edge are supersampled on a 16 × 16 grid, so coverage is exact to 1/256.

/// An ellipse: centre, semi-axes and rotation of the first semi-axis from the x axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ellipse {
    /// Centre column, pixels.
    pub cx_px: f64,
    /// Centre row, pixels.
    pub cy_px: f64,
    /// First semi-axis, pixels.
    pub a_px: f64,
    /// Second semi-axis, pixels.
    pub b_px: f64,
    /// Rotation of the first semi-axis from +x (towards +y), radians.
    pub angle_rad: f64,
}

impl Ellipse {
    /// A circle.
    pub fn circle(cx_px: f64, cy_px: f64, r_px: f64) -> Self {
        Self {
            cx_px,
            cy_px,
            a_px: r_px,
            b_px: r_px,
            angle_rad: 0.0,
        }
    }

    /// Area `π a b`.
    pub fn area_px(&self) -> f64 {
        std::f64::consts::PI * self.a_px * self.b_px
    }

    /// Eccentricity `sqrt(1 − (minor/major)²)`.
    pub fn eccentricity(&self) -> f64 {
        let (ma, mi) = if self.a_px >= self.b_px {
            (self.a_px, self.b_px)
        } else {
            (self.b_px, self.a_px)
        };
        if ma <= 0.0 {
            0.0
        } else {
            (1.0 - (mi / ma).powi(2)).sqrt()
        }
    }

    /// Implicit value: < 1 inside, > 1 outside.
    fn value(&self, x: f64, y: f64) -> f64 {
        let (s, c) = self.angle_rad.sin_cos();
        let (dx, dy) = (x - self.cx_px, y - self.cy_px);
        let u = (c * dx + s * dy) / self.a_px;
        let v = (-s * dx + c * dy) / self.b_px;
        u * u + v * v
    }

    /// Half-size of the axis-aligned bounding box.
    fn half_extent(&self) -> (f64, f64) {
        let (s, c) = self.angle_rad.sin_cos();
        let hx = ((self.a_px * c).powi(2) + (self.b_px * s).powi(2)).sqrt();
        let hy = ((self.a_px * s).powi(2) + (self.b_px * c).powi(2)).sqrt();
        (hx, hy)
    }
}

/// A float canvas, row-major, one value per pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct Canvas {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Values, row-major.
    pub data: Vec<f32>,
}

const SS: usize = 16;

impl Canvas {
    /// A canvas filled with `v`.
    pub fn filled(width: usize, height: usize, v: f32) -> Self {
        Self {
            width,
            height,
            data: vec![v; width * height],
        }
    }

    /// Coverage of pixel `(x, y)` by the shape `inside(x, y) -> bool`.
    fn coverage(x: usize, y: usize, inside: &impl Fn(f64, f64) -> bool) -> f64 {
        let mut k = 0;
        for j in 0..SS {
            let sy = y as f64 - 0.5 + (j as f64 + 0.5) / SS as f64;
            for i in 0..SS {
                let sx = x as f64 - 0.5 + (i as f64 + 0.5) / SS as f64;
                if inside(sx, sy) {
                    k += 1;
                }
            }
        }
        k as f64 / (SS * SS) as f64
    }

    /// Blends `value` into the canvas where the ellipse `outer` covers and `inner` (if any)
    /// does not: `pixel = pixel · (1 − c) + value · c`.
    pub fn fill(&mut self, outer: &Ellipse, inner: Option<&Ellipse>, value: f32) {
        let (hx, hy) = outer.half_extent();
        let x0 = (outer.cx_px - hx - 1.0).floor().max(0.0) as usize;
        let y0 = (outer.cy_px - hy - 1.0).floor().max(0.0) as usize;
        let x1 = ((outer.cx_px + hx + 2.0).ceil().max(0.0) as usize).min(self.width);
        let y1 = ((outer.cy_px + hy + 2.0).ceil().max(0.0) as usize).min(self.height);
        // A pixel whose centre is this far (in implicit-value terms) from the level set 1 is
        // surely fully inside or outside: the pixel's half-diagonal is 0.71 px and the implicit
        // value changes by at most 2·0.71/min_axis·(1 + 0.71/min_axis) across it.
        let margin = |e: &Ellipse| {
            let m = e.a_px.min(e.b_px).max(1e-6);
            (2.0 * 0.75 / m) * (1.0 + 0.75 / m) * 1.5
        };
        let mo = margin(outer);
        let mi = inner.map_or(0.0, margin);
        let inside =
            |x: f64, y: f64| outer.value(x, y) <= 1.0 && inner.is_none_or(|e| e.value(x, y) > 1.0);
        for y in y0..y1 {
            for x in x0..x1 {
                let vo = outer.value(x as f64, y as f64);
                let edge_o = (vo - 1.0).abs() < mo;
                let vi = inner.map(|e| e.value(x as f64, y as f64));
                let edge_i = vi.is_some_and(|v| (v - 1.0).abs() < mi);
                let c = if edge_o || edge_i {
                    Self::coverage(x, y, &inside)
                } else if vo < 1.0 && vi.is_none_or(|v| v > 1.0) {
                    1.0
                } else {
                    0.0
                };
                if c > 0.0 {
                    let p = &mut self.data[y * self.width + x];
                    *p = (f64::from(*p) * (1.0 - c) + f64::from(value) * c) as f32;
                }
            }
        }
    }
}

/// A convex polygon prepared for coverage tests: unit edge normals pointing inwards.
#[derive(Clone, Debug)]
pub struct ConvexPolygon {
    vertices: Vec<(f64, f64)>,
    edges: Vec<(f64, f64, f64)>,
}

impl ConvexPolygon {
    /// The convex hull of `points` (so a slightly dented outline is drawn, and measured as
    /// truth, as its hull). Returns `None` for fewer than 3 points or a zero-area hull.
    pub fn new(points: Vec<(f64, f64)>) -> Option<Self> {
        let vertices = convex_hull(points);
        if vertices.len() < 3 {
            return None;
        }
        let area = shoelace(&vertices).0;
        if area.abs() < 1e-12 {
            return None;
        }
        let sign = area.signum();
        let n = vertices.len();
        let edges = (0..n)
            .map(|i| {
                let (x0, y0) = vertices[i];
                let (x1, y1) = vertices[(i + 1) % n];
                // Inward normal for counter-clockwise (positive area) order is (−dy, dx).
                let (mut a, mut b) = (-(y1 - y0), x1 - x0);
                let len = a.hypot(b).max(1e-300);
                a *= sign / len;
                b *= sign / len;
                (a, b, -(a * x0 + b * y0))
            })
            .collect();
        Some(Self { vertices, edges })
    }

    /// Area (positive) and centroid `(x, y)`.
    pub fn area_centroid(&self) -> (f64, (f64, f64)) {
        let (a, c) = shoelace(&self.vertices);
        (a.abs(), c)
    }

    /// The x-range where the horizontal line at `y` crosses the polygon.
    fn cross_section(&self, y: f64) -> Option<(f64, f64)> {
        let n = self.vertices.len();
        let mut range: Option<(f64, f64)> = None;
        for i in 0..n {
            let (x0, y0) = self.vertices[i];
            let (x1, y1) = self.vertices[(i + 1) % n];
            if (y0 <= y && y <= y1) || (y1 <= y && y <= y0) {
                let x = if (y1 - y0).abs() < 1e-300 {
                    x0
                } else {
                    x0 + (y - y0) * (x1 - x0) / (y1 - y0)
                };
                range = Some(range.map_or((x, x), |(a, b)| (a.min(x), b.max(x))));
            }
        }
        range
    }

    /// The minor axis of the ellipse with the polygon's second moments, `4·sqrt(λ_min)` (as the
    /// vision pipeline measures blobs): how wide the shape is at its narrowest.
    pub fn minor_axis(&self) -> f64 {
        let v = &self.vertices;
        let n = v.len();
        let (mut a, mut sx, mut sy, mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for i in 0..n {
            let (x0, y0) = v[i];
            let (x1, y1) = v[(i + 1) % n];
            let c = x0 * y1 - x1 * y0;
            a += c;
            sx += (x0 + x1) * c;
            sy += (y0 + y1) * c;
            sxx += (x0 * x0 + x0 * x1 + x1 * x1) * c;
            syy += (y0 * y0 + y0 * y1 + y1 * y1) * c;
            sxy += (x0 * y1 + 2.0 * x0 * y0 + 2.0 * x1 * y1 + x1 * y0) * c;
        }
        a *= 0.5;
        if a.abs() < 1e-300 {
            return 0.0;
        }
        let (cx, cy) = (sx / (6.0 * a), sy / (6.0 * a));
        let mu20 = sxx / (12.0 * a) - cx * cx;
        let mu02 = syy / (12.0 * a) - cy * cy;
        let mu11 = sxy / (24.0 * a) - cx * cy;
        let half = 0.5 * (mu20 + mu02);
        let root = (0.25 * (mu20 - mu02).powi(2) + mu11 * mu11).sqrt();
        4.0 * (half - root).max(0.0).sqrt()
    }

    /// The hull's vertices.
    pub fn vertices(&self) -> &[(f64, f64)] {
        &self.vertices
    }

    /// Whether the point lies inside (or on) the polygon.
    pub fn contains(&self, x: f64, y: f64) -> bool {
        self.edges.iter().all(|&(a, b, c)| a * x + b * y + c >= 0.0)
    }

    /// The smallest distance between this polygon and `other` (0 when they overlap).
    pub fn gap_to(&self, other: &ConvexPolygon) -> f64 {
        let inside = self.vertices.iter().any(|&(x, y)| other.contains(x, y))
            || other.vertices.iter().any(|&(x, y)| self.contains(x, y));
        if inside {
            return 0.0;
        }
        let seg = |p: (f64, f64), a: (f64, f64), b: (f64, f64)| {
            let (dx, dy) = (b.0 - a.0, b.1 - a.1);
            let l2 = dx * dx + dy * dy;
            let t = if l2 > 0.0 {
                (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (p.0 - a.0 - t * dx).hypot(p.1 - a.1 - t * dy)
        };
        let one_way = |from: &ConvexPolygon, to: &ConvexPolygon| {
            let n = to.vertices.len();
            from.vertices
                .iter()
                .flat_map(|&p| (0..n).map(move |i| (p, i)))
                .map(|(p, i)| seg(p, to.vertices[i], to.vertices[(i + 1) % n]))
                .fold(f64::INFINITY, f64::min)
        };
        one_way(self, other).min(one_way(other, self))
    }

    /// Axis-aligned bounds `(x0, y0, x1, y1)`.
    pub fn bounds(&self) -> (f64, f64, f64, f64) {
        self.vertices.iter().fold(
            (
                f64::INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
            ),
            |b, &(x, y)| (b.0.min(x), b.1.min(y), b.2.max(x), b.3.max(y)),
        )
    }
}

/// Which shapes come within `clear` pixels of another: `shapes` are polygons (or `None`, never
/// crowded) with their centroids. Neighbours are found by a sweep along x; exact gaps only for
/// pairs whose bounding circles are that close.
pub fn crowded(shapes: &[(Option<&ConvexPolygon>, (f64, f64))], clear: f64) -> Vec<bool> {
    let reach: Vec<f64> = shapes
        .iter()
        .map(|(p, c)| {
            p.map_or(0.0, |p| {
                p.vertices
                    .iter()
                    .map(|&(x, y)| (x - c.0).hypot(y - c.1))
                    .fold(0.0, f64::max)
            })
        })
        .collect();
    let mut order: Vec<usize> = (0..shapes.len())
        .filter(|&i| shapes[i].0.is_some())
        .collect();
    order.sort_by(|&a, &b| shapes[a].1 .0.total_cmp(&shapes[b].1 .0));
    let max_reach = reach.iter().copied().fold(0.0, f64::max);
    let mut out = vec![false; shapes.len()];
    for (k, &i) in order.iter().enumerate() {
        for &j in &order[k + 1..] {
            let (ci, cj) = (shapes[i].1, shapes[j].1);
            if cj.0 - ci.0 > 2.0 * max_reach + clear {
                break;
            }
            if (ci.0 - cj.0).hypot(ci.1 - cj.1) - reach[i] - reach[j] > clear {
                continue;
            }
            if let (Some(pi), Some(pj)) = (shapes[i].0, shapes[j].0) {
                if pi.gap_to(pj) < clear {
                    out[i] = true;
                    out[j] = true;
                }
            }
        }
    }
    out
}

/// Whether a marker's outline has been squeezed to a sliver by the skin's strain (its minor axis
/// under 35 % of its rest value `rest`, or under 2.5 px — for markers under 4.2 px across at
/// rest, under 60 % of their rest value): no longer a blob of its own.
pub fn squeezed(outline: Option<&ConvexPolygon>, rest: Option<&ConvexPolygon>) -> bool {
    let rest_minor = rest.map_or(0.0, ConvexPolygon::minor_axis);
    let floor = if rest_minor > 0.0 {
        2.5f64.min(0.6 * rest_minor)
    } else {
        2.5
    };
    outline.is_none_or(|p| p.minor_axis() < (0.35 * rest_minor).max(floor))
}

/// Clears the visibility of every marker within `clear` pixels of another (touching markers
/// make one blob): `markers` are outlines with their truth, `centroid` and `visible` reach into
/// the truth.
pub fn clear_crowded<M>(
    markers: &mut [(Option<ConvexPolygon>, M)],
    clear: f64,
    centroid: impl Fn(&M) -> (f64, f64),
    visible: impl Fn(&mut M) -> &mut bool,
) {
    let shapes: Vec<(Option<&ConvexPolygon>, (f64, f64))> = markers
        .iter()
        .map(|(p, m)| (p.as_ref(), centroid(m)))
        .collect();
    let crowded = crowded(&shapes, clear);
    for ((_, m), c) in markers.iter_mut().zip(crowded) {
        *visible(m) &= !c;
    }
}

/// Andrew's monotone chain: hull vertices counter-clockwise (in x-right, y-down pixels,
/// clockwise on screen), collinear points dropped.
fn convex_hull(mut p: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    p.retain(|q| q.0.is_finite() && q.1.is_finite());
    p.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let cross = |o: (f64, f64), a: (f64, f64), b: (f64, f64)| {
        (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0)
    };
    let mut hull: Vec<(f64, f64)> = Vec::with_capacity(2 * p.len());
    // Lower chain, then upper chain; the upper chain never pops into the lower one.
    for &q in &p {
        while hull.len() >= 2 && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0 {
            hull.pop();
        }
        hull.push(q);
    }
    let lower = hull.len() + 1;
    for &q in p.iter().rev().skip(1) {
        while hull.len() >= lower && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0 {
            hull.pop();
        }
        hull.push(q);
    }
    hull.pop();
    hull
}

/// A convex polygon seen by one row of pixel squares `[x ± ½] × [y ± ½]`.
struct Band {
    /// x-extent of the polygon within the band (where squares can meet it).
    meet: Option<(f64, f64)>,
    /// x-range inside the polygon at both band edges (squares within it lie wholly inside:
    /// a convex polygon's cross-sections narrow monotonically towards its top and bottom, so
    /// the band's narrowest cross-section is at one of its edges).
    inside: Option<(f64, f64)>,
}

impl Band {
    fn of(p: &ConvexPolygon, y: f64) -> Self {
        let (top, bottom) = (p.cross_section(y - 0.5), p.cross_section(y + 0.5));
        let mut meet: Option<(f64, f64)> = None;
        let mut widen = |lo: f64, hi: f64| {
            meet = Some(meet.map_or((lo, hi), |(a, b)| (a.min(lo), b.max(hi))));
        };
        for s in [top, bottom].into_iter().flatten() {
            widen(s.0, s.1);
        }
        for &(vx, vy) in &p.vertices {
            if (y - 0.5..=y + 0.5).contains(&vy) {
                widen(vx, vx);
            }
        }
        let inside = top.zip(bottom).map(|(t, b)| (t.0.max(b.0), t.1.min(b.1)));
        Self { meet, inside }
    }

    /// Whether the square at column `x` meets the polygon.
    fn meets(&self, x: f64) -> bool {
        self.meet.is_some_and(|(l, r)| x + 0.5 >= l && x - 0.5 <= r)
    }

    /// Whether the square at column `x` lies wholly inside the polygon.
    fn contains(&self, x: f64) -> bool {
        self.inside.is_some_and(|(l, r)| x - 0.5 > l && x + 0.5 < r)
    }
}

/// Signed area and centroid of a simple polygon.
fn shoelace(v: &[(f64, f64)]) -> (f64, (f64, f64)) {
    let n = v.len();
    let (mut a, mut cx, mut cy) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let (x0, y0) = v[i];
        let (x1, y1) = v[(i + 1) % n];
        let cross = x0 * y1 - x1 * y0;
        a += cross;
        cx += (x0 + x1) * cross;
        cy += (y0 + y1) * cross;
    }
    a *= 0.5;
    if a.abs() < 1e-300 {
        return (0.0, (0.0, 0.0));
    }
    (a, (cx / (6.0 * a), cy / (6.0 * a)))
}

/// Area and centroid of `outer` minus `hole` (a ring), exact for the polygons.
pub fn ring_area_centroid(
    outer: &ConvexPolygon,
    hole: Option<&ConvexPolygon>,
) -> (f64, (f64, f64)) {
    let (ao, co) = outer.area_centroid();
    match hole {
        None => (ao, co),
        Some(h) => {
            let (ah, ch) = h.area_centroid();
            let a = ao - ah;
            (
                a,
                ((ao * co.0 - ah * ch.0) / a, (ao * co.1 - ah * ch.1) / a),
            )
        }
    }
}

/// Supersampling grid per axis for edge pixels of polygons.
const POLY_SS: usize = 8;

impl Canvas {
    /// Blends `value` where `outer` covers and `hole` does not, anti-aliased (edge pixels
    /// supersampled 8 × 8).
    pub fn fill_polygon(
        &mut self,
        outer: &ConvexPolygon,
        hole: Option<&ConvexPolygon>,
        value: f32,
    ) {
        let (bx0, by0, bx1, by1) = outer.bounds();
        let x0 = (bx0 - 1.0).floor().max(0.0) as usize;
        let y0 = (by0 - 1.0).floor().max(0.0) as usize;
        let x1 = ((bx1 + 2.0).ceil().max(0.0) as usize).min(self.width);
        let y1 = ((by1 + 2.0).ceil().max(0.0) as usize).min(self.height);
        // Edges whose line passes within a pixel's half-diagonal of its centre; the others are
        // on the same side for every sample of the pixel, so only these need testing.
        let mut near_out: Vec<(f64, f64, f64)> = Vec::with_capacity(8);
        let mut near_hole: Vec<(f64, f64, f64)> = Vec::with_capacity(8);
        for y in y0..y1 {
            let fy = y as f64;
            // Per row: where the pixel squares of this row meet each polygon, and where they
            // lie wholly inside it (exact for convex polygons; see `Band`).
            let bo = Band::of(outer, fy);
            let bh = hole.map(|h| Band::of(h, fy));
            for x in x0..x1 {
                let fx = x as f64;
                let meets_hole = bh.as_ref().is_some_and(|b| b.meets(fx));
                let c = if !bo.meets(fx) || bh.as_ref().is_some_and(|b| b.contains(fx)) {
                    0.0
                } else if bo.contains(fx) && !meets_hole {
                    1.0
                } else {
                    near_out.clear();
                    near_out.extend(
                        outer
                            .edges
                            .iter()
                            .copied()
                            .filter(|&(a, b, c)| a * fx + b * fy + c < 0.75),
                    );
                    near_hole.clear();
                    if let (true, Some(h)) = (meets_hole, hole) {
                        near_hole.extend(
                            h.edges
                                .iter()
                                .copied()
                                .filter(|&(a, b, c)| a * fx + b * fy + c < 0.75),
                        );
                    }
                    let mut k = 0;
                    for j in 0..POLY_SS {
                        let sy = fy - 0.5 + (j as f64 + 0.5) / POLY_SS as f64;
                        for i in 0..POLY_SS {
                            let sx = fx - 0.5 + (i as f64 + 0.5) / POLY_SS as f64;
                            let in_outer =
                                near_out.iter().all(|&(a, b, c)| a * sx + b * sy + c >= 0.0);
                            let in_hole = meets_hole
                                && near_hole
                                    .iter()
                                    .all(|&(a, b, c)| a * sx + b * sy + c >= 0.0);
                            k += usize::from(in_outer && !in_hole);
                        }
                    }
                    k as f64 / (POLY_SS * POLY_SS) as f64
                };
                if c > 0.0 {
                    let p = &mut self.data[y * self.width + x];
                    *p = (f64::from(*p) * (1.0 - c) + f64::from(value) * c) as f32;
                }
            }
        }
    }

    /// Separable Gaussian blur with standard deviation `sigma_px` (edges clamped).
    pub fn blur(&mut self, sigma_px: f64) {
        if sigma_px <= 0.0 {
            return;
        }
        let (r, k) = gaussian_taps(sigma_px);
        let (w, h) = (self.width, self.height);
        // Each output pixel sums its taps in the same order as a per-pixel loop would (tap 0
        // first); the loops run over whole rows so that the sums vectorise. Edges clamp.
        let mut tmp = vec![0f32; self.data.len()];
        for (row, out) in self.data.chunks_exact(w).zip(tmp.chunks_exact_mut(w)) {
            let at = |x: usize, t: usize| row[(x + t).saturating_sub(r).min(w - 1)];
            let inner = r.min(w)..w.saturating_sub(r).max(r.min(w));
            for x in (0..inner.start).chain(inner.end..w) {
                out[x] = k
                    .iter()
                    .enumerate()
                    .fold(0f32, |acc, (t, kv)| acc + kv * at(x, t));
            }
            if inner.is_empty() {
                continue;
            }
            let out_inner = &mut out[inner.clone()];
            out_inner.fill(0.0);
            for (t, kv) in k.iter().enumerate() {
                let src = &row[inner.start + t - r..inner.end + t - r];
                for (o, &v) in out_inner.iter_mut().zip(src) {
                    *o += kv * v;
                }
            }
        }
        for y in 0..h {
            let out = &mut self.data[y * w..(y + 1) * w];
            out.fill(0.0);
            for (t, kv) in k.iter().enumerate() {
                let yy = (y + t).saturating_sub(r).min(h - 1);
                for (o, &v) in out.iter_mut().zip(&tmp[yy * w..(yy + 1) * w]) {
                    *o += kv * v;
                }
            }
        }
    }
}

/// The radius `r = ⌈3σ⌉` and the `2r + 1` taps of a normalised Gaussian kernel.
fn gaussian_taps(sigma_px: f64) -> (usize, Vec<f32>) {
    let r = (3.0 * sigma_px).ceil() as i64;
    let k: Vec<f64> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma_px * sigma_px)).exp())
        .collect();
    let sum: f64 = k.iter().sum();
    (r as usize, k.iter().map(|v| (v / sum) as f32).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polygon_coverage_matches_its_area_and_centroid() {
        // A regular 64-gon of radius 10 at a sub-pixel position.
        let verts: Vec<(f64, f64)> = (0..64)
            .map(|i| {
                let t = i as f64 / 64.0 * std::f64::consts::TAU;
                (30.3 + 10.0 * t.cos(), 20.7 + 7.0 * t.sin())
            })
            .collect();
        let poly = ConvexPolygon::new(verts).unwrap();
        let mut c = Canvas::filled(64, 48, 0.0);
        c.fill_polygon(&poly, None, 1.0);
        let (mut s, mut sx, mut sy) = (0.0, 0.0, 0.0);
        for y in 0..48 {
            for x in 0..64 {
                let v = f64::from(c.data[y * 64 + x]);
                s += v;
                sx += v * x as f64;
                sy += v * y as f64;
            }
        }
        let (a, (cx, cy)) = poly.area_centroid();
        assert!((s - a).abs() < 0.01 * a, "coverage {s} vs area {a}");
        assert!((sx / s - cx).abs() < 0.01 && (sy / s - cy).abs() < 0.01);
    }

    #[test]
    fn minor_axis_of_an_ellipse_and_a_rectangle() {
        // An ellipse with semi-axes 6 and 2, rotated 30°: minor axis 4 (as 4·sqrt(b²/4)).
        let (s, c) = 30f64.to_radians().sin_cos();
        let e = ConvexPolygon::new(
            (0..720)
                .map(|i| {
                    let t = i as f64 / 720.0 * std::f64::consts::TAU;
                    let (x, y) = (6.0 * t.cos(), 2.0 * t.sin());
                    (10.0 + c * x - s * y, 20.0 + s * x + c * y)
                })
                .collect(),
        )
        .unwrap();
        assert!((e.minor_axis() - 4.0).abs() < 1e-3, "{}", e.minor_axis());
        // A 10 × 3 rectangle: variance 3²/12 across, minor axis 4·sqrt(0.75).
        let r = ConvexPolygon::new(vec![(0.0, 0.0), (10.0, 0.0), (10.0, 3.0), (0.0, 3.0)]).unwrap();
        assert!((r.minor_axis() - 4.0 * 0.75f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn dented_outlines_become_their_hull() {
        let square_with_dent = vec![(0.0, 0.0), (2.0, 1.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0)];
        let p = ConvexPolygon::new(square_with_dent).unwrap();
        let (a, (x, y)) = p.area_centroid();
        assert!((a - 16.0).abs() < 1e-12 && (x - 2.0).abs() < 1e-12 && (y - 2.0).abs() < 1e-12);
    }

    #[test]
    fn ring_centroid_of_concentric_polygons_is_the_centre() {
        let circle = |r: f64| {
            ConvexPolygon::new(
                (0..32)
                    .map(|i| {
                        let t = i as f64 / 32.0 * std::f64::consts::TAU;
                        (5.0 + r * t.cos(), 7.0 + r * t.sin())
                    })
                    .collect(),
            )
            .unwrap()
        };
        let (a, (x, y)) = ring_area_centroid(&circle(4.0), Some(&circle(2.0)));
        assert!(a > 0.0 && (x - 5.0).abs() < 1e-12 && (y - 7.0).abs() < 1e-12);
    }

    #[test]
    fn blur_equals_the_per_pixel_sums_bit_for_bit() {
        // The taps summed per pixel in order, edges clamped: the definition the row loops
        // must reproduce exactly (frames are seeded and compared across versions).
        for (w, h, sigma) in [(37, 23, 1.3f64), (5, 4, 2.0), (64, 3, 0.7), (1, 9, 1.0)] {
            let mut canvas = Canvas::filled(w, h, 0.0);
            for (i, v) in canvas.data.iter_mut().enumerate() {
                *v = ((i * 7919) % 256) as f32 / 255.0;
            }
            let src = canvas.data.clone();
            canvas.blur(sigma);
            let (r, k) = gaussian_taps(sigma);
            let r = r as i64;
            let (wi, hi) = (w as i64, h as i64);
            // Σ_t k[t] · line(clamp(at + t − r)) over a line of n pixels, tap 0 first.
            let taps = |line: &dyn Fn(i64) -> f32, at: i64, n: i64| {
                k.iter().enumerate().fold(0f32, |acc, (t, kv)| {
                    acc + kv * line((at + t as i64 - r).clamp(0, n - 1))
                })
            };
            let mut tmp = vec![0f32; src.len()];
            for y in 0..hi {
                for x in 0..wi {
                    tmp[(y * wi + x) as usize] = taps(&|xx| src[(y * wi + xx) as usize], x, wi);
                }
            }
            for y in 0..hi {
                for x in 0..wi {
                    let acc = taps(&|yy| tmp[(yy * wi + x) as usize], y, hi);
                    let got = canvas.data[(y * wi + x) as usize];
                    assert_eq!(got.to_bits(), acc.to_bits(), "{w}×{h} at ({x}, {y})");
                }
            }
        }
    }
}
