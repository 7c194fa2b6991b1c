//! Hostile inputs (issue 15): every case exits with a reported error (code 1, never a panic's
//! 101), names what is wrong, creates nothing it should not and changes no input.

mod common;

use common::{fails, fresh_dir, ok, s, vt};

/// `run`'s and `record`'s durations, rates and counts are checked before anything starts:
/// negative, NaN and astronomically large values were panics in `Duration::from_secs_f64`.
#[test]
fn durations_rates_and_counts_are_checked_first() {
    let d = fresh_dir("hostile-durations");
    for (arg, names) in [
        ("--duration-s=-1", "duration_s"),
        ("--duration-s=NaN", "duration_s"),
        ("--duration-s=1e300", "duration_s"),
        // Was an abort (a billion frames' queue reserved up front).
        ("--queue=1000000000", "at most 1000 frames"),
    ] {
        let err = fails(&vt(&[
            "run",
            "--source",
            "sim:iats",
            "--sensor",
            "none.json",
            arg,
        ]));
        // Checked before any file is read.
        assert!(err.contains(names), "{arg}: {err}");
    }
    let session = d.join("rec");
    for (flag, bad, names) in [
        ("--sync-every-s", "1e300", "sync_every_s"),
        ("--duration-s", "-1", "duration_s"),
        ("--duration-s", "NaN", "duration_s"),
        ("--fps", "0", "fps"),
        ("--fps", "1e-300", "fps"),
        ("--force-rate-hz", "inf", "force_rate_hz"),
        ("--max-frames", "0", "max_frames"),
    ] {
        let arg = format!("{flag}={bad}");
        let err = fails(&vt(&[
            "record",
            "--source",
            "sim:iats",
            "-o",
            s(&session),
            &arg,
        ]));
        assert!(err.contains(names), "{flag} {bad}: {err}");
        // Nothing was created: the corrected run is not refused as "already holds a session".
        assert!(!session.exists(), "{flag} {bad} left {}", session.display());
    }
    // Zero touches would simulate or check nothing and report success.
    for cmd in [
        &["simulate", "-o", s(&session), "--touches", "0"][..],
        &["check-tracking", "--touches", "0"][..],
    ] {
        // A usage error: exit 2, as clap's own.
        let o = vt(cmd);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(
            err.contains("--touches") && err.contains("not in 1.."),
            "{err}"
        );
        assert!(!session.exists());
    }
    // The scorecard's real half on a folder without the real sets names what it looked for.
    let err = fails(&vt(&["check-tracking", "--real", s(&d)]));
    assert!(
        err.contains("tactip127_surface") && err.contains("not found"),
        "{err}"
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// A busy force port or a bad force table is reported before the session folder exists.
#[test]
fn force_sources_are_opened_before_the_session_folder() {
    let d = fresh_dir("hostile-force");
    let busy = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let port = busy.local_addr().unwrap().port();
    let session = d.join("rec");
    let udp = format!("udp:127.0.0.1:{port}");
    let err = fails(&vt(&[
        "record",
        "--source",
        "sim:iats",
        "--force",
        &udp,
        "-o",
        s(&session),
    ]));
    assert!(err.contains(&port.to_string()), "{err}");
    assert!(!session.exists());
    let table = d.join("force.csv");
    std::fs::write(&table, "timestamp_s,fx_n\n0.0,1.0\n0.1,abc\n").unwrap();
    let csv = format!("csv:{}", table.display());
    let err = fails(&vt(&[
        "record",
        "--source",
        "sim:iats",
        "--force",
        &csv,
        "-o",
        s(&session),
    ]));
    assert!(err.contains("line 3, column `fx_n`"), "{err}");
    assert!(!session.exists());
    assert_eq!(
        std::fs::read_to_string(&table).unwrap(),
        "timestamp_s,fx_n\n0.0,1.0\n0.1,abc\n"
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// Doing nothing is not success: a source with no readable frame fails `run` and `record`.
#[test]
fn nothing_done_is_an_error() {
    let d = fresh_dir("hostile-nothing");
    let frames = d.join("frames");
    std::fs::create_dir_all(&frames).unwrap();
    std::fs::write(frames.join("a.png"), b"\x89PNG not really").unwrap();
    let err = fails(&vt(&[
        "record",
        "--source",
        s(&frames),
        "-o",
        s(&d.join("rec")),
    ]));
    assert!(err.contains("nothing recorded"), "{err}");
    assert!(
        err.contains("a.png"),
        "the unreadable frame is named: {err}"
    );
    // No empty session is left to refuse the corrected run; a zero duration is refused first.
    assert!(!d.join("rec").exists());
    // A source folder with no image at all: refused, and no session folder left either.
    let empty = d.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let err = fails(&vt(&[
        "record",
        "--source",
        s(&empty),
        "-o",
        s(&d.join("rec")),
    ]));
    assert!(err.contains("no image files"), "{err}");
    assert!(!d.join("rec").exists());
    let err = fails(&vt(&[
        "record",
        "--source",
        "sim:cone",
        "--duration-s",
        "0",
        "-o",
        s(&d.join("rec")),
    ]));
    assert!(err.contains("positive duration"), "{err}");
    assert!(!d.join("rec").exists());
    // A feature table with a header only: no estimate table, an error.
    let (features, labels, _) = literal_tables(&d);
    let model = d.join("m.json");
    ok(&vt(&[
        "train",
        "--features",
        s(&features),
        "--labels",
        s(&labels),
        "--targets",
        "x_mm",
        "-o",
        s(&model),
        "--quiet",
    ]));
    let header = d.join("header.csv");
    std::fs::write(&header, "frame,m000_dx_px,m000_dy_px\n").unwrap();
    let out = d.join("p.csv");
    let err = fails(&vt(&[
        "predict",
        "--model",
        s(&model),
        "--features",
        s(&header),
        "-o",
        s(&out),
    ]));
    assert!(err.contains("no row to estimate"), "{err}");
    assert!(!out.exists());
    std::fs::remove_dir_all(&d).unwrap();
}

/// A session whose frames.csv lists no frame: every export refuses it and writes nothing
/// (was: "wrote z.mcap (0 frames, 0 messages)", exit 0, for MCAP and Rerun).
#[test]
fn exporting_a_session_without_frames_is_an_error() {
    let d = fresh_dir("hostile-export-nothing");
    let session = d.join("session");
    std::fs::create_dir_all(session.join("frames")).unwrap();
    std::fs::write(
        session.join("frames.csv"),
        "frame,frame_index,timestamp_s,kind\n",
    )
    .unwrap();
    for (format, out) in [("mcap", "z.mcap"), ("rerun", "z.rrd"), ("lerobot", "zl")] {
        let out = d.join(out);
        let err = fails(&vt(&["export", format, s(&session), "-o", s(&out)]));
        assert!(
            err.contains("frames.csv") && err.contains("no frames"),
            "{format}: {err}"
        );
        assert!(!out.exists(), "{format} left {}", out.display());
    }
    std::fs::remove_dir_all(&d).unwrap();
}

/// Extracting frames none of which can be processed (1 × 480, not the sensor's size) is an
/// error naming the first one's reason, and no header-only table is left under the output's
/// name (was: exit 1 beside a header-only CSV).
#[test]
fn extracting_nothing_leaves_no_table() {
    let d = fresh_dir("hostile-extract-nothing");
    let thin = d.join("thin");
    std::fs::create_dir_all(&thin).unwrap();
    visuotact_io::frames::write_png(
        &thin.join("t.png"),
        &visuotact_image::RgbImage::from_fn(1, 480, |_, _| [128; 3]),
    )
    .unwrap();
    std::fs::create_dir_all(d.join("sim")).unwrap();
    let (_, sensor, _) = common::iats_features(&d.join("sim"), "2", "1");
    let table = d.join("thin.csv");
    let err = fails(&vt(&[
        "extract",
        "--sensor",
        s(&sensor),
        s(&thin),
        "-o",
        s(&table),
    ]));
    assert!(
        err.contains("no frame could be processed") && err.contains("1×480"),
        "{err}"
    );
    assert!(!table.exists());
    std::fs::remove_dir_all(&d).unwrap();
}

/// Outputs never overwrite inputs: the same file, the same folder, or a session's own file.
#[test]
fn outputs_never_overwrite_inputs() {
    let d = fresh_dir("hostile-overwrite");
    let f = d.join("f.csv");
    let text = "timestamp_s,fz_n\n0.0,1.0\n0.01,1.1\n";
    std::fs::write(&f, text).unwrap();
    let session = d.join("session");
    std::fs::create_dir_all(&session).unwrap();
    std::fs::write(session.join("frames.csv"), "frame,index,timestamp_s,kind\n").unwrap();
    std::fs::write(session.join("labels.csv"), "frame,x_mm\n").unwrap();
    let labels = session.join("labels.csv");
    let model = d.join("m.json");
    std::fs::write(&model, "{}").unwrap();
    // The same file by another spelling of its path.
    let other = d.join(".").join("f.csv");
    let cases: Vec<Vec<&str>> = vec![
        vec!["filter", s(&f), "-o", s(&other)],
        vec!["extract", "--sensor", s(&model), s(&f), "-o", s(&f)],
        vec![
            "predict",
            "--model",
            s(&model),
            "--features",
            s(&f),
            "-o",
            s(&model),
        ],
        vec!["dataset", s(&session), "-o", s(&session)],
        vec![
            "replay",
            "--model",
            s(&model),
            s(&session),
            "-o",
            s(&labels),
        ],
        vec![
            "train",
            "--features",
            s(&f),
            "--labels",
            s(&labels),
            "--targets",
            "x_mm",
            "-o",
            s(&f),
        ],
    ];
    for args in cases {
        let err = fails(&vt(&args));
        assert!(err.contains("choose another output"), "{args:?}: {err}");
    }
    assert_eq!(std::fs::read_to_string(&f).unwrap(), text);
    assert_eq!(std::fs::read_to_string(&model).unwrap(), "{}");
    assert_eq!(std::fs::read_to_string(&labels).unwrap(), "frame,x_mm\n");
    std::fs::remove_dir_all(&d).unwrap();
}

/// The same rule for files inside an input folder and for secondary outputs (`--report`,
/// `--map`, `--plot`, `--mcap`, `--summary`): nothing is written, the inputs stay as they were.
#[test]
fn outputs_never_land_in_input_folders_nor_on_secondary_inputs() {
    let d = fresh_dir("hostile-inside");
    let frames = d.join("frames");
    std::fs::create_dir_all(&frames).unwrap();
    let frame = frames.join("frame_000000.png");
    std::fs::write(&frame, b"not really a png").unwrap();
    let (p, l) = (d.join("p.csv"), d.join("l.csv"));
    std::fs::write(&p, "frame,x_mm\na,1\n").unwrap();
    std::fs::write(&l, "frame,x_mm\na,1\n").unwrap();
    let sensor = d.join("s.json");
    std::fs::write(&sensor, "{}").unwrap();
    let model = d.join("m.json");
    std::fs::write(&model, "{}").unwrap();
    let source = format!("frames:{}", frames.display());
    let eval = |opt: &'static str| -> Vec<&str> {
        vec![
            "eval",
            "--predictions",
            s(&p),
            "--labels",
            s(&l),
            opt,
            s(&l),
        ]
    };
    let cases: Vec<Vec<&str>> = vec![
        vec![
            "extract",
            "--sensor",
            s(&sensor),
            s(&frames),
            "-o",
            s(&frame),
        ],
        vec!["calibrate", s(&frames), "-o", s(&frame)],
        vec!["blobs", s(&frames), "-o", s(&frame)],
        vec!["replay", "--model", s(&model), s(&frames), "-o", s(&frame)],
        vec![
            "predict",
            "--model",
            s(&model),
            "--sensor",
            s(&sensor),
            s(&frames),
            "-o",
            s(&frame),
        ],
        eval("--report"),
        eval("--map"),
        eval("--plot"),
        vec![
            "run",
            "--model",
            s(&model),
            "--source",
            &source,
            "--summary",
            s(&frame),
        ],
        vec![
            "run",
            "--model",
            s(&model),
            "--source",
            &source,
            "--sensor",
            s(&sensor),
            "--mcap",
            s(&sensor),
        ],
    ];
    for args in cases {
        let err = fails(&vt(&args));
        assert!(err.contains("choose another output"), "{args:?}: {err}");
    }
    assert_eq!(std::fs::read(&frame).unwrap(), b"not really a png");
    assert_eq!(std::fs::read_to_string(&l).unwrap(), "frame,x_mm\na,1\n");
    assert_eq!(std::fs::read_to_string(&sensor).unwrap(), "{}");
    std::fs::remove_dir_all(&d).unwrap();
}

/// A feature table (two marker columns) and labels (`x_mm` varying, `fy_n` constant) of 30
/// frames in `d`; returns their paths and the labels' text.
fn literal_tables(d: &std::path::Path) -> (std::path::PathBuf, std::path::PathBuf, String) {
    let (features, labels) = (d.join("f.csv"), d.join("l.csv"));
    let mut f = String::from("frame,m000_dx_px,m000_dy_px\n");
    let mut l = String::from("frame,x_mm,fy_n\n");
    for k in 0..30 {
        let x = k as f64 / 10.0;
        f.push_str(&format!("f{k},{x},{}\n", (x * 1.7).sin()));
        l.push_str(&format!("f{k},{},0.5\n", 2.0 * x + 1.0));
    }
    std::fs::write(&features, &f).unwrap();
    std::fs::write(&labels, &l).unwrap();
    (features, labels, l)
}

/// A constant target trains with a warning and a model that loads; a value of 1e308 is
/// refused before training, naming its row and column, and no model is written.
#[test]
fn models_are_written_only_when_they_load() {
    let d = fresh_dir("hostile-model");
    let (features, labels, l) = literal_tables(&d);
    let model = d.join("m.json");
    let train = |labels: &std::path::Path| {
        vt(&[
            "train",
            "--features",
            s(&features),
            "--labels",
            s(labels),
            "--targets",
            "x_mm,fy_n",
            "--hidden",
            "3",
            "--ensemble",
            "1",
            "--max-epochs",
            "20",
            "-o",
            s(&model),
        ])
    };
    let o = train(&labels);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("target `fy_n` has the same value in every frame"),
        "{err}"
    );
    let predictions = d.join("p.csv");
    common::ok(&vt(&[
        "predict",
        "--model",
        s(&model),
        "--features",
        s(&features),
        "-o",
        s(&predictions),
    ]));
    // Weights of 1e308 overflow every sum: no estimate, an error with the reason and no
    // table — not "30 estimates" of empty cells.
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    for w in v["net"]["params"].as_array_mut().unwrap() {
        *w = serde_json::json!(1e308);
    }
    let overflowing = d.join("overflow.json");
    std::fs::write(&overflowing, v.to_string()).unwrap();
    let err = fails(&vt(&[
        "predict",
        "--model",
        s(&overflowing),
        "--features",
        s(&features),
        "-o",
        s(&d.join("p_overflow.csv")),
    ]));
    assert!(
        err.contains("no frame got an estimate") && err.contains("non-finite"),
        "{err}"
    );
    assert!(!d.join("p_overflow.csv").exists());
    std::fs::remove_file(&model).unwrap();
    let huge = d.join("huge.csv");
    let l2: String = l
        .lines()
        .map(|line| if line.starts_with("f7,") { "f7,1e308,0.5".to_string() } else { line.to_string() } + "\n")
        .collect();
    std::fs::write(&huge, &l2).unwrap();
    let err = fails(&train(&huge));
    assert!(err.contains("x_mm") && err.contains("1e15"), "{err}");
    assert!(!model.exists(), "a model was written");
    std::fs::remove_dir_all(&d).unwrap();
}

/// A training that cannot fit in memory is refused before it allocates, with the figure.
#[test]
fn oversized_trainings_are_refused_first() {
    let d = fresh_dir("hostile-memory");
    let (features, labels, _) = literal_tables(&d);
    let model = d.join("m.json");
    for extra in [
        &["--hidden", "1000000,1000000"][..],
        &["--max-memory-gib", "0.000001"],
    ] {
        let err = fails(&common::train(&features, &labels, "x_mm", &model, extra));
        assert!(
            err.contains("this training needs about"),
            "{extra:?}: {err}"
        );
        assert!(!model.exists());
    }
    std::fs::remove_dir_all(&d).unwrap();
}

/// A sensor file describing no possible image is refused when read, naming it; the dashboard
/// takes a host name; an error's cause is said once.
#[test]
fn small_things() {
    let d = fresh_dir("hostile-small");
    // A simulated session, its sensor file (and a feature table this test does not need).
    let (session, sensor, _) = common::iats_features(&d, "2", "1");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&sensor).unwrap()).unwrap();
    v["image_width"] = serde_json::json!(0);
    let bad = d.join("bad.json");
    std::fs::write(&bad, v.to_string()).unwrap();
    let err = fails(&vt(&[
        "extract",
        "--sensor",
        s(&bad),
        s(&session.join("frames")),
        "-o",
        s(&d.join("f.csv")),
    ]));
    assert!(
        err.contains("bad.json") && err.contains("image size 0×480"),
        "{err}"
    );
    common::ok(&vt(&[
        "run",
        "--source",
        "sim:iats",
        "--sensor",
        s(&sensor),
        "--max-frames",
        "3",
        "--unpaced",
        "--quiet",
        "--serve",
        "localhost:0",
    ]));
    let err = fails(&vt(&[
        "calibrate",
        "/nonexistent/frames",
        "-o",
        s(&d.join("x.json")),
    ]));
    assert_eq!(err.matches("os error").count(), 1, "{err}");
    std::fs::remove_dir_all(&d).unwrap();
}

