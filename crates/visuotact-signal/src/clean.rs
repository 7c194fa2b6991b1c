//! A force record cleaned for labels: put on a uniform time grid at its median sample interval
//! (missing samples filled by linear interpolation), low-passed forward and backward by a
//! windowed-sinc FIR ([`crate::fir`], equal to scipy's `firwin` + `filtfilt`), and debiased from
//! its no-contact periods ([`crate::bias`]). `visuotact filter` and `visuotact dataset` run it.

use crate::align::{AlignError, Resampler};
use crate::bias::{Bias, BiasConfig, BiasError};
use crate::fir::{filtfilt, firwin, FiltFiltOptions, FilterError, FirSpec, Window};

/// How the bias is removed.
#[derive(Clone, Debug, PartialEq)]
pub enum BiasRemoval {
    /// Not at all.
    None,
    /// From the still periods [`Bias::detect`] finds on the detection channels; a level
    /// change beyond `contact_threshold` (channel units, N) counts as contact.
    Auto {
        /// Level change beyond which a still period is contact.
        contact_threshold: f64,
    },
    /// From these `(start_s, end_s)` ranges, known to be free of contact.
    Ranges(Vec<(f64, f64)>),
}

impl BiasRemoval {
    /// Parses `auto` (with `contact_threshold`), `none`, or time ranges `A:B,C:D` in seconds.
    pub fn parse(s: &str, contact_threshold: f64) -> Result<Self, CleanError> {
        match s {
            "none" => Ok(Self::None),
            "auto" => Ok(Self::Auto { contact_threshold }),
            ranges => ranges
                .split(',')
                .map(|r| {
                    let (a, b) = r.split_once(':')?;
                    Some((a.trim().parse().ok()?, b.trim().parse().ok()?))
                })
                .collect::<Option<Vec<(f64, f64)>>>()
                .map(Self::Ranges)
                .ok_or_else(|| CleanError::BiasRemoval(s.to_string())),
        }
    }
}

/// How a force record is cleaned. [`Default`]: 51 taps at 5 Hz, Hamming window, scipy's
/// padding, automatic bias removal at 0.25 N.
#[derive(Clone, Debug, PartialEq)]
pub struct CleanConfig {
    /// Low-pass cutoff, Hz.
    pub cutoff_hz: f64,
    /// Filter length, taps.
    pub taps: usize,
    /// The FIR's window.
    pub window: Window,
    /// Padding at the ends.
    pub filtfilt: FiltFiltOptions,
    /// Bias removal.
    pub bias: BiasRemoval,
}

impl Default for CleanConfig {
    fn default() -> Self {
        Self {
            cutoff_hz: 5.0,
            taps: 51,
            window: Window::Hamming,
            filtfilt: FiltFiltOptions::default(),
            bias: BiasRemoval::Auto {
                contact_threshold: BiasConfig::default().contact_threshold,
            },
        }
    }
}

/// A cleaned record on a uniform time grid.
#[derive(Clone, Debug)]
pub struct Cleaned {
    /// Sample times, s: the first to the last input sample.
    pub t: Vec<f64>,
    /// Input values on the grid, per channel.
    pub raw: Vec<Vec<f64>>,
    /// Filtered, debiased values, per channel.
    pub clean: Vec<Vec<f64>>,
    /// The bias removed, when it was.
    pub bias: Option<Bias>,
    /// Grid rate, Hz.
    pub rate_hz: f64,
    /// Grid samples that were missing in the input (filled by interpolation).
    pub filled: usize,
}

