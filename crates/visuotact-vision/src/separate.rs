//! Touching markers parted where the grey image dips between them.
//!
//! A threshold joins markers that touch into one blob, yet the grey image between them still
//! dips: a downscaled frame's pixels are only partly covered where two pins meet, and two
//! blurred discs leave a saddle. A blob that could hold two markers — at least 1.6 times the
//! frame's median blob area (at most 8: more is light or shade), and filling its moments'
//! ellipse less than the sensor's own markers do (`max_fill`: 1 less the tracker's shape
//! tolerance, [`TrackReference::fill_sigma`](crate::track::TrackReference::fill_sigma); a clean
//! pin fills nearly all of it, two touching equal discs 0.89, three packed pins 0.7) — is cut at
//! the lowest level over its threshold where it falls apart into two or more parts each
//! holding half the median area and each peaking a quarter of the blob's height above that
//! level (a noise peak does not; the level is found in one sweep of its pixels). Its pixels
//! then flood from the parts, highest first (a watershed), so that the parts keep the pixels
//! they had and meet along the valley, and each part still as large is cut the same way. The
//! blob is replaced by its parts only when every part comes down to under 1.6 median areas:
//! it is explained as markers, one per part. A blob with a flat top (a binarised frame), one
//! peak, the shape of the sensor's own ragged markers, or a part that stays large (a dot joined
//! by a line drawn across the frame) is kept whole; the tracker's two-markers-in-one-blob
//! hypothesis still reads it.
//!
//! On the real 331-pin TacTip frames scaled to 128 × 128 (pins 3.7 px across, packed near the
//! rim of a tilted dome) this cuts the pin-frames missing by about half (docs/benchmarks.md).
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
//! let parted = separate_touching(&mut blobs, &img, |_, _| 100.0, (Connectivity::Eight, 0.9),
//!     &mut SeparateScratch::default());
//! assert_eq!((parted, blobs.len()), (1, 4));
//! ```

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use visuotact_image::GrayImage;

use crate::blobs::{blob_of_pixels, BBox, Blob, Connectivity};
use crate::track::ellipse_fill;

/// How many times the frame's median blob area a blob must hold to be cut again: a pair's
/// two areas, less what a squeeze takes off them.
const LARGE: f64 = 1.6;
/// The most median areas a blob may hold to be cut again: more than eight markers' worth is
/// light or shade (a reflection on the dome, its rim), not markers packed together, and
/// would only be searched to be kept whole.
const MOST: f64 = 8.0;
/// The least share of the median blob area a part must hold.
const PART: f64 = 0.5;
/// The least share of the blob's height over the level by which each part's peak must stand
/// above the level where the parts separate.
const DYNAMIC: f64 = 0.25;

/// Scratch for [`separate_touching`] (the blobs kept; a parted blob's regions are small).
#[derive(Clone, Debug, Default)]
pub struct SeparateScratch {
    areas: Vec<u32>,
    parts: Vec<Blob>,
    kept: Vec<Blob>,
}

