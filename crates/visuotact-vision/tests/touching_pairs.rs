//! A reference frame in contact can squeeze two markers into one blob. Calibration splits such
//! a blob by its second moments when the lattice agrees (both halves fall on lattice sites),
//! and leaves a round swollen marker or a marker with a tail whole.
//!
//! Frames: a 9 × 9 grid of discs of radius 7 px rendered by the simulator (`render_markers`).

use visuotact_image::RgbImage;
use visuotact_sim::pattern::{render_markers, Look};
use visuotact_sim::render::Ellipse;
use visuotact_vision::calibration::{calibrate, Preset};

const RADIUS: f64 = 7.0;

/// The grid's site centres, `pitch` apart, row by row.
fn sites(pitch: f64) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    for r in 0..9 {
        for c in 0..9 {
            out.push((30.0 + pitch * f64::from(c), 30.0 + pitch * f64::from(r)));
        }
    }
    out
}

/// A frame of the discs `(centre, radius)`: green on dark fabric with noise and vignetting, as
/// the simulator renders seed 000's membrane.
fn frame(discs: &[((f64, f64), f64)]) -> RgbImage {
    let shapes: Vec<_> = discs
        .iter()
        .map(|&((x, y), r)| (Ellipse::circle(x, y, r), None))
        .collect();
    render_markers(250, 250, &shapes, &Look::GREEN_ON_DARK, 7)
}

fn calibrated_markers(img: &RgbImage) -> Vec<(f64, f64)> {
    let (cal, _) = calibrate([("rest", img)], &Preset::Iats.config()).unwrap();
    cal.markers.iter().map(|m| (m.x_px, m.y_px)).collect()
}

fn nearest(markers: &[(f64, f64)], p: (f64, f64)) -> f64 {
    markers
        .iter()
        .map(|m| (m.0 - p.0).hypot(m.1 - p.1))
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn two_markers_squeezed_into_one_blob_are_two_markers() {
    // 18 px apart: markers nearly touch at rest, as a TacTip's pins.
    let mut centres = sites(18.0);
    // Markers (4, 3) and (4, 4) pushed 2.5 px towards each other: 13 px apart, radius 7, one blob.
    centres[4 * 9 + 3].0 += 2.5;
    centres[4 * 9 + 4].0 -= 2.5;
    let discs: Vec<_> = centres.iter().map(|&c| (c, RADIUS)).collect();
    let markers = calibrated_markers(&frame(&discs));
    assert_eq!(markers.len(), 81);
    for k in [4 * 9 + 3, 4 * 9 + 4] {
        let off = nearest(&markers, centres[k]);
        assert!(off < 1.0, "marker {k} placed {off:.2} px from its disc");
    }
}

#[test]
fn a_swollen_marker_or_one_with_a_speck_stays_one_marker() {
    let pitch = 24.0;
    let centres = sites(pitch);
    let mut discs: Vec<_> = centres.iter().map(|&c| (c, RADIUS)).collect();
    // (2, 2) swollen to twice its area: round, one marker.
    discs[2 * 9 + 2].1 = RADIUS * std::f64::consts::SQRT_2;
    // (6, 6) joined by a speck of 0.6 its area 10 px above its centre: half as big again as
    // a marker and elongated as two discs would be, but the halves of a split would not both
    // lie on lattice sites.
    let (sx, sy) = centres[6 * 9 + 6];
    discs.push(((sx, sy - 10.0), RADIUS * 0.6f64.sqrt()));
    let markers = calibrated_markers(&frame(&discs));
    assert_eq!(markers.len(), 81);
    assert!(nearest(&markers, centres[2 * 9 + 2]) < 1.0);
    // One marker near the disc, its centroid pulled towards the speck.
    let off = nearest(&markers, centres[6 * 9 + 6]);
    assert!(
        off < 4.0,
        "the marker with a speck {off:.2} px from its disc"
    );
}

#[test]
fn two_slivers_squeezed_into_one_blob_in_a_crease_are_two_markers() {
    // A crease down the middle squeezes columns 3–6 together (12–15 px apart where the others
    // are 18) and their markers to half their area; in it, markers (4, 4) and (4, 5) are pushed
    // 1.5 px towards each other into one blob of about one whole marker's area: twice its
    // neighbours' area, not the array's.
    let columns_px = [30.0, 48.0, 66.0, 81.0, 93.0, 105.0, 120.0, 138.0, 156.0];
    let squeezed = RADIUS / std::f64::consts::SQRT_2;
    let mut discs = Vec::new();
    for r in 0..9 {
        for (c, &x) in columns_px.iter().enumerate() {
            let push = match (r, c) {
                (4, 4) => 1.5,
                (4, 5) => -1.5,
                _ => 0.0,
            };
            let radius = if (3..=6).contains(&c) {
                squeezed
            } else {
                RADIUS
            };
            discs.push(((x + push, 30.0 + 18.0 * f64::from(r)), radius));
        }
    }
    let markers = calibrated_markers(&frame(&discs));
    assert_eq!(markers.len(), 81);
    for k in [4 * 9 + 4, 4 * 9 + 5] {
        let off = nearest(&markers, discs[k].0);
        assert!(off < 1.0, "marker {k} placed {off:.2} px from its disc");
    }
}

#[test]
fn markers_a_crease_squeezes_to_slivers_are_markers_not_specks() {
    // A crease squeezes column 4 to slivers of under a sixth of a whole marker's area (under
    // the floor, a fifth, below which a blob of a frame at rest is a speck) and columns 3 and 5
    // to half of it: among their neighbours the slivers are markers all the same.
    let mut discs = Vec::new();
    for (k, &c) in sites(18.0).iter().enumerate() {
        let radius = match k % 9 {
            4 => 2.8,
            3 | 5 => RADIUS / std::f64::consts::SQRT_2,
            _ => RADIUS,
        };
        discs.push((c, radius));
    }
    let markers = calibrated_markers(&frame(&discs));
    assert_eq!(markers.len(), 81);
    for (k, &(c, _)) in discs.iter().enumerate() {
        let off = nearest(&markers, c);
        assert!(off < 1.0, "marker {k} placed {off:.2} px from its disc");
    }
}
