//! How well the marker pipeline follows a simulated sensor, against the simulator's exact
//! per-marker truth (`visuotact check-tracking`).
//!
//! For a sensor (`iats` or a zoo family, preset or drawn variant) and a protocol, frames are
//! rendered in memory, the sensor is calibrated from rest frames with the layout recognised,
//! and every touch frame is tracked on its own. Each calibrated marker is paired with the
//! simulator's marker nearest to it at rest; then per frame and marker:
//! - a marker the simulator calls *visible* (wholly in view and a blob of its own) that the
//!   tracker does not report `ok` is **lost**;
//! - a marker reported `ok` whose measured position is nearer another marker's true position
//!   than its own, or off its own by over half its spacing, has a **wrong identity**;
//! - the **displacement error** is `|(measured − reference) − (true − true at rest)|` over the
//!   visible markers reported `ok`.
//!
//! A frame's motion is the largest true displacement of a visible marker; the lost markers in
//! frames within the motion limit are also counted apart where a marker in view but hidden
//! (behind a neighbour, or squeezed to a sliver) moved beyond it.

use rayon::prelude::*;
use visuotact_image::RgbImage;
use visuotact_sim::iats::{IatsConfig, Touch};
use visuotact_sim::protocol;
use visuotact_sim::zoo::{self, ZooConfig, ZooKind, ZooTouch};
use visuotact_sim::SimError;
use visuotact_vision::calibration::{
    calibrate, CalibrationConfig, CalibrationError, Preset, SensorCalibration,
};
use visuotact_vision::detect::{BlobFilter, Centroid, DetectorConfig};
use visuotact_vision::features::{FeatureExtractor, FeatureSet, FrameFeatures, FrameSizeError};
use visuotact_vision::layout::{Layout, LayoutChoice};
use visuotact_vision::options::DetectorOptions;
use visuotact_vision::preprocess::CircleMask;
use visuotact_vision::track::TrackParams;

/// Why a check could not run.
#[derive(Debug, thiserror::Error)]
pub enum CheckError {
    /// No simulated sensor has this name.
    #[error("unknown sensor {0:?}: expected iats, tactip, tactip-small, gelsight or dots")]
    UnknownSensor(String),
    /// The protocol is not one of the sensor's.
    #[error("protocol {name:?}: expected {expected}")]
    UnknownProtocol {
        /// The name asked for.
        name: String,
        /// The protocols there are, listed.
        expected: String,
    },
    /// The simulator refused a frame.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// Calibration failed on the rest frames.
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
    /// The feature extractor refused the calibration.
    #[error(transparent)]
    Features(#[from] visuotact_vision::ConfigError),
    /// A frame's size differs from the reference's.
    #[error(transparent)]
    FrameSize(#[from] FrameSizeError),
}

/// A simulated sensor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SimSensor {
    /// Seed 000's membrane (or a variant).
    Iats(IatsConfig),
    /// A zoo sensor.
    Zoo(ZooConfig),
}

impl SimSensor {
    /// The sensor called `name` (`iats`, `tactip`, `tactip-small`, `gelsight`, `dots`), variant `variant`
    /// (0: the preset).
    pub fn named(name: &str, variant: u64) -> Result<Self, CheckError> {
        if name == "iats" {
            return Ok(Self::Iats(IatsConfig::variant(variant)));
        }
        ZooKind::from_name(name)
            .map(|k| Self::Zoo(ZooConfig::variant(k, variant)))
            .ok_or_else(|| CheckError::UnknownSensor(name.to_string()))
    }

    /// Whether the markers are brighter than the skin around them.
    fn bright_markers(&self) -> bool {
        let look = match self {
            SimSensor::Iats(c) => c.look,
            SimSensor::Zoo(c) => c.look,
        };
        let luma = |c: [f32; 3]| 0.2989 * c[0] + 0.5870 * c[1] + 0.1140 * c[2];
        luma(look.marker) > luma(look.background)
    }

