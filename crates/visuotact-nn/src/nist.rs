//! The NIST StRD nonlinear regression problems (`testdata/reference/nist_strd/*.dat`): parser,
//! the 27 models, and the log relative error (certified digits) of a fit.

use faer::Mat;

use crate::dual::Dual;
use crate::lm::Problem;

/// A model `f(b, x)`: parameters as dual numbers, one or two predictors.
pub type Model = fn(&[Dual], [f64; 2]) -> Dual;

/// One StRD problem.
#[derive(Clone, Debug)]
pub struct Dataset {
    /// Dataset name (`Misra1a`, …).
    pub name: String,
    /// Starting points 1 and 2.
    pub starts: [Vec<f64>; 2],
    /// Certified parameter values.
    pub certified: Vec<f64>,
    /// Certified residual sum of squares.
    pub certified_rss: f64,
    /// Responses.
    pub y: Vec<f64>,
    /// Predictors (one or two per observation).
    pub x: Vec<[f64; 2]>,
}

fn line_range(text: &str, label: &str) -> Option<(usize, usize)> {
    let l = text
        .lines()
        .find(|l| l.contains(label) && l.contains("(lines"))?;
    let inner = l.split("(lines").nth(1)?;
    let nums: Vec<usize> = inner
        .split(|c: char| !c.is_ascii_digit())
        .filter_map(|s| s.parse().ok())
        .collect();
    Some((*nums.first()?, *nums.get(1)?))
}

fn numbers(line: &str) -> Vec<f64> {
    line.split_whitespace()
        .filter_map(|t| t.parse::<f64>().ok())
        .collect()
}

/// Why a NIST StRD file does not parse.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum NistError {
    /// A section the format always has is not there.
    #[error("no {0}")]
    Missing(&'static str),
    /// A line of a section does not hold the numbers it should.
    #[error("bad {section} line {line:?}")]
    Line {
        /// `parameter`, `RSS` or `data`.
        section: &'static str,
        /// The line.
        line: String,
    },
}

impl NistError {
    fn line(section: &'static str, line: &str) -> Self {
        Self::Line {
            section,
            line: line.to_string(),
        }
    }
}

impl Dataset {
    /// Parses a `.dat` file's text; `name` is the dataset name (the file stem).
    pub fn parse(name: &str, text: &str) -> Result<Self, NistError> {
        let lines: Vec<&str> = text.lines().collect();
        let (s0, s1) = line_range(text, "Starting Values")
            .ok_or(NistError::Missing("starting-values line range"))?;
        let (d0, d1) = line_range(text, "Data ")
            .or_else(|| line_range(text, "Data"))
            .ok_or(NistError::Missing("data line range"))?;
        let mut starts = [Vec::new(), Vec::new()];
        let mut certified = Vec::new();
        for l in &lines[s0 - 1..s1] {
            // "  b1 =   500   250   2.3894212918E+02  2.7070075241E+00"
            let v = numbers(
                l.split('=')
                    .nth(1)
                    .ok_or_else(|| NistError::line("parameter", l))?,
            );
            if v.len() < 4 {
                return Err(NistError::line("parameter", l));
            }
            starts[0].push(v[0]);
            starts[1].push(v[1]);
            certified.push(v[2]);
        }
        let rss_line = lines
            .iter()
            .find(|l| l.contains("Residual Sum of Squares"))
            .ok_or(NistError::Missing("certified RSS"))?;
        let certified_rss = *numbers(rss_line)
            .last()
            .ok_or_else(|| NistError::line("RSS", rss_line))?;
        let (mut y, mut x) = (Vec::new(), Vec::new());
        for l in &lines[d0 - 1..d1.min(lines.len())] {
            let v = numbers(l);
            match v.len() {
                2 => {
                    y.push(v[0]);
                    x.push([v[1], 0.0]);
                }
                3 => {
                    y.push(v[0]);
                    x.push([v[1], v[2]]);
                }
                _ => return Err(NistError::line("data", l)),
            }
        }
        Ok(Self {
            name: name.to_string(),
            starts,
            certified,
            certified_rss,
            y,
            x,
        })
    }

    /// The model `f(b, x)` of this dataset.
    pub fn model(&self) -> Option<Model> {
        model(&self.name)
    }
}

