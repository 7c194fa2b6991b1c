//! Text reports: the demo's experiments laid out as the source documents' tables, beside the
//! papers' numbers (`visuotact demo` prints them).

use std::fmt::Write as _;

use crate::demo::{ConeDemo, ConeRow, IatsDemo, RotationDemo, SweepBest, TorqueDemo};
use visuotact_nn::metrics::TargetErrors;
use visuotact_sim::protocol::PressureGauge;

/// Seed 000's experiment: the trainings, Table 3 and the random touches beside the paper.
pub fn iats_text(d: &IatsDemo) -> String {
    let mut out = String::new();
    iats_training(&mut out, d);
    table3(&mut out, d);
    random(&mut out, d);
    out
}

fn joined(v: &[usize]) -> String {
    v.iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join(" → ")
}

fn iats_training(out: &mut String, d: &IatsDemo) {
    let _ =
        writeln!(out,
        "calibrated {} markers; grid protocol: {} touches, {} with every marker found ({:.1} s)",
        d.markers, d.grid_touches, d.complete_frames, d.setup_s
    );
    let _ = writeln!(out,
        "the paper's network: 351 → 20 → 20 → 20 → 20 → 20 → 3 by Levenberg–Marquardt (trainlm): {} epochs in {:.1} s (the paper: 13 h 20 min)",
        d.paper.model.training.epochs, d.paper.train_s
    );
    let m = &d.default.model;
    let _ = writeln!(out,
        "visuotact's default (`visuotact train` with no options{}): {} of {} frames, {} → {} → 3, {} ({} networks, {} epochs) in {:.1} s",
        d.quick_note,
        d.default_frames,
        d.grid_touches,
        d.default.inputs,
        joined(&d.default_hidden),
        m.training.algorithm,
        m.networks().count(),
        m.training.epochs,
        d.default.train_s
    );
}

fn table3(out: &mut String, d: &IatsDemo) {
    let _ = writeln!(out,
        "\nTable 3 layout, visuotact's default: actual | estimate ± its stated spread | error || paper's estimate | paper's error"
    );
    for (k, r) in d.table3.iter().enumerate() {
        let (actual, paper) = (r.actual, r.paper);
        let (v, sd) = match &r.estimate {
            Ok(e) => e,
            Err(why) => {
                let _ = writeln!(out, "{}  no estimate: {why}", k + 1);
                continue;
            }
        };
        let d = (v[0] - actual[0]).hypot(v[1] - actual[1]);
        let pd = (paper[0] - actual[0]).hypot(paper[1] - actual[1]);
        let _ = writeln!(out,
            "{}  X {:>4} Y {:>4} Depth {} | X {:6.2} ± {:.2} Y {:6.2} ± {:.2} Depth {:5.2} ± {:.2} | D {:4.2} mm, depth {:4.2} mm || X {:5.2} Y {:5.2} Depth {:4.2} | D {:4.2} mm, depth {:4.2} mm",
            k + 1,
            actual[0],
            actual[1],
            actual[2],
            v[0],
            sd[0],
            v[1],
            sd[1],
            v[2],
            sd[2],
            d,
            (v[2] - actual[2]).abs(),
            paper[0],
            paper[1],
            paper[2],
            pd,
            (paper[2] - actual[2]).abs()
        );
    }
}

fn row(e: &TargetErrors) -> String {
    format!(
        "mean {:.3}, max {:.3}, R {:.5}, accuracy {:.1} %",
        e.mean_abs, e.max_abs, e.r, e.accuracy_percent
    )
}

fn random(out: &mut String, d: &IatsDemo) {
    let _ = writeln!(out,
        "\n{} random touches (not in training), {} estimated by visuotact's default (mean ± its mean stated spread, the held-out error):",
        d.random_touches, d.errors[0].n
    );
    for (j, (name, paper_figures)) in [
        ("X:    ", "mean 1.84 mm, accuracy 86.7 %"),
        ("Y:    ", "mean 0.9 mm, accuracy 96.5 %"),
        ("depth:", "mean 0.2 mm, accuracy 94.9 %"),
    ]
    .into_iter()
    .enumerate()
    {
        let _ = writeln!(
            out,
            "  {name} {} (± {:.3})   | paper: {paper_figures}",
            row(&d.errors[j]),
            d.mean_spread[j]
        );
    }
    let (dmean, dmax) = d.distance_mm;
    let _ = writeln!(
        out,
        "  D:     mean {dmean:.3} mm, max {dmax:.3} mm   | paper: up to 3.24 mm (Table 2)"
    );
    let _ = writeln!(out,
        "  the paper's network on the {} of them with every marker found: D mean {:.3} mm, max {:.3} mm, depth mean {:.3} mm",
        d.paper_frames, d.paper_distance_mm.0, d.paper_distance_mm.1, d.paper_depth_mm
    );
}

