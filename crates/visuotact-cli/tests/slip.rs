//! `visuotact slip`: labels matched to videos before anything is tracked, and on real GelSight
//! Mini grasps a fitted detector written, read back and run per video and per frame.

mod common;
use common::{fails, fresh_dir, ok, s, shared_real, vt};
use std::path::Path;

#[test]
fn labels_must_cover_the_videos_exactly_and_name_what_is_missing() {
    let d = fresh_dir("slip-labels");
    for v in ["a.avi", "b.avi"] {
        std::fs::write(d.join(v), b"").unwrap();
    }
    let labels = d.join("labels.csv");
    let out = d.join("slip.json");
    let fit = |labels_text: &str| {
        std::fs::write(&labels, labels_text).unwrap();
        fails(&vt(&[
            "slip",
            "fit",
            "-q",
            "--labels",
            s(&labels),
            "-o",
            s(&out),
            s(&d),
        ]))
    };
    let a = d.join("a.avi");
    let b = d.join("b.avi");
    let e = fit(&format!("video,slip\n{},1\n", s(&a)));
    assert!(e.contains("b.avi: no label"), "{e}");
    let e = fit(&format!(
        "video,slip\n{},1\n{},0\n{}/c.avi,1\n",
        s(&a),
        s(&b),
        s(&d)
    ));
    assert!(
        e.contains("labels.csv:4") && e.contains("c.avi is labelled but not among"),
        "{e}"
    );
    let e = fit(&format!("video,slip\n{},1\n{},yes\n", s(&a), s(&b)));
    assert!(
        e.contains("labels.csv:3") && e.contains("expected 0 or 1"),
        "{e}"
    );
    assert!(!out.exists(), "nothing written on an error");
    let e = fails(&vt(&["slip", "detect", "-q", "-o", s(&out), s(&labels)]));
    assert!(e.contains("labels.csv: expected a video"), "{e}");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn a_detector_fitted_on_real_grasps_is_read_back_and_run_per_video_and_per_frame() {
    let Some(root) = shared_real("gelsight_slip/videos") else {
        return;
    };
    let d = fresh_dir("slip-real");
    let slips = [
        "nylon_thread/exp_num_1/camera_0.avi",
        "marker_pen/exp_num_2/camera_0.avi",
    ];
    let sticks = [
        "blue_mug/exp_num_5/camera_0.avi",
        "blue_mug/exp_num_5/camera_2.avi",
    ];
    let mut labels = String::from("video,slip\n");
    for (v, y) in slips
        .iter()
        .map(|v| (v, 1))
        .chain(sticks.iter().map(|v| (v, 0)))
    {
        labels.push_str(&format!("{},{y}\n", s(&root.join(v))));
    }
    std::fs::write(d.join("labels.csv"), labels).unwrap();
    let det = d.join("slip.json");
    let videos: Vec<String> = slips
        .iter()
        .chain(&sticks)
        .map(|v| s(&root.join(v)).to_string())
        .collect();
    let mut args = vec!["slip", "fit", "-q", "--labels"];
    let l = d.join("labels.csv");
    args.extend([s(&l), "-o", s(&det)]);
    args.extend(videos.iter().map(String::as_str));
    let e = ok(&vt(&args));
    assert!(e.contains("fitted on 4 videos (2 slip)"), "{e}");
    let text = std::fs::read_to_string(&det).unwrap();
    assert!(text.contains("\"format\": \"visuotact-slip\""));
    let out = d.join("verdicts.csv");
    let mut args = vec!["slip", "detect", "-q", "--detector", s(&det), "-o", s(&out)];
    args.extend(videos.iter().map(String::as_str));
    ok(&vt(&args));
    let each = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<&str> = each.lines().collect();
    assert_eq!(rows[0], "video,slip,onset_s,score");
    assert_eq!(rows.len(), 5, "one row per video");
    for (r, v) in rows[1..].iter().zip(&videos) {
        let c: Vec<&str> = r.split(',').collect();
        assert_eq!(c[0], v);
        let score: f64 = c[3].parse().unwrap();
        assert!((0.0..=1.0).contains(&score));
        assert_eq!(
            c[2].is_empty(),
            c[1] == "0",
            "an onset exactly when slipping: {r}"
        );
    }
    grasps_sensors_fused(&det, &out, &videos, &rows);
    // The built-in detector, one row per frame: the 49 frames of the first video.
    ok(&vt(&[
        "slip",
        "detect",
        "-q",
        "--frames",
        "-o",
        s(&out),
        &videos[0],
    ]));
    let frames = std::fs::read_to_string(&out).unwrap();
    assert_eq!(frames.lines().count(), 50);
    assert!(frames
        .lines()
        .skip(1)
        .all(|l| ["stick", "incipient", "slip"].contains(&l.split(',').nth(3).unwrap())));
    std::fs::remove_dir_all(&d).unwrap();
}

/// A CSV file's header and rows, split at commas.
fn csv_cells(p: &std::path::Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(p).unwrap();
    let mut lines = text.lines();
    let split = |l: &str| l.split(',').map(String::from).collect::<Vec<_>>();
    let header = split(lines.next().unwrap());
    (header, lines.map(split).collect())
}

/// `extract --temporal` ends each row with the displacement field's dynamics: the signals
/// `slip detect --frames` gives for the same sensor and tracking (equal to its 5 decimals), on a
/// real GelSight Mini video.
#[test]
fn extract_in_order_writes_the_fields_dynamics_that_slip_detect_reads() {
    let Some(root) = shared_real("gelsight_mini") else {
        return;
    };
    let d = fresh_dir("slip-extract");
    let video = root.join("video_1.avi");
    let sensor = d.join("s.json");
    ok(&vt(&[
        "calibrate",
        "-q",
        s(&video),
        "--first",
        "5",
        "-o",
        s(&sensor),
    ]));
    let table = d.join("f.csv");
    ok(&vt(&[
        "extract",
        "-q",
        "--sensor",
        s(&sensor),
        "--temporal",
        "--features",
        "x,y",
        s(&video),
        "-o",
        s(&table),
    ]));
    let frames = d.join("frames.csv");
    ok(&vt(&[
        "slip",
        "detect",
        "-q",
        "--sensor",
        s(&sensor),
        "--temporal",
        "--frames",
        "-o",
        s(&frames),
        s(&video),
    ]));
    let (th, tr) = csv_cells(&table);
    let (sh, sr) = csv_cells(&frames);
    assert_eq!(tr.len(), sr.len());
    assert!(tr.len() >= 10, "{} frames", tr.len());
    let mut moved = 0.0f64;
    for n in visuotact_vision::field::FieldDynamics::NAMES {
        let (ti, si) = (
            th.iter()
                .position(|c| c == n)
                .unwrap_or_else(|| panic!("extract: no {n}")),
            sh.iter().position(|c| c == n).unwrap(),
        );
        for (t, r) in tr.iter().zip(&sr) {
            let (a, b): (f64, f64) = (t[ti].parse().unwrap(), r[si].parse().unwrap());
            assert!((a - b).abs() <= 6e-6, "{n}: {a} against {b}");
            moved = moved.max(a.abs());
        }
    }
    assert!(moved > 0.0, "the signals are all zero");
    // Frames not in order get no dynamics: the table ends with the markers and the flags.
    ok(&vt(&[
        "extract",
        "-q",
        "--sensor",
        s(&sensor),
        s(&video),
        "-o",
        s(&table),
    ]));
    let (th, _) = csv_cells(&table);
    assert!(!th.iter().any(|c| c == "shift_pitches"), "{th:?}");
    std::fs::remove_dir_all(&d).unwrap();
}

/// A simulated grasp past the friction limit: its labels hold the truth per frame (`slip_state`
/// 0 at rest and under the press, 1 from the first sideways frame, 2 from the frame at the
/// limit), and its frames folder is a sequence `slip detect --frames` reads, one row per frame.
#[test]
fn a_simulated_grasp_has_its_slip_in_the_truth_and_its_frames_are_a_sequence() {
    let d = fresh_dir("slip-sim");
    let session = d.join("grasp");
    ok(&vt(&[
        "simulate",
        "--sensor",
        "gelsight",
        "--protocol",
        "grasp-slip",
        "--touches",
        "72",
        "--seed",
        "3",
        "-o",
        s(&session),
    ]));
    let (header, rows) = csv_cells(&session.join("labels.csv"));
    assert_eq!(header.last().map(String::as_str), Some("slip_state"));
    let states: Vec<&str> = rows.iter().map(|r| r.last().unwrap().as_str()).collect();
    assert_eq!(states.len(), 72);
    // 10 at rest, a press over 10, the sideways load from frame 21, at the limit from a frame
    // the seed draws among 50–70.
    let at = states.iter().position(|s| *s == "2").unwrap_or(72);
    assert!((50..=70).contains(&at), "{states:?}");
    assert!(states[..21].iter().all(|s| *s == "0"), "{states:?}");
    assert!(states[21..at].iter().all(|s| *s == "1"), "{states:?}");
    assert!(states[at..].iter().all(|s| *s == "2"), "{states:?}");
    let out = d.join("frames.csv");
    ok(&vt(&[
        "slip",
        "detect",
        "-q",
        "--frames",
        "-o",
        s(&out),
        s(&session.join("frames")),
    ]));
    let (header, rows) = csv_cells(&out);
    assert_eq!(
        &header[..5],
        ["video", "frame", "timestamp_s", "state", "score"]
    );
    assert_eq!(rows.len(), 72);
    assert!(rows
        .iter()
        .all(|r| ["stick", "incipient", "slip"].contains(&r[3].as_str())));
    fails(&vt(&[
        "simulate",
        "--sensor",
        "iats",
        "--protocol",
        "grasp-slip",
        "-o",
        s(&d.join("no")),
    ]));
    std::fs::remove_dir_all(&d).unwrap();
}

/// `slip fit --cv-by object --cv-table`: one row per video with its held-out score and the
/// thirty statistics; `--grasp-per-folder` adds the held-out figure of each folder's sensors
/// fused.
#[test]
fn the_cross_validation_table_and_the_fused_grasps_are_written() {
    let Some(root) = shared_real("gelsight_slip/videos") else {
        return;
    };
    let d = fresh_dir("slip-cv-table");
    let videos = [
        ("nylon_thread/exp_num_1/camera_0.avi", 1, "nylon_thread"),
        ("marker_pen/exp_num_2/camera_0.avi", 1, "marker_pen"),
        ("blue_mug/exp_num_5/camera_0.avi", 0, "blue_mug"),
        ("blue_mug/exp_num_5/camera_2.avi", 0, "blue_mug"),
        (
            "artificial_strawberry/exp_num_1/camera_0.avi",
            0,
            "strawberry",
        ),
    ];
    let mut labels = String::from("video,slip,object\n");
    for (v, y, o) in &videos {
        labels.push_str(&format!("{},{y},{o}\n", s(&root.join(v))));
    }
    let l = d.join("labels.csv");
    std::fs::write(&l, labels).unwrap();
    let (det, table) = (d.join("slip.json"), d.join("cv.csv"));
    let paths: Vec<String> = videos
        .iter()
        .map(|(v, _, _)| s(&root.join(v)).to_string())
        .collect();
    let mut args = vec!["slip", "fit", "-q", "--labels", s(&l), "-o", s(&det)];
    args.extend([
        "--cv-by",
        "object",
        "--cv-table",
        s(&table),
        "--grasp-per-folder",
    ]);
    args.extend(paths.iter().map(String::as_str));
    let o = vt(&args);
    let e = ok(&o);
    let said = String::from_utf8_lossy(&o.stdout).to_string() + &e;
    assert!(
        said.contains("cross-validated by object (4 folds, 5 videos)"),
        "{said}"
    );
    assert!(
        said.contains("each folder's sensors fused (held out)"),
        "{said}"
    );
    let (header, rows) = csv_cells(&table);
    assert_eq!(header.len(), 5 + 33, "{header:?}");
    // Without --imprint the imprint's slide is not measured: its statistics are 0.
    let imprint: Vec<usize> = (0..header.len())
        .filter(|&j| header[j].ends_with("imprint_slide_pitches"))
        .collect();
    assert_eq!(imprint.len(), 3);
    assert_eq!(
        header[..5],
        ["video", "slip", "group", "frames", "held_out_score"]
    );
    assert_eq!(rows.len(), 5);
    for (r, (v, y, o)) in rows.iter().zip(&videos) {
        assert_eq!(r[0], s(&root.join(v)));
        assert_eq!((r[1].as_str(), r[2].as_str()), (&*y.to_string(), *o));
        assert!(r[3].parse::<usize>().unwrap() > 5);
        assert!((0.0..=1.0).contains(&r[4].parse::<f64>().unwrap()));
        assert!(imprint.iter().all(|&j| r[j].parse::<f64>().unwrap() == 0.0));
    }
    std::fs::remove_dir_all(&d).unwrap();
}

/// The two sensors of one grasp (blue_mug/exp_num_5, the last two videos) fused: one verdict for
/// both rows, its score their log-odds summed; the videos alone in their folders keep theirs.
fn grasps_sensors_fused(det: &Path, out: &Path, videos: &[String], rows: &[&str]) {
    let mut args = vec!["slip", "detect", "-q", "--grasp-per-folder", "--detector"];
    args.extend([s(det), "-o", s(out)]);
    args.extend(videos.iter().map(String::as_str));
    ok(&vt(&args));
    let fused = std::fs::read_to_string(out).unwrap();
    let fused: Vec<&str> = fused.lines().collect();
    assert_eq!(fused[1..3], rows[1..3]);
    let tail = |r: &str| r.split_once(',').unwrap().1.to_string();
    assert_eq!(tail(fused[3]), tail(fused[4]));
    let score = |r: &str| -> f64 { r.rsplit(',').next().unwrap().parse().unwrap() };
    let logit = |p: f64| (p / (1.0 - p)).ln();
    let want = 1.0 / (1.0 + (-(logit(score(rows[3])) + logit(score(rows[4])))).exp());
    assert!((score(fused[3]) - want).abs() < 2e-3, "{fused:?} {rows:?}");
}
