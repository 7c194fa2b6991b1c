//! The real frames' half of the tracking scorecard: every real set under
//! `shared/reference/real/` tracked as a user would track it, counted where no label is needed,
//! and a baseline to hold the counts to (`visuotact check-tracking --real DIR`, test
//! `real_card_holds_its_baseline`).
//!
//! Real frames carry no truth of which blob is which marker, so each row counts what can be
//! checked without one:
//! - **TacTip sets** — `frames`, `marker_frames`, `missing` (marker-frames without a position)
//!   and `frames_missing` (frames missing any); of the missing, those `lost`, `ambiguous` and
//!   `merged` (told, not held: what moves between them is no worse). The 127-pin set is
//!   calibrated on its 20 lightest training frames (`scripts/bench/real-tactip127`) and on one
//!   in-contact frame, `frame_0_0` (a user with no contact-free frame); the 331-pin set on its
//!   shallowest training frame (`scripts/bench/real-tactip331`), and again with every frame
//!   scaled to 128 × 128 by area averaging (ffmpeg's `area` filter), where `apart` counts the
//!   pins both readings hold that lie over half a pitch apart: a reading a lattice step off
//!   misses no pin, and shows only there.
//! - **GelSight Mini videos** 0, 1, 2, 3 and 5 beside the vendor tracker's positions
//!   (`marker_locations_N.csv`), calibrated on their first 5 frames with border markers kept,
//!   each frame on its own and `followed` (the temporal prior): the vendor's marker-frames of
//!   the markers paired at the first frame (nearest within half the vendor's pitch),
//!   `reported` of them, the median distance to the vendor's (`median_mpx`, thousandths of a
//!   pixel) and `over_10px` outside the frames where the vendor's tracker froze (its positions
//!   repeat the last frame's while the gel is displaced) — `scripts/bench/peers_tracking_real.py`'s
//!   measure.
//! - **9DTact** `camera_calibration/sample.png` (dark-marker preset, adaptive window 51,
//!   offset −0.03): `markers`, `rows`, `cols`.
//!
//! `stride` keeps every n-th frame of the TacTip sets (the test's card runs a fifth of them;
//! 1 gives the benches' frames). Every value is an integer so a table reads back exactly.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use visuotact_image::{Frame, RgbImage};
use visuotact_io::frames::{expand_inputs, FrameError, FrameStream, Input};
use visuotact_pipeline::calibrate::{calibrate_frames, CalibrateError, ReferenceSource};
use visuotact_vision::calibration::{
    calibrate, CalibrationConfig, CalibrationError, Preset, SensorCalibration,
};
use visuotact_vision::features::{FeatureExtractor, FrameFeatures, FrameSizeError};
use visuotact_vision::layout::{median, LayoutChoice};
use visuotact_vision::options::{DetectorOptions, Purpose};
use visuotact_vision::track::{MarkerStatus, TrackParams};
use visuotact_vision::ConfigError;

/// What the real card runs.
#[derive(Clone, Debug)]
pub struct RealCardConfig {
    /// The real sets' folder (`shared/reference/real`).
    pub dir: PathBuf,
    /// Every `stride`-th frame of the TacTip sets (their calibration frames too); 1: all.
    pub stride: usize,
    /// The tracker's settings.
    pub track: TrackParams,
}

impl RealCardConfig {
    /// Every frame of the sets in `dir`, default tracker settings.
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self {
            dir: dir.into(),
            stride: 1,
            track: TrackParams::DEFAULT,
        }
    }
}

