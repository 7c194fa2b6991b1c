//! `visuotact demo --quick` runs both experiments end to end, prints the papers' layouts and
//! writes the HTML report, which headless Chromium opens offline.

use std::path::Path;
use std::process::{Command, Stdio};

mod common;
use common::*;

#[test]
fn quick_demo_runs_both_experiments() {
    let d = fresh_dir("demo-report");
    let report = d.join("report.html");
    let o = Command::new(env!("CARGO_BIN_EXE_visuotact"))
        .args(["demo", "--quick", "--report", s(&report)])
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
        "Table 5.2 layout: visuotact | paper (with rotation)",
        "2 layers, best of 1..20 × 1..20",
        "paper: 1 hidden layer (74 neurons)",
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
    report_opens_offline(&report, &out);
}

/// The report holds the printed tables and the figures, refers to nothing outside itself, and
/// headless Chromium renders it: the tables are in its DOM and its screenshot is not blank.
fn report_opens_offline(report: &Path, printed: &str) {
    let html = std::fs::read_to_string(report).unwrap();
    for want in [
        "Table 3 layout",
        "Table 5.1 layout",
        "Contact map",
        "Sweep of 1..40",
        "seconds",
    ] {
        assert!(html.contains(want), "report lacks {want:?}");
    }
    // Every printed table row is in the page as printed (escaped).
    let row = printed
        .lines()
        .find(|l| l.contains("best of sweep, over its own press"))
        .unwrap();
    assert!(html.contains(row.trim()), "report lacks {row:?}");
    assert!(html.matches("<svg").count() >= 12, "figures missing");
    for outside in ["<script", "<link", "src=", "href="] {
        assert!(!html.contains(outside), "the report refers to {outside}");
    }
    let Some(chromium) = ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|c| {
            Command::new(c)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        })
    else {
        eprintln!("skipped the browser check: no chromium (scripts/test installs Debian's)");
        return;
    };
    let dir = report.parent().unwrap();
    let shot = dir.join("report.png");
    let url = format!("file://{}", report.display());
    let browser = |extra: &[&str]| {
        let profile = format!("--user-data-dir={}", dir.join("profile").display());
        let mut args = vec![
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            profile.as_str(),
        ];
        args.extend_from_slice(extra);
        args.push(&url);
        Command::new(chromium)
            .args(&args)
            .stderr(Stdio::null())
            .output()
            .unwrap()
    };
    let dom = browser(&["--dump-dom"]);
    let dom = String::from_utf8_lossy(&dom.stdout);
    for want in [
        "Table 3 layout",
        "Table 5.1 layout",
        "Table 5.2 layout",
        "<svg",
        "<table",
    ] {
        assert!(dom.contains(want), "Chromium's DOM lacks {want:?}");
    }
    let arg = format!("--screenshot={}", shot.display());
    browser(&[arg.as_str(), "--window-size=1280,2400", "--hide-scrollbars"]);
    let img = image::open(&shot)
        .expect("Chromium wrote a screenshot")
        .to_rgb8();
    // Text and figures: a good share of the page is not background.
    let inked = img
        .pixels()
        .filter(|p| p.0.iter().any(|&c| c < 200))
        .count();
    let share = inked as f64 / (img.width() * img.height()) as f64;
    assert!(
        share > 0.02,
        "screenshot nearly blank: {share:.4} of pixels inked"
    );
}
