//! `simulate` end to end: session folders of both sensors that `calibrate` and `extract` read,
//! measured centroids against the simulator's projected truth, byte-identical reruns, and
//! clear errors for impossible settings.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

mod common;
use common::*;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("visuotact-sim-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn rows(path: &Path) -> Vec<HashMap<String, String>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    lines
        .map(|l| {
            header
                .iter()
                .cloned()
                .zip(l.split(',').map(str::to_string))
                .collect()
        })
        .collect()
}

/// Extracted positions (reference + displacement) against truth.csv for fully visible markers;
/// returns (checked, mean error px, worst error px). Grid markers are paired with the nearest visible truth;
/// concentric rings share a centre, so ring `k` is paired with truth ring `k`.
fn compare_with_truth(
    session: &Path,
    sensor: &Path,
    features: &Path,
    by_index: bool,
) -> (usize, f64, f64) {
    let cal: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(sensor).unwrap()).unwrap();
    let markers = cal["markers"].as_array().unwrap();
    let feats = rows(features);
    let truth = rows(&session.join("truth.csv"));
    let (mut checked, mut worst, mut sum) = (0, 0.0f64, 0.0);
    for f in &feats {
        let frame = &f["frame"];
        let frame_truth: Vec<&HashMap<String, String>> =
            truth.iter().filter(|t| &t["frame"] == frame).collect();
        for (k, m) in markers.iter().enumerate() {
            let dx = &f[&format!("m{k:03}_dx_px")];
            if dx.is_empty() {
                continue;
            }
            let x = m["x_px"].as_f64().unwrap() + dx.parse::<f64>().unwrap();
            let y =
                m["y_px"].as_f64().unwrap() + f[&format!("m{k:03}_dy_px")].parse::<f64>().unwrap();
            // The truth row of this marker: the nearest fully visible one (identities are
            // checked by the tracker tests; here the geometry).
            let t = frame_truth
                .iter()
                .filter(|t| {
                    t["fully_in_view"] == "1" && (!by_index || t["marker"] == k.to_string())
                })
                .map(|t| {
                    (
                        t["x_px"].parse::<f64>().unwrap(),
                        t["y_px"].parse::<f64>().unwrap(),
                    )
                })
                .min_by(|a, b| {
                    (a.0 - x)
                        .hypot(a.1 - y)
                        .total_cmp(&(b.0 - x).hypot(b.1 - y))
                });
            if let Some(t) = t {
                let e = (t.0 - x).hypot(t.1 - y);
                if e < 5.0 {
                    checked += 1;
                    worst = worst.max(e);
                    sum += e;
                }
            }
        }
    }
    (checked, sum / checked.max(1) as f64, worst)
}

/// `calibrate SESSION/reference [extra]` then `extract SESSION/frames`; returns the sensor
/// file, the feature table and what calibrate printed.
fn calibrate_and_extract(d: &Path, extra: &[&str]) -> (PathBuf, PathBuf, String) {
    let sensor = d.join("sensor.json");
    let reference = d.join("reference");
    let mut args = vec!["calibrate", s(&reference), "-o", s(&sensor)];
    args.extend_from_slice(extra);
    let err = ok(&vt(&args));
    let out = d.join("f.csv");
    ok(&vt(&[
        "extract",
        "--sensor",
        s(&sensor),
        s(&d.join("frames")),
        "-o",
        s(&out),
    ]));
    (sensor, out, err)
}

