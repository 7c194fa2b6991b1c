//! `visuotact demo`: both source documents' experiments end to end on the simulator
//! ([`visuotact_pipeline::demo`]), printed beside the papers' numbers.

use std::time::Instant;

use visuotact_pipeline::demo::{self, DemoConfig};
use visuotact_report::tables::{cone_text, iats_text};

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// A smaller run (under a minute): half the grid in each axis, shorter presses.
    #[arg(long)]
    quick: bool,
    /// Seed of the simulation, the splits and the weights.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let t_all = Instant::now();
    let cfg = DemoConfig {
        quick: a.quick,
        seed: a.seed,
    };
    println!("== Seed 000: image-based areal touch sensor (117 markers, 60 × 45 mm) ==");
    print!("{}", iats_text(&demo::iats(&cfg)?));
    println!("\n== Seed 001: inflatable link (cone, three annuli, JR3 force) ==");
    print!("{}", cone_text(&demo::cone(&cfg)?));
    println!("\ndemo finished in {:.0} s", t_all.elapsed().as_secs_f64());
    Ok(())
}
