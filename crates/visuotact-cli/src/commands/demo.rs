//! `visuotact demo`: both source documents' experiments end to end on the simulator
//! ([`visuotact_experiments::demo`]), printed beside the papers' numbers.

use std::path::PathBuf;
use std::time::Instant;

use visuotact_experiments::demo::{self, DemoConfig};
use visuotact_experiments::pages::demo_page;
use visuotact_experiments::tables::{cone_text, iats_text, rotation_text, torque_text};
use visuotact_report::pages::RunInfo;

#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// A smaller run (under a minute): half the grid in each axis, shorter presses.
    #[arg(long)]
    quick: bool,
    /// Seed of the simulation, the splits and the weights.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Also write one self-contained HTML page (readable offline): every table beside the
    /// papers', the regression plots, the contact map, the sweep figures, settings and timings.
    #[arg(long, value_name = "FILE.html")]
    report: Option<PathBuf>,
}

pub(crate) fn run(a: &Args) -> anyhow::Result<()> {
    let t_all = Instant::now();
    let cfg = DemoConfig {
        quick: a.quick,
        seed: a.seed,
    };
    say!("== The 117-marker membrane: image-based areal touch sensor (117 markers, 60 × 45 mm) ==");
    let iats = demo::iats(&cfg)?;
    let iats_s = t_all.elapsed().as_secs_f64();
    say_part!("{}", iats_text(&iats));
    say!("\n== The inflatable cone: inflatable link (cone, three annuli, JR3 force) ==");
    let cone = demo::cone(&cfg)?;
    say_part!("{}", cone_text(&cone));
    let t_rotation = Instant::now();
    say!("\n== The inflatable cone with rotation (Table 5.2) ==");
    let rotation = demo::cone_rotation(&cfg)?;
    say_part!("{}", rotation_text(&rotation));
    let rotation_s = t_rotation.elapsed().as_secs_f64();
    let t_torque = Instant::now();
    say!("\n== The inflatable cone's future work: torque from the T-shaped marker ==");
    let torque = demo::cone_torque(&cfg)?;
    say_part!("{}", torque_text(&torque));
    let torque_s = t_torque.elapsed().as_secs_f64();
    let total_s = t_all.elapsed().as_secs_f64();
    say!("\ndemo finished in {total_s:.0} s");
    if let Some(path) = &a.report {
        let run = RunInfo {
            settings: vec![
                (
                    "command".into(),
                    std::env::args().collect::<Vec<_>>().join(" "),
                ),
                ("version".into(), env!("CARGO_PKG_VERSION").into()),
                ("quick".into(), a.quick.to_string()),
                ("seed".into(), a.seed.to_string()),
                ("threads".into(), rayon::current_num_threads().to_string()),
            ],
            timings_s: vec![
                ("membrane: simulate and calibrate".into(), iats.setup_s),
                ("membrane: paper's network".into(), iats.paper.train_s),
                ("membrane: default".into(), iats.default.train_s),
                ("membrane in all".into(), iats_s),
                ("cone: one 6 → 20 → 1".into(), cone.one_network.train_s),
                (
                    "cone: sweep, rings".into(),
                    cone.sweeps.first().map_or(0.0, |s| s.secs),
                ),
                (
                    "cone: sweep, rings + gauge".into(),
                    cone.sweeps.get(1).map_or(0.0, |s| s.secs),
                ),
                (
                    "cone in all".into(),
                    total_s - iats_s - rotation_s - torque_s,
                ),
                (
                    "cone with rotation: sweeps and Table 5.2".into(),
                    rotation_s,
                ),
                ("cone: torque from the T".into(), torque_s),
                ("demo".into(), total_s),
            ],
        };
        demo_page(&iats, (&cone, &rotation, &torque), &run)?.write(path)?;
        note!("wrote {}", path.display());
    }
    Ok(())
}
