//! `visuotact pattern`: marker-grid test frames with exact truth.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{bail, Context};
use visuotact_io::frames::write_png;
use visuotact_sim::pattern::{render_grid, GridPattern, Press};

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
    let pattern = GridPattern::IATS;
    let rest_dir = a.output.join("rest");
    let touch_dir = a.output.join("touch");
    for d in [&rest_dir, &touch_dir] {
        std::fs::create_dir_all(d)
            .with_context(|| format!("{}: cannot create folder", d.display()))?;
    }
    for i in 0..a.rest {
        let (img, _) = render_grid(
            &pattern,
            None,
            a.seed.wrapping_mul(1_000_003).wrapping_add(i as u64),
        );
        write_png(&rest_dir.join(format!("rest_{i:04}.png")), &img)?;
    }
    // SplitMix64: a fixed, documented sequence for the touch parameters.
    let mut state = a.seed ^ 0x9E37_79B9_7F4A_7C15;
    let mut uniform = || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut truth =
        String::from("frame,x_px,y_px,sigma_px,push_px,shear_x_px,shear_y_px,grow,stretch\n");
    for i in 0..a.touches {
        let ang = uniform() * std::f64::consts::TAU;
        let drag = a.max_drag * pattern.pitch_x_px * uniform();
        let p = Press {
            x_px: 100.0 + 440.0 * uniform(),
            y_px: 90.0 + 300.0 * uniform(),
            sigma_px: 50.0 + 50.0 * uniform(),
            push_px: 8.0 * uniform(),
            shear_x_px: drag * ang.cos(),
            shear_y_px: drag * ang.sin(),
            grow: 0.3 * uniform(),
            stretch: 0.25 * uniform(),
        };
        let (img, _) = render_grid(
            &pattern,
            Some(&p),
            a.seed.wrapping_mul(7_919).wrapping_add(10_000 + i as u64),
        );
        let name = format!("touch_{i:04}.png");
        write_png(&touch_dir.join(&name), &img)?;
        let _ = writeln!(
            truth,
            "{name},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4}",
            p.x_px, p.y_px, p.sigma_px, p.push_px, p.shear_x_px, p.shear_y_px, p.grow, p.stretch
        );
    }
    crate::write_atomically(&a.output.join("truth.csv"), &truth)?;
    eprintln!(
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
