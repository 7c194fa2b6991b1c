//! `visuotact eval`: the error figures of predictions against labels
//! ([`visuotact_pipeline::evaluation`]), with the regression plot and the contact map.

use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Predictions from `predict`.
    #[arg(long)]
    predictions: PathBuf,
    /// Labels keyed by `frame`.
    #[arg(long)]
    labels: PathBuf,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// Also draw the regression plot (estimate against truth, one panel per target), as SVG or
    /// PNG by the file's extension.
    #[arg(long, value_name = "FILE.svg|FILE.png")]
    plot: Option<PathBuf>,
    /// Also draw the contact map (the membrane paper's Fig. 10): actual and estimated contact points
    /// (`x_mm`, `y_mm`), joined, circle size ∝ depth (`depth_mm`, when present); SVG or PNG.
    #[arg(long, value_name = "FILE.svg|FILE.png")]
    map: Option<PathBuf>,
    /// Also write one self-contained HTML page (readable offline): the error table, the
    /// regression plot and the contact map.
    #[arg(long, value_name = "FILE.html")]
    report: Option<PathBuf>,
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let outputs: Vec<&std::path::Path> = [&a.plot, &a.map, &a.report]
        .into_iter()
        .filter_map(Option::as_deref)
        .collect();
    visuotact_io::guard::refuse_outputs_over_inputs(&outputs, &[&a.predictions, &a.labels])?;
    crate::print::evaluation(
        &a.predictions,
        &a.labels,
        a.json,
        a.plot.as_deref(),
        a.map.as_deref(),
        a.report.as_deref(),
    )
}