/// Seed 001's experiment: the trainings, the sweeps and Table 5.1 beside the paper.
pub fn cone_text(d: &ConeDemo) -> String {
    let mut text = String::new();
    let out = &mut text;
    let _ = writeln!(out,
        "calibrated {} rings (the outermost is cut by the image border); trained 6 → 20 → 1 on {} frames: {} epochs in {:.2} s",
        d.rings, d.train_frames, d.one_network.model.training.epochs, d.one_network.train_s
    );
    for s in &d.sweeps {
        sweep_line(out, "1..40 neurons", d.repeats, s);
    }
    let _ = writeln!(out,
        "\nTable 5.1 layout: visuotact | paper (no rotation)\n  {:<52} {:<14} {:>8} {:>8} {:>8} {:>7}",
        "", "inputs", "mean N", "max N", "MPE %", "R"
    );
    force_rows(out, &d.rows);
    let _ = writeln!(
        out,
        "  {:<52} {:<14} {:>8.3} {:>8.3} {:>8.2}",
        "paper (best of sweep, Testing Model)", "rings", 0.051, 0.531, 1.25
    );
    let _ = writeln!(out,
        "  (MPE over frames ≥ {:.2} N; the later press starts 5 s after the first ends, with the link's pressure {:.1} % lower;",
        d.mpe_floor_n, d.pressure_drop_percent
    );
    let _ =
        writeln!(out,
        "   gauge: the link's pressure through a {} s lag with {} kPa noise, read with each frame)",
        PressureGauge::SEED001.time_constant_s,
        PressureGauge::SEED001.noise_kpa
    );
    text
}

/// `6 → 74 → 1`: a sweep's best network.
fn network(s: &SweepBest) -> String {
    let hidden: Vec<String> = s.hidden.iter().map(ToString::to_string).collect();
    format!("{} → {} → 1", s.n_inputs, hidden.join(" → "))
}

/// `sweep SPAN × REPEATS, inputs …, in … s: best 6 → 22 → 1 (test MSE …)`.
fn sweep_line(out: &mut String, span: &str, repeats: u64, s: &SweepBest) {
    let _ = writeln!(
        out,
        "sweep {span} × {repeats}, inputs {}, in {:.1} s: best {} (test MSE {:.4})",
        s.inputs,
        s.secs,
        network(s),
        s.test_mse
    );
}

/// Rows of a force table: what, inputs, mean and max |error|, MPE, R.
fn force_rows(out: &mut String, rows: &[ConeRow]) {
    for r in rows {
        let e = &r.errors;
        let _ = writeln!(
            out,
            "  {:<52} {:<14} {:>8.3} {:>8.3} {:>8.2} {:>7.5}",
            r.what, r.inputs, e.mean_abs, e.max_abs, e.mean_percentage_error, e.r
        );
    }
}

/// Seed 001's experiment with rotation: the sweeps and Table 5.2 beside the paper.
pub fn rotation_text(d: &RotationDemo) -> String {
    let mut text = String::new();
    let out = &mut text;
    let _ = writeln!(
        out,
        "press with rotation (the force turns once about the axis); trained on {} frames",
        d.train_frames
    );
    for s in &d.one_layer {
        let span = format!("1..100 neurons ({} sizes)", s.curve.len());
        sweep_line(out, &span, d.repeats, s);
    }
    for s in &d.two_layer {
        let span = format!("1..20 × 1..20 neurons ({} architectures)", s.cells.len());
        sweep_line(out, &span, d.repeats, &s.best);
    }
    let _ = writeln!(out,
        "\nTable 5.2 layout: visuotact | paper (with rotation)\n  {:<52} {:<14} {:>8} {:>8} {:>8} {:>7}",
        "", "inputs", "mean N", "max N", "MPE %", "R"
    );
    force_rows(out, &d.rows);
    for (what, mean, max, mpe) in [
        ("paper: 1 hidden layer (74 neurons)", 0.185, 0.902, 5.446),
        ("paper: 2 hidden layers (16-1)", 0.255, 0.882, 7.094),
    ] {
        let _ = writeln!(
            out,
            "  {what:<52} {:<14} {mean:>8.3} {max:>8.3} {mpe:>8.2}",
            "rings"
        );
    }
    text
}

/// The inflatable cone's future work: torque from the T-shaped marker.
pub fn torque_text(d: &TorqueDemo) -> String {
    let mut text = String::new();
    let out = &mut text;
    let _ = writeln!(
        out,
        "T marker on the distal disc, the link twisted up to ±{:.0} N·mm while pressed; the T found in {:.1} % of the frames; trained on {} frames (force and torque), tested on a later press",
        d.max_torque_nmm, d.t_found_percent, d.train_frames
    );
    let _ = writeln!(
        out,
        "  {:<34} {:>10} {:>10} {:>8} {:>7}",
        "", "mean |e|", "max |e|", "MPE %", "R"
    );
    let rows = d
        .errors
        .iter()
        .map(|e| (format!("{} (rings + T)", e.target), e))
        .chain(std::iter::once((
            "torque_nmm (rings alone)".to_string(),
            &d.rings_only,
        )));
    for (what, e) in rows {
        let _ = writeln!(
            out,
            "  {what:<34} {:>10.3} {:>10.3} {:>8.2} {:>7.5}",
            e.mean_abs, e.max_abs, e.mean_percentage_error, e.r
        );
    }
    let _ = writeln!(
        out,
        "  (no paper figure: the cone paper planned torque as future work)"
    );
    text
}
