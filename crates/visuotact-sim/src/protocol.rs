//! Experiment protocols: the sequences of touches and loads the source documents used, with
//! frame timestamps at the camera rate. Deterministic given a seed.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::Distribution;

use crate::cone::{ConeConfig, ConeLoad};
use crate::iats::{IatsConfig, Touch};
use crate::zoo::{Surface, ZooConfig, ZooTouch};

/// Seed 000's grid: x in 4 mm steps × 16, y in 3 mm steps × 16, at depths 1..=5 mm
/// (1 280 touches), depth-major then rows then columns.
pub fn iats_grid() -> Vec<Touch> {
    iats_grid_for(&IatsConfig::SEED000)
}

/// Seed 000's grid scaled to a sensor's marker area: 16 × 16 contacts from the first to the
/// last marker row and column (seed 000: 4 mm and 3 mm steps), at depths 1..=5 mm (capped at
/// the sensor's deepest press).
pub fn iats_grid_for(cfg: &IatsConfig) -> Vec<Touch> {
    let mut out = Vec::with_capacity(1280);
    let (sx, sy) = (cfg.span_x_mm / 15.0, cfg.span_y_mm / 15.0);
    for depth in 1..=5 {
        for iy in 0..16 {
            for ix in 0..16 {
                out.push(Touch {
                    x_mm: (sx * f64::from(ix)).min(cfg.span_x_mm),
                    y_mm: (sy * f64::from(iy)).min(cfg.span_y_mm),
                    depth_mm: f64::from(depth).min(cfg.max_depth_mm),
                    ..Touch::default()
                });
            }
        }
    }
    out
}

/// Seed 000's Table 2 line: y = 30 mm, x = 4..=28 mm in 4 mm steps, 4 mm deep.
pub fn iats_line() -> Vec<Touch> {
    (1..=7)
        .map(|k| Touch {
            x_mm: 4.0 * f64::from(k),
            y_mm: 30.0,
            depth_mm: 4.0,
            ..Touch::default()
        })
        .collect()
}

/// `n` touches uniform over the marker area, depth uniform in 1..5 mm.
pub fn iats_random(cfg: &IatsConfig, n: usize, seed: u64) -> Vec<Touch> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| Touch {
            x_mm: rng.random_range(0.0..=cfg.span_x_mm),
            y_mm: rng.random_range(0.0..=cfg.span_y_mm),
            depth_mm: rng.random_range(1.0..=cfg.max_depth_mm.min(5.0)),
            ..Touch::default()
        })
        .collect()
}

/// Random touches that also drag the fabric sideways by up to one marker pitch in a random
/// direction (frames in random order, as a dataset of independent touches).
pub fn iats_shear(cfg: &IatsConfig, n: usize, seed: u64) -> Vec<Touch> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5EA5);
    let pitch = cfg.pitch_x_mm().min(cfg.pitch_y_mm());
    iats_random(cfg, n, seed)
        .into_iter()
        .map(|mut t| {
            let ang = rng.random_range(0.0..std::f64::consts::TAU);
            let drag = pitch * rng.random_range(0.0..=1.0);
            t.shear_x_mm = drag * ang.cos();
            t.shear_y_mm = drag * ang.sin();
            t
        })
        .collect()
}

/// The names [`iats_named`] knows, in the order a user reads them.
pub const IATS_PROTOCOLS: [&str; 4] = ["grid", "random", "shear", "line"];

/// An iats protocol by name: `grid` ([`iats_grid_for`]), `random`, `shear` (`n` touches from
/// `seed`) or `line`; `None` for any other name.
pub fn iats_named(cfg: &IatsConfig, name: &str, n: usize, seed: u64) -> Option<Vec<Touch>> {
    match name {
        "grid" => Some(iats_grid_for(cfg)),
        "random" => Some(iats_random(cfg, n, seed)),
        "shear" => Some(iats_shear(cfg, n, seed)),
        "line" => Some(iats_line()),
        _ => None,
    }
}

/// The names [`zoo_named`] knows (`plate` on a dome only).
pub const ZOO_PROTOCOLS: [&str; 5] = ["grid", "random", "shear", "drag", "plate"];

