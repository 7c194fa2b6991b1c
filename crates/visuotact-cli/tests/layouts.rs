//! Marker layouts recognised on rendered sensors (and refused when forced on the wrong one),
//! the sensor file's layout and neighbours, references from the lightest frames of a data set
//! with no contact-free frame, the temporal prior, and compact warnings — through the
//! `visuotact` binary as a user runs it.

#![allow(
    clippy::too_many_lines,
    reason = "an end-to-end scenario reads top to bottom; split, its steps would scatter"
)]

use std::path::{Path, PathBuf};
use std::process::Output;

use visuotact_sim::zoo::{self, Arrangement, ZooConfig, ZooTouch};

mod common;
use common::*;

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `simulate --sensor NAME --protocol random` with a few touches; extra args appended.
fn simulate(dir: &Path, sensor: &str, extra: &[&str]) -> PathBuf {
    let out = dir.join(sensor);
    let mut args = vec![
        "simulate",
        "--sensor",
        sensor,
        "--protocol",
        "random",
        "--touches",
        "30",
        "--references",
        "5",
        "-o",
        s(&out),
    ];
    args.extend_from_slice(extra);
    ok(&vt(&args));
    out
}

fn sensor_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn layouts_are_recognised_on_rendered_sensors_and_forced_ones_refused() {
    let d = fresh_dir("recognise");
    // No preset given: the markers' polarity picks it (dark dots: dark-markers).
    for (sensor, dark, layout, extra) in [
        ("tactip", false, "hex", vec![]),
        ("gelsight", true, "grid", vec![]),
        ("dots", false, "irregular", vec![]),
        ("iats", false, "grid", vec![]),
    ] {
        let session = simulate(&d, sensor, &extra);
        let out = d.join(format!("{sensor}.json"));
        let err = ok(&vt(&[
            "calibrate",
            s(&session.join("reference")),
            "-o",
            s(&out),
        ]));
        assert!(err.contains(&format!("({layout}:")), "{sensor}: {err}");
        assert_eq!(
            err.contains("markers darker than the skin: preset dark-markers"),
            dark,
            "{sensor}: {err}"
        );
        let cal = sensor_json(&out);
        assert_eq!(cal["layout"], layout, "{sensor}");
        assert_eq!(cal["version"], 2);
        // Every marker lists its neighbours; on a lattice, interior ones have them all.
        let markers = cal["markers"].as_array().unwrap();
        let degrees: Vec<usize> = markers
            .iter()
            .map(|m| m["neighbours"].as_array().unwrap().len())
            .collect();
        let full = match layout {
            "hex" => 6,
            "grid" => 4,
            _ => 1,
        };
        assert!(
            degrees.iter().filter(|&&k| k >= full).count() * 2 > markers.len(),
            "{sensor}: {degrees:?}"
        );
        // Neighbours are mutual.
        for (i, m) in markers.iter().enumerate() {
            for n in m["neighbours"].as_array().unwrap() {
                let j = n.as_u64().unwrap() as usize;
                let back = markers[j]["neighbours"].as_array().unwrap();
                if layout != "irregular" {
                    assert!(
                        back.iter().any(|b| b.as_u64() == Some(i as u64)),
                        "{sensor}"
                    );
                }
            }
        }
    }
    // The wrong layout forced is refused with what the markers look like.
    let tactip = d.join("tactip/reference");
    let o = vt(&[
        "calibrate",
        s(&tactip),
        "--layout",
        "grid",
        "-o",
        s(&d.join("x.json")),
    ]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("layout grid does not fit") && e.contains("hexagonal"),
        "{e}"
    );
    let o = vt(&[
        "calibrate",
        s(&tactip),
        "--layout",
        "rings",
        "-o",
        s(&d.join("x.json")),
    ]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("no two of the") && e.contains("share a centre"),
        "{e}"
    );
    let dots = d.join("dots/reference");
    let o = vt(&[
        "calibrate",
        s(&dots),
        "--layout",
        "hex",
        "-o",
        s(&d.join("x.json")),
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("irregular"), "{}", stderr(&o));
    // The cone's annuli are recognised without --layout.
    let cone = d.join("cone");
    ok(&vt(&[
        "simulate",
        "--sensor",
        "cone",
        "--protocol",
        "press",
        "--duration-s",
        "0.2",
        "--references",
        "3",
        "-o",
        s(&cone),
    ]));
    let out = d.join("cone.json");
    let err = ok(&vt(&[
        "calibrate",
        s(&cone.join("reference")),
        "--preset",
        "cone",
        "-o",
        s(&out),
    ]));
    assert_eq!(sensor_json(&out)["layout"], "rings", "{err}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn rings_of_dots_are_numbered_in_polar_order() {
    let d = fresh_dir("dotrings");
    let cfg = ZooConfig {
        arrangement: Arrangement::DotRings,
        ..ZooConfig::DOTS
    };
    let cfg_path = d.join("rings.json");
    std::fs::write(&cfg_path, serde_json::to_string(&cfg).unwrap()).unwrap();
    let session = simulate(&d, "dots", &["--config", s(&cfg_path)]);
    let out = d.join("s.json");
    ok(&vt(&[
        "calibrate",
        s(&session.join("reference")),
        "-o",
        s(&out),
    ]));
    let cal = sensor_json(&out);
    assert_eq!(cal["layout"], "dot-rings");
    let markers = cal["markers"].as_array().unwrap();
    let (truth, _) = {
        let ms = zoo::markers(&cfg, &ZooTouch::default());
        (ms.len(), ())
    };
    assert_eq!(markers.len(), truth);
    // Marker 0 is the centre dot (ring 0); rings grow outwards.
    assert_eq!(markers[0]["row"], 0);
    let radius = |m: &serde_json::Value| {
        let (x0, y0) = (
            markers[0]["x_px"].as_f64().unwrap(),
            markers[0]["y_px"].as_f64().unwrap(),
        );
        (m["x_px"].as_f64().unwrap() - x0).hypot(m["y_px"].as_f64().unwrap() - y0)
    };
    for w in markers.windows(2) {
        let (r0, r1) = (w[0]["row"].as_u64().unwrap(), w[1]["row"].as_u64().unwrap());
        assert!(r1 == r0 || r1 == r0 + 1);
        if r1 > r0 {
            assert!(radius(&w[1]) > radius(&w[0]));
        }
    }
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn a_reference_from_the_lightest_frames_of_a_pressed_data_set() {
    let d = fresh_dir("lightest");
    // Every touch frame pressed (5–100 % of the skin's limit); no reference frames used.
    let session = simulate(&d, "tactip", &[]);
    let out = d.join("light.json");
    let err = ok(&vt(&[
        "calibrate",
        s(&session.join("frames")),
        "--reference",
        "lightest:3",
        "-o",
        s(&out),
    ]));
    assert!(
        err.contains("reference from the 3 lightest of 30 frames"),
        "{err}"
    );
    let cal = sensor_json(&out);
    assert_eq!(cal["reference"]["method"], "lightest");
    assert_eq!(cal["reference"]["frames_considered"], 30);
    assert_eq!(cal["reference_frames"].as_array().unwrap().len(), 3);
    // The chosen frames are among the lightest presses by the simulator's labels.
    let labels = std::fs::read_to_string(session.join("labels.csv")).unwrap();
    let mut depths: Vec<(f64, String)> = labels
        .lines()
        .skip(1)
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            (c[3].parse().unwrap(), c[0].to_string())
        })
        .collect();
    depths.sort_by(|a, b| a.0.total_cmp(&b.0));
    let lightest: Vec<&str> = depths[..8].iter().map(|x| x.1.as_str()).collect();
    for f in cal["reference_frames"].as_array().unwrap() {
        let name = f.as_str().unwrap().rsplit('/').next().unwrap();
        assert!(
            lightest.contains(&name),
            "{name} is not among the 8 lightest {lightest:?}"
        );
    }
    // The reference's markers lie close to the rest positions of a true still reference.
    let still = d.join("still.json");
    ok(&vt(&[
        "calibrate",
        s(&session.join("reference")),
        "-o",
        s(&still),
    ]));
    let (a, b) = (sensor_json(&out), sensor_json(&still));
    let (ma, mb) = (
        a["markers"].as_array().unwrap(),
        b["markers"].as_array().unwrap(),
    );
    assert_eq!(ma.len(), mb.len());
    let mut far = 0;
    for m in ma {
        let (x, y) = (m["x_px"].as_f64().unwrap(), m["y_px"].as_f64().unwrap());
        let nearest = mb
            .iter()
            .map(|n| (n["x_px"].as_f64().unwrap() - x).hypot(n["y_px"].as_f64().unwrap() - y))
            .fold(f64::INFINITY, f64::min);
        far += usize::from(nearest > 1.0);
    }
    assert!(
        far * 20 < ma.len(),
        "{far} of {} markers over 1 px from rest",
        ma.len()
    );
    // Extraction with it says the reference was taken under contact when it was.
    if a["reference"]["under_contact"] == true {
        let o = vt(&[
            "extract",
            "--sensor",
            s(&out),
            s(&session.join("frames")),
            "-o",
            s(&d.join("f.csv")),
            "--max-warnings",
            "0",
        ]);
        assert!(stderr(&o).contains("taken under contact"), "{}", stderr(&o));
    }
    // Bad requests are refused.
    for bad in ["lightest:0", "lightest:x", "darkest:3"] {
        let o = vt(&[
            "calibrate",
            s(&session.join("frames")),
            "--reference",
            bad,
            "-o",
            s(&d.join("x.json")),
        ]);
        assert!(
            !o.status.success() && stderr(&o).contains("--reference"),
            "{bad}"
        );
    }
    let o = vt(&[
        "calibrate",
        s(&session.join("reference")),
        "--reference",
        "lightest:9",
        "-o",
        s(&d.join("x.json")),
    ]);
    assert!(
        stderr(&o).contains("5 frames given, 9 asked for"),
        "{}",
        stderr(&o)
    );
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn warnings_are_one_short_line_per_frame_and_max_zero_is_silent() {
    let d = fresh_dir("warnings");
    let session = simulate(&d, "gelsight", &[]);
    let sensor = d.join("g.json");
    ok(&vt(&[
        "calibrate",
        s(&session.join("reference")),
        "--preset",
        "dark-markers",
        "-o",
        s(&sensor),
    ]));
    // Hide half of a frame so that markers are missing.
    let frame = session.join("frames/frame_000000.png");
    let mut img = image::open(&frame).unwrap().into_rgb8();
    let bg = *img.get_pixel(160, 5);
    for y in 0..120 {
        for x in 0..320 {
            img.put_pixel(x, y, bg);
        }
    }
    img.save(&frame).unwrap();
    let run = |max: &str| {
        ok(&vt(&[
            "extract",
            "--sensor",
            s(&sensor),
            s(&session.join("frames")),
            "-o",
            s(&d.join("f.csv")),
            "--max-warnings",
            max,
        ]))
    };
    let err = run("5");
    let warnings: Vec<&str> = err.lines().filter(|l| l.starts_with("warning:")).collect();
    assert!(!warnings.is_empty(), "{err}");
    for w in &warnings {
        assert!(w.len() < 160, "long warning: {w}");
    }
    assert!(
        warnings[0].contains(" lost") && warnings[0].contains(": m0"),
        "{}",
        warnings[0]
    );
    assert!(
        err.lines().last().unwrap().starts_with("extracted"),
        "{err}"
    );
    let err = run("0");
    assert!(!err.contains("warning"), "{err}");
    assert!(
        err.lines().last().unwrap().starts_with("extracted"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// The real 127-pin TacTip calibrated as a user with no contact-free frame would, from ONE
/// in-contact frame (`frame_0_0.png`): a speck on the tip's rim (12 px² beside a 37 px² pin,
/// one lattice step past the array's corner) was numbered as a marker and then missed in 70 % of
/// the frames (0.80 % of pin-frames missing). It is a speck, not a marker: no marker of the
/// sensor hangs on the array by one neighbour while under half its size, and over every frame
/// of the set at most 0.5 % of pin-frames are missing (0.057 % measured at 85d0a79).
#[test]
fn a_speck_on_the_rim_of_one_in_contact_frame_is_no_marker() {
    let Some(data) = shared_real("tactip127_surface/frames") else {
        return;
    };
    let d = fresh_dir("layouts-one-frame");
    let sensor = d.join("tip.json");
    ok(&vt(&[
        "calibrate",
        s(&data.join("frame_0_0.png")),
        "-o",
        s(&sensor),
    ]));
    let markers = sensor_json(&sensor)["markers"].as_array().unwrap().clone();
    for m in &markers {
        let nb = m["neighbours"].as_array().unwrap();
        if nb.len() == 1 {
            let other = &markers[nb[0].as_u64().unwrap() as usize];
            let (a, b) = (
                m["area_px"].as_f64().unwrap(),
                other["area_px"].as_f64().unwrap(),
            );
            assert!(2.0 * a >= b, "a speck numbered as a marker: {m}");
        }
    }
    let features = d.join("f.csv");
    ok(&vt(&[
        "extract",
        "--sensor",
        s(&sensor),
        s(&data),
        "-o",
        s(&features),
        "--max-warnings",
        "0",
    ]));
    let (rows, empty) = rows_and_empty_cells(&features, markers.len());
    let cells = rows * markers.len();
    assert!(cells > 600_000, "{cells} pin-frames");
    assert!(
        200 * empty <= cells,
        "{empty} of {cells} pin-frames missing (over 0.5 %)"
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// The real 331-pin TacTip set (`tactip331_franka`: binarised frames, every one in contact, tilt
/// up to 25°, slides up to 5 mm) calibrated as a user with no contact-free frame would, on its
/// shallowest training frame (`image_1.png`, itself tilted and slid), on every fifth frame (the
/// workflow's test split, 400 frames): every frame gets its row, and at most 1.25 % of
/// pin-frames are missing. Measured at 85d0a79: 1.08 % on these frames, 0.99 % over all 2 000
/// (issue 60 asks at most 1 % of the whole set; the tracker before it missed 27.9 %).
#[test]
fn the_real_331_pin_set_calibrated_in_contact_keeps_its_pins() {
    let Some(data) = shared_real("tactip331_franka/frames") else {
        return;
    };
    let d = fresh_dir("layouts-331");
    let sensor = d.join("tip.json");
    ok(&vt(&[
        "calibrate",
        s(&data.join("image_1.png")),
        "-o",
        s(&sensor),
    ]));
    let pins = sensor_json(&sensor)["markers"].as_array().unwrap().len();
    assert_eq!(pins, 331, "pins numbered");
    let features = d.join("f.csv");
    let frames: Vec<PathBuf> = (1..=400)
        .map(|k| data.join(format!("image_{}.png", 5 * k)))
        .collect();
    let mut args = vec!["extract", "--sensor", s(&sensor), "-o", s(&features)];
    args.extend(["--max-warnings", "0"]);
    args.extend(frames.iter().map(|p| s(p)));
    ok(&vt(&args));
    let (rows, empty) = rows_and_empty_cells(&features, pins);
    assert_eq!(rows, 400, "a row per frame");
    let cells = rows * pins;
    assert!(
        80 * empty <= cells,
        "{empty} of {cells} pin-frames missing (over 1.25 %)"
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// A features table's rows and its markers' empty `dx` cells (markers without a position),
/// checking that it has a `dx` column for each of `markers`.
fn rows_and_empty_cells(features: &Path, markers: usize) -> (usize, usize) {
    let text = std::fs::read_to_string(features).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let dx: Vec<usize> = (0..header.len())
        .filter(|&k| header[k].ends_with("_dx_px"))
        .collect();
    assert_eq!(dx.len(), markers, "a dx column per marker");
    let (mut rows, mut empty) = (0, 0);
    for line in text.lines().skip(1) {
        let row: Vec<&str> = line.split(',').collect();
        rows += 1;
        empty += dx.iter().filter(|&&k| row[k].is_empty()).count();
    }
    (rows, empty)
}

/// `check-tracking --reference-pressed` runs one of the scorecard's `plate` cases alone (a dome
/// calibrated on frames pressed by a plate drawn from the seed): its row is the library's check
/// of that case, not the one calibrated at rest; without a plate to press the reference with, it
/// is refused.
#[test]
fn one_scorecard_plate_case_runs_alone() {
    use visuotact_experiments::scorecard::touched_reference;
    use visuotact_experiments::trackcheck::{check, CheckConfig, SimSensor};
    let sensor = SimSensor::named("tactip-small", 2).unwrap();
    let touch = touched_reference(&sensor, "plate", 5);
    assert!(touch.is_some());
    let case = CheckConfig::zoo(sensor, "plate", 2, 5);
    let pressed = check(&CheckConfig {
        reference_touch: touch,
        ..case.clone()
    })
    .unwrap()
    .tsv_row("tactip-small", 2);
    let at_rest = check(&case).unwrap().tsv_row("tactip-small", 2);
    assert_ne!(pressed, at_rest);
    let args = [
        "check-tracking",
        "--sensor",
        "tactip-small",
        "--variants",
        "2",
        "--protocol",
        "plate",
        "--touches",
        "2",
        "--seed",
        "5",
    ];
    let o = vt(&[&args[..], &["--reference-pressed"]].concat());
    ok(&o);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.lines().any(|l| l == pressed),
        "{out}\nexpected {pressed}"
    );
    let o = vt(&args);
    ok(&o);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.lines().any(|l| l == at_rest),
        "{out}\nexpected {at_rest}"
    );
    let err = fails(&vt(&[
        "check-tracking",
        "--touches",
        "1",
        "--reference-pressed",
    ]));
    assert!(
        err.contains("--reference-pressed") && err.contains("plate"),
        "{err}"
    );
}
