//! The object's imprint sliding against the markers, frame by frame: a slip signal read from
//! the image itself rather than from the tracked markers.
//!
//! On a sensor whose markers are printed on the skin and whose image shows the object's imprint
//! (a GelSight-type sensor: shading), an object that sticks carries skin, markers and imprint
//! together, while one that slips moves its imprint over the markers. Contract:
//! [`ImprintFollower::update`] takes the frames of one sequence in order and returns, for each,
//! the imprint's motion against the markers since `lag_frames` frames before (`(dx, dy)`,
//! pixels of the full image; zero until `lag_frames` frames have been seen, and where there is
//! no imprint).
//!
//! How, per frame, on the gray frame halved: the markers are the pixels darker than their
//! surroundings (a Gaussian of 4 px) by [`ImprintParams::dot_contrast`]; the shading is the
//! frame with them filled in from around them (normalised convolution, 2 px), minus the
//! sequence's first frame's shading; the contact is where the shading changed most (its top
//! [`ImprintParams::contact_fraction`], at least [`ImprintParams::min_change`]). The imprint's
//! shift is the one (within [`ImprintParams::reach_px`], refined by a parabola) that best aligns
//! the shading change of the earlier frame with this one's over the contact, the markers' shift
//! the same alignment of the marker images around the contact; the slide is their difference.
//! A sticking contact gives 0; tests below move a synthetic imprint and lattice of dots by
//! known amounts. The study behind it: `research/gelsight_slip_imprint.py`.

use std::collections::VecDeque;

use visuotact_image::RgbImage;

/// The imprint follower's settings; every length is in pixels of the halved image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImprintParams {
    /// How much darker than its surroundings a pixel is to be a marker's, grey levels (12: a
    /// GelSight Mini's dots are 60–100 levels darker, its shading varies by a few).
    pub dot_contrast: f32,
    /// The share of the image the contact is taken to cover at most (0.1).
    pub contact_fraction: f64,
    /// The least change of shading that is contact, grey levels (4: above a camera's noise).
    pub min_change: f32,
    /// The largest shift searched between the two frames (3 px: 6 px of the full image over
    /// the lag, faster than any grasp in the GelSight set moves).
    pub reach_px: usize,
}

impl ImprintParams {
    /// The settings the study measured (module docs).
    pub const DEFAULT: Self = Self {
        dot_contrast: 12.0,
        contact_fraction: 0.1,
        min_change: 4.0,
        reach_px: 3,
    };
}

impl Default for ImprintParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// The fewest contact pixels (halved image) a slide is measured over.
const MIN_CONTACT_PX: f32 = 50.0;

/// A Gaussian of `sigma` pixels cut at 3σ, its weights summing to 1.
#[derive(Clone, Debug)]
struct Kernel {
    radius: usize,
    weights: Vec<f32>,
}

impl Kernel {
    fn gaussian(sigma: f32) -> Self {
        let r = (3.0 * sigma) as isize;
        let mut weights: Vec<f32> = (-r..=r)
            .map(|i| (-((i * i) as f32) / (2.0 * sigma * sigma)).exp())
            .collect();
        let total: f32 = weights.iter().sum();
        for k in &mut weights {
            *k /= total;
        }
        Self {
            radius: r as usize,
            weights,
        }
    }
}

/// The blurs of the measurement (module docs): the background (4 px), the markers' mask
/// widened (1 px), the normalised convolution (2 px) and the contact widened (3 px).
#[derive(Clone, Debug)]
struct Blurs {
    background: Kernel,
    mask: Kernel,
    fill: Kernel,
    contact: Kernel,
    /// Scratch: a row with its edges repeated, and the rows blurred.
    padded: Vec<f32>,
    rows: Vec<f32>,
}

/// One frame's planes, halved: the shading change since the first frame, where no marker is
/// (1) and the marker image (how much darker than around).
#[derive(Clone, Debug, Default)]
struct Planes {
    change: Vec<f32>,
    keep: Vec<f32>,
    dots: Vec<f32>,
}

