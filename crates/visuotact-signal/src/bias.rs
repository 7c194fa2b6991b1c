//! Force-sensor bias from no-contact periods, with drift.
//!
//! Contract: the bias is the mean of each channel over every quiet window, joined by straight
//! lines between window centres and held constant before the first and after the last — so a
//! bias that drifts slowly is followed from one no-contact period to the next. Quiet windows
//! are given as time ranges or detected:
//!
//! 1. the signal is cut into windows of `window_s`; in each a straight line is fitted per
//!    channel, and the channel's noise σ is the median of the windows' residual standard
//!    deviations (detrended, so slow presses do not count as noise);
//! 2. a window is *flat* when, on every detection channel, both its residual deviation and
//!    the change of its line across the window are at most `flat_sigmas · σ`;
//! 3. the first window is taken as no contact (a recording starts untouched, as seed 001's
//!    procedure does), and a later flat window is quiet when every detection channel stays
//!    within `flat_sigmas · σ + max_drift_per_s · Δt` (at most `contact_threshold`) of the last
//!    quiet level, Δt after it: a held press is flat too, but sits far from the unloaded level,
//!    and a slow press cannot creep in window by window.
//!
//! ```
//! use visuotact_signal::bias::{Bias, BiasConfig};
//! // 0.5 N of bias, a 5 N press from 2 s to 4 s.
//! let t: Vec<f64> = (0..6000).map(|i| i as f64 * 1e-3).collect();
//! let f: Vec<f64> = t.iter().map(|&t| 0.5 + if (2.0..4.0).contains(&t) { 5.0 } else { 0.0 }).collect();
//! let bias = Bias::detect(&t, &[&f], &[&f], &BiasConfig::default()).unwrap();
//! assert!((bias.at(3.0)[0] - 0.5).abs() < 1e-12);
//! ```

use serde::{Deserialize, Serialize};

/// Settings of quiet-period detection.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BiasConfig {
    /// Window length, seconds.
    pub window_s: f64,
    /// A window is flat when its standard deviation is at most this many noise σ.
    pub flat_sigmas: f64,
    /// Largest change of the unloaded level between quiet windows, in signal units (N):
    /// anything further away is contact.
    pub contact_threshold: f64,
    /// Fastest bias drift followed, signal units per second.
    pub max_drift_per_s: f64,
}

impl Default for BiasConfig {
    fn default() -> Self {
        Self {
            window_s: 0.25,
            flat_sigmas: 3.0,
            contact_threshold: 0.25,
            max_drift_per_s: 0.02,
        }
    }
}

/// Why no bias could be estimated.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum BiasError {
    /// Channel lengths differ from the time base.
    #[error("channel {channel} has {len} samples, the time base {expected}")]
    Length {
        /// Channel index.
        channel: usize,
        /// Its length.
        len: usize,
        /// Samples in the time base.
        expected: usize,
    },
    /// No quiet window was found or given.
    #[error("no no-contact period found: {0}")]
    NoQuiet(String),
    /// A setting is out of range.
    #[error("bias settings: {0}")]
    Config(String),
}

/// One quiet window: its time span and each channel's mean over it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct QuietWindow {
    /// First sample's time, s.
    pub start_s: f64,
    /// Last sample's time, s.
    pub end_s: f64,
    /// Mean of each channel.
    pub level: Vec<f64>,
}

/// A bias estimate: levels at knot times, interpolated linearly.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Bias {
    /// The quiet windows it was fitted to, in time order.
    pub windows: Vec<QuietWindow>,
}

fn check_lengths(t: &[f64], channels: &[&[f64]]) -> Result<(), BiasError> {
    for (channel, c) in channels.iter().enumerate() {
        if c.len() != t.len() {
            return Err(BiasError::Length {
                channel,
                len: c.len(),
                expected: t.len(),
            });
        }
    }
    Ok(())
}

/// Mean, residual standard deviation about a fitted line, and the line's change across the
/// window.
fn line_stats(t: &[f64], v: &[f64]) -> (f64, f64, f64) {
    let n = v.len().max(1) as f64;
    let tm = t.iter().sum::<f64>() / n;
    let vm = v.iter().sum::<f64>() / n;
    let (mut stt, mut stv) = (0.0, 0.0);
    for (a, b) in t.iter().zip(v) {
        stt += (a - tm) * (a - tm);
        stv += (a - tm) * (b - vm);
    }
    let slope = if stt > 0.0 { stv / stt } else { 0.0 };
    let res = t
        .iter()
        .zip(v)
        .map(|(a, b)| (b - vm - slope * (a - tm)).powi(2))
        .sum::<f64>()
        / n;
    let span = t.last().unwrap_or(&0.0) - t.first().unwrap_or(&0.0);
    (vm, res.sqrt(), (slope * span).abs())
}

