//! A simulated JR3 six-axis force/torque sensor: 1 kHz samples of the true load plus white
//! noise and a slowly drifting bias (a random walk), deterministic given a seed.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Fastest sample rate simulated, Hz: beyond the fastest six-axis sensors (8 kHz), and a
/// bound on the stream's length.
pub const MAX_RATE_HZ: f64 = 100_000.0;

/// Sensor parameters.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Jr3Config {
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// White noise on each force axis, N (standard deviation).
    pub noise_n: f64,
    /// White noise on each torque axis, N·m.
    pub noise_nm: f64,
    /// Bias random walk on each force axis, N per √s.
    pub bias_walk_n: f64,
    /// Bias random walk on each torque axis, N·m per √s.
    pub bias_walk_nm: f64,
    /// Bias at the start, `[fx, fy, fz, tx, ty, tz]`.
    pub initial_bias: [f64; 6],
    /// Distance from the sensor's origin to the point of contact along the tool axis, mm.
    pub lever_arm_mm: f64,
}

impl Jr3Config {
    /// A JR3 at 1 kHz as in seed 001.
    pub const JR3_1KHZ: Self = Self {
        rate_hz: 1000.0,
        noise_n: 0.03,
        noise_nm: 0.002,
        bias_walk_n: 0.01,
        bias_walk_nm: 0.001,
        initial_bias: [0.12, -0.08, 0.25, 0.004, -0.003, 0.001],
        lever_arm_mm: 60.0,
    };

    /// Checks the parameters.
    pub fn validate(&self) -> Result<(), crate::SimError> {
        if !(self.rate_hz.is_finite() && self.rate_hz > 0.0 && self.rate_hz <= MAX_RATE_HZ) {
            return Err(crate::SimError::out_of_range(
                "force sample rate",
                self.rate_hz,
                format!("positive and at most {MAX_RATE_HZ} Hz"),
            ));
        }
        for (name, v) in [
            ("force noise_n", self.noise_n),
            ("force noise_nm", self.noise_nm),
            ("force bias_walk_n", self.bias_walk_n),
            ("force bias_walk_nm", self.bias_walk_nm),
            ("force lever_arm_mm", self.lever_arm_mm),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(crate::SimError::out_of_range(name, v, "≥ 0"));
            }
        }
        Ok(())
    }
}

impl Default for Jr3Config {
    fn default() -> Self {
        Self::JR3_1KHZ
    }
}

/// Generates samples one at a time.
pub struct Jr3 {
    cfg: Jr3Config,
    rng: ChaCha8Rng,
    unit: Normal<f64>,
    bias: [f64; 6],
}

impl Jr3 {
    /// A sensor with its noise fixed by `seed`.
    pub fn new(cfg: Jr3Config, seed: u64) -> Self {
        // Our own constant parameters: a unit normal always exists.
        let unit = Normal::new(0.0, 1.0).expect("unit normal distribution");
        Self {
            cfg,
            rng: ChaCha8Rng::seed_from_u64(seed),
            unit,
            bias: cfg.initial_bias,
        }
    }

    /// The next sample `[fx, fy, fz, tx, ty, tz]` (N, N·m) for the true force `force_n`
    /// applied at the contact point; advances the bias by one sample period.
    pub fn sample(&mut self, force_n: [f64; 3]) -> [f64; 6] {
        let dt = 1.0 / self.cfg.rate_hz;
        // Torque about the sensor origin of a force applied `lever` mm along +z: r × F.
        let lever_m = self.cfg.lever_arm_mm * 1e-3;
        let truth = [
            force_n[0],
            force_n[1],
            force_n[2],
            -lever_m * force_n[1],
            lever_m * force_n[0],
            0.0,
        ];
        let mut out = [0.0; 6];
        for k in 0..6 {
            let (noise, walk) = if k < 3 {
                (self.cfg.noise_n, self.cfg.bias_walk_n)
            } else {
                (self.cfg.noise_nm, self.cfg.bias_walk_nm)
            };
            self.bias[k] += walk * dt.sqrt() * self.unit.sample(&mut self.rng);
            out[k] = truth[k] + self.bias[k] + noise * self.unit.sample(&mut self.rng);
        }
        out
    }

    /// The current bias.
    pub fn bias(&self) -> [f64; 6] {
        self.bias
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_and_bias_have_the_configured_size() {
        let cfg = Jr3Config {
            bias_walk_n: 0.0,
            bias_walk_nm: 0.0,
            ..Jr3Config::JR3_1KHZ
        };
        let mut s = Jr3::new(cfg, 5);
        let n = 20000;
        let xs: Vec<[f64; 6]> = (0..n).map(|_| s.sample([1.0, 0.0, -2.0])).collect();
        let mean = |k: usize| xs.iter().map(|x| x[k]).sum::<f64>() / n as f64;
        let sd =
            |k: usize| (xs.iter().map(|x| (x[k] - mean(k)).powi(2)).sum::<f64>() / n as f64).sqrt();
        assert!((mean(0) - 1.12).abs() < 0.002 && (mean(2) + 1.75).abs() < 0.002);
        assert!((sd(0) - 0.03).abs() < 0.002);
        // Torque of 1 N along x at 60 mm: ty = 0.06 N·m.
        assert!((mean(4) - (0.06 - 0.003)).abs() < 1e-3);
    }

    #[test]
    fn same_seed_same_stream() {
        let mut a = Jr3::new(Jr3Config::JR3_1KHZ, 9);
        let mut b = Jr3::new(Jr3Config::JR3_1KHZ, 9);
        for _ in 0..100 {
            assert_eq!(a.sample([0.5, 0.5, 0.5]), b.sample([0.5, 0.5, 0.5]));
        }
    }
}
