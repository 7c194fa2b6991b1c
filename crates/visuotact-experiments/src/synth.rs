//! Simulated session folders with exact ground truth (`visuotact simulate`): no-contact
//! references, then a protocol's frames, their labels, the markers' true positions
//! (`truth.csv`) and, for the cone, the JR3's force stream — in the layout `record` writes, so
//! every tool reads them alike.
//!
//! The contract: the same [`SimulateConfig`] writes the same bytes (every frame's noise comes
//! from [`frame_seed`]); frames are rendered in parallel batches and written in order; a folder
//! that already holds a session is refused.

use std::path::PathBuf;

use rayon::prelude::*;
use serde::Serialize;
use visuotact_image::RgbImage;
use visuotact_io::force::{ForceLayout, ForceSample};
use visuotact_io::frames::{write_png, FrameError};
use visuotact_io::session::{SessionWriter, TruthRow};
use visuotact_sim::cone::{ConeConfig, ConeLoad};
use visuotact_sim::iats::{IatsConfig, Touch};
use visuotact_sim::jr3::{Jr3, Jr3Config};
use visuotact_sim::pattern::{render_grid, GridPattern, Press};
use visuotact_sim::protocol::{self, zoo_slip, ConePress, GraspKind, PressureGauge};
use visuotact_sim::rig::{cone_labels, frame_seed, CONE_LABELS, GAUGE_SEED};
use visuotact_sim::zoo::{self, ZooConfig, ZooKind, ZooTouch};
use visuotact_sim::SimError;

/// Which simulated sensor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SimKind {
    /// Seed 000's areal touch sensor.
    Iats,
    /// Seed 001's inflatable link.
    Cone,
    /// A sensor of the zoo (TacTip-like, GelSight-like, random dots).
    Zoo(ZooKind),
}

visuotact_image::names_from_str!(SimKind, "simulated sensor");

impl SimKind {
    /// The names [`SimKind::from_name`] and `FromStr` read (each is also what `name` writes,
    /// where the type has one).
    pub const NAMES: &'static [&'static str] =
        &["iats", "cone", "tactip", "tactip-small", "gelsight", "dots"];

    /// `iats`, `cone`, or a zoo sensor's name.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "iats" => Some(Self::Iats),
            "cone" => Some(Self::Cone),
            other => ZooKind::from_name(other).map(Self::Zoo),
        }
    }

    /// The name [`SimKind::from_name`] reads.
    pub fn name(self) -> &'static str {
        match self {
            Self::Iats => "iats",
            Self::Cone => "cone",
            Self::Zoo(k) => k.name(),
        }
    }
}

/// The cone's press and force sensor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConeSession {
    /// Press-and-release time, s.
    pub duration_s: f64,
    /// Peak force, N.
    pub max_force_n: f64,
    /// The force sensor's sample rate, Hz.
    pub force_rate_hz: f64,
}

impl Default for ConeSession {
    fn default() -> Self {
        Self {
            duration_s: 20.0,
            max_force_n: 10.0,
            force_rate_hz: 1000.0,
        }
    }
}

/// What to simulate.
#[derive(Clone, Debug)]
pub struct SimulateConfig {
    /// The sensor.
    pub sensor: SimKind,
    /// The protocol: iats `grid`, `random`, `shear`, `line`; cone `press`, `press-rotate`; zoo
    /// `grid`, `random`, `shear`, `drag`, `plate` (domes), and the grasps `grasp-press`,
    /// `grasp-drag`, `grasp-twist`, `grasp-slip`, `grasp-shake` (one grasp of `touches` frames,
    /// at least 60, its `slip_state` truth per frame: 0 stick, 1 incipient, 2 slip).
    pub protocol: String,
    /// iats and zoo: the sensor's parameters drawn from their ranges with this seed (0: the
    /// preset).
    pub variant: u64,
    /// Random seed: the same seed writes the same bytes.
    pub seed: u64,
    /// Session folder to create.
    pub output: PathBuf,
    /// Touches for the random and shear protocols; a grasp's frames.
    pub touches: usize,
    /// No-contact reference frames written first.
    pub references: usize,
    /// Camera frame rate, frames per second.
    pub fps: f64,
    /// The cone's press and force sensor.
    pub cone: ConeSession,
    /// The force packet layout recorded in `session.json` (for senders of the stream).
    pub force_layout: ForceLayout,
    /// Settings over the sensor model: a JSON object with any subset of its fields.
    pub overrides: Option<serde_json::Map<String, serde_json::Value>>,
}