    /// The detector a user would pick for it: the iats preset (green channel, sampled Otsu)
    /// for bright markers, the dark-markers preset (inverted luma, adaptive) for dark ones,
    /// with grey-weighted centroids when asked.
    /// A circular view (a TacTip's rim) is masked at its edge, as `--circle`
    /// does, so markers cut by the rim count as cut by the border.
    pub fn detector(&self, centroid: Centroid) -> DetectorConfig {
        let preset = if self.bright_markers() {
            Preset::Iats
        } else {
            Preset::DarkMarkers
        };
        let mut preprocess = preset.config().detector.preprocess;
        if let SimSensor::Zoo(c) = self {
            preprocess.circle = c.aperture_px().map(|((cx, cy), r)| CircleMask {
                cx_px: cx,
                cy_px: cy,
                radius_px: r,
            });
        }
        DetectorConfig {
            preprocess,
            filter: BlobFilter::DEFAULT,
            centroid,
        }
    }
}

/// One check.
#[derive(Clone, Debug)]
pub struct CheckConfig {
    /// The sensor.
    pub sensor: SimSensor,
    /// `grid`, `random` or `shear`.
    pub protocol: String,
    /// Touches for `random` and `shear`.
    pub touches: usize,
    /// Seed of the touches and the noise.
    pub seed: u64,
    /// Rest frames averaged into the reference.
    pub references: usize,
    /// The touch the reference frames are made under (zoo sensors only): `None` at rest, or a
    /// touch, as a user calibrates a sensor that is never out of contact (the real 331-pin set).
    /// Motion is then measured from that reference.
    pub reference_touch: Option<ZooTouch>,
    /// How markers are detected.
    pub detector: DetectorConfig,
    /// The layout calibration uses.
    pub layout: LayoutChoice,
    /// Frames where some visible marker moves farther than this, in pitches, are also counted
    /// apart (`beyond_*`): order-free tracking is specified up to this motion.
    pub motion_limit_pitches: f64,
    /// 0: every frame tracked on its own (order-free). N > 0: each touch is built up from rest
    /// in N frames — pressed over the first third, then dragged and twisted — and followed
    /// with the temporal prior, as `--temporal` follows a video; every frame is checked.
    pub followed_steps: usize,
    /// The tracker's settings.
    pub track: TrackParams,
}

impl CheckConfig {
    /// A check of `sensor` through `protocol` as the tests and the scorecard run it: ten rest
    /// frames averaged into the reference, the sensor's own detector with grey-level
    /// centroids, the layout recognised, [`MOTION_LIMIT_PITCHES`], every frame order-free,
    /// the tracker's defaults.
    pub fn zoo(sensor: SimSensor, protocol: &str, touches: usize, seed: u64) -> Self {
        Self {
            sensor,
            protocol: protocol.to_string(),
            touches,
            seed,
            references: 10,
            reference_touch: None,
            detector: sensor.detector(Centroid::Grey),
            layout: LayoutChoice::Auto,
            motion_limit_pitches: MOTION_LIMIT_PITCHES,
            followed_steps: 0,
            track: TrackParams::DEFAULT,
        }
    }
}

/// The motion up to which order-free tracking must keep every visible marker, in pitches.
pub const MOTION_LIMIT_PITCHES: f64 = 1.5;

/// What a check measured.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CheckReport {
    /// Markers the simulator draws.
    pub sim_markers: usize,
    /// Markers calibrated.
    pub calibrated: usize,
    /// Simulated markers visible at rest that calibration did not number.
    pub uncalibrated: usize,
    /// The layout recognised.
    pub layout: Option<Layout>,
    /// Median marker spacing, pixels.
    pub pitch_px: f64,
    /// Touch frames tracked.
    pub frames: usize,
    /// (frame, marker) pairs where the marker is visible.
    pub visible: usize,
    /// Visible markers not reported `ok`.
    pub lost: usize,
    /// Markers reported `ok` with another marker's blob.
    pub wrong: usize,
    /// Markers reported `ok` although not visible (cut by the border, touching a neighbour).
    pub ok_not_visible: usize,
    /// Mean displacement error over visible markers reported `ok`, pixels.
    pub err_mean_px: f64,
    /// 99th percentile of it, pixels.
    pub err_p99_px: f64,
    /// Largest, pixels.
    pub err_max_px: f64,
    /// The first few problems, wrong identities first, for the record: `frame k: marker m …`.
    pub examples: Vec<String>,
    /// The largest motion of a visible marker in any frame, pitches.
    pub max_motion_pitches: f64,
    /// Frames with a visible marker moving beyond `motion_limit_pitches`.
    pub beyond_frames: usize,
    /// Of `lost`, those in such frames.
    pub beyond_lost: usize,
    /// Of `wrong`, those in such frames.
    pub beyond_wrong: usize,
    /// Of `lost` in the frames within `motion_limit_pitches`, those in frames where a marker
    /// in view but not visible (hidden behind a neighbour, or squeezed to a sliver) moved
    /// beyond it: the skin moved that far, under a neighbour.
    pub hidden_beyond_lost: usize,
    /// The same counts per motion band ([`MOTION_BANDS`]: the frame's largest motion of a
    /// visible marker under 0.5, 0.5–1, 1–1.5 and over 1.5 pitches).
    pub bands: [BandCounts; 4],
    /// Per touch frame in order: its largest motion of a visible marker (pitches) and its
    /// counts (`frames` 1), to find the frames a problem is in.
    pub per_frame: Vec<(f64, BandCounts)>,
}

