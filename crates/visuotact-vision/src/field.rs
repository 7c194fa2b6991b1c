//! The displacement field's dynamics, frame by frame: how the tracked markers move as a whole
//! and how far that motion is from a rigid one — the signals a slip detector reads.
//!
//! Contract: [`FieldTracker::update_into`] takes each marker's displacement from the reference
//! (pixels, `None` where it was not tracked) and writes one [`FieldDynamics`]: the field's mean
//! shift and its spread about it, the curl and divergence of the field's best affine fit
//! (least squares over the markers' reference positions) and the residual from it, the
//! entropy of the displacement magnitudes, and — over the last `lag_frames` frames — the rigid
//! motion of the increments (translation and spin, least squares) and the residual from it.
//! Lengths are in marker pitches, so one detector reads sensors of any size; a rigid
//! translation has zero residuals, a rotation by ω has curl 2ω, a uniform stretch by s has
//! divergence 2s (tests below). Stick moves the markers under an object together with it
//! (small increment residual); slip leaves some behind (a partial-slip annulus) or lets the
//! object go (the shear relaxes): the residual grows against the motion.
//!
//! Needs at least [`MIN_MARKERS`] markers in a frame (and in both frames of an increment);
//! with fewer, the signals it cannot compute are zero.

/// The fewest markers a fit is made from.
pub const MIN_MARKERS: usize = 6;

/// Bins of the displacement-magnitude histogram whose entropy [`FieldDynamics::entropy_nats`]
/// is.
const ENTROPY_BINS: usize = 10;

/// One frame's displacement-field signals (lengths in marker pitches).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct FieldDynamics {
    /// Markers with a displacement this frame.
    pub markers: usize,
    /// Length of the mean displacement.
    pub shift_pitches: f64,
    /// RMS of the displacements about their mean.
    pub spread_pitches: f64,
    /// Curl of the best affine fit (∂dy/∂x − ∂dx/∂y; twice the rotation).
    pub curl: f64,
    /// Divergence of the best affine fit (∂dx/∂x + ∂dy/∂y; the area change).
    pub divergence: f64,
    /// RMS residual of the displacements from their best affine fit.
    pub affine_residual_pitches: f64,
    /// Entropy of the displacement magnitudes over 10 bins from 0 to the largest, nats.
    pub entropy_nats: f64,
    /// Length of the increments' rigid translation over the lag.
    pub speed_pitches: f64,
    /// RMS residual of the increments from their best rigid motion.
    pub slide_pitches: f64,
    /// The increments' rigid rotation over the lag, radians (absolute).
    pub spin_rad: f64,
    /// How far the increments are from rigid: the slide over the whole motion plus 0.02
    /// pitches (0 for a rigid motion, towards 1 when markers move apart).
    pub nonrigid: f64,
}

impl FieldDynamics {
    /// Names of [`FieldDynamics::signals`], in order (also the column names).
    pub const NAMES: [&'static str; 10] = [
        "shift_pitches",
        "spread_pitches",
        "curl",
        "divergence",
        "affine_residual_pitches",
        "entropy_nats",
        "speed_pitches",
        "slide_pitches",
        "spin_rad",
        "nonrigid",
    ];

    /// The signals in [`FieldDynamics::NAMES`] order.
    pub fn signals(&self) -> [f64; 10] {
        [
            self.shift_pitches,
            self.spread_pitches,
            self.curl,
            self.divergence,
            self.affine_residual_pitches,
            self.entropy_nats,
            self.speed_pitches,
            self.slide_pitches,
            self.spin_rad,
            self.nonrigid,
        ]
    }
}

/// Follows a sensor's displacement field frame to frame ([`FieldTracker::update_into`]).
#[derive(Clone, Debug)]
pub struct FieldTracker {
    /// Reference positions, pitches.
    reference: Vec<[f64; 2]>,
    pitch_px: f64,
    lag: usize,
    /// The last `lag` frames' displacements (pitches), oldest first.
    history: std::collections::VecDeque<Vec<Option<[f64; 2]>>>,
    /// The buffer of the frame that left the history, reused for the next one.
    spare: Option<Vec<Option<[f64; 2]>>>,
    /// Scratch: this frame's positions and values.
    points: Vec<[f64; 2]>,
    values: Vec<[f64; 2]>,
}

