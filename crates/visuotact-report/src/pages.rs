//! The report pages of the command line as [`Page`]s: `visuotact demo --report` (both papers'
//! tables beside the papers' numbers, the regression plots, the contact map, the sweep
//! figures, the run's settings and timings) and `visuotact eval --report` (the error table,
//! the regression plot and the contact map of one evaluation).

use visuotact_nn::metrics::{TargetErrors, MPE_FLOOR_FRACTION};
use visuotact_pipeline::demo::{ConeDemo, ConeRow, IatsDemo, RotationDemo, TorqueDemo};
use visuotact_pipeline::evaluation::Evaluation;

use crate::figures::{ContactMap, Panel, PerformancePlot, RegressionPlot, SweepSurface};
use crate::html::Page;
use crate::tables::{cone_text, iats_text, rotation_text, torque_text};
use crate::ReportError;

/// What a run was asked and how long its parts took, for the page's last section.
#[derive(Clone, Debug, Default)]
pub struct RunInfo {
    /// (setting, value), e.g. ("seed", "1").
    pub settings: Vec<(String, String)>,
    /// (part, seconds).
    pub timings_s: Vec<(String, f64)>,
}

/// The regression panels of (actual, estimate) triples: x, y and depth, with each target's R.
fn xyz_panels(points: &[([f64; 3], [f64; 3])], errors: &[TargetErrors]) -> Vec<Panel> {
    ["x_mm", "y_mm", "depth_mm"]
        .iter()
        .enumerate()
        .map(|(j, name)| {
            let r = errors.get(j).map_or(f64::NAN, |e| e.r);
            let pts = points.iter().map(|(t, e)| (t[j], e[j])).collect();
            ((*name).to_string(), pts, r)
        })
        .collect()
}

/// The table of a set of target errors.
fn error_rows(errors: &[&TargetErrors]) -> Vec<Vec<String>> {
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

const ERROR_HEADER: [&str; 8] = [
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
fn run_section(page: &mut Page, run: &RunInfo) {
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

/// Regression plots of a force table's rows, two per figure.
fn force_regressions(page: &mut Page, table: &str, rows: &[ConeRow]) -> Result<(), ReportError> {
    let panels: Vec<Panel> = rows
        .iter()
        .map(|r| {
            let name = format!("{} [{}]", r.what, r.inputs);
            (name, r.points.clone(), r.errors.r)
        })
        .collect();
    for (k, chunk) in panels.chunks(2).enumerate() {
        page.figure(
            &format!(
                "Regression of the force (N), {table} rows {}–{}",
                2 * k + 1,
                2 * k + chunk.len()
            ),
            &RegressionPlot(chunk),
        )?;
    }
    Ok(())
}

/// The inflatable cone with rotation: Table 5.2, the sweeps' figures (Figs. 4.11 and 4.13) and the rows'
/// regressions.
fn rotation_section(page: &mut Page, d: &RotationDemo) -> Result<(), ReportError> {
    page.heading(3, "With rotation: Table 5.2, beside the paper");
    page.preformatted(&rotation_text(d));
    for s in &d.one_layer {
        page.figure(
            &format!(
                "With rotation, one hidden layer of 1..100 neurons × {} trainings, inputs {} \
                 (the cone paper's Fig. 4.11): mean and best test MSE (N²); best {} neurons",
                d.repeats, s.inputs, s.hidden[0]
            ),
            &PerformancePlot {
                points: &s.curve,
                targets: &["force_n".to_string()],
            },
        )?;
    }
    for s in &d.two_layer {
        page.figure(
            &format!(
                "With rotation, two hidden layers of 1..20 × 1..20 neurons, inputs {} (the cone paper's \
                 Fig. 4.13 seen from above): mean test MSE (N²), the best cell ringed",
                s.best.inputs
            ),
            &SweepSurface {
                cells: &s.cells,
                targets: &["force_n".to_string()],
            },
        )?;
    }
    force_regressions(page, "Table 5.2", &d.rows)
}

/// `visuotact demo --report`: both experiments, their tables beside the papers', and figures.
pub fn demo_page(
    iats: &IatsDemo,
    (cone, rotation, torque): (&ConeDemo, &RotationDemo, &TorqueDemo),
    run: &RunInfo,
) -> Result<Page, ReportError> {
    let mut page = Page::new("visuotact demo — both source documents' experiments");
    page.paragraph(
        "Everything below was measured in this run on the simulator (no hardware): each table \
         is laid out as in its paper, with the paper's numbers beside visuotact's.",
    );
    page.heading(
        2,
        "The 117-marker membrane: image-based areal touch sensor (117 markers, 60 × 45 mm)",
    );
    page.heading(
        3,
        "Trainings, Table 3 and the random touches, beside the paper",
    );
    page.preformatted(&iats_text(iats));
    page.figure(
        &format!(
            "Contact map of the {} random touches (the membrane paper's Fig. 10): actual contact points \
             (rings) and visuotact's estimates (discs), joined; radius ∝ depth. Mean D {:.3} mm.",
            iats.random_points.len(),
            iats.distance_mm.0
        ),
        &ContactMap {
            points: &iats.random_points,
            distance_mean_mm: iats.distance_mm.0,
        },
    )?;
    let panels = xyz_panels(&iats.random_points, &iats.errors);
    page.figure(
        "Regression of the random touches: estimate against truth (x, y, depth, mm) with R",
        &RegressionPlot(&panels),
    )?;
    page.heading(
        2,
        "The inflatable cone: inflatable link (cone, three annuli, JR3 force)",
    );
    page.heading(3, "Table 5.1, beside the paper");
    page.preformatted(&cone_text(cone));
    for s in &cone.sweeps {
        page.figure(
            &format!(
                "Sweep of 1..40 hidden neurons × {} trainings, inputs {} (the cone paper's Fig. 4.8): \
                 mean and best test MSE (N²); best {} neurons, {:.1} s",
                cone.repeats, s.inputs, s.hidden[0], s.secs
            ),
            &PerformancePlot {
                points: &s.curve,
                targets: &["force_n".to_string()],
            },
        )?;
    }
    force_regressions(&mut page, "Table 5.1", &cone.rows)?;
    rotation_section(&mut page, rotation)?;
    page.heading(
        3,
        "Torque from the T-shaped marker (the cone paper's future work)",
    );
    page.preformatted(&torque_text(torque));
    let r = torque.errors.get(1).map_or(f64::NAN, |e| e.r);
    let panel: Vec<Panel> = vec![("torque_nmm".to_string(), torque.points.clone(), r)];
    page.figure(
        "Torque on the later press (N·mm): estimate against the simulator's truth",
        &RegressionPlot(&panel),
    )?;
    run_section(&mut page, run);
    Ok(page)
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
