//! `visuotact demo --quick` runs both experiments end to end and prints the papers' layouts.

use std::process::Command;

#[test]
fn quick_demo_runs_both_experiments() {
    let o = Command::new(env!("CARGO_BIN_EXE_visuotact"))
        .args(["demo", "--quick"])
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{out}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    for want in [
        "Table 3 layout",
        "random touches (not in training)",
        "Table 5.1 layout",
        "best of sweep, over its own press",
        "calibrated 117 markers",
        "calibrated 2 rings",
        "inputs rings + gauge",
    ] {
        assert!(out.contains(want), "missing {want:?} in\n{out}");
    }
    // The depth line: "depth: mean 0.247, max …": well under the 5 mm range even in the quick run.
    let depth_line = out
        .lines()
        .find(|l| l.trim_start().starts_with("depth:"))
        .unwrap();
    let mean: f64 = depth_line
        .split("mean ")
        .nth(1)
        .unwrap()
        .split(',')
        .next()
        .unwrap()
        .trim()
        .parse()
        .unwrap();
    assert!(mean < 0.6, "{depth_line}");
    // "best of sweep, over its own press (paper's way)   0.088  0.386  2.12 0.99951": R last.
    let r_line = out
        .lines()
        .find(|l| l.contains("best of sweep, over its own press"))
        .unwrap();
    let r: f64 = r_line.split_whitespace().last().unwrap().parse().unwrap();
    assert!(r > 0.99, "{r_line}");
}