impl FieldTracker {
    /// A tracker of markers at `reference_px` (pixels) `pitch_px` apart, taking increments over
    /// `lag_frames` frames (at least 1).
    pub fn new(reference_px: &[(f64, f64)], pitch_px: f64, lag_frames: usize) -> Self {
        let pitch_px = if pitch_px > 0.0 { pitch_px } else { 1.0 };
        Self {
            reference: reference_px
                .iter()
                .map(|&(x, y)| [x / pitch_px, y / pitch_px])
                .collect(),
            pitch_px,
            lag: lag_frames.max(1),
            history: std::collections::VecDeque::new(),
            spare: None,
            points: Vec::new(),
            values: Vec::new(),
        }
    }

    /// Markers followed.
    pub fn markers(&self) -> usize {
        self.reference.len()
    }

    /// Forgets the frames seen (a new sequence starts).
    pub fn reset(&mut self) {
        self.history.clear();
    }

    /// The signals of this frame's displacements `displacement_px` (one per reference marker,
    /// pixels; `None`: not tracked).
    pub fn update(&mut self, displacement_px: &[Option<(f64, f64)>]) -> FieldDynamics {
        let mut out = FieldDynamics::default();
        self.update_into(displacement_px, &mut out);
        out
    }

    /// [`FieldTracker::update`] into `out`, allocating nothing once the history is full.
    pub fn update_into(&mut self, displacement_px: &[Option<(f64, f64)>], out: &mut FieldDynamics) {
        // The frame `lag` frames ago is the history's oldest; its buffer is reused for this one.
        let then = if self.history.len() >= self.lag {
            self.history.pop_front().unwrap_or_default()
        } else {
            Vec::new()
        };
        let mut now = self.spare.take().unwrap_or_default();
        now.clear();
        now.extend((0..self.reference.len()).map(|i| {
            displacement_px
                .get(i)
                .copied()
                .flatten()
                .and_then(|(x, y)| {
                    (x.is_finite() && y.is_finite()).then(|| [x / self.pitch_px, y / self.pitch_px])
                })
        }));
        *out = FieldDynamics::default();
        self.fill_values(&now, None);
        out.markers = self.points.len();
        if self.points.len() >= MIN_MARKERS {
            field_of(&self.points, &self.values, out);
        }
        if !then.is_empty() {
            self.fill_values(&now, Some(&then));
            if self.points.len() >= MIN_MARKERS {
                increments_of(&self.points, &self.values, out);
            }
        }
        self.spare = Some(then);
        self.history.push_back(now);
    }

    /// The points and values of the markers present in `now` (and in `then`: their increment).
    fn fill_values(&mut self, now: &[Option<[f64; 2]>], then: Option<&[Option<[f64; 2]>]>) {
        self.points.clear();
        self.values.clear();
        for (i, d) in now.iter().enumerate() {
            let Some(d) = d else { continue };
            let v = match then {
                None => *d,
                Some(t) => match t.get(i).copied().flatten() {
                    Some(p) => [d[0] - p[0], d[1] - p[1]],
                    None => continue,
                },
            };
            self.points.push(self.reference[i]);
            self.values.push(v);
        }
    }
}

fn mean_of(v: &[[f64; 2]]) -> [f64; 2] {
    let n = v.len().max(1) as f64;
    let s = v.iter().fold([0.0, 0.0], |a, p| [a[0] + p[0], a[1] + p[1]]);
    [s[0] / n, s[1] / n]
}

fn rms(v: impl Iterator<Item = [f64; 2]>) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for p in v {
        s += p[0] * p[0] + p[1] * p[1];
        n += 1;
    }
    if n == 0 {
        0.0
    } else {
        (s / n as f64).sqrt()
    }
}