/// Follows one sequence's imprint against its markers ([module docs](self)).
#[derive(Clone, Debug)]
pub struct ImprintFollower {
    params: ImprintParams,
    lag: usize,
    size: (usize, usize),
    reference: Vec<f32>,
    history: VecDeque<Planes>,
    spare: Option<Planes>,
    gray: Vec<f32>,
    a: Vec<f32>,
    b: Vec<f32>,
    tmp: Vec<f32>,
    weight: Vec<f32>,
    blurs: Blurs,
    /// Scratch: the weighted pixels [`shift_between`] compares.
    pixels: Vec<(usize, f32)>,
}

impl ImprintFollower {
    /// A follower comparing each frame with the one `lag_frames` before (at least 1).
    pub fn new(params: ImprintParams, lag_frames: usize) -> Self {
        Self {
            params,
            lag: lag_frames.max(1),
            size: (0, 0),
            reference: Vec::new(),
            history: VecDeque::new(),
            spare: None,
            gray: Vec::new(),
            a: Vec::new(),
            b: Vec::new(),
            tmp: Vec::new(),
            weight: Vec::new(),
            blurs: Blurs {
                background: Kernel::gaussian(4.0),
                mask: Kernel::gaussian(1.0),
                fill: Kernel::gaussian(2.0),
                contact: Kernel::gaussian(3.0),
                padded: Vec::new(),
                rows: Vec::new(),
            },
            pixels: Vec::new(),
        }
    }

    /// Starts a new sequence: the next frame is its first.
    pub fn reset(&mut self) {
        self.reference.clear();
        while let Some(p) = self.history.pop_front() {
            self.spare = Some(p);
        }
    }

    /// The imprint's motion against the markers since `lag_frames` frames before, `(dx, dy)`
    /// pixels of the full image. A frame of another size than the sequence's starts a new
    /// sequence.
    pub fn update(&mut self, img: &RgbImage) -> (f64, f64) {
        let (w, h) = (img.width() / 2, img.height() / 2);
        if (w, h) != self.size {
            self.size = (w, h);
            self.reset();
        }
        if w <= 2 * self.params.reach_px + 2 || h <= 2 * self.params.reach_px + 2 {
            return (0.0, 0.0);
        }
        let mut planes = self.spare.take().unwrap_or_default();
        self.planes_into(img, &mut planes);
        self.history.push_back(planes);
        if self.history.len() <= self.lag {
            return (0.0, 0.0);
        }
        let slide = self.slide_px();
        self.spare = self.history.pop_front();
        slide
    }

    /// The frame's planes into `out`; the first frame of a sequence becomes its reference.
    fn planes_into(&mut self, img: &RgbImage, out: &mut Planes) {
        let (w, h) = self.size;
        let p = &self.params;
        let bl = &mut self.blurs;
        halved_gray_into(img, &mut self.gray);
        // The background (a) and the markers: darker than it by the contrast.
        blurred_into(
            &self.gray,
            (w, h),
            &bl.background,
            &mut bl.padded,
            &mut bl.rows,
            &mut self.a,
        );
        out.dots.clear();
        out.dots
            .extend(self.a.iter().zip(&self.gray).map(|(bg, g)| bg - g));
        self.b.clear();
        self.b.extend(
            out.dots
                .iter()
                .map(|&d| if d > p.dot_contrast { 1.0 } else { 0.0 }),
        );
        blurred_into(
            &self.b,
            (w, h),
            &bl.mask,
            &mut bl.padded,
            &mut bl.rows,
            &mut out.keep,
        );
        for k in &mut out.keep {
            *k = 1.0 - (4.0 * *k).clamp(0.0, 1.0);
        }
        // The shading: the frame filled in where the markers are.
        self.b.clear();
        self.b
            .extend(self.gray.iter().zip(&out.keep).map(|(g, k)| g * k));
        blurred_into(
            &self.b,
            (w, h),
            &bl.fill,
            &mut bl.padded,
            &mut bl.rows,
            &mut self.a,
        );
        blurred_into(
            &out.keep,
            (w, h),
            &bl.fill,
            &mut bl.padded,
            &mut bl.rows,
            &mut self.b,
        );
        out.change.clear();
        out.change
            .extend(self.a.iter().zip(&self.b).map(|(s, k)| s / (k + 1e-3)));
        if self.reference.is_empty() {
            self.reference.extend_from_slice(&out.change);
        }
        for (c, r) in out.change.iter_mut().zip(&self.reference) {
            *c -= r;
        }
    }