/// A zoo protocol by name: `grid`, `random`, `shear`, `drag` or `plate` (`n` touches from
/// `seed`); `None` for any other name, and for `plate` on a flat skin.
pub fn zoo_named(cfg: &ZooConfig, name: &str, n: usize, seed: u64) -> Option<Vec<ZooTouch>> {
    match name {
        "grid" => Some(zoo_grid(cfg)),
        "random" => Some(zoo_random(cfg, n, seed)),
        "shear" => Some(zoo_shear(cfg, n, seed)),
        "drag" => Some(zoo_drag(cfg, n, seed)),
        "plate" => zoo_plate(cfg, n, seed),
        _ => None,
    }
}

/// Steepest tilt of [`zoo_plate`]'s plate, degrees (the real 331-pin TacTip set reaches 25°).
pub const PLATE_TILT_DEG: f64 = 25.0;

/// `n` presses of a flat plate on a dome, as a robot arm presses a TacTip on a table: the plate
/// tilted by up to [`PLATE_TILT_DEG`] about a random axis, so it touches the dome of radius `R`
/// at arc `R θ` from the apex, as a ball of radius `R` ([`ZooTouch::indenter_radius_mm`]);
/// depth uniform from 10 % to 60 % of the skin's limit; slid by up to two pitches (the touch's
/// limit) in a random direction and twisted by up to ±10°. `None` on a flat skin: a tilted
/// plate meets a flat gel with its edge, which the zoo's Hertzian contact does not model.
pub fn zoo_plate(cfg: &ZooConfig, n: usize, seed: u64) -> Option<Vec<ZooTouch>> {
    if cfg.surface != Surface::Dome {
        return None;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x91A7_0400);
    let r = cfg.dome_radius_mm;
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let tilt = rng
            .random_range(-PLATE_TILT_DEG..=PLATE_TILT_DEG)
            .to_radians();
        let axis = rng.random_range(0.0..std::f64::consts::PI);
        let slide_dir = rng.random_range(0.0..std::f64::consts::TAU);
        let slide = rng.random_range(0.0..=2.0) * cfg.pitch_mm;
        let t = ZooTouch {
            x_mm: r * tilt * axis.cos(),
            y_mm: r * tilt * axis.sin(),
            depth_mm: rng.random_range(0.1..=0.6) * cfg.max_depth_mm,
            shear_x_mm: slide * slide_dir.cos(),
            shear_y_mm: slide * slide_dir.sin(),
            twist_deg: rng.random_range(-10.0..=10.0),
            slip_annulus: 0.0,
            indenter_radius_mm: Some(r),
        };
        if cfg.field_contains(t.x_mm, t.y_mm) {
            out.push(t);
        }
    }
    Some(out)
}

/// `a, b or c` from a list of names, for error messages.
pub fn names_listed(names: &[&str]) -> String {
    match names {
        [] => String::new(),
        [one] => (*one).to_string(),
        [rest @ .., last] => format!("{} or {last}", rest.join(", ")),
    }
}

/// A zoo sensor's grid: contacts on a 7 × 7 lattice over the marker field (a 9 × 9 one cut to
/// the disc on a dome) at depths 0.2, 0.4 … 1.0 of the skin's limit, depth-major.
pub fn zoo_grid(cfg: &ZooConfig) -> Vec<ZooTouch> {
    let (half_w, half_h) = match cfg.surface {
        Surface::Flat => (0.5 * cfg.field_width_mm, 0.5 * cfg.field_height_mm),
        Surface::Dome => (0.5 * cfg.field_width_mm, 0.5 * cfg.field_width_mm),
    };
    let n = match cfg.surface {
        Surface::Flat => 7,
        Surface::Dome => 9,
    };
    let mut out = Vec::new();
    for k in 1..=5 {
        for iy in 0..n {
            for ix in 0..n {
                let f = |i: usize| 2.0 * i as f64 / (n - 1) as f64 - 1.0;
                let (x, y) = (f(ix) * half_w, f(iy) * half_h);
                if cfg.field_contains(x, y) {
                    out.push(ZooTouch {
                        x_mm: x,
                        y_mm: y,
                        depth_mm: 0.2 * f64::from(k) * cfg.max_depth_mm,
                        ..ZooTouch::default()
                    });
                }
            }
        }
    }
    out
}

/// `n` touches uniform over a zoo sensor's marker field, depth uniform from 5 % of the skin's
/// limit to the limit.
pub fn zoo_random(cfg: &ZooConfig, n: usize, seed: u64) -> Vec<ZooTouch> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x200);
    let half_w = 0.5 * cfg.field_width_mm;
    let half_h = match cfg.surface {
        Surface::Flat => 0.5 * cfg.field_height_mm,
        Surface::Dome => half_w,
    };
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let (x, y) = (
            rng.random_range(-half_w..=half_w),
            rng.random_range(-half_h..=half_h),
        );
        let depth = rng.random_range(0.05..=1.0) * cfg.max_depth_mm;
        if cfg.field_contains(x, y) {
            out.push(ZooTouch {
                x_mm: x,
                y_mm: y,
                depth_mm: depth,
                ..ZooTouch::default()
            });
        }
    }
    out
}

