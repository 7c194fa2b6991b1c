//! Touching markers parted where the grey image dips between them.
//!
//! A threshold joins markers that touch into one blob, yet the grey image between them still
//! dips: a downscaled frame's pixels are only partly covered where two pins meet, and two
//! blurred discs leave a saddle. A blob that could hold two markers — at least 1.6 times the
//! frame's median blob area, and filling its moments' ellipse less than 0.92 (two touching
//! equal discs fill 0.89; one marker swollen or stretched fills it nearly whole) — is cut
//! again at higher levels, one grey value at a time, until it falls apart into two or more
//! parts each holding a quarter of the median area and each peaking a quarter of the blob's
//! height above the level where they part (a noise peak does not). Its pixels then flood
//! from the parts, highest first (a watershed), so that the parts keep the pixels they had
//! and meet along the valley. A blob with a flat top (a binarised frame) or one peak is kept
//! whole; the tracker's two-markers-in-one-blob hypothesis still reads it.
//!
//! On the real 331-pin TacTip frames scaled to 128 × 128 (pins 3.7 px across, crowded near the
//! rim) this halves the pin-frames missing (docs/benchmarks.md).
//!
//! ```
//! use visuotact_image::GrayImage;
//! use visuotact_vision::blobs::{blobs_from_gray, Connectivity, Level};
//! use visuotact_vision::separate::{separate_touching, SeparateScratch};
//! // Two 3 × 3 squares joined by a dimmer neck, beside two single squares.
//! let mut img = GrayImage::new(20, 6);
//! for (x0, y0) in [(1, 1), (5, 1), (10, 1), (15, 1)] {
//!     for y in y0..y0 + 3 {
//!         for x in x0..x0 + 3 {
//!             img.set(x, y, 250);
//!         }
//!     }
//! }
//! img.set(4, 2, 120);
//! let mut blobs = blobs_from_gray(&img, Level::Scalar(100), Connectivity::Eight);
//! assert_eq!(blobs.len(), 3);
//! let parted = separate_touching(&mut blobs, &img, |_, _| 100.0, Connectivity::Eight,
//!     &mut SeparateScratch::default());
//! assert_eq!((parted, blobs.len()), (1, 4));
//! ```

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use visuotact_image::GrayImage;

use crate::blobs::{BBox, Blob, Connectivity};

/// How many times the frame's median blob area a blob must hold to be cut again: a pair's
/// two areas, less what a squeeze takes off them.
const LARGE: f64 = 1.6;
/// Below this share of its moments' ellipse a blob may be two markers (two touching equal
/// discs fill 0.89).
const TWO_LOBES_FILL: f64 = 0.92;
/// The least share of the median blob area a part must hold.
const PART: f64 = 0.25;
/// The least share of the blob's height over the level by which each part's peak must stand
/// above the level where the parts separate.
const DYNAMIC: f64 = 0.25;

/// Scratch for [`separate_touching`]: nothing is allocated once it has grown.
#[derive(Clone, Debug, Default)]
pub struct SeparateScratch {
    areas: Vec<u32>,
    heights: Vec<i32>,
    /// Per pixel of the box: the blob's (1) or not (0).
    mask: Vec<u8>,
    /// Per pixel of the box: its part above the level tried (0: none).
    comp: Vec<u32>,
    /// Per pixel of the box: the part it floods to (0: none yet).
    label: Vec<u32>,
    queue: Vec<usize>,
    sizes: Vec<usize>,
    peaks: Vec<i32>,
    big: Vec<u32>,
    heap: BinaryHeap<(i32, Reverse<usize>)>,
    parts: Vec<Blob>,
    kept: Vec<Blob>,
}

