//! The README's commands on real sensors, run as written (the file names swapped for the
//! real frames in `../shared/reference/real`; skipped where that folder is absent). Each test
//! first checks the README still says exactly what it runs.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn readme() -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../README.md"))
        .expect("README.md")
}

fn real(rel: &str) -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/reference/real")
        .join(rel);
    if p.exists() {
        return Some(p);
    }
    eprintln!("skipping: {} absent", p.display());
    None
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("visuotact-readme-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs a README command line (`visuotact …`, words split on spaces) in `dir` with `swap`
/// replacing file names.
fn run(line: &str, dir: &Path, swap: &[(&str, &Path)]) -> Output {
    let words: Vec<String> = line
        .split_whitespace()
        .skip(1)
        .map(|w| {
            swap.iter()
                .find(|(name, _)| *name == w)
                .map_or(w.to_string(), |(_, p)| p.display().to_string())
        })
        .collect();
    Command::new(env!("CARGO_BIN_EXE_visuotact"))
        .args(&words)
        .current_dir(dir)
        .output()
        .expect("run visuotact")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn the_gelsight_mini_commands_work_as_written() {
    let calibrate = "visuotact calibrate mini_example.avi --first 10 --keep-border -o gs.json";
    let extract = "visuotact extract --sensor gs.json mini_example.avi -o gs.csv";
    let text = readme();
    assert!(text.contains(calibrate) && text.contains(extract));
    let Some(video) = real("gelsight_mini/mini_example.avi") else {
        return;
    };
    let d = tmp("gelsight");
    let o = run(calibrate, &d, &[("mini_example.avi", &video)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("calibrated 80 markers (grid: 8 rows × 10 columns"),
        "{}",
        stderr(&o)
    );
    let o = run(extract, &d, &[("mini_example.avi", &video)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rows = std::fs::read_to_string(d.join("gs.csv")).unwrap();
    assert_eq!(rows.lines().count(), 1 + 219);
}

#[test]
fn the_9dtact_options_work_as_written() {
    let options = "--preset dark-markers --window 51 --offset -0.03";
    assert!(readme().contains(&format!("`{options}`")));
    let Some(grid) = real("9dtact/camera_calibration/sample.png") else {
        return;
    };
    let d = tmp("9dtact");
    let line = format!("visuotact calibrate sample.png {options} -o grid.json");
    let o = run(&line, &d, &[("sample.png", &grid)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("calibrated 63 markers (grid: 7 rows × 9 columns"),
        "{}",
        stderr(&o)
    );
    // The window also refines `auto` where it picks the adaptive preset.
    let line = "visuotact calibrate sample.png --window 51 --offset -0.03 -o auto.json";
    let o = run(line, &d, &[("sample.png", &grid)]);
    assert!(o.status.success(), "{}", stderr(&o));
}
