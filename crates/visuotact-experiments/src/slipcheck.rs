//! Slip detection on the simulator, where the onset is known: grasps of the GelSight-like zoo
//! sensor (`visuotact_sim::protocol::zoo_slip`: presses, drags under the friction limit,
//! twists, and slips past it) rendered, tracked from a calibration on rest frames, and run
//! through a slip detector frame by frame.
//!
//! Contract: [`check_grasp`] reports, per grasp, the frame the whole contact started to slide
//! (the truth), the first frame the detector called `slip`, and the state at the end; the
//! latency of a detected slip is the difference.

use rayon::prelude::*;
use visuotact_pipeline::slip::{detect, SlipDetector, SlipState, TrackedFrame, TrackedSequence};
use visuotact_sim::protocol::{zoo_slip, GraspKind};
use visuotact_sim::zoo::{render, ZooConfig, ZooTouch};
use visuotact_sim::SimError;
use visuotact_vision::calibration::{calibrate, CalibrationConfig, CalibrationError};
use visuotact_vision::detect::Centroid;
use visuotact_vision::features::{FeatureExtractor, FeatureSet, FrameFeatures};
use visuotact_vision::imprint::{ImprintFollower, ImprintParams};
use visuotact_vision::options::DetectorOptions;

use crate::trackcheck::SimSensor;

/// Why a simulated grasp could not be checked.
#[derive(Debug, thiserror::Error)]
pub enum SlipCheckError {
    /// The simulator refused a touch.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// The rest frames did not calibrate.
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
    /// A frame did not match the sensor.
    #[error("frame {frame}: {why}")]
    Frame {
        /// The frame.
        frame: usize,
        /// Why.
        why: String,
    },
}

/// One simulated grasp's outcome.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GraspOutcome {
    /// What the grasp did.
    pub kind: GraspKind,
    /// Its seed.
    pub seed: u64,
    /// The frame the whole contact started to slide (the truth), if it did.
    pub slip_frame: Option<usize>,
    /// The first frame the detector called `slip`.
    pub first_alarm: Option<usize>,
    /// The detector's state at the last frame (the sequence's verdict).
    pub final_state: SlipState,
}

/// Renders, tracks and runs `detector` over one grasp of `kind` on `cfg` (`frames` frames at
/// 25 fps, seeded by `seed`).
pub fn check_grasp(
    cfg: &ZooConfig,
    kind: GraspKind,
    frames: usize,
    seed: u64,
    detector: &SlipDetector,
) -> Result<GraspOutcome, SlipCheckError> {
    let grasp = zoo_slip(cfg, kind, frames, seed);
    let rest: Vec<_> = (0..5)
        .map(|k| render(cfg, &ZooTouch::default(), seed.wrapping_mul(31) + k).map(|r| r.0))
        .collect::<Result<_, _>>()?;
    let ids: Vec<String> = (0..5).map(|k| format!("r{k}")).collect();
    let (det, _) =
        DetectorOptions::default().sized(SimSensor::Zoo(*cfg).detector(Centroid::Grey), &rest[0]);
    let set = FeatureSet::parse("x,y").unwrap_or(FeatureSet::ALL);
    let (cal, _) = calibrate(
        ids.iter().map(String::as_str).zip(rest.iter()),
        &CalibrationConfig {
            detector: det,
            features: set,
            ..Default::default()
        },
    )?;
    let images: Vec<_> = grasp
        .touches
        .par_iter()
        .enumerate()
        .map(|(k, t)| render(cfg, t, seed.wrapping_mul(1000) + k as u64).map(|r| r.0))
        .collect::<Result<_, _>>()?;
    let mut seq = TrackedSequence {
        markers_px: cal.markers.iter().map(|m| (m.x_px, m.y_px)).collect(),
        pitch_px: cal.pitch_px,
        frames: Vec::with_capacity(images.len()),
    };
    let n = cal.markers.len();
    let mut ex = FeatureExtractor::new(cal, set).map_err(|e| SlipCheckError::Frame {
        frame: 0,
        why: e.to_string(),
    })?;
    ex.set_temporal_prior(true);
    let mut f = FrameFeatures::default();
    let mut imprint = detector
        .reads_imprint()
        .then(|| ImprintFollower::new(ImprintParams::DEFAULT, 1));
    for (k, img) in images.iter().enumerate() {
        ex.extract_into(img, &mut f)
            .map_err(|e| SlipCheckError::Frame {
                frame: k,
                why: e.to_string(),
            })?;
        let mut d = Vec::with_capacity(n);
        visuotact_pipeline::slip::displacements_into(&f, set, n, &mut d);
        seq.frames.push(TrackedFrame {
            timestamp_s: k as f64 / 25.0,
            id: k.to_string(),
            displacement_px: d,
            imprint_slide_px: imprint.as_mut().map_or((0.0, 0.0), |f| f.update(img)),
        });
    }
    let v = detect(&seq, detector);
    Ok(GraspOutcome {
        kind,
        seed,
        slip_frame: grasp.slip_frame,
        first_alarm: v.frames.iter().position(|f| f.state == SlipState::Slip),
        final_state: v.frames.last().map_or(SlipState::Stick, |f| f.state),
    })
}