impl Default for SimulateConfig {
    fn default() -> Self {
        Self {
            sensor: SimKind::Iats,
            protocol: "random".into(),
            variant: 0,
            seed: 1,
            output: PathBuf::from("session"),
            touches: 200,
            references: 10,
            fps: 25.0,
            cone: ConeSession::default(),
            force_layout: ForceLayout::default(),
            overrides: None,
        }
    }
}

/// Why a session could not be simulated.
#[derive(Debug, thiserror::Error)]
pub enum SimulateError {
    /// A setting is out of range or does not fit the sensor.
    #[error("{0}")]
    Config(String),
    /// The overrides are not the sensor model's fields.
    #[error("not a {sensor} sensor model: {why}")]
    Overrides {
        /// The sensor's name.
        sensor: &'static str,
        /// serde's message (names the field).
        why: String,
    },
    /// The simulator refused a setting or a frame.
    #[error("{0}")]
    Sim(#[from] SimError),
    /// Writing the session failed.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// Writing a frame failed.
    #[error(transparent)]
    Frame(#[from] FrameError),
}

/// What was written.
#[derive(Clone, Debug, Default)]
pub struct Simulated {
    /// Frames after the references.
    pub frames: usize,
    /// The cone's force stream (empty for other sensors), at `force_rate_hz`.
    pub force: Vec<ForceSample>,
}

pub use visuotact_sim::{MAX_FRAMES, MAX_REFERENCES};

/// Most force samples one simulated stream holds (kept in memory, 56 bytes each): about 2.8
/// hours at the JR3's 1 kHz.
pub const MAX_FORCE_SAMPLES: usize = 10_000_000;

/// `Err` naming `setting` when `count` (a float product, possibly infinite) exceeds `limit`.
fn check_count(setting: &str, count: f64, limit: usize, unit: &str) -> Result<(), SimulateError> {
    if count.is_finite() && count <= limit as f64 {
        Ok(())
    } else {
        let asked = if count < 1e15 {
            format!("{count:.0}")
        } else {
            format!("{count:.3e}")
        };
        Err(SimulateError::Config(format!(
            "{setting} asks for {asked} {unit}; at most {limit} are simulated in one session"
        )))
    }
}

/// Writes the session `cfg` describes.
pub fn simulate(cfg: &SimulateConfig) -> Result<Simulated, SimulateError> {
    if !(cfg.fps.is_finite() && cfg.fps > 0.0) {
        return Err(SimulateError::Config(format!(
            "fps must be a positive frame rate, got {}",
            cfg.fps
        )));
    }
    check_count("touches", cfg.touches as f64, MAX_FRAMES, "frames")?;
    check_count(
        "references",
        cfg.references as f64,
        MAX_REFERENCES,
        "reference frames",
    )?;
    match cfg.sensor {
        SimKind::Iats => simulate_iats(cfg),
        SimKind::Cone if cfg.variant != 0 => Err(SimulateError::Config(
            "variants apply to iats and the zoo sensors (tactip, gelsight, dots)".into(),
        )),
        SimKind::Cone => simulate_cone(cfg),
        SimKind::Zoo(kind) => simulate_zoo(cfg, kind),
    }
}

/// The sensor model: `base` with `cfg.overrides` over it.
fn sensor_model<T: serde::de::DeserializeOwned + Serialize>(
    cfg: &SimulateConfig,
    base: T,
) -> Result<T, SimulateError> {
    let Some(over) = &cfg.overrides else {
        return Ok(base);
    };
    let bad = |e: serde_json::Error| SimulateError::Overrides {
        sensor: cfg.sensor.name(),
        why: e.to_string(),
    };
    let mut merged = serde_json::to_value(base).map_err(bad)?;
    if let serde_json::Value::Object(m) = &mut merged {
        m.extend(over.clone());
    }
    serde_json::from_value(merged).map_err(bad)
}

/// Frames rendered and written per parallel batch.
const BATCH: usize = 64;

/// A frame's labels and markers' truth.
struct Rendered {
    labels: Vec<f64>,
    truth: Vec<TruthRow>,
}

/// Renders `count` frames with `render(k)` in parallel batches of [`BATCH`], writing each PNG
/// at `path(k)` as it comes and handing `row(k, what render gave)` the frames in order, so
/// memory holds one batch whatever the count.
fn write_batched<R: Send>(
    count: usize,
    path: impl Fn(usize) -> std::path::PathBuf + Sync,
    render: impl Fn(usize) -> Result<(RgbImage, R), SimulateError> + Sync,
    mut row: impl FnMut(usize, R) -> Result<(), SimulateError>,
) -> Result<(), SimulateError> {
    for start in (0..count).step_by(BATCH) {
        let end = (start + BATCH).min(count);
        let rows: Vec<R> = (start..end)
            .into_par_iter()
            .map(|k| {
                let (img, r) = render(k)?;
                write_png(&path(k), &img)?;
                Ok(r)
            })
            .collect::<Result<_, SimulateError>>()?;
        for (k, r) in (start..end).zip(rows) {
            row(k, r)?;
        }
    }
    Ok(())
}

/// A frame's file name in `frames/`.
fn frame_name(k: usize) -> String {
    format!("frame_{k:06}.png")
}

/// A reference frame's file name in `reference/`.
fn reference_name(k: usize) -> String {
    format!("ref_{k:04}.png")
}

/// `count` touch frames after `first_index` references, their labels and truth.
fn write_frames(
    w: &mut SessionWriter,
    count: usize,
    first_index: usize,
    fps: f64,
    render: impl Fn(usize) -> Result<(RgbImage, Rendered), SimulateError> + Sync,
) -> Result<(), SimulateError> {
    let frames = w.frame_path("");
    write_batched(
        count,
        |k| frames.join(frame_name(k)),
        render,
        |k, r| {
            let index = first_index + k;
            Ok(w.add_frame(
                &frame_name(k),
                index,
                index as f64 / fps,
                &r.labels,
                &r.truth,
            )?)
        },
    )
}

/// `n` no-contact reference frames and their truth.
fn write_references(
    w: &mut SessionWriter,
    n: usize,
    fps: f64,
    render: impl Fn(usize) -> Result<(RgbImage, Vec<TruthRow>), SimulateError> + Sync,
) -> Result<(), SimulateError> {
    let refs = w.reference_path("");
    write_batched(
        n,
        |k| refs.join(reference_name(k)),
        render,
        |k, truth| Ok(w.add_reference(&reference_name(k), k, k as f64 / fps, &truth)?),
    )
}

/// Truth rows from (x, y, area, fully in view, visible) per marker.
fn truth_rows(markers: impl Iterator<Item = (f64, f64, f64, bool, bool)>) -> Vec<TruthRow> {
    markers
        .map(|(x_px, y_px, area_px, fully_in_view, visible)| TruthRow {
            x_px,
            y_px,
            area_px,
            fully_in_view,
            visible,
        })
        .collect()
}

fn iats_truth(markers: &[visuotact_sim::iats::IatsMarker]) -> Vec<TruthRow> {
    truth_rows(
        markers
            .iter()
            .map(|m| (m.x_px, m.y_px, m.area_px, m.fully_in_view, m.visible)),
    )
}

fn zoo_truth(markers: &[zoo::ZooMarker]) -> Vec<TruthRow> {
    truth_rows(
        markers
            .iter()
            .map(|m| (m.x_px, m.y_px, m.area_px, m.in_view, m.visible)),
    )
}

/// Rings are visible whenever they are wholly in view (they never crowd one another).
fn cone_truth(rings: &[visuotact_sim::cone::RingTruth]) -> Vec<TruthRow> {
    truth_rows(
        rings
            .iter()
            .map(|r| (r.x_px, r.y_px, r.area_px, r.fully_in_view, r.fully_in_view)),
    )
}

/// What a touch protocol's simulator gives [`write_touch_session`]: the sensor model, the
/// label columns, the touch count and its two renderers.
struct TouchSession<'a, C, R, F> {
    config: &'a C,
    cols: Vec<&'a str>,
    touches: usize,
    /// The rest frame and truth for a noise seed.
    reference: R,
    /// Touch `k`'s frame, labels and truth for a noise seed.
    frame: F,
}

/// The session description's common fields.
#[derive(Serialize)]
struct Description<'a, C: Serialize, X: Serialize> {
    sensor: &'a str,
    protocol: &'a str,
    seed: u64,
    fps: f64,
    reference_frames: usize,
    frames: usize,
    labels: &'a [&'a str],
    config: &'a C,
    #[serde(flatten)]
    extra: X,
    generator: String,
}

