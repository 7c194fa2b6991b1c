//! Windowed-sinc FIR design and zero-phase filtering.
//!
//! Contract: [`firwin`] equals `scipy.signal.firwin` (Hamming, Hann, rectangular and Kaiser
//! windows; low-, high-, band-pass and band-stop; `scale=True`), [`lfilter`] and [`lfilter_zi`]
//! equal `scipy.signal.lfilter` / `lfilter_zi`, and [`filtfilt`] equals
//! `scipy.signal.filtfilt(b, a, x, padtype, padlen)` with `method="pad"` — all to 1e−12 on
//! `shared/reference/golden/scipy_firwin_filtfilt.json` (test `tests/golden.rs`). The padding
//! length is an option: scipy's default `3·max(len a, len b)` or MATLAB's `3·(nfilt − 1)`.
//!
//! For FIR filters (`a = [1]`) the passes are a blocked direct-form convolution: an initial
//! state of `lfilter_zi · u₀` is the same as the input having been `u₀` forever, so each pass
//! prepends `ntaps − 1` copies of its first sample and convolves. Outputs are accumulated tap
//! by tap over blocks of samples (the order scipy's direct form II transposed sums in), which the
//! compiler vectorises without reassociating anything.
//!
//! ```
//! use visuotact_signal::fir::{filtfilt, firwin, FiltFiltOptions, FirSpec};
//! // 51-tap Hamming low-pass at 5 Hz for a 1 kHz force sensor; unit gain at DC.
//! let b = firwin(&FirSpec::lowpass(51, 5.0, 1000.0)).unwrap();
//! assert!((b.iter().sum::<f64>() - 1.0).abs() < 1e-12);
//! let x = vec![2.0; 500];
//! let y = filtfilt(&b, &[1.0], &x, &FiltFiltOptions::default()).unwrap();
//! assert!(y.iter().all(|v| (v - 2.0).abs() < 1e-12));
//! ```

use std::f64::consts::PI;

use serde::{Deserialize, Serialize};

/// Why a design or a filter call was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FilterError {
    /// The design parameters are inconsistent; the message says which.
    #[error("FIR design: {0}")]
    Design(String),
    /// The coefficients cannot filter (empty, `a[0] = 0`, non-finite).
    #[error("filter coefficients: {0}")]
    Coefficients(String),
    /// The signal is too short for the padding.
    #[error("signal of {len} samples is too short: the padding needs more than {padlen}")]
    TooShort {
        /// Samples in the signal.
        len: usize,
        /// Padding samples at each end.
        padlen: usize,
    },
}

/// Window applied to the ideal (sinc) impulse response.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum Window {
    /// 0.54 − 0.46 cos: scipy's and MATLAB `fir1`'s default.
    Hamming,
    /// 0.5 − 0.5 cos.
    Hann,
    /// No window (scipy's `boxcar`).
    Rectangular,
    /// Kaiser window with shape `beta`.
    Kaiser {
        /// Shape parameter β (0 is rectangular; 8.6 ≈ Blackman).
        beta: f64,
    },
}

visuotact_image::from_str_by_parse!(Window, FilterError);

impl Window {
    /// Parses `hamming`, `hann`, `rectangular` (or `boxcar`), `kaiser:BETA`.
    pub fn parse(s: &str) -> Result<Self, FilterError> {
        let s = s.trim().to_ascii_lowercase();
        Ok(match s.as_str() {
            "hamming" => Self::Hamming,
            "hann" | "hanning" => Self::Hann,
            "rectangular" | "boxcar" | "rect" => Self::Rectangular,
            _ => match s.strip_prefix("kaiser:") {
                Some(b) => Self::Kaiser {
                    beta: b.parse().map_err(|_| {
                        FilterError::Design(format!("kaiser beta {b:?} is not a number"))
                    })?,
                },
                None => {
                    return Err(FilterError::Design(format!(
                        "unknown window {s:?}: hamming, hann, rectangular or kaiser:BETA"
                    )))
                }
            },
        })
    }

