use super::*;

/// A 7 × 9 grid 30 px apart, as a GelSight Mini's dots.
fn grid() -> Vec<(f64, f64)> {
    (0..7)
        .flat_map(|r| (0..9).map(move |c| (20.0 + 30.0 * c as f64, 15.0 + 30.0 * r as f64)))
        .collect()
}

/// A seeded sequence of `n` frames: the object shaken sideways (every marker moving with it),
/// and with `slip` its imprint sliding from frame `n / 2`: the centre keeps following the
/// object while the rim is left behind by a growing share (partial slip spreading inwards).
fn sequence(n: usize, slip: bool, seed: u64) -> TrackedSequence {
    let mut state = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    let mut noise = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.1
    };
    let markers = grid();
    let (cx, cy) = (140.0, 105.0);
    let frames = (0..n)
        .map(|k| {
            let shake = 3.0 * (k as f64 * 0.6 + seed as f64).sin();
            let d = markers
                .iter()
                .map(|&(x, y)| {
                    let r = (x - cx).hypot(y - cy) / 120.0;
                    let sliding = slip && k >= n / 2;
                    let left_behind = if sliding {
                        let spread = (k - n / 2) as f64 / (n / 2) as f64;
                        (r - (1.0 - spread)).clamp(0.0, 1.0)
                    } else {
                        0.0
                    };
                    let drag = if sliding {
                        0.4 * (k - n / 2) as f64
                    } else {
                        0.0
                    };
                    Some((shake + drag * (1.0 - left_behind) + noise(), noise()))
                })
                .collect();
            TrackedFrame {
                timestamp_s: k as f64 / 25.0,
                id: k.to_string(),
                displacement_px: d,
                imprint_slide_px: (0.0, 0.0),
            }
        })
        .collect();
    TrackedSequence {
        markers_px: markers,
        pitch_px: 30.0,
        frames,
    }
}

#[test]
fn the_built_in_detector_reads_and_broken_files_are_named() {
    let d = SlipDetector::default();
    assert_eq!(d.inputs, SlipEvidence::names());
    assert_eq!(d.fitted_on, [300, 130]);
    assert_eq!(
        d.state_of(d.score(&[0.0; EVIDENCE_LEN])),
        SlipState::Stick,
        "a still field has not slipped"
    );
    let mut bad = d.clone();
    bad.weights.pop();
    let e = SlipDetector::from_json(&bad.to_json(), "x.json")
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("x.json: not a slip detector") && e.contains("33 inputs"),
        "{e}"
    );
    let mut bad = d.clone();
    bad.scale[3] = 0.0;
    assert!(SlipDetector::from_json(&bad.to_json(), "x").is_err());
    let mut bad = d.clone();
    bad.incipient_threshold = 0.9;
    assert!(SlipDetector::from_json(&bad.to_json(), "x")
        .unwrap_err()
        .to_string()
        .contains("incipient_threshold"));
    let e = SlipDetector::from_json("{\"format\": \"visuotact-model\"}", "m.json").unwrap_err();
    assert!(e.to_string().starts_with("m.json"), "{e}");
}

#[test]
fn evidence_of_steady_signals_is_their_value_with_no_rate() {
    let mut e = SlipEvidence::new(3);
    let f = FieldDynamics {
        shift_pitches: 0.5,
        curl: -0.2,
        ..FieldDynamics::default()
    };
    for _ in 0..10 {
        e.push(&f, 0.25);
    }
    let v = e.values();
    let g = |x: f64| (10.0 * x).ln_1p();
    assert!((v[0] - g(0.5)).abs() < 1e-12 && (v[11] - g(0.5)).abs() < 1e-12);
    assert!(
        (v[2] - g(0.2)).abs() < 1e-12,
        "the curl's size counts, not its sign"
    );
    assert!((v[10] - g(0.25)).abs() < 1e-12 && (v[21] - g(0.25)).abs() < 1e-12);
    assert!(v[22..].iter().all(|&r| r == 0.0));
    let names = SlipEvidence::names();
    assert_eq!(names[27], "max_rate_entropy_nats");
    assert_eq!(names[10], "max_imprint_slide_pitches");
}