/// Writes `session.json` over the description's fields.
fn finish<C: Serialize, X: Serialize>(
    w: SessionWriter,
    d: &Description<'_, C, X>,
) -> Result<(), SimulateError> {
    let v = serde_json::to_value(d).map_err(std::io::Error::other)?;
    Ok(w.finish(v)?)
}

/// Writes a touch session (references, frames, truth and the manifest); returns its frames.
fn write_touch_session<C, R, F>(
    cfg: &SimulateConfig,
    s: TouchSession<'_, C, R, F>,
) -> Result<Simulated, SimulateError>
where
    C: Serialize,
    R: Fn(u64) -> Result<(RgbImage, Vec<TruthRow>), SimError> + Sync,
    F: Fn(usize, u64) -> Result<(RgbImage, Rendered), SimError> + Sync,
{
    let mut w = SessionWriter::create(&cfg.output, &s.cols, true, false)?;
    write_references(&mut w, cfg.references, cfg.fps, |k| {
        Ok((s.reference)(frame_seed(cfg.seed, k as u64))?)
    })?;
    write_frames(&mut w, s.touches, cfg.references, cfg.fps, |k| {
        (s.frame)(k, frame_seed(cfg.seed, (cfg.references + k) as u64))
            .map_err(|e| SimulateError::Config(format!("touch {k}: {e}")))
    })?;
    #[derive(Serialize)]
    struct Variant {
        variant: u64,
    }
    finish(
        w,
        &Description {
            sensor: cfg.sensor.name(),
            protocol: &cfg.protocol,
            seed: cfg.seed,
            fps: cfg.fps,
            reference_frames: cfg.references,
            frames: s.touches,
            labels: &s.cols,
            config: s.config,
            extra: Variant {
                variant: cfg.variant,
            },
            generator: format!("visuotact {}", env!("CARGO_PKG_VERSION")),
        },
    )?;
    Ok(Simulated {
        frames: s.touches,
        force: Vec::new(),
    })
}