/// Why a record could not be cleaned.
#[derive(Debug, thiserror::Error)]
pub enum CleanError {
    /// A bias removal that does not parse.
    #[error("bias removal {0:?}: expected auto, none or A:B,C:D seconds")]
    BiasRemoval(String),
    /// Too few samples for a filter.
    #[error("{0} force samples; too few to filter")]
    TooFew(usize),
    /// The timestamps are not finite and increasing.
    #[error(transparent)]
    Time(#[from] AlignError),
    /// The timestamps leave a gap too wide to fill ([`MAX_GRID_PER_SAMPLE`]).
    #[error(
        "the timestamps jump from {from_s} s to {to_s} s at sample {sample} (counting from 0), \
         {periods:.3e} sample periods: a clock jump or timestamps in another unit? \
         Split the table there or fix its time column"
    )]
    Gap {
        /// The sample after the gap (0-based).
        sample: usize,
        /// The time before the gap, s.
        from_s: f64,
        /// The time after it, s.
        to_s: f64,
        /// Its width in median sample periods.
        periods: f64,
    },
    /// The samples do not cover the grid.
    #[error("force samples do not cover a uniform grid; are the timestamps in seconds?")]
    NotUniform,
    /// The filter could not be designed or run at this rate.
    #[error("at {rate_hz:.1} Hz: {source}")]
    Filter {
        /// The grid's rate.
        rate_hz: f64,
        /// Why.
        source: FilterError,
    },
    /// The bias could not be estimated.
    #[error("bias: {0}")]
    Bias(#[from] BiasError),
}

/// The uniform grid holds at most this many points per recorded sample: a stream with a
/// longer gap (a clock jump, timestamps in another unit) is refused rather than interpolated
/// over millions of invented samples.
pub const MAX_GRID_PER_SAMPLE: usize = 8;

/// [`CleanError::Gap`] at the widest gap of `t_s`, with the median period `period_s`.
fn gap_error(t_s: &[f64], period_s: f64) -> CleanError {
    let (row, width) = t_s
        .windows(2)
        .map(|w| w[1] - w[0])
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((0, 0.0));
    CleanError::Gap {
        sample: row + 1,
        from_s: t_s[row],
        to_s: t_s.get(row + 1).copied().unwrap_or(t_s[row]),
        periods: width / period_s,
    }
}

