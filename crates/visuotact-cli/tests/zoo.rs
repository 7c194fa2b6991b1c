//! Tracking on sensors the code was not written for: the simulator's zoo (TacTip-like dome
//! with a hexagonal pin array, GelSight-like dark-dot grid on a bright gel, random dots) with
//! every parameter drawn from its ranges, and seed 000's membrane, against the simulator's
//! exact per-marker truth (`visuotact check-tracking` in memory).
//!
//! Contract: every visible marker is found with its own identity in every frame whose largest
//! motion stays within `MOTION_LIMIT_PITCHES` (frames beyond it are counted apart), and the
//! mean displacement error is at most 0.05 px on grey-level frames.

use visuotact_cli::trackcheck::{check, CheckConfig, CheckReport, SimSensor, MOTION_LIMIT_PITCHES};
use visuotact_vision::detect::Centroid;
use visuotact_vision::layout::{Layout, LayoutChoice};

fn run(sensor: SimSensor, protocol: &str, touches: usize, seed: u64) -> CheckReport {
    check(&CheckConfig {
        sensor,
        protocol: protocol.to_string(),
        touches,
        seed,
        references: 10,
        detector: sensor.detector(Centroid::Grey),
        layout: LayoutChoice::Auto,
        motion_limit_pitches: MOTION_LIMIT_PITCHES,
    })
    .unwrap()
}

fn assert_tracked(what: &str, r: &CheckReport, max_err_px: f64) {
    assert_eq!(
        r.uncalibrated, 0,
        "{what}: markers visible at rest not calibrated"
    );
    assert_eq!(
        r.calibrated,
        r.sim_markers - r.uncalibrated.min(r.sim_markers),
        "{what}"
    );
    assert_eq!(
        r.lost - r.beyond_lost,
        0,
        "{what}: visible markers lost: {:#?}",
        r.examples
    );
    assert_eq!(
        r.wrong - r.beyond_wrong,
        0,
        "{what}: wrong identities: {:#?}",
        r.examples
    );
    assert!(
        r.err_mean_px <= max_err_px,
        "{what}: mean displacement error {:.4} px",
        r.err_mean_px
    );
    assert!(r.visible > 0 && r.frames > 0, "{what}: nothing checked");
}

#[test]
fn zoo_variants_keep_every_visible_marker() {
    for (name, layout) in [
        ("tactip", Layout::Hex),
        ("gelsight", Layout::Grid),
        ("dots", Layout::Irregular),
    ] {
        for variant in 1..=5 {
            let sensor = SimSensor::named(name, variant).unwrap();
            for (protocol, touches) in [("random", 16), ("shear", 24)] {
                let r = run(sensor, protocol, touches, variant);
                let what = format!("{name} variant {variant}, {protocol}");
                assert_eq!(r.layout, Some(layout), "{what}");
                assert_tracked(&what, &r, 0.05);
            }
        }
    }
}

#[test]
fn zoo_presets_on_their_grid_protocol() {
    for name in ["tactip", "gelsight", "dots"] {
        let r = run(SimSensor::named(name, 0).unwrap(), "grid", 0, 1);
        assert_tracked(&format!("{name} preset, grid"), &r, 0.05);
        // The grid protocol presses to the skin's limit.
        assert!(r.frames >= 125, "{name}: {} frames", r.frames);
    }
}

#[test]
fn seed_000_membrane_five_seeds() {
    for seed in 1..=5 {
        let sensor = SimSensor::named("iats", 0).unwrap();
        for (protocol, touches) in [("random", 24), ("shear", 24)] {
            let r = run(sensor, protocol, touches, seed);
            assert_tracked(&format!("iats seed {seed}, {protocol}"), &r, 0.05);
        }
    }
}

#[test]
fn binarised_tactip_frames_are_tracked_at_the_digitisation_floor() {
    // Black-and-white frames (as published TacTip data sets) hold no grey level to refine a
    // centroid: a binary disc of radius 5 px has an RMS centroid error of ≈ 0.1 px from
    // pixel digitisation alone, so the bound here is that floor, not 0.05 px.
    for variant in [0, 2] {
        let mut sensor = SimSensor::named("tactip", variant).unwrap();
        if let SimSensor::Zoo(c) = &mut sensor {
            c.binarise = true;
        }
        let r = run(sensor, "shear", 16, 7);
        assert_tracked(&format!("binarised tactip variant {variant}"), &r, 0.15);
    }
}
