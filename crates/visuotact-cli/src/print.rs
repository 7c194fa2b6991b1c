//! Printing what several commands report the same way.

use std::path::Path;

use anyhow::bail;
use visuotact_nn::metrics::TargetErrors;
use visuotact_pipeline::evaluation::{evaluate_files, Evaluation};
use visuotact_report::figures::{ContactMap, Panel, RegressionPlot};
use visuotact_report::pages::{
    evaluation_page, spread_rows, text_table, RunInfo, SPREAD_CAPTION, SPREAD_HEADER,
};

/// Writes `eval --report`'s page.
fn evaluation_report(
    e: &Evaluation,
    (predictions, labels): (&Path, &Path),
    path: &Path,
    secs: f64,
) -> anyhow::Result<()> {
    let run = RunInfo {
        settings: vec![
            (
                "command".into(),
                std::env::args().collect::<Vec<_>>().join(" "),
            ),
            ("version".into(), env!("CARGO_PKG_VERSION").into()),
        ],
        timings_s: vec![("evaluation".into(), secs)],
    };
    let names = (
        predictions.display().to_string(),
        labels.display().to_string(),
    );
    evaluation_page(e, (&names.0, &names.1), &run)?.write(path)?;
    note!("wrote {}", path.display());
    Ok(())
}

/// States a training's memory estimate before it starts.
pub(crate) fn memory(what: &str, bytes: u64) {
    note!(
        "memory: {what} about {} MiB at the peak",
        bytes.div_ceil(1 << 20)
    );
}

/// Prints the error figures of a predictions table against a labels table
/// ([`visuotact_pipeline::evaluation`]) and draws the figures asked for.
pub(crate) fn evaluation(
    predictions: &Path,
    labels: &Path,
    json: bool,
    plot: Option<&Path>,
    map: Option<&Path>,
    report: Option<&Path>,
) -> anyhow::Result<()> {
    let t0 = std::time::Instant::now();
    let e = evaluate_files(predictions, labels)?;
    for note in &e.notes {
        note!("note: {note}");
    }
    if let Some(path) = plot {
        let panels: Vec<Panel> = e
            .targets
            .iter()
            .map(|t| (t.errors.target.clone(), t.points.clone(), t.errors.r))
            .collect();
        visuotact_report::save(&RegressionPlot(&panels), path)?;
        note!("wrote {}", path.display());
    }
    if let Some(path) = map {
        let Some(d) = e.distance_mm else {
            bail!(
                "--map needs contact positions: columns x_mm and y_mm in both {} and {}",
                predictions.display(),
                labels.display()
            );
        };
        let figure = ContactMap {
            points: &e.map,
            distance_mean_mm: d.mean,
        };
        visuotact_report::save(&figure, path)?;
        note!("wrote {}", path.display());
    }
    if let Some(path) = report {
        evaluation_report(&e, (predictions, labels), path, t0.elapsed().as_secs_f64())?;
    }
    let figures: Vec<&TargetErrors> = e.targets.iter().map(|t| &t.errors).collect();
    if json {
        let spreads: Vec<_> = e.targets.iter().map(|t| t.spread).collect();
        let v = serde_json::json!({
            "targets": figures,
            "spread": spreads,
            "distance_mm": e.distance_mm,
        });
        say!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    say!(
        "{:<12} {:>6} {:>11} {:>8} {:>10} {:>10} {:>8} {:>9}",
        "target",
        "n",
        "mse",
        "R",
        "mean |e|",
        "max |e|",
        "MPE %",
        "acc. %"
    );
    for f in &figures {
        say!(
            "{:<12} {:>6} {:>11.4e} {:>8.5} {:>10.4} {:>10.4} {:>8.2} {:>9.2}",
            f.target,
            f.n,
            f.mse,
            f.r,
            f.mean_abs,
            f.max_abs,
            f.mean_percentage_error,
            f.accuracy_percent
        );
    }
    if let Some(d) = e.distance_mm {
        say!(
            "distance D (x, y): mean {:.3} mm, max {:.3} mm",
            d.mean,
            d.max
        );
    }
    say!(
        "MPE and accuracy over samples with |target| ≥ {:.0} % of the largest |target|",
        100.0 * visuotact_nn::metrics::MPE_FLOOR_FRACTION
    );
    spread_checks(&e);
    Ok(())
}

/// The table of how each target's `<target>_std` agrees with its errors, when any has one.
fn spread_checks(e: &Evaluation) {
    let rows = spread_rows(e);
    if !rows.is_empty() {
        say!("{}:", SPREAD_CAPTION.to_lowercase());
        say_part!("{}", text_table(&SPREAD_HEADER, &rows));
    }
}