/// Shift, spread, affine fit and entropy of the displacements `d` at `p`.
fn field_of(p: &[[f64; 2]], d: &[[f64; 2]], out: &mut FieldDynamics) {
    let (pc, dc) = (mean_of(p), mean_of(d));
    out.shift_pitches = dc[0].hypot(dc[1]);
    out.spread_pitches = rms(d.iter().map(|v| [v[0] - dc[0], v[1] - dc[1]]));
    // Gradient G of d − dc ≈ G (p − pc): normal equations with the 2×2 scatter of p.
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    let (mut bx, mut by) = ([0.0; 2], [0.0; 2]);
    for (q, v) in p.iter().zip(d) {
        let (x, y) = (q[0] - pc[0], q[1] - pc[1]);
        let (u, w) = (v[0] - dc[0], v[1] - dc[1]);
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
        bx = [bx[0] + x * u, bx[1] + y * u];
        by = [by[0] + x * w, by[1] + y * w];
    }
    let det = sxx * syy - sxy * sxy;
    if det.abs() > 1e-12 * (sxx * syy).max(1e-300) {
        let solve = |b: [f64; 2]| {
            [
                (syy * b[0] - sxy * b[1]) / det,
                (sxx * b[1] - sxy * b[0]) / det,
            ]
        };
        let (gx, gy) = (solve(bx), solve(by)); // rows: ∂dx/∂(x, y), ∂dy/∂(x, y)
        out.curl = gy[0] - gx[1];
        out.divergence = gx[0] + gy[1];
        out.affine_residual_pitches = rms(p.iter().zip(d).map(|(q, v)| {
            let (x, y) = (q[0] - pc[0], q[1] - pc[1]);
            [
                v[0] - dc[0] - gx[0] * x - gx[1] * y,
                v[1] - dc[1] - gy[0] * x - gy[1] * y,
            ]
        }));
    }
    let largest = d.iter().map(|v| v[0].hypot(v[1])).fold(0.0, f64::max);
    if largest > 0.0 {
        let mut bins = [0usize; ENTROPY_BINS];
        for v in d {
            let k = (v[0].hypot(v[1]) / largest * ENTROPY_BINS as f64) as usize;
            bins[k.min(ENTROPY_BINS - 1)] += 1;
        }
        let n = d.len() as f64;
        out.entropy_nats = bins
            .iter()
            .filter(|&&c| c > 0)
            .map(|&c| {
                let q = c as f64 / n;
                -q * q.ln()
            })
            .sum();
    }
}