/// Upper edges of the motion bands, pitches (the last band has none).
pub const MOTION_BANDS: [f64; 3] = [0.5, 1.0, 1.5];

/// What one motion band of a check counted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BandCounts {
    /// Frames in the band.
    pub frames: usize,
    /// Visible marker-frames.
    pub visible: usize,
    /// Visible markers reported lost or merged.
    pub lost: usize,
    /// Visible markers reported ambiguous.
    pub ambiguous: usize,
    /// Markers reported with a position that is another marker's or over half a pitch off.
    pub wrong: usize,
}

impl BandCounts {
    /// Adds `o`'s counts.
    pub fn add(&mut self, o: &BandCounts) {
        self.frames += o.frames;
        self.visible += o.visible;
        self.lost += o.lost;
        self.ambiguous += o.ambiguous;
        self.wrong += o.wrong;
    }
}

/// The band of a frame whose largest motion is `pitches`.
pub fn band_of(pitches: f64) -> usize {
    MOTION_BANDS
        .iter()
        .position(|&edge| pitches < edge)
        .unwrap_or(MOTION_BANDS.len())
}

/// Per simulated marker: position (pixels), area (pixels), visible, in view.
type Truth = Vec<(f64, f64, f64, bool, bool)>;

/// A touch of either kind, with its depth for the record.
enum AnyTouch {
    Iats(Touch),
    Zoo(ZooTouch),
}

impl AnyTouch {
    /// The touch built up from rest in `n` frames: the press over the first third, then the
    /// drag and twist; the last frame is the touch itself.
    fn built_up(&self, n: usize) -> Vec<AnyTouch> {
        let pressing = (n / 3).max(1) as f64;
        (1..=n)
            .map(|k| {
                let k = k as f64;
                let press = (k / pressing).min(1.0);
                let drag = if n as f64 > pressing {
                    ((k - pressing) / (n as f64 - pressing)).clamp(0.0, 1.0)
                } else {
                    1.0
                };
                match self {
                    AnyTouch::Iats(t) => AnyTouch::Iats(t.partway(press, drag)),
                    AnyTouch::Zoo(t) => AnyTouch::Zoo(t.partway(press, drag)),
                }
            })
            .collect()
    }

    fn depth_mm(&self) -> f64 {
        match self {
            AnyTouch::Iats(t) => t.depth_mm,
            AnyTouch::Zoo(t) => t.depth_mm,
        }
    }
}

fn touches(c: &CheckConfig) -> Result<Vec<AnyTouch>, CheckError> {
    let (name, n, seed) = (c.protocol.as_str(), c.touches, c.seed);
    let (touches, known): (Option<Vec<AnyTouch>>, &[&str]) = match &c.sensor {
        SimSensor::Iats(s) => (
            protocol::iats_named(s, name, n, seed)
                .map(|t| t.into_iter().map(AnyTouch::Iats).collect()),
            &protocol::IATS_PROTOCOLS,
        ),
        SimSensor::Zoo(s) => (
            protocol::zoo_named(s, name, n, seed)
                .map(|t| t.into_iter().map(AnyTouch::Zoo).collect()),
            &protocol::ZOO_PROTOCOLS,
        ),
    };
    touches.ok_or_else(|| CheckError::UnknownProtocol {
        name: name.to_string(),
        expected: protocol::names_listed(known),
    })
}

fn render(sensor: &SimSensor, touch: &AnyTouch, seed: u64) -> Result<(RgbImage, Truth), SimError> {
    match (sensor, touch) {
        (SimSensor::Iats(c), AnyTouch::Iats(t)) => {
            let (img, truth) = visuotact_sim::iats::render(c, t, seed)?;
            Ok((
                img,
                truth
                    .iter()
                    .map(|m| (m.x_px, m.y_px, m.area_px, m.visible, m.fully_in_view))
                    .collect(),
            ))
        }
        (SimSensor::Zoo(c), AnyTouch::Zoo(t)) => {
            let (img, truth) = zoo::render(c, t, seed)?;
            Ok((
                img,
                truth
                    .iter()
                    .map(|m| (m.x_px, m.y_px, m.area_px, m.visible, m.in_view))
                    .collect(),
            ))
        }
        _ => Err(SimError::WrongSensor("a touch of another sensor")),
    }
}

