//! `visuotact filter`: force CSV → zero-phase low-passed, debiased CSV with a before/after plot
//! ([`visuotact_signal::clean`]).

use std::path::PathBuf;

use anyhow::Context;
use visuotact_io::force::{ForceTable, AXES};
use visuotact_pipeline::dataset::clean_table;
use visuotact_report::figures::{ForcePlot, ForceRecord};

use crate::args::ForceArgs;

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Force CSV (`timestamp_s` and any of fx_n … tz_nm), as `simulate` and `record` write.
    input: PathBuf,
    /// Output CSV: the same axes, low-passed and debiased, on a uniform time grid.
    #[arg(short, long)]
    output: PathBuf,
    /// Before/after plot (.svg or .png).
    #[arg(long)]
    plot: Option<PathBuf>,
    #[command(flatten)]
    force: ForceArgs,
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let mut outputs = vec![a.output.as_path()];
    outputs.extend(a.plot.as_deref());
    visuotact_io::guard::refuse_outputs_over_inputs(&outputs, &[&a.input])?;
    let mut notes = Vec::new();
    let mut table = ForceTable::read_noting(&a.input, &mut notes).map_err(anyhow::Error::msg)?;
    for n in notes {
        note!("note: {n}");
    }
    let (p, duplicates) = clean_table(&mut table, &a.force.config()?)
        .with_context(|| a.input.display().to_string())?;
    let cols: Vec<usize> = (0..6).filter(|&k| table.present[k]).collect();
    let mut text = String::from("timestamp_s");
    for &k in &cols {
        text.push(',');
        text.push_str(AXES[k]);
    }
    text.push('\n');
    for (i, t) in p.t.iter().enumerate() {
        text.push_str(&format!("{t:.6}"));
        for &k in &cols {
            text.push_str(&format!(",{:.6}", p.clean[k][i]));
        }
        text.push('\n');
    }
    crate::write_atomically(&a.output, &text)?;
    note!(
        "{} samples at {:.1} Hz ({} missing filled, {} repeats dropped); low-pass {} taps at {} Hz",
        p.t.len(),
        p.rate_hz,
        p.filled,
        duplicates,
        a.force.taps,
        a.force.cutoff_hz
    );
    if let Some(b) = &p.bias {
        let periods = b.periods(0.5);
        let first = b.at(p.t[0]);
        let last = b.at(p.t[p.t.len() - 1]);
        // The force axes the table has (contact is detected on them), start → end.
        let drift: Vec<String> = (0..3)
            .filter(|&k| table.present[k])
            .map(|k| format!("{} {:.4} → {:.4} N", &AXES[k][..2], first[k], last[k]))
            .collect();
        note!(
            "bias from {} no-contact periods (start → end): {}",
            periods.len(),
            drift.join(", ")
        );
    }
    if let Some(path) = &a.plot {
        let record = ForceRecord {
            t: &p.t,
            raw: &p.raw,
            clean: &p.clean,
            present: table.present,
            bias: p.bias.as_ref(),
        };
        visuotact_report::save(&ForcePlot(record), path)?;
        note!("wrote {}", path.display());
    }
    note!("wrote {}", a.output.display());
    Ok(())
}