/// Runs `visuotact args` with every file it writes limited to `limit_kib` KiB (`ulimit -f`,
/// SIGXFSZ ignored): a write past it fails with EFBIG as a full disk fails with ENOSPC.
#[cfg(unix)]
fn vt_with_file_limit(limit_kib: u32, args: &[&str]) -> std::process::Output {
    std::process::Command::new("bash")
        .arg("-c")
        .arg(format!(
            "trap '' XFSZ; ulimit -f {limit_kib}; exec \"$0\" \"$@\""
        ))
        .arg(env!("CARGO_BIN_EXE_visuotact"))
        .args(args)
        .output()
        .expect("run bash")
}

/// A full disk while recording: the failed frame write is the error reported (naming the
/// frame's file), no torn PNG is left under a frame's name, `session.json` says how many
/// frames are safe, and `--resume` without the limit completes the session. A disk too full
/// for the start-up probe is reported before anything is recorded and leaves no folder.
#[cfg(unix)]
#[test]
fn a_full_disk_stops_recording_without_loss() {
    let d = fresh_dir("hostile-disk-full");
    let src = d.join("src");
    std::fs::create_dir_all(&src).unwrap();
    let (w, h) = (700, 600);
    let flat = visuotact_image::RgbImage::from_fn(w, h, |_, _| [40, 40, 40]);
    // Pseudo-random pixels: a PNG of 1.2 MiB, over the 1 100 KiB limit (the probe is 1 MiB).
    let mut state = 1u64;
    let noise = visuotact_image::RgbImage::from_fn(w, h, |_, _| {
        let mut px = [0u8; 3];
        for c in &mut px {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            *c = (state >> 56) as u8;
        }
        px
    });
    for (name, img) in [("f0", &flat), ("f1", &flat), ("f2", &noise), ("f3", &flat)] {
        visuotact_io::frames::write_png(&src.join(format!("{name}.png")), img).unwrap();
    }
    let rec = d.join("rec");
    let args = [
        "record",
        "--source",
        s(&src),
        "--save-frames",
        "-o",
        s(&rec),
    ];
    let err = fails(&vt_with_file_limit(1100, &args));
    assert!(err.contains("f2.png"), "the failed frame is named: {err}");
    let saved: Vec<String> = std::fs::read_dir(rec.join("frames"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(!saved.iter().any(|n| n.starts_with("f2")), "{saved:?}");
    let session: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(rec.join("session.json")).unwrap()).unwrap();
    assert_eq!(session["complete"], false);
    assert_eq!(session["frames"], 2);
    let rows = std::fs::read_to_string(rec.join("frames.csv")).unwrap();
    assert_eq!(rows.lines().count(), 3, "{rows}");
    ok(&vt(&[&args[..], &["--resume"]].concat()));
    let rows = std::fs::read_to_string(rec.join("frames.csv")).unwrap();
    assert_eq!(rows.lines().count(), 5, "{rows}");
    for name in ["f0", "f1", "f2", "f3"] {
        let got = visuotact_io::frames::read_image(&rec.join("frames").join(format!("{name}.png")));
        assert!(got.is_ok(), "{name}: {got:?}");
    }
    // Resuming a session whose source has nothing later records nothing: an error, not
    // success.
    let err = fails(&vt(&[&args[..], &["--resume"]].concat()));
    assert!(
        err.contains("nothing recorded") && err.contains("already holds 4 frames"),
        "{err}"
    );
    // Too full to start: refused before recording, nothing left behind.
    let early = d.join("early");
    let err = fails(&vt_with_file_limit(
        100,
        &["record", "--source", s(&src), "-o", s(&early)],
    ));
    assert!(err.contains("cannot record into"), "{err}");
    assert!(!early.exists(), "the refused run left {}", early.display());
    std::fs::remove_dir_all(&d).unwrap();
}

/// A Rerun recording that cannot be written whole (a full disk; here a file-size limit) is an
/// error naming the file, and no truncated `.rrd` is left (was: "wrote x.rrd (300 frames)",
/// exit 0, a cut file). The SDK's file sink only logs a failed write, so the file is read back.
#[cfg(unix)]
#[test]
fn a_rerun_recording_cut_by_a_full_disk_is_an_error() {
    let d = fresh_dir("hostile-rerun-full");
    let session = d.join("s");
    ok(&vt(&[
        "simulate",
        "--sensor",
        "iats",
        "--protocol",
        "random",
        "--touches",
        "30",
        "-o",
        s(&session),
    ]));
    let whole = d.join("whole.rrd");
    let err = ok(&vt(&["export", "rerun", s(&session), "-o", s(&whole)]));
    assert!(err.contains("(40 frames)"), "{err}");
    let cut = d.join("cut.rrd");
    let o = vt_with_file_limit(200, &["export", "rerun", s(&session), "-o", s(&cut)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("cut.rrd") && err.contains("breaks off"),
        "{err}"
    );
    assert!(!cut.exists());
    // Nor its temporary file: the retry starts clean.
    let left: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".part~"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
    std::fs::remove_dir_all(&d).unwrap();
}

/// A FIFO given as `run --sensors` (nothing ever written into it) is refused at once as not a
/// regular file (was: the run waited on it for ever). The child is killed after 30 s so that a
/// regression fails instead of hanging the suite.
#[test]
fn a_fifo_as_the_sensors_file_is_refused_not_waited_on() {
    let d = fresh_dir("hostile-fifo-sensors");
    let fifo = d.join("sensors.toml");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("mkfifo");
    assert!(made.success());
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_visuotact"))
        .args(["run", "--sensors", s(&fifo), "--max-frames", "1", "--quiet"])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let err = fails(&common::finished_within(child, 30, "run --sensors FIFO"));
    assert!(
        err.contains("not a regular file") && err.contains("--sensors"),
        "{err}"
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// Two runs writing one output: while one holds the output's lock (`.NAME.lock~`, taken here
/// by the test as another run would), a second is refused, naming the output and saying why,
/// and the output is left as it was (was: both wrote, the last rename won); once the lock is
/// let go the same command writes it.
#[test]
fn a_second_writer_of_one_output_is_refused() {
    let d = fresh_dir("hostile-two-writers");
    let (session, _, _) = common::iats_features(&d, "2", "1");
    let out = d.join("s.json");
    std::fs::write(&out, "old").unwrap();
    let lock = std::fs::File::create(d.join(".s.json.lock~")).unwrap();
    lock.try_lock().unwrap();
    let reference = session.join("reference");
    let args = ["calibrate", s(&reference), "-o", s(&out)];
    let err = fails(&vt(&args));
    assert!(
        err.contains("s.json") && err.contains("another run is writing it"),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "old");
    lock.unlock().unwrap();
    drop(lock);
    ok(&vt(&args));
    assert!(std::fs::read_to_string(&out)
        .unwrap()
        .contains("visuotact-sensor"));
    std::fs::remove_dir_all(&d).unwrap();
}

/// A run whose frames came but none could be estimated (1 × 1 frames for a 640 × 480 sensor)
/// is an error naming why, each frame a warning naming it (was: "0 estimated, latency NaN
/// ms", exit 0).
#[test]
fn a_run_that_estimates_nothing_is_an_error() {
    let d = fresh_dir("hostile-run-nothing");
    let (_, sensor, _) = common::iats_features(&d, "2", "1");
    let frames = d.join("tiny");
    std::fs::create_dir_all(&frames).unwrap();
    for k in 0..3 {
        std::fs::write(frames.join(format!("f{k}.pgm")), b"P5\n1 1\n255\n\x00").unwrap();
    }
    let err = fails(&vt(&[
        "run",
        "--source",
        s(&frames),
        "--sensor",
        s(&sensor),
        "--unpaced",
        "--quiet",
    ]));
    assert!(
        err.contains("none of the 3 frames captured could be estimated")
            && err.contains("frame f0.pgm: expected 640×480 like the reference, got 1×1"),
        "{err}"
    );
    assert!(err.contains("warning: frame f2.pgm"), "{err}");
    std::fs::remove_dir_all(&d).unwrap();
}

/// A reader that closes the run's standard output (`visuotact run | head -1`) ends a run that
/// would go on for ever, cleanly (exit 0, its summary said). The child is killed after 30 s
/// so that a regression fails instead of hanging the suite.
#[test]
fn a_closed_standard_output_ends_a_run_cleanly() {
    use std::io::BufRead;
    let d = fresh_dir("hostile-run-closed-stdout");
    let (_, sensor, _) = common::iats_features(&d, "2", "1");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_visuotact"))
        .args(["run", "--source", "sim:iats", "--sensor", s(&sensor)])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    std::io::BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(first.starts_with("{\"frame\":"), "{first}");
    let o = common::finished_within(child, 30, "run with its standard output closed");
    let err = ok(&o);
    assert!(err.contains("estimated"), "{err}");
    std::fs::remove_dir_all(&d).unwrap();
}

/// The round-three report's worst writes, on the command line: a leftover link under the old
/// fixed temporary name (`m.json.part~` → the labels) is never followed, so `train` leaves the
/// labels as they were and writes a plain `m.json` (was: the labels overwritten by the model,
/// `m.json` a link to them, exit 0); `-o /dev/null` and a FIFO are written through and stay
/// what they were (was: `/dev/null` replaced by a regular file when run as root).
#[cfg(unix)]
#[test]
fn writes_land_only_in_their_own_file() {
    use std::os::unix::fs::FileTypeExt;
    let d = fresh_dir("hostile-own-file");
    let (features, labels, labels_text) = literal_tables(&d);
    let model = d.join("m.json");
    std::os::unix::fs::symlink(&labels, d.join("m.json.part~")).unwrap();
    ok(&common::train(
        &features,
        &labels,
        "x_mm",
        &model,
        &["--quiet"],
    ));
    assert_eq!(std::fs::read_to_string(&labels).unwrap(), labels_text);
    let meta = std::fs::symlink_metadata(&model).unwrap();
    assert!(meta.file_type().is_file(), "m.json is not a plain file");
    let predict = |out: &str| {
        vt(&[
            "predict",
            "--model",
            s(&model),
            "--features",
            s(&features),
            "--quiet",
            "-o",
            out,
        ])
    };
    ok(&predict("/dev/null"));
    assert!(std::fs::metadata("/dev/null")
        .unwrap()
        .file_type()
        .is_char_device());
    let fifo = d.join("out.fifo");
    assert!(std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read_to_string(fifo).unwrap())
    };
    ok(&predict(s(&fifo)));
    assert!(reader.join().unwrap().starts_with("frame,x_mm"));
    assert!(std::fs::symlink_metadata(&fifo)
        .unwrap()
        .file_type()
        .is_fifo());
    std::fs::remove_dir_all(&d).unwrap();
}