/// Random zoo touches that also drag the skin by up to one marker pitch in a random direction
/// and twist it by up to ±10°.
pub fn zoo_shear(cfg: &ZooConfig, n: usize, seed: u64) -> Vec<ZooTouch> {
    dragged(cfg, zoo_random(cfg, n, seed), 1.0, seed ^ 0x5EA5_0200)
}

/// Random zoo touches with larger local drags: the skin under the tip dragged by 0.5 to 1.5
/// marker pitches in a random direction (the drag fades away from the contact, so neighbours
/// move by different amounts) and twisted by up to ±10° — beyond what a tracker can always
/// resolve: markers it cannot tell apart must be reported lost, never swapped.
pub fn zoo_drag(cfg: &ZooConfig, n: usize, seed: u64) -> Vec<ZooTouch> {
    let touches = dragged(cfg, zoo_random(cfg, n, seed), 1.5, seed ^ 0xD4A6_0300);
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xD4A6_0301);
    touches
        .into_iter()
        .map(|mut t| {
            // At least half a pitch: a third of the drags lie beyond one pitch.
            let (x, y) = (t.shear_x_mm, t.shear_y_mm);
            let len = x.hypot(y);
            let want = cfg.pitch_mm * rng.random_range(0.5..=1.5);
            if len > 0.0 {
                t.shear_x_mm = x / len * want;
                t.shear_y_mm = y / len * want;
            }
            t
        })
        .collect()
}

/// `touches` dragged by up to `pitches` marker pitches in a random direction and twisted by
/// up to ±10°, seeded by `seed`.
fn dragged(cfg: &ZooConfig, touches: Vec<ZooTouch>, pitches: f64, seed: u64) -> Vec<ZooTouch> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    touches
        .into_iter()
        .map(|mut t| {
            let ang = rng.random_range(0.0..std::f64::consts::TAU);
            let drag = cfg.pitch_mm * rng.random_range(0.0..=pitches);
            t.shear_x_mm = drag * ang.cos();
            t.shear_y_mm = drag * ang.sin();
            t.twist_deg = rng.random_range(-10.0..=10.0);
            t
        })
        .collect()
}

/// Pressure over time: a slow leak and the compressor's ripple.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PressureDrift {
    /// Fraction of pressure lost per second.
    pub leak_per_s: f64,
    /// Ripple amplitude, kPa.
    pub ripple_kpa: f64,
    /// Ripple frequency, Hz.
    pub ripple_hz: f64,
}

impl PressureDrift {
    /// A slightly leaky link with a small compressor ripple.
    pub const DEFAULT: Self = Self {
        leak_per_s: 0.0015,
        ripple_kpa: 0.05,
        ripple_hz: 0.5,
    };

    /// Pressure at time `t_s` for nominal pressure `p0`.
    pub fn at(&self, p0: f64, t_s: f64) -> f64 {
        p0 * (1.0 - self.leak_per_s * t_s)
            + self.ripple_kpa * (std::f64::consts::TAU * self.ripple_hz * t_s).sin()
    }
}

/// The gauge pressure sensor on the link's air line (seed 001 §3.2: a gauge sensor teed into
/// the line to the link, on a longer tube that acts as a pneumatic low-pass filter): the link's
/// pressure through a first-order lag, plus white reading noise.
///
/// The lag is applied in closed form to [`PressureDrift`] (its steady-state response: the leak
/// ramp delayed by the time constant, the ripple attenuated by `1/√(1 + (ωτ)²)` and delayed by
/// `atan(ωτ)/ω`), so a reading depends only on its time and its noise draw.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PressureGauge {
    /// Time constant of the tube and sensor, s.
    pub time_constant_s: f64,
    /// Standard deviation of the reading noise, kPa.
    pub noise_kpa: f64,
}

impl PressureGauge {
    /// A 0–10 kPa gauge (12-bit readout, a few counts of noise) on a tube with a 0.1 s lag.
    pub const SEED001: Self = Self {
        time_constant_s: 0.1,
        noise_kpa: 0.01,
    };