/// Cleans `channels` sampled at `t_s` (strictly increasing seconds; each channel as long as
/// `t_s`). With [`BiasRemoval::Auto`], still periods are found on the channels numbered in
/// `detect` (e.g. the three force axes; torques follow the same periods).
pub fn clean(
    t_s: &[f64],
    channels: &[Vec<f64>],
    detect: &[usize],
    cfg: &CleanConfig,
) -> Result<Cleaned, CleanError> {
    let n = t_s.len();
    if n < 8 {
        return Err(CleanError::TooFew(n));
    }
    let mut dt: Vec<f64> = t_s.windows(2).map(|w| w[1] - w[0]).collect();
    dt.sort_by(f64::total_cmp);
    let (t0, t1) = (t_s[0], t_s[n - 1]);
    let grid = ((t1 - t0) / dt[dt.len() / 2]).round();
    if !(grid.is_finite() && grid < (MAX_GRID_PER_SAMPLE * n) as f64) {
        return Err(gap_error(t_s, dt[dt.len() / 2]));
    }
    let len = grid as usize + 1;
    // The grid spans exactly the first to the last sample.
    let period = (t1 - t0) / (len - 1).max(1) as f64;
    let rate_hz = 1.0 / period;
    let t: Vec<f64> = (0..len)
        .map(|k| {
            if k + 1 == len {
                t1
            } else {
                t0 + k as f64 * period
            }
        })
        .collect();
    let rs = Resampler::new(t_s, &t, 0.0, f64::INFINITY)?;
    let raw: Vec<Vec<f64>> = channels
        .iter()
        .map(|x| {
            rs.apply(x)
                .into_iter()
                .map(|v| v.unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    if raw.iter().flatten().any(|v| !v.is_finite()) {
        return Err(CleanError::NotUniform);
    }
    let filter_error = |source| CleanError::Filter { rate_hz, source };
    let spec = FirSpec {
        window: cfg.window,
        ..FirSpec::lowpass(cfg.taps, cfg.cutoff_hz, rate_hz)
    };
    let b = firwin(&spec).map_err(filter_error)?;
    let filtered: Vec<Vec<f64>> = raw
        .iter()
        .map(|x| filtfilt(&b, &[1.0], x, &cfg.filtfilt))
        .collect::<Result<_, _>>()
        .map_err(filter_error)?;
    let chans: Vec<&[f64]> = filtered.iter().map(Vec::as_slice).collect();
    let bias = match &cfg.bias {
        BiasRemoval::None => None,
        BiasRemoval::Auto { contact_threshold } => {
            let on: Vec<&[f64]> = detect.iter().map(|&k| filtered[k].as_slice()).collect();
            let bias_cfg = BiasConfig {
                contact_threshold: *contact_threshold,
                ..BiasConfig::default()
            };
            Some(Bias::detect(&t, &on, &chans, &bias_cfg)?)
        }
        BiasRemoval::Ranges(r) => Some(Bias::from_time_ranges(
            &t,
            &chans,
            r,
            BiasConfig::default().window_s,
        )?),
    };
    let mut clean = filtered;
    if let Some(bias) = &bias {
        let mut refs: Vec<&mut [f64]> = clean.iter_mut().map(Vec::as_mut_slice).collect();
        bias.remove(&t, &mut refs);
    }
    Ok(Cleaned {
        filled: len.saturating_sub(n),
        t,
        raw,
        clean,
        bias,
        rate_hz,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bias_removal_parses() {
        assert_eq!(BiasRemoval::parse("none", 0.25).unwrap(), BiasRemoval::None);
        assert_eq!(
            BiasRemoval::parse("auto", 0.5).unwrap(),
            BiasRemoval::Auto {
                contact_threshold: 0.5
            }
        );
        assert_eq!(
            BiasRemoval::parse("0:1.5, 9:10", 0.25).unwrap(),
            BiasRemoval::Ranges(vec![(0.0, 1.5), (9.0, 10.0)])
        );
        assert!(BiasRemoval::parse("0-1", 0.25).is_err());
    }

    /// 200 Hz for 4 s with one missing sample: a 0.3 N offset, a 2 N press from 1.5 to 2.5 s
    /// and a 40 Hz ripple.
    fn record() -> (Vec<f64>, Vec<f64>) {
        let t: Vec<f64> = (0..800)
            .filter(|&k| k != 300)
            .map(|k| f64::from(k) / 200.0)
            .collect();
        let x = t
            .iter()
            .map(|&t| {
                let press = if (1.5..2.5).contains(&t) { 2.0 } else { 0.0 };
                0.3 + press + 0.2 * (2.0 * std::f64::consts::PI * 40.0 * t).sin()
            })
            .collect();
        (t, x)
    }

    #[test]
    fn the_offset_and_the_ripple_go_the_press_stays() {
        let (t, x) = record();
        let c = clean(&t, &[x], &[0], &CleanConfig::default()).unwrap();
        assert_eq!((c.t.len(), c.filled), (800, 1));
        assert!((c.rate_hz - 200.0).abs() < 1e-9);
        let at = |s: f64| c.clean[0][(s * 200.0) as usize];
        // Rest: the offset removed, the 40 Hz ripple (8× the cutoff) gone.
        for s in [0.5, 1.0, 3.2] {
            assert!(at(s).abs() < 0.02, "{s} s: {}", at(s));
        }
        // The press, away from its edges, keeps its 2 N.
        assert!((at(2.0) - 2.0).abs() < 0.02, "{}", at(2.0));
        // Raw values are on the grid, untouched.
        assert!((c.raw[0][0] - 0.3).abs() < 1e-12);
    }

    #[test]
    fn bad_records_say_why() {
        let (t, x) = record();
        let none = CleanConfig {
            bias: BiasRemoval::None,
            ..CleanConfig::default()
        };
        let kept = clean(&t, std::slice::from_ref(&x), &[0], &none).unwrap();
        assert!((kept.clean[0][100] - 0.3).abs() < 0.02 && kept.bias.is_none());
        assert!(matches!(
            clean(&t[..5], &[x[..5].to_vec()], &[0], &none),
            Err(CleanError::TooFew(5))
        ));
        let mut back = t.clone();
        back.swap(10, 11);
        assert!(matches!(
            clean(&back, std::slice::from_ref(&x), &[0], &none),
            Err(CleanError::Time(_))
        ));
        // A cutoff above Nyquist cannot be designed.
        let high = CleanConfig {
            cutoff_hz: 150.0,
            ..none
        };
        let err = clean(&t, &[x], &[0], &high).unwrap_err();
        assert!(err.to_string().starts_with("at 200.0 Hz"), "{err}");
    }
}
