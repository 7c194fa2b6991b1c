//! The force data path end to end on the simulator: `record` a cone session with the simulated
//! JR3 streaming over UDP on loopback, `dataset` (filter, bias, alignment), `train`, `record`
//! live with the model, `replay` — and the faults: SIGKILL mid-session then `--resume`, an
//! unwritable place, a session that exists, `filter` on a bad file.

#![allow(
    clippy::too_many_lines,
    reason = "an end-to-end scenario reads top to bottom; split, its steps would scatter"
)]

use std::path::Path;
use std::process::Command;

mod common;
use common::*;

/// `frame → row` of a CSV keyed by its first column.
fn rows(p: &Path) -> Vec<(String, Vec<String>)> {
    std::fs::read_to_string(p)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let c: Vec<String> = l.split(',').map(str::to_string).collect();
            (c[0].clone(), c[1..].to_vec())
        })
        .collect()
}

fn column(p: &Path, name: &str) -> Vec<(String, f64)> {
    let text = std::fs::read_to_string(p).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let i = header.iter().position(|h| *h == name).unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            (c[0].to_string(), c[i].parse().unwrap_or(f64::NAN))
        })
        .collect()
}

/// The frames a simulated recording of `due` frames kept: with those it dropped they make
/// `due`, and at most a quarter were dropped.
fn frames_of(session: &serde_json::Value, due: u64) -> usize {
    let kept = session["frames"].as_u64().unwrap();
    let dropped = session["frames_dropped"].as_u64().unwrap();
    assert_eq!(kept + dropped, due, "{session}");
    assert!(4 * dropped <= due, "{session}");
    kept as usize
}