/// Label columns of a touch protocol: position and depth, and the shear's when it shears.
fn touch_columns(shear: bool, extra: &[&'static str]) -> Vec<&'static str> {
    let mut cols = vec!["x_mm", "y_mm", "depth_mm"];
    if shear {
        cols.extend(extra);
    }
    cols
}

fn unknown_protocol(cfg: &SimulateConfig, known: &[&str]) -> SimulateError {
    SimulateError::Config(format!(
        "protocol {:?} is not a{} {} protocol: expected {}",
        cfg.protocol,
        if cfg.sensor == SimKind::Iats { "n" } else { "" },
        cfg.sensor.name(),
        protocol::names_listed(known)
    ))
}

fn simulate_iats(a: &SimulateConfig) -> Result<Simulated, SimulateError> {
    let cfg: IatsConfig = sensor_model(a, IatsConfig::variant(a.variant))?;
    cfg.validate()
        .map_err(|e| SimulateError::Config(format!("sensor model: {e}")))?;
    let touches = protocol::iats_named(&cfg, &a.protocol, a.touches, a.seed)
        .ok_or_else(|| unknown_protocol(a, &protocol::IATS_PROTOCOLS))?;
    for (k, t) in touches.iter().enumerate() {
        t.validate(&cfg)
            .map_err(|e| SimulateError::Config(format!("touch {k}: {e}")))?;
    }
    let shear = a.protocol == "shear";
    let rest = Touch::default();
    write_touch_session(
        a,
        TouchSession {
            config: &cfg,
            cols: touch_columns(shear, &["shear_x_mm", "shear_y_mm"]),
            touches: touches.len(),
            reference: |seed| {
                let (img, truth) = visuotact_sim::iats::render(&cfg, &rest, seed)?;
                Ok((img, iats_truth(&truth)))
            },
            frame: |k, seed| {
                let t = &touches[k];
                let (img, truth) = visuotact_sim::iats::render(&cfg, t, seed)?;
                let mut labels = vec![t.x_mm, t.y_mm, t.depth_mm];
                if shear {
                    labels.extend([t.shear_x_mm, t.shear_y_mm]);
                }
                let truth = iats_truth(&truth);
                Ok((img, Rendered { labels, truth }))
            },
        },
    )
}

fn simulate_zoo(a: &SimulateConfig, kind: ZooKind) -> Result<Simulated, SimulateError> {
    let cfg: ZooConfig = sensor_model(a, ZooConfig::variant(kind, a.variant))?;
    cfg.validate()
        .map_err(|e| SimulateError::Config(format!("sensor model: {e}")))?;
    let grasp = GraspKind::from_protocol(&a.protocol).map(|g| zoo_slip(&cfg, g, a.touches, a.seed));
    let known = || {
        let mut k = protocol::ZOO_PROTOCOLS.to_vec();
        k.extend(GraspKind::PROTOCOLS);
        unknown_protocol(a, &k)
    };
    let touches = match &grasp {
        Some(g) => g.touches.clone(),
        None => protocol::zoo_named(&cfg, &a.protocol, a.touches, a.seed).ok_or_else(known)?,
    };
    for (k, t) in touches.iter().enumerate() {
        t.validate(&cfg)
            .map_err(|e| SimulateError::Config(format!("touch {k}: {e}")))?;
    }
    let shear = a.protocol == "shear" || grasp.is_some();
    let rest = ZooTouch::default();
    let mut cols = touch_columns(shear, &["shear_x_mm", "shear_y_mm", "twist_deg"]);
    if grasp.is_some() {
        cols.push("slip_state");
    }
    write_touch_session(
        a,
        TouchSession {
            config: &cfg,
            cols,
            touches: touches.len(),
            reference: |seed| {
                let (img, truth) = zoo::render(&cfg, &rest, seed)?;
                Ok((img, zoo_truth(&truth)))
            },
            frame: |k, seed| {
                let t = &touches[k];
                let (img, truth) = zoo::render(&cfg, t, seed)?;
                let mut labels = vec![t.x_mm, t.y_mm, t.depth_mm];
                if shear {
                    labels.extend([t.shear_x_mm, t.shear_y_mm, t.twist_deg]);
                }
                if let Some(g) = &grasp {
                    labels.push(f64::from(g.state_at(k)));
                }
                let truth = zoo_truth(&truth);
                Ok((img, Rendered { labels, truth }))
            },
        },
    )
}

/// The cone's press for `a`'s protocol, checked.
fn cone_press(a: &SimulateConfig) -> Result<ConePress, SimulateError> {
    let press = ConePress {
        max_force_n: a.cone.max_force_n,
        duration_s: a.cone.duration_s,
        rotate: match a.protocol.as_str() {
            "press" => false,
            "press-rotate" => true,
            _ => return Err(unknown_protocol(a, &["press", "press-rotate"])),
        },
        ..ConePress::SEED001
    };
    press.validate()?;
    Ok(press)
}

fn simulate_cone(a: &SimulateConfig) -> Result<Simulated, SimulateError> {
    let cfg: ConeConfig = sensor_model(a, ConeConfig::default())?;
    cfg.validate()
        .map_err(|e| SimulateError::Config(format!("sensor model: {e}")))?;
    let press = cone_press(a)?;
    let jr3_cfg = Jr3Config {
        rate_hz: a.cone.force_rate_hz,
        ..Jr3Config::JR3_1KHZ
    };
    jr3_cfg.validate()?;
    let t0 = a.references as f64 / a.fps;
    let frames = (a.cone.duration_s * a.fps).round();
    check_count("duration_s × fps", frames, MAX_FRAMES, "frames")?;
    check_count(
        "(references / fps + duration_s) × force_rate_hz",
        ((t0 + a.cone.duration_s) * jr3_cfg.rate_hz).round(),
        MAX_FORCE_SAMPLES,
        "force samples",
    )?;
    let n = frames as usize;
    let mut w = SessionWriter::create(&a.output, &CONE_LABELS, true, true)?;
    write_references(&mut w, a.references, a.fps, |k| {
        let t = k as f64 / a.fps;
        let load = ConeLoad::none(press.drift.at(cfg.pressure_kpa, t));
        let (img, rings) = visuotact_sim::cone::render(&cfg, &load, frame_seed(a.seed, k as u64))?;
        Ok((img, cone_truth(&rings)))
    })?;
    write_frames(&mut w, n, a.references, a.fps, |k| {
        let load = press.load_at(&cfg, k as f64 / a.fps, t0);
        let seed = frame_seed(a.seed, (a.references + k) as u64);
        let (img, rings) = visuotact_sim::cone::render(&cfg, &load, seed)
            .map_err(|e| SimulateError::Config(format!("frame {k}: {e}")))?;
        let t = t0 + k as f64 / a.fps;
        let gauge_seed = frame_seed(a.seed ^ GAUGE_SEED, k as u64);
        let labels = cone_labels(&cfg, &press, &load, t, gauge_seed);
        let truth = cone_truth(&rings);
        Ok((img, Rendered { labels, truth }))
    })?;
    let samples = force_stream(a, &cfg, &press, &jr3_cfg, t0);
    w.add_force(&samples)?;
    #[derive(Serialize)]
    struct ConeExtra<'a> {
        press: &'a ConePress,
        pressure_gauge: PressureGauge,
        force_sensor: &'a Jr3Config,
        force_layout: Vec<&'static str>,
    }
    let extra = ConeExtra {
        press: &press,
        pressure_gauge: PressureGauge::SEED001,
        force_sensor: &jr3_cfg,
        force_layout: a.force_layout.fields.iter().map(|f| f.name()).collect(),
    };
    finish(
        w,
        &Description {
            sensor: "cone",
            protocol: &a.protocol,
            seed: a.seed,
            fps: a.fps,
            reference_frames: a.references,
            frames: n,
            labels: &CONE_LABELS,
            config: &cfg,
            extra,
            generator: format!("visuotact {}", env!("CARGO_PKG_VERSION")),
        },
    )?;
    Ok(Simulated {
        frames: n,
        force: samples,
    })
}

/// The force stream over the references and the press, at the sensor's own rate.
fn force_stream(
    a: &SimulateConfig,
    cfg: &ConeConfig,
    press: &ConePress,
    jr3_cfg: &Jr3Config,
    t0: f64,
) -> Vec<ForceSample> {
    let mut jr3 = Jr3::new(*jr3_cfg, a.seed ^ 0x4A33);
    let n_samples = ((t0 + a.cone.duration_s) * jr3_cfg.rate_hz).round() as usize;
    (0..n_samples)
        .map(|i| {
            let t = i as f64 / jr3_cfg.rate_hz;
            let load = if t < t0 {
                ConeLoad::none(cfg.pressure_kpa)
            } else {
                press.load_at(cfg, t - t0, t0)
            };
            ForceSample {
                timestamp_s: t,
                values: jr3.sample(load.components_n()),
            }
        })
        .collect()
}

/// Marker-grid test frames with exact truth (`visuotact pattern`).
#[derive(Clone, Debug, PartialEq)]
pub struct PatternConfig {
    /// Output folder: `rest/` (still frames), `touch/` (pressed frames), `truth.csv`.
    pub output: PathBuf,
    /// Rest (no-contact) frames, at least 1.
    pub rest: usize,
    /// Touch frames.
    pub touches: usize,
    /// Largest sideways drag, in marker pitches (0..1.5).
    pub max_drag: f64,
    /// Random seed.
    pub seed: u64,
}

/// The touches of a pattern series: SplitMix64 from `seed`, a fixed, documented sequence.
pub fn pattern_presses(pattern: &GridPattern, n: usize, max_drag: f64, seed: u64) -> Vec<Press> {
    let mut state = seed ^ 0x9E37_79B9_7F4A_7C15;
    let mut uniform = || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..n)
        .map(|_| {
            let ang = uniform() * std::f64::consts::TAU;
            let drag = max_drag * pattern.pitch_x_px * uniform();
            Press {
                x_px: 100.0 + 440.0 * uniform(),
                y_px: 90.0 + 300.0 * uniform(),
                sigma_px: 50.0 + 50.0 * uniform(),
                push_px: 8.0 * uniform(),
                shear_x_px: drag * ang.cos(),
                shear_y_px: drag * ang.sin(),
                grow: 0.3 * uniform(),
                stretch: 0.25 * uniform(),
            }
        })
        .collect()
}