#[test]
fn iats_session_calibrates_extracts_and_matches_truth() {
    let d = tmp("iats");
    ok(&vt(&[
        "simulate",
        "--sensor",
        "iats",
        "--protocol",
        "random",
        "--touches",
        "6",
        "--references",
        "4",
        "--seed",
        "7",
        "-o",
        s(&d),
    ]));
    for f in [
        "session.json",
        "frames.csv",
        "labels.csv",
        "truth.csv",
        "reference/ref_0003.png",
        "frames/frame_000005.png",
    ] {
        assert!(d.join(f).is_file(), "{f} missing");
    }
    let labels = rows(&d.join("labels.csv"));
    assert_eq!(labels.len(), 6);
    // Every reference frame has the rest truth of all 117 markers, all of them visible.
    let truth = rows(&d.join("truth.csv"));
    for k in 0..4 {
        let rest: Vec<_> = truth
            .iter()
            .filter(|t| t["frame"] == format!("ref_{k:04}.png"))
            .collect();
        assert_eq!(rest.len(), 117, "ref_{k:04}.png");
        assert!(rest.iter().all(|t| t["visible"] == "1"));
    }
    assert!(labels
        .iter()
        .all(|r| r["depth_mm"].parse::<f64>().unwrap() >= 1.0));
    let (sensor, out, err) = calibrate_and_extract(&d, &[]);
    assert!(
        err.contains("calibrated 117 markers (grid: 9 rows × 13 columns"),
        "{err}"
    );
    let (checked, mean, worst) = compare_with_truth(&d, &sensor, &out, false);
    eprintln!(
        "iats: {checked} marker-frames, centroid error mean {mean:.3} px, worst {worst:.3} px"
    );
    assert!(checked >= 6 * 110, "{checked}");
    assert!(
        mean < 0.1 && worst < 0.3,
        "mean {mean} px, worst {worst} px"
    );
    // Every fully visible marker is found.
    let feats = rows(&out);
    let truth = rows(&d.join("truth.csv"));
    for f in &feats {
        let visible = truth
            .iter()
            .filter(|t| t["frame"] == f["frame"] && t["fully_in_view"] == "1")
            .count();
        assert!(
            f["n_found"].parse::<usize>().unwrap() >= visible,
            "{}",
            f["frame"]
        );
    }
}

#[test]
fn cone_session_with_force_stream() {
    let d = tmp("cone");
    ok(&vt(&[
        "simulate",
        "--sensor",
        "cone",
        "--protocol",
        "press-rotate",
        "--duration-s",
        "2",
        "--references",
        "5",
        "-o",
        s(&d),
    ]));
    let force = rows(&d.join("force.csv"));
    assert_eq!(
        force.len(),
        2200,
        "1 kHz over 0.2 s of references and the 2 s press"
    );
    let labels = rows(&d.join("labels.csv"));
    assert_eq!(labels.len(), 50);
    let peak = labels
        .iter()
        .map(|r| r["force_n"].parse::<f64>().unwrap())
        .fold(0.0, f64::max);
    assert!((peak - 10.0).abs() < 0.1, "peak {peak}");
    // The binary centroid is the one comparable with the truth (the area centroid of the shape
    // drawn); the cone preset's default, the grey-weighted one, leans towards the brighter side
    // of a vignetted ring (a bias the reference subtracts) and is checked for jitter below.
    let (sensor, out, err) =
        calibrate_and_extract(&d, &["--preset", "cone", "--centroid", "binary"]);
    assert!(
        err.contains("calibrated 2 markers"),
        "the outermost ring is cut by the border: {err}"
    );
    let (checked, mean, worst) = compare_with_truth(&d, &sensor, &out, true);
    eprintln!("cone: {checked} ring-frames, centroid error mean {mean:.3} px, worst {worst:.3} px");
    assert_eq!(checked, 100);
    // A ring's centroid moves by radius / area ≈ 0.03 px for every pixel the camera noise flips
    // across the threshold (the lever arm of a 200 px ring): rings are noisier than dots.
    assert!(
        mean < 0.3 && worst < 0.8,
        "mean {mean} px, worst {worst} px"
    );
    // Jitter over the 5 still reference frames: grey-weighted centroids 3.3× steadier here.
    let jitter = |err: &str| -> f64 {
        err.split("marker jitter over the calibration frames: median ")
            .nth(1)
            .and_then(|r| r.split(' ').next())
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("no jitter in {err}"))
    };
    let weighted = ok(&vt(&[
        "calibrate",
        s(&d.join("reference")),
        "--preset",
        "cone",
        "-o",
        s(&d.join("weighted.json")),
    ]));
    let (b, w) = (jitter(&err), jitter(&weighted));
    eprintln!("cone ring jitter: binary {b} px, weighted {w} px");
    assert!(w * 2.5 < b, "binary {b} px, weighted {w} px");
}