    /// The symmetric window of `n` points (scipy `get_window(.., fftbins=False)`).
    pub fn coefficients(self, n: usize) -> Vec<f64> {
        if n == 1 {
            return vec![1.0];
        }
        let general_cosine = |a0: f64, a1: f64| -> Vec<f64> {
            // scipy: fac = linspace(−π, π, n); w = a0 − a1·cos(fac) written as a0 + a1 cos(...)
            // with alternating sign; here directly a0 − a1 cos(2πk/(n−1)) evaluated as scipy does.
            let step = 2.0 * PI / (n - 1) as f64;
            (0..n)
                .map(|k| {
                    let fac = if k == n - 1 {
                        PI
                    } else {
                        -PI + k as f64 * step
                    };
                    a0 + a1 * fac.cos()
                })
                .collect()
        };
        match self {
            Self::Hamming => general_cosine(0.54, 0.46),
            Self::Hann => general_cosine(0.5, 0.5),
            Self::Rectangular => vec![1.0; n],
            Self::Kaiser { beta } => {
                let alpha = (n - 1) as f64 / 2.0;
                let den = bessel_i0(beta);
                (0..n)
                    .map(|k| {
                        let r = (k as f64 - alpha) / alpha;
                        bessel_i0(beta * (1.0 - r * r).max(0.0).sqrt()) / den
                    })
                    .collect()
            }
        }
    }
}

/// Modified Bessel function of the first kind, order 0 (power series; relative error ~1e−16
/// for the arguments a Kaiser window uses).
pub fn bessel_i0(x: f64) -> f64 {
    let q = 0.25 * x * x;
    let (mut term, mut sum) = (1.0f64, 1.0f64);
    for k in 1..500 {
        term *= q / (k * k) as f64;
        sum += term;
        if term <= sum * 1e-17 {
            break;
        }
    }
    sum
}

/// A windowed-sinc design, as scipy's `firwin(numtaps, cutoff, window, pass_zero, scale, fs)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FirSpec {
    /// Filter length (taps). High-pass and band-stop designs need an odd length.
    pub numtaps: usize,
    /// Band edges, increasing: in Hz when `fs_hz` is given, else as a fraction of Nyquist.
    pub cutoff: Vec<f64>,
    /// Sample rate, Hz; `None` means `cutoff` is normalised (1 = Nyquist).
    pub fs_hz: Option<f64>,
    /// Whether the band from 0 to the first edge passes (low-pass, band-stop).
    pub pass_zero: bool,
    /// Window.
    pub window: Window,
    /// Scale to unit gain at the centre of the first pass band (scipy's `scale=True`).
    pub scale: bool,
}

impl FirSpec {
    /// Low-pass at `cutoff_hz`, Hamming window.
    pub fn lowpass(numtaps: usize, cutoff_hz: f64, fs_hz: f64) -> Self {
        Self {
            numtaps,
            cutoff: vec![cutoff_hz],
            fs_hz: Some(fs_hz),
            pass_zero: true,
            window: Window::Hamming,
            scale: true,
        }
    }

    /// High-pass from `cutoff_hz` (odd `numtaps`).
    pub fn highpass(numtaps: usize, cutoff_hz: f64, fs_hz: f64) -> Self {
        Self {
            pass_zero: false,
            ..Self::lowpass(numtaps, cutoff_hz, fs_hz)
        }
    }

    /// Band-pass between `low_hz` and `high_hz`.
    pub fn bandpass(numtaps: usize, low_hz: f64, high_hz: f64, fs_hz: f64) -> Self {
        Self {
            cutoff: vec![low_hz, high_hz],
            pass_zero: false,
            ..Self::lowpass(numtaps, low_hz, fs_hz)
        }
    }

    /// Band-stop between `low_hz` and `high_hz` (odd `numtaps`).
    pub fn bandstop(numtaps: usize, low_hz: f64, high_hz: f64, fs_hz: f64) -> Self {
        Self {
            pass_zero: true,
            ..Self::bandpass(numtaps, low_hz, high_hz, fs_hz)
        }
    }
}

