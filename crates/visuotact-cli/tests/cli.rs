//! The command line end to end: the README's main job, and bad input that must give a clear
//! message naming the frame (never a panic), with `extract` carrying on where it can.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;

fn vt(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_visuotact"))
        .args(args)
        .output()
        .expect("run visuotact")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("visuotact-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `extract --sensor SENSOR FRAMES -o OUT`, plus any extra arguments.
fn extract(sensor: &Path, frames: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["extract", "--sensor", s(sensor), s(frames), "-o", s(out)];
    args.extend_from_slice(extra);
    vt(&args)
}

/// Renders test frames and calibrates on them; returns (folder, sensor file).
fn setup(name: &str, touches: usize) -> (PathBuf, PathBuf) {
    let d = tmp(name);
    let o = vt(&[
        "pattern",
        "-o",
        s(&d),
        "--touches",
        &touches.to_string(),
        "--seed",
        "3",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let sensor = d.join("sensor.json");
    let o = vt(&["calibrate", s(&d.join("rest")), "-o", s(&sensor)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("calibrated 117 markers (grid: 9 rows × 13 columns"),
        "{}",
        stderr(&o)
    );
    (d, sensor)
}

#[test]
fn readme_main_job_pattern_calibrate_extract() {
    let (d, sensor) = setup("main", 6);
    let out = d.join("features.csv");
    let o = extract(&sensor, &d.join("touch"), &out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&out).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    // frame, 6 leading columns, 117 markers × 3, the 6 field-summary columns, flags.
    assert_eq!(header.len(), 1 + 6 + 117 * 3 + 6 + 1);
    assert_eq!(&header[..3], &["frame", "timestamp_s", "n_found"]);
    assert_eq!(header[7], "m000_dx_px");
    assert_eq!(header[header.len() - 8], "m116_darea_px");
    assert_eq!(header[header.len() - 7], "field_rms_px");
    assert_eq!(header[header.len() - 2], "field_spread_px");
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 6);
    for (i, r) in rows.iter().enumerate() {
        assert_eq!(r[0], format!("touch_{i:04}.png"));
        assert_eq!(r[2], "117", "all markers found");
    }
    // JSON lines carry the same numbers.
    let outj = d.join("features.jsonl");
    let o = extract(&sensor, &d.join("touch"), &outj, &["--format", "jsonl"]);
    assert!(o.status.success());
    let first: serde_json::Value = serde_json::from_str(
        std::fs::read_to_string(&outj)
            .unwrap()
            .lines()
            .next()
            .unwrap(),
    )
    .unwrap();
    let dx: f64 = rows[0][7].parse().unwrap();
    assert_eq!(first["m000_dx_px"].as_f64().unwrap(), dx);
}

#[test]
fn bad_frames_are_named_and_skipped() {
    let (d, sensor) = setup("bad", 3);
    let frames = d.join("touch");
    // Garbage, a truncated PNG, and a frame of another size.
    std::fs::write(frames.join("touch_0100.png"), b"not an image at all").unwrap();
    let good = std::fs::read(frames.join("touch_0000.png")).unwrap();
    std::fs::write(frames.join("touch_0101.png"), &good[..good.len() / 3]).unwrap();
    let small = image::RgbImage::new(320, 240);
    small.save(frames.join("touch_0102.png")).unwrap();
    let out = d.join("f.csv");
    let o = extract(&sensor, &frames, &out, &[]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("touch_0100.png: cannot decode image"), "{err}");
    assert!(err.contains("touch_0101.png: cannot decode image"), "{err}");
    assert!(
        err.contains(
            "frame touch_0102.png: expected 640×480 like the reference, got 320×240; skipped"
        ),
        "{err}"
    );
    assert!(err.contains("extracted 3 frames"), "{err}");
    assert!(err.contains("skipped 3"), "{err}");
    assert_eq!(std::fs::read_to_string(&out).unwrap().lines().count(), 4);
}

#[test]
fn half_the_markers_vanishing_is_reported_without_shifting_columns() {
    let (d, sensor) = setup("half", 1);
    let path = d.join("touch/touch_0000.png");
    let mut img = image::open(&path).unwrap().into_rgb8();
    let bg = *img.get_pixel(2, 2);
    for y in 0..300 {
        for x in 0..640 {
            img.put_pixel(x, y, bg);
        }
    }
    img.save(&path).unwrap();
    let out = d.join("f.csv");
    let o = extract(&sensor, &d.join("touch"), &out, &[]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("markers not found (") && err.contains("half or more: is the skin in view?"),
        "{err}"
    );
    let text = std::fs::read_to_string(&out).unwrap();
    let row: Vec<&str> = text.lines().nth(1).unwrap().split(',').collect();
    // Top rows are gone: their cells are empty; bottom-row markers keep their own columns.
    assert_eq!(row[7], "", "m000 missing");
    let last = 7 + 116 * 3;
    assert!(!row[last].is_empty() && row[last].parse::<f64>().unwrap().abs() < 20.0);
    assert!(row.last().unwrap().contains("m000:lost"));
}

#[test]
fn unusable_inputs_fail_with_the_reason() {
    let d = tmp("unusable");
    let empty = d.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let o = vt(&["calibrate", s(&empty), "-o", s(&d.join("x.json"))]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("folder has no image files"),
        "{}",
        stderr(&o)
    );

    let bad_video = d.join("broken.avi");
    std::fs::write(&bad_video, b"RIFF....AVI garbage").unwrap();
    let o = vt(&["calibrate", s(&bad_video), "-o", s(&d.join("x.json"))]);
    assert_eq!(o.status.code(), Some(1));
    let err = stderr(&o);
    assert!(
        err.contains("broken.avi")
            && (err.contains("ffmpeg cannot open it") || err.contains("not installed")),
        "{err}"
    );

    let o = vt(&[
        "calibrate",
        s(&d.join("missing.png")),
        "-o",
        s(&d.join("x.json")),
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("missing.png"), "{}", stderr(&o));

    let o = extract(&d.join("nope.json"), &empty, Path::new("-"), &[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("nope.json: cannot read sensor file"),
        "{}",
        stderr(&o)
    );

    std::fs::write(d.join("bad.json"), "{\"format\": 3}").unwrap();
    let o = extract(&d.join("bad.json"), &empty, Path::new("-"), &[]);
    assert!(
        stderr(&o).contains("bad.json: not a sensor file"),
        "{}",
        stderr(&o)
    );

    let o = vt(&["calibrate", s(&empty), "-o", "x.json", "--threshold", "1.7"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("fixed threshold must be in 0..1"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn video_input_is_decoded_by_ffmpeg() {
    let Some(video) = common::shared_real("gelsight_mini/mini_example.avi") else {
        return;
    };
    let d = tmp("video");
    let sensor = d.join("gs.json");
    let o = vt(&[
        "calibrate",
        s(&video),
        "--first",
        "10",
        "--preset",
        "dark-markers",
        "--keep-border",
        "-o",
        s(&sensor),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("calibrated 80 markers (grid: 8 rows × 10 columns"),
        "{}",
        stderr(&o)
    );
    let out = d.join("gs.csv");
    let o = extract(&sensor, &video, &out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<&str> = text.lines().skip(1).collect();
    assert_eq!(rows.len(), 219);
    assert!(rows[0].starts_with("0,0,80,80,"), "{}", &rows[0][..40]);
    assert!(rows[218].starts_with("218,8.72,"), "{}", &rows[218][..40]);
}
