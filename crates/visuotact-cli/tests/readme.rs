//! The README's commands on real sensors, run as written (the file names swapped for the
//! real frames in `../shared/reference/real`; skipped where that folder is absent). Each test
//! first checks the README still says exactly what it runs.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;
use common::shared_real as real;

/// The README with shell line continuations (`\` at a line's end) joined, as a shell reads it.
fn readme() -> String {
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../README.md"))
            .expect("README.md");
    let mut joined = String::with_capacity(text.len());
    let mut rest = text.as_str();
    while let Some(at) = rest.find("\\\n") {
        joined.push_str(rest[..at].trim_end_matches(' '));
        joined.push(' ');
        rest = rest[at + 2..].trim_start_matches(' ');
    }
    joined.push_str(rest);
    joined
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

/// The TacTip data set commands on the real 127-pin set: every test frame estimated, each
/// target's mean absolute error under the naive OpenCV + scikit-learn MLP(64, 64) peer's on the
/// same split (`scripts/bench/peer_tactip127.py`, measured 0.1648 mm, 2.0715°, 0.4837 mm, 1.3798°),
/// and the pose's (y, rotation) at most half the peer's, as issue 34 asks. Shear and twist stay
/// above half the peer's (the frames' limit there, docs/benchmarks.md); the bounds on them
/// (0.81 and 0.73 of the peer's: 0.392 mm, 1.007°) hold the gain of reading the binarised pins
/// without their areas: with the areas the default measured 0.395–0.397 mm and 1.036–1.041° on
/// train seeds 1–3, without them 0.377–0.379 mm and 0.965–0.974°.
#[test]
fn the_tactip_data_set_commands_work_as_written() {
    let lines = [
        "visuotact calibrate --reference lightest:20 frames -o tip.json",
        "visuotact extract --sensor tip.json frames -o features.csv",
        "visuotact train --features features.csv --labels train_targets.csv --targets pose_2,pose_6,move_1,move_6 -o tip_model.json",
        "visuotact predict --model tip_model.json --features features.csv -o estimates.csv",
        "visuotact eval --predictions estimates.csv --labels test_targets.csv",
    ];
    let text = readme();
    for l in lines {
        assert!(text.contains(l), "README lacks {l}");
    }
    let Some(data) = real("tactip127_surface") else {
        return;
    };
    let d = tmp("tactip127");
    let (frames, train, test) = (
        data.join("frames"),
        data.join("train_targets.csv"),
        data.join("test_targets.csv"),
    );
    let swap: [(&str, &Path); 3] = [
        ("frames", &frames),
        ("train_targets.csv", &train),
        ("test_targets.csv", &test),
    ];
    for l in &lines[..4] {
        let o = run(l, &d, &swap);
        assert!(o.status.success(), "{l}: {}", stderr(&o));
    }
    let json = format!("{} --json", lines[4]);
    let o = run(&json, &d, &swap);
    assert!(o.status.success(), "{}", stderr(&o));
    let ev: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    // (target, the peer's error, the share of it to stay under)
    let peer = [
        ("pose_2", 0.1648, 0.5),
        ("pose_6", 2.0715, 0.5),
        ("move_1", 0.4837, 0.81),
        ("move_6", 1.3798, 0.73),
    ];
    for t in ev["targets"].as_array().unwrap() {
        let name = t["target"].as_str().unwrap();
        let (_, peer_mae, share) = peer.iter().find(|(n, ..)| *n == name).unwrap();
        let worst = share * peer_mae;
        assert_eq!(
            t["n"].as_u64(),
            Some(1237),
            "{name}: every test frame estimated"
        );
        let mae = t["mean_abs"].as_f64().unwrap();
        assert!(
            mae <= worst,
            "{name}: mean abs error {mae} against {share} × the peer's {peer_mae}"
        );
    }
}

/// The README's "your sensor in four commands", as written, on a simulated membrane session:
/// its rest frames, touch frames and labels under the README's names, the camera swapped for
/// the touch frames (no camera here) and the live run bounded.
#[test]
fn the_four_commands_work_as_written() {
    let text = readme();
    let block = text
        .split("## Your sensor in four commands")
        .nth(1)
        .and_then(|s| s.split("```sh").nth(1))
        .and_then(|s| s.split("```").next())
        .expect("the four commands' block");
    let lines: Vec<&str> = block
        .lines()
        .map(|l| l.split('#').next().unwrap_or("").trim())
        .filter(|l| l.starts_with("visuotact "))
        .collect();
    assert_eq!(lines.len(), 4, "{block}");
    let d = tmp("four");
    let session = d.join("session");
    let sim = run(
        "visuotact simulate --sensor iats --protocol random --touches 40 -o session",
        &d,
        &[],
    );
    assert!(sim.status.success(), "{}", stderr(&sim));
    std::fs::rename(session.join("reference"), d.join("rest_frames")).unwrap();
    std::fs::rename(session.join("frames"), d.join("touch_frames")).unwrap();
    std::fs::rename(session.join("labels.csv"), d.join("labels.csv")).unwrap();
    for line in &lines[..3] {
        let o = run(line, &d, &[]);
        assert!(o.status.success(), "{line}: {}", stderr(&o));
    }
    let live = lines[3]
        .replace("camera:/dev/video0", "touch_frames")
        .replace(
            "--serve",
            "--serve 127.0.0.1:0 --max-frames 40 --unpaced --quiet",
        );
    let o = run(&live, &d, &[]);
    assert!(o.status.success(), "{live}: {}", stderr(&o));
    assert!(
        stderr(&o).contains("40 frames captured, 40 estimated"),
        "{}",
        stderr(&o)
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// The README's install command is the one the test command runs (and then runs the binary
/// it installed), so it stays true.
#[test]
fn the_install_command_is_the_one_the_test_command_runs() {
    let install = "cargo install --path crates/visuotact-cli";
    assert!(
        readme().contains(&format!("{install}      #")),
        "README lacks {install}"
    );
    let script =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scripts/test"))
            .unwrap();
    assert!(script.contains("cargo install --path crates/visuotact-cli --locked"));
    assert!(script.contains("target/install-check/bin/visuotact --version"));
}