fn sinc(x: f64) -> f64 {
    if x == 0.0 {
        1.0
    } else {
        let y = PI * x;
        y.sin() / y
    }
}

/// The longest filter designed: a million taps (at 1 kHz, a 17-minute impulse response).
pub const MAX_TAPS: usize = 1 << 20;

/// The taps of a windowed-sinc design (scipy `firwin`).
pub fn firwin(spec: &FirSpec) -> Result<Vec<f64>, FilterError> {
    let n = spec.numtaps;
    if n == 0 {
        return Err(FilterError::Design("numtaps must be at least 1".into()));
    }
    if n > MAX_TAPS {
        return Err(FilterError::Design(format!(
            "numtaps {n} is beyond the limit of {MAX_TAPS}"
        )));
    }
    let nyq = match spec.fs_hz {
        Some(fs) if fs.is_finite() && fs > 0.0 => fs / 2.0,
        Some(fs) => {
            return Err(FilterError::Design(format!(
                "sample rate must be positive, got {fs} Hz"
            )))
        }
        None => 1.0,
    };
    if spec.cutoff.is_empty() {
        return Err(FilterError::Design("at least one cutoff is needed".into()));
    }
    let cut: Vec<f64> = spec.cutoff.iter().map(|c| c / nyq).collect();
    if cut.iter().any(|c| !(c.is_finite() && *c > 0.0 && *c < 1.0)) {
        return Err(FilterError::Design(format!(
            "cutoffs {:?} must lie strictly between 0 and the Nyquist frequency {nyq}",
            spec.cutoff
        )));
    }
    if cut.windows(2).any(|w| w[1] <= w[0]) {
        return Err(FilterError::Design(format!(
            "cutoffs {:?} must increase",
            spec.cutoff
        )));
    }
    let pass_nyquist = (cut.len() % 2 == 1) != spec.pass_zero;
    if pass_nyquist && n.is_multiple_of(2) {
        return Err(FilterError::Design(format!(
            "a filter that passes the Nyquist frequency needs an odd number of taps, got {n}"
        )));
    }
    let mut edges = Vec::with_capacity(cut.len() + 2);
    if spec.pass_zero {
        edges.push(0.0);
    }
    edges.extend_from_slice(&cut);
    if pass_nyquist {
        edges.push(1.0);
    }
    let alpha = 0.5 * (n - 1) as f64;
    let m: Vec<f64> = (0..n).map(|k| k as f64 - alpha).collect();
    let mut h = vec![0.0; n];
    for band in edges.chunks_exact(2) {
        let (left, right) = (band[0], band[1]);
        for (hk, mk) in h.iter_mut().zip(&m) {
            *hk += right * sinc(right * mk);
            *hk -= left * sinc(left * mk);
        }
    }
    for (hk, w) in h.iter_mut().zip(spec.window.coefficients(n)) {
        *hk *= w;
    }
    if spec.scale {
        let (left, right) = (edges[0], edges[1]);
        let f = if left == 0.0 {
            0.0
        } else if right == 1.0 {
            1.0
        } else {
            0.5 * (left + right)
        };
        let s: f64 = h
            .iter()
            .zip(&m)
            .map(|(hk, mk)| hk * (PI * mk * f).cos())
            .sum();
        for hk in &mut h {
            *hk /= s;
        }
    }
    Ok(h)
}

/// Checks `b` and `a` and returns them normalised by `a[0]`, padded to one length.
fn normalised(b: &[f64], a: &[f64]) -> Result<(Vec<f64>, Vec<f64>), FilterError> {
    if b.is_empty() || a.is_empty() {
        return Err(FilterError::Coefficients(
            "b and a need at least one coefficient".into(),
        ));
    }
    if b.iter().chain(a).any(|v| !v.is_finite()) {
        return Err(FilterError::Coefficients(
            "coefficients must be finite".into(),
        ));
    }
    if a[0] == 0.0 {
        return Err(FilterError::Coefficients("a[0] must not be zero".into()));
    }
    let n = a.len().max(b.len());
    let mut bn: Vec<f64> = b.iter().map(|v| v / a[0]).collect();
    let mut an: Vec<f64> = a.iter().map(|v| v / a[0]).collect();
    bn.resize(n, 0.0);
    an.resize(n, 0.0);
    Ok((bn, an))
}