/// Why the real card could not be run or read.
#[derive(Debug, thiserror::Error)]
pub enum RealCardError {
    /// A file of the sets is not there.
    #[error("{0}: not found (expected the real sets of shared/reference/real)")]
    Missing(PathBuf),
    /// A labels or positions file line that does not parse.
    #[error("{path} line {line}: {expected}")]
    Line {
        /// The file.
        path: PathBuf,
        /// The 1-based line.
        line: usize,
        /// What the line should hold.
        expected: &'static str,
    },
    /// A table line that does not parse.
    #[error("{source_name} line {line}: expected set, quantity and a whole number")]
    Table {
        /// The table's name (its file).
        source_name: String,
        /// The 1-based line.
        line: usize,
    },
    /// A file could not be read.
    #[error("reading {path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A frame of another size than its calibration's.
    #[error("frame {frame}: {source}")]
    Size {
        /// The frame.
        frame: String,
        /// Its size against the calibration's.
        source: FrameSizeError,
    },
    /// Frames could not be opened or decoded.
    #[error(transparent)]
    Frames(#[from] FrameError),
    /// A calibration from files failed.
    #[error(transparent)]
    Calibrate(#[from] CalibrateError),
    /// A calibration failed.
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
    /// Detector settings that do not hold together.
    #[error(transparent)]
    Config(#[from] ConfigError),
}

/// Values per set and quantity.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RealCard {
    /// Rows in set order, each its quantities in name order.
    pub rows: BTreeMap<String, BTreeMap<String, u64>>,
}

/// How a quantity may move against its baseline before it counts as worse.
enum Rule {
    /// It must be the same (what was run: frames, markers).
    Same,
    /// At most this much more.
    Rise(u64),
    /// At most this much less.
    Fall(u64),
    /// Any change (what the missing ones are: a share of a count that is checked).
    Any,
}

/// `share` of `of`, rounded up, and at least two.
fn slack(share: f64, of: u64) -> u64 {
    ((share * of as f64).ceil() as u64).max(2)
}

/// How `quantity` of a row (`row`: the row now) may move.
fn rule(quantity: &str, row: &BTreeMap<String, u64>) -> Rule {
    let of = |q: &str| row.get(q).copied().unwrap_or(0);
    match quantity {
        "missing" => Rule::Rise(slack(REAL_TOLERANCE, of("marker_frames"))),
        "frames_missing" => Rule::Rise(slack(REAL_TOLERANCE, of("frames"))),
        // A reading a step off is a wrong identity: a tenth of the slack.
        "apart" => Rule::Rise(slack(REAL_TOLERANCE / 10.0, of("marker_frames"))),
        "reported" => Rule::Fall(slack(REAL_TOLERANCE, of("vendor_marker_frames"))),
        "median_mpx" | "over_10px" => Rule::Rise(2),
        "lost" | "ambiguous" | "merged" => Rule::Any,
        _ => Rule::Same,
    }
}

/// How much more of a row's marker-frames (or frames) may be missing, or fewer reported, than
/// in its baseline: 0.2 % (at least two), as the zoo's [`crate::scorecard::BASELINE_TOLERANCE`];
/// `apart` a tenth of that, the median distance 0.002 px, marker-frames over 10 px two.
pub const REAL_TOLERANCE: f64 = 0.002;

impl RealCard {
    /// The table, tab-separated: set, quantity, value.
    pub fn to_tsv(&self) -> String {
        let mut out = String::from("set\tquantity\tvalue\n");
        for (set, qs) in &self.rows {
            for (q, v) in qs {
                let _ = writeln!(out, "{set}\t{q}\t{v}");
            }
        }
        out
    }

    /// Reads a table written by [`RealCard::to_tsv`] (`source_name` names it in errors).
    pub fn from_tsv(text: &str, source_name: &str) -> Result<Self, RealCardError> {
        let mut rows: BTreeMap<String, BTreeMap<String, u64>> = BTreeMap::new();
        for (n, line) in text.lines().enumerate().skip(1) {
            if line.trim().is_empty() {
                continue;
            }
            let bad = || RealCardError::Table {
                source_name: source_name.to_string(),
                line: n + 1,
            };
            let f: Vec<&str> = line.split('\t').collect();
            let [set, q, v] = f[..] else {
                return Err(bad());
            };
            let v = v.parse().map_err(|_| bad())?;
            rows.entry(set.to_string())
                .or_default()
                .insert(q.to_string(), v);
        }
        Ok(Self { rows })
    }

    /// Where this card is worse than `baseline` ([`REAL_TOLERANCE`]), one line each; a row or
    /// quantity the baseline lacks, or one it has and this card lacks, is a line too.
    pub fn regressions(&self, baseline: &RealCard) -> Vec<String> {
        let mut out = Vec::new();
        for set in baseline.rows.keys().filter(|s| !self.rows.contains_key(*s)) {
            out.push(format!("{set}: in the baseline, not run"));
        }
        for (set, qs) in &self.rows {
            let Some(base) = baseline.rows.get(set) else {
                out.push(format!("{set}: not in the baseline"));
                continue;
            };
            for (q, &v) in qs {
                let Some(&b) = base.get(q) else {
                    out.push(format!("{set} {q}: not in the baseline"));
                    continue;
                };
                let worse = match rule(q, qs) {
                    Rule::Same => v != b,
                    Rule::Rise(by) => v > b + by,
                    Rule::Fall(by) => v + by < b,
                    Rule::Any => false,
                };
                if worse {
                    out.push(format!("{set} {q}: {v}, baseline {b}"));
                }
            }
        }
        out
    }
}

/// Runs the real card over the sets in `c.dir`; `stage` hears the name of each set as it
/// starts (a progress line: the whole card takes minutes at `stride` 1).
pub fn real_card(
    c: &RealCardConfig,
    stage: &mut dyn FnMut(&str),
) -> Result<RealCard, RealCardError> {
    let mut card = RealCard::default();
    stage("tactip127");
    tactip127(c, &mut card)?;
    stage("tactip331");
    tactip331(c, &mut card)?;
    for video in [0, 1, 2, 3, 5] {
        stage(&format!("gelsight video_{video}"));
        gelsight(c, video, &mut card)?;
    }
    stage("9dtact");
    let sample = existing(c.dir.join("9dtact/camera_calibration/sample.png"))?;
    let options = DetectorOptions {
        preset: Some(Preset::DarkMarkers),
        window_px: Some(51),
        offset: Some(-0.03),
        ..Default::default()
    };
    let cal = calibrated(&[sample], None, ReferenceSource::Still, &options, None, c)?;
    card.rows.insert(
        "9dtact sample".into(),
        BTreeMap::from([
            ("markers".into(), cal.markers.len() as u64),
            ("rows".into(), u64::from(cal.grid_rows)),
            ("cols".into(), u64::from(cal.grid_cols)),
        ]),
    );
    Ok(card)
}

/// The real card, as a table, and where it is worse than `baseline` (what
/// `check-tracking --real` prints); `stage` as [`real_card`]'s.
pub fn real_card_table(
    c: &RealCardConfig,
    baseline: Option<&Path>,
    stage: &mut dyn FnMut(&str),
) -> Result<(String, Vec<String>), RealCardError> {
    let card = real_card(c, stage)?;
    let worse = match baseline {
        Some(path) => card.regressions(&RealCard::from_tsv(
            &text_of(path)?,
            &path.display().to_string(),
        )?),
        None => Vec::new(),
    };
    Ok((card.to_tsv().trim_end().to_string(), worse))
}

fn existing(p: PathBuf) -> Result<PathBuf, RealCardError> {
    if p.exists() {
        Ok(p)
    } else {
        Err(RealCardError::Missing(p))
    }
}

/// The text of `path`, or why not.
fn text_of(path: &Path) -> Result<String, RealCardError> {
    std::fs::read_to_string(existing(path.to_path_buf())?).map_err(|source| RealCardError::Read {
        path: path.to_path_buf(),
        source,
    })
}

/// Each marker's position in one frame (`None`: no position).
type Positions = Vec<Option<(f64, f64)>>;

/// Each marker's position per frame, and how many marker-frames had each status (by name).
struct Reading {
    frames: Vec<Positions>,
    status: BTreeMap<&'static str, u64>,
}

/// A sensor calibrated as `visuotact calibrate` does with `options`: on `paths` (the first
/// `first` frames, or the lightest of them), every frame scaled to `scale_to` when given.
fn calibrated(
    paths: &[PathBuf],
    first: Option<usize>,
    source: ReferenceSource,
    options: &DetectorOptions,
    scale_to: Option<(usize, usize)>,
    c: &RealCardConfig,
) -> Result<SensorCalibration, RealCardError> {
    let open = || {
        let s = FrameStream::open(paths, 25.0)?;
        Ok(match first {
            Some(n) => s.take_first(n),
            None => s,
        })
    };
    let scaled = |f: Frame| match scale_to {
        Some((w, h)) => area_scaled(&f.image, w, h),
        None => f.image,
    };
    let first_image = open()?.next().transpose()?.map(scaled);
    let fc = options.config_for_frames(Purpose::Tracking, || first_image.clone())?;
    let cfg = CalibrationConfig {
        detector: fc.detector,
        layout: LayoutChoice::Auto,
        features: fc.features,
        track: c.track,
    };
    let mut cal = match (source, scale_to) {
        (ReferenceSource::Lightest(_), _) | (_, None) => {
            calibrate_frames(open, source, &cfg, &mut |_, _| {
                std::ops::ControlFlow::Continue(())
            })?
            .calibration
        }
        (ReferenceSource::Still, Some(_)) => {
            let frames = open()?
                .map(|f| f.map(|f| (f.id.clone(), scaled(f))))
                .collect::<Result<Vec<_>, _>>()?;
            calibrate(frames.iter().map(|(id, im)| (id.as_str(), im)), &cfg)?.0
        }
    };
    cal.marker_size = fc.size;
    cal.track = c.track;
    Ok(cal)
}

/// How many frames are read and tracked at once (in parallel when order-free).
const BATCH: usize = 64;

/// `cal`'s markers through the frames of `paths`, each frame scaled to `scale_to` when given:
/// order-free (every frame on its own, in parallel) or followed (the temporal prior).
fn reading(
    cal: &SensorCalibration,
    paths: &[PathBuf],
    followed: bool,
    scale_to: Option<(usize, usize)>,
) -> Result<Reading, RealCardError> {
    let mut ex = FeatureExtractor::new(cal.clone(), cal.features)?;
    ex.set_temporal_prior(followed);
    let positions = |ex: &mut FeatureExtractor, id: &str, im: &RgbImage| {
        let mut f = FrameFeatures::default();
        ex.extract_into(im, &mut f)
            .map_err(|source| RealCardError::Size {
                frame: id.to_string(),
                source,
            })?;
        let t = ex.last_track();
        let positions: Positions = (0..cal.markers.len())
            .map(|i| t.position_px(i, ex.last_blobs()))
            .collect();
        Ok::<_, RealCardError>((positions, t.status.clone()))
    };
    let mut stream = FrameStream::open(paths, 25.0)?;
    let mut out = Reading {
        frames: Vec::new(),
        status: BTreeMap::new(),
    };
    let mut add = |(p, status): (Positions, Vec<MarkerStatus>)| {
        for s in status {
            *out.status.entry(s.name()).or_default() += 1;
        }
        out.frames.push(p);
    };
    loop {
        let mut batch = Vec::with_capacity(BATCH);
        for f in stream.by_ref().take(BATCH) {
            let f = f?;
            let im = match scale_to {
                Some((w, h)) => area_scaled(&f.image, w, h),
                None => f.image,
            };
            batch.push((f.id, im));
        }
        if batch.is_empty() {
            break;
        }
        if followed {
            for (id, im) in &batch {
                add(positions(&mut ex, id, im)?);
            }
        } else {
            let shared = &ex;
            let got: Vec<_> = batch
                .par_iter()
                .map_init(|| shared.clone(), |ex, (id, im)| positions(ex, id, im))
                .collect::<Result<_, _>>()?;
            got.into_iter().for_each(&mut add);
        }
    }
    Ok(out)
}

/// The image files of `folder`, in natural order, every `stride`-th.
fn frame_files(folder: &Path, stride: usize) -> Result<Vec<PathBuf>, RealCardError> {
    let inputs = expand_inputs(&[existing(folder.to_path_buf())?])?;
    Ok(inputs
        .into_iter()
        .filter_map(|i| match i {
            Input::Image(p) => Some(p),
            Input::Video(_) => None,
        })
        .step_by(stride.max(1))
        .collect())
}

/// `frames`, `marker_frames`, `missing` and `frames_missing` of a reading, and of the
/// missing how many were `lost`, `ambiguous` and `merged`.
fn missing_counts(reading: &Reading) -> BTreeMap<String, u64> {
    let r = &reading.frames;
    let missing = |f: &Positions| f.iter().filter(|p| p.is_none()).count() as u64;
    let status = |s: MarkerStatus| reading.status.get(s.name()).copied().unwrap_or(0);
    BTreeMap::from([
        ("lost".into(), status(MarkerStatus::Lost)),
        ("ambiguous".into(), status(MarkerStatus::Ambiguous)),
        ("merged".into(), status(MarkerStatus::Merged)),
        ("frames".into(), r.len() as u64),
        (
            "marker_frames".into(),
            r.iter().map(|f| f.len() as u64).sum(),
        ),
        ("missing".into(), r.iter().map(missing).sum()),
        (
            "frames_missing".into(),
            r.iter().filter(|f| missing(f) > 0).count() as u64,
        ),
    ])
}

/// The first comma-separated column of every line of `path` after its header, and the column
/// the header names `column`, when given, parsed as a number.
fn labels(path: &Path, column: Option<&str>) -> Result<Vec<(String, f64)>, RealCardError> {
    let text = text_of(path)?;
    let column = match column {
        Some(name) => Some(
            text.lines()
                .next()
                .and_then(|h| h.split(',').position(|c| c.trim() == name))
                .ok_or(RealCardError::Line {
                    path: path.to_path_buf(),
                    line: 1,
                    expected: "a header naming the frame and label columns",
                })?,
        ),
        None => None,
    };
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate().skip(1) {
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        let value = match column {
            Some(k) => f
                .get(k)
                .and_then(|v| v.parse().ok())
                .ok_or(RealCardError::Line {
                    path: path.to_path_buf(),
                    line: n + 1,
                    expected: "a frame name and a number in the label column",
                })?,
            None => 0.0,
        };
        out.push((f[0].to_string(), value));
    }
    Ok(out)
}

/// The 127-pin set, calibrated on its 20 lightest training frames and on `frame_0_0`.
fn tactip127(c: &RealCardConfig, card: &mut RealCard) -> Result<(), RealCardError> {
    let set = c.dir.join("tactip127_surface");
    let frames = frame_files(&set.join("frames"), c.stride)?;
    let train: Vec<PathBuf> = labels(&set.join("train_targets.csv"), None)?
        .into_iter()
        .step_by(c.stride.max(1))
        .map(|(name, _)| set.join("frames").join(name))
        .collect();
    let options = DetectorOptions::default();
    for (name, cal_frames, source) in [
        (
            "tactip127 lightest:20",
            train,
            ReferenceSource::Lightest(20),
        ),
        (
            "tactip127 frame_0_0",
            vec![existing(set.join("frames/frame_0_0.png"))?],
            ReferenceSource::Still,
        ),
    ] {
        let cal = calibrated(&cal_frames, None, source, &options, None, c)?;
        let r = reading(&cal, &frames, false, None)?;
        card.rows.insert(name.into(), missing_counts(&r));
    }
    Ok(())
}

/// The 331-pin set on its shallowest training frame (every fifth frame is a test frame), at
/// full size and at 128 × 128, with the pins the two readings put over half a pitch apart.
fn tactip331(c: &RealCardConfig, card: &mut RealCard) -> Result<(), RealCardError> {
    let set = c.dir.join("tactip331_franka");
    let labels_path = set.join("labels.csv");
    let number = |name: &str| {
        name.trim_end_matches(".png")
            .rsplit('_')
            .next()
            .and_then(|n| n.parse::<u64>().ok())
    };
    let shallowest = labels(&labels_path, Some("pose_z"))?
        .into_iter()
        .filter(|(name, _)| number(name).is_some_and(|n| n % 5 != 0))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .ok_or(RealCardError::Line {
            path: labels_path,
            line: 2,
            expected: "training frames (names ending in a number not a multiple of 5)",
        })?
        .0;
    let frames = frame_files(&set.join("frames"), c.stride)?;
    let cal_frame = [existing(set.join("frames").join(shallowest))?];
    let options = DetectorOptions::default();
    let cal = calibrated(&cal_frame, None, ReferenceSource::Still, &options, None, c)?;
    let full = reading(&cal, &frames, false, None)?;
    card.rows
        .insert("tactip331 shallowest".into(), missing_counts(&full));
    let small = Some((128, 128));
    let cal_small = calibrated(&cal_frame, None, ReferenceSource::Still, &options, small, c)?;
    let scaled = reading(&cal_small, &frames, false, small)?;
    // Each 128 × 128 marker is paired with the full-size one nearest to it at rest.
    let (sx, sy) = (
        128.0 / cal.image_width as f64,
        128.0 / cal.image_height as f64,
    );
    let pair: Vec<usize> = cal_small
        .markers
        .iter()
        .map(|m| {
            (0..cal.markers.len())
                .min_by(|&a, &b| {
                    let d = |k: usize| {
                        let q = &cal.markers[k];
                        (q.x_px * sx - m.x_px).hypot(q.y_px * sy - m.y_px)
                    };
                    d(a).total_cmp(&d(b))
                })
                .unwrap_or(0)
        })
        .collect();
    let half = 0.5 * cal_small.pitch_px;
    let apart = scaled
        .frames
        .iter()
        .zip(&full.frames)
        .flat_map(|(s, f)| s.iter().zip(&pair).map(move |(p, &k)| (*p, f[k])))
        .filter(|(p, q)| match (p, q) {
            (Some(p), Some(q)) => (q.0 * sx - p.0).hypot(q.1 * sy - p.1) > half,
            _ => false,
        })
        .count();
    let mut row = missing_counts(&scaled);
    row.insert("apart".into(), apart as u64);
    card.rows.insert("tactip331 128x128".into(), row);
    Ok(())
}

/// The vendor tracker's positions of one video: per frame (0-based), each marker's position
/// (in the first frame's marker order; `None` where that frame lacks it).
fn vendor_positions(path: &Path) -> Result<Vec<Positions>, RealCardError> {
    let text = text_of(path)?;
    // Per frame, per (row, column), the position.
    type Marks = BTreeMap<(i64, i64), (f64, f64)>;
    let mut frames: BTreeMap<usize, Marks> = BTreeMap::new();
    for (n, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let v: Vec<f64> = line
            .split(',')
            .map(|x| x.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .ok()
            .filter(|v: &Vec<f64>| v.len() == 7 && v[0] >= 1.0)
            .ok_or(RealCardError::Line {
                path: path.to_path_buf(),
                line: n + 1,
                expected: "frame (from 1), row, col, Ox, Oy, Cx, Cy",
            })?;
        frames
            .entry(v[0] as usize - 1)
            .or_default()
            .insert((v[1] as i64, v[2] as i64), (v[5], v[6]));
    }
    let keys: Vec<(i64, i64)> = frames
        .get(&0)
        .map(|f| f.keys().copied().collect())
        .unwrap_or_default();
    let last = frames.keys().next_back().copied().unwrap_or(0);
    Ok((0..=last)
        .map(|f| {
            keys.iter()
                .map(|k| frames.get(&f).and_then(|m| m.get(k)).copied())
                .collect()
        })
        .collect())
}

/// The median distance from each point to its nearest other.
fn pitch_of(xy: &[(f64, f64)]) -> f64 {
    let mut d: Vec<f64> = xy
        .iter()
        .enumerate()
        .map(|(i, a)| {
            xy.iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(_, b)| (a.0 - b.0).hypot(a.1 - b.1))
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    median(&mut d)
}

/// A GelSight Mini video's two rows, each frame on its own and followed, beside the vendor's.
fn gelsight(c: &RealCardConfig, video: u32, card: &mut RealCard) -> Result<(), RealCardError> {
    let dir = c.dir.join("gelsight_mini");
    let path = existing(dir.join(format!("video_{video}.avi")))?;
    let vendor = vendor_positions(&dir.join(format!("marker_locations_{video}.csv")))?;
    let options = DetectorOptions {
        keep_border: true,
        ..Default::default()
    };
    let paths = [path];
    let cal = calibrated(&paths, Some(5), ReferenceSource::Still, &options, None, c)?;
    // The vendor's frozen frames: positions equal to the last frame's while the gel is over
    // a pixel from the first frame's.
    let largest = |a: &[Option<(f64, f64)>], b: &[Option<(f64, f64)>]| {
        a.iter()
            .zip(b)
            .filter_map(|(p, q)| Some(((*p)?, (*q)?)))
            .map(|(p, q)| (p.0 - q.0).abs().max((p.1 - q.1).abs()))
            .fold(0.0, f64::max)
    };
    let frozen: Vec<bool> = (0..vendor.len())
        .map(|f| {
            f > 0
                && largest(&vendor[f], &vendor[f - 1]) == 0.0
                && largest(&vendor[f], &vendor[0]) > 1.0
        })
        .collect();
    let at_rest: Vec<(f64, f64)> = vendor[0].iter().flatten().copied().collect();
    let half = 0.5 * pitch_of(&at_rest);
    // Each vendor marker's nearest reference marker, when within half a pitch.
    let pair: Vec<Option<usize>> = vendor[0]
        .iter()
        .map(|v| {
            let v = (*v)?;
            let (k, d) = cal
                .markers
                .iter()
                .map(|m| (m.x_px - v.0).hypot(m.y_px - v.1))
                .enumerate()
                .min_by(|a, b| a.1.total_cmp(&b.1))?;
            (d < half).then_some(k)
        })
        .collect();
    for (name, followed) in [("", false), (" followed", true)] {
        let r = reading(&cal, &paths, followed, None)?;
        let (mut seen, mut over) = (0u64, 0u64);
        let mut dist = Vec::new();
        for ((ours, theirs), frozen) in r.frames.iter().zip(&vendor).zip(&frozen) {
            for (v, k) in theirs.iter().zip(&pair) {
                let (Some(v), Some(k)) = (v, k) else { continue };
                seen += 1;
                if let Some(p) = ours[*k] {
                    let d = (p.0 - v.0).hypot(p.1 - v.1);
                    dist.push(d);
                    over += u64::from(!frozen && d > 10.0);
                }
            }
        }
        let reported = dist.len() as u64;
        card.rows.insert(
            format!("gelsight video_{video}{name}"),
            BTreeMap::from([
                ("vendor_marker_frames".into(), seen),
                ("reported".into(), reported),
                (
                    "median_mpx".into(),
                    (1000.0 * median(&mut dist)).round() as u64,
                ),
                ("over_10px".into(), over),
            ]),
        );
    }
    Ok(())
}

/// `img` scaled to `w` × `h` by area averaging: each output pixel the mean of the input it
/// covers, partly covered pixels weighted by the part (ffmpeg's and OpenCV's `area`).
fn area_scaled(img: &RgbImage, w: usize, h: usize) -> RgbImage {
    // Per output index, the input indices it covers with their weights (summing to one).
    let spans = |from: usize, to: usize| -> Vec<Vec<(usize, f64)>> {
        let step = from as f64 / to as f64;
        (0..to)
            .map(|o| {
                let (a, b) = (o as f64 * step, (o + 1) as f64 * step);
                (a.floor() as usize..(b.ceil() as usize).min(from))
                    .map(|i| {
                        let cover = (b.min(i as f64 + 1.0) - a.max(i as f64)).max(0.0);
                        (i, cover / step)
                    })
                    .filter(|(_, wgt)| *wgt > 0.0)
                    .collect()
            })
            .collect()
    };
    let (xs, ys) = (spans(img.width(), w), spans(img.height(), h));
    let src = img.as_slice();
    let stride = 3 * img.width();
    RgbImage::from_fn(w, h, |x, y| {
        let mut acc = [0.0f64; 3];
        for &(iy, wy) in &ys[y] {
            for &(ix, wx) in &xs[x] {
                let p = iy * stride + 3 * ix;
                for (c, a) in acc.iter_mut().enumerate() {
                    *a += wy * wx * f64::from(src[p + c]);
                }
            }
        }
        acc.map(|a| a.round().clamp(0.0, 255.0) as u8)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn area_scaling_averages_what_each_pixel_covers() {
        // 3 × 1 → 2 × 1: the middle pixel is shared half and half.
        let img = RgbImage::from_fn(3, 1, |x, _| [[0, 0, 0], [90, 90, 90], [180, 180, 180]][x]);
        let s = area_scaled(&img, 2, 1);
        // (0 · 1 + 90 · 0.5) / 1.5 = 30; (90 · 0.5 + 180) / 1.5 = 150.
        assert_eq!(s.as_slice(), &[30, 30, 30, 150, 150, 150]);
        // An even halving is the mean of each 2 × 2 block.
        let img = RgbImage::from_fn(4, 2, |x, y| [(10 * (x + 4 * y)) as u8; 3]);
        assert_eq!(
            area_scaled(&img, 2, 1).as_slice(),
            &[25, 25, 25, 45, 45, 45]
        );
    }

    #[test]
    fn a_real_card_reads_back_and_names_what_got_worse() {
        let mut card = RealCard::default();
        card.rows.insert(
            "tactip".into(),
            BTreeMap::from([
                ("frames".into(), 100),
                ("marker_frames".into(), 10_000),
                ("missing".into(), 40),
                ("apart".into(), 3),
            ]),
        );
        card.rows.insert(
            "video".into(),
            BTreeMap::from([
                ("vendor_marker_frames".into(), 5000),
                ("reported".into(), 4900),
                ("median_mpx".into(), 700),
            ]),
        );
        let back = RealCard::from_tsv(&card.to_tsv(), "t").unwrap();
        assert_eq!(back, card);
        assert!(card.regressions(&back).is_empty());
        let mut worse = card.clone();
        let set = |card: &mut RealCard, row: &str, q: &str, v: u64| {
            card.rows.get_mut(row).unwrap().insert(q.into(), v);
        };
        // 0.2 % of 10 000 marker-frames is 20 more missing; apart may rise by two.
        set(&mut worse, "tactip", "missing", 60);
        set(&mut worse, "tactip", "apart", 5);
        assert!(worse.regressions(&card).is_empty());
        set(&mut worse, "tactip", "missing", 61);
        set(&mut worse, "tactip", "apart", 6);
        set(&mut worse, "video", "reported", 4889);
        set(&mut worse, "video", "median_mpx", 703);
        assert_eq!(
            worse.regressions(&card),
            [
                "tactip apart: 6, baseline 3",
                "tactip missing: 61, baseline 40",
                "video median_mpx: 703, baseline 700",
                "video reported: 4889, baseline 4900",
            ]
        );
        set(&mut worse, "tactip", "frames", 99);
        worse.rows.remove("video");
        let told = worse.regressions(&card);
        assert!(told.contains(&"tactip frames: 99, baseline 100".into()));
        assert!(told.contains(&"video: in the baseline, not run".into()));
        // What the missing are (lost, ambiguous, merged) is told, not held.
        let mut lost = card.clone();
        set(&mut lost, "tactip", "lost", 10);
        let mut more_lost = lost.clone();
        set(&mut more_lost, "tactip", "lost", 40);
        assert!(more_lost.regressions(&lost).is_empty());
        assert!(RealCard::from_tsv("set\tquantity\tvalue\nx\ty", "t").is_err());
        assert!(RealCard::from_tsv("set\tquantity\tvalue\nx\ty\t1.5", "t").is_err());
    }
}