#[test]
fn a_detector_file_without_the_imprint_reads_it_with_weight_zero() {
    let d = SlipDetector::default();
    assert!(
        !d.reads_imprint(),
        "the built-in detector reads the markers only"
    );
    // The same detector written as a file of thirty inputs, before the imprint was measured.
    let mut v: serde_json::Value = serde_json::from_str(&d.to_json()).unwrap();
    let keep: Vec<bool> = d
        .inputs
        .iter()
        .map(|i| !i.ends_with(IMPRINT_SIGNAL))
        .collect();
    for key in ["inputs", "center", "scale", "weights"] {
        let a = v[key].as_array_mut().unwrap();
        let mut k = keep.iter();
        a.retain(|_| *k.next().unwrap());
        assert_eq!(a.len(), 30);
    }
    assert_eq!(
        SlipDetector::from_json(&v.to_string(), "old.json").unwrap(),
        d
    );
}

/// Sequences whose slips also move the imprint against the markers from their middle on
/// (0.3 px per frame); the others' imprint sticks.
fn with_imprint(mut seq: TrackedSequence, slip: bool) -> TrackedSequence {
    let n = seq.frames.len();
    for f in &mut seq.frames[n / 2..] {
        f.imprint_slide_px = if slip { (0.3, 0.0) } else { (0.0, 0.0) };
    }
    seq
}

#[test]
fn a_detector_fitted_with_the_imprint_reads_it_and_one_fitted_without_does_not() {
    let s = SlipSettings::default();
    let (ev, y) = training(60, &s, None);
    assert!(!fit_detector(&ev, &y, &s).unwrap().reads_imprint());
    let ev: Vec<_> = (0..40u64)
        .map(|k| {
            let q = with_imprint(sequence(60, k % 2 == 0, k), k % 2 == 0);
            evidence_of(&q, &s, None)
        })
        .collect();
    let d = fit_detector(&ev, &y, &s).unwrap();
    assert!(d.reads_imprint());
    // The imprint's statistics: the slide over the lag (2 frames × 0.3 px) in pitches (30 px).
    let want = (10.0f64 * 0.6 / 30.0).ln_1p();
    assert!((ev[0].whole[10] - want).abs() < 1e-9 && ev[1].whole[10] == 0.0);
    let right = (100..110u64)
        .filter(|&k| {
            let slip = k % 2 == 0;
            detect(&with_imprint(sequence(60, slip, k), slip), &d).slip == slip
        })
        .count();
    assert!(right >= 9, "{right} of 10 held-out sequences right");
}

/// Forty training sequences of `n` frames, every second one slipping (labelled with `onset_s`
/// when given): their evidence and labels.
fn training(
    n: usize,
    s: &SlipSettings,
    onset_s: Option<f64>,
) -> (Vec<SequenceEvidence>, Vec<SlipTruth>) {
    (0..40u64)
        .map(|k| {
            let slip = k % 2 == 0;
            let onset_s = onset_s.filter(|_| slip);
            let t = SlipTruth { slip, onset_s };
            (evidence_of(&sequence(n, slip, k), s, onset_s), t)
        })
        .unzip()
}

