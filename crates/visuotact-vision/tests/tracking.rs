//! Calibrate on rendered rest frames, then track frames in random order with presses that drag
//! markers by up to a full pitch: every marker keeps its identity (its measured position stays
//! within 0.3 px of its own true position), lost markers are reported without shifting others.

use visuotact_sim::pattern::{
    grid_markers, render_grid, render_markers, GridPattern, MarkerTruth, Press,
};
use visuotact_vision::calibration::{calibrate, CalibrationConfig, SensorCalibration};
use visuotact_vision::detect::DetectorConfig;
use visuotact_vision::features::{FeatureExtractor, FeatureSet};
use visuotact_vision::layout::{Layout, LayoutChoice};
use visuotact_vision::preprocess::PreprocessConfig;
use visuotact_vision::track::MarkerStatus;

fn calibrated(pattern: &GridPattern) -> SensorCalibration {
    let frames: Vec<_> = (0..5)
        .map(|s| render_grid(pattern, None, 100 + s).0)
        .collect();
    let ids: Vec<String> = (0..5).map(|i| format!("ref{i}")).collect();
    let det = DetectorConfig {
        preprocess: PreprocessConfig::IATS,
        ..Default::default()
    };
    let (cal, report) = calibrate(
        ids.iter().map(String::as_str).zip(frames.iter()),
        &CalibrationConfig {
            detector: det,
            layout: LayoutChoice::Auto,
            features: FeatureSet::ALL,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(cal.layout, Layout::Grid);
    assert!(
        report.missing_per_frame.is_empty(),
        "{:?}",
        report.missing_per_frame
    );
    cal
}

fn check_frame(
    ex: &mut FeatureExtractor,
    truth: &[MarkerTruth],
    img: &visuotact_image::RgbImage,
    what: &str,
) {
    let f = ex.extract(img).unwrap();
    let cal = ex.calibration();
    for (k, m) in cal.markers.iter().enumerate() {
        let t = truth[k].ellipse;
        let reach = t.a_px.max(t.b_px) + 1.5;
        let inside = t.cx_px - reach > 0.0
            && t.cy_px - reach > 0.0
            && t.cx_px + reach < img.width() as f64
            && t.cy_px + reach < img.height() as f64;
        if !inside {
            // Pushed onto the border: excluded like any border blob, so it may be lost.
            assert!(matches!(f.status[k], MarkerStatus::Ok | MarkerStatus::Lost));
            if f.status[k] == MarkerStatus::Lost {
                continue;
            }
        }
        assert_eq!(
            f.status[k],
            MarkerStatus::Ok,
            "{what}: marker {k} {:?}",
            f.status[k]
        );
        assert_at_truth(&f, m, k, t, what);
    }
}

/// Marker `k`'s measured position (its reference `m` plus its displacement in `f`) lies within
/// 0.3 px of the drawn ellipse `t`'s centre.
fn assert_at_truth(
    f: &visuotact_vision::features::FrameFeatures,
    m: &visuotact_vision::calibration::ReferenceMarker,
    k: usize,
    t: visuotact_sim::render::Ellipse,
    what: &str,
) {
    let (x, y) = (m.x_px + f.values[4 * k], m.y_px + f.values[4 * k + 1]);
    assert!(
        (x - t.cx_px).hypot(y - t.cy_px) < 0.3,
        "{what}: marker {k} at ({x:.2}, {y:.2}), truth ({:.2}, {:.2})",
        t.cx_px,
        t.cy_px
    );
}

#[test]
fn rest_grid_numbered_in_grid_order() {
    let pattern = GridPattern::IATS;
    let cal = calibrated(&pattern);
    assert_eq!(cal.markers.len(), 117);
    assert_eq!((cal.grid_rows, cal.grid_cols), (9, 13));
    let truth = render_grid(&pattern, None, 0).1;
    for (m, t) in cal.markers.iter().zip(&truth) {
        assert_eq!((m.row as usize, m.col as usize), (t.row, t.col));
        assert!((m.x_px - t.ellipse.cx_px).hypot(m.y_px - t.ellipse.cy_px) < 0.2);
        assert!(
            m.jitter_px.is_some_and(|j| j < 0.2),
            "jitter {:?}",
            m.jitter_px
        );
    }
}

#[test]
fn drags_up_to_a_full_pitch_in_random_order() {
    let pattern = GridPattern::IATS;
    let cal = calibrated(&pattern);
    let mut ex = FeatureExtractor::new(cal, FeatureSet::ALL).unwrap();
    // A fixed pseudo-random sequence of touches: position, depth-like push, drag of up to one
    // pitch in any direction.
    let mut s = 12345u64;
    let mut next = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    for i in 0..120 {
        let ang = next() * std::f64::consts::TAU;
        let drag = pattern.pitch_x_px * (0.3 + 0.7 * next());
        let press = Press {
            x_px: 120.0 + 400.0 * next(),
            y_px: 100.0 + 280.0 * next(),
            sigma_px: 60.0 + 40.0 * next(),
            push_px: 6.0 * next(),
            shear_x_px: drag * ang.cos(),
            shear_y_px: drag * ang.sin(),
            grow: 0.3 * next(),
            stretch: 0.2 * next(),
        };
        let (img, truth) = render_grid(&pattern, Some(&press), 1000 + i);
        check_frame(
            &mut ex,
            &truth,
            &img,
            &format!("touch {i} (drag {drag:.1} px)"),
        );
    }
}

#[test]
fn missing_markers_are_reported_not_shifted() {
    let pattern = GridPattern::IATS;
    let cal = calibrated(&pattern);
    let mut ex = FeatureExtractor::new(cal, FeatureSet::ALL).unwrap();
    // Render with the left half of the markers removed (painted over by background).
    let (img, truth) = render_grid(&pattern, None, 7);
    let mut img = img;
    let w = img.width();
    let bg = img.get(2, 2);
    {
        let data = img.as_mut_slice();
        for y in 0..480 {
            for x in 0..(44 + 6 * 46 + 23) {
                let i = (y * w + x) * 3;
                data[i..i + 3].copy_from_slice(&bg);
            }
        }
    }
    let f = ex.extract(&img).unwrap();
    for (k, t) in truth.iter().enumerate() {
        if t.col <= 6 {
            assert_eq!(f.status[k], MarkerStatus::Lost, "marker {k}");
            assert!(f.values[4 * k].is_nan());
        } else {
            assert_eq!(f.status[k], MarkerStatus::Ok, "marker {k}");
            assert!(f.values[4 * k].abs() < 0.3 && f.values[4 * k + 1].abs() < 0.3);
        }
    }
    assert_eq!(f.found, 9 * 6);
}

#[test]
fn merged_markers_are_flagged() {
    let pattern = GridPattern::IATS;
    let cal = calibrated(&pattern);
    let mut ex = FeatureExtractor::new(cal.clone(), FeatureSet::ALL).unwrap();
    // Paint a broad bridge between markers 60 and 61 (row 4, columns 8 and 9) in marker
    // colour: one blob of over 1.4 times the pair's area, which no split explains.
    let (mut img, _) = render_grid(&pattern, None, 9);
    let (a, b) = (&cal.markers[60], &cal.markers[61]);
    let fg = img.get(a.x_px as usize, a.y_px as usize);
    let w = img.width();
    let y0 = a.y_px as usize;
    for y in y0 - 8..=y0 + 8 {
        for x in a.x_px as usize..=b.x_px as usize {
            let i = (y * w + x) * 3;
            img.as_mut_slice()[i..i + 3].copy_from_slice(&fg);
        }
    }
    let f = ex.extract(&img).unwrap();
    assert_eq!(f.status[60], MarkerStatus::Merged);
    assert_eq!(f.status[61], MarkerStatus::Merged);
    assert!(f.values[4 * 60].is_nan() && f.values[4 * 61].is_nan());
    assert_eq!(f.found, 115);
    // Every other marker is unaffected.
    for k in (0..117).filter(|k| *k != 60 && *k != 61) {
        assert_eq!(f.status[k], MarkerStatus::Ok);
    }
}

/// Two markers pushed together until their blobs join: the pair that only touches (the grey
/// image still dips between them within the blur) is parted there, each marker on its own
/// part with an area (0.06 px from the truth); the pair overlapping by a pixel has no dip and is
/// split by the blob's moments (a position, no area).
#[test]
fn a_merged_pair_is_parted_or_split_by_its_moments() {
    let pattern = GridPattern::IATS;
    let cal = calibrated(&pattern);
    let mut ex = FeatureExtractor::new(cal.clone(), FeatureSet::ALL).unwrap();
    // Markers 60 and 61 pushed together until they touch (the gap closes within the blur),
    // and a pair in a column (markers 30 and 43) overlapping by a pixel.
    for (p, q, gap_px, status, tol_px) in [
        (60, 61, 0.0, MarkerStatus::Ok, 0.25),
        (30, 43, -1.0, MarkerStatus::Split, 0.6),
    ] {
        let mut markers = grid_markers(&pattern, None);
        let (mp, mq) = (markers[p].ellipse, markers[q].ellipse);
        let (mx, my) = (0.5 * (mp.cx_px + mq.cx_px), 0.5 * (mp.cy_px + mq.cy_px));
        let (ux, uy) = (mq.cx_px - mp.cx_px, mq.cy_px - mp.cy_px);
        let len = ux.hypot(uy);
        let half = pattern.radius_px + 0.5 * gap_px;
        for (k, sign) in [(p, -1.0), (q, 1.0)] {
            markers[k].ellipse.cx_px = mx + sign * half * ux / len;
            markers[k].ellipse.cy_px = my + sign * half * uy / len;
        }
        let shapes: Vec<_> = markers.iter().map(|m| (m.ellipse, None)).collect();
        let img = render_markers(pattern.width, pattern.height, &shapes, &pattern.look, 9);
        let f = ex.extract(&img).unwrap();
        for k in [p, q] {
            assert_eq!(f.status[k], status, "marker {k}");
            let (x, y) = (
                cal.markers[k].x_px + f.values[4 * k],
                cal.markers[k].y_px + f.values[4 * k + 1],
            );
            let (tx, ty) = (markers[k].ellipse.cx_px, markers[k].ellipse.cy_px);
            let e = (x - tx).hypot(y - ty);
            assert!(
                e < tol_px,
                "marker {k}: ({x:.2}, {y:.2}) vs ({tx:.2}, {ty:.2})"
            );
            // Split: a position only, no area or eccentricity of its own; parted: both.
            let shape = [f.values[4 * k + 2], f.values[4 * k + 3]];
            assert_eq!(
                shape.map(f64::is_nan),
                [status == MarkerStatus::Split; 2],
                "marker {k}"
            );
        }
        assert_eq!(f.found, 117);
        for k in (0..117).filter(|k| *k != p && *k != q) {
            assert_eq!(f.status[k], MarkerStatus::Ok);
        }
    }
}

/// Followed frame by frame (the temporal prior), the right half of the grid slides left until
/// columns 5 and 6 overlap (centres 0.8 radius apart: one blob of about 1.5 markers, smaller
/// than the 1.6 that marks a blob as merged by its size alone). Neither marker of a squeezed
/// pair is reported at the pair's centroid as its own: both are merged, or split by the
/// blob's moments near their true centres; every other marker stays its own.
#[test]
fn squeezed_pins_sharing_a_blob_are_merged_not_one_of_them_at_the_centroid() {
    let pattern = GridPattern::IATS;
    let cal = calibrated(&pattern);
    let mut ex = FeatureExtractor::new(cal.clone(), FeatureSet::ALL).unwrap();
    ex.set_temporal_prior(true);
    let rest = grid_markers(&pattern, None);
    let last = 12;
    for step in 0..=last {
        let slide = (pattern.pitch_x_px - 0.8 * pattern.radius_px) * f64::from(step) / 12.0;
        let mut markers = rest.clone();
        for m in markers.iter_mut().filter(|m| m.col >= 6) {
            m.ellipse.cx_px -= slide;
        }
        let shapes: Vec<_> = markers.iter().map(|m| (m.ellipse, None)).collect();
        let img = render_markers(pattern.width, pattern.height, &shapes, &pattern.look, 40);
        let f = ex.extract(&img).unwrap();
        for (k, m) in cal.markers.iter().enumerate() {
            let t = markers[k].ellipse;
            let (x, y) = (m.x_px + f.values[4 * k], m.y_px + f.values[4 * k + 1]);
            let e = (x - t.cx_px).hypot(y - t.cy_px);
            let what = format!("step {step}: marker {k} {:?}", f.status[k]);
            match f.status[k] {
                MarkerStatus::Ok => assert!(e < 0.5, "{what} {e:.2} px off"),
                MarkerStatus::Split => assert!(e < 2.5, "{what} {e:.2} px off"),
                MarkerStatus::Merged => assert!(markers[k].col == 5 || markers[k].col == 6),
                other => panic!("{what}: {other:?}"),
            }
        }
        if step == last {
            for k in (0..117).filter(|&k| rest[k].col == 5 || rest[k].col == 6) {
                assert!(
                    matches!(f.status[k], MarkerStatus::Merged | MarkerStatus::Split),
                    "marker {k}: {:?}",
                    f.status[k]
                );
            }
        }
    }
}

#[test]
fn spurious_blobs_are_counted_not_assigned() {
    let pattern = GridPattern::IATS;
    let cal = calibrated(&pattern);
    let mut ex = FeatureExtractor::new(cal, FeatureSet::ALL).unwrap();
    let (mut img, _) = render_grid(&pattern, None, 11);
    // A 5×5 bright speck halfway between four markers.
    let fg = img.get(44, 48);
    let w = img.width();
    for y in 70..75 {
        for x in 64..69 {
            let i = (y * w + x) * 3;
            img.as_mut_slice()[i..i + 3].copy_from_slice(&fg);
        }
    }
    let f = ex.extract(&img).unwrap();
    assert_eq!(f.found, 117);
    assert_eq!(f.spurious, 1);
    for k in 0..117 {
        assert!(
            f.values[4 * k].abs() < 0.5 && f.values[4 * k + 1].abs() < 0.5,
            "marker {k} moved"
        );
    }
}

#[test]
fn a_hidden_marker_does_not_take_a_stray_blob_from_afar() {
    // One inner marker is painted over and a marker-sized blob of the same look appears in the
    // gap 1.5 pitches away, halfway between four others: the all-at-once reassignment reaches
    // that far to fill holes, but a blob its neighbours do not put there is not that marker.
    let pattern = GridPattern::IATS;
    let cal = calibrated(&pattern);
    let mut ex = FeatureExtractor::new(cal, FeatureSet::ALL).unwrap();
    let (mut img, truth) = render_grid(&pattern, None, 13);
    let k = truth.iter().position(|t| t.row == 4 && t.col == 5).unwrap();
    let right = truth.iter().position(|t| t.row == 4 && t.col == 6).unwrap();
    let below = truth.iter().position(|t| t.row == 5 && t.col == 5).unwrap();
    let (cx, cy) = (truth[k].ellipse.cx_px, truth[k].ellipse.cy_px);
    let px = truth[right].ellipse.cx_px - cx;
    let py = truth[below].ellipse.cy_px - cy;
    let half = (0.4 * px.min(py)) as i64;
    let (sx, sy) = ((cx + 1.5 * px) as i64, (cy + 0.5 * py) as i64);
    let (w, bg) = (img.width() as i64, img.get(2, 2));
    let data = img.as_mut_slice();
    for dy in -half..=half {
        for dx in -half..=half {
            let from = (((cy as i64 + dy) * w + cx as i64 + dx) * 3) as usize;
            let to = (((sy + dy) * w + sx + dx) * 3) as usize;
            let marker: [u8; 3] = data[from..from + 3].try_into().unwrap();
            data[to..to + 3].copy_from_slice(&marker);
            data[from..from + 3].copy_from_slice(&bg);
        }
    }
    let f = ex.extract(&img).unwrap();
    assert_eq!(f.status[k], MarkerStatus::Lost, "the hidden marker");
    assert_eq!(f.found, 116);
    assert_eq!(f.spurious, 1);
    for j in (0..117).filter(|&j| j != k) {
        assert_eq!(f.status[j], MarkerStatus::Ok, "marker {j}");
        assert!(
            f.values[4 * j].abs() < 0.5 && f.values[4 * j + 1].abs() < 0.5,
            "marker {j} moved"
        );
    }
}

/// Paints over the marker `k` of a rendered frame with the background.
fn painted_over(img: &mut visuotact_image::RgbImage, truth: &[MarkerTruth], k: usize) {
    let e = truth[k].ellipse;
    let r = e.a_px.max(e.b_px) + 3.0;
    let (w, h) = (img.width(), img.height());
    let bg = img.get(2, 2);
    let data = img.as_mut_slice();
    let (x0, x1) = (
        (e.cx_px - r).max(0.0) as usize,
        ((e.cx_px + r) as usize).min(w - 1),
    );
    let (y0, y1) = (
        (e.cy_px - r).max(0.0) as usize,
        ((e.cy_px + r) as usize).min(h - 1),
    );
    for y in y0..=y1 {
        for x in x0..=x1 {
            let i = (y * w + x) * 3;
            data[i..i + 3].copy_from_slice(&bg);
        }
    }
}

/// A marker gone from the middle of a field dragged by under a pitch (hidden, or merged with
/// its neighbour) is reported lost, and every other marker keeps its own blob. Dragged by 1.4
/// pitches, the markers near the gap may be put in doubt, but none reported `ok` has another's
/// blob.
#[test]
fn a_gap_in_a_field_dragged_under_a_pitch_is_one_lost_marker() {
    let pattern = GridPattern::IATS;
    let cal = calibrated(&pattern);
    let mut ex = FeatureExtractor::new(cal, FeatureSet::ALL).unwrap();
    let centre = (44.0 + 6.0 * 46.0, 48.0 + 4.0 * 48.0);
    for (pitches, seed) in [(0.9, 31), (0.9 * 46.0 / 48.0, 32), (1.4, 33)] {
        let press = Press {
            x_px: centre.0,
            y_px: centre.1,
            sigma_px: 70.0,
            push_px: 2.0,
            shear_x_px: pitches * 46.0,
            shear_y_px: 0.0,
            grow: 0.1,
            stretch: 0.0,
        };
        let (mut img, truth) = render_grid(&pattern, Some(&press), seed);
        // The marker nearest the contact: row 4, column 6.
        let gone = 4 * 13 + 6;
        painted_over(&mut img, &truth, gone);
        let f = ex.extract(&img).unwrap();
        let cal = ex.calibration();
        let what = format!("drag of {pitches:.2} pitch");
        assert_eq!(f.status[gone], MarkerStatus::Lost, "{what}");
        let mut in_doubt = 0;
        for (k, m) in cal.markers.iter().enumerate() {
            if k == gone {
                continue;
            }
            if f.status[k] != MarkerStatus::Ok {
                assert!(pitches > 1.0, "{what}: marker {k} {:?}", f.status[k]);
                in_doubt += 1;
                continue;
            }
            assert_at_truth(&f, m, k, truth[k].ellipse, &what);
        }
        eprintln!("{what}: {in_doubt} markers in doubt");
    }
}

/// A 5 × 5 grid of 30-px markers 20 px apart, starting at (30, 30): the positions and the
/// tracking reference.
fn grid_reference() -> (Vec<(f64, f64)>, visuotact_vision::track::TrackReference) {
    let positions: Vec<(f64, f64)> = (0..25)
        .map(|k| {
            (
                30.0 + 20.0 * f64::from(k % 5),
                30.0 + 20.0 * f64::from(k / 5),
            )
        })
        .collect();
    let reference = visuotact_vision::track::TrackReference::new(positions.clone(), vec![30.0; 25]);
    (positions, reference)
}

/// A disc-shaped blob of `area_px` pixels at (x, y), as the labelling pass reports it.
fn disc_blob(x: f64, y: f64, area_px: u32, touches_border: bool) -> visuotact_vision::blobs::Blob {
    let r = (f64::from(area_px) / std::f64::consts::PI).sqrt();
    let v = r * r / 4.0;
    visuotact_vision::blobs::Blob {
        area_px,
        x_px: x,
        y_px: y,
        mu20_px2: v,
        mu11_px2: 0.0,
        mu02_px2: v,
        bbox: visuotact_vision::blobs::BBox {
            x0: (x - r).floor().max(0.0) as u32,
            y0: (y - r).floor().max(0.0) as u32,
            x1: (x + r).ceil() as u32 + 1,
            y1: (y + r).ceil() as u32 + 1,
        },
        touches_border,
    }
}

/// A marker whose blob touches the view's edge (a circular mask a pixel beyond the marker's
/// outline, pixel by pixel) is measured when the blob is as big as the marker at rest (scaled by
/// the local magnification), and lost when the edge cut part of it off or the blob holds more
/// than the marker (a rim cut by the frame beside it).
#[test]
fn a_marker_touching_the_views_edge_whole_is_measured_cut_is_lost() {
    use visuotact_vision::track::{track_with, TrackHints, TrackParams};
    let (positions, reference) = grid_reference();
    let cfg = TrackParams::default();
    // Every marker's blob at `at` of its rest position, of `others_px` (marker 4's, top right,
    // of `area_px`, listed as cut: the last one).
    let track_cut = |at: &dyn Fn((f64, f64)) -> (f64, f64), others_px: u32, area_px: u32| {
        let mut blobs: Vec<_> = positions
            .iter()
            .enumerate()
            .filter(|&(k, _)| k != 4)
            .map(|(_, &p)| disc_blob(at(p).0, at(p).1, others_px, false))
            .collect();
        let (x, y) = at(positions[4]);
        blobs.push(disc_blob(x, y, area_px, true));
        let hints = TrackHints {
            cut: 1,
            ..TrackHints::default()
        };
        let r = track_with(&reference, &blobs, &cfg, hints);
        assert!((0..25)
            .filter(|&k| k != 4)
            .all(|k| r.status[k] == MarkerStatus::Ok));
        (r.status[4], r.assignment[4].map(|j| blobs[j].x_px))
    };
    // Moved 1 px.
    let frame = |area_px: u32| track_cut(&|(x, y)| (x + 1.0, y), 30, area_px);
    // Pixel noise of the outline: a 30-px marker seen as 27 px is whole.
    for area in [27, 30, 34] {
        assert_eq!(frame(area), (MarkerStatus::Ok, Some(111.0)), "{area} px");
    }
    // Cut by the edge (under the rest area by more than the outline's noise), or a blob far
    // bigger than a marker: left the view, never measured.
    for area in [15, 24, 60, 1200] {
        assert_eq!(frame(area).0, MarkerStatus::Lost, "{area} px");
    }
    // The grid magnified 1.25 times about its centre (a deep press): the markers swell with the
    // skin to 47 px, and the rest area of 30 px is then a cut marker.
    let magnified = |area_px: u32| {
        let at = |(x, y): (f64, f64)| (70.0 + 1.25 * (x - 70.0), 70.0 + 1.25 * (y - 70.0));
        track_cut(&at, 47, area_px).0
    };
    assert_eq!(magnified(46), MarkerStatus::Ok);
    assert_eq!(magnified(30), MarkerStatus::Lost);
}

/// Order-free tracking of a grid with every marker's blob at rest, of `others_px`, but markers
/// 12 and 13 (the middle row's centre and its right neighbour), for which there is one `blob`.
/// Every other marker is checked measured. Returns the tracking and the blobs.
fn pair_on_one_blob(
    positions: &[(f64, f64)],
    reference: &visuotact_vision::track::TrackReference,
    others_px: u32,
    blob: visuotact_vision::blobs::Blob,
) -> (
    visuotact_vision::track::TrackResult,
    Vec<visuotact_vision::blobs::Blob>,
) {
    use visuotact_vision::track::{track_with, TrackHints, TrackParams};
    let mut blobs: Vec<_> = positions
        .iter()
        .enumerate()
        .filter(|&(k, _)| k != 12 && k != 13)
        .map(|(_, &(x, y))| disc_blob(x, y, others_px, false))
        .collect();
    blobs.push(blob);
    let r = track_with(
        reference,
        &blobs,
        &TrackParams::default(),
        TrackHints::default(),
    );
    for k in (0..25).filter(|&k| k != 12 && k != 13) {
        assert_eq!(r.status[k], MarkerStatus::Ok, "marker {k}");
    }
    (r, blobs)
}

/// Order-free, marker 12 hidden (no blob) beside marker 13, whose blob is swollen or moved:
/// the energy weighs the blob as 13's alone (its area against 13's, its centroid against 13's
/// prediction) and as the pair's (its area against two, its length along the pair against two
/// markers' at their predicted separation). A round blob up to 1.5 markers near 13 is 13's (a
/// pair would be long); a blob with two markers' area and length between them holds both: 13
/// is not measured at its centroid.
#[test]
fn a_blob_swollen_beside_a_hidden_neighbour_is_weighed_as_one_and_as_two() {
    let (positions, reference) = grid_reference();
    // Markers 12 (at (70, 70)) and 13 (at (90, 70)): one blob at (x, 70) of `area_px`; the
    // other markers' blobs at rest, of `others_px` (30 at rest).
    let frame = |blob: visuotact_vision::blobs::Blob, others_px: u32| {
        let (r, blobs) = pair_on_one_blob(&positions, &reference, others_px, blob);
        (
            r.status[12],
            r.status[13],
            r.assignment[13].map(|j| blobs[j].x_px),
        )
    };
    let ok = |x: f64| (MarkerStatus::Lost, MarkerStatus::Ok, Some(x));
    let round = |x: f64, area_px: u32| disc_blob(x, 70.0, area_px, false);
    assert_eq!(frame(round(88.0, 36), 30), ok(88.0));
    assert_eq!(frame(round(88.0, 45), 30), ok(88.0));
    assert_eq!(frame(round(88.0, 41), 39), ok(88.0));
    assert_eq!(frame(round(93.0, 45), 30), ok(93.0));
    // Two markers' area, as long along x as two discs of 30 px 20 px apart.
    let mut pair = round(80.0, 60);
    pair.mu20_px2 = 2.0 * 30.0 / (4.0 * std::f64::consts::PI) + 100.0;
    let (s12, s13, _) = frame(pair, 30);
    for st in [s12, s13] {
        assert!(
            matches!(st, MarkerStatus::Merged | MarkerStatus::Split),
            "{st:?}"
        );
    }
}

/// Order-free, on a 5 × 5 grid of 64-px markers 20 px apart, one blob of two markers' area
/// midway between markers 12 and 13 (predicted at x = 70 and 90), the other markers at rest.
/// With a waist between two lobes (the moments of two touching discs) it is split into the two
/// markers at their centres. With no waist (an ellipse) it is split only when it is about as
/// long as the two at their predicted separation (the energy's elongation term within the
/// margin): an ellipse as wide as one marker whose split puts the two 7.8 px apart, 0.39 of
/// their predictions' separation, is one marker stretched by a drag, its neighbour hidden
/// elsewhere: both merged, neither measured. A thinner ellipse whose split puts them 12 px
/// apart, 0.6 of the predictions' (side-by-side pins squeezed into one outline), is split.
#[test]
fn a_blob_without_a_waist_is_split_only_as_far_apart_as_predicted() {
    use visuotact_vision::track::TrackReference;
    let (positions, _) = grid_reference();
    let reference = TrackReference::new(positions.clone(), vec![64.0; 25]);
    // Variances along x and y of a 128-px blob at (80, 70).
    let frame = |var_x: f64, var_y: f64| {
        let mut pair = disc_blob(80.0, 70.0, 128, false);
        pair.mu20_px2 = var_x;
        pair.mu02_px2 = var_y;
        let (r, blobs) = pair_on_one_blob(&positions, &reference, 64, pair);
        [12, 13].map(|k| (r.status[k], r.position_px(k, &blobs).map(|p| p.0)))
    };
    // A disc of 64 px: radius 4.51 px, a variance of 64/4π = 5.09 px² along any axis.
    let disc = 64.0 / (4.0 * std::f64::consts::PI);
    let radius = (64.0 / std::f64::consts::PI).sqrt();
    // Two touching discs: split near their centres (within 0.3 px: the local fit sees marker
    // 13 a little smaller, 0.97 of its rest size, and weights the split by area).
    let [(s12, x12), (s13, x13)] = frame(disc + radius * radius, disc);
    assert_eq!((s12, s13), (MarkerStatus::Split, MarkerStatus::Split));
    assert!((x12.unwrap() - (80.0 - radius)).abs() < 0.3, "{x12:?}");
    assert!((x13.unwrap() - (80.0 + radius)).abs() < 0.3, "{x13:?}");
    // An ellipse of 128 px as wide as a disc, twice as long: the moments would put the two
    // 7.8 px apart, 0.39 of their predictions' separation, and it has no waist: one marker
    // stretched by a drag, its neighbour hidden elsewhere: both merged, neither measured.
    let [(s12, x12), (s13, x13)] = frame(radius * radius, disc);
    assert_eq!((s12, s13), (MarkerStatus::Merged, MarkerStatus::Merged));
    assert_eq!((x12, x13), (None, None));
    // An ellipse of 128 px whose split is 12 px: half-axes 2·√(5.09 + 36) and 128/(π·that).
    let long = 2.0 * (disc + 36.0_f64).sqrt();
    let thin = 128.0 / (std::f64::consts::PI * long);
    let [(s12, x12), (s13, x13)] = frame(long * long / 4.0, thin * thin / 4.0);
    assert_eq!((s12, s13), (MarkerStatus::Split, MarkerStatus::Split));
    assert!((x12.unwrap() - 74.0).abs() < 0.3, "{x12:?}");
    assert!((x13.unwrap() - 86.0).abs() < 0.3, "{x13:?}");
}

/// Order-free, on a 5 × 5 grid of 30-px markers 20 px apart (gate 12 px), one free blob of
/// two markers' area and two touching lobes along x, 7.5 px below the midpoint of markers 12
/// and 13 (two pins joined by a bridge on a TacTip's rim, its centroid between them): 12.5 px
/// from either prediction, beyond both gates, but 7.5 px from where the pair's centroid is
/// expected. The pair is read on it (split or merged), neither marker lost.
#[test]
fn two_blobless_neighbours_share_the_blob_between_them() {
    let (positions, reference) = grid_reference();
    let mut pair = disc_blob(80.0, 77.5, 60, false);
    pair.mu20_px2 = 2.0 * 30.0 / (4.0 * std::f64::consts::PI) + 100.0;
    pair.mu02_px2 = 30.0 / (4.0 * std::f64::consts::PI);
    let (r, _) = pair_on_one_blob(&positions, &reference, 30, pair);
    for k in [12, 13] {
        assert!(
            matches!(r.status[k], MarkerStatus::Merged | MarkerStatus::Split),
            "marker {k}: {:?}",
            r.status[k]
        );
    }
}

/// Order-free, marker 13 hidden (no blob) and marker 12's blob, at its rest place 1 spacing
/// from 13's prediction, of one marker's area but two lobes (the moments of two half-size discs
/// 8 px apart: it fills 0.73 of its ellipse): two markers shrunk under the contact and touching,
/// the centroid neither's. 12 is not measured (the shape term makes the blob too dear for one
/// marker). A disc of the same area stays 12's, and so does a 30-px blob whose lobes lie 4 px
/// apart (a waist within the pixel noise of its outline).
#[test]
fn a_two_lobed_blob_beside_a_hidden_neighbour_is_not_the_holders_alone() {
    use visuotact_vision::track::TrackReference;
    let (positions, small) = grid_reference();
    let status_12 = |area_px: u32, lobes_apart_px: f64| {
        let reference = TrackReference::new(positions.clone(), vec![f64::from(area_px); 25]);
        let mut blob = disc_blob(70.0, 70.0, area_px, false);
        if lobes_apart_px > 0.0 {
            // Two discs of half the area, their centres `lobes_apart_px` apart along x.
            let half = f64::from(area_px) / 2.0 / (4.0 * std::f64::consts::PI);
            blob.mu20_px2 = half + lobes_apart_px * lobes_apart_px / 4.0;
            blob.mu02_px2 = half;
        }
        let (r, _) = pair_on_one_blob(&positions, &reference, area_px, blob);
        assert_eq!(r.status[13], MarkerStatus::Lost);
        r.status[12]
    };
    assert!(!status_12(64, 8.0).has_position());
    assert_eq!(status_12(64, 0.0), MarkerStatus::Ok);
    assert_eq!(small.areas_px[0], 30.0);
    assert_eq!(status_12(30, 4.0), MarkerStatus::Ok);
}

/// Order-free, every marker of the grid in view and marker 12's blob carrying a tail: its
/// own disc (120 px) joined by a speck of 18 px 11 px from its centre, as binarised TacTip pins fray
/// in contact (the blob fills 0.8 of its moments' ellipse). The pin is still 12, measured,
/// and no neighbour is put in doubt: with no neighbour hidden that could be its other lobe, a
/// misshapen blob costs at most a speck of clutter (beside a hidden neighbour it does not:
/// `a_two_lobed_blob_beside_a_hidden_neighbour_is_not_the_holders_alone`).
#[test]
fn a_pin_with_a_tail_is_still_the_pin() {
    use visuotact_vision::track::{track, TrackParams, TrackReference};
    let (positions, _) = grid_reference();
    let reference = TrackReference::new(positions.clone(), vec![120.0; 25]);
    let mut blobs: Vec<_> = positions
        .iter()
        .map(|&(x, y)| disc_blob(x, y, 120, false))
        .collect();
    // The disc's variance is 120/(4π) ≈ 9.5 px², the speck's 18/(4π); the speck 11 px out
    // along x shifts the centroid by 18·11/138 ≈ 1.4 px and widens the variance along x by
    // 120·18·11²/138² ≈ 13.7 px².
    let (a, s, r) = (120.0, 18.0, 11.0);
    let w = a + s;
    let own = (a * a + s * s) / (4.0 * std::f64::consts::PI * w);
    let b = &mut blobs[12];
    b.area_px = 138;
    b.x_px += s * r / w;
    b.mu20_px2 = own + a * s * r * r / (w * w);
    b.mu02_px2 = own;
    let fill = 138.0 / (4.0 * std::f64::consts::PI * (b.mu20_px2 * b.mu02_px2).sqrt());
    assert!((0.75..0.85).contains(&fill), "{fill}");
    let t = track(&reference, &blobs, &TrackParams::default());
    for k in 0..25 {
        assert_eq!(t.status[k], MarkerStatus::Ok, "marker {k}");
        assert_eq!(t.assignment[k], Some(k), "marker {k}");
    }
}

/// Followed tracking of the grid with markers 12 and 13 (the middle row's centre and its
/// right neighbour) last seen at `pair` (`None`: without a position) and the others at rest;
/// the frame has every other marker's blob at rest and `blob` for the pair. Every other
/// marker is checked measured.
fn middle_pair_followed(
    pair: [Option<(f64, f64)>; 2],
    blob: visuotact_vision::blobs::Blob,
) -> visuotact_vision::track::TrackResult {
    use visuotact_vision::track::{track_with, TrackHints, TrackParams};
    let (positions, reference) = grid_reference();
    let mut prior: Vec<Option<(f64, f64)>> = positions.iter().copied().map(Some).collect();
    prior[12] = pair[0];
    prior[13] = pair[1];
    let mut blobs: Vec<_> = positions
        .iter()
        .enumerate()
        .filter(|&(k, _)| k != 12 && k != 13)
        .map(|(_, &(x, y))| disc_blob(x, y, 30, false))
        .collect();
    blobs.push(blob);
    let hints = TrackHints {
        prior: Some(&prior),
        ..TrackHints::default()
    };
    let r = track_with(&reference, &blobs, &TrackParams::default(), hints);
    for k in (0..25).filter(|&k| k != 12 && k != 13) {
        assert_eq!(r.status[k], MarkerStatus::Ok, "marker {k}");
    }
    r
}

/// Followed (a temporal prior), two neighbours squeezed towards each other end on one blob of
/// 1.5 markers between their last positions, 0.62 spacing apart: neither is reported at the
/// pair's centroid as its own (merged, split, lost, or in doubt where the energy cannot tell
/// one marker on the blob from both by the margin).
#[test]
fn a_blob_between_two_squeezed_neighbours_merges_them() {
    // Markers 12 and 13 (the middle row's centre and its right neighbour) were last seen at
    // x = 75 and 87.4; the others at rest.
    let r = middle_pair_followed(
        [Some((75.0, 70.0)), Some((87.4, 70.0))],
        disc_blob(81.0, 70.0, 45, false),
    );
    for k in [12, 13] {
        assert_ne!(r.status[k], MarkerStatus::Ok, "marker {k}");
    }
}

/// Followed (a temporal prior), two neighbours that had no position in the prior frame (both
/// lost or merged) and one blob between their predictions: which of the two it shows is not
/// known when it lies about as near both predictions, so the one that took it is in doubt, not
/// measured. When the blob is nearer one prediction by more than the margin says, it stays the
/// taker's.
#[test]
fn a_blob_between_two_markers_unseen_a_frame_ago_is_neither_ones() {
    // Markers 12 and 13 (predicted at x = 70 and 90 from their neighbours, at rest); one blob
    // at x = `blob_x` on their row.
    let frame = |blob_x: f64, seen_13: bool| {
        let r = middle_pair_followed(
            [None, seen_13.then_some((90.0, 70.0))],
            disc_blob(blob_x, 70.0, 30, false),
        );
        assert_eq!(r.status[13], MarkerStatus::Lost);
        r.status[12]
    };
    // Midway, 10 px (half a spacing) from both predictions: either's.
    assert_eq!(frame(80.0, false), MarkerStatus::Ambiguous);
    // 13 was seen a frame ago, 12 px from the blob: 12's.
    assert_eq!(frame(78.0, true), MarkerStatus::Ok);
    // 8 px from 12's prediction, 12 px (at 13's gate): 12's by more than the margin.
    assert_eq!(frame(78.0, false), MarkerStatus::Ok);
    assert_eq!(frame(72.0, false), MarkerStatus::Ok);
}

/// The frame of [`two_rows_dragged_past_a_pitch_are_in_doubt_not_read_a_step_short`].
struct DraggedRows {
    positions: Vec<(f64, f64)>,
    reference: visuotact_vision::track::TrackReference,
    blobs: Vec<visuotact_vision::blobs::Blob>,
    /// Each marker's true position (`None`: hidden).
    truth: Vec<Option<(f64, f64)>>,
}

/// Columns of [`two_rows_dragged`]'s grid (8 rows).
const COLS: usize = 12;

fn two_rows_dragged() -> DraggedRows {
    const H: f64 = f64::NAN; // hidden under the squeeze
    let positions: Vec<(f64, f64)> = (0..COLS * 8)
        .map(|k| {
            (
                40.0 + 22.0 * (k % COLS) as f64,
                50.0 + 22.0 * (k / COLS) as f64,
            )
        })
        .collect();
    let reference =
        visuotact_vision::track::TrackReference::new(positions.clone(), vec![85.0; COLS * 8]);
    // Leftward motion per row (the first four) and column, px.
    let motion: [[f64; COLS]; 4] = [
        [0., -1., -3., -6., H, H, -33., -26., -10., -4., -2., -1.],
        [0., -1., -3., -6., H, H, -33., -26., -10., -4., -2., -1.],
        [0., -1., -2., -4., -9., -15., -16., -12., -6., -3., -1., 0.],
        [0., -1., -1., -2., -4., -6., -6., -5., -3., -2., -1., 0.],
    ];
    let mut truth: Vec<Option<(f64, f64)>> = positions
        .iter()
        .enumerate()
        .map(|(k, &(x, y))| {
            let dx = motion.get(k / COLS).map_or(0.0, |row| row[k % COLS]);
            (!dx.is_nan()).then_some((x + dx, y))
        })
        .collect();
    let mut blobs: Vec<_> = truth
        .iter()
        .flatten()
        .map(|&(x, y)| disc_blob(x, y, 85, false))
        .collect();
    // The squeezed pair of each row: one blob, the fifth marker's as seen.
    for r in 0..2 {
        let (x, y) = positions[r * COLS + 4];
        blobs.push(disc_blob(x - 13.0, y, 93, false));
        truth[r * COLS + 4] = Some((x - 13.0, y));
    }
    DraggedRows {
        positions,
        reference,
        blobs,
        truth,
    }
}

/// Two rows of a 12 × 8 grid (pitch 22 px) dragged left by up to 1.5 pitches near the top
/// edge (the drag of `scripts/bench/drag-matrix`'s GelSight variant 1, seed 2, frame 5): in each,
/// the fifth and sixth markers are squeezed into one blob of about one marker's size (seen as
/// the fifth) and the next two slid past their rest places, so the rows read one lattice step
/// short are about as smooth as the truth — but only when both rows slide together (each alone
/// leaves a shear between them). No marker is reported at another's blob: those the two
/// readings disagree on are in doubt — in frames in any order, and followed when the prior
/// frame did not see the dragged markers (their places come from their neighbours).
#[test]
fn two_rows_dragged_past_a_pitch_are_in_doubt_not_read_a_step_short() {
    use visuotact_vision::track::{track_with, TrackHints, TrackParams};
    let DraggedRows {
        positions,
        reference,
        blobs,
        truth,
    } = two_rows_dragged();
    // Frames in any order; and followed, the prior frame having seen the rows' dragged part
    // nowhere (the rest where it was at rest).
    let mut prior: Vec<Option<(f64, f64)>> = positions.iter().copied().map(Some).collect();
    for r in 0..2 {
        for c in 4..8 {
            prior[r * COLS + c] = None;
        }
    }
    let hints = [
        TrackHints::default(),
        TrackHints {
            prior: Some(&prior),
            ..TrackHints::default()
        },
    ];
    for (what, hints) in ["in any order", "followed"].into_iter().zip(hints) {
        let r = track_with(&reference, &blobs, &TrackParams::default(), hints);
        for (k, t) in truth.iter().enumerate() {
            let Some(j) = r.assignment[k] else { continue };
            let b = (blobs[j].x_px, blobs[j].y_px);
            let own = t.is_some_and(|t| (b.0 - t.0).hypot(b.1 - t.1) < 3.0);
            assert!(
                own,
                "{what}: marker {k} {:?} at {b:?}, truth {t:?}",
                r.status[k]
            );
        }
        // Away from the drag every marker is measured.
        for k in 4 * COLS..positions.len() {
            assert_eq!(r.status[k], MarkerStatus::Ok, "{what}: marker {k}");
        }
    }
}

/// A wide grid twisted about its centre moves its rim by more than a pitch while its centre
/// stays: read order-free, every marker keeps its own blob (none is read a step along the
/// twist, no seam of lost markers where regions read from different seeds meet).
#[test]
fn a_twisted_wide_grid_keeps_every_identity() {
    use visuotact_vision::track::{track, MarkerStatus, TrackParams, TrackReference};
    let (n, pitch) = (15usize, 20.0);
    let rest: Vec<(f64, f64)> = (0..n * n)
        .map(|k| (40.0 + pitch * (k % n) as f64, 40.0 + pitch * (k / n) as f64))
        .collect();
    let reference = TrackReference::new(rest.clone(), vec![30.0; n * n]);
    let c = 40.0 + pitch * (n - 1) as f64 / 2.0;
    for deg in [-14.0f64, -11.0, -8.0, -5.0, 5.0, 8.0, 11.0, 14.0] {
        let (s, co) = deg.to_radians().sin_cos();
        let moved: Vec<(f64, f64)> = rest
            .iter()
            .map(|&(x, y)| {
                let (dx, dy) = (x - c, y - c);
                (c + co * dx - s * dy + 3.0, c + s * dx + co * dy - 2.0)
            })
            .collect();
        // Blobs in another order than the markers.
        let blobs: Vec<_> = moved
            .iter()
            .rev()
            .map(|&(x, y)| disc_blob(x, y, 30, false))
            .collect();
        let t = track(&reference, &blobs, &TrackParams::DEFAULT);
        for k in 0..n * n {
            assert_eq!(t.status[k], MarkerStatus::Ok, "{deg}°: marker {k}");
            assert_eq!(t.assignment[k], Some(n * n - 1 - k), "{deg}°: marker {k}");
        }
    }
}

/// The tracker's settings parse from `name=value` pairs over the defaults, every bad one
/// named; a sensor file written before `spread_sigmas` existed gets its default.
#[test]
fn tracker_settings_parse_and_default() {
    use visuotact_vision::track::TrackParams;
    let p = TrackParams::DEFAULT
        .parse_over("spread_sigmas=1, margin=3")
        .unwrap();
    assert_eq!((p.spread_sigmas, p.margin), (1.0, 3.0));
    assert_eq!(p.gate_spacings, TrackParams::DEFAULT.gate_spacings);
    for bad in ["spread_sigmas=0", "spread_sigmas=x", "spread=1", "margin"] {
        let e = TrackParams::DEFAULT
            .parse_over(bad)
            .unwrap_err()
            .to_string();
        assert!(e.contains(bad.split('=').next().unwrap()), "{bad}: {e}");
    }
    let old: TrackParams = serde_json::from_str(r#"{"margin": 2.5}"#).unwrap();
    assert_eq!(old.spread_sigmas, TrackParams::DEFAULT.spread_sigmas);
    assert_eq!(old.margin, 2.5);
}

/// A pin hidden when the reference was taken (under a crease of a reference in contact) leaves
/// its lattice site empty. When it shows again in a column dragged 0.7 pitch, followed as an
/// unseen site, the pin's blob has an owner: every identity is right and no blob is clutter.
/// Without the site, its blob is clutter; the column was read a step along as well (each marker
/// taking the next one's blob) while the order-free search took its steps from the marker
/// nearest the centroid, next to the hole, which had neighbours three ways only and so could
/// shift a reading down the column but not back up.
#[test]
fn a_pin_hidden_at_rest_is_an_unseen_site_not_a_neighbours_blob() {
    use visuotact_vision::layout::Layout;
    use visuotact_vision::track::{track, unseen_sites, TrackParams, TrackReference};
    let (n, hole) = (7i64, (3i64, 3i64));
    let site_px = |(r, c): (i64, i64)| (40.0 + 20.0 * c as f64, 40.0 + 20.0 * r as f64);
    let all: Vec<(i64, i64)> = (0..n * n).map(|k| (k / n, k % n)).collect();
    let sites: Vec<(i64, i64)> = all.iter().copied().filter(|&s| s != hole).collect();
    let positions: Vec<(f64, f64)> = sites.iter().map(|&s| site_px(s)).collect();
    let unseen = unseen_sites(&sites, &positions, Layout::Grid.row_col_steps());
    assert_eq!(unseen, vec![(hole, site_px(hole))]);
    // Column 3 dragged down 14 px (0.7 pitch) below the crease, half that above it, its
    // neighbouring columns 30 % of it: every pin visible, the hidden one too.
    let blobs: Vec<_> = all
        .iter()
        .map(|&(r, c)| {
            let p = site_px((r, c));
            let dy = match (c, r < 3) {
                (3, true) => 7.0,
                (3, false) => 14.0,
                (2 | 4, _) => 4.2,
                _ => 0.0,
            };
            disc_blob(p.0, p.1 + dy, 60, false)
        })
        .collect();
    let truth: Vec<usize> = (0..all.len()).filter(|&j| all[j] != hole).collect();
    let areas = vec![60.0; positions.len()];
    let wrong = |t: &visuotact_vision::track::TrackResult| {
        t.assignment
            .iter()
            .zip(&truth)
            .filter(|(a, &j)| a.is_some_and(|a| a != j))
            .count()
    };
    let unseen_px: Vec<(f64, f64)> = unseen.iter().map(|u| u.1).collect();
    let with = TrackReference::with_unseen(positions.clone(), areas.clone(), &unseen_px, 60.0);
    assert_eq!(with.markers(), 48);
    let t = track(&with, &blobs, &TrackParams::DEFAULT);
    assert_eq!(t.status.len(), 48, "the unseen site is not reported");
    assert_eq!(wrong(&t), 0);
    assert_eq!(t.found(), 48);
    assert_eq!(
        t.spurious, 0,
        "the hidden pin's blob is its site's, not clutter"
    );
    let without = track(
        &TrackReference::new(positions, areas),
        &blobs,
        &TrackParams::DEFAULT,
    );
    assert_eq!(wrong(&without), 0);
    assert_eq!(
        without.spurious, 1,
        "without the site its pin's blob is clutter"
    );
}

/// Order-free, a frame missing one marker's blob leaves it unexplained: the other starts are
/// searched (`searched_again`), and searching them beside the first instead of after it
/// (`starts_side_by_side`, what a video's next frame asks for) gives the same reading.
#[test]
fn starts_searched_side_by_side_read_the_same() {
    use visuotact_vision::track::{track_with, TrackHints, TrackParams};
    let (positions, reference) = grid_reference();
    let slid = |&(x, y): &(f64, f64)| disc_blob(x + 2.0, y + 1.0, 30, false);
    let params = TrackParams::default();
    let all: Vec<_> = positions.iter().map(slid).collect();
    let whole = track_with(&reference, &all, &params, TrackHints::default());
    assert!(!whole.searched_again);
    let one_short: Vec<_> = positions
        .iter()
        .enumerate()
        .filter(|&(k, _)| k != 7)
        .map(|(_, p)| slid(p))
        .collect();
    let after = track_with(&reference, &one_short, &params, TrackHints::default());
    assert!(after.searched_again);
    assert_eq!(after.status[7], MarkerStatus::Lost);
    let beside = TrackHints {
        starts_side_by_side: true,
        ..TrackHints::default()
    };
    assert_eq!(after, track_with(&reference, &one_short, &params, beside));
}

/// Followed (a temporal prior), a block of markers the last frame read a row off — a whole
/// corner of an 8 × 10 grid, its far row then beyond the view's edge, so that nothing there is
/// left without its blob — is read right again in a frame at rest: the seam where the block
/// meets the rest leaves blobs unexplained, and the frame read on its own explains every blob
/// at a lower energy. Without that, each frame started where the last one ended, and the
/// block stayed a row off for as long as the video lasted (a real GelSight Mini video, its
/// last 90 frames).
#[test]
fn a_block_followed_a_row_off_is_read_right_again() {
    use visuotact_vision::track::{track_with, TrackHints, TrackParams, TrackReference, View};
    let (rows, cols, pitch) = (8, 10, 20.0);
    let at = |r: usize, c: usize| (30.0 + pitch * c as f64, 30.0 + pitch * r as f64);
    let positions: Vec<(f64, f64)> = (0..rows * cols).map(|k| at(k / cols, k % cols)).collect();
    let reference = TrackReference::new(positions.clone(), vec![30.0; rows * cols]);
    let blobs: Vec<_> = positions
        .iter()
        .map(|&(x, y)| disc_blob(x, y, 30, false))
        .collect();
    let view = View {
        x0: 0.0,
        y0: 0.0,
        x1: 30.0 + pitch * (cols as f64 - 0.5),
        y1: 30.0 + pitch * (rows as f64 - 0.5),
        circle: None,
    };
    for (r0, c0) in [(3, 5), (2, 4), (4, 6)] {
        // The block from row r0, column c0 to the far corner, read a row down.
        let prior: Vec<Option<(f64, f64)>> = (0..rows * cols)
            .map(|k| {
                let (r, c) = (k / cols, k % cols);
                Some(if r >= r0 && c >= c0 {
                    at(r + 1, c)
                } else {
                    at(r, c)
                })
            })
            .collect();
        let hints = TrackHints {
            prior: Some(&prior),
            view: Some(view),
            ..TrackHints::default()
        };
        let t = track_with(&reference, &blobs, &TrackParams::default(), hints);
        for k in 0..rows * cols {
            assert_eq!(
                (t.status[k], t.assignment[k]),
                (MarkerStatus::Ok, Some(k)),
                "block from ({r0}, {c0}): marker {k}"
            );
        }
    }
}

/// A dot joined by a line drawn across it (a tracker's displacement arrow burned into a video,
/// as in the GelSight Mini demo recordings) is one blob of about twice the dot's area with two
/// lobes. Its marker takes it: the blob is at worst the marker and a clutter joined, so its
/// size and shape together cost no more than a clutter's cost — while every neighbour holds
/// its own blob, none can be the other lobe. Before, area and shape were charged apart and the
/// marker cost more taking its blob than leaving it as clutter: lost (and, in a sheared field,
/// its row read a column off to avoid it).
#[test]
fn a_dot_joined_by_a_drawn_line_keeps_its_marker() {
    use visuotact_vision::track::{track, TrackParams, TrackReference};
    let (pitch, dot) = (30.0, 100.0);
    let positions: Vec<(f64, f64)> = (0..25)
        .map(|k| {
            (
                40.0 + pitch * f64::from(k % 5),
                40.0 + pitch * f64::from(k / 5),
            )
        })
        .collect();
    let reference = TrackReference::new(positions.clone(), vec![dot; 25]);
    let mut blobs: Vec<_> = positions
        .iter()
        .map(|&(x, y)| disc_blob(x, y, 100, false))
        .collect();
    // Marker 12's dot (radius 5.6 px, variance r²/4) joined by a line 4 px wide from its rim
    // to 30 px out along the diagonal between its neighbours (variance L²/12 along, w²/12
    // across): the parts' moments added about their common centroid.
    let r = (dot / std::f64::consts::PI).sqrt();
    let (t0, t1, w) = (r, 30.0, 4.0);
    let line = (t1 - t0) * w;
    let total = dot + line;
    let along = line * (t0 + t1) / 2.0 / total;
    let var_along = (dot * (r * r / 4.0 + along * along)
        + line * ((t1 - t0).powi(2) / 12.0 + ((t0 + t1) / 2.0 - along).powi(2)))
        / total;
    let var_across = (dot * r * r / 4.0 + line * w * w / 12.0) / total;
    // Rotated by 45°: x and y each take half of both, their covariance half the difference.
    let b = &mut blobs[12];
    let u = std::f64::consts::FRAC_1_SQRT_2;
    b.area_px = total.round() as u32;
    b.x_px += along * u;
    b.y_px += along * u;
    b.mu20_px2 = (var_along + var_across) / 2.0;
    b.mu02_px2 = (var_along + var_across) / 2.0;
    b.mu11_px2 = (var_along - var_across) / 2.0;
    let det = b.mu20_px2 * b.mu02_px2 - b.mu11_px2 * b.mu11_px2;
    let fill = total / (4.0 * std::f64::consts::PI * det.sqrt());
    assert!((0.6..0.8).contains(&fill), "{fill}");
    let t = track(&reference, &blobs, &TrackParams::default());
    for k in 0..25 {
        assert_eq!(
            (t.status[k], t.assignment[k]),
            (MarkerStatus::Ok, Some(k)),
            "marker {k}"
        );
    }
}