/// Direct form II transposed filtering (scipy `lfilter(b, a, x, zi)`): returns the output and
/// the final state. `zi` has `max(len a, len b) − 1` values; `None` starts from rest.
pub fn lfilter(
    b: &[f64],
    a: &[f64],
    x: &[f64],
    zi: Option<&[f64]>,
) -> Result<(Vec<f64>, Vec<f64>), FilterError> {
    let (b, a) = normalised(b, a)?;
    let n = b.len();
    let mut z = vec![0.0; n - 1];
    if let Some(zi) = zi {
        if zi.len() != n - 1 {
            return Err(FilterError::Coefficients(format!(
                "initial state has {} values, the filter needs {}",
                zi.len(),
                n - 1
            )));
        }
        z.copy_from_slice(zi);
    }
    let mut y = Vec::with_capacity(x.len());
    for &xk in x {
        let yk = b[0] * xk + z.first().copied().unwrap_or(0.0);
        for i in 0..n.saturating_sub(1) {
            let next = if i + 1 < n - 1 { z[i + 1] } else { 0.0 };
            z[i] = b[i + 1] * xk - a[i + 1] * yk + next;
        }
        y.push(yk);
    }
    Ok((y, z))
}

/// The state of the filter after a unit step held forever (scipy `lfilter_zi`): scaled by the
/// first sample, it starts a pass without a transient.
pub fn lfilter_zi(b: &[f64], a: &[f64]) -> Result<Vec<f64>, FilterError> {
    let (b, a) = normalised(b, a)?;
    let asum: f64 = a.iter().sum();
    if asum.abs() < 1e-300 {
        return Err(FilterError::Coefficients(
            "the filter has a pole at DC (sum of a is 0): no steady state".into(),
        ));
    }
    let yss = b.iter().sum::<f64>() / asum;
    // z_i = Σ_{j > i} (b_j − a_j · yss), from the transposed direct form at steady state.
    let n = b.len();
    let mut z = vec![0.0; n - 1];
    let mut acc = 0.0;
    for i in (0..n - 1).rev() {
        acc += b[i + 1] - a[i + 1] * yss;
        z[i] = acc;
    }
    Ok(z)
}

/// How `filtfilt` extends the signal at both ends.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Padding {
    /// Point reflection about the end sample (`2·x₀ − x[k]`): scipy's and MATLAB's default.
    Odd,
    /// Mirror reflection (`x[k]`).
    Even,
    /// The end sample repeated.
    Constant,
    /// No extension.
    None,
}

/// How many samples `filtfilt` pads at each end.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PadLen {
    /// `3 · max(len a, len b)` (scipy's default).
    Scipy,
    /// `3 · (max(len a, len b) − 1)` (MATLAB `filtfilt`'s).
    Matlab,
    /// A given number of samples.
    Samples(usize),
}

/// Options of [`filtfilt`]; the default is scipy's.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FiltFiltOptions {
    /// Extension type.
    pub padding: Padding,
    /// Extension length (ignored with [`Padding::None`]).
    pub padlen: PadLen,
}

impl Default for FiltFiltOptions {
    fn default() -> Self {
        Self {
            padding: Padding::Odd,
            padlen: PadLen::Scipy,
        }
    }
}

visuotact_image::names_from_str!(Padding, "padding");

impl Padding {
    /// The names [`Padding::from_name`] and `FromStr` read (each is also what `name` writes,
    /// where the type has one).
    pub const NAMES: &'static [&'static str] = &["odd", "even", "constant", "none"];

    /// Parses `odd` (scipy and MATLAB), `even`, `constant` or `none`.
    pub fn from_name(s: &str) -> Option<Self> {
        match s {
            "odd" => Some(Self::Odd),
            "even" => Some(Self::Even),
            "constant" => Some(Self::Constant),
            "none" => Some(Self::None),
            _ => None,
        }
    }
}

