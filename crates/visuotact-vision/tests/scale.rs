//! A sensor calibrated with its marker pitch in millimetres (`calibrate --pitch-mm`) gives its
//! displacements in millimetres beside the pixels. On the simulated seed-000 membrane seen
//! through a lens without distortion (one scale holds across the image: distance / focal
//! length), the scale found from the measured pitch is within 1 % of the camera's, and the
//! displacements in mm of dragged markers are within 1 % of their true pixel displacements ×
//! that scale (least-squares ratio over the markers that moved more than a pixel; each marker
//! within 0.25 px × scale).

use visuotact_sim::camera::Camera;
use visuotact_sim::iats::{render, IatsConfig, Touch};
use visuotact_vision::calibration::{calibrate, Preset, SensorCalibration};
use visuotact_vision::features::{FeatureExtractor, FeatureSet, MmColumns, FIELD_COLUMNS_MM};

/// Seed 000's membrane: 13 × 9 markers, 5 mm apart along the rows (5.625 mm down the columns),
/// 36 mm from a 330 px focal length, here without barrel distortion.
fn membrane() -> IatsConfig {
    IatsConfig {
        camera: Camera {
            k1: 0.0,
            k2: 0.0,
            ..Camera::WEBCAM_640X480
        },
        ..IatsConfig::SEED000
    }
}

fn calibrated(cfg: &IatsConfig) -> SensorCalibration {
    let rest: Vec<_> = (0..4)
        .map(|s| render(cfg, &Touch::default(), 100 + s).unwrap().0)
        .collect();
    let ids = ["r0", "r1", "r2", "r3"];
    let (cal, _) = calibrate(ids.into_iter().zip(rest.iter()), &Preset::Iats.config()).unwrap();
    assert_eq!(cal.markers.len(), cfg.rows * cfg.cols);
    cal
}

#[test]
fn the_pitch_in_mm_gives_the_cameras_scale_and_displacements_in_mm() {
    let cfg = membrane();
    let mut cal = calibrated(&cfg);
    assert_eq!(cal.mm_per_px(), None);
    // The nearest neighbours are the row neighbours, 60 mm / 12 = 5 mm apart.
    cal.set_pitch_mm(cfg.pitch_x_mm()).unwrap();
    let scale = cal.mm_per_px().unwrap();
    let truth_scale = cfg.camera_distance_mm / cfg.camera.fx_px;
    assert!(
        (scale / truth_scale - 1.0).abs() < 0.01,
        "{scale} mm/px against the camera's {truth_scale}"
    );
    // The scale travels in the sensor file.
    let back = SensorCalibration::from_json(&cal.to_json(), "scale test").unwrap();
    assert_eq!(back.mm_per_px(), Some(scale));

    let mut ex = FeatureExtractor::new(cal.clone(), FeatureSet::IATS).unwrap();
    let names = ex.column_names();
    let mm = MmColumns::new(&names, scale);
    assert!(mm.names().iter().any(|n| n == "m000_dx_mm"));
    assert!(mm.names().iter().any(|n| n == "m116_darea_mm2"));
    assert!(FIELD_COLUMNS_MM
        .iter()
        .all(|c| mm.names().iter().any(|n| n == c)));
    let at = |name: &str| mm.names().iter().position(|n| n == name).unwrap();
    let (_, rest) = render(&cfg, &Touch::default(), 0).unwrap();
    let touches = [
        (30.0, 22.0, 1.5, 2.0, -1.0),
        (15.0, 10.0, 2.5, -1.5, 1.5),
        (45.0, 30.0, 3.0, 0.0, 2.5),
    ];
    let (mut dot, mut sq, mut worst) = (0.0, 0.0, 0.0f64);
    let mut moved = 0;
    for (k, &(x_mm, y_mm, depth_mm, shear_x_mm, shear_y_mm)) in touches.iter().enumerate() {
        let touch = Touch {
            x_mm,
            y_mm,
            depth_mm,
            shear_x_mm,
            shear_y_mm,
        };
        let (img, truth) = render(&cfg, &touch, 10 + k as u64).unwrap();
        let f = ex.extract(&img).unwrap();
        let mut values = Vec::new();
        mm.values_into(&f.values, &mut values);
        assert_eq!(values.len(), mm.names().len());
        for m in &cal.markers {
            let i = m.row as usize * cfg.cols + m.col as usize;
            let true_px = (truth[i].x_px - rest[i].x_px, truth[i].y_px - rest[i].y_px);
            let got_mm = (
                values[at(&format!("m{:03}_dx_mm", m.id))],
                values[at(&format!("m{:03}_dy_mm", m.id))],
            );
            if !(got_mm.0.is_finite() && got_mm.1.is_finite()) {
                continue;
            }
            let want_mm = (true_px.0 * truth_scale, true_px.1 * truth_scale);
            worst = worst
                .max((got_mm.0 - want_mm.0).abs())
                .max((got_mm.1 - want_mm.1).abs());
            if true_px.0.hypot(true_px.1) > 1.0 {
                moved += 1;
                dot += got_mm.0 * want_mm.0 + got_mm.1 * want_mm.1;
                sq += want_mm.0 * want_mm.0 + want_mm.1 * want_mm.1;
            }
        }
    }
    let ratio = dot / sq;
    println!(
        "scale {scale:.6} mm/px (camera {truth_scale:.6}); displacement ratio {ratio:.5} over {moved} markers; worst marker {worst:.4} mm"
    );
    assert!(moved > 30, "only {moved} markers moved more than a pixel");
    assert!(
        (ratio - 1.0).abs() < 0.01,
        "measured / true displacement in mm: {ratio} over {moved} markers"
    );
    assert!(
        worst < 0.25 * truth_scale,
        "a marker's displacement is {worst} mm off"
    );
}

#[test]
fn a_pitch_that_is_not_a_positive_length_is_refused() {
    let mut cal = calibrated(&membrane());
    for bad in [0.0, -2.0, f64::NAN, f64::INFINITY] {
        let e = cal.set_pitch_mm(bad).unwrap_err().to_string();
        assert!(e.contains("pitch"), "{e}");
        assert_eq!(cal.mm_per_px(), None);
    }
}

#[test]
fn mm_twins_scale_lengths_once_and_areas_twice() {
    let names: Vec<String> = [
        "m003_dx_px",
        "m003_dy_px",
        "m003_darea_px",
        "m003_decc",
        "field_rms_px",
        "field_cx_px",
    ]
    .map(String::from)
    .to_vec();
    let mm = MmColumns::new(&names, 0.5);
    assert_eq!(
        mm.names(),
        [
            "m003_dx_mm",
            "m003_dy_mm",
            "m003_darea_mm2",
            "field_rms_mm",
            "field_cx_mm"
        ]
    );
    let mut out = vec![7.0];
    mm.values_into(&[2.0, -4.0, 8.0, 0.3, f64::NAN, 10.0], &mut out);
    assert_eq!(out.len(), 6);
    assert_eq!(out[..4], [7.0, 1.0, -2.0, 2.0]);
    assert!(out[4].is_nan());
    assert_eq!(out[5], 5.0);
    assert!(MmColumns::default().names().is_empty());
}
