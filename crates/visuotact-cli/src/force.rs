//! `visuotact filter`: force CSV → zero-phase low-passed, debiased CSV with a before/after plot;
//! and the force processing `dataset` shares with it.

use std::path::PathBuf;

use anyhow::Context;
use plotters::prelude::*;
use visuotact_io::force::{ForceTable, AXES};
use visuotact_signal::bias::Bias;
use visuotact_signal::clean::{clean, BiasRemoval, CleanConfig};
use visuotact_signal::fir::{FiltFiltOptions, PadLen, Padding, Window};

/// Filter and bias options shared by `filter` and `dataset`.
#[derive(clap::Args, Debug, Clone)]
pub(crate) struct ForceArgs {
    /// Low-pass cutoff, Hz (FIR, windowed sinc).
    #[arg(long, default_value_t = 5.0)]
    cutoff_hz: f64,
    /// Filter length, taps.
    #[arg(long, default_value_t = 51)]
    taps: usize,
    /// Window: hamming, hann, rectangular, kaiser:BETA.
    #[arg(long, default_value = "hamming")]
    window: String,
    /// Padding at the ends: odd (scipy and MATLAB), even, constant, none.
    #[arg(long, default_value = "odd", value_parser = ["odd", "even", "constant", "none"])]
    padding: String,
    /// Padding length: scipy (3·taps), matlab (3·(taps − 1)) or a number of samples.
    #[arg(long, default_value = "scipy")]
    padlen: String,
    /// Bias removal: auto (detect no-contact periods), none, or time ranges `A:B,C:D` in
    /// seconds that are known to be free of contact.
    #[arg(long, default_value = "auto")]
    bias: String,
    /// Level change (N) beyond which a still period counts as contact, for `--bias auto`.
    #[arg(long, default_value_t = 0.25)]
    contact_threshold_n: f64,
}

/// A processed force record on a uniform time grid.
pub(crate) struct Processed {
    /// Sample times, s.
    pub t: Vec<f64>,
    /// Raw values on the grid, one vector per axis (fx … tz).
    pub raw: Vec<Vec<f64>>,
    /// Filtered, debiased values.
    pub clean: Vec<Vec<f64>>,
    /// Which axes the input had.
    pub present: [bool; 6],
    /// The bias estimate, when removed.
    pub bias: Option<Bias>,
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// Grid samples that were missing in the input (filled by interpolation).
    pub filled: usize,
    /// Repeated samples dropped.
    pub duplicates: usize,
}

impl ForceArgs {
    /// The cleaning these options ask for.
    pub(crate) fn config(&self) -> anyhow::Result<CleanConfig> {
        let padding = match self.padding.as_str() {
            "odd" => Padding::Odd,
            "even" => Padding::Even,
            "constant" => Padding::Constant,
            _ => Padding::None,
        };
        let padlen = match self.padlen.as_str() {
            "scipy" => PadLen::Scipy,
            "matlab" => PadLen::Matlab,
            n => PadLen::Samples(n.parse().map_err(|_| {
                anyhow::anyhow!("--padlen {n:?}: expected scipy, matlab or a number of samples")
            })?),
        };
        let bias = match self.bias.as_str() {
            "none" => BiasRemoval::None,
            "auto" => BiasRemoval::Auto {
                contact_threshold: self.contact_threshold_n,
            },
            ranges => BiasRemoval::Ranges(parse_ranges(ranges)?),
        };
        Ok(CleanConfig {
            cutoff_hz: self.cutoff_hz,
            taps: self.taps,
            window: Window::parse(&self.window)?,
            filtfilt: FiltFiltOptions { padding, padlen },
            bias,
        })
    }

    /// Filters and debiases a force table (sorted, repeats dropped, gaps filled on a uniform
    /// grid at the median sample interval: [`visuotact_signal::clean`]).
    pub(crate) fn process(&self, mut table: ForceTable, name: &str) -> anyhow::Result<Processed> {
        let cfg = self.config()?;
        let duplicates = table.sort_dedup();
        let channels: Vec<Vec<f64>> = (0..6).map(|k| table.axis(k)).collect();
        let detect: Vec<usize> = (0..3).filter(|&k| table.present[k]).collect();
        let c = clean(&table.timestamp_s, &channels, &detect, &cfg)
            .with_context(|| name.to_string())?;
        Ok(Processed {
            filled: c.filled,
            t: c.t,
            raw: c.raw,
            clean: c.clean,
            present: table.present,
            bias: c.bias,
            rate_hz: c.rate_hz,
            duplicates,
        })
    }
}

/// Parses `A:B,C:D` (seconds).
fn parse_ranges(s: &str) -> anyhow::Result<Vec<(f64, f64)>> {
    s.split(',')
        .map(|r| {
            let (a, b) = r
                .split_once(':')
                .with_context(|| format!("--bias {s:?}: expected auto, none or A:B,C:D seconds"))?;
            Ok((a.trim().parse()?, b.trim().parse()?))
        })
        .collect()
}

