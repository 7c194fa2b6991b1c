//! Rendered shapes of known centre, area and eccentricity (anti-aliased, 8-bit, with noise) are
//! measured within written tolerances, and the fused pass equals the reference flood fill.
//!
//! Tolerances: the thresholded boundary lies within about half a pixel of the true edge, so
//! |area − πab| ≤ 0.5 · perimeter. Binary moments carry a digitisation error that depends on
//! the shape's sub-pixel position (the renderer's own coverage centroid is exact to 0.002 px,
//! the thresholded disc of radius 8 px is off by up to 0.08 px with no noise at all), so the
//! centroid within 0.2 px with or without a 3×3 opening (the OpenCV
//! peer's max on exact ellipses); the axis ratio minor/major within
//! 0.25 / b for semi-minor axis b in pixels (half a pixel of boundary on one side of a 2b-wide
//! shape), 0.03 at b = 8 (eccentricity itself is ill-conditioned near a circle: a ratio of 0.986 already gives
//! e = 0.17), and the eccentricity of clearly elongated shapes (e > 0.5) within 0.02.

use proptest::prelude::*;
use visuotact_image::GrayImage;
use visuotact_sim::pattern::{render_markers, Look};
use visuotact_sim::render::Ellipse;
use visuotact_vision::blobs::{
    blobs_from_gray, blobs_reference, Blob, Connectivity, Level, MomentConvention,
};
use visuotact_vision::detect::{Detector, DetectorConfig};
use visuotact_vision::preprocess::PreprocessConfig;

fn perimeter(a: f64, b: f64) -> f64 {
    // Ramanujan's approximation.
    let h = ((a - b) / (a + b)).powi(2);
    std::f64::consts::PI * (a + b) * (1.0 + 3.0 * h / (10.0 + (4.0 - 3.0 * h).sqrt()))
}

fn detect_one(shapes: &[(Ellipse, Option<Ellipse>)], seed: u64, open: bool) -> Vec<Blob> {
    let look = Look {
        vignetting: 0.0,
        ..Look::GREEN_ON_DARK
    };
    let img = render_markers(160, 120, shapes, &look, seed);
    let preprocess = PreprocessConfig {
        open,
        ..PreprocessConfig::IATS
    };
    let mut det = Detector::new(DetectorConfig {
        preprocess,
        ..Default::default()
    })
    .unwrap();
    det.detect(&img)
}

#[test]
fn ellipses_of_known_moments() {
    ellipses_within(false, 0.2);
    // The 3×3 grey opening reshapes anti-aliased edges depending on the sub-pixel position;
    // the OpenCV peer doing the same shows up to 0.2 px on exact ellipses.
    ellipses_within(true, 0.2);
}

fn ellipses_within(open: bool, centroid_tol_px: f64) {
    let mut worst = (0.0f64, 0.0f64, 0.0f64);
    let mut seed = 0;
    for &(a, b) in &[
        (8.0, 8.0),
        (12.0, 7.0),
        (20.0, 10.0),
        (15.0, 6.0),
        (25.0, 24.0),
    ] {
        for k in 0..6 {
            seed += 1;
            let angle = f64::from(k) * 0.47;
            let e = Ellipse {
                cx_px: 80.3 + 0.13 * f64::from(k),
                cy_px: 59.71,
                a_px: a,
                b_px: b,
                angle_rad: angle,
            };
            let blobs = detect_one(&[(e, None)], seed, open);
            assert_eq!(
                blobs.len(),
                1,
                "ellipse {a}×{b} at {angle}: {} blobs",
                blobs.len()
            );
            let bl = blobs[0];
            let dc = (bl.x_px - e.cx_px).hypot(bl.y_px - e.cy_px);
            let da = (f64::from(bl.area_px) - e.area_px()).abs();
            let sh = bl.shape(MomentConvention::Pixel);
            let ratio = sh.minor_axis_px / sh.major_axis_px;
            let dr = (ratio - b / a).abs();
            assert!(
                dc < centroid_tol_px,
                "centroid off by {dc} px for {a}×{b} at {angle}"
            );
            assert!(
                da <= 0.5 * perimeter(a, b),
                "area {} vs {} for {a}×{b}",
                bl.area_px,
                e.area_px()
            );
            assert!(
                dr < 0.25 / b,
                "axis ratio {ratio} vs {} for {a}×{b} at {angle}",
                b / a
            );
            if e.eccentricity() > 0.5 {
                let de = (sh.eccentricity - e.eccentricity()).abs();
                assert!(
                    de < 0.02,
                    "eccentricity {} vs {} for {a}×{b}",
                    sh.eccentricity,
                    e.eccentricity()
                );
            }
            worst = (
                worst.0.max(dc),
                worst.1.max(da / e.area_px()),
                worst.2.max(dr),
            );
        }
    }
    eprintln!(
        "open {open}: worst centroid {:.4} px, area {:.3} %, axis ratio {:.4}",
        worst.0,
        100.0 * worst.1,
        worst.2
    );
}