/// The touch the reference is made under: `c.reference_touch`, or rest.
fn reference(c: &CheckConfig) -> Result<AnyTouch, CheckError> {
    match (&c.sensor, c.reference_touch) {
        (SimSensor::Iats(_), None) => Ok(AnyTouch::Iats(Touch::default())),
        (SimSensor::Iats(_), Some(_)) => Err(CheckError::Sim(SimError::WrongSensor(
            "a reference in contact is for zoo sensors only",
        ))),
        (SimSensor::Zoo(_), t) => Ok(AnyTouch::Zoo(t.unwrap_or_default())),
    }
}

/// Calibrates on rendered rest frames and tracks every touch frame against the truth.
pub fn check(c: &CheckConfig) -> Result<CheckReport, CheckError> {
    let seed_of = |k: u64| visuotact_sim::rig::frame_seed(c.seed, k);
    let reference = reference(c)?;
    let refs: Vec<(RgbImage, Truth)> = (0..c.references.max(1) as u64)
        .into_par_iter()
        .map(|k| render(&c.sensor, &reference, seed_of(k)))
        .collect::<Result<_, SimError>>()?;
    let ids: Vec<String> = (0..refs.len()).map(|k| format!("ref{k}")).collect();
    // The opening and smallest blob sized from the markers, as `calibrate` does.
    let (detector, _) = DetectorOptions::default().sized(c.detector.clone(), &refs[0].0);
    let (cal, _) = calibrate(
        ids.iter()
            .map(String::as_str)
            .zip(refs.iter().map(|r| &r.0)),
        &CalibrationConfig {
            detector,
            layout: c.layout,
            features: FeatureSet::ALL,
            track: c.track,
        },
    )?;
    let ref_truth = &refs[0].1;
    let pairing = pair(&cal, ref_truth);
    let mut report = CheckReport {
        sim_markers: ref_truth.len(),
        calibrated: cal.markers.len(),
        layout: Some(cal.layout),
        pitch_px: cal.pitch_px,
        ..Default::default()
    };
    let mut taken = vec![false; ref_truth.len()];
    for t in pairing.iter().flatten() {
        taken[*t] = true;
    }
    report.uncalibrated = ref_truth
        .iter()
        .zip(&taken)
        .filter(|(t, k)| t.3 && !**k)
        .count();
    let touches = touches(c)?;
    let run = Run {
        c,
        cal: &cal,
        pairing: &pairing,
        rest: ref_truth,
        first: c.references.max(1) as u64,
    };
    let per_frame = if c.followed_steps > 0 {
        report.frames = touches.len() * c.followed_steps;
        run.followed(&touches)?
    } else {
        report.frames = touches.len();
        run.order_free(&touches)?
    };
    report.add(per_frame, c.motion_limit_pitches);
    Ok(report)
}

/// What tracking the touches of one check needs.
struct Run<'a> {
    c: &'a CheckConfig,
    cal: &'a SensorCalibration,
    pairing: &'a [Option<usize>],
    rest: &'a Truth,
    /// Seed index of the first touch frame (after the rest frames).
    first: u64,
}