/// Replaces each blob of `blobs` that holds touching markers by its parts (see the module),
/// `gray` the image they were cut from at `level_at(x, y)` (foreground: grey value above it).
/// Returns how many blobs were parted. Blobs touching the border are kept as they are.
pub fn separate_touching(
    blobs: &mut Vec<Blob>,
    gray: &GrayImage,
    level_at: impl Fn(usize, usize) -> f32,
    connectivity: Connectivity,
    s: &mut SeparateScratch,
) -> usize {
    if blobs.len() < 3 {
        return 0;
    }
    s.areas.clear();
    s.areas.extend(blobs.iter().map(|b| b.area_px));
    let mid = s.areas.len() / 2;
    let median = f64::from(*s.areas.select_nth_unstable(mid).1);
    let large = (LARGE * median).ceil() as u32;
    let candidate = |b: &Blob| b.area_px >= large && !b.touches_border && two_lobes(b);
    if !blobs.iter().any(candidate) {
        return 0;
    }
    let least = ((PART * median).round() as usize).max(2);
    let mut kept = std::mem::take(&mut s.kept);
    kept.clear();
    let mut parted = 0;
    for b in blobs.iter() {
        if candidate(b) && parts_of(b, gray, &level_at, connectivity, least, s) {
            parted += 1;
            kept.extend_from_slice(&s.parts);
        } else {
            kept.push(*b);
        }
    }
    std::mem::swap(blobs, &mut kept);
    s.kept = kept;
    parted
}

/// Whether blob `b` fills its moments' ellipse (each variance counting the pixel as a unit
/// square) less than [`TWO_LOBES_FILL`].
fn two_lobes(b: &Blob) -> bool {
    let pixel = 1.0 / 12.0;
    let det = (b.mu20_px2 + pixel) * (b.mu02_px2 + pixel) - b.mu11_px2 * b.mu11_px2;
    f64::from(b.area_px) / (4.0 * std::f64::consts::PI * det.max(0.0).sqrt()) < TWO_LOBES_FILL
}

/// The pixels of a `w × h` box next to pixel `k` (row-major) under `connectivity`.
fn neighbours(k: usize, w: usize, h: usize, c: Connectivity, mut f: impl FnMut(usize)) {
    let (x, y) = (k % w, k / w);
    for dy in -1i64..=1 {
        for dx in -1i64..=1 {
            if (dx == 0 && dy == 0) || (c == Connectivity::Four && dx * dy != 0) {
                continue;
            }
            let (nx, ny) = (x as i64 + dx, y as i64 + dy);
            if nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h {
                f(ny as usize * w + nx as usize);
            }
        }
    }
}

/// Labels with `label` the pixels connected to `start` for which `inside` holds and whose
/// label is 0; returns how many.
fn flood(
    start: usize,
    (w, h, c): (usize, usize, Connectivity),
    labels: &mut [u32],
    label: u32,
    queue: &mut Vec<usize>,
    inside: impl Fn(usize) -> bool,
) -> usize {
    queue.clear();
    queue.push(start);
    labels[start] = label;
    let mut k = 0;
    while k < queue.len() {
        let p = queue[k];
        k += 1;
        neighbours(p, w, h, c, |q| {
            if labels[q] == 0 && inside(q) {
                labels[q] = label;
                queue.push(q);
            }
        });
    }
    queue.len()
}