/// `simulate --sensor iats --protocol line --references 2 --seed SEED -o DIR`.
fn simulate_line(seed: u64, dir: &Path) {
    let seed = seed.to_string();
    ok(&vt(&[
        "simulate",
        "--sensor",
        "iats",
        "--protocol",
        "line",
        "--references",
        "2",
        "--seed",
        &seed,
        "-o",
        s(dir),
    ]));
}

#[test]
fn same_seed_same_bytes() {
    let (a, b) = (tmp("det-a"), tmp("det-b"));
    for d in [&a, &b] {
        simulate_line(5, d);
    }
    for f in [
        "session.json",
        "frames.csv",
        "labels.csv",
        "truth.csv",
        "reference/ref_0001.png",
        "frames/frame_000006.png",
    ] {
        assert_eq!(
            std::fs::read(a.join(f)).unwrap(),
            std::fs::read(b.join(f)).unwrap(),
            "{f} differs"
        );
    }
    let c = tmp("det-c");
    simulate_line(6, &c);
    assert_ne!(
        std::fs::read(a.join("frames/frame_000006.png")).unwrap(),
        std::fs::read(c.join("frames/frame_000006.png")).unwrap()
    );
}

#[test]
fn impossible_settings_are_refused() {
    let d = tmp("bad");
    let cases: [(&[&str], &str); 5] = [
        (
            &["--sensor", "iats", "--protocol", "grid", "--fps", "0"],
            "--fps must be a positive frame rate",
        ),
        (
            &["--sensor", "iats", "--protocol", "press"],
            "not an iats protocol",
        ),
        (
            &["--sensor", "cone", "--protocol", "grid"],
            "not a cone protocol",
        ),
        (
            &[
                "--sensor",
                "cone",
                "--protocol",
                "press",
                "--max-force-n=-3",
            ],
            "peak force must be ≥ 0 N",
        ),
        (
            &[
                "--sensor",
                "cone",
                "--protocol",
                "press",
                "--force-rate-hz",
                "0",
            ],
            "force sample rate must be positive",
        ),
    ];
    for (args, want) in cases {
        let mut all = vec!["simulate", "-o", s(&d)];
        all.extend_from_slice(args);
        let o = vt(&all);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
    }
    ok(&vt(&[
        "simulate",
        "--sensor",
        "iats",
        "--protocol",
        "line",
        "--references",
        "1",
        "-o",
        s(&d),
    ]));
    let o = vt(&[
        "simulate",
        "--sensor",
        "iats",
        "--protocol",
        "line",
        "-o",
        s(&d),
    ]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("already holds a session"));
}

#[test]
fn force_stream_goes_out_over_udp_on_loopback() {
    use visuotact_io::force::ForceLayout;
    let sock = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    sock.set_read_timeout(Some(std::time::Duration::from_secs(5)))
        .unwrap();
    let addr = sock.local_addr().unwrap().to_string();
    let d = tmp("udp");
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_visuotact"))
        .args([
            "simulate",
            "--sensor",
            "cone",
            "--protocol",
            "press",
            "--duration-s",
            "0.4",
            "--references",
            "2",
        ])
        .args(["--udp", &addr, "-o", s(&d)])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let layout = ForceLayout::default();
    let mut buf = [0u8; 128];
    let mut got = Vec::new();
    while got.len() < 480 {
        match sock.recv(&mut buf) {
            Ok(n) => got.push(layout.decode(&buf[..n]).unwrap()),
            Err(_) => break,
        }
    }
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // 0.08 s of references + 0.4 s of press at 1 kHz; loopback may drop a few under load.
    assert!(got.len() >= 470, "received {} packets", got.len());
    let file = rows(&d.join("force.csv"));
    assert_eq!(file.len(), 480);
    for p in got.iter().take(10) {
        let k = (p.timestamp_s * 1000.0).round() as usize;
        let fx: f64 = file[k]["fx_n"].parse().unwrap();
        assert!((p.values[0] - fx).abs() < 1e-5, "packet and file agree");
    }
}

