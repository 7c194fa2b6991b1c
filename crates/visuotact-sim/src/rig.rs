//! Simulated rigs as the command line, the demo and live runs use them: one seed mixer for
//! every frame's noise ([`frame_seed`]), the cone's label row with its pressure gauge
//! ([`cone_labels`]), and the looping camera of a live run ([`live_frames`]).

use crate::cone::{ConeConfig, ConeLoad};
use crate::iats::{IatsConfig, Touch};
use crate::protocol::{ConePress, PressureGauge};
use rayon::prelude::*;
use visuotact_image::RgbImage;

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
/// `KIND_NNNN`, each frame's noise from [`frame_seed`], rendered in parallel. Unknown kinds say what is expected.
pub fn live_frames(
    kind: &str,
    n: usize,
    seed: u64,
) -> Result<Vec<(String, RgbImage)>, crate::SimError> {
    let n = n.max(2);
    match kind {
        "iats" => {
            let cfg = IatsConfig::SEED000;
            let touches = crate::protocol::iats_random(&cfg, n, seed);
            (0..n)
                .into_par_iter()
                .map(|k| {
                    let t = if k < n * 2 / 5 {
                        Touch::default()
                    } else {
                        touches[k]
                    };
                    let img = crate::iats::render(&cfg, &t, frame_seed(seed, k as u64))?.0;
                    Ok((format!("iats_{k:04}"), img))
                })
                .collect()
        }
        "cone" => {
            let cfg = ConeConfig::SEED001;
            let press = ConePress {
                duration_s: 1.0,
                ..ConePress::SEED001
            };
            (0..n)
                .into_par_iter()
                .map(|k| {
                    let u = k as f64 / n as f64;
                    let load = if u < 0.3 {
                        ConeLoad::none(cfg.pressure_kpa)
                    } else {
                        ConeLoad {
                            pressure_kpa: cfg.pressure_kpa,
                            ..press.load_at(&cfg, (u - 0.3) / 0.7, 0.0)
                        }
                    };
                    let img = crate::cone::render(&cfg, &load, frame_seed(seed, k as u64))?.0;
                    Ok((format!("cone_{k:04}"), img))
                })
                .collect()
        }
        other => Err(crate::SimError(format!(
            "sim:{other}: expected sim:iats or sim:cone"
        ))),
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
    fn live_frames_rest_then_touch() {
        let f = live_frames("iats", 5, 1).unwrap();
        assert_eq!(f.len(), 5);
        assert_eq!(f[4].0, "iats_0004");
        assert_ne!(f[0].1, f[1].1, "noise differs frame to frame");
        assert!(live_frames("gelsight", 2, 1)
            .unwrap_err()
            .0
            .contains("expected sim:iats"));
    }
}