#[test]
fn a_fitted_detector_tells_held_out_slips_from_shakes_and_dates_the_onset() {
    let s = SlipSettings::default();
    let (ev, y) = training(100, &s, None);
    let d = fit_detector(&ev, &y, &s).unwrap();
    assert_eq!(d.fitted_on, [40, 20]);
    assert_eq!(
        ev[0].prefixes.len(),
        3,
        "100 frames: beginnings at 25, 50, 75"
    );
    let mut right = 0;
    for k in 100..120 {
        let slip = k % 2 == 0;
        let v = detect(&sequence(100, slip, k), &d);
        right += usize::from(v.slip == slip);
        assert_eq!(v.frames.len(), 100);
        assert_eq!(v.score, v.frames[99].score);
        if let Some(t) = v.onset_s {
            assert!(slip, "seed {k}: a shake called slip at {t} s");
            // The slide starts at frame 50 (2.0 s).
            assert!(t >= 1.9, "seed {k}: onset {t} s before the slide");
            assert!(v
                .frames
                .iter()
                .skip_while(|f| f.timestamp_s < t)
                .all(|f| f.state == SlipState::Slip));
        }
    }
    assert!(right >= 18, "{right} of 20 held-out sequences right");
    let only_slips = vec![SlipTruth::from(true); ev.len()];
    assert!(matches!(
        fit_detector(&ev, &only_slips, &s),
        Err(SlipError::OneClass { .. })
    ));
}

/// Labelled with their onsets, slipping sequences teach the detector when a slip begins: their
/// beginnings before the onset count as no slip, the later ones as slip, and every frame within
/// [`ONSET_FRAMES`] of the onset counts. Held out, the onset is then found nearer the truth
/// (3.0 s) than by a detector fitted on the verdicts alone (mean error measured 0.096 s, 2.4
/// frames, against 0.98 s over ten slips; 0.45 s with the 1 s beginnings alone), and every
/// verdict is right.
#[test]
fn onsets_in_the_labels_date_the_slip_nearer_the_truth() {
    let s = SlipSettings::default();
    let (ev, plain) = training(150, &s, None);
    assert_eq!(ev[0].prefix_end_s, [0.96, 1.96, 2.96, 3.96, 4.96]);
    // A sequence's start is the evidence of its first frames alone.
    let mut first = sequence(150, true, 0);
    first.frames.truncate(START_FRAMES);
    assert_eq!(ev[0].start, evidence_of(&first, &s, None).whole);
    let (ev_timed, timed) = training(150, &s, Some(3.0));
    assert_eq!(ev_timed[0].near_onset.len(), 2 * ONSET_FRAMES);
    assert!(ev[0].near_onset.is_empty() && ev_timed[1].near_onset.is_empty());
    let (d_plain, d_timed) = (
        fit_detector(&ev, &plain, &s).unwrap(),
        fit_detector(&ev_timed, &timed, &s).unwrap(),
    );
    assert_ne!(d_timed.weights, d_plain.weights, "the onsets are used");
    let (mut off_plain, mut off_timed) = (0.0, 0.0);
    for k in 100..120 {
        let slip = k % 2 == 0;
        let q = sequence(150, slip, k);
        let (a, b) = (detect(&q, &d_plain), detect(&q, &d_timed));
        assert_eq!(b.slip, slip, "seed {k}");
        if slip {
            off_plain += (a.onset_s.unwrap_or(0.0) - 3.0).abs();
            off_timed += (b.onset_s.unwrap() - 3.0).abs();
        }
    }
    assert!(
        off_timed < 0.15 * 10.0 && off_timed < 0.2 * off_plain,
        "onset errors summed over 10 slips: {off_timed} s with onsets, {off_plain} s without"
    );
}

#[test]
fn verdicts_are_written_one_row_per_video_or_per_frame() {
    let q = sequence(20, false, 1);
    let v = detect(&q, &SlipDetector::default());
    let rows = [(PathBuf::from("a.avi"), &q, v)];
    let per_video = verdicts_csv(&rows, false);
    let lines: Vec<&str> = per_video.lines().collect();
    assert_eq!(lines[0], "video,slip,onset_s,score");
    assert_eq!(lines.len(), 2);
    assert!(lines[1].starts_with("a.avi,"));
    let per_frame = verdicts_csv(&rows, true);
    assert_eq!(per_frame.lines().count(), 21);
    assert_eq!(per_frame.lines().next().unwrap().split(',').count(), 15);
}

