//! The report page of `visuotact eval --report` (the error table, the regression plot and the
//! contact map of one evaluation) as a [`Page`], and the parts every report page shares: the
//! error table and the run's settings and timings.

use visuotact_nn::metrics::{TargetErrors, MPE_FLOOR_FRACTION};
use visuotact_pipeline::evaluation::Evaluation;

use crate::figures::{ContactMap, Panel, RegressionPlot};
use crate::html::Page;
use crate::ReportError;

/// What a run was asked and how long its parts took, for the page's last section.
#[derive(Clone, Debug, Default)]
pub struct RunInfo {
    /// (setting, value), e.g. ("seed", "1").
    pub settings: Vec<(String, String)>,
    /// (part, seconds).
    pub timings_s: Vec<(String, f64)>,
}

/// The table of a set of target errors.
pub fn error_rows(errors: &[&TargetErrors]) -> Vec<Vec<String>> {
    errors
        .iter()
        .map(|f| {
            vec![
                f.target.clone(),
                f.n.to_string(),
                format!("{:.4e}", f.mse),
                format!("{:.5}", f.r),
                format!("{:.4}", f.mean_abs),
                format!("{:.4}", f.max_abs),
                format!("{:.2}", f.mean_percentage_error),
                format!("{:.2}", f.accuracy_percent),
            ]
        })
        .collect()
}

/// The columns of [`error_rows`].
pub const ERROR_HEADER: [&str; 8] = [
    "target",
    "n",
    "MSE",
    "R",
    "mean |e|",
    "max |e|",
    "MPE %",
    "accuracy %",
];

/// The settings and timings of a run.
pub fn run_section(page: &mut Page, run: &RunInfo) {
    page.heading(2, "Run");
    let settings: Vec<Vec<String>> = run
        .settings
        .iter()
        .map(|(k, v)| vec![k.clone(), v.clone()])
        .collect();
    page.table("settings", &["setting", "value"], &settings);
    let timings: Vec<Vec<String>> = run
        .timings_s
        .iter()
        .map(|(k, s)| vec![k.clone(), format!("{s:.1}")])
        .collect();
    page.table("timings", &["part", "seconds"], &timings);
}

/// `visuotact eval --report`: one evaluation's error table, regression plot and contact map.
pub fn evaluation_page(
    e: &Evaluation,
    (predictions, labels): (&str, &str),
    run: &RunInfo,
) -> Result<Page, ReportError> {
    let mut page = Page::new(&format!("visuotact eval — {predictions} against {labels}"));
    for note in &e.notes {
        page.paragraph(&format!("note: {note}"));
    }
    page.heading(2, "Errors");
    let figures: Vec<&TargetErrors> = e.targets.iter().map(|t| &t.errors).collect();
    page.table(
        &format!(
            "MPE and accuracy over samples with |target| ≥ {:.0} % of the largest |target|",
            100.0 * MPE_FLOOR_FRACTION
        ),
        &ERROR_HEADER,
        &error_rows(&figures),
    );
    if let Some(d) = e.distance_mm {
        page.paragraph(&format!(
            "Contact distance D (x, y): mean {:.3} mm, max {:.3} mm.",
            d.mean, d.max
        ));
    }
    let panels: Vec<Panel> = e
        .targets
        .iter()
        .map(|t| (t.errors.target.clone(), t.points.clone(), t.errors.r))
        .collect();
    page.heading(2, "Figures");
    page.figure(
        "Estimate against truth, one panel per target, with y = x and R",
        &RegressionPlot(&panels),
    )?;
    if let Some(d) = e.distance_mm {
        page.figure(
            "Contact map: actual (rings) and estimated (discs) contact points, joined; radius ∝ depth",
            &ContactMap {
                points: &e.map,
                distance_mean_mm: d.mean,
            },
        )?;
    }
    run_section(&mut page, run);
    Ok(page)
}