fn mean_std(v: &[f64]) -> (f64, f64) {
    let n = v.len().max(1) as f64;
    let m = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / n;
    (m, var.sqrt())
}

/// Sample index ranges of consecutive windows of `window_s` (the last may be shorter).
fn windows(t: &[f64], window_s: f64) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut start = 0;
    while start < t.len() {
        let end_t = t[start] + window_s;
        let end = start + t[start..].partition_point(|&s| s < end_t);
        let end = end.max(start + 1);
        out.push(start..end);
        start = end;
    }
    out
}

impl Bias {
    /// Fits the bias of `channels` to quiet windows detected on `detect` (e.g. the three force
    /// axes; torques follow the same windows).
    pub fn detect(
        t: &[f64],
        detect: &[&[f64]],
        channels: &[&[f64]],
        cfg: &BiasConfig,
    ) -> Result<Self, BiasError> {
        check_lengths(t, detect)?;
        check_lengths(t, channels)?;
        if !(cfg.window_s > 0.0
            && cfg.flat_sigmas > 0.0
            && cfg.contact_threshold > 0.0
            && cfg.max_drift_per_s >= 0.0)
        {
            return Err(BiasError::Config(
                "window, flat σ multiple and contact threshold must be positive, drift ≥ 0".into(),
            ));
        }
        let wins: Vec<_> = windows(t, cfg.window_s)
            .into_iter()
            .filter(|r| r.len() >= 4)
            .collect();
        if wins.is_empty() || detect.is_empty() {
            return Err(BiasError::NoQuiet(
                "the signal is shorter than a window".into(),
            ));
        }
        let stats: Vec<Vec<(f64, f64, f64)>> = wins
            .iter()
            .map(|r| {
                detect
                    .iter()
                    .map(|c| line_stats(&t[r.clone()], &c[r.clone()]))
                    .collect()
            })
            .collect();
        let sigma: Vec<f64> = (0..detect.len())
            .map(|c| {
                let mut s: Vec<f64> = stats.iter().map(|w| w[c].1).collect();
                s.sort_by(f64::total_cmp);
                s[s.len() / 2]
            })
            .collect();
        let mut last: Option<(f64, Vec<f64>)> = None;
        let mut quiet = Vec::new();
        for (r, st) in wins.iter().zip(&stats) {
            let flat = st.iter().zip(&sigma).all(|((_, sd, change), s)| {
                let lim = cfg.flat_sigmas * s.max(1e-300);
                *sd <= lim && *change <= lim
            });
            if !flat && last.is_some() {
                continue;
            }
            let level: Vec<f64> = st.iter().map(|(m, _, _)| *m).collect();
            let t_mid = 0.5 * (t[r.start] + t[r.end - 1]);
            let near = last.as_ref().is_none_or(|(t_last, l)| {
                let drift = cfg.max_drift_per_s * (t_mid - t_last);
                l.iter().zip(&level).zip(&sigma).all(|((a, b), s)| {
                    (a - b).abs() <= (cfg.flat_sigmas * s + drift).min(cfg.contact_threshold)
                })
            });
            if near {
                quiet.push(r.clone());
                last = Some((t_mid, level));
            }
        }
        if quiet.is_empty() {
            return Err(BiasError::NoQuiet(format!(
                "no window of {} s is flat within {} σ",
                cfg.window_s, cfg.flat_sigmas
            )));
        }
        Ok(Self::from_ranges(t, channels, &quiet))
    }

    /// Fits the bias of `channels` to the samples inside the given `(start_s, end_s)` ranges,
    /// each cut into windows of `window_s`.
    pub fn from_time_ranges(
        t: &[f64],
        channels: &[&[f64]],
        ranges_s: &[(f64, f64)],
        window_s: f64,
    ) -> Result<Self, BiasError> {
        check_lengths(t, channels)?;
        let mut quiet = Vec::new();
        for &(a, b) in ranges_s {
            if b.partial_cmp(&a) != Some(std::cmp::Ordering::Greater) {
                return Err(BiasError::Config(format!(
                    "no-contact range {a}..{b} s is empty"
                )));
            }
            let (i, j) = (
                t.partition_point(|&s| s < a),
                t.partition_point(|&s| s <= b),
            );
            if j > i {
                for r in windows(&t[i..j], window_s) {
                    quiet.push(i + r.start..i + r.end);
                }
            }
        }
        if quiet.is_empty() {
            return Err(BiasError::NoQuiet(format!(
                "no sample lies in the ranges {ranges_s:?}"
            )));
        }
        quiet.sort_by_key(|r| r.start);
        Ok(Self::from_ranges(t, channels, &quiet))
    }

