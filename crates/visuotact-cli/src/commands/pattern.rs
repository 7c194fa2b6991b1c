//! `visuotact pattern`: marker-grid test frames with exact truth
//! ([`visuotact_experiments::synth::write_pattern`]).

use std::path::PathBuf;

use anyhow::bail;
use visuotact_experiments::synth::{write_pattern, PatternConfig};
use visuotact_sim::pattern::GridPattern;

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Output folder: `rest/` (still frames), `touch/` (pressed frames), `truth.csv`.
    #[arg(short, long)]
    output: PathBuf,
    /// Number of rest (no-contact) frames.
    #[arg(long, default_value_t = 5)]
    rest: usize,
    /// Number of touch frames.
    #[arg(long, default_value_t = 20)]
    touches: usize,
    /// Largest sideways drag, in marker pitches.
    #[arg(long, default_value_t = 0.5)]
    max_drag: f64,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    if a.rest == 0 {
        bail!("--rest must be at least 1 (calibration needs a still frame)");
    }
    if !(0.0..=1.5).contains(&a.max_drag) {
        bail!("--max-drag must be in 0..1.5 pitches, got {}", a.max_drag);
    }
    write_pattern(&PatternConfig {
        output: a.output.clone(),
        rest: a.rest,
        touches: a.touches,
        max_drag: a.max_drag,
        seed: a.seed,
    })?;
    let pattern = GridPattern::IATS;
    note!(
        "wrote {} rest and {} touch frames ({}×{}, {} markers) to {}",
        a.rest,
        a.touches,
        pattern.width,
        pattern.height,
        pattern.rows * pattern.cols,
        a.output.display()
    );
    Ok(())
}
