//! The report page of `visuotact demo --report`: both papers' tables beside the papers'
//! numbers, the regression plots, the contact map, the sweep figures, the run's settings and
//! timings.

use visuotact_nn::metrics::TargetErrors;
use visuotact_report::figures::{ContactMap, Panel, PerformancePlot, RegressionPlot, SweepSurface};
use visuotact_report::html::Page;
use visuotact_report::pages::{run_section, RunInfo};
use visuotact_report::ReportError;

use crate::demo::{ConeDemo, ConeRow, IatsDemo, RotationDemo, TorqueDemo};
use crate::tables::{cone_text, iats_text, rotation_text, torque_text};

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