impl Run<'_> {
    fn check_frame(
        &self,
        ex: &mut FeatureExtractor,
        touch: &AnyTouch,
        frame: usize,
    ) -> Result<FrameCheck, CheckError> {
        let seed = visuotact_sim::rig::frame_seed(self.c.seed, self.first + frame as u64);
        let (img, truth) = render(&self.c.sensor, touch, seed)?;
        let f = ex.extract(&img)?;
        Ok(frame_check(
            self.cal,
            self.pairing,
            self.rest,
            &truth,
            &f,
            frame,
            touch.depth_mm(),
        ))
    }

    /// Every frame on its own, in parallel batches, each thread with its own extractor.
    fn order_free(&self, touches: &[AnyTouch]) -> Result<Vec<FrameCheck>, CheckError> {
        touches
            .par_iter()
            .enumerate()
            .map_init(
                || FeatureExtractor::new(self.cal.clone(), FeatureSet::ALL),
                |ex, (k, t)| {
                    let ex = ex.as_mut().map_err(|e| e.clone())?;
                    self.check_frame(ex, t, k)
                },
            )
            .collect()
    }

    /// Each touch built up in `followed_steps` frames and followed with the temporal prior;
    /// touches in parallel, each with its own extractor.
    fn followed(&self, touches: &[AnyTouch]) -> Result<Vec<FrameCheck>, CheckError> {
        let n = self.c.followed_steps;
        let per_touch: Vec<Vec<FrameCheck>> = touches
            .par_iter()
            .enumerate()
            .map(|(k, t)| -> Result<Vec<FrameCheck>, CheckError> {
                let mut ex = FeatureExtractor::new(self.cal.clone(), FeatureSet::ALL)?;
                ex.set_temporal_prior(true);
                t.built_up(n)
                    .iter()
                    .enumerate()
                    .map(|(s, step)| self.check_frame(&mut ex, step, k * n + s))
                    .collect()
            })
            .collect::<Result<_, CheckError>>()?;
        Ok(per_touch.into_iter().flatten().collect())
    }
}

impl CheckReport {
    /// The header of [`CheckReport::tsv_row`]'s table.
    pub const TSV_HEADER: &'static str = "sensor\tvariant\tlayout\tmarkers\tcalibrated\tuncalibrated\tframes\tvisible\tlost\twrong\terr_mean_px\terr_p99_px\terr_max_px\tmax_motion_pitch\tbeyond_frames\tbeyond_lost\tbeyond_wrong\thidden_beyond_lost";

    /// This report as one tab-separated row for sensor `name`, variant `variant`.
    pub fn tsv_row(&self, name: &str, variant: u64) -> String {
        let r = self;
        format!(
            "{name}\t{variant}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{:.4}\t{:.4}\t{:.4}\t{:.2}\t{}\t{}\t{}\t{}",
            r.layout.map_or("-", Layout::name),
            r.sim_markers,
            r.calibrated,
            r.uncalibrated,
            r.frames,
            r.visible,
            r.lost,
            r.wrong,
            r.err_mean_px,
            r.err_p99_px,
            r.err_max_px,
            r.max_motion_pitches,
            r.beyond_frames,
            r.beyond_lost,
            r.beyond_wrong,
            r.hidden_beyond_lost
        )
    }

    /// Adds the frames' checks: counts, the error percentiles, the first examples.
    fn add(&mut self, per_frame: Vec<FrameCheck>, motion_limit_pitches: f64) {
        let report = self;
        let mut errs: Vec<f64> = Vec::new();
        // Wrong identities are the worst problem: they are listed first.
        let mut wrong_examples: Vec<String> = Vec::new();
        for fc in per_frame {
            report.max_motion_pitches = report.max_motion_pitches.max(fc.max_motion);
            if fc.max_motion > motion_limit_pitches {
                report.beyond_frames += 1;
                report.beyond_lost += fc.lost;
                report.beyond_wrong += fc.wrong;
            } else if fc.max_motion_in_view > motion_limit_pitches {
                report.hidden_beyond_lost += fc.lost;
            }
            let counts = BandCounts {
                frames: 1,
                visible: fc.visible,
                lost: fc.lost - fc.ambiguous,
                ambiguous: fc.ambiguous,
                wrong: fc.wrong,
            };
            report.bands[band_of(fc.max_motion)].add(&counts);
            report.per_frame.push((fc.max_motion, counts));
            report.visible += fc.visible;
            report.lost += fc.lost;
            report.wrong += fc.wrong;
            report.ok_not_visible += fc.ok_not_visible;
            errs.extend(fc.errs);
            for e in fc.wrong_examples {
                if wrong_examples.len() < 10 {
                    wrong_examples.push(e);
                }
            }
            for e in fc.examples {
                if report.examples.len() < 10 {
                    report.examples.push(e);
                }
            }
        }
        let others = std::mem::take(&mut report.examples);
        report.examples = wrong_examples;
        let room = 10usize.saturating_sub(report.examples.len());
        report.examples.extend(others.into_iter().take(room));
        errs.sort_by(f64::total_cmp);
        if !errs.is_empty() {
            report.err_mean_px = errs.iter().sum::<f64>() / errs.len() as f64;
            report.err_p99_px = errs[((errs.len() - 1) as f64 * 0.99).round() as usize];
            report.err_max_px = *errs.last().unwrap_or(&0.0);
        }
    }
}

