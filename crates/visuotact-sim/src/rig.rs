//! Simulated rigs as the command line, the demo and live runs use them: one seed mixer for
//! every frame's noise ([`frame_seed`]), the cone's label row with its pressure gauge
//! ([`cone_labels`]), the looping camera of a live run ([`live_frames`]) and the recorder's rigs
//! ([`SimRig`]).

use crate::cone::{ConeConfig, ConeLoad};
use crate::iats::{IatsConfig, Touch};
use crate::protocol::{ConePress, PressureGauge};
use rayon::prelude::*;
use visuotact_image::RgbImage;

use crate::SimError;

/// Per-frame noise seed: SplitMix64 of the session seed and the frame number.
pub fn frame_seed(seed: u64, k: u64) -> u64 {
    let mut z = seed.wrapping_add(k.wrapping_add(1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Label columns of a simulated cone: the true load and link pressure, and the reading of the
/// link's pressure gauge (lagged and noisy, as a real one: an input a network may use).
pub const CONE_LABELS: [&str; 6] = [
    "force_n",
    "fx_n",
    "fy_n",
    "fz_n",
    "pressure_kpa",
    "gauge_kpa",
];

/// Mixed into the session seed for the pressure gauge's reading noise.
pub const GAUGE_SEED: u64 = 0x6761_7567_655F_6B70;

/// One frame's [`CONE_LABELS`] row: the load at time `t_s` of a link drifting as `press` says,
/// and the gauge's reading then, its noise drawn from `gauge_seed`.
pub fn cone_labels(
    cfg: &ConeConfig,
    press: &ConePress,
    load: &ConeLoad,
    t_s: f64,
    gauge_seed: u64,
) -> Vec<f64> {
    let [fx, fy, fz] = load.components_n();
    let gauge = PressureGauge::SEED001.reading_kpa(&press.drift, cfg.pressure_kpa, t_s, gauge_seed);
    vec![load.force_n, fx, fy, fz, load.pressure_kpa, gauge]
}

/// The frames a simulated camera loops over in a live run (`visuotact run --source sim:KIND`):
/// `n` (at least 2) frames of seed 000's sensor (`iats`: 40 % without contact, then random
/// touches) or seed 001's cone (`cone`: 30 % at rest, then one press and release), named
/// `KIND_NNNN`, each frame's noise from [`frame_seed`], rendered on demand by
/// [`LiveFrames::frame`] — so a long loop costs no memory. Unknown kinds say what is expected.
pub struct LiveFrames {
    scene: LiveScene,
    n: usize,
    seed: u64,
}

/// What a [`LiveFrames`] draws.
enum LiveScene {
    Iats {
        cfg: IatsConfig,
        touches: Vec<Touch>,
    },
    Cone {
        cfg: ConeConfig,
        press: ConePress,
    },
}

impl LiveFrames {
    /// The loop of `n` (at least 2) frames of sensor `kind` (`iats` or `cone`).
    pub fn new(kind: &str, n: usize, seed: u64) -> Result<Self, SimError> {
        let n = n.max(2);
        let scene = match kind {
            "iats" => {
                let cfg = IatsConfig::SEED000;
                let touches = crate::protocol::iats_random(&cfg, n, seed);
                LiveScene::Iats { cfg, touches }
            }
            "cone" => LiveScene::Cone {
                cfg: ConeConfig::SEED001,
                press: ConePress {
                    duration_s: 1.0,
                    ..ConePress::SEED001
                },
            },
            other => return Err(crate::SimError::UnknownRig(other.to_string())),
        };
        Ok(Self { scene, n, seed })
    }

    /// Frames in the loop.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Never: a loop holds at least 2 frames.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Frame `k` of the loop (`k < len()`) and its name.
    pub fn frame(&self, k: usize) -> Result<(String, RgbImage), SimError> {
        let (n, noise) = (self.n, frame_seed(self.seed, k as u64));
        match &self.scene {
            LiveScene::Iats { cfg, touches } => {
                let t = if k < n * 2 / 5 {
                    Touch::default()
                } else {
                    touches[k]
                };
                let img = crate::iats::render(cfg, &t, noise)?.0;
                Ok((format!("iats_{k:04}"), img))
            }
            LiveScene::Cone { cfg, press } => {
                let u = k as f64 / n as f64;
                let load = if u < 0.3 {
                    ConeLoad::none(cfg.pressure_kpa)
                } else {
                    ConeLoad {
                        pressure_kpa: cfg.pressure_kpa,
                        ..press.load_at(cfg, (u - 0.3) / 0.7, 0.0)
                    }
                };
                let img = crate::cone::render(cfg, &load, noise)?.0;
                Ok((format!("cone_{k:04}"), img))
            }
        }
    }
}

/// Every frame of [`LiveFrames::new`]`(kind, n, seed)`, rendered in parallel.
pub fn live_frames(
    kind: &str,
    n: usize,
    seed: u64,
) -> Result<Vec<(String, RgbImage)>, crate::SimError> {
    let frames = LiveFrames::new(kind, n, seed)?;
    (0..frames.len())
        .into_par_iter()
        .map(|k| frames.frame(k))
        .collect()
}

/// A simulated rig for recording: frames on a real-time clock and the truth behind them.
#[derive(Clone, Debug)]
pub enum SimRig {
    /// Seed 001's cone: rest, one press and release, rest; labels [`CONE_LABELS`].
    Cone {
        /// The link.
        cfg: ConeConfig,
        /// The press.
        press: ConePress,
        /// Rest before and after the press, seconds.
        rest_s: f64,
    },
    /// Seed 000's membrane: one random touch per frame; labels `x_mm, y_mm, depth_mm`.
    Iats {
        /// The sensor.
        cfg: IatsConfig,
        /// The touches, cycled.
        touches: Vec<Touch>,
    },
}

impl SimRig {
    /// Seed 001's cone pressed for `press_s` up to `max_force_n`, with `rest_s` at rest
    /// before and after.
    pub fn cone(press_s: f64, max_force_n: f64, rest_s: f64) -> Result<Self, SimError> {
        let press = ConePress {
            max_force_n,
            duration_s: press_s,
            ..ConePress::SEED001
        };
        press.validate()?;
        if !(rest_s.is_finite() && rest_s >= 0.0) {
            return Err(SimError::out_of_range("rest (s)", rest_s, "≥ 0"));
        }
        Ok(Self::Cone {
            cfg: ConeConfig::SEED001,
            press,
            rest_s,
        })
    }

    /// Seed 000's membrane under `n` random touches drawn with `seed`.
    pub fn iats(n: usize, seed: u64) -> Self {
        let cfg = IatsConfig::SEED000;
        Self::Iats {
            touches: crate::protocol::iats_random(&cfg, n.max(1), seed),
            cfg,
        }
    }

    /// The label columns of [`SimRig::frame`].
    pub fn label_columns(&self) -> Vec<&'static str> {
        match self {
            Self::Cone { .. } => CONE_LABELS.to_vec(),
            Self::Iats { .. } => vec!["x_mm", "y_mm", "depth_mm"],
        }
    }

    /// The session's length at `fps`, seconds.
    pub fn total_s(&self, fps: f64) -> f64 {
        match self {
            Self::Cone { press, rest_s, .. } => press.duration_s + 2.0 * rest_s,
            Self::Iats { touches, .. } => touches.len() as f64 / fps,
        }
    }

    /// The cone's load at `t` s: `press` after `rest_s` at rest, the drifting link at rest
    /// otherwise.
    pub fn cone_load(cfg: &ConeConfig, press: &ConePress, rest_s: f64, t: f64) -> ConeLoad {
        if t >= rest_s && t <= rest_s + press.duration_s {
            press.load_at(cfg, t - rest_s, rest_s)
        } else {
            ConeLoad::none(press.drift.at(cfg.pressure_kpa, t))
        }
    }

    /// A contact-free reference frame, its noise from `seed`.
    pub fn reference(&self, seed: u64) -> Result<RgbImage, SimError> {
        Ok(match self {
            Self::Cone { cfg, .. } => {
                crate::cone::render(cfg, &ConeLoad::none(cfg.pressure_kpa), seed)?.0
            }
            Self::Iats { cfg, .. } => crate::iats::render(cfg, &Touch::default(), seed)?.0,
        })
    }

    /// Frame `k` at time `t_s`: image and labels (the gauge's noise and the frame's from
    /// `seed`).
    pub fn frame(&self, k: usize, t_s: f64, seed: u64) -> Result<(RgbImage, Vec<f64>), SimError> {
        match self {
            Self::Cone { cfg, press, rest_s } => {
                let load = Self::cone_load(cfg, press, *rest_s, t_s);
                let img = crate::cone::render(cfg, &load, seed)?.0;
                Ok((img, cone_labels(cfg, press, &load, t_s, seed ^ GAUGE_SEED)))
            }
            Self::Iats { cfg, touches } => {
                let t = &touches[k % touches.len()];
                let img = crate::iats::render(cfg, t, seed)?.0;
                Ok((img, vec![t.x_mm, t.y_mm, t.depth_mm]))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_seeds_differ_by_frame_and_session() {
        let seeds: Vec<u64> = (0..100).map(|k| frame_seed(1, k)).collect();
        let mut unique = seeds.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), 100);
        assert_ne!(frame_seed(1, 0), frame_seed(2, 0));
        assert_eq!(frame_seed(7, 3), frame_seed(7, 3));
    }

    #[test]
    fn a_cone_rig_rests_presses_and_rests() {
        let rig = SimRig::cone(1.0, 5.0, 0.5).unwrap();
        assert_eq!(rig.total_s(25.0), 2.0);
        assert_eq!(rig.label_columns(), CONE_LABELS);
        let (_, rest) = rig.frame(0, 0.1, 1).unwrap();
        let (_, pressed) = rig.frame(25, 1.0, 1).unwrap();
        assert_eq!(rest[0], 0.0);
        assert!(pressed[0] > 1.0, "{pressed:?}");
        assert!(SimRig::cone(1.0, 5.0, -1.0).is_err());
        let iats = SimRig::iats(3, 7);
        assert_eq!(iats.total_s(3.0), 1.0);
        assert_eq!(iats.frame(4, 0.0, 1).unwrap().1.len(), 3);
    }

    #[test]
    fn live_frames_rest_then_touch() {
        let f = live_frames("iats", 5, 1).unwrap();
        assert_eq!(f.len(), 5);
        assert_eq!(f[4].0, "iats_0004");
        assert_ne!(f[0].1, f[1].1, "noise differs frame to frame");
        assert_eq!(
            live_frames("gelsight", 2, 1).unwrap_err(),
            crate::SimError::UnknownRig("gelsight".into())
        );
    }
}