visuotact_image::from_str_by_parse!(PadLen, FilterError);

impl PadLen {
    /// Parses `scipy` (3·taps), `matlab` (3·(taps − 1)) or a number of samples.
    pub fn parse(s: &str) -> Result<Self, FilterError> {
        match s {
            "scipy" => Ok(Self::Scipy),
            "matlab" => Ok(Self::Matlab),
            n => n.parse().map(Self::Samples).map_err(|_| {
                FilterError::Design(format!(
                    "padding length {n:?}: expected scipy, matlab or a number of samples"
                ))
            }),
        }
    }
}

impl FiltFiltOptions {
    /// MATLAB `filtfilt`'s padding: odd, `3·(nfilt − 1)` samples.
    pub const MATLAB: Self = Self {
        padding: Padding::Odd,
        padlen: PadLen::Matlab,
    };

    /// Samples padded at each end for a filter of `nfilt = max(len a, len b)` coefficients.
    pub fn padlen_for(&self, nfilt: usize) -> usize {
        match (self.padding, self.padlen) {
            (Padding::None, _) => 0,
            (_, PadLen::Scipy) => 3 * nfilt,
            (_, PadLen::Matlab) => 3 * nfilt.saturating_sub(1),
            (_, PadLen::Samples(n)) => n,
        }
    }
}

/// Reusable buffers for [`filtfilt_into`].
#[derive(Clone, Debug, Default)]
pub struct FiltFiltScratch {
    w: Vec<f64>,
    y: Vec<f64>,
}

/// Zero-phase filtering (scipy `filtfilt(b, a, x, padtype, padlen, method="pad")`).
pub fn filtfilt(
    b: &[f64],
    a: &[f64],
    x: &[f64],
    options: &FiltFiltOptions,
) -> Result<Vec<f64>, FilterError> {
    let mut out = Vec::new();
    filtfilt_into(b, a, x, options, &mut FiltFiltScratch::default(), &mut out)?;
    Ok(out)
}

/// [`filtfilt`] writing into `out`, with caller-owned scratch buffers.
pub fn filtfilt_into(
    b: &[f64],
    a: &[f64],
    x: &[f64],
    options: &FiltFiltOptions,
    scratch: &mut FiltFiltScratch,
    out: &mut Vec<f64>,
) -> Result<(), FilterError> {
    let (bn, an) = normalised(b, a)?;
    let nfilt = bn.len();
    let p = options.padlen_for(nfilt);
    let n = x.len();
    if n == 0 || (p > 0 && n <= p) {
        return Err(FilterError::TooShort { len: n, padlen: p });
    }
    let fir = an[1..].iter().all(|v| *v == 0.0);
    if !fir {
        padded_into(x, options.padding, p, 0, &mut scratch.w);
        return iir_passes(&bn, &an, &scratch.w, p, n, out);
    }
    let lead = nfilt - 1;
    let w = &mut scratch.w;
    padded_into(x, options.padding, p, lead, w);
    // Forward pass, then the backward pass on the reversed output (preceded by its own first
    // sample repeated), then reverse back and trim.
    let len = n + 2 * p;
    let y = &mut scratch.y;
    y.clear();
    y.resize(len, 0.0);
    convolve_valid(&bn, w, y);
    let ylast = y[len - 1];
    w.clear();
    w.resize(lead, ylast);
    w.extend(y.iter().rev());
    convolve_valid(&bn, w, y);
    out.clear();
    out.extend(y[p..p + n].iter().rev());
    Ok(())
}