#[derive(clap::Args, Debug)]
pub(crate) struct FilterArgs {
    /// Force CSV (`timestamp_s` and any of fx_n … tz_nm), as `simulate` and `record` write.
    input: PathBuf,
    /// Output CSV: the same axes, low-passed and debiased, on a uniform time grid.
    #[arg(short, long)]
    output: PathBuf,
    /// Before/after plot (.svg or .png).
    #[arg(long)]
    plot: Option<PathBuf>,
    #[command(flatten)]
    force: ForceArgs,
}

pub(crate) fn filter(a: &FilterArgs) -> anyhow::Result<()> {
    let table = ForceTable::read(&a.input).map_err(anyhow::Error::msg)?;
    if table.dropped_partial_line {
        eprintln!(
            "note: {}: an unfinished last line was left out",
            a.input.display()
        );
    }
    let p = a.force.process(table, &a.input.display().to_string())?;
    let cols: Vec<usize> = (0..6).filter(|&k| p.present[k]).collect();
    let mut text = String::from("timestamp_s");
    for &k in &cols {
        text.push(',');
        text.push_str(AXES[k]);
    }
    text.push('\n');
    for (i, t) in p.t.iter().enumerate() {
        text.push_str(&format!("{t:.6}"));
        for &k in &cols {
            text.push_str(&format!(",{:.6}", p.clean[k][i]));
        }
        text.push('\n');
    }
    crate::write_atomically(&a.output, &text)?;
    eprintln!(
        "{} samples at {:.1} Hz ({} missing filled, {} repeats dropped); low-pass {} taps at {} Hz",
        p.t.len(),
        p.rate_hz,
        p.filled,
        p.duplicates,
        a.force.taps,
        a.force.cutoff_hz
    );
    if let Some(b) = &p.bias {
        let periods = b.periods(0.5);
        let first = b.at(p.t[0]);
        let last = b.at(p.t[p.t.len() - 1]);
        eprintln!(
            "bias from {} no-contact periods: fz {:.4} N at the start, {:.4} N at the end",
            periods.len(),
            first[2],
            last[2]
        );
    }
    if let Some(path) = &a.plot {
        crate::plot::save(&ForcePlot(&p), path)?;
        eprintln!("wrote {}", path.display());
    }
    eprintln!("wrote {}", a.output.display());
    Ok(())
}

/// Raw, filtered and debiased force per axis, with the bias.
struct ForcePlot<'a>(&'a Processed);

impl crate::plot::Figure for ForcePlot<'_> {
    fn size(&self) -> (u32, u32) {
        let n = self.0.present.iter().filter(|p| **p).count().max(1) as u32;
        (1000, 220 * n + 20)
    }

    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String> {
        use crate::plot::{finite_range, padded, text};
        let p = self.0;
        root.fill(&WHITE).map_err(text)?;
        let axes: Vec<usize> = (0..6).filter(|&k| p.present[k]).collect();
        let (t0, t1) = (p.t[0], p.t[p.t.len() - 1]);
        // At most ~4000 points per line: a 1 kHz record of minutes stays a small file.
        let step = (p.t.len() / 4000).max(1);
        for (area, &k) in root.split_evenly((axes.len(), 1)).iter().zip(&axes) {
            let (lo, hi) = padded(
                finite_range(p.raw[k].iter().chain(&p.clean[k]).copied()).unwrap_or((0.0, 1.0)),
                0.05,
            );
            let mut chart = ChartBuilder::on(area)
                .caption(
                    format!(
                        "{}: raw (grey), filtered and debiased (blue), bias (red)",
                        AXES[k]
                    ),
                    ("sans-serif", 15),
                )
                .margin(8)
                .x_label_area_size(30)
                .y_label_area_size(55)
                .build_cartesian_2d(t0..t1, lo..hi)
                .map_err(text)?;
            chart
                .configure_mesh()
                .x_desc("time (s)")
                .draw()
                .map_err(text)?;
            let line = |v: &[f64]| -> Vec<(f64, f64)> {
                p.t.iter()
                    .zip(v)
                    .step_by(step)
                    .map(|(t, v)| (*t, *v))
                    .collect()
            };
            chart
                .draw_series(LineSeries::new(line(&p.raw[k]), RGBColor(170, 170, 170)))
                .map_err(text)?;
            chart
                .draw_series(LineSeries::new(line(&p.clean[k]), BLUE))
                .map_err(text)?;
            if let Some(b) = &p.bias {
                let pts: Vec<(f64, f64)> =
                    p.t.iter().step_by(step).map(|&t| (t, b.at(t)[k])).collect();
                chart.draw_series(LineSeries::new(pts, RED)).map_err(text)?;
            }
        }
        Ok(())
    }
}
