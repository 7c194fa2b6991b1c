//! `visuotact slip`: labels matched to videos before anything is tracked, and on real GelSight
//! Mini grasps a fitted detector written, read back and run per video and per frame.

mod common;
use common::{fails, fresh_dir, ok, s, shared_real, vt};

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
    let rows = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<&str> = rows.lines().collect();
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
