//! Test arrays shared by the tracker's unit tests.

use crate::blobs::{BBox, Blob};
use crate::track::energy::Energy;
use crate::track::solve::Matching;
use crate::track::{TrackParams, TrackReference};

/// The six axial steps of a hexagonal lattice, in turn around the circle.
pub const HEX: [(i64, i64); 6] = [(1, 0), (0, 1), (-1, 1), (-1, 0), (0, -1), (1, -1)];

/// Ring `k`'s sites of a hexagonal array in turn around it (the centre for `k = 0`).
pub fn ring(k: i64) -> Vec<(i64, i64)> {
    if k == 0 {
        return vec![(0, 0)];
    }
    let mut at = (HEX[4].0 * k, HEX[4].1 * k);
    let mut out = Vec::new();
    for d in HEX {
        for _ in 0..k {
            out.push(at);
            at = (at.0 + d.0, at.1 + d.1);
        }
    }
    out
}

/// A hexagonal array numbered ring by ring.
pub struct HexArray {
    /// Each pin's lattice site (axial coordinates).
    pub sites: Vec<(i64, i64)>,
    /// Each pin's position, pixels.
    pub positions: Vec<(f64, f64)>,
    /// The reference, its lattice steps from the sites.
    pub reference: TrackReference,
}

/// The hexagonal array of rings `0..=rings` at `pitch` pixels.
pub fn hex_array(rings: i64, pitch: f64) -> HexArray {
    let sites: Vec<(i64, i64)> = (0..=rings).flat_map(ring).collect();
    let positions: Vec<(f64, f64)> = sites
        .iter()
        .map(|&(q, r)| {
            let (q, r) = (q as f64, r as f64);
            (
                100.0 + pitch * (q + 0.5 * r),
                100.0 + pitch * r * 0.75_f64.sqrt(),
            )
        })
        .collect();
    let mut reference = TrackReference::new(positions.clone(), vec![50.0; positions.len()]);
    reference.take_lattice(&sites, &HEX);
    HexArray {
        sites,
        positions,
        reference,
    }
}

impl HexArray {
    /// Every pin's blob, a disc of 50 px², slid by `(dx, dy)` pixels.
    pub fn blobs_slid(&self, dx: f64, dy: f64) -> Vec<Blob> {
        self.positions
            .iter()
            .map(|p| disc(p.0 + dx, p.1 + dy, 50))
            .collect()
    }

    /// The order-free matching of `blobs` with `params`, nothing taken yet.
    pub fn matching<'a>(&'a self, blobs: &'a [Blob], params: &'a TrackParams) -> Matching<'a> {
        let energy = Energy {
            reference: &self.reference,
            params,
            view: None,
        };
        let anchors = self.positions.clone();
        Matching::new(
            &self.reference,
            blobs,
            blobs.len(),
            energy,
            anchors,
            (0.0, 0.0),
        )
    }
}

/// A disc of `area_px` pixels centred at `(x, y)`.
pub fn disc(x: f64, y: f64, area_px: u32) -> Blob {
    let r = (f64::from(area_px) / std::f64::consts::PI).sqrt();
    Blob {
        area_px,
        x_px: x,
        y_px: y,
        mu20_px2: r * r / 4.0,
        mu11_px2: 0.0,
        mu02_px2: r * r / 4.0,
        bbox: BBox {
            x0: (x - r) as u32,
            y0: (y - r) as u32,
            x1: (x + r) as u32 + 1,
            y1: (y + r) as u32 + 1,
        },
        touches_border: false,
    }
}
