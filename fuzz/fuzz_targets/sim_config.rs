//! A simulated sensor's settings (`simulate --config`): the first byte picks the model (areal
//! membrane, zoo tip, cone), the rest is its JSON. Settings parse and validate or are refused,
//! never a panic; settings that validate render a frame (where the camera is small enough to
//! keep every run fast) of the camera's size.
#![no_main]

use libfuzzer_sys::fuzz_target;
use visuotact_sim::cone::{ConeConfig, ConeLoad};
use visuotact_sim::iats::{IatsConfig, Touch};
use visuotact_sim::zoo::{ZooConfig, ZooTouch};

/// Small enough that a frame renders in milliseconds.
const SMALL_PX: usize = 160 * 120;

fuzz_target!(|data: &[u8]| {
    let Some((&kind, json)) = data.split_first() else {
        return;
    };
    let text = String::from_utf8_lossy(json);
    match kind % 3 {
        0 => {
            if let Ok(cfg) = serde_json::from_str::<IatsConfig>(&text) {
                if cfg.validate().is_ok() && cfg.camera.width * cfg.camera.height <= SMALL_PX {
                    let (img, _) = visuotact_sim::iats::render(&cfg, &Touch::default(), 1)
                        .expect("a validated sensor renders its rest frame");
                    assert_eq!(
                        (img.width(), img.height()),
                        (cfg.camera.width, cfg.camera.height)
                    );
                }
            }
        }
        1 => {
            if let Ok(cfg) = serde_json::from_str::<ZooConfig>(&text) {
                if cfg.validate().is_ok() && cfg.camera.width * cfg.camera.height <= SMALL_PX {
                    let (img, _) = visuotact_sim::zoo::render(&cfg, &ZooTouch::default(), 1)
                        .expect("a validated sensor renders its rest frame");
                    assert_eq!(
                        (img.width(), img.height()),
                        (cfg.camera.width, cfg.camera.height)
                    );
                }
            }
        }
        _ => {
            if let Ok(cfg) = serde_json::from_str::<ConeConfig>(&text) {
                if cfg.validate().is_ok() && cfg.camera.width * cfg.camera.height <= SMALL_PX {
                    let load = ConeLoad::none(cfg.pressure_kpa);
                    let (img, _) = visuotact_sim::cone::render(&cfg, &load, 1)
                        .expect("a validated sensor renders its rest frame");
                    assert_eq!(
                        (img.width(), img.height()),
                        (cfg.camera.width, cfg.camera.height)
                    );
                }
            }
        }
    }
});