/// Most touch frames [`write_pattern`] writes (a benchmark's frames, one folder).
pub const MAX_PATTERN_TOUCHES: usize = 100_000;

/// Writes a pattern series ([`GridPattern::IATS`]): rest frames, touch frames and the
/// presses behind them.
pub fn write_pattern(cfg: &PatternConfig) -> Result<(), SimulateError> {
    if cfg.rest == 0 {
        return Err(SimulateError::Config(
            "rest must be at least 1 (calibration needs a still frame)".into(),
        ));
    }
    if !(0.0..=1.5).contains(&cfg.max_drag) {
        return Err(SimulateError::Config(format!(
            "the largest drag must be in 0..1.5 pitches, got {}",
            cfg.max_drag
        )));
    }
    check_count("rest", cfg.rest as f64, MAX_REFERENCES, "rest frames")?;
    check_count(
        "touches",
        cfg.touches as f64,
        MAX_PATTERN_TOUCHES,
        "touch frames",
    )?;
    let pattern = GridPattern::IATS;
    let (rest_dir, touch_dir) = (cfg.output.join("rest"), cfg.output.join("touch"));
    for d in [&rest_dir, &touch_dir] {
        std::fs::create_dir_all(d).map_err(|e| {
            std::io::Error::new(
                e.kind(),
                format!("{}: cannot create folder: {e}", d.display()),
            )
        })?;
    }
    for i in 0..cfg.rest {
        let seed = cfg.seed.wrapping_mul(1_000_003).wrapping_add(i as u64);
        let (img, _) = render_grid(&pattern, None, seed);
        write_png(&rest_dir.join(format!("rest_{i:04}.png")), &img)?;
    }
    let mut truth =
        String::from("frame,x_px,y_px,sigma_px,push_px,shear_x_px,shear_y_px,grow,stretch\n");
    for (i, p) in pattern_presses(&pattern, cfg.touches, cfg.max_drag, cfg.seed)
        .iter()
        .enumerate()
    {
        let seed = cfg.seed.wrapping_mul(7_919).wrapping_add(10_000 + i as u64);
        let (img, _) = render_grid(&pattern, Some(p), seed);
        let name = format!("touch_{i:04}.png");
        write_png(&touch_dir.join(&name), &img)?;
        truth.push_str(&format!(
            "{name},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4}\n",
            p.x_px, p.y_px, p.sigma_px, p.push_px, p.shear_x_px, p.shear_y_px, p.grow, p.stretch
        ));
    }
    Ok(visuotact_io::session::write_atomically(
        &cfg.output.join("truth.csv"),
        &truth,
    )?)
}