#[test]
fn sequences_are_videos_folders_of_images_or_folders_of_them() {
    let dir = std::env::temp_dir().join(format!("vt-seq-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("b")).unwrap();
    std::fs::create_dir_all(dir.join("session/frames")).unwrap();
    for f in [
        "b/2.avi",
        "1.mp4",
        "notes.txt",
        "session/frames/frame_000000.png",
        "session/frames/frame_000001.png",
    ] {
        std::fs::write(dir.join(f), b"").unwrap();
    }
    let got = sequences_in(std::slice::from_ref(&dir)).unwrap();
    assert_eq!(
        got,
        vec![
            dir.join("1.mp4"),
            dir.join("b/2.avi"),
            dir.join("session/frames")
        ]
    );
    let frames = dir.join("session/frames");
    assert_eq!(
        sequences_in(std::slice::from_ref(&frames)).unwrap(),
        vec![frames]
    );
    let e = sequences_in(&[dir.join("notes.txt")])
        .unwrap_err()
        .to_string();
    assert!(e.contains("notes.txt: expected a video"), "{e}");
    std::fs::create_dir_all(dir.join("empty")).unwrap();
    let e = sequences_in(&[dir.join("empty")]).unwrap_err().to_string();
    assert!(e.contains("folder has no video"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Leave-one-group-out on the synthetic grasps: four groups, every sequence answered, the
/// fitted detector at least as good as the naive threshold on the largest shift, and the start
/// alarms a count of the sequences.
#[test]
fn cross_validation_holds_each_group_out_and_counts_start_alarms() {
    let s = SlipSettings::default();
    let (ev, y) = training(100, &s, None);
    let groups: Vec<String> = (0..ev.len()).map(|k| format!("g{}", k % 4)).collect();
    let cv = cross_validate(&ev, &y, &groups, &s, None).unwrap();
    assert_eq!(cv.folds, 4);
    assert_eq!(cv.fitted.answered, 40);
    assert!(cv.fitted.balanced_accuracy >= 0.9, "{:?}", cv.fitted);
    assert!(cv.fitted.balanced_accuracy >= cv.largest_shift.balanced_accuracy);
    assert!((0.0..=1.0).contains(&cv.start_alarms));
    let alarms = 40.0 * cv.start_alarms;
    assert!(
        (alarms - alarms.round()).abs() < 1e-9,
        "{alarms}: a count of the 40"
    );
    assert!(cv.default.is_none());
}

/// A detector reads a sequence from the fewest frames it was fitted on: before that every
/// frame is `stick` with score 0 (the built-in one, fitted on beginnings of 25 frames and
/// more, called 71 % of the real no-slip grasps `slip` at their first frame), from it on the
/// score is the evidence's. A fit's shortest evidence sets it; files without it read 25, and
/// 0 is refused.
#[test]
fn a_detector_reads_a_sequence_from_the_fewest_frames_it_was_fitted_on() {
    let d = SlipDetector::default();
    assert_eq!(d.min_frames, PREFIX_EVERY);
    let q = sequence(60, true, 7);
    let mut m = SlipMonitor::new(d.clone(), &grid(), 30.0);
    let mut read = 0;
    for (k, f) in q.frames.iter().enumerate() {
        let live = m.update(&f.displacement_px, f.timestamp_s);
        let score = d.score(&m.evidence().values());
        if k + 1 < PREFIX_EVERY {
            assert_eq!(
                (live.state, live.score),
                (SlipState::Stick, 0.0),
                "frame {k}"
            );
        } else {
            assert_eq!((live.state, live.score), (d.state_of(score), score));
        }
        read += usize::from(score >= d.incipient_threshold && k + 1 < PREFIX_EVERY);
    }
    assert!(read > 0, "the evidence is kept from the first frame");
    let s = SlipSettings::default();
    let (ev, y) = training(100, &s, None);
    assert_eq!(fit_detector(&ev, &y, &s).unwrap().min_frames, PREFIX_EVERY);
    // A slip labelled at 0.4 s is taught from the frames 5 before it: from frame 6 on.
    let (ev, early) = training(100, &s, Some(0.4));
    assert_eq!(fit_detector(&ev, &early, &s).unwrap().min_frames, 6);
    let text = d
        .to_json()
        .replace("\"min_frames\": 25", "\"min_frames\": 0");
    assert!(SlipDetector::from_json(&text, "x.json").is_err());
    let without: String = d
        .to_json()
        .lines()
        .filter(|l| !l.contains("min_frames"))
        .collect::<Vec<_>>()
        .join("\n")
        .replace("],\n}", "]\n}");
    assert_eq!(SlipDetector::from_json(&without, "x.json").unwrap(), d);
}

/// Two sensors' scores of one grasp: equal evidence either way cancels, agreement
/// strengthens, one sensor alone is itself; the fused verdict runs to the shorter sequence and
/// takes the detector's states.
#[test]
fn a_grasps_sensors_add_their_log_odds() {
    assert!((fused_score([0.9, 0.1]) - 0.5).abs() < 1e-12);
    assert!((fused_score([0.7]) - 0.7).abs() < 1e-12);
    let both = fused_score([0.8, 0.8]);
    assert!((both - 16.0 / 17.0).abs() < 1e-12, "{both}");
    assert!(fused_score([0.4, 0.4]) < 0.4);
    let s = SlipSettings::default();
    let (ev, y) = training(100, &s, None);
    let d = fit_detector(&ev, &y, &s).unwrap();
    let (a, b) = (
        detect(&sequence(100, true, 200), &d),
        detect(&sequence(90, true, 201), &d),
    );
    let f = fuse(&[&a, &b], &d);
    assert_eq!(f.frames.len(), 90);
    for (k, fr) in f.frames.iter().enumerate() {
        let want = fused_score([a.frames[k].score, b.frames[k].score]);
        assert!((fr.score - want).abs() < 1e-12);
        assert_eq!(fr.state, d.state_of(want));
        assert_eq!(fr.timestamp_s, a.frames[k].timestamp_s);
    }
    assert_eq!(f.score, f.frames[89].score);
    assert_eq!(f.slip, f.frames[89].state == SlipState::Slip);
}

/// Held out by group, a grasp's two sensors fused: on synthetic grasps where each sensor alone
/// is noisy, the fused figure is at least the single sensors'.
#[test]
fn fused_held_out_scores_judge_each_grasp_once() {
    let s = SlipSettings::default();
    let (ev, y) = training(100, &s, None);
    let groups: Vec<String> = (0..ev.len()).map(|k| format!("g{}", k % 4)).collect();
    let cv = cross_validate(&ev, &y, &groups, &s, None).unwrap();
    // Sequences k and k + 4 share a group; pair them as one grasp's two sensors when their
    // labels agree, else alone.
    let grasp: Vec<usize> = (0..ev.len())
        .map(|k| {
            let partner = if k % 8 < 4 { k + 4 } else { k - 4 };
            if partner < ev.len() && y[partner].slip == y[k].slip {
                k.min(partner)
            } else {
                k
            }
        })
        .collect();
    let fused = fused_scores(&cv, &y, &grasp, 0.5);
    assert_eq!(fused.answered, cv.fitted.answered);
    let alone = fused_scores(&cv, &y, &(0..ev.len()).collect::<Vec<_>>(), 0.5);
    assert_eq!(alone, cv.fitted, "a grasp of one sensor is that sensor");
    assert!(fused.balanced_accuracy >= 0.9, "{fused:?}");
    assert!(
        fused.balanced_accuracy >= cv.fitted.balanced_accuracy,
        "{fused:?} {cv:?}"
    );
}

#[test]
fn a_grasp_is_a_folder_of_videos() {
    let v: Vec<PathBuf> = ["g1/c0.avi", "g1/c2.avi", "g2/c0.avi", "g1/c4.avi", "c.avi"]
        .iter()
        .map(PathBuf::from)
        .collect();
    assert_eq!(grasps_of(&v), [0, 0, 1, 0, 2]);
}