#[test]
fn a_config_file_matches_the_simulator_to_another_sensor() {
    let d = tmp("config");
    std::fs::create_dir_all(&d).unwrap();
    let cfg = d.join("my_sensor.json");
    std::fs::write(
        &cfg,
        r#"{"cols": 8, "rows": 6, "span_x_mm": 40, "span_y_mm": 30, "camera": {"k1": -0.2}}"#,
    )
    .unwrap();
    let session = d.join("session");
    ok(&vt(&[
        "simulate",
        "--sensor",
        "iats",
        "--protocol",
        "line",
        "--config",
        s(&cfg),
        "-o",
        s(&session),
    ]));
    let desc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(session.join("session.json")).unwrap())
            .unwrap();
    assert_eq!(desc["config"]["cols"], 8);
    assert_eq!(desc["config"]["camera"]["k1"], -0.2);
    assert_eq!(
        desc["config"]["tip_radius_mm"], 5.0,
        "unspecified fields keep the preset"
    );
    let err = ok(&vt(&[
        "calibrate",
        s(&session.join("reference")),
        "-o",
        s(&d.join("s.json")),
    ]));
    assert!(
        err.contains("calibrated 48 markers (grid: 6 rows × 8 columns"),
        "{err}"
    );
    std::fs::write(&cfg, r#"{"colz": 8}"#).unwrap();
    let o = vt(&[
        "simulate",
        "--sensor",
        "iats",
        "--protocol",
        "line",
        "--config",
        s(&cfg),
        "-o",
        s(&d.join("x")),
    ]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("unknown field `colz`"));
}

/// Published TacTip data sets' format (128 × 128, binarised, 2–4 px pins ≈ 5 px apart), drawn
/// variants: `calibrate` with no option numbers every pin visible at rest and `extract` loses
/// at most 1 % of pin-frames.
#[test]
fn tiny_pins_calibrate_with_no_options() {
    for variant in ["0", "1", "2", "4"] {
        let d = tmp(&format!("tiny-{variant}"));
        let sv = &["simulate", "--sensor", "tactip-small", "--variant", variant];
        let rest = [&sv[..], &["--protocol", "random", "--touches", "30"]].concat();
        ok(&vt(&[&rest[..], &["--seed", "5", "-o", s(&d)]].concat()));
        let sensor = d.join("s.json");
        let err = ok(&vt(&[
            "calibrate",
            s(&d.join("reference")),
            "-o",
            s(&sensor),
        ]));
        assert!(err.contains("no opening"), "{err}");
        let visible_at_rest = rows(&d.join("truth.csv"))
            .iter()
            .filter(|t| t["frame"] == "ref_0000.png" && t["visible"] == "1")
            .count();
        let cal: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&sensor).unwrap()).unwrap();
        let numbered = cal["markers"].as_array().unwrap().len();
        assert!(
            numbered >= visible_at_rest && numbered > 250,
            "variant {variant}: {numbered} numbered, {visible_at_rest} visible at rest"
        );
        assert!(cal["marker_size"]["diameter_px"].as_f64().unwrap() < 5.0);
        let out = d.join("f.csv");
        let err = ok(&vt(&[
            "extract",
            "--sensor",
            s(&sensor),
            s(&d.join("frames")),
            "-o",
            s(&out),
            "--max-warnings",
            "0",
        ]));
        let lost: usize = err
            .split("frames with missing markers (")
            .nth(1)
            .and_then(|r| r.split(' ').next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("{err}"));
        assert!(
            lost * 100 <= numbered * 30,
            "variant {variant}: {lost} of {} pin-frames lost",
            numbered * 30
        );
        let _ = std::fs::remove_dir_all(&d);
    }
}
