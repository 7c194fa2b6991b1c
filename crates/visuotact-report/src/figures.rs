//! The figures of the command line and the reports, each a [`Figure`] over plain data: the
//! regression plot and the contact map of an evaluation (seed 000 Fig. 10), a force record
//! before and after cleaning, and an architecture sweep's performance against network size
//! (seed 001 Figs. 4.8/4.11/4.13).

use plotters::coord::ranged1d::ValueFormatter;
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use visuotact_io::force::AXES;
use visuotact_signal::bias::Bias;

use crate::{finite_range, padded, text, Figure};

/// Seed 000 Fig. 10: actual contact points (rings) and estimates (discs), joined; radius ∝
/// depth; y down, as the marker coordinates.
pub struct ContactMap<'a> {
    /// Actual and estimated (x, y, depth) per touch; depth NaN when absent.
    pub points: &'a [([f64; 3], [f64; 3])],
    /// The mean contact distance D, mm (in the caption).
    pub distance_mean_mm: f64,
}

impl Figure for ContactMap<'_> {
    fn size(&self) -> (u32, u32) {
        (800, 640)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        root.fill(&WHITE).map_err(text)?;
        let pts = self.points;
        let (x_lo, x_hi) = padded(
            finite_range(pts.iter().flat_map(|(a, e)| [a[0], e[0]])).unwrap_or((0.0, 1.0)),
            0.04,
        );
        let (y_lo, y_hi) = padded(
            finite_range(pts.iter().flat_map(|(a, e)| [a[1], e[1]])).unwrap_or((0.0, 1.0)),
            0.04,
        );
        let depth_max = pts
            .iter()
            .flat_map(|(a, e)| [a[2], e[2]])
            .filter(|d| d.is_finite())
            .fold(0.0f64, |m, d| m.max(d.abs()));
        let radius = |d: f64| -> i32 {
            if d.is_finite() && depth_max > 0.0 {
                (2.0 + 10.0 * (d.abs() / depth_max)).round() as i32
            } else {
                4
            }
        };
        let depth_note = if depth_max > 0.0 {
            ", radius ∝ depth"
        } else {
            ""
        };
        let mut chart = ChartBuilder::on(root)
            .caption(
                format!(
                    "contact map: actual (rings) and estimated (discs){depth_note}; D mean {:.3} mm",
                    self.distance_mean_mm
                ),
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(x_lo..x_hi, y_hi..y_lo)
            .map_err(text)?;
        chart
            .configure_mesh()
            .x_desc("x, mm")
            .y_desc("y, mm")
            .draw()
            .map_err(text)?;
        chart
            .draw_series(pts.iter().map(|(a, e)| {
                PathElement::new([(a[0], a[1]), (e[0], e[1])], RED.mix(0.6).stroke_width(1))
            }))
            .map_err(text)?;
        chart
            .draw_series(
                pts.iter()
                    .map(|(a, _)| Circle::new((a[0], a[1]), radius(a[2]), BLACK.stroke_width(1))),
            )
            .map_err(text)?;
        chart
            .draw_series(
                pts.iter()
                    .map(|(_, e)| Circle::new((e[0], e[1]), radius(e[2]), BLUE.mix(0.45).filled())),
            )
            .map_err(text)?;
        Ok(())
    }
}

/// One regression panel: target name, (truth, estimate) pairs, R.
pub type Panel = (String, Vec<(f64, f64)>, f64);

/// Estimates against truth, one panel per target, with the y = x line and R.
pub struct RegressionPlot<'a>(pub &'a [Panel]);

impl Figure for RegressionPlot<'_> {
    fn size(&self) -> (u32, u32) {
        (420 * self.0.len().max(1) as u32, 420)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        root.fill(&WHITE).map_err(text)?;
        for (area, (name, pts, r)) in root
            .split_evenly((1, self.0.len().max(1)))
            .iter()
            .zip(self.0)
        {
            let (lo, hi) = padded(
                finite_range(pts.iter().flat_map(|p| [p.0, p.1])).unwrap_or((0.0, 1.0)),
                0.05,
            );
            let mut chart = ChartBuilder::on(area)
                .caption(format!("{name}: R = {r:.5}"), ("sans-serif", 18))
                .margin(10)
                .x_label_area_size(35)
                .y_label_area_size(50)
                .build_cartesian_2d(lo..hi, lo..hi)
                .map_err(text)?;
            chart
                .configure_mesh()
                .x_desc("target")
                .y_desc("estimate")
                .draw()
                .map_err(text)?;
            chart
                .draw_series(LineSeries::new([(lo, lo), (hi, hi)], &BLACK))
                .map_err(text)?;
            chart
                .draw_series(
                    pts.iter()
                        .map(|&(t, e)| Circle::new((t, e), 2, BLUE.mix(0.5).filled())),
                )
                .map_err(text)?;
        }
        Ok(())
    }
}