#[test]
fn annulus_of_known_moments() {
    for (k, &(ro, ri)) in [(30.0, 22.0), (40.0, 30.0), (25.0, 15.0)]
        .iter()
        .enumerate()
    {
        let outer = Ellipse {
            cx_px: 79.6,
            cy_px: 60.2,
            a_px: ro,
            b_px: ro * 0.9,
            angle_rad: 0.3,
        };
        let inner = Ellipse {
            a_px: ri,
            b_px: ri * 0.9,
            ..outer
        };
        let blobs = detect_one(&[(outer, Some(inner))], k as u64, false);
        assert_eq!(blobs.len(), 1);
        let bl = blobs[0];
        let area = outer.area_px() - inner.area_px();
        let tol = 0.5 * (perimeter(ro, 0.9 * ro) + perimeter(ri, 0.9 * ri));
        let dc = (bl.x_px - 79.6).hypot(bl.y_px - 60.2);
        eprintln!(
            "annulus {ro}/{ri}: centre off by {dc:.4} px, area {} vs {area:.1}",
            bl.area_px
        );
        assert!(dc < 0.1, "annulus centre {} {}", bl.x_px, bl.y_px);
        assert!(
            (f64::from(bl.area_px) - area).abs() <= tol,
            "annulus area {} vs {area}",
            bl.area_px
        );
        // An annulus with equal axis ratios has the same eccentricity as its ellipses.
        assert!((bl.eccentricity() - outer.eccentricity()).abs() < 0.03);
    }
}

fn arb_image() -> impl Strategy<Value = (usize, usize, Vec<u8>)> {
    (1usize..70, 1usize..40)
        .prop_flat_map(|(w, h)| (Just(w), Just(h), prop::collection::vec(0u8..4, w * h)))
}

/// The cases' seed: fixed, so every run (CI's too) tries the same cases, unless
/// `PROPTEST_RNG_SEED` names another one for a long run (docs/failure.md; proptest reads it).
fn seed() -> proptest::test_runner::RngSeed {
    use proptest::test_runner::RngSeed;
    match ProptestConfig::default().rng_seed {
        RngSeed::Random => RngSeed::Fixed(173),
        named => named,
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 300,
        rng_seed: seed(),
        ..ProptestConfig::default()
    })]
    #[test]
    fn fused_pass_equals_reference((w, h, data) in arb_image(), t in 0u8..3, four in any::<bool>()) {
        let img = GrayImage::from_vec(w, h, data).unwrap();
        let conn = if four { Connectivity::Four } else { Connectivity::Eight };
        let fast = blobs_from_gray(&img, Level::Scalar(t), conn);
        let mask: Vec<bool> = img.as_slice().iter().map(|&v| v > t).collect();
        let slow = blobs_reference(&mask, w, h, conn);
        prop_assert_eq!(fast.len(), slow.len());
        for (a, b) in fast.iter().zip(&slow) {
            prop_assert_eq!((a.area_px, a.bbox, a.touches_border), (b.area_px, b.bbox, b.touches_border));
            prop_assert!((a.x_px - b.x_px).abs() < 1e-9 && (a.y_px - b.y_px).abs() < 1e-9);
            prop_assert!((a.mu20_px2 - b.mu20_px2).abs() < 1e-9);
            prop_assert!((a.mu02_px2 - b.mu02_px2).abs() < 1e-9);
            prop_assert!((a.mu11_px2 - b.mu11_px2).abs() < 1e-9);
        }
    }

    #[test]
    fn per_pixel_levels_equal_scalar(w in 1usize..80, h in 1usize..20, seed in any::<u64>(), t in 0u8..255) {
        let mut s = seed;
        let img = GrayImage::from_fn(w, h, |_, _| { s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407); (s >> 56) as u8 });
        let levels = vec![f32::from(t); w * h];
        let a = blobs_from_gray(&img, Level::Scalar(t), Connectivity::Eight);
        let b = blobs_from_gray(&img, Level::PerPixel(&levels), Connectivity::Eight);
        prop_assert_eq!(a, b);
    }
}