/// The increments `v` at `p`: their rigid motion (translation, spin) and the residual from it.
fn increments_of(p: &[[f64; 2]], v: &[[f64; 2]], out: &mut FieldDynamics) {
    let (pc, t) = (mean_of(p), mean_of(v));
    let (mut num, mut den) = (0.0, 0.0);
    for (q, w) in p.iter().zip(v) {
        let (x, y) = (q[0] - pc[0], q[1] - pc[1]);
        num += x * (w[1] - t[1]) - y * (w[0] - t[0]);
        den += x * x + y * y;
    }
    let omega = if den > 0.0 { num / den } else { 0.0 };
    out.speed_pitches = t[0].hypot(t[1]);
    out.spin_rad = omega.abs();
    out.slide_pitches = rms(p.iter().zip(v).map(|(q, w)| {
        let (x, y) = (q[0] - pc[0], q[1] - pc[1]);
        [w[0] - t[0] + omega * y, w[1] - t[1] - omega * x]
    }));
    let whole = rms(v.iter().copied());
    out.nonrigid = out.slide_pitches / (out.speed_pitches + whole + 0.02);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 7 × 9 grid 10 px apart, as the GelSight Mini's dots.
    fn grid() -> Vec<(f64, f64)> {
        (0..7)
            .flat_map(|r| (0..9).map(move |c| (20.0 + 10.0 * c as f64, 15.0 + 10.0 * r as f64)))
            .collect()
    }

    fn field(f: impl Fn(f64, f64) -> (f64, f64)) -> Vec<Option<(f64, f64)>> {
        grid().iter().map(|&(x, y)| Some(f(x, y))).collect()
    }

    #[test]
    fn a_translation_is_a_shift_with_no_residual() {
        let mut t = FieldTracker::new(&grid(), 10.0, 1);
        let a = t.update(&field(|_, _| (0.0, 0.0)));
        assert_eq!(a.markers, 63);
        assert_eq!(a.speed_pitches, 0.0, "no increment on the first frame");
        let b = t.update(&field(|_, _| (3.0, -4.0)));
        assert!((b.shift_pitches - 0.5).abs() < 1e-12);
        assert!(b.spread_pitches < 1e-12 && b.affine_residual_pitches < 1e-12);
        assert!(b.curl.abs() < 1e-12 && b.divergence.abs() < 1e-12);
        assert!((b.speed_pitches - 0.5).abs() < 1e-12);
        assert!(b.slide_pitches < 1e-12 && b.nonrigid < 1e-12 && b.spin_rad < 1e-12);
        assert_eq!(b.entropy_nats, 0.0, "every magnitude in one bin");
    }

    #[test]
    fn a_small_rotation_has_curl_twice_its_angle_and_a_stretch_divergence_twice_its_strain() {
        let (cx, cy, w) = (60.0, 45.0, 0.01);
        let mut t = FieldTracker::new(&grid(), 10.0, 1);
        t.update(&field(|_, _| (0.0, 0.0)));
        let r = t.update(&field(|x, y| (-w * (y - cy), w * (x - cx))));
        assert!((r.curl - 2.0 * w).abs() < 1e-12, "{}", r.curl);
        assert!(r.divergence.abs() < 1e-12);
        assert!((r.spin_rad - w).abs() < 1e-12, "{}", r.spin_rad);
        assert!(r.slide_pitches < 1e-12, "a rotation is rigid");
        let s = 0.02;
        let mut t = FieldTracker::new(&grid(), 10.0, 1);
        t.update(&field(|_, _| (0.0, 0.0)));
        let e = t.update(&field(|x, y| (s * (x - cx), s * (y - cy))));
        assert!((e.divergence - 2.0 * s).abs() < 1e-12 && e.curl.abs() < 1e-12);
        assert!(e.affine_residual_pitches < 1e-12);
        assert!(e.slide_pitches > 0.0, "a stretch is not rigid");
    }

    #[test]
    fn a_sticking_centre_and_a_sliding_rim_leave_a_residual_against_the_motion() {
        // The centre moves with the object, the rim lags by half: the increment is not rigid.
        let (cx, cy) = (60.0, 45.0);
        let mut t = FieldTracker::new(&grid(), 10.0, 2);
        for k in 0..4 {
            let step = k as f64;
            t.update(&field(|x, y| {
                let rim = ((x - cx).hypot(y - cy) > 20.0) as u8 as f64;
                (step * (1.0 - 0.5 * rim), 0.0)
            }));
        }
        let d = t.update(&field(|x, y| {
            let rim = ((x - cx).hypot(y - cy) > 20.0) as u8 as f64;
            (4.0 * (1.0 - 0.5 * rim), 0.0)
        }));
        assert!(d.slide_pitches > 0.04 && d.nonrigid > 0.1, "{d:?}");
        assert!(d.entropy_nats > 0.5, "two magnitudes: {}", d.entropy_nats);
    }

    #[test]
    fn too_few_markers_give_zero_signals_and_missing_ones_are_left_out() {
        let mut t = FieldTracker::new(&grid(), 10.0, 1);
        let mut few = vec![None; 63];
        for d in few.iter_mut().take(5) {
            *d = Some((1.0, 1.0));
        }
        let f = t.update(&few);
        assert_eq!((f.markers, f.shift_pitches), (5, 0.0));
        let mut most = field(|_, _| (2.0, 0.0));
        most[3] = None;
        most[4] = Some((f64::NAN, 0.0));
        let g = t.update(&most);
        assert_eq!(g.markers, 61);
        assert!((g.shift_pitches - 0.2).abs() < 1e-12);
    }
}
