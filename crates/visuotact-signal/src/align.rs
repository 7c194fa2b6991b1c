//! Force samples onto frame timestamps.
//!
//! Contract: the value at a frame time `t` is the straight-line interpolation of the two force
//! samples around `t + offset_s` (`offset_s` is the latency correction: negative when the frame
//! shows the contact later than the force sensor saw it). Times outside the samples, or inside
//! a gap longer than `max_gap_s` (lost packets), give `None` — never an extrapolated number.
//!
//! ```
//! use visuotact_signal::align::Resampler;
//! let t = [0.0, 0.001, 0.002, 0.003];
//! let r = Resampler::new(&t, &[0.0015, 0.0105], 0.0, 0.01).unwrap();
//! assert_eq!(r.apply(&[0.0, 1.0, 2.0, 3.0]), vec![Some(1.5), None]);
//! ```

/// Why samples cannot be resampled.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum AlignError {
    /// The source times are not strictly increasing at this sample.
    #[error("force timestamps must increase: sample {index} is at {t_s} s, after {prev_s} s")]
    NotIncreasing {
        /// Index of the offending sample.
        index: usize,
        /// Its time.
        t_s: f64,
        /// The previous sample's time.
        prev_s: f64,
    },
    /// A time is not finite.
    #[error("time {index} is not a finite number")]
    NotFinite {
        /// Index of the offending time.
        index: usize,
    },
}

/// Interpolation indices and weights from one time base to another, reused for every channel.
#[derive(Clone, Debug, PartialEq)]
pub struct Resampler {
    /// Per destination time: the left source index and the weight of the right one.
    taps: Vec<Option<(usize, f64)>>,
}

impl Resampler {
    /// Prepares interpolation from samples at `t_src` (strictly increasing) to `t_dst + offset_s`,
    /// refusing to bridge gaps longer than `max_gap_s`.
    pub fn new(
        t_src: &[f64],
        t_dst: &[f64],
        offset_s: f64,
        max_gap_s: f64,
    ) -> Result<Self, AlignError> {
        if let Some(index) = t_src.iter().position(|t| !t.is_finite()) {
            return Err(AlignError::NotFinite { index });
        }
        for (i, w) in t_src.windows(2).enumerate() {
            if w[1] <= w[0] {
                return Err(AlignError::NotIncreasing {
                    index: i + 1,
                    t_s: w[1],
                    prev_s: w[0],
                });
            }
        }
        let taps = t_dst
            .iter()
            .map(|&td| {
                let t = td + offset_s;
                if !t.is_finite() || t_src.is_empty() || t < t_src[0] || t > t_src[t_src.len() - 1]
                {
                    return None;
                }
                // First source time ≥ t.
                let j = t_src.partition_point(|&s| s < t);
                if t_src[j] == t {
                    return Some((j, 0.0));
                }
                let (t0, t1) = (t_src[j - 1], t_src[j]);
                (t1 - t0 <= max_gap_s).then(|| (j - 1, (t - t0) / (t1 - t0)))
            })
            .collect();
        Ok(Self { taps })
    }

    /// One channel's values at the destination times.
    pub fn apply(&self, values: &[f64]) -> Vec<Option<f64>> {
        self.taps
            .iter()
            .map(|tap| {
                tap.and_then(|(j, w)| {
                    let v0 = *values.get(j)?;
                    if w == 0.0 {
                        return Some(v0);
                    }
                    let v1 = *values.get(j + 1)?;
                    Some(v0 + w * (v1 - v0))
                })
            })
            .collect()
    }

    /// Destination times that fell outside the samples or inside a gap.
    pub fn missing(&self) -> usize {
        self.taps.iter().filter(|t| t.is_none()).count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_signals_are_reproduced_exactly_and_gaps_refused() {
        let t: Vec<f64> = (0..100).map(|i| i as f64 * 0.01).collect();
        let v: Vec<f64> = t.iter().map(|t| 3.0 * t - 1.0).collect();
        let dst = [0.005, 0.333, 0.5, 0.99, 1.2, -0.1];
        let r = Resampler::new(&t, &dst, 0.0, 0.015).unwrap();
        let got = r.apply(&v);
        for (g, d) in got.iter().zip(dst).take(4) {
            assert!((g.unwrap() - (3.0 * d - 1.0)).abs() < 1e-12);
        }
        assert_eq!((got[4], got[5], r.missing()), (None, None, 2));
        // A latency offset reads the force later.
        let r = Resampler::new(&t, &[0.2], 0.05, 0.015).unwrap();
        assert!((r.apply(&v)[0].unwrap() - (3.0 * 0.25 - 1.0)).abs() < 1e-12);
        // A lost stretch of samples is not bridged.
        let t2 = [0.0, 0.01, 0.5, 0.51];
        let r = Resampler::new(&t2, &[0.005, 0.2], 0.0, 0.015).unwrap();
        assert_eq!(r.apply(&[0.0, 1.0, 2.0, 3.0]), vec![Some(0.5), None]);
    }

    #[test]
    fn unordered_times_are_an_error() {
        let e = Resampler::new(&[0.0, 0.2, 0.1], &[0.0], 0.0, 1.0).unwrap_err();
        assert!(matches!(e, AlignError::NotIncreasing { index: 2, .. }));
    }
}