    /// The noise-free reading at `t_s` of a link at nominal pressure `p0` drifting as `drift`.
    pub fn mean_reading_kpa(&self, drift: &PressureDrift, p0: f64, t_s: f64) -> f64 {
        let tau = self.time_constant_s.max(0.0);
        let w = std::f64::consts::TAU * drift.ripple_hz;
        let gain = 1.0 / (1.0 + (w * tau).powi(2)).sqrt();
        let phase = (w * tau).atan();
        p0 * (1.0 - drift.leak_per_s * (t_s - tau))
            + drift.ripple_kpa * gain * (w * t_s - phase).sin()
    }

    /// The reading at `t_s` with its noise: one draw from `seed` (the same seed, the same
    /// reading).
    pub fn reading_kpa(&self, drift: &PressureDrift, p0: f64, t_s: f64, seed: u64) -> f64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let z: f64 = rand_distr::StandardNormal.sample(&mut rng);
        self.mean_reading_kpa(drift, p0, t_s) + self.noise_kpa * z
    }
}

/// A cone press: force rises smoothly from 0 to `max_force_n` and back over `duration_s`, at 30°
/// elevation; with `rotate`, the direction turns once about the axis during the press.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ConePress {
    /// Peak force, N.
    pub max_force_n: f64,
    /// Press and release time, s.
    pub duration_s: f64,
    /// Force direction about the axis at the start, radians.
    pub azimuth_rad: f64,
    /// Turn the direction about the axis (seed 001's "with rotation").
    pub rotate: bool,
    /// Largest torque about the axis, N·mm: the link is twisted back and forth,
    /// `τ = τ_max sin(2π · 3.3 · t / duration + torque_phase_rad)` — 3.3 turns per press, so
    /// that the torque cannot be told from the force's phase (0: no torque, seed 001's
    /// presses).
    pub max_torque_nmm: f64,
    /// Phase of the twist at the start of the press, radians.
    pub torque_phase_rad: f64,
    /// Pressure drift.
    pub drift: PressureDrift,
}

/// Back-and-forth twists per press of [`ConePress::max_torque_nmm`].
const TORQUE_TURNS: f64 = 3.3;

impl ConePress {
    /// Seed 001's slow press: up to 10 N over 20 s.
    pub const SEED001: Self = Self {
        max_force_n: 10.0,
        duration_s: 20.0,
        azimuth_rad: 0.0,
        rotate: false,
        max_torque_nmm: 0.0,
        torque_phase_rad: 0.0,
        drift: PressureDrift::DEFAULT,
    };

    /// The load at time `t_s` from the start of the press (no force outside `0..duration`).
    pub fn load_at(&self, cfg: &ConeConfig, t_s: f64, t0_s: f64) -> ConeLoad {
        let u = (t_s / self.duration_s).clamp(0.0, 1.0);
        let force_n = self.max_force_n * (std::f64::consts::PI * u).sin().powi(2);
        let azimuth_rad = self.azimuth_rad
            + if self.rotate {
                std::f64::consts::TAU * u
            } else {
                0.0
            };
        ConeLoad {
            force_n,
            elevation_rad: 30f64.to_radians(),
            azimuth_rad,
            pressure_kpa: self.drift.at(cfg.pressure_kpa, t0_s + t_s),
            torque_nmm: self.max_torque_nmm
                * (std::f64::consts::TAU * TORQUE_TURNS * u + self.torque_phase_rad).sin(),
        }
    }