    fn from_ranges(t: &[f64], channels: &[&[f64]], ranges: &[std::ops::Range<usize>]) -> Self {
        Self {
            windows: ranges
                .iter()
                .map(|r| QuietWindow {
                    start_s: t[r.start],
                    end_s: t[r.end - 1],
                    level: channels.iter().map(|c| mean_std(&c[r.clone()]).0).collect(),
                })
                .collect(),
        }
    }

    /// The bias of every channel at time `t_s`.
    pub fn at(&self, t_s: f64) -> Vec<f64> {
        let centre = |w: &QuietWindow| 0.5 * (w.start_s + w.end_s);
        let ws = &self.windows;
        let j = ws.partition_point(|w| centre(w) < t_s);
        if j == 0 {
            return ws[0].level.clone();
        }
        if j == ws.len() {
            return ws[ws.len() - 1].level.clone();
        }
        let (a, b) = (&ws[j - 1], &ws[j]);
        let u = (t_s - centre(a)) / (centre(b) - centre(a));
        a.level
            .iter()
            .zip(&b.level)
            .map(|(p, q)| p + u * (q - p))
            .collect()
    }

    /// Subtracts the bias from every channel in place (channels in the order it was fitted).
    pub fn remove(&self, t: &[f64], channels: &mut [&mut [f64]]) {
        for (k, &tk) in t.iter().enumerate() {
            let b = self.at(tk);
            for (c, bc) in channels.iter_mut().zip(&b) {
                c[k] -= bc;
            }
        }
    }

    /// Merged quiet periods `(start_s, end_s)` for reports.
    pub fn periods(&self, max_join_s: f64) -> Vec<(f64, f64)> {
        let mut out: Vec<(f64, f64)> = Vec::new();
        for w in &self.windows {
            match out.last_mut() {
                Some(last) if w.start_s - last.1 <= max_join_s => last.1 = w.end_s,
                _ => out.push((w.start_s, w.end_s)),
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Seeded noise without a dependency: a 64-bit LCG through Box–Muller.
    fn noise(n: usize, sigma: f64, seed: u64) -> Vec<f64> {
        let mut s = seed;
        let mut u = || {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((s >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        (0..n)
            .map(|_| sigma * (-2.0 * u().ln()).sqrt() * (std::f64::consts::TAU * u()).cos())
            .collect()
    }

    #[test]
    fn drifting_bias_under_presses_is_followed() {
        // 30 s at 1 kHz: bias drifts linearly 0.2 → 0.5 N, presses of 6 N (held flat at the
        // top) at 5–10 s and 18–24 s, noise 0.03 N.
        let t: Vec<f64> = (0..30_000).map(|i| i as f64 * 1e-3).collect();
        let n = noise(t.len(), 0.03, 7);
        let bias_true = |t: f64| 0.2 + 0.01 * t;
        let press = |t: f64| {
            let ramp =
                |a: f64, b: f64| ((t - a) / 0.5).clamp(0.0, 1.0) * ((b - t) / 0.5).clamp(0.0, 1.0);
            6.0 * (ramp(5.0, 10.0) + ramp(18.0, 24.0))
        };
        let f: Vec<f64> = t
            .iter()
            .zip(&n)
            .map(|(&t, e)| bias_true(t) + press(t) + e)
            .collect();
        let bias = Bias::detect(&t, &[&f], &[&f], &BiasConfig::default()).unwrap();
        for w in &bias.windows {
            assert!(press(w.start_s) == 0.0 && press(w.end_s) == 0.0, "{w:?}");
        }
        let periods = bias.periods(0.01);
        assert_eq!(periods.len(), 3, "{periods:?}");
        // Within the presses the interpolated bias is within 0.02 N of the drift.
        for tk in [6.0, 8.0, 20.0, 23.0, 1.0, 29.0] {
            let e = bias.at(tk)[0] - bias_true(tk);
            assert!(e.abs() < 0.02, "t {tk}: {e}");
        }
        let mut g = f.clone();
        bias.remove(&t, &mut [&mut g]);
        assert!((g[8000] - 6.0).abs() < 0.15);
    }

    #[test]
    fn given_ranges_and_errors() {
        let t: Vec<f64> = (0..1000).map(|i| i as f64 * 0.01).collect();
        let f: Vec<f64> = t.iter().map(|t| 1.0 + t).collect();
        let b = Bias::from_time_ranges(&t, &[&f], &[(0.0, 1.0), (8.0, 9.0)], 0.5).unwrap();
        assert_eq!(b.periods(0.02), vec![(0.0, 1.0), (8.0, 9.0)]);
        assert!((b.at(5.0)[0] - 6.0).abs() < 0.01);
        assert!(Bias::from_time_ranges(&t, &[&f], &[(20.0, 30.0)], 0.5).is_err());
        assert!(matches!(
            Bias::detect(&t, &[&f[..10]], &[&f], &BiasConfig::default()),
            Err(BiasError::Length { .. })
        ));
    }
}