    /// The slide between the oldest and the newest frame held.
    fn slide_px(&mut self) -> (f64, f64) {
        let (w, h) = self.size;
        let p = self.params;
        let (old, new) = (&self.history[0], &self.history[self.history.len() - 1]);
        self.tmp.clear();
        self.tmp.extend(new.change.iter().map(|c| c.abs()));
        let k = ((1.0 - p.contact_fraction) * (self.tmp.len() - 1) as f64).round() as usize;
        let (_, q, _) = self.tmp.select_nth_unstable_by(k, f32::total_cmp);
        let threshold = q.max(p.min_change);
        self.weight.clear();
        self.weight.extend(
            new.change
                .iter()
                .zip(new.keep.iter().zip(&old.keep))
                .map(|(c, (k1, k0))| if c.abs() >= threshold { k1 * k0 } else { 0.0 }),
        );
        if self.weight.iter().sum::<f32>() < MIN_CONTACT_PX {
            return (0.0, 0.0);
        }
        let px = &mut self.pixels;
        let imprint = shift_between(
            &new.change,
            &old.change,
            &self.weight,
            (w, h),
            p.reach_px,
            px,
        );
        let bl = &mut self.blurs;
        blurred_into(
            &self.weight,
            (w, h),
            &bl.contact,
            &mut bl.padded,
            &mut bl.rows,
            &mut self.a,
        );
        for a in &mut self.a {
            *a = (3.0 * *a).clamp(0.0, 1.0);
        }
        let markers = shift_between(&new.dots, &old.dots, &self.a, (w, h), p.reach_px, px);
        (2.0 * (imprint.0 - markers.0), 2.0 * (imprint.1 - markers.1))
    }
}

/// The gray (BT.601 luma) of `img` halved (each pixel the mean of a 2 × 2 block), into `out`.
fn halved_gray_into(img: &RgbImage, out: &mut Vec<f32>) {
    let (w, h) = (img.width() / 2, img.height() / 2);
    let src = img.as_slice();
    let stride = 3 * img.width();
    let luma = |i: usize| {
        0.299 * f32::from(src[i]) + 0.587 * f32::from(src[i + 1]) + 0.114 * f32::from(src[i + 2])
    };
    out.clear();
    for y in 0..h {
        for x in 0..w {
            let i = 2 * y * stride + 6 * x;
            out.push(0.25 * (luma(i) + luma(i + 3) + luma(i + stride) + luma(i + stride + 3)));
        }
    }
}

/// `src` (`size` = (w, h)) blurred by `kernel` (edges repeated), into `dst`; `padded` and
/// `rows` are scratch.
fn blurred_into(
    src: &[f32],
    size: (usize, usize),
    kernel: &Kernel,
    padded: &mut Vec<f32>,
    rows: &mut Vec<f32>,
    dst: &mut Vec<f32>,
) {
    let (w, h) = size;
    let r = kernel.radius as isize;
    let clamp = |v: isize, n: usize| v.clamp(0, n as isize - 1) as usize;
    rows.clear();
    for y in 0..h {
        let row = &src[y * w..(y + 1) * w];
        padded.clear();
        padded.extend((-r..w as isize + r).map(|x| row[clamp(x, w)]));
        rows.extend(padded.windows(kernel.weights.len()).map(|win| {
            kernel
                .weights
                .iter()
                .zip(win)
                .map(|(k, v)| k * v)
                .sum::<f32>()
        }));
    }
    dst.clear();
    dst.resize(w * h, 0.0);
    for (k, d) in kernel.weights.iter().zip(-r..=r) {
        for y in 0..h {
            let from = &rows[clamp(y as isize + d, h) * w..][..w];
            for (o, v) in dst[y * w..(y + 1) * w].iter_mut().zip(from) {
                *o += k * v;
            }
        }
    }
}