/// Writes `lead` copies of the extended signal's first sample, then the signal extended by `p`
/// samples at each end, into `w`.
fn padded_into(x: &[f64], padding: Padding, p: usize, lead: usize, w: &mut Vec<f64>) {
    let n = x.len();
    let (x0, xn) = (x[0], x[n - 1]);
    let left = |i: usize| match padding {
        Padding::Odd => 2.0 * x0 - x[p - i],
        Padding::Even => x[p - i],
        Padding::Constant | Padding::None => x0,
    };
    w.clear();
    w.reserve(lead + n + 2 * p);
    w.resize(lead, if p > 0 { left(0) } else { x0 });
    w.extend((0..p).map(left));
    w.extend_from_slice(x);
    w.extend((0..p).map(|i| match padding {
        Padding::Odd => 2.0 * xn - x[n - 2 - i],
        Padding::Even => x[n - 2 - i],
        Padding::Constant | Padding::None => xn,
    }));
}

/// Forward and backward direct-form passes started at steady state (any IIR or FIR filter).
fn iir_passes(
    bn: &[f64],
    an: &[f64],
    ext: &[f64],
    p: usize,
    n: usize,
    out: &mut Vec<f64>,
) -> Result<(), FilterError> {
    let zi = lfilter_zi(bn, an)?;
    let z0: Vec<f64> = zi.iter().map(|z| z * ext[0]).collect();
    let (fwd, _) = lfilter(bn, an, ext, Some(&z0))?;
    let rev: Vec<f64> = fwd.iter().rev().copied().collect();
    let z1: Vec<f64> = zi.iter().map(|z| z * rev[0]).collect();
    let (bwd, _) = lfilter(bn, an, &rev, Some(&z1))?;
    out.clear();
    out.extend(bwd[p..p + n].iter().rev());
    Ok(())
}

/// `y[i] = Σ_k b[k] · w[i + m − 1 − k]` for every `i < y.len()` (`w.len() = y.len() + m − 1`),
/// summed oldest sample first (tap `b[m − 1]` first), so every path gives the same bits.
fn convolve_valid(b: &[f64], w: &[f64], y: &mut [f64]) {
    debug_assert_eq!(w.len(), y.len() + b.len() - 1);
    let c: Vec<f64> = b.iter().rev().copied().collect();
    kernel::convolve(&c, w, y);
}

/// The convolution loop, compiled twice: for the baseline CPU and with AVX, chosen at run time.
#[allow(unsafe_code)] // reason: calling the AVX-compiled copy needs `unsafe`; it is only called after `is_x86_feature_detected!("avx")`.
mod kernel {
    /// Outputs per register tile: 8 vector accumulators of 4 (AVX) or 2 (SSE2) lanes hide the
    /// add latency.
    const TILE: usize = 32;

