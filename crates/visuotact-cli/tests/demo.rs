//! `visuotact demo --quick` runs both experiments end to end, prints the papers' layouts and
//! writes the HTML report, which headless Chromium opens offline.

use std::path::Path;

mod common;
use common::*;

#[test]
fn quick_demo_runs_both_experiments() {
    let d = fresh_dir("demo-report");
    let report = d.join("report.html");
    let o = vt(&["demo", "--quick", "--report", s(&report)]);
    ok(&o);
    let out = String::from_utf8_lossy(&o.stdout);
    let wants = [
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
        "torque_nmm (rings + T)",
        "torque_nmm (rings alone)",
    ];
    has_all(&out, &wants, "the printed demo");
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
    // Torque from the T: "torque_nmm (rings + T)   mean max MPE R", R last; the T is what
    // carries it (the rings do not turn with the twist).
    let r_of = |label: &str| -> f64 {
        let line = out.lines().find(|l| l.contains(label)).unwrap();
        line.split_whitespace().last().unwrap().parse().unwrap()
    };
    let (with_t, rings) = (
        r_of("torque_nmm (rings + T)"),
        r_of("torque_nmm (rings alone)"),
    );
    assert!(
        with_t > 0.99 && with_t > rings,
        "torque R {with_t} with the T, {rings} without"
    );
    report_opens_offline(&report, &out);
}

/// Every one of `wants` is in `text`.
fn has_all(text: &str, wants: &[&str], what: &str) {
    for want in wants {
        assert!(text.contains(want), "{what} lacks {want:?}");
    }
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
    let Some(chromium) = chromium() else {
        eprintln!("skipped the browser check: no chromium (scripts/test installs Debian's)");
        return;
    };
    let dir = report.parent().unwrap();
    let (shot, profile) = (dir.join("report.png"), dir.join("profile"));
    let url = format!("file://{}", report.display());
    let dom = headless(chromium, &profile, &["--dump-dom"], &url);
    let dom = String::from_utf8_lossy(&dom.stdout);
    has_all(
        &dom,
        &[
            "Table 3 layout",
            "Table 5.1 layout",
            "Table 5.2 layout",
            "<svg",
            "<table",
        ],
        "Chromium's DOM",
    );
    let arg = format!("--screenshot={}", shot.display());
    headless(
        chromium,
        &profile,
        &[&arg, "--window-size=1280,2400", "--hide-scrollbars"],
        &url,
    );
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
