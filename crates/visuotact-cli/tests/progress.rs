//! Long trainings and passes over frames as a user with a log file sees them: progress lines
//! on a standard error that is not a terminal, none with `--quiet`, and Ctrl-C stopping
//! cleanly with nothing written.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

mod common;
use common::*;

/// A table of 1 200 frames of 40 markers' features moving on their own, the field summary,
/// and a target needing three of them: large enough for the wide network and a few seconds of
/// training.
fn table(dir: &Path) -> (PathBuf, PathBuf) {
    let (features, labels) = (dir.join("f.csv"), dir.join("l.csv"));
    let mut f = String::from("frame");
    for m in 0..40 {
        f.push_str(&format!(",m{m:03}_dx_px"));
    }
    f.push_str(",field_rms_px,field_max_px,field_top_px,field_cx_px,field_cy_px,field_spread_px\n");
    let mut l = String::from("frame,y_mm\n");
    let mut state = 12345u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    };
    for k in 0..1200 {
        let v: Vec<f64> = (0..46).map(|_| next()).collect();
        let cells: Vec<String> = v.iter().map(|x| format!("{x:.5}")).collect();
        f.push_str(&format!("f{k},{}\n", cells.join(",")));
        l.push_str(&format!("f{k},{:.5}\n", (2.0 * v[0]).sin() + v[1] * v[2]));
    }
    std::fs::write(&features, f).unwrap();
    std::fs::write(&labels, l).unwrap();
    (features, labels)
}

fn train_args<'a>(f: &'a Path, l: &'a Path, model: &'a Path) -> Vec<&'a str> {
    vec![
        "train",
        "--features",
        s(f),
        "--labels",
        s(l),
        "--targets",
        "y_mm",
        "-o",
        s(model),
        "--max-epochs",
        "40",
        "--ensemble",
        "2",
    ]
}

#[test]
fn a_piped_training_prints_progress_and_quiet_silences_it() {
    let d = fresh_dir("progress");
    let (f, l) = table(&d);
    let model = d.join("m.json");
    let err = ok(&vt(&train_args(&f, &l, &model)));
    assert!(err.contains("choosing the inputs: started"), "{err}");
    assert!(err.contains("training: started"), "{err}");
    assert!(model.is_file());
    let quiet = d.join("q.json");
    let mut args = train_args(&f, &l, &quiet);
    args.push("--quiet");
    let err = ok(&vt(&args));
    assert!(
        !err.contains("started") && !err.contains(": network "),
        "{err}"
    );
    assert!(err.contains("wrote"), "{err}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn ctrl_c_stops_a_training_and_writes_no_model() {
    let d = fresh_dir("interrupt");
    let (f, l) = table(&d);
    let model = d.join("m.json");
    let (code, rest) = interrupt_after_start(&train_args(&f, &l, &model), "choosing the inputs");
    assert_eq!(code, Some(1), "{rest:?}");
    assert!(
        rest.iter()
            .any(|l| l.contains("interrupted (Ctrl-C): no model written")),
        "{rest:?}"
    );
    assert!(!model.exists());
    let _ = std::fs::remove_dir_all(&d);
}

/// Sends Ctrl-C to `args` once its stage `stage` has started; returns the exit code and the
/// lines printed after.
fn interrupt_after_start(args: &[&str], stage: &str) -> (Option<i32>, Vec<String>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_visuotact"))
        .args(args)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
    for line in lines.by_ref() {
        if line.unwrap() == format!("{stage}: started") {
            break;
        }
    }
    let pid = child.id().to_string();
    assert!(Command::new("kill")
        .args(["-INT", &pid])
        .status()
        .unwrap()
        .success());
    let rest: Vec<String> = lines.map_while(Result::ok).collect();
    (child.wait().unwrap().code(), rest)
}

/// A simulated session's sensor file and a folder `many/` of one of its frames linked under
/// `n` names.
fn linked_frames(d: &Path, n: usize) -> (PathBuf, PathBuf) {
    let (session, sensor, _) = iats_features(d, "2", "3");
    let one = std::fs::read_dir(session.join("frames"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "png"))
        .unwrap();
    let frames = d.join("many");
    std::fs::create_dir_all(&frames).unwrap();
    for k in 0..n {
        std::fs::hard_link(&one, frames.join(format!("f{k:05}.png"))).unwrap();
    }
    (sensor, frames)
}

/// `extract -o - | head`: the reader leaving after the first rows ends the run with exit 0 and
/// no error (a closed pipe is not a failure, docs/failure.md).
#[test]
fn a_reader_closing_standard_output_is_not_an_error() {
    let d = fresh_dir("closed-pipe");
    let (sensor, frames) = linked_frames(&d, 400);
    let mut child = Command::new(env!("CARGO_BIN_EXE_visuotact"))
        .args([
            "extract",
            "--sensor",
            s(&sensor),
            s(&frames),
            "-o",
            "-",
            "--quiet",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(first.starts_with("frame,"), "{first}");
    // The reader is gone: the rows still to come have nowhere to go.
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(!err.contains("error"), "{err}");
}

/// An extraction over 3 000 frames (one simulated frame linked under 3 000 names): it says
/// it started, stops on Ctrl-C with exit 1, and leaves neither the table nor a temporary; so
/// does the ranking of the same frames for a reference.
#[test]
fn ctrl_c_stops_an_extraction_or_a_ranking_and_writes_nothing() {
    let d = fresh_dir("interrupt-extract");
    let (sensor, frames) = linked_frames(&d, 3000);
    let out = d.join("many.csv");
    let args = ["extract", "--sensor", s(&sensor), s(&frames), "-o", s(&out)];
    let (code, rest) = interrupt_after_start(&args, "extract");
    assert_eq!(code, Some(1), "{rest:?}");
    assert!(
        rest.iter()
            .any(|l| l.contains("interrupted (Ctrl-C) after") && l.contains("not written")),
        "{rest:?}"
    );
    // No temporary left behind either (`.many.csv.XXXXXX.part~`).
    let no_part = || {
        std::fs::read_dir(&d)
            .unwrap()
            .all(|e| !e.unwrap().file_name().to_string_lossy().ends_with(".part~"))
    };
    assert!(!out.exists() && no_part());
    // Uninterrupted and quiet: the table, no progress line.
    let mut quiet = args.to_vec();
    quiet.push("--quiet");
    let err = ok(&vt(&quiet));
    assert!(
        !err.contains("started") && err.contains("extracted 3000 frames"),
        "{err}"
    );
    assert!(out.is_file() && no_part());
    // Ranking the same frames for a reference (`--reference lightest:N`) stops likewise.
    let ranked = d.join("ranked.json");
    let args = [
        "calibrate",
        "--reference",
        "lightest:5",
        s(&frames),
        "-o",
        s(&ranked),
    ];
    let (code, rest) = interrupt_after_start(&args, "ranking the frames by deformation");
    assert_eq!(code, Some(1), "{rest:?}");
    assert!(
        rest.iter()
            .any(|l| l.contains("interrupted (Ctrl-C) after ranking")),
        "{rest:?}"
    );
    assert!(!ranked.exists());
    let _ = std::fs::remove_dir_all(&d);
}