/// The model of a named StRD dataset (Nelson's is for `ln y`).
pub fn model(name: &str) -> Option<Model> {
    use std::f64::consts::PI;
    let f: Model = match name {
        "Misra1a" | "BoxBOD" => |b, x| b[0] * (1.0 - (-(b[1] * x[0])).exp()),
        "Chwirut1" | "Chwirut2" => |b, x| (-(b[0] * x[0])).exp() / (b[1] + b[2] * x[0]),
        "Lanczos1" | "Lanczos2" | "Lanczos3" => |b, x| {
            b[0] * (-(b[1] * x[0])).exp()
                + b[2] * (-(b[3] * x[0])).exp()
                + b[4] * (-(b[5] * x[0])).exp()
        },
        "Gauss1" | "Gauss2" | "Gauss3" => |b, x| {
            let g1 = (x[0] - b[3]) / b[4];
            let g2 = (x[0] - b[6]) / b[7];
            b[0] * (-(b[1] * x[0])).exp() + b[2] * (-(g1 * g1)).exp() + b[5] * (-(g2 * g2)).exp()
        },
        "DanWood" => |b, x| b[0] * Dual::constant(x[0]).pow(b[1]),
        "Misra1b" => |b, x| b[0] * (1.0 - (1.0 + b[1] * x[0] / 2.0).powf(-2.0)),
        "Kirby2" => |b, x| {
            (b[0] + b[1] * x[0] + b[2] * x[0] * x[0]) / (1.0 + b[3] * x[0] + b[4] * x[0] * x[0])
        },
        "Hahn1" | "Thurber" => |b, x| {
            let (x1, x2, x3) = (x[0], x[0] * x[0], x[0] * x[0] * x[0]);
            (b[0] + b[1] * x1 + b[2] * x2 + b[3] * x3) / (1.0 + b[4] * x1 + b[5] * x2 + b[6] * x3)
        },
        "Nelson" => |b, x| b[0] - b[1] * x[0] * (-(b[2] * x[1])).exp(),
        "MGH17" => |b, x| b[0] + b[1] * (-(b[3] * x[0])).exp() + b[2] * (-(b[4] * x[0])).exp(),
        "Misra1c" => |b, x| b[0] * (1.0 - (1.0 + 2.0 * b[1] * x[0]).powf(-0.5)),
        "Misra1d" => |b, x| b[0] * b[1] * x[0] / (1.0 + b[1] * x[0]),
        "Roszman1" => |b, x| b[0] - b[1] * x[0] - (b[2] / (x[0] - b[3])).atan() / PI,
        "ENSO" => |b, x| {
            let t = 2.0 * PI * x[0];
            let c12 = Dual::constant((t / 12.0).cos());
            let s12 = Dual::constant((t / 12.0).sin());
            b[0] + b[1] * c12
                + b[2] * s12
                + b[4] * (t / b[3]).cos()
                + b[5] * (t / b[3]).sin()
                + b[7] * (t / b[6]).cos()
                + b[8] * (t / b[6]).sin()
        },
        "MGH09" => |b, x| b[0] * (x[0] * x[0] + x[0] * b[1]) / (x[0] * x[0] + x[0] * b[2] + b[3]),
        "Rat42" => |b, x| b[0] / (1.0 + (b[1] - b[2] * x[0]).exp()),
        "MGH10" => |b, x| b[0] * (b[1] / (x[0] + b[2])).exp(),
        "Eckerle4" => |b, x| {
            let z = (x[0] - b[2]) / b[1];
            (b[0] / b[1]) * (-0.5 * (z * z)).exp()
        },
        "Rat43" => |b, x| b[0] / (1.0 + (b[1] - b[2] * x[0]).exp()).pow(1.0 / b[3]),
        "Bennett5" => |b, x| b[0] * (b[1] + x[0]).pow(-1.0 / b[2]),
        _ => return None,
    };
    Some(f)
}

/// A dataset as a least-squares problem.
pub struct NistProblem<'a> {
    data: &'a Dataset,
    f: Model,
    log_y: bool,
}

impl<'a> NistProblem<'a> {
    /// Wraps a dataset; `None` for an unknown model.
    pub fn new(data: &'a Dataset) -> Option<Self> {
        Some(Self {
            data,
            f: data.model()?,
            log_y: data.name == "Nelson",
        })
    }

    fn target(&self, i: usize) -> f64 {
        if self.log_y {
            self.data.y[i].ln()
        } else {
            self.data.y[i]
        }
    }
}

impl Problem for NistProblem<'_> {
    fn n_params(&self) -> usize {
        self.data.certified.len()
    }

    fn n_residuals(&self) -> usize {
        self.data.y.len()
    }

    fn residuals(&mut self, p: &[f64], out: &mut [f64]) {
        let b: Vec<Dual> = p.iter().map(|&v| Dual::constant(v)).collect();
        for (i, o) in out.iter_mut().enumerate() {
            *o = (self.f)(&b, self.data.x[i]).v - self.target(i);
        }
    }

    fn jacobian(&mut self, p: &[f64], jac: &mut Mat<f64>) {
        let b: Vec<Dual> = p
            .iter()
            .enumerate()
            .map(|(k, &v)| Dual::var(v, k))
            .collect();
        for i in 0..self.data.y.len() {
            let f = (self.f)(&b, self.data.x[i]);
            for k in 0..p.len() {
                jac[(i, k)] = f.d[k];
            }
        }
    }
}

/// Log relative error: the number of digits of `est` that agree with `cert` (0..=11, where
/// 11 is all the certified digits).
pub fn certified_digits(est: f64, cert: f64) -> f64 {
    if !est.is_finite() {
        return 0.0;
    }
    let rel = if cert == 0.0 {
        est.abs()
    } else {
        ((est - cert) / cert).abs()
    };
    if rel == 0.0 {
        11.0
    } else {
        (-rel.log10()).clamp(0.0, 11.0)
    }
}