#[test]
fn record_dataset_train_replay_on_the_simulated_cone() {
    let d = fresh_dir("record");
    let a = d.join("a");
    // 1 s rest, 6 s press to 10 N, 1 s rest at 10 fps; the JR3 streams at 1 kHz over UDP.
    let err = ok(&vt(&[
        "record",
        "--source",
        "sim:cone",
        "--fps",
        "10",
        "--press-s",
        "6",
        "--rest-s",
        "1",
        "--force",
        "udp:127.0.0.1:0",
        "--save-frames",
        "-o",
        s(&a),
    ]));
    assert!(err.contains("0 malformed, 0 duplicates"), "{err}");
    let session: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(a.join("session.json")).unwrap()).unwrap();
    assert_eq!(session["complete"], true);
    // 81 frames are due; the paced camera drops the ones it is over a period late for (a
    // loaded machine), and says so.
    let recorded = frames_of(&session, 81);
    assert!(
        err.contains(&format!("recorded {recorded} frames")),
        "{err}"
    );
    assert!(session["force_packets"]["kept"].as_u64().unwrap() > 7500);

    ok(&vt(&[
        "calibrate",
        s(&a.join("reference")),
        "--preset",
        "cone",
        "-o",
        s(&d.join("sensor.json")),
    ]));
    ok(&vt(&[
        "dataset",
        s(&a),
        "--sensor",
        s(&d.join("sensor.json")),
        "-o",
        s(&d.join("ds")),
    ]));
    // Filtered, debiased, aligned force against the simulator's true force on each frame:
    // within the JR3's noise (σ = 0.03 N per axis before filtering).
    let truth: std::collections::HashMap<String, f64> = column(&a.join("labels.csv"), "force_n")
        .into_iter()
        .collect();
    let got = column(&d.join("ds/labels.csv"), "force_n");
    assert!(got.len() + 2 >= recorded, "{} labelled frames", got.len());
    let errs: Vec<f64> = got.iter().map(|(k, v)| v - truth[k]).collect();
    let mean_abs = errs.iter().map(|e| e.abs()).sum::<f64>() / errs.len() as f64;
    let max_abs = errs.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    assert!(
        mean_abs < 0.03 && max_abs < 0.1,
        "mean {mean_abs}, max {max_abs}"
    );

    ok(&vt(&[
        "train",
        "--features",
        s(&d.join("ds/features.csv")),
        "--labels",
        s(&d.join("ds/labels.csv")),
        "--targets",
        "force_n",
        "--hidden",
        "10",
        "--sensor",
        s(&d.join("sensor.json")),
        "-o",
        s(&d.join("model.json")),
    ]));
    // Live: a second press, estimated as it is recorded; then replayed from its frames.
    let b = d.join("b");
    ok(&vt(&[
        "record",
        "--source",
        "sim:cone",
        "--fps",
        "10",
        "--press-s",
        "3",
        "--rest-s",
        "0.5",
        "--seed",
        "2",
        "--model",
        s(&d.join("model.json")),
        "--save-frames",
        "-o",
        s(&b),
    ]));
    let err = ok(&vt(&[
        "replay",
        "--model",
        s(&d.join("model.json")),
        s(&b),
        "-o",
        s(&d.join("replay.csv")),
    ]));
    let session_b: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(b.join("session.json")).unwrap()).unwrap();
    let recorded_b = frames_of(&session_b, 41);
    assert!(
        err.contains(&format!("replayed {recorded_b} frames")),
        "{err}"
    );
    let live = rows(&b.join("estimates.csv"));
    let replayed = rows(&d.join("replay.csv"));
    assert_eq!(live.len(), recorded_b);
    assert_eq!(
        live, replayed,
        "replay must give the live estimates exactly"
    );
    let o = vt(&[
        "eval",
        "--predictions",
        s(&d.join("replay.csv")),
        "--labels",
        s(&b.join("labels.csv")),
        "--json",
    ]);
    ok(&o);
    let ev: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(ev["targets"][0]["r"].as_f64().unwrap() > 0.98, "{ev}");
    // With the built-in slip detector: the same estimates, then a score and a state.
    ok(&vt(&[
        "replay",
        "--model",
        s(&d.join("model.json")),
        "--slip",
        "builtin",
        s(&b),
        "-o",
        s(&d.join("replay_slip.csv")),
    ]));
    let text = std::fs::read_to_string(d.join("replay_slip.csv")).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    // The score, the state, then the field's ten signals the detector read.
    let names = visuotact_vision::field::FieldDynamics::NAMES;
    let at = header.len() - 3 - names.len();
    assert_eq!(
        header[at..at + 2],
        ["slip_score", "slip_state"],
        "{header:?}"
    );
    assert_eq!(header[at + 2..header.len() - 1], names, "{header:?}");
    assert_eq!(header[header.len() - 1], "flags");
    for line in text.lines().skip(1) {
        let c: Vec<&str> = line.split(',').collect();
        let score: f64 = c[at].parse().unwrap();
        assert!((0.0..=1.0).contains(&score), "{line}");
        assert!(["0", "1", "2"].contains(&c[at + 1]), "{line}");
        for v in &c[at + 2..c.len() - 1] {
            assert!(v.parse::<f64>().unwrap().is_finite(), "{line}");
        }
    }
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn a_killed_recording_keeps_its_rows_and_resumes() {
    let d = fresh_dir("kill");
    let args = [
        "record",
        "--source",
        "sim:cone",
        "--fps",
        "10",
        "--press-s",
        "4",
        "--rest-s",
        "0.5",
        "--force",
        "udp:127.0.0.1:0",
        "--sync-every-s",
        "0.2",
        "-o",
        s(&d),
    ];
    let mut child = Command::new(env!("CARGO_BIN_EXE_visuotact"))
        .args(args)
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(2500));
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    // Everything written so far reads back: complete rows, in order.
    let frames = rows(&d.join("frames.csv"));
    assert!(
        frames.len() >= 10,
        "{} frames before the kill",
        frames.len()
    );
    for (i, (name, r)) in frames.iter().enumerate() {
        assert_eq!(name, &format!("frame_{i:06}.png"));
        assert_eq!(r[0], i.to_string());
        assert_eq!(r.len(), 3);
    }
    let labels = rows(&d.join("labels.csv"));
    assert!(labels.len() + 1 >= frames.len());
    let force = std::fs::read_to_string(d.join("force.csv")).unwrap();
    let complete = force.lines().filter(|l| l.split(',').count() == 8).count();
    assert!(complete > 1000, "{complete} force rows");
    let session: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("session.json")).unwrap()).unwrap();
    assert_eq!(session["complete"], false);
    // Without --resume the folder is refused; with it the recording goes on where it stopped.
    let o = vt(&args);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--resume"));
    let mut resume = args.to_vec();
    resume.push("--resume");
    ok(&vt(&resume));
    // 5 s and the last frame at 10 fps: 51 frames due. The paced simulated camera drops a
    // frame it is a period late for (a loaded test machine), so up to a quarter may be gone;
    // the rest keep their own numbers, in order, each once.
    let all = rows(&d.join("frames.csv"));
    assert!((39..=51).contains(&all.len()), "{} frames", all.len());
    let mut last: Option<usize> = None;
    for (name, r) in &all {
        let k: usize = r[0].parse().unwrap();
        assert_eq!(name, &format!("frame_{k:06}.png"));
        assert!(
            last.is_none_or(|l| l < k) && k <= 50,
            "{name} after {last:?}"
        );
        last = Some(k);
    }
    let session: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("session.json")).unwrap()).unwrap();
    assert_eq!(session["complete"], true);
    // The force table reads back whole, and a dataset can be built from it.
    let t = visuotact_io::force::ForceTable::read(&d.join("force.csv")).unwrap();
    assert!(t.timestamp_s.len() > 4000);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn unwritable_places_and_bad_force_files_are_refused_up_front() {
    let o = vt(&[
        "record",
        "--source",
        "sim:iats",
        "-o",
        "/proc/visuotact-session",
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("/proc/visuotact-session"), "{err}");

    let d = fresh_dir("filter");
    let bad = d.join("force.csv");
    std::fs::write(&bad, "timestamp_s,fz_n\n0,1\n0.001,oops\n").unwrap();
    let o = vt(&["filter", s(&bad), "-o", s(&d.join("out.csv"))]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("line 3, column `fz_n`"),
        "{err}"
    );
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn filter_removes_noise_and_a_drifting_bias() {
    // 20 s at 1 kHz: bias 0.3 → 0.5 N, presses of 4 N at 4–8 s and 12–16 s, noise 0.05 N.
    let d = fresh_dir("filter-ok");
    let mut text = String::from("timestamp_s,fx_n,fz_n\n");
    let mut seed = 12345u64;
    let mut noise = || {
        let mut acc = 0.0;
        for _ in 0..12 {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            acc += (seed >> 11) as f64 / (1u64 << 53) as f64;
        }
        0.05 * (acc - 6.0)
    };
    let press = |t: f64| {
        let r = |a: f64, b: f64| ((t - a) / 0.5).clamp(0.0, 1.0) * ((b - t) / 0.5).clamp(0.0, 1.0);
        4.0 * (r(4.0, 8.0) + r(12.0, 16.0))
    };
    for i in 0..20_000 {
        let t = i as f64 / 1000.0;
        let bias = 0.3 + 0.01 * t;
        text.push_str(&format!(
            "{t:.3},{:.5},{:.5}\n",
            bias + noise(),
            bias + press(t) + noise()
        ));
    }
    std::fs::write(d.join("f.csv"), text).unwrap();
    let err = ok(&vt(&[
        "filter",
        s(&d.join("f.csv")),
        "-o",
        s(&d.join("out.csv")),
        "--plot",
        s(&d.join("f.png")),
    ]));
    // Three rests (before, between and after the presses), possibly cut into pieces where the
    // filtered noise wandered; never inside a press (the values below would show it).
    let periods: usize = err
        .split("bias from ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap();
    assert!(periods >= 3, "{err}");
    let fz = column(&d.join("out.csv"), "fz_n");
    for (k, (_, v)) in fz.iter().enumerate().step_by(97) {
        let t = k as f64 / 1000.0;
        // Away from the ramps (where the low-pass rounds corners) and the ends (where any
        // zero-phase filter leans on the first and last noisy samples), within 0.05 N.
        let near_ramp = [0.0, 4.0, 4.5, 7.5, 8.0, 12.0, 12.5, 15.5, 16.0, 20.0]
            .iter()
            .any(|r| (t - r).abs() < 0.3);
        if !near_ramp {
            assert!((v - press(t)).abs() < 0.05, "t {t}: {v} vs {}", press(t));
        }
    }
    assert!(d.join("f.png").is_file());
    std::fs::remove_dir_all(&d).unwrap();
}

/// `--resume` continues only the recording that made the session: a description that does not
/// parse, another source, or a missing sensor is refused before anything is written (was: 300
/// frames appended to another session's table; `features.csv` short of the frames while
/// `session.json` said complete; a failed resume marking the session complete).
#[test]
fn resume_refuses_a_session_it_did_not_record() {
    let d = fresh_dir("resume-mismatch");
    let (session, sensor, _) = common::iats_features(&d, "6", "1");
    let frames = session.join("frames");
    let rec = d.join("rec");
    let first = [
        "record",
        "--source",
        s(&frames),
        "--sensor",
        s(&sensor),
        "--max-frames",
        "3",
        "-o",
        s(&rec),
    ];
    ok(&vt(&first));
    let tables = ["session.json", "frames.csv", "features.csv"];
    let before: Vec<Vec<u8>> = tables
        .iter()
        .map(|t| std::fs::read(rec.join(t)).unwrap())
        .collect();
    let unchanged = |case: &str| {
        for (t, b) in tables.iter().zip(&before) {
            assert_eq!(
                &std::fs::read(rec.join(t)).unwrap(),
                b,
                "{case}: {t} changed"
            );
        }
    };
    // Without the sensor the first run used.
    let err = fails(&vt(&[
        "record",
        "--source",
        s(&frames),
        "--resume",
        "-o",
        s(&rec),
    ]));
    assert!(
        err.contains("cannot resume") && err.contains("sensor was"),
        "{err}"
    );
    unchanged("no sensor");
    // Another source.
    let other = d.join("other");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::copy(frames.join("frame_000000.png"), other.join("a.png")).unwrap();
    let err = fails(&vt(&[
        "record",
        "--source",
        s(&other),
        "--sensor",
        s(&sensor),
        "--resume",
        "-o",
        s(&rec),
    ]));
    assert!(err.contains("source was"), "{err}");
    unchanged("another source");
    // A description that does not parse.
    let described = rec.join("session.json");
    std::fs::write(&described, &before[0][..before[0].len() / 2]).unwrap();
    let resume = [&first[..], &["--resume"]].concat();
    let err = fails(&vt(&resume));
    assert!(err.contains("not a session description"), "{err}");
    std::fs::write(&described, &before[0]).unwrap();
    unchanged("corrupt description");
    // The same settings go on where the first run stopped.
    let resume: Vec<&str> = resume
        .into_iter()
        .filter(|a| *a != "--max-frames" && *a != "3")
        .collect();
    ok(&vt(&resume));
    let rows = std::fs::read_to_string(rec.join("features.csv")).unwrap();
    assert_eq!(rows.lines().count(), 1 + 6, "{rows}");
    std::fs::remove_dir_all(&d).unwrap();
}

/// A force sender on its own clock (stamps from 1 000 s, as a real F/T box's) streaming
/// 56-byte packets at about 1 kHz to `port` until `stop` is set.
fn stream_force(
    port: u16,
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        let sock = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let start = std::time::Instant::now();
        while !stop.load(std::sync::atomic::Ordering::Relaxed) {
            let t = 1000.0 + start.elapsed().as_secs_f64();
            let packet: Vec<u8> = [t, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]
                .iter()
                .flat_map(|v| v.to_le_bytes())
                .collect();
            let _ = sock.send_to(&packet, ("127.0.0.1", port));
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
    })
}

/// A force sender that never stops does not keep a recording going: `--max-frames`,
/// `--duration-s` and Ctrl-C each end `record` while packets stream, with a complete session
/// (was: a 2-second recording ran 20.8 s, for as long as the sender streamed). The sender
/// streams for the whole test; a recording still running after 30 s is killed and fails.
#[test]
fn a_streaming_force_sender_never_keeps_a_recording_going() {
    let d = fresh_dir("record-endless-force");
    let port = std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let sender = stream_force(port, stop.clone());
    let udp = format!("udp:127.0.0.1:{port}");
    let record = |name: &str, until: &[&str]| {
        let mut args = vec![
            "record", "--source", "sim:iats", "--fps", "10", "--force", &udp,
        ];
        args.extend(until);
        let out = d.join(name);
        args.extend(["-o", s(&out)]);
        Command::new(env!("CARGO_BIN_EXE_visuotact"))
            .args(args)
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap()
    };
    let described = |name: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(d.join(name).join("session.json")).unwrap())
            .unwrap()
    };
    let o = finished_within(
        record("frames", &["--max-frames", "3"]),
        30,
        "--max-frames 3",
    );
    ok(&o);
    assert_eq!(described("frames")["complete"], true);
    assert_eq!(rows(&d.join("frames").join("frames.csv")).len(), 3);
    let o = finished_within(
        record("seconds", &["--duration-s", "1"]),
        30,
        "--duration-s 1",
    );
    ok(&o);
    assert_eq!(described("seconds")["complete"], true);
    let child = record("interrupted", &[]);
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let sent = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(sent.success());
    let o = finished_within(child, 30, "Ctrl-C");
    ok(&o);
    assert_eq!(described("interrupted")["complete"], true);
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    sender.join().unwrap();
    std::fs::remove_dir_all(&d).unwrap();
}