    /// Checks the protocol.
    pub fn validate(&self) -> Result<(), crate::SimError> {
        if !(self.max_torque_nmm.is_finite() && self.torque_phase_rad.is_finite()) {
            return Err(crate::SimError::NotFinite("the peak torque and its phase"));
        }
        if !(self.max_force_n.is_finite() && self.max_force_n >= 0.0) {
            return Err(crate::SimError::out_of_range(
                "peak force",
                self.max_force_n,
                "≥ 0 N",
            ));
        }
        if !(self.duration_s.is_finite() && self.duration_s > 0.0) {
            return Err(crate::SimError::out_of_range(
                "press duration (s)",
                self.duration_s,
                "positive",
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_is_seed000s() {
        let g = iats_grid();
        assert_eq!(g.len(), 1280);
        assert_eq!((g[0].x_mm, g[0].y_mm, g[0].depth_mm), (0.0, 0.0, 1.0));
        assert_eq!(
            (g[1279].x_mm, g[1279].y_mm, g[1279].depth_mm),
            (60.0, 45.0, 5.0)
        );
        let cfg = IatsConfig::SEED000;
        assert!(g.iter().all(|t| t.validate(&cfg).is_ok()));
    }

    #[test]
    fn scaled_grids_stay_on_the_marker_area() {
        for v in 0..30 {
            let cfg = IatsConfig::variant(v);
            for t in iats_grid_for(&cfg) {
                t.validate(&cfg).unwrap();
            }
        }
    }

    #[test]
    fn zoo_touches_are_valid_and_seeded() {
        for kind in crate::zoo::ZooKind::ALL {
            for v in 0..4 {
                let cfg = ZooConfig::variant(kind, v);
                let a = zoo_shear(&cfg, 40, 3);
                assert_eq!(a, zoo_shear(&cfg, 40, 3));
                assert_ne!(a, zoo_shear(&cfg, 40, 4));
                let g = zoo_grid(&cfg);
                assert!(g.len() >= 5 * 25, "{} touches", g.len());
                for t in a.iter().chain(&g) {
                    t.validate(&cfg).unwrap();
                }
            }
        }
    }

    #[test]
    fn protocols_by_name_are_the_named_functions() {
        let cfg = IatsConfig::SEED000;
        assert_eq!(iats_named(&cfg, "grid", 9, 1), Some(iats_grid_for(&cfg)));
        assert_eq!(
            iats_named(&cfg, "random", 9, 1),
            Some(iats_random(&cfg, 9, 1))
        );
        assert_eq!(
            iats_named(&cfg, "shear", 9, 1),
            Some(iats_shear(&cfg, 9, 1))
        );
        assert_eq!(iats_named(&cfg, "line", 9, 1), Some(iats_line()));
        assert_eq!(iats_named(&cfg, "press", 9, 1), None);
        let zoo = ZooConfig::variant(crate::zoo::ZooKind::ALL[0], 0);
        assert_eq!(zoo_named(&zoo, "grid", 9, 1), Some(zoo_grid(&zoo)));
        assert_eq!(
            zoo_named(&zoo, "random", 9, 1),
            Some(zoo_random(&zoo, 9, 1))
        );
        assert_eq!(zoo_named(&zoo, "shear", 9, 1), Some(zoo_shear(&zoo, 9, 1)));
        assert_eq!(zoo_named(&zoo, "line", 9, 1), None);
        assert_eq!(zoo_named(&zoo, "plate", 9, 1), zoo_plate(&zoo, 9, 1));
        assert_eq!(
            names_listed(&ZOO_PROTOCOLS),
            "grid, random, shear, drag or plate"
        );
        assert_eq!(names_listed(&["a"]), "a");
        assert_eq!(names_listed(&[]), "");
    }

    /// A plate on a dome touches where its tilt points (arc `R θ`, `θ` ≤ 25°) as a ball of the
    /// dome's radius, slid up to two pitches; a flat skin has no plate protocol.
    #[test]
    fn plate_presses_touch_where_the_tilt_points() {
        let dome = ZooConfig::variant(crate::zoo::ZooKind::Tactip, 3);
        let touches = zoo_plate(&dome, 200, 5).unwrap();
        assert_eq!(touches.len(), 200);
        assert_eq!(touches, zoo_plate(&dome, 200, 5).unwrap());
        let r = dome.dome_radius_mm;
        let mut steepest = 0.0f64;
        for t in &touches {
            t.validate(&dome).unwrap();
            assert_eq!(t.indenter_radius_mm, Some(r));
            let tilt_deg = (t.x_mm.hypot(t.y_mm) / r).to_degrees();
            assert!(tilt_deg <= PLATE_TILT_DEG + 1e-9, "{t:?}");
            steepest = steepest.max(tilt_deg);
            assert!(t.shear_x_mm.hypot(t.shear_y_mm) <= 2.0 * dome.pitch_mm + 1e-9);
        }
        assert!(steepest > 0.9 * PLATE_TILT_DEG, "steepest tilt {steepest}°");
        assert_eq!(zoo_plate(&ZooConfig::GELSIGHT, 5, 5), None);
        assert_eq!(zoo_named(&ZooConfig::GELSIGHT, "plate", 5, 5), None);
    }

    #[test]
    fn random_and_shear_touches_are_valid_and_seeded() {
        let cfg = IatsConfig::SEED000;
        let a = iats_shear(&cfg, 50, 3);
        assert_eq!(a, iats_shear(&cfg, 50, 3));
        assert_ne!(a, iats_shear(&cfg, 50, 4));
        assert!(a.iter().all(|t| t.validate(&cfg).is_ok()));
        assert!(a
            .iter()
            .any(|t| t.shear_x_mm.hypot(t.shear_y_mm) > 0.8 * cfg.pitch_x_mm()));
    }

    #[test]
    fn gauge_lags_the_link_pressure_as_a_first_order_filter() {
        let g = PressureGauge {
            time_constant_s: 0.2,
            noise_kpa: 0.0,
        };
        let d = PressureDrift::DEFAULT;
        // Integrate τ·y' + y = p(t) numerically from well before; after the transient the
        // closed form must agree.
        let (dt, tau) = (1e-4, 0.2);
        let mut t = -5.0;
        let mut y = d.at(4.0, t);
        while t < 3.0 {
            y += dt / tau * (d.at(4.0, t) - y);
            t += dt;
        }
        let closed = g.mean_reading_kpa(&d, 4.0, t);
        assert!((y - closed).abs() < 2e-4, "{y} vs {closed}");
        // No lag: the reading is the pressure.
        let none = PressureGauge {
            time_constant_s: 0.0,
            noise_kpa: 0.0,
        };
        assert!((none.mean_reading_kpa(&d, 4.0, 1.3) - d.at(4.0, 1.3)).abs() < 1e-12);
        // Noise: seeded, with the stated spread.
        let n = PressureGauge::SEED001;
        let r: Vec<f64> = (0..4000)
            .map(|k| n.reading_kpa(&d, 4.0, 1.0, k) - n.mean_reading_kpa(&d, 4.0, 1.0))
            .collect();
        assert_eq!(
            n.reading_kpa(&d, 4.0, 1.0, 9),
            n.reading_kpa(&d, 4.0, 1.0, 9)
        );
        let sd = (r.iter().map(|v| v * v).sum::<f64>() / r.len() as f64).sqrt();
        assert!((sd / n.noise_kpa - 1.0).abs() < 0.05, "noise sd {sd}");
    }

    #[test]
    fn press_rises_and_falls() {
        let c = ConeConfig::SEED001;
        let p = ConePress::SEED001;
        assert_eq!(p.load_at(&c, 0.0, 0.0).force_n, 0.0);
        assert!((p.load_at(&c, 10.0, 0.0).force_n - 10.0).abs() < 1e-9);
        assert!(p.load_at(&c, 20.0, 0.0).force_n < 1e-9);
        let r = ConePress { rotate: true, ..p };
        assert!((r.load_at(&c, 10.0, 0.0).azimuth_rad - std::f64::consts::PI).abs() < 1e-9);
    }
}

/// What a simulated grasp does ([`zoo_slip`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GraspKind {
    /// A press, held.
    Press,
    /// A press, then a sideways load that stays under the friction limit (60 % of it): the
    /// rim slides a little, the centre sticks, the object does not slip.
    Drag,
    /// A press, then a twist of up to 10°, held.
    Twist,
    /// A press, then a sideways load that reaches the friction limit: the sliding annulus
    /// grows inwards until the whole contact slides, and the object slides over the skin.
    Slip,
    /// A press, then the grip shaken with the object held: a sideways load swinging back and
    /// forth within 60 % of the friction limit (a period of 12 frames, about 2 Hz at 25 fps):
    /// the rim slides a little at each swing, the centre sticks, the object does not slip (the
    /// real GelSight grasps' negatives are shakes).
    Shake,
}

impl GraspKind {
    /// Every kind, in the order of [`GraspKind::PROTOCOLS`].
    pub const ALL: [GraspKind; 5] = [
        GraspKind::Press,
        GraspKind::Drag,
        GraspKind::Twist,
        GraspKind::Slip,
        GraspKind::Shake,
    ];

    /// The protocol names `simulate` takes for grasps ([`zoo_slip`]).
    pub const PROTOCOLS: [&'static str; 5] = [
        "grasp-press",
        "grasp-drag",
        "grasp-twist",
        "grasp-slip",
        "grasp-shake",
    ];

    /// The kind of a grasp protocol's name (`grasp-slip`), if it is one.
    pub fn from_protocol(name: &str) -> Option<Self> {
        Self::PROTOCOLS
            .iter()
            .position(|p| *p == name)
            .map(|k| Self::ALL[k])
    }
}

impl GraspSequence {
    /// The truth of frame `k`, as the slip detector's states: 0 stick (no sideways load yet),
    /// 1 incipient (the rim slides, the centre sticks), 2 slip (the whole contact slides).
    pub fn state_at(&self, k: usize) -> u8 {
        if self.slip_frame.is_some_and(|s| k >= s) {
            2
        } else if self.incipient_frame.is_some_and(|s| k >= s) {
            1
        } else {
            0
        }
    }
}

/// A simulated grasp frame by frame, with when it slipped.
#[derive(Clone, Debug, PartialEq)]
pub struct GraspSequence {
    /// One touch per frame.
    pub touches: Vec<ZooTouch>,
    /// The first frame under a sideways load (the rim starts to slide), if any.
    pub incipient_frame: Option<usize>,
    /// The first frame at the friction limit: the whole contact slides from here.
    pub slip_frame: Option<usize>,
}

/// A grasp of `frames` frames (at least 60) on `cfg`'s skin: 10 frames of rest, a press over
/// 10, then what `kind` does, seeded by `seed` (where, how deep, which way, how fast). The
/// sideways load `q` (a share of the friction limit) rises linearly over 30–50 frames (drawn,
/// whole frames: a slip's whole contact slides from frame 50–70); by Cattaneo–Mindlin the
/// sticking centre's radius is `a (1 − q)^{1/3}` and the skin's drag `δ (1 − (1 − q)^{2/3})`,
/// with `δ` 0.6 marker pitches at the limit. Past the limit (`Slip`) the drag stays at `δ`
/// and the contact slides over the skin by 0.04 pitches a frame. A shake swings `q` as
/// `0.6 sin(2π k / 12)` from the press on, the drag and the annulus following `|q|`, the drag
/// its sign.
pub fn zoo_slip(cfg: &ZooConfig, kind: GraspKind, frames: usize, seed: u64) -> GraspSequence {
    let frames = frames.max(60);
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x511F_0400);
    let half = 0.2 * cfg.field_width_mm.min(cfg.field_height_mm);
    let (x0, y0) = (
        rng.random_range(-half..=half),
        rng.random_range(-half..=half),
    );
    let depth = rng.random_range(0.5..=0.9) * cfg.max_depth_mm.min(2.0);
    let ang = rng.random_range(0.0..std::f64::consts::TAU);
    let (cx, sy) = (ang.cos(), ang.sin());
    let delta = 0.6 * cfg.pitch_mm;
    let ramp = f64::from(rng.random_range(30u32..=50));
    let (rest, pressed) = (10, 20);
    let q_end = match kind {
        GraspKind::Slip => 1.0,
        GraspKind::Drag | GraspKind::Shake => 0.6,
        GraspKind::Press | GraspKind::Twist => 0.0,
    };
    let mut out = GraspSequence {
        touches: Vec::with_capacity(frames),
        incipient_frame: (q_end > 0.0).then_some(pressed + 1),
        slip_frame: None,
    };
    let mut slid = 0.0;
    for k in 0..frames {
        let mut t = ZooTouch {
            x_mm: x0,
            y_mm: y0,
            ..ZooTouch::default()
        };
        if k >= rest {
            t.depth_mm = depth * ((k - rest) as f64 / (pressed - rest) as f64).min(1.0);
        }
        if k > pressed {
            let along = (k - pressed) as f64 / ramp;
            let q = if kind == GraspKind::Shake {
                q_end * (std::f64::consts::TAU * (k - pressed) as f64 / 12.0).sin()
            } else {
                (q_end * along).min(q_end)
            };
            if q >= 1.0 {
                out.slip_frame.get_or_insert(k);
                slid += 0.04 * cfg.pitch_mm;
            }
            let drag = q.signum() * delta * (1.0 - (1.0 - q.abs()).max(0.0).powf(2.0 / 3.0));
            t.shear_x_mm = drag * cx;
            t.shear_y_mm = drag * sy;
            t.slip_annulus = 1.0 - (1.0 - q.abs()).max(0.0).cbrt();
            t.x_mm += slid * cx;
            t.y_mm += slid * sy;
            if kind == GraspKind::Twist {
                t.twist_deg = 10.0
                    * along.min(1.0)
                    * if ang > std::f64::consts::PI {
                        -1.0
                    } else {
                        1.0
                    };
            }
        }
        out.touches.push(t);
    }
    out
}

#[cfg(test)]
mod slip_tests {
    use super::*;
    use crate::zoo::displacement_mm;

    #[test]
    fn a_slip_grows_its_annulus_to_the_whole_contact_then_slides_and_a_drag_never_does() {
        let cfg = ZooConfig::GELSIGHT;
        let s = zoo_slip(&cfg, GraspKind::Slip, 90, 3);
        let at = s.slip_frame.unwrap();
        assert_eq!(s.incipient_frame, Some(21));
        assert!((50..=70).contains(&at), "{at}");
        // Seeds draw the load's rise: the onsets are not all one frame.
        let onsets: std::collections::BTreeSet<_> = (0..8)
            .map(|k| zoo_slip(&cfg, GraspKind::Slip, 90, k).slip_frame)
            .collect();
        assert!(onsets.len() >= 4, "{onsets:?}");
        let annulus: Vec<f64> = s.touches.iter().map(|t| t.slip_annulus).collect();
        assert!(annulus.windows(2).all(|w| w[1] >= w[0]));
        assert!(annulus[at - 1] < 1.0 && annulus[at] == 1.0);
        let moved = |t: &ZooTouch| (t.x_mm - s.touches[0].x_mm).hypot(t.y_mm - s.touches[0].y_mm);
        assert!(s.touches[..at].iter().all(|t| moved(t) == 0.0));
        let slid = (90 - at) as f64 * 0.04 * cfg.pitch_mm;
        assert!((moved(&s.touches[89]) - slid).abs() < 1e-9);
        for t in &s.touches {
            t.validate(&cfg).unwrap();
        }
        let d = zoo_slip(&cfg, GraspKind::Drag, 90, 3);
        assert_eq!(d.slip_frame, None);
        let most = d.touches.iter().map(|t| t.slip_annulus).fold(0.0, f64::max);
        assert!((most - (1.0 - 0.4f64.cbrt())).abs() < 1e-12, "{most}");
        // A shake swings the drag both ways, within the drag's limit, and never slips.
        let k = zoo_slip(&cfg, GraspKind::Shake, 90, 3);
        assert_eq!((k.incipient_frame, k.slip_frame), (Some(21), None));
        let first = k.touches[22];
        let along: Vec<f64> = k
            .touches
            .iter()
            .map(|t| t.shear_x_mm * first.shear_x_mm + t.shear_y_mm * first.shear_y_mm)
            .collect();
        assert!(along.iter().any(|&a| a > 0.0) && along.iter().any(|&a| a < 0.0));
        let widest = k.touches.iter().map(|t| t.slip_annulus).fold(0.0, f64::max);
        assert!((widest - (1.0 - 0.4f64.cbrt())).abs() < 1e-12, "{widest}");
        let moved = |t: &ZooTouch| (t.x_mm - k.touches[0].x_mm).hypot(t.y_mm - k.touches[0].y_mm);
        assert!(k.touches.iter().all(|t| moved(t) == 0.0));
        for t in &k.touches {
            t.validate(&cfg).unwrap();
        }
        for kind in [GraspKind::Press, GraspKind::Twist] {
            let p = zoo_slip(&cfg, kind, 60, 3);
            assert_eq!((p.incipient_frame, p.slip_frame), (None, None));
            assert!(p
                .touches
                .iter()
                .all(|t| t.slip_annulus == 0.0 && t.shear_x_mm == 0.0));
        }
    }

    #[test]
    fn under_partial_slip_the_centre_follows_the_drag_and_the_rim_lags() {
        let cfg = ZooConfig::GELSIGHT;
        let stuck = ZooTouch {
            depth_mm: 1.0,
            shear_x_mm: 0.5,
            ..ZooTouch::default()
        };
        let a = (cfg.tip_radius_mm * stuck.depth_mm).sqrt();
        let slipping = ZooTouch {
            slip_annulus: 0.5,
            ..stuck
        };
        let along = |t: &ZooTouch, r: f64| {
            displacement_mm(&cfg, t, r, 0.0)[0]
                - displacement_mm(
                    &cfg,
                    &ZooTouch {
                        shear_x_mm: 0.0,
                        ..*t
                    },
                    r,
                    0.0,
                )[0]
        };
        // The centre, inside the sticking radius a/2: the whole drag, with or without slip.
        assert!((along(&slipping, 0.2 * a) - 0.5).abs() < 1e-12);
        assert!((along(&stuck, 0.2 * a) - 0.5).abs() < 1e-12);
        // Halfway across the annulus: 7/8 of it; at the edge, 3/4.
        assert!((along(&slipping, 0.75 * a) - 0.5 * 0.875).abs() < 1e-12);
        assert!((along(&slipping, a) - 0.5 * 0.75).abs() < 1e-12);
        assert!((along(&stuck, a) - 0.5).abs() < 1e-12);
    }
}