    #[inline(always)]
    fn convolve_generic(c: &[f64], w: &[f64], y: &mut [f64]) {
        let mut tiles = y.chunks_exact_mut(TILE);
        let mut start = 0;
        for out in &mut tiles {
            let mut acc = [0.0f64; TILE];
            for (k, &ck) in c.iter().enumerate() {
                let src: &[f64; TILE] = w[start + k..start + k + TILE].try_into().unwrap();
                for (a, s) in acc.iter_mut().zip(src) {
                    *a += ck * s;
                }
            }
            out.copy_from_slice(&acc);
            start += TILE;
        }
        for (i, out) in tiles.into_remainder().iter_mut().enumerate() {
            let mut acc = 0.0;
            for (k, &ck) in c.iter().enumerate() {
                acc += ck * w[start + i + k];
            }
            *out = acc;
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn convolve_avx(c: &[f64], w: &[f64], y: &mut [f64]) {
        convolve_generic(c, w, y);
    }

    pub(super) fn convolve(c: &[f64], w: &[f64], y: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx") {
            // SAFETY: the CPU supports AVX (checked just above).
            return unsafe { convolve_avx(c, w, y) };
        }
        convolve_generic(c, w, y);
    }

    #[cfg(test)]
    #[test]
    fn dispatched_and_baseline_copies_give_the_same_bits() {
        let c: Vec<f64> = (0..51)
            .map(|k| ((k * 37 % 11) as f64 - 5.0) / 7.0)
            .collect();
        let w: Vec<f64> = (0..1000 + 50).map(|i| (i as f64 * 0.37).sin()).collect();
        let (mut a, mut b) = (vec![0.0; 1000], vec![0.0; 1000]);
        convolve(&c, &w, &mut a);
        convolve_generic(&c, &w, &mut b);
        assert!(a.iter().zip(&b).all(|(p, q)| p.to_bits() == q.to_bits()));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_filter_beyond_the_tap_limit_is_an_error_not_an_abort() {
        let e = firwin(&FirSpec::lowpass(usize::MAX, 20.0, 1000.0)).unwrap_err();
        assert!(e.to_string().contains("beyond the limit of 1048576"), "{e}");
    }

    #[test]
    fn padding_names_parse() {
        assert_eq!(Padding::from_name("even"), Some(Padding::Even));
        assert_eq!(Padding::from_name("wrap"), None);
        assert_eq!(PadLen::parse("matlab").unwrap(), PadLen::Matlab);
        assert_eq!(PadLen::parse("12").unwrap(), PadLen::Samples(12));
        assert!(PadLen::parse("lots").is_err());
    }

    #[test]
    fn window_shapes() {
        let h = Window::Hamming.coefficients(5);
        assert!((h[0] - 0.08).abs() < 1e-15 && (h[2] - 1.0).abs() < 1e-15);
        let k = Window::Kaiser { beta: 0.0 }.coefficients(7);
        assert!(k.iter().all(|v| (v - 1.0).abs() < 1e-15));
        // I0(1) = 1.2660658777520082 (Abramowitz & Stegun 9.8).
        assert!((bessel_i0(1.0) - 1.266_065_877_752_008_4).abs() < 1e-15);
        assert_eq!(
            Window::parse("kaiser:8").unwrap(),
            Window::Kaiser { beta: 8.0 }
        );
        assert!(Window::parse("blackman").is_err());
    }

    #[test]
    fn design_errors_are_explained() {
        let mut s = FirSpec::highpass(32, 10.0, 100.0);
        assert!(matches!(firwin(&s), Err(FilterError::Design(m)) if m.contains("odd")));
        s.numtaps = 33;
        s.cutoff = vec![60.0];
        assert!(firwin(&s).is_err());
        assert!(firwin(&FirSpec::bandpass(31, 20.0, 10.0, 100.0)).is_err());
    }

    #[test]
    fn fir_fast_path_equals_the_general_filter() {
        let b = firwin(&FirSpec::lowpass(21, 8.0, 100.0)).unwrap();
        let x: Vec<f64> = (0..2000)
            .map(|i| (i as f64 * 0.07).sin() + 0.3 * ((i * 7919) % 13) as f64)
            .collect();
        for opt in [
            FiltFiltOptions::default(),
            FiltFiltOptions::MATLAB,
            FiltFiltOptions {
                padding: Padding::Even,
                padlen: PadLen::Samples(40),
            },
            FiltFiltOptions {
                padding: Padding::None,
                padlen: PadLen::Scipy,
            },
        ] {
            let fast = filtfilt(&b, &[1.0], &x, &opt).unwrap();
            let p = opt.padlen_for(b.len());
            let mut ext = Vec::new();
            padded_into(&x, opt.padding, p, 0, &mut ext);
            let mut slow = Vec::new();
            iir_passes(&b, &[1.0], &ext, p, x.len(), &mut slow).unwrap();
            let d = fast
                .iter()
                .zip(&slow)
                .map(|(p, q)| (p - q).abs())
                .fold(0.0, f64::max);
            assert!(d < 1e-12, "{opt:?}: {d}");
        }
    }

    #[test]
    fn short_signals_are_refused() {
        let b = [0.25, 0.5, 0.25];
        let e = filtfilt(&b, &[1.0], &[1.0; 9], &FiltFiltOptions::default()).unwrap_err();
        assert_eq!(e, FilterError::TooShort { len: 9, padlen: 9 });
        assert!(filtfilt(&b, &[1.0], &[1.0; 10], &FiltFiltOptions::default()).is_ok());
        assert!(filtfilt(&b, &[0.0], &[1.0; 10], &FiltFiltOptions::default()).is_err());
    }
}