/// Cuts blob `b` into its parts (into `s.parts`) when it has two or more; false otherwise.
fn parts_of(
    b: &Blob,
    gray: &GrayImage,
    level_at: &impl Fn(usize, usize) -> f32,
    connectivity: Connectivity,
    least: usize,
    s: &mut SeparateScratch,
) -> bool {
    let BBox { x0, y0, x1, y1 } = b.bbox;
    let (x0, y0) = (x0 as usize, y0 as usize);
    let (w, h) = (x1 as usize - x0, y1 as usize - y0);
    let geometry = (w, h, connectivity);
    // Each pixel's height over the level (0: background).
    s.heights.clear();
    s.heights.extend((0..w * h).map(|k| {
        let (x, y) = (x0 + k % w, y0 + k / w);
        let v = f32::from(gray.get(x, y)) - level_at(x, y);
        if v > 0.0 {
            v.ceil() as i32
        } else {
            0
        }
    }));
    // The blob's own pixels: the component of the box whose area is the blob's.
    s.comp.clear();
    s.comp.resize(w * h, 0);
    let heights = &s.heights;
    let mut found = None;
    let mut next = 1;
    for start in 0..w * h {
        if heights[start] == 0 || s.comp[start] != 0 {
            continue;
        }
        let n = flood(start, geometry, &mut s.comp, next, &mut s.queue, |q| {
            heights[q] > 0
        });
        if n == b.area_px as usize {
            found = Some(next);
            break;
        }
        next += 1;
    }
    let Some(own) = found else { return false };
    s.mask.clear();
    s.mask.extend(s.comp.iter().map(|&c| u8::from(c == own)));
    let mask = &s.mask;
    let top = (0..w * h)
        .filter(|&k| mask[k] == 1)
        .map(|k| heights[k])
        .max()
        .unwrap_or(0);
    let clear = (f64::from(top) * DYNAMIC).ceil() as i32;
    // Raise the level until the blob's pixels above it fall into two parts that count.
    for t in 1..top {
        s.comp.iter_mut().for_each(|c| *c = 0);
        s.sizes.clear();
        for start in 0..w * h {
            if mask[start] == 0 || heights[start] <= t || s.comp[start] != 0 {
                continue;
            }
            let label = s.sizes.len() as u32 + 1;
            let above = |q: usize| mask[q] == 1 && heights[q] > t;
            let n = flood(start, geometry, &mut s.comp, label, &mut s.queue, above);
            s.sizes.push(n);
        }
        s.peaks.clear();
        s.peaks.resize(s.sizes.len(), 0);
        for (k, &c) in s.comp.iter().enumerate() {
            if c != 0 {
                let p = &mut s.peaks[c as usize - 1];
                *p = (*p).max(heights[k]);
            }
        }
        s.big.clear();
        s.big.extend(
            (0..s.sizes.len())
                .filter(|&c| s.sizes[c] >= least && s.peaks[c] - t >= clear)
                .map(|c| c as u32 + 1),
        );
        if s.big.len() < 2 {
            continue;
        }
        watershed_from_parts(s, geometry);
        s.parts.clear();
        for &l in &s.big {
            s.parts.push(blob_of(&s.label, l, (x0, y0, w)));
        }
        return true;
    }
    false
}

/// Floods the blob's pixels (`s.mask`) from its parts (`s.big` among `s.comp`) into
/// `s.label`, highest first: two parts meet along the valley between them.
fn watershed_from_parts(
    s: &mut SeparateScratch,
    (w, h, connectivity): (usize, usize, Connectivity),
) {
    s.label.clear();
    s.label.resize(w * h, 0);
    s.heap.clear();
    for (k, (&c, &height)) in s.comp.iter().zip(&s.heights).enumerate() {
        if c != 0 && s.big.contains(&c) {
            s.label[k] = c;
            s.heap.push((height, Reverse(k)));
        }
    }
    while let Some((_, Reverse(p))) = s.heap.pop() {
        let l = s.label[p];
        let (label, heap, mask, heights) = (&mut s.label, &mut s.heap, &s.mask, &s.heights);
        neighbours(p, w, h, connectivity, |q| {
            if mask[q] == 1 && label[q] == 0 {
                label[q] = l;
                heap.push((heights[q], Reverse(q)));
            }
        });
    }
}