/// A force record on a uniform time grid, before and after cleaning.
pub struct ForceRecord<'a> {
    /// Sample times, s.
    pub t: &'a [f64],
    /// Raw values, one vector per axis (fx … tz).
    pub raw: &'a [Vec<f64>],
    /// Filtered, debiased values.
    pub clean: &'a [Vec<f64>],
    /// Which axes the record has.
    pub present: [bool; 6],
    /// The bias removed, if any.
    pub bias: Option<&'a Bias>,
}

/// Raw, filtered and debiased force per axis, with the bias.
pub struct ForcePlot<'a>(pub ForceRecord<'a>);

impl Figure for ForcePlot<'_> {
    fn size(&self) -> (u32, u32) {
        let n = self.0.present.iter().filter(|p| **p).count().max(1) as u32;
        (1000, 220 * n + 20)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let p = &self.0;
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
            if let Some(b) = p.bias {
                let pts: Vec<(f64, f64)> =
                    p.t.iter().step_by(step).map(|&t| (t, b.at(t)[k])).collect();
                chart.draw_series(LineSeries::new(pts, RED)).map_err(text)?;
            }
        }
        Ok(())
    }
}

/// Mean and best test MSE against the number of hidden neurons (seed 001 Figs. 4.8/4.11/4.13).
pub struct PerformancePlot<'a> {
    /// (hidden neurons, mean test MSE, best test MSE) per architecture.
    pub points: &'a [(f64, f64, f64)],
    /// The targets' names (in the caption).
    pub targets: &'a [String],
}

impl Figure for PerformancePlot<'_> {
    fn size(&self) -> (u32, u32) {
        (800, 500)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        root.fill(&WHITE).map_err(text)?;
        let xmax = self.points.iter().map(|p| p.0).fold(1.0, f64::max);
        let ys = self
            .points
            .iter()
            .flat_map(|p| [p.1, p.2])
            .filter(|v| *v > 0.0);
        let (ymin, ymax) = finite_range(ys).map_or((1e-6, 1.0), |(lo, hi)| (lo * 0.8, hi * 1.25));
        let caption = format!(
            "Performance against network size ({})",
            self.targets.join(", ")
        );
        let mut builder = ChartBuilder::on(root);
        builder
            .caption(caption, ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(40)
            .y_label_area_size(80);
        // A log axis only pays when the errors span decades; within one it has no labels.
        if ymax / ymin > 20.0 {
            let mut chart = builder
                .build_cartesian_2d(0.0..xmax + 1.0, (ymin..ymax).log_scale())
                .map_err(text)?;
            self.draw_series(&mut chart)
        } else {
            let mut chart = builder
                .build_cartesian_2d(0.0..xmax + 1.0, 0.0..ymax)
                .map_err(text)?;
            self.draw_series(&mut chart)
        }
    }
}

impl PerformancePlot<'_> {
    fn draw_series<'a, DB: DrawingBackend + 'a, Y>(
        &self,
        chart: &mut ChartContext<'a, DB, Cartesian2d<RangedCoordf64, Y>>,
    ) -> Result<(), String>
    where
        Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
    {
        chart
            .configure_mesh()
            .x_desc("hidden neurons")
            .y_desc("test MSE (target units²)")
            .x_label_formatter(&|x| format!("{x:.0}"))
            .y_label_formatter(&|y| format!("{y:.3e}"))
            .draw()
            .map_err(text)?;
        let mut mean: Vec<(f64, f64)> = self
            .points
            .iter()
            .map(|p| (p.0, p.1))
            .filter(|p| p.1 > 0.0)
            .collect();
        mean.sort_by(|a, b| a.0.total_cmp(&b.0));
        chart
            .draw_series(LineSeries::new(mean, &BLUE))
            .map_err(text)?
            .label("mean of repeats")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
        chart
            .draw_series(
                self.points
                    .iter()
                    .filter(|p| p.2 > 0.0)
                    .map(|p| Circle::new((p.0, p.2), 3, RED.filled())),
            )
            .map_err(text)?
            .label("best of repeats")
            .legend(|(x, y)| Circle::new((x + 10, y), 3, RED.filled()));
        chart
            .configure_series_labels()
            .border_style(BLACK)
            .background_style(WHITE)
            .draw()
            .map_err(text)
    }
}