/// The shift `(dx, dy)` within `reach` that minimises the `weight`-weighted mean squared
/// difference between `a(p)` and `b(p − shift)` (`size` = (w, h)), refined by a parabola
/// through the best shift's neighbours along each axis; `pixels` is scratch.
fn shift_between(
    a: &[f32],
    b: &[f32],
    weight: &[f32],
    size: (usize, usize),
    reach: usize,
    pixels: &mut Vec<(usize, f32)>,
) -> (f64, f64) {
    let (w, h) = size;
    let n = 2 * reach + 1;
    // The weighted pixels, at least `reach` from every edge: only they are compared.
    pixels.clear();
    pixels.extend(
        (reach..h - reach)
            .flat_map(|y| (reach..w - reach).map(move |x| y * w + x))
            .filter_map(|i| (weight[i] > 0.0).then_some((i, weight[i]))),
    );
    let total: f64 = pixels.iter().map(|&(_, v)| f64::from(v)).sum();
    if total <= 0.0 {
        return (0.0, 0.0);
    }
    let mut cost = vec![f64::INFINITY; n * n];
    for (k, c) in cost.iter_mut().enumerate() {
        // b is read `shift` back: index i − (dy · w + dx), never below 0 or past the end.
        let back = (k / n) * w + k % n;
        let s: f64 = pixels
            .iter()
            .map(|&(i, wt)| {
                let d = a[i] - b[i + reach * w + reach - back];
                f64::from(wt * d * d)
            })
            .sum();
        *c = s / total;
    }
    let best = (0..n * n)
        .min_by(|&i, &j| cost[i].total_cmp(&cost[j]))
        .unwrap_or(n * n / 2);
    let (iy, ix) = (best / n, best % n);
    let vertex = |c0: f64, cm: f64, cp: f64| {
        let d = cm - 2.0 * c0 + cp;
        if d > 0.0 {
            0.5 * (cm - cp) / d
        } else {
            0.0
        }
    };
    let c = |y: usize, x: usize| cost[y * n + x];
    let sx = if ix > 0 && ix + 1 < n {
        vertex(c(iy, ix), c(iy, ix - 1), c(iy, ix + 1))
    } else {
        0.0
    };
    let sy = if iy > 0 && iy + 1 < n {
        vertex(c(iy, ix), c(iy - 1, ix), c(iy + 1, ix))
    } else {
        0.0
    };
    (ix as f64 - reach as f64 + sx, iy as f64 - reach as f64 + sy)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 160 × 120 frame: a lattice of dark dots (pitch 24 px) shifted by `dots_px`, on a
    /// background with a bright round imprint (radius 24 px) centred at `imprint_px`.
    fn frame(dots_px: (f64, f64), imprint_px: (f64, f64)) -> RgbImage {
        RgbImage::from_fn(160, 120, |x, y| {
            let (x, y) = (x as f64, y as f64);
            let (ix, iy) = ((x - imprint_px.0) / 24.0, (y - imprint_px.1) / 24.0);
            let mut v = 100.0 + 60.0 * (-(ix * ix + iy * iy) * 2.0).exp();
            let (u, w) = (x - dots_px.0, y - dots_px.1);
            let (du, dw) = (u - 24.0 * (u / 24.0).round(), w - 24.0 * (w / 24.0).round());
            if du * du + dw * dw < 16.0 {
                v -= 70.0;
            }
            let g = v.clamp(0.0, 255.0) as u8;
            [g, g, g]
        })
    }

    /// The slide's length between the frame pressed at (80, 60) and the next one.
    fn slide(dots_px: (f64, f64), imprint_px: (f64, f64)) -> f64 {
        let (dx, dy) = slide_vector(dots_px, imprint_px);
        dx.hypot(dy)
    }

    /// The slide between the frame pressed at (80, 60) and the next one.
    fn slide_vector(dots_px: (f64, f64), imprint_px: (f64, f64)) -> (f64, f64) {
        let mut f = ImprintFollower::new(ImprintParams::DEFAULT, 1);
        // The first frame is the reference (no imprint), then the imprint appears, then moves.
        assert_eq!(f.update(&frame((0.0, 0.0), (-1000.0, 0.0))), (0.0, 0.0));
        f.update(&frame((0.0, 0.0), (80.0, 60.0)));
        f.update(&frame(dots_px, imprint_px))
    }

    #[test]
    fn a_sticking_imprint_does_not_slide() {
        assert!(slide((0.0, 0.0), (80.0, 60.0)) < 0.3);
        // Skin, dots and imprint moved together by 4 px: still stick.
        let s = slide((4.0, 0.0), (84.0, 60.0));
        assert!(s < 0.6, "{s}");
    }

    #[test]
    fn an_imprint_moving_over_still_dots_slides_by_its_motion() {
        for (d, want) in [
            ((6.0, 0.0), 6.0),
            ((0.0, -4.0), 4.0),
            ((4.0, 4.0), 32f64.sqrt()),
        ] {
            let s = slide((0.0, 0.0), (80.0 + d.0, 60.0 + d.1));
            assert!((s - want).abs() < 1.0, "{d:?}: {s} for {want}");
        }
        // The dots dragged 2 px one way, the imprint 4 px the other: 6 px apart, towards −x.
        let (dx, dy) = slide_vector((2.0, 0.0), (76.0, 60.0));
        assert!((dx + 6.0).abs() < 1.0 && dy.abs() < 0.5, "{dx} {dy}");
        let (dx, dy) = slide_vector((0.0, 0.0), (80.0, 64.0));
        assert!(dx.abs() < 0.5 && (dy - 4.0).abs() < 1.0, "{dx} {dy}");
    }

    #[test]
    fn without_an_imprint_nothing_slides() {
        let mut f = ImprintFollower::new(ImprintParams::DEFAULT, 1);
        for k in 0..4 {
            let s = f.update(&frame((f64::from(k), 0.0), (-1000.0, 0.0)));
            assert_eq!(s, (0.0, 0.0), "frame {k}");
        }
    }

    #[test]
    fn the_blur_keeps_a_constant_and_the_shift_is_found_to_a_fraction_of_a_pixel() {
        let (w, h) = (40, 30);
        let (mut padded, mut rows, mut out) = (Vec::new(), Vec::new(), Vec::new());
        let k = Kernel::gaussian(2.0);
        blurred_into(
            &vec![7.0; w * h],
            (w, h),
            &k,
            &mut padded,
            &mut rows,
            &mut out,
        );
        assert!(out.iter().all(|v| (v - 7.0).abs() < 1e-4));
        let bump = |cx: f64| -> Vec<f32> {
            (0..w * h)
                .map(|i| {
                    let (x, y) = ((i % w) as f64, (i / w) as f64);
                    (50.0 * (-((x - cx).powi(2) + (y - 15.0).powi(2)) / 18.0).exp()) as f32
                })
                .collect()
        };
        let ones = vec![1.0; w * h];
        let s = shift_between(&bump(21.5), &bump(20.0), &ones, (w, h), 3, &mut Vec::new());
        assert!((s.0 - 1.5).abs() < 0.2 && s.1.abs() < 0.05, "{s:?}");
    }
}