/// Replaces each blob of `blobs` that holds touching markers by its parts (see the module),
/// `gray` the image they were cut from at `level_at(x, y)` (foreground: grey value above it),
/// `max_fill` the least share of its moments' ellipse one of the sensor's markers fills.
/// Returns how many blobs were parted. Blobs touching the border are kept as they are.
pub fn separate_touching(
    blobs: &mut Vec<Blob>,
    gray: &GrayImage,
    level_at: impl Fn(usize, usize) -> f32,
    (connectivity, max_fill): (Connectivity, f64),
    s: &mut SeparateScratch,
) -> usize {
    if blobs.len() < 3 {
        return 0;
    }
    s.areas.clear();
    s.areas.extend(blobs.iter().map(|b| b.area_px));
    let mid = s.areas.len() / 2;
    let median = f64::from(*s.areas.select_nth_unstable(mid).1);
    let sizes = Sizes {
        large: (LARGE * median).ceil() as usize,
        least: ((PART * median).round() as usize).max(2),
    };
    let most = (MOST * median) as usize;
    let candidate = |b: &Blob| {
        (sizes.large..=most).contains(&(b.area_px as usize))
            && !b.touches_border
            && ellipse_fill(b) < max_fill
    };
    if !blobs.iter().any(candidate) {
        return 0;
    }
    let mut kept = std::mem::take(&mut s.kept);
    kept.clear();
    let mut parted = 0;
    for b in blobs.iter() {
        if candidate(b) && parts_of(b, gray, &level_at, connectivity, sizes, &mut s.parts) {
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

/// The frame's blob sizes that decide: a blob that may hold two markers, and the least part.
#[derive(Clone, Copy)]
struct Sizes {
    large: usize,
    least: usize,
}

/// A blob's box: its pixels' heights over the level (0: background) and the connectivity.
struct BoxOf {
    w: usize,
    h: usize,
    heights: Vec<i32>,
    connectivity: Connectivity,
}

impl BoxOf {
    /// The pixels next to pixel `k` (row-major).
    fn neighbours(&self, k: usize, mut f: impl FnMut(usize)) {
        let (x, y) = ((k % self.w) as i64, (k / self.w) as i64);
        for dy in -1i64..=1 {
            for dx in -1i64..=1 {
                if (dx == 0 && dy == 0) || (self.connectivity == Connectivity::Four && dx * dy != 0)
                {
                    continue;
                }
                let (nx, ny) = (x + dx, y + dy);
                if nx >= 0 && ny >= 0 && (nx as usize) < self.w && (ny as usize) < self.h {
                    f(ny as usize * self.w + nx as usize);
                }
            }
        }
    }

    /// The connected groups of the pixels `of` for which `keep` holds.
    fn components(&self, of: &[usize], keep: impl Fn(usize) -> bool) -> Vec<Vec<usize>> {
        let mut inside = vec![false; self.w * self.h];
        for &k in of {
            inside[k] = keep(k);
        }
        let mut out = Vec::new();
        for &start in of {
            if !inside[start] {
                continue;
            }
            inside[start] = false;
            let mut group = vec![start];
            let mut i = 0;
            while i < group.len() {
                let p = group[i];
                i += 1;
                self.neighbours(p, |q| {
                    if inside[q] {
                        inside[q] = false;
                        group.push(q);
                    }
                });
            }
            out.push(group);
        }
        out
    }

    /// The pixels `of` flooded from `seeds`, highest first (a watershed: seeds meet along the
    /// valley between them); one region per seed.
    fn flood(&self, of: &[usize], seeds: &[Vec<usize>]) -> Vec<Vec<usize>> {
        let mut label = vec![u32::MAX; self.w * self.h];
        for &k in of {
            label[k] = 0;
        }
        let mut heap = BinaryHeap::new();
        for (l, seed) in seeds.iter().enumerate() {
            for &k in seed {
                label[k] = l as u32 + 1;
                heap.push((self.heights[k], Reverse(k)));
            }
        }
        while let Some((_, Reverse(p))) = heap.pop() {
            let l = label[p];
            self.neighbours(p, |q| {
                if label[q] == 0 {
                    label[q] = l;
                    heap.push((self.heights[q], Reverse(q)));
                }
            });
        }
        let mut out = vec![Vec::new(); seeds.len()];
        for &k in of {
            if let Some(r) = out.get_mut((label[k] as usize).wrapping_sub(1)) {
                r.push(k);
            }
        }
        out
    }

    /// Region `of` cut into parts of one marker's size each, the level raised from `from`:
    /// at the first level where it falls into two or more parts that count (see the module),
    /// its pixels are flooded from them and each part still large is cut the same way. `None`
    /// when it does not fall apart, or a part stays large: the region is kept whole.
    fn split(&self, of: &[usize], from: i32, sizes: Sizes) -> Option<Vec<Vec<usize>>> {
        let t = self.parting_level(of, from, sizes)?;
        let top = of.iter().map(|&k| self.heights[k]).max()?;
        let clear = (f64::from(top) * DYNAMIC).ceil() as i32;
        let seeds: Vec<Vec<usize>> = self
            .components(of, |k| self.heights[k] > t)
            .into_iter()
            .filter(|c| {
                let peak = c.iter().map(|&k| self.heights[k]).max().unwrap_or(0);
                c.len() >= sizes.least && peak - t >= clear
            })
            .collect();
        let mut parts = Vec::new();
        for region in self.flood(of, &seeds) {
            if region.len() < sizes.large {
                parts.push(region);
            } else {
                parts.extend(self.split(&region, t + 1, sizes)?);
            }
        }
        Some(parts)
    }

    /// The lowest level from `from` on at which region `of` falls into two or more parts
    /// that count: its pixels added highest first (a union–find of the parts above each
    /// level), the parts counted at each height the region has.
    fn parting_level(&self, of: &[usize], from: i32, sizes: Sizes) -> Option<i32> {
        let h = &self.heights;
        let mut order = of.to_vec();
        order.sort_unstable_by_key(|&k| Reverse(h[k]));
        let top = h[*order.first()?];
        let clear = (f64::from(top) * DYNAMIC).ceil() as i32;
        // Per pixel of the box: its parent (u32::MAX: not added yet); per root, its part's size
        // and peak (its first pixel's height).
        let mut parent = vec![u32::MAX; self.w * self.h];
        let mut size = vec![0u32; self.w * self.h];
        let find = |parent: &mut [u32], mut x: usize| {
            while parent[x] as usize != x {
                let up = parent[x] as usize;
                parent[x] = parent[up];
                x = up;
            }
            x
        };
        let mut large: Vec<usize> = Vec::new();
        let mut lowest = None;
        let mut i = 0;
        while i < order.len() {
            let v = h[order[i]];
            while i < order.len() && h[order[i]] == v {
                let k = order[i];
                parent[k] = k as u32;
                size[k] = 1;
                self.neighbours(k, |q| {
                    if parent[q] != u32::MAX {
                        let (a, b) = (find(&mut parent, k), find(&mut parent, q));
                        if a != b {
                            // The part that peaked first keeps its root (and its peak).
                            let (keep, gone) = if h[a] >= h[b] { (a, b) } else { (b, a) };
                            parent[gone] = keep as u32;
                            size[keep] += size[gone];
                        }
                    }
                });
                let r = find(&mut parent, k);
                if size[r] as usize >= sizes.least && !large.contains(&r) {
                    large.push(r);
                }
                i += 1;
            }
            // The pixels added are those above every level from the next height down to this
            // one: the lowest of them (not under `from`) gives these parts.
            let next = order.get(i).map_or(i32::MIN, |&k| h[k]);
            let t = next.max(from);
            if t >= top {
                continue;
            }
            large.retain(|&r| parent[r] as usize == r);
            let counted = large.iter().filter(|&&r| h[r] - t >= clear).count();
            if counted >= 2 {
                lowest = Some(t);
            }
            if next < from {
                break;
            }
        }
        lowest
    }
}

/// Cuts blob `b` into parts of one marker's size each (into `parts`) when it can be; false
/// when it stays whole.
fn parts_of(
    b: &Blob,
    gray: &GrayImage,
    level_at: &impl Fn(usize, usize) -> f32,
    connectivity: Connectivity,
    sizes: Sizes,
    parts: &mut Vec<Blob>,
) -> bool {
    let BBox { x0, y0, x1, y1 } = b.bbox;
    let (x0, y0) = (x0 as usize, y0 as usize);
    let (w, h) = (x1 as usize - x0, y1 as usize - y0);
    let heights = (0..w * h)
        .map(|k| {
            let (x, y) = (x0 + k % w, y0 + k / w);
            let v = f32::from(gray.get(x, y)) - level_at(x, y);
            if v > 0.0 {
                v.ceil() as i32
            } else {
                0
            }
        })
        .collect();
    let bx = BoxOf {
        w,
        h,
        heights,
        connectivity,
    };
    // The blob's own pixels: the component of its box with its area.
    let all: Vec<usize> = (0..w * h).collect();
    let Some(own) = bx
        .components(&all, |k| bx.heights[k] > 0)
        .into_iter()
        .find(|c| c.len() == b.area_px as usize)
    else {
        return false;
    };
    let Some(regions) = bx.split(&own, 1, sizes) else {
        return false;
    };
    parts.clear();
    parts.extend(
        regions
            .iter()
            .map(|r| blob_of_pixels(r.iter().map(|&k| (x0 + k % w, y0 + k / w)))),
    );
    true
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
            (Connectivity::Eight, 0.92),
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

    /// Three pins packed in a row are one blob; parted, each part is one pin (within 0.3 px
    /// of its centre). Asked with a sensor whose own markers fill their ellipse no better than
    /// the pair does, the same blob is kept whole.
    #[test]
    fn three_packed_pins_become_three_parts() {
        let pins = [(10.0, 10.0), (14.2, 10.3), (18.4, 10.0)];
        let others = [(30.0, 10.0), (36.0, 10.0), (42.0, 10.0), (48.0, 10.0)];
        let all: Vec<(f64, f64)> = pins.iter().chain(&others).copied().collect();
        let img = discs(56, 20, &all, 2.0);
        let (n, blobs) = parted(&img, 125);
        assert_eq!((n, blobs.len()), (1, 7));
        for c in &pins {
            let d = blobs
                .iter()
                .map(|b| (b.x_px - c.0).hypot(b.y_px - c.1))
                .fold(f64::MAX, f64::min);
            assert!(d < 0.3, "part {d:.3} px from {c:?}");
        }
        let mut whole = blobs_from_gray(&img, Level::Scalar(125), Connectivity::Eight);
        let how = (Connectivity::Eight, 0.5);
        let n = separate_touching(
            &mut whole,
            &img,
            |_, _| 125.0,
            how,
            &mut SeparateScratch::default(),
        );
        assert_eq!((n, whole.len()), (0, 5));
    }

    /// A dot joined by a line drawn across the frame (dimmer where they meet) parts into the
    /// dot and a line far larger than a marker, which does not part: the blob is kept whole.
    #[test]
    fn a_dot_joined_by_a_line_stays_whole() {
        let dots = discs(
            60,
            20,
            &[(10.0, 10.0), (40.0, 10.0), (46.0, 10.0), (52.0, 10.0)],
            2.0,
        );
        let img = GrayImage::from_fn(60, 20, |x, y| {
            let line = if (13..34).contains(&x) && (9..11).contains(&y) {
                200
            } else {
                0
            };
            let neck = if x == 12 && (9..11).contains(&y) {
                140
            } else {
                0
            };
            dots.get(x, y).max(line).max(neck)
        });
        assert_eq!(parted(&img, 125).0, 0);
    }
}
