//! The figures of the command line and the reports, each a [`Figure`] over plain data: the
//! regression plot and the contact map of an evaluation (the membrane paper's Fig. 10), a force record
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

/// A two-layer sweep's mean test MSE over both layer sizes as a heat map (the cone paper's Fig. 4.13's
/// surface seen from above): one cell per architecture, coloured by log₁₀ of the error (dark
/// blue lowest, yellow highest), the best cell ringed, and a colour bar.
pub struct SweepSurface<'a> {
    /// (first layer, second layer, mean test MSE) per architecture.
    pub cells: &'a [(usize, usize, f64)],
    /// The targets' names (in the caption).
    pub targets: &'a [String],
}

/// A tick's label when it falls on a whole number (a layer size), else none.
fn integer_label(v: &f64) -> String {
    if (v - v.round()).abs() < 1e-9 {
        format!("{v:.0}")
    } else {
        String::new()
    }
}

/// A colour from dark blue (0) through teal and green to yellow (1).
pub fn heat_colour(t: f64) -> RGBColor {
    let stops = [
        (68.0, 1.0, 84.0),
        (59.0, 82.0, 139.0),
        (33.0, 145.0, 140.0),
        (94.0, 201.0, 98.0),
        (253.0, 231.0, 37.0),
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        1.0
    } * (stops.len() - 1) as f64;
    let k = (t.floor() as usize).min(stops.len() - 2);
    let w = t - k as f64;
    let (a, b) = (stops[k], stops[k + 1]);
    let mix = |x: f64, y: f64| (x + (y - x) * w).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

impl SweepSurface<'_> {
    /// log₁₀ range of the positive errors.
    fn log_range(&self) -> (f64, f64) {
        finite_range(self.cells.iter().filter(|c| c.2 > 0.0).map(|c| c.2.log10())).map_or(
            (0.0, 1.0),
            |(lo, hi)| {
                if hi > lo {
                    (lo, hi)
                } else {
                    (lo - 0.5, hi + 0.5)
                }
            },
        )
    }

    fn colour(&self, mse: f64) -> RGBColor {
        let (lo, hi) = self.log_range();
        heat_colour(if mse > 0.0 {
            (mse.log10() - lo) / (hi - lo)
        } else {
            f64::NAN
        })
    }
}

impl Figure for SweepSurface<'_> {
    fn size(&self) -> (u32, u32) {
        (760, 640)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        root.fill(&WHITE).map_err(text)?;
        let (map, bar) = root.split_horizontally(620);
        let n1 = self.cells.iter().map(|c| c.0).max().unwrap_or(1);
        let n2 = self.cells.iter().map(|c| c.1).max().unwrap_or(1);
        let mut chart = ChartBuilder::on(&map)
            .caption(
                format!(
                    "Mean test MSE over both layer sizes ({})",
                    self.targets.join(", ")
                ),
                ("sans-serif", 18),
            )
            .margin(15)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(0.5..n1 as f64 + 0.5, 0.5..n2 as f64 + 0.5)
            .map_err(text)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("first hidden layer")
            .y_desc("second hidden layer")
            .x_label_formatter(&integer_label)
            .y_label_formatter(&integer_label)
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(text)?;
        chart
            .draw_series(self.cells.iter().map(|&(a, b, mse)| {
                let (x, y) = (a as f64, b as f64);
                Rectangle::new(
                    [(x - 0.5, y - 0.5), (x + 0.5, y + 0.5)],
                    self.colour(mse).filled(),
                )
            }))
            .map_err(text)?;
        let best = self
            .cells
            .iter()
            .filter(|c| c.2 > 0.0)
            .min_by(|p, q| p.2.total_cmp(&q.2));
        if let Some(&(a, b, _)) = best {
            chart
                .draw_series([Circle::new((a as f64, b as f64), 8, RED.stroke_width(3))])
                .map_err(text)?;
        }
        self.draw_bar(&bar)
    }
}

impl SweepSurface<'_> {
    fn draw_bar<DB: DrawingBackend>(&self, bar: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let (lo, hi) = self.log_range();
        let mut chart = ChartBuilder::on(bar)
            .margin_top(60)
            .margin_bottom(55)
            .margin_right(5)
            .y_label_area_size(80)
            .build_cartesian_2d(0.0..1.0, lo..hi)
            .map_err(text)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .disable_x_axis()
            .y_label_formatter(&|v| format!("{:.1e}", 10f64.powf(*v)))
            .label_style(("sans-serif", 13))
            .y_labels(6)
            .draw()
            .map_err(text)?;
        let steps = 64;
        chart
            .draw_series((0..steps).map(|k| {
                let (a, b) = (k as f64 / steps as f64, (k + 1) as f64 / steps as f64);
                let (y0, y1) = (lo + (hi - lo) * a, lo + (hi - lo) * b);
                Rectangle::new([(0.0, y0), (1.0, y1)], heat_colour(a).filled())
            }))
            .map_err(text)?;
        Ok(())
    }
}

#[cfg(test)]
mod surface_tests {
    use super::*;

    #[test]
    fn heat_colours_run_from_dark_blue_to_yellow_and_nan_is_the_top() {
        assert_eq!(heat_colour(0.0), RGBColor(68, 1, 84));
        assert_eq!(heat_colour(1.0), RGBColor(253, 231, 37));
        assert_eq!(heat_colour(f64::NAN), heat_colour(1.0));
        assert_eq!(heat_colour(0.5), RGBColor(33, 145, 140));
    }

    #[test]
    fn the_surface_draws_one_cell_per_architecture_and_rings_the_best() {
        let cells = [(1, 1, 1e-2), (1, 2, 1e-3), (2, 1, 1e-1), (2, 2, 5e-3)];
        let targets = ["force_n".to_string()];
        let fig = SweepSurface {
            cells: &cells,
            targets: &targets,
        };
        let path = std::env::temp_dir().join(format!("vt-surface-{}.svg", std::process::id()));
        crate::save(&fig, &path).unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        // The lowest error is the darkest cell; the highest the yellow one.
        assert!(svg.contains("fill=\"#440154\""), "darkest cell");
        assert!(
            svg.contains("fill=\"#FDE725\"") || svg.contains("fill=\"#fde725\""),
            "yellow cell"
        );
        assert!(svg.contains("<circle"), "the best cell is ringed");
        assert!(svg.contains("first hidden layer") && svg.contains("second hidden layer"));
    }
}
