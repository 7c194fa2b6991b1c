//! Hostile inputs, sizes and streams: every count, size, rate and duration is bounded before
//! anything is allocated or written (an error naming the setting and its limit, never an abort,
//! a hang or gigabytes on disk), sensor files that describe no sensor are refused when read,
//! and a standard stream that cannot be written is never a panic.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use common::{fails, fresh_dir, ok, s, vt};

/// Runs `visuotact args`, expecting exit 1 with every one of `names` in its message and
/// nothing at `out`.
fn refused(args: &[&str], names: &[&str], out: &Path) {
    let err = fails(&vt(args));
    for n in names {
        assert!(err.contains(n), "{args:?}: {n:?} not in {err}");
    }
    assert!(!out.exists(), "{args:?} left {}", out.display());
}

/// The issue's aborts and hangs: `simulate --touches 1e12` (abort), a cone press of 1e300 s
/// (407 MB written before a timeout), a 1e12 Hz force sensor, `--references 1e12`, `pattern
/// --touches 1e8`, a 100 000² camera, a blur of a million pixels or a negative one, a million
/// rows of markers, `run --sim-frames 2e7`, `train --ensemble 1e11` (abort after the memory
/// check).
#[test]
fn simulated_counts_sizes_and_rates_are_bounded_before_anything_is_written() {
    let d = fresh_dir("hostile-sizes");
    let out = d.join("out");
    let o = s(&out);
    let sim = |extra: &[&'static str]| [&["simulate", "-o", o][..], extra].concat();
    let iats = ["--sensor", "iats", "--protocol", "random", "--touches", "2"];
    let cone = ["--sensor", "cone", "--protocol", "press"];
    refused(
        &sim(&[
            "--sensor",
            "iats",
            "--protocol",
            "random",
            "--touches",
            "1000000000000",
        ]),
        &["touches", "1000000"],
        &out,
    );
    refused(
        &sim(&[&iats[..], &["--references", "1000000000000"]].concat()),
        &["references", "10000"],
        &out,
    );
    refused(
        &sim(&[&cone[..], &["--duration-s", "1e300"]].concat()),
        &["duration_s × fps", "1000000"],
        &out,
    );
    refused(
        &sim(&[&cone[..], &["--force-rate-hz", "1e12"]].concat()),
        &["force sample rate", "100000 Hz"],
        &out,
    );
    // 2.8 hours of a 1 kHz stream are kept in memory: a longer press is refused.
    refused(
        &sim(&[&cone[..], &["--duration-s", "20000", "--fps", "1"]].concat()),
        &["force_rate_hz", "10000000 are simulated"],
        &out,
    );
    for (name, settings, says) in [
        (
            "camera",
            r#"{"camera":{"width":100000,"height":100000}}"#,
            "4096 px a side",
        ),
        ("blur", r#"{"blur_px":1e6}"#, "blur_px must be in 0..25"),
        ("negative-blur", r#"{"blur_px":-3}"#, "got -3"),
        ("rows", r#"{"rows":1000000}"#, "at most 200 × 200 markers"),
    ] {
        let config = d.join(format!("{name}.json"));
        std::fs::write(&config, settings).unwrap();
        refused(
            &[&["simulate", "-o", o][..], &iats, &["--config", s(&config)]].concat(),
            &[says],
            &out,
        );
    }
    refused(
        &["pattern", "--touches", "100000000", "-o", o],
        &["touches", "100000"],
        &out,
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// The same for recording, live runs and training.
#[test]
fn recording_live_and_training_counts_are_bounded_first() {
    let d = fresh_dir("hostile-sizes-live");
    let out = d.join("out");
    let o = s(&out);
    refused(
        &[
            "record",
            "--source",
            "sim:iats",
            "--references",
            "1000000000000",
            "-o",
            o,
        ],
        &["references", "10000"],
        &out,
    );
    refused(
        &[
            "run",
            "--source",
            "sim:iats",
            "--sensor",
            "none.json",
            "--sim-frames",
            "20000000",
        ],
        &["sim_frames", "1000000"],
        &out,
    );
    let (session, _, features) = common::iats_features(&d, "20", "1");
    let model = d.join("m.json");
    refused(
        &[
            "train",
            "--features",
            s(&features),
            "--labels",
            s(&session.join("labels.csv")),
            "--targets",
            "x_mm",
            "--ensemble",
            "100000000000",
            "-o",
            s(&model),
        ],
        &["ensemble of 100000000000", "at most 1000"],
        &model,
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// A force table whose clock jumps to 1e9 s (an abort allocating 8 TB for the uniform grid)
/// is refused, naming the jump.
#[test]
fn a_force_table_whose_clock_jumps_is_refused_naming_the_jump() {
    let d = fresh_dir("hostile-clock-jump");
    let mut text = String::from("timestamp_s,fx_n,fy_n,fz_n\n");
    for i in 0..1000 {
        let t = if i < 500 { 0.0 } else { 1e9 } + i as f64 * 0.001;
        text.push_str(&format!("{t},0,0,{}\n", i % 7));
    }
    let force = d.join("force.csv");
    std::fs::write(&force, &text).unwrap();
    let out = d.join("clean.csv");
    refused(
        &["filter", s(&force), "-o", s(&out)],
        &[
            "force.csv",
            "jump from 0.499 s to 1000000000.5 s",
            "sample 500",
        ],
        &out,
    );
    assert_eq!(std::fs::read_to_string(&force).unwrap(), text);
    std::fs::remove_dir_all(&d).unwrap();
}

/// A sensor file's name, an edit that spoils it and what the refusal says.
type SensorEdit = (&'static str, fn(&mut serde_json::Value), &'static str);

/// Sensor files that describe no sensor: two markers with one id, a neighbour that is not
/// there, a 0 × 0 region of interest, a zero tracking gate, more markers than any sensor
/// (10⁶ markers hung `extract`).
#[test]
fn sensor_files_that_describe_no_sensor_are_refused_when_read() {
    let d = fresh_dir("hostile-sensor-files");
    let (session, sensor, _) = common::iats_features(&d, "2", "1");
    let text = std::fs::read_to_string(&sensor).unwrap();
    let base: serde_json::Value = serde_json::from_str(&text).unwrap();
    let edits: [SensorEdit; 6] = [
        (
            "scale",
            |v| v["scale"] = serde_json::json!({"mm_per_px": -0.1, "pitch_mm": 2.5}),
            "scale: mm_per_px -0.1 and pitch_mm 2.5 must be positive",
        ),
        (
            "twice",
            |v| v["markers"][1]["id"] = serde_json::json!(0),
            "marker id 0 is listed twice",
        ),
        (
            "neighbour",
            |v| v["markers"][0]["neighbours"] = serde_json::json!([5000]),
            "names neighbour 5000",
        ),
        (
            "roi",
            |v| {
                v["detector"]["preprocess"]["roi"] =
                    serde_json::json!({"x": 10, "y": 10, "width": 0, "height": 0})
            },
            "region of interest of 0 × 0 px",
        ),
        (
            "gate",
            |v| v["track"]["gate_spacings"] = serde_json::json!(0),
            "gate_spacings must be in (0, 100]",
        ),
        (
            "many",
            |v| {
                let m = v["markers"][0].clone();
                let many: Vec<serde_json::Value> = (0..100_001)
                    .map(|k| {
                        let mut m = m.clone();
                        m["id"] = serde_json::json!(k);
                        m["neighbours"] = serde_json::json!([]);
                        m
                    })
                    .collect();
                v["markers"] = serde_json::Value::Array(many);
            },
            "100001 markers: over the limit of 100000",
        ),
    ];
    for (name, edit, says) in edits {
        let mut v = base.clone();
        edit(&mut v);
        let bad = d.join(format!("{name}.json"));
        std::fs::write(&bad, v.to_string()).unwrap();
        let out = d.join(format!("{name}.csv"));
        refused(
            &[
                "extract",
                "--sensor",
                s(&bad),
                s(&session.join("frames")),
                "-o",
                s(&out),
            ],
            &[&format!("{name}.json"), says],
            &out,
        );
    }
    std::fs::remove_dir_all(&d).unwrap();
}

/// `run --sim-frames` longer than what is rendered up front streams the rest: every frame is
/// estimated, none dropped.
#[test]
fn a_long_simulated_loop_is_rendered_as_it_plays() {
    let d = fresh_dir("hostile-sim-loop");
    let (_, sensor, _) = common::iats_features(&d, "2", "1");
    let err = ok(&vt(&[
        "run",
        "--source",
        "sim:iats",
        "--sensor",
        s(&sensor),
        "--sim-frames",
        "300",
        "--max-frames",
        "300",
        "--unpaced",
        "--quiet",
    ]));
    assert!(err.contains("300 frames captured, 300 estimated"), "{err}");
    std::fs::remove_dir_all(&d).unwrap();
}

/// `visuotact args` with stdout and stderr sent to `/dev/full` (every write: ENOSPC).
#[cfg(target_os = "linux")]
fn vt_into_full_streams(args: &[&str], stdout_full: bool) -> std::process::Output {
    let full = || {
        std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap()
    };
    let mut c = Command::new(env!("CARGO_BIN_EXE_visuotact"));
    c.args(args).stderr(Stdio::from(full()));
    if stdout_full {
        c.stdout(Stdio::from(full()));
    } else {
        c.stdout(Stdio::piped());
    }
    c.output().expect("run visuotact")
}

/// A full disk under stderr (exit 101: `eprintln!` panics) no longer ends a run: the session
/// is written whole. Standard output that cannot be written is an error (exit 1), not a panic
/// and not a silent success.
#[cfg(target_os = "linux")]
#[test]
fn a_stream_that_cannot_be_written_is_never_a_panic() {
    let d = fresh_dir("hostile-full-streams");
    let session = d.join("session");
    let args = [
        "simulate",
        "--sensor",
        "iats",
        "--protocol",
        "random",
        "--touches",
        "2",
        "-o",
        s(&session),
    ];
    let o = vt_into_full_streams(&args, false);
    assert_eq!(o.status.code(), Some(0));
    let sensor = d.join("sensor.json");
    let o = vt_into_full_streams(
        &["calibrate", s(&session.join("reference")), "-o", s(&sensor)],
        true,
    );
    assert_eq!(o.status.code(), Some(0));
    assert!(sensor.exists());
    let o = vt_into_full_streams(
        &["check-tracking", "--sensor", "iats", "--touches", "2"],
        true,
    );
    assert_eq!(o.status.code(), Some(1), "stdout into a full disk");
    std::fs::remove_dir_all(&d).unwrap();
}

/// What used to pass in silence: `record --sensor` over frames the sensor cannot process
/// (exit 0, no feature row), `dataset --latency-s nan`, a dangling link named like a frame
/// (left out without a word).
#[test]
fn what_was_accepted_in_silence_is_said() {
    let d = fresh_dir("hostile-silent");
    let (session, sensor, _) = common::iats_features(&d, "2", "1");
    let small = d.join("small");
    ok(&vt(&[
        "simulate",
        "--sensor",
        "tactip-small",
        "--protocol",
        "random",
        "--touches",
        "2",
        "-o",
        s(&small),
    ]));
    let rec = d.join("rec");
    let err = fails(&vt(&[
        "record",
        "--source",
        s(&small.join("frames")),
        "--sensor",
        s(&sensor),
        "-o",
        s(&rec),
    ]));
    assert!(
        err.contains("expected 640×480") && err.contains("processed none of the 2 frames"),
        "{err}"
    );
    let described = std::fs::read_to_string(rec.join("session.json")).unwrap();
    assert!(described.contains("\"complete\": false"), "{described}");
    let out = d.join("ds");
    refused(
        &[
            "dataset",
            s(&session),
            "--sensor",
            s(&sensor),
            "--latency-s",
            "nan",
            "-o",
            s(&out),
        ],
        &["latency_s must be within ±10 s"],
        &out,
    );
    let frames = d.join("frames");
    std::fs::create_dir_all(&frames).unwrap();
    for k in 0..2 {
        let name = format!("frame_{k:06}.png");
        std::fs::copy(session.join("frames").join(&name), frames.join(&name)).unwrap();
    }
    #[cfg(unix)]
    std::os::unix::fs::symlink("/nonexistent/x.png", frames.join("frame_000002.png")).unwrap();
    #[cfg(unix)]
    {
        let err = ok(&vt(&[
            "extract",
            "--sensor",
            s(&sensor),
            s(&frames),
            "-o",
            s(&d.join("f2.csv")),
        ]));
        assert!(
            err.contains("frame_000002.png") && err.contains("skipped 1"),
            "{err}"
        );
    }
    std::fs::remove_dir_all(&d).unwrap();
}

/// A simulated IATS session of two touches under `d` and a recording of its two frames
/// (`d/rec`, no model): (the simulated session, the recording).
fn recorded_session(d: &Path) -> (PathBuf, PathBuf) {
    let (session, _, _) = common::iats_features(d, "2", "1");
    let rec = d.join("rec");
    record_two_frames(&session, &rec, &[]);
    (session, rec)
}

/// Records the first two frames of the simulated `session` into `rec`, with `extra` options.
fn record_two_frames(session: &Path, rec: &Path, extra: &[&str]) {
    let frames = session.join("frames");
    let mut args = vec![
        "record",
        "--source",
        s(&frames),
        "--max-frames",
        "2",
        "-o",
        s(rec),
    ];
    args.extend_from_slice(extra);
    ok(&vt(&args));
}

/// Exports say when a session's recording did not complete, and refuse a `session.json` that
/// does not read (was: exported without a word, the description's fields silently ignored).
#[test]
fn exports_say_a_session_is_incomplete_and_refuse_an_unreadable_description() {
    let d = fresh_dir("hostile-export-incomplete");
    let (_, rec) = recorded_session(&d);
    let described = rec.join("session.json");
    let text = std::fs::read_to_string(&described).unwrap();
    std::fs::write(
        &described,
        text.replace("\"complete\": true", "\"complete\": false"),
    )
    .unwrap();
    let bag = d.join("a.mcap");
    let err = ok(&vt(&["export", "mcap", s(&rec), "-o", s(&bag)]));
    assert!(
        err.contains("did not complete (2 frames recorded)"),
        "{err}"
    );
    std::fs::write(&described, "{\"fps\": ").unwrap();
    let bag = d.join("b.mcap");
    refused(
        &["export", "mcap", s(&rec), "-o", s(&bag)],
        &["session.json: not a session description"],
        &bag,
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// A link left under an export's temporary name (`OUT.mcap.part~`, the folder bag's
/// `OUT.part~`) to a file or to nowhere is never followed: the bag is refused, naming the
/// unfinished name, and nothing is written where the link points (was: a dangling link's
/// target created). A LeRobot data set is built under a random name of its own, so a leftover
/// link under its old temporary name is left alone and the export lands (was: followed).
#[test]
fn links_under_an_exports_temporary_name_are_never_followed() {
    let d = fresh_dir("hostile-part-links");
    let (session, rec) = recorded_session(&d);
    let labels = session.join("labels.csv");
    let before = std::fs::read(&labels).unwrap();
    let nowhere = d.join("nowhere");
    let link = |out: &Path, to: &Path| {
        let mut part = out.as_os_str().to_owned();
        part.push(".part~");
        std::os::unix::fs::symlink(to, &part).unwrap();
    };
    for (out, to) in [
        (d.join("a.mcap"), &labels),
        (d.join("b.mcap"), &nowhere),
        (d.join("c"), &nowhere),
    ] {
        link(&out, to);
        refused(
            &["export", "mcap", s(&rec), "-o", s(&out)],
            &["unfinished bag"],
            &out,
        );
    }
    let set = d.join("set");
    link(&set, &nowhere);
    ok(&vt(&[
        "export",
        "lerobot",
        s(&rec),
        "-o",
        s(&set),
        "--no-video",
    ]));
    assert!(set.join("meta/info.json").exists());
    assert_eq!(std::fs::read(&labels).unwrap(), before);
    assert!(!nowhere.exists());
    std::fs::remove_dir_all(&d).unwrap();
}

/// A session whose `force.csv` was stamped on the force sensor's own clock (from 1 000 s, as
/// a real F/T box's) with no `recv_s` to put it on the recording's: no sample meets a frame,
/// so every export refuses, naming the file and why, and writes nothing (was: wrenches
/// 1 000 s after the frames in MCAP and Rerun, `observation.force` NaN in every LeRobot frame,
/// exit 0).
#[test]
fn exports_refuse_force_that_meets_no_frame() {
    let d = fresh_dir("hostile-export-clock");
    let (_, rec) = recorded_session(&d);
    let rows: String = (0..50)
        .map(|k| format!("{},0.1,0.2,{}\n", 1000.0 + 0.01 * f64::from(k), 1.0))
        .collect();
    std::fs::write(
        rec.join("force.csv"),
        format!("timestamp_s,fx_n,fy_n,fz_n\n{rows}"),
    )
    .unwrap();
    for (format, out) in [
        ("mcap", d.join("a.mcap")),
        ("rerun", d.join("a.rrd")),
        ("lerobot", d.join("a-lerobot")),
    ] {
        refused(
            &["export", format, s(&rec), "-o", s(&out)],
            &["force.csv", "no force sample meets a frame", "recv_s"],
            &out,
        );
    }
    std::fs::remove_dir_all(&d).unwrap();
}

/// Exports find the sensor in the model a session was recorded with (`record --model` alone:
/// was "no sensor file", no marker cloud), and a session is a closed world: a `frames.csv` row
/// naming a file outside it (`../../secret.png`) is refused by every export, naming the row,
/// with nothing written (was: the file embedded into MCAP, LeRobot and Rerun).
#[test]
fn exports_take_the_models_sensor_and_read_nothing_outside_the_session() {
    let d = fresh_dir("hostile-export-closed");
    let (session, sensor, features) = common::iats_features(&d, "40", "1");
    let model = d.join("m.json");
    ok(&vt(&[
        "train",
        "--features",
        s(&features),
        "--labels",
        s(&session.join("labels.csv")),
        "--targets",
        "x_mm,y_mm,depth_mm",
        "--hidden",
        "4",
        "--ensemble",
        "1",
        "--drop-incomplete",
        "--sensor",
        s(&sensor),
        "-o",
        s(&model),
        "--quiet",
    ]));
    let rec = d.join("rec");
    ok(&vt(&[
        "record",
        "--source",
        s(&session.join("frames")),
        "--model",
        s(&model),
        "--max-frames",
        "3",
        "-o",
        s(&rec),
    ]));
    let err = ok(&vt(&[
        "export",
        "mcap",
        s(&rec),
        "-o",
        s(&d.join("a.mcap")),
    ]));
    assert!(!err.contains("no marker cloud"), "{err}");
    std::fs::write(d.join("secret.png"), b"secret").unwrap();
    let index = rec.join("frames.csv");
    let text = std::fs::read_to_string(&index).unwrap();
    std::fs::write(&index, format!("{text}../../secret.png,9,9.0,touch\n")).unwrap();
    for (format, out) in [
        ("mcap", d.join("b.mcap")),
        ("rerun", d.join("b.rrd")),
        ("lerobot", d.join("b-lerobot")),
    ] {
        refused(
            &["export", format, s(&rec), "-o", s(&out)],
            &["frames.csv", "../../secret.png", "plain file name"],
            &out,
        );
    }
    std::fs::remove_dir_all(&d).unwrap();
}

/// `--ros-network` on an address this machine does not have (TEST-NET-1, never assigned) or on
/// the unspecified address published to nobody in silence; now refused before the run.
#[test]
fn ros_on_an_address_the_machine_lacks_is_refused() {
    let d = fresh_dir("hostile-ros-network");
    let (_, sensor, _) = common::iats_features(&d, "2", "1");
    for (addr, says) in [
        (
            "192.0.2.1",
            "no network interface of this machine has that address",
        ),
        ("0.0.0.0", "the unspecified address"),
    ] {
        let err = fails(&vt(&[
            "run",
            "--source",
            "sim:iats",
            "--sensor",
            s(&sensor),
            "--ros2",
            "--ros-network",
            addr,
            "--max-frames",
            "3",
            "--unpaced",
            "--quiet",
        ]));
        assert!(err.contains(addr) && err.contains(says), "{err}");
    }
    std::fs::remove_dir_all(&d).unwrap();
}

/// Appends an unfinished row (no line end: a writer killed mid-row) to the table at `p`.
fn cut_mid_row(p: &Path, row: &str) {
    let text = std::fs::read_to_string(p).unwrap();
    std::fs::write(p, format!("{text}{row}")).unwrap();
}

/// A table whose last line a writer was killed in the middle of is read to its last whole
/// row, and every reader says so, naming the file: `predict` (features), `train` (labels),
/// `eval` (predictions), `dataset` and the exports (a session's frames.csv). Was: the row
/// dropped in silence by all but `filter` and `dataset`'s force record.
#[test]
fn an_unfinished_last_line_is_left_out_and_said_by_every_reader() {
    let d = fresh_dir("hostile-torn-rows");
    let (_, rec) = recorded_session(&d.join("rec"));
    let (session, _, features) = common::iats_features(&d, "30", "1");
    let labels = session.join("labels.csv");
    let said = |err: &str, name: &str| {
        assert!(
            err.contains(&format!(
                "{name}: an unfinished last line (no line end) was left out"
            )),
            "{name} not said in {err}"
        );
    };
    cut_mid_row(&labels, "frame_999999.png,1.0");
    let model = d.join("m.json");
    let err = ok(&common::train(&features, &labels, "x_mm", &model, &[]));
    said(&err, s(&labels));
    cut_mid_row(&features, "frame_999999.png,0.0,1");
    let pred = d.join("p.csv");
    let err = ok(&vt(&[
        "predict",
        "--model",
        s(&model),
        "--features",
        s(&features),
        "-o",
        s(&pred),
    ]));
    said(&err, s(&features));
    assert!(err.contains("30 estimates"), "{err}");
    cut_mid_row(&pred, "frame_999999.png,1");
    let err = ok(&vt(&[
        "eval",
        "--predictions",
        s(&pred),
        "--labels",
        s(&labels),
    ]));
    said(&err, s(&pred));
    said(&err, s(&labels));
    cut_mid_row(&rec.join("frames.csv"), "frame_000002.png,2,0.");
    let bag = d.join("a.mcap");
    let err = ok(&vt(&["export", "mcap", s(&rec), "-o", s(&bag)]));
    said(&err, s(&rec.join("frames.csv")));
    std::fs::remove_dir_all(&d).unwrap();
}

/// An export says which images it could not write: a session recorded without
/// `--save-frames` has none, and a frame listed in frames.csv but gone from `frames/` is
/// counted (was: "wrote a.mcap (2 frames, 1 messages)" without a word). Both exports say it.
#[test]
fn exports_say_which_frames_have_no_image() {
    let d = fresh_dir("hostile-export-images");
    let (session, rec) = recorded_session(&d);
    let bag = d.join("a.mcap");
    let err = ok(&vt(&["export", "mcap", s(&rec), "-o", s(&bag)]));
    assert!(
        err.contains("no frames/ (recorded without --save-frames): no images"),
        "{err}"
    );
    let saved = d.join("saved");
    record_two_frames(&session, &saved, &["--save-frames"]);
    std::fs::remove_file(saved.join("frames/frame_000001.png")).unwrap();
    for (format, out) in [("mcap", "b.mcap"), ("rerun", "b.rrd")] {
        let err = ok(&vt(&["export", format, s(&saved), "-o", s(&d.join(out))]));
        assert!(
            err.contains(
                "1 of the 2 frames listed in frames.csv are not in frames/: written without their image"
            ),
            "{format}: {err}"
        );
    }
    std::fs::remove_dir_all(&d).unwrap();
}