/// Per calibrated marker, the simulated marker nearest to it at rest (within half its
/// spacing), if any.
fn pair(cal: &SensorCalibration, rest: &Truth) -> Vec<Option<usize>> {
    cal.markers
        .iter()
        .map(|m| {
            rest.iter()
                .enumerate()
                .filter(|(_, t)| t.0.is_finite())
                .map(|(j, t)| (j, (t.0 - m.x_px).hypot(t.1 - m.y_px)))
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .filter(|&(_, d)| d < 0.5 * cal.pitch_px)
                .map(|(j, _)| j)
        })
        .collect()
}

#[derive(Default)]
struct FrameCheck {
    max_motion: f64,
    /// The largest motion of a marker in view, visible or not, in pitches.
    max_motion_in_view: f64,
    visible: usize,
    lost: usize,
    /// Of `lost`, those reported ambiguous.
    ambiguous: usize,
    wrong: usize,
    ok_not_visible: usize,
    errs: Vec<f64>,
    examples: Vec<String>,
    wrong_examples: Vec<String>,
}

fn frame_check(
    cal: &SensorCalibration,
    pairing: &[Option<usize>],
    rest: &Truth,
    now: &Truth,
    f: &FrameFeatures,
    k: usize,
    depth_mm: f64,
) -> FrameCheck {
    let mut out = FrameCheck::default();
    let per = FeatureSet::ALL.per_marker();
    // The largest true displacement of a visible marker, and of one in view, in pitches.
    let largest_motion = |counts: &dyn Fn(usize) -> bool| {
        pairing
            .iter()
            .filter_map(|t| *t)
            .filter(|&t| counts(t))
            .map(|t| (now[t].0 - rest[t].0).hypot(now[t].1 - rest[t].1) / cal.pitch_px)
            .fold(0.0, f64::max)
    };
    let max_disp = largest_motion(&|t| now[t].3);
    out.max_motion = max_disp;
    out.max_motion_in_view = largest_motion(&|t| now[t].4);
    for (i, (m, t)) in cal.markers.iter().zip(pairing).enumerate() {
        let Some(t) = *t else { continue };
        let visible = now[t].3;
        let ok = f.status[i].has_position();
        if visible {
            out.visible += 1;
        }
        if !ok {
            if visible {
                out.lost += 1;
                if f.status[i] == visuotact_vision::track::MarkerStatus::Ambiguous {
                    out.ambiguous += 1;
                }
                out.examples.push(format!(
                    "frame {k} (depth {depth_mm:.2} mm, motion up to {max_disp:.2} pitch): marker {i} {} though visible",
                    f.status[i].name()
                ));
            }
            continue;
        }
        let (dx, dy) = (f.values[per * i], f.values[per * i + 1]);
        let (x, y) = (m.x_px + dx, m.y_px + dy);
        let own = (x - now[t].0).hypot(y - now[t].1);
        // The simulated marker nearest the measurement: another one nearer than its own is a
        // wrong identity.
        let (u, du) = now
            .iter()
            .enumerate()
            .filter(|(_, o)| o.0.is_finite())
            .map(|(j, o)| (j, (x - o.0).hypot(y - o.1)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or((t, own));
        let nearer = u != t && du < own;
        if nearer || own > 0.5 * cal.pitch_px {
            out.wrong += 1;
            // The calibrated marker the nearest simulated one is.
            let whose = pairing.iter().position(|&p| p == Some(u)).map_or_else(
                || "uncalibrated".to_string(),
                |q| format!("marker {q}, {}", f.status[q].name()),
            );
            out.wrong_examples.push(format!(
                "frame {k} (depth {depth_mm:.2} mm, motion up to {max_disp:.2} pitch): marker {i} measured at ({x:.1}, {y:.1}), truth ({:.1}, {:.1}), darea {:.1} px of {:.1}; nearest truth ({:.1}, {:.1}) is {whose}",
                now[t].0, now[t].1, f.values[per * i + 2], m.area_px, now[u].0, now[u].1
            ));
            continue;
        }
        if !visible {
            out.ok_not_visible += 1;
            continue;
        }
        let (tx, ty) = (now[t].0 - rest[t].0, now[t].1 - rest[t].1);
        let e = (dx - tx).hypot(dy - ty);
        if e > 0.25 * cal.pitch_px.min(4.0) {
            out.examples.push(format!(
                "frame {k} (depth {depth_mm:.2} mm): marker {i} off by {e:.2} px"
            ));
        }
        out.errs.push(e);
    }
    out
}
