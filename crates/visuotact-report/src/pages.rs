//! The report page of `visuotact eval --report` (the error table, the regression plot and the
//! contact map of one evaluation, and how the stated spread agrees with the errors) as a
//! [`Page`], and the parts every report page shares: the error table and the run's settings
//! and timings.

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

/// How each target's stated spread (`<target>_std`) agrees with its errors, one row per target
/// that has one ([`visuotact_pipeline::evaluation::SpreadCheck`]); empty when none has.
pub fn spread_rows(e: &Evaluation) -> Vec<Vec<String>> {
    e.targets
        .iter()
        .filter_map(|t| {
            let c = t.spread?;
            Some(vec![
                t.errors.target.clone(),
                format!("{:.4}", c.mean_spread),
                format!("{:.1}", 100.0 * c.within_one),
                format!("{:.1}", 100.0 * c.within_two),
                format!("{:.2}", c.correlation),
                format!("{:.4}", c.top_quarter_error),
                format!("{:.4}", c.rest_error),
            ])
        })
        .collect()
}

/// The header of [`spread_rows`].
pub const SPREAD_HEADER: [&str; 7] = [
    "target",
    "mean std",
    "|e| ≤ std %",
    "|e| ≤ 2 std %",
    "corr.",
    "mean |e|, top 1/4 std",
    "mean |e|, rest",
];

/// The caption of [`spread_rows`]' table.
pub const SPREAD_CAPTION: &str = "The stated spread (<target>_std) against the errors (a normal error's standard deviation holds 68 % within 1 and 95 % within 2)";

/// `header` and `rows` as plain text for a terminal: one line each, columns padded to their
/// widest cell, the first left-aligned and the others right-aligned, two spaces apart.
///
/// ```
/// let t = visuotact_report::pages::text_table(&["a", "bb"], &[vec!["xyz".into(), "1".into()]]);
/// assert_eq!(t, "a    bb\nxyz   1\n");
/// ```
pub fn text_table(header: &[&str], rows: &[Vec<String>]) -> String {
    let width = |c: usize| {
        rows.iter()
            .filter_map(|r| r.get(c))
            .map(|v| v.chars().count())
            .chain([header[c].chars().count()])
            .max()
            .unwrap_or(0)
    };
    let widths: Vec<usize> = (0..header.len()).map(width).collect();
    let line = |cells: Vec<&str>| {
        let padded: Vec<String> = cells
            .iter()
            .zip(&widths)
            .enumerate()
            .map(|(c, (v, &w))| {
                if c == 0 {
                    format!("{v:<w$}")
                } else {
                    format!("{v:>w$}")
                }
            })
            .collect();
        padded.join("  ") + "\n"
    };
    let mut out = line(header.to_vec());
    for r in rows {
        out.push_str(&line(r.iter().map(String::as_str).collect()));
    }
    out
}

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
    let spread = spread_rows(e);
    if !spread.is_empty() {
        page.table(SPREAD_CAPTION, &SPREAD_HEADER, &spread);
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