/// The blob of the pixels labelled `l` in a box at `(x0, y0)`, `w` wide.
fn blob_of(labels: &[u32], l: u32, (x0, y0, w): (usize, usize, usize)) -> Blob {
    let at = |k: usize| ((x0 + k % w) as f64, (y0 + k / w) as f64);
    let own = || (0..labels.len()).filter(|&k| labels[k] == l).map(at);
    let n = own().count() as f64;
    let (cx, cy) = own().fold((0.0, 0.0), |a, p| (a.0 + p.0, a.1 + p.1));
    let (cx, cy) = (cx / n, cy / n);
    let (mut xx, mut xy, mut yy) = (0.0, 0.0, 0.0);
    let (mut bx0, mut by0, mut bx1, mut by1) = (f64::MAX, f64::MAX, 0.0f64, 0.0f64);
    for (x, y) in own() {
        xx += (x - cx) * (x - cx);
        xy += (x - cx) * (y - cy);
        yy += (y - cy) * (y - cy);
        (bx0, by0, bx1, by1) = (bx0.min(x), by0.min(y), bx1.max(x), by1.max(y));
    }
    Blob {
        area_px: n as u32,
        x_px: cx,
        y_px: cy,
        mu20_px2: xx / n,
        mu11_px2: xy / n,
        mu02_px2: yy / n,
        bbox: BBox {
            x0: bx0 as u32,
            y0: by0 as u32,
            x1: bx1 as u32 + 1,
            y1: by1 as u32 + 1,
        },
        touches_border: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::blobs::{blobs_from_gray, Level};

    /// A frame of discs of radius `r` (grey 250 inside, the covered share of a pixel on its
    /// edge, sampled 8 × 8 per pixel) on black.
    fn discs(w: usize, h: usize, centres: &[(f64, f64)], r: f64) -> GrayImage {
        GrayImage::from_fn(w, h, |x, y| {
            let mut covered = 0;
            for sy in 0..8 {
                for sx in 0..8 {
                    let (px, py) = (
                        x as f64 + (sx as f64 + 0.5) / 8.0 - 0.5,
                        y as f64 + (sy as f64 + 0.5) / 8.0 - 0.5,
                    );
                    if centres.iter().any(|c| (px - c.0).hypot(py - c.1) <= r) {
                        covered += 1;
                    }
                }
            }
            (250 * covered / 64) as u8
        })
    }

    fn parted(img: &GrayImage, level: u8) -> (usize, Vec<Blob>) {
        let mut blobs = blobs_from_gray(img, Level::Scalar(level), Connectivity::Eight);
        let n = separate_touching(
            &mut blobs,
            img,
            |_, _| f32::from(level),
            Connectivity::Eight,
            &mut SeparateScratch::default(),
        );
        (n, blobs)
    }

    /// Two discs of radius 2 px whose edges meet in partly covered pixels (a pin array scaled
    /// down) are one blob at a level of half the grey; parted, each part's centroid is within
    /// 0.25 px of its disc's centre and the parts hold the blob's pixels between them.
    #[test]
    fn two_touching_small_discs_are_parted_near_their_centres() {
        let centres = [(10.3, 10.0), (14.4, 10.6), (30.0, 10.0), (40.0, 10.0)];
        let img = discs(50, 20, &centres, 2.0);
        let whole = blobs_from_gray(&img, Level::Scalar(125), Connectivity::Eight);
        assert_eq!(whole.len(), 3, "the pair is one blob at the level");
        let (n, blobs) = parted(&img, 125);
        assert_eq!((n, blobs.len()), (1, 4));
        for c in &centres[..2] {
            let d = blobs
                .iter()
                .map(|b| (b.x_px - c.0).hypot(b.y_px - c.1))
                .fold(f64::MAX, f64::min);
            assert!(d < 0.25, "part {d:.3} px from {c:?}");
        }
        assert_eq!(
            blobs.iter().map(|b| b.area_px).sum::<u32>(),
            whole.iter().map(|b| b.area_px).sum::<u32>()
        );
    }

    /// One stretched marker (an ellipse twice a disc's area) fills its ellipse and is kept,
    /// as is a pair binarised (a flat top: nothing to part it at).
    #[test]
    fn a_stretched_marker_and_a_flat_pair_are_kept_whole() {
        let ellipse = GrayImage::from_fn(60, 20, |x, y| {
            let (dx, dy) = ((x as f64 - 10.0) / 5.6, (y as f64 - 10.0) / 2.8);
            if dx * dx + dy * dy <= 1.0 {
                250
            } else {
                0
            }
        });
        let others = discs(60, 20, &[(30.0, 10.0), (40.0, 10.0), (50.0, 10.0)], 2.8);
        let img = GrayImage::from_fn(60, 20, |x, y| ellipse.get(x, y).max(others.get(x, y)));
        assert_eq!(parted(&img, 125).0, 0);
        let flat = discs(
            50,
            20,
            &[(10.0, 10.0), (13.6, 10.0), (30.0, 10.0), (40.0, 10.0)],
            2.0,
        );
        let flat = GrayImage::from_fn(50, 20, |x, y| if flat.get(x, y) > 125 { 255 } else { 0 });
        assert_eq!(parted(&flat, 125).0, 0);
    }
}
