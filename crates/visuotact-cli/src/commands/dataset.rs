//! `visuotact dataset`: session folders → one features table and one labels table for `train`
//! ([`visuotact_pipeline::dataset`]).

use std::path::PathBuf;

use visuotact_io::table::format_number;
use visuotact_pipeline::dataset::{build, DatasetConfig};

use crate::args::ForceArgs;

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Session folders (`simulate` or `record`).
    #[arg(required = true)]
    sessions: Vec<PathBuf>,
    /// Output folder: features.csv and labels.csv, keyed by `frame` (`SESSION/frame` when
    /// more than one session is given).
    #[arg(short, long)]
    output: PathBuf,
    /// Sensor file, to extract features from sessions' frames (needed when a session has no
    /// features.csv).
    #[arg(long)]
    sensor: Option<PathBuf>,
    /// Latency correction, seconds: a frame at time t is labelled with the force at t + this.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    latency_s: f64,
    /// Longest run of missing force samples to interpolate across, seconds; frames inside a
    /// longer gap get no label.
    #[arg(long, default_value_t = 0.05)]
    max_gap_s: f64,
    #[command(flatten)]
    force: ForceArgs,
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let inputs: Vec<&std::path::Path> = a.sessions.iter().map(PathBuf::as_path).collect();
    visuotact_io::guard::refuse_output_over_input(&a.output, &inputs)?;
    let sensor = a.sensor.as_deref().map(crate::load_sensor).transpose()?;
    let cfg = DatasetConfig {
        latency_s: a.latency_s,
        max_gap_s: a.max_gap_s,
        clean: a.force.config()?,
    };
    let ds = build(&a.sessions, sensor.as_ref(), &cfg)?;
    for note in &ds.notes {
        note!("note: {note}");
    }
    let write = |name: &str, cols: &[String], rows: &[Vec<f64>]| -> anyhow::Result<()> {
        let mut text = format!("frame,{}\n", cols.join(","));
        for (k, r) in ds.keys.iter().zip(rows) {
            text.push_str(k);
            for v in r {
                text.push(',');
                text.push_str(&format_number(*v));
            }
            text.push('\n');
        }
        crate::write_atomically(&a.output.join(name), &text)
    };
    write("features.csv", &ds.feature_columns, &ds.features)?;
    write("labels.csv", &ds.label_columns, &ds.labels)?;
    note!(
        "wrote {} rows to {}/features.csv and labels.csv",
        ds.keys.len(),
        a.output.display()
    );
    Ok(())
}
