//! `train`, `predict`, `eval` end to end on a simulated cone session, and their errors for bad
//! tables: a non-numeric cell (file, line, column named), a missing target column, a model used
//! with features it was not trained on, a half-written model never replacing a good one; an
//! extra input (the simulated pressure gauge) beside the marker features.

#![allow(
    clippy::too_many_lines,
    reason = "an end-to-end scenario reads top to bottom; split, its steps would scatter"
)]

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;
use common::*;

/// `visuotact train --targets force_n` from features `f` and labels `l` into `model`, with
/// `extra` arguments.
fn train(f: &Path, l: &Path, model: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "train",
        "--features",
        s(f),
        "--labels",
        s(l),
        "--targets",
        "force_n",
        "-o",
        s(model),
    ];
    args.extend_from_slice(extra);
    vt(&args)
}

/// `visuotact predict --model model -o out` with `extra` arguments (the inputs).
fn predict(model: &Path, out: &str, extra: &[&str]) -> Output {
    let mut args = vec!["predict", "--model", s(model), "-o", out];
    args.extend_from_slice(extra);
    vt(&args)
}

/// `visuotact eval --predictions p --labels l` with `extra` arguments.
fn eval(p: &Path, l: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["eval", "--predictions", s(p), "--labels", s(l)];
    args.extend_from_slice(extra);
    vt(&args)
}

/// A simulated 6 s cone press in a fresh folder `name`: calibrated (s.json) and extracted
/// (f.csv).
fn session(name: &str) -> PathBuf {
    let d = fresh_dir(name).join("session");
    ok(&vt(&[
        "simulate",
        "--sensor",
        "cone",
        "--protocol",
        "press",
        "--duration-s",
        "6",
        "--references",
        "5",
        "-o",
        s(&d),
    ]));
    ok(&vt(&[
        "calibrate",
        s(&d.join("reference")),
        "--preset",
        "cone",
        "--layout",
        "rings",
        "-o",
        s(&d.join("s.json")),
    ]));
    ok(&vt(&[
        "extract",
        "--sensor",
        s(&d.join("s.json")),
        s(&d.join("frames")),
        "-o",
        s(&d.join("f.csv")),
    ]));
    d
}

#[test]
fn train_predict_eval_and_bad_tables() {
    let d = session("train");
    let (f, l, m) = (d.join("f.csv"), d.join("labels.csv"), d.join("model.json"));
    let err = ok(&train(
        &f,
        &l,
        &m,
        &[
            "--hidden",
            "10",
            "--algorithm",
            "trainlm",
            "--sensor",
            s(&d.join("s.json")),
        ],
    ));
    assert!(
        err.contains("training 6 → 10 → 1 (81 weights, trainlm)"),
        "{err}"
    );
    assert!(err.contains("R train 0.99"), "{err}");
    assert!(
        err.contains("spread (<target>_std): the larger of the networks' disagreement and the held-out RMS error of the 30 nearest of"),
        "{err}"
    );
    let model: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&m).unwrap()).unwrap();
    assert_eq!(model["format"], "visuotact-model");
    assert_eq!(model["target_columns"][0], "force_n");
    assert_eq!(model["feature_columns"].as_array().unwrap().len(), 6);
    assert!(model["sensor"]["markers"].is_array());
    for subset in 0..3 {
        let r = model["training"]["r"][subset][0].as_f64().unwrap();
        assert!(r > 0.99 && r <= 1.0, "R of subset {subset}: {r}");
    }
    let p = d.join("p.csv");
    ok(&predict(&m, s(&p), &["--features", s(&f)]));
    // Straight from frames with the sensor file: the same estimates.
    let p2 = d.join("p2.csv");
    ok(&predict(
        &m,
        s(&p2),
        &["--sensor", s(&d.join("s.json")), s(&d.join("frames"))],
    ));
    assert_eq!(std::fs::read(&p).unwrap(), std::fs::read(&p2).unwrap());
    let plot = d.join("regression.svg");
    let o = eval(&p, &l, &["--json", "--plot", s(&plot)]);
    ok(&o);
    let ev: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let t = &ev["targets"][0];
    assert_eq!(t["target"], "force_n");
    assert_eq!(t["n"], 150);
    assert!(t["r"].as_f64().unwrap() > 0.99, "{t}");
    assert!(t["mean_abs"].as_f64().unwrap() < 0.5, "{t}");
    // trainlm held frames out: the spread beside each estimate is checked against the errors.
    let sp = &ev["spread"][0];
    assert_eq!(sp["n"], 150, "{ev}");
    assert!(sp["within_two"].as_f64().unwrap() > 0.5, "{sp}");
    let table = String::from_utf8(eval(&p, &l, &[]).stdout).unwrap();
    assert!(
        table.contains("the stated spread (<target>_std) against the errors"),
        "{table}"
    );
    let svg = std::fs::read_to_string(&plot).unwrap();
    assert!(svg.contains("force_n: R = ") && svg.matches("<circle").count() == 150);

    // A sweep over sizes with repeats: table, best model, plot.
    let sw = d.join("sweep");
    let err = ok(&vt(&[
        "sweep",
        "--features",
        s(&f),
        "--labels",
        s(&l),
        "--targets",
        "force_n",
        "--hidden",
        "1..4",
        "--repeats",
        "3",
        "--keep",
        "3",
        "-o",
        s(&sw),
    ]));
    for k in 1..=3 {
        assert!(sw.join(format!("ensemble/model_{k}.json")).is_file());
    }
    assert!(!sw.join("ensemble/model_4.json").exists());
    assert!(err.contains("12 trainings of 4 architectures"), "{err}");
    let table = std::fs::read_to_string(sw.join("sweep.csv")).unwrap();
    assert_eq!(table.lines().count(), 5);
    assert!(table.lines().nth(1).unwrap().starts_with("1,3,"));
    let best: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(sw.join("best_model.json")).unwrap())
            .unwrap();
    assert_eq!(best["format"], "visuotact-model");
    let svg = std::fs::read_to_string(sw.join("performance.svg")).unwrap();
    assert!(
        svg.starts_with("<svg")
            && svg.contains("hidden neurons")
            && svg.matches("<circle").count() >= 4
    );
    let png = visuotact_io::frames::read_image(&sw.join("performance.png")).unwrap();
    assert_eq!((png.width(), png.height()), (800, 500));
    sharded_sweep_equals_the_single_machine(&d, &f, &l, &sw);

    // A non-numeric cell.
    let text = std::fs::read_to_string(&f).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let cells: Vec<&str> = lines[3].split(',').collect();
    let mut bad_cells: Vec<String> = cells.iter().map(|c| c.to_string()).collect();
    bad_cells[8] = "abc".into();
    lines[3] = bad_cells.join(",");
    let bad = d.join("bad.csv");
    std::fs::write(&bad, lines.join("\n")).unwrap();
    let before = std::fs::read(&m).unwrap();
    let err = fails(&train(&bad, &l, &m, &[]));
    assert!(
        err.contains("bad.csv: line 4, column `m000_dy_px`: \"abc\" is not a number"),
        "{err}"
    );
    assert_eq!(
        std::fs::read(&m).unwrap(),
        before,
        "a failed training leaves the model alone"
    );
    // A target that is not in the labels.
    let err = fails(&vt(&[
        "train",
        "--features",
        s(&f),
        "--labels",
        s(&l),
        "--targets",
        "torque",
        "-o",
        s(&d.join("x.json")),
    ]));
    assert!(err.contains("no target column `torque`"), "{err}");
    // A model used on other features.
    let other = d.join("other.csv");
    std::fs::write(&other, "frame,m000_dx_px\nframe_000000.png,1.0\n").unwrap();
    let err = fails(&predict(&m, "-", &["--features", s(&other)]));
    assert!(
        err.contains("the model") && err.contains("was trained on other inputs"),
        "{err}"
    );
    // Labels with no matching frames.
    let nolab = d.join("nolab.csv");
    std::fs::write(&nolab, "frame,force_n\nnot_a_frame.png,1.0\n").unwrap();
    let err = fails(&train(&f, &nolab, &d.join("y.json"), &[]));
    assert!(err.contains("too few to train"), "{err}");
}

#[test]
fn trainbr_on_principal_components() {
    let d = session("trainbr");
    let (f, l, m) = (d.join("f.csv"), d.join("labels.csv"), d.join("br.json"));
    let err = ok(&train(
        &f,
        &l,
        &m,
        &[
            "--hidden",
            "8",
            "--algorithm",
            "trainbr",
            "--components",
            "3",
        ],
    ));
    assert!(err.contains("trained (trainbr)"), "{err}");
    assert!(err.contains("effective parameters γ"), "{err}");
    let model: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&m).unwrap()).unwrap();
    assert_eq!(model["training"]["algorithm"], "trainbr");
    // Every frame trains: no validation or test figures, and no NaN written as null.
    assert_eq!(model["training"]["samples"][1], 0);
    assert!(model["training"]["mse"][1].as_array().unwrap().is_empty());
    let gamma = model["training"]["evidence"]["gamma"].as_f64().unwrap();
    let weights = model["net"]["params"].as_array().unwrap().len();
    assert_eq!(weights, 8 * 4 + 9, "3 components → 8 → 1");
    assert!(
        gamma > 1.0 && gamma < weights as f64,
        "γ {gamma} of {weights}"
    );
    let proj = &model["projection"];
    assert_eq!(proj["components"].as_array().unwrap().len(), 3);
    let explained = proj["explained"].as_f64().unwrap();
    assert!(explained > 0.8 && explained <= 1.0, "{proj}");
    // The model reads the 6 raw features and predicts as well as trainlm does here.
    // An ensemble of 5 by default: 4 further networks, and the spread in the predictions.
    assert_eq!(model["members"].as_array().unwrap().len(), 4);
    let p = d.join("p.csv");
    ok(&predict(&m, s(&p), &["--features", s(&f)]));
    let text = std::fs::read_to_string(&p).unwrap();
    assert!(
        text.starts_with("frame,force_n,force_n_std,flags"),
        "{text}"
    );
    let spreads: Vec<f64> = text
        .lines()
        .skip(1)
        .map(|r| r.split(',').nth(2).unwrap().parse().unwrap())
        .collect();
    assert!(spreads.iter().all(|v| v.is_finite() && *v >= 0.0));
    assert!(spreads.iter().any(|v| *v > 0.0));
    let o = eval(&p, &l, &["--json"]);
    ok(&o);
    let ev: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let t = &ev["targets"][0];
    assert_eq!(t["n"], 150);
    assert!(t["r"].as_f64().unwrap() > 0.99, "{t}");
    // Asking for more components than inputs is refused with the reason.
    let err = fails(&train(&f, &l, &d.join("bad.json"), &["--components", "9"]));
    assert!(
        err.contains("--components: asked for 9 components of 6 inputs"),
        "{err}"
    );
}

/// Blanks every cell of the listed markers in the given data rows of a feature CSV.
fn blank_markers(src: &Path, dst: &Path, rows: std::ops::Range<usize>, markers: &[usize]) {
    let text = std::fs::read_to_string(src).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let header: Vec<&str> = lines[0].split(',').collect();
    let cols: Vec<usize> = header
        .iter()
        .enumerate()
        .filter(|(_, h)| markers.iter().any(|m| h.starts_with(&format!("m{m:03}_"))))
        .map(|(i, _)| i)
        .collect();
    for line in &mut lines[1 + rows.start..1 + rows.end] {
        let mut cells: Vec<String> = line.split(',').map(str::to_string).collect();
        for &c in &cols {
            cells[c].clear();
        }
        *line = cells.join(",");
    }
    std::fs::write(dst, lines.join("\n") + "\n").unwrap();
}

#[test]
fn the_field_summary_passes_by_the_projection() {
    let (d, sensor, f) = iats_features(&fresh_dir("field"), "60", "7");
    let l = d.join("labels.csv");
    let header = std::fs::read_to_string(&f).unwrap();
    let header = header.lines().next().unwrap();
    assert!(
        header.ends_with(
            "field_rms_px,field_max_px,field_top_px,field_cx_px,field_cy_px,field_spread_px,flags"
        ),
        "{header}"
    );
    let t = [
        "--targets",
        "x_mm,y_mm,depth_mm",
        "--hidden",
        "6",
        "--ensemble",
        "1",
    ];
    let tr = |feat: &Path, out: &Path, extra: &[&str]| -> Output {
        let head = [
            "train",
            "--features",
            s(feat),
            "--labels",
            s(&l),
            "-o",
            s(out),
        ];
        vt(&[&head[..], &t[..], extra].concat())
    };
    let model = |p: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    // Default (over 20 markers' features): the field summary with the markers' features, or
    // alone, whichever cross-validation prefers; the scores are in the model file.
    let chosen = d.join("chosen.json");
    let err = ok(&tr(&f, &chosen, &[]));
    assert!(
        err.contains("choosing the inputs by 5-fold cross-validation"),
        "{err}"
    );
    let selection = model(&chosen)["training"]["selection"].clone();
    let scores = selection.as_array().unwrap();
    assert_eq!(scores.len(), 2, "{selection}");
    let picked: Vec<usize> = (0..2)
        .filter(|&i| scores[i]["chosen"].as_bool().unwrap())
        .collect();
    assert_eq!(picked.len(), 1, "{selection}");
    let (won, lost) = (&scores[picked[0]], &scores[1 - picked[0]]);
    assert!(scores.iter().all(|s| s["folds"] == 5), "{selection}");
    assert!(
        won["error"].as_f64() <= lost["error"].as_f64(),
        "{selection}"
    );
    assert!(
        err.contains(&format!("chose {}", won["inputs"].as_str().unwrap())),
        "{err}"
    );
    let width = model(&chosen)["feature_columns"].as_array().unwrap().len();
    assert_eq!(width, if picked[0] == 0 { 357 } else { 6 }, "{selection}");
    // --field yes: the markers' 351 as 10 components, the 6 field columns beside them as
    // they are.
    let m = d.join("m.json");
    let err = ok(&tr(&f, &m, &["--field", "yes"]));
    assert!(!err.contains("cross-validation"), "{err}");
    assert!(
        err.contains(
            "357 inputs (the markers' 351 as 10 principal components, 6 more as they are) → 6 → 3"
        ),
        "{err}"
    );
    let mv = model(&m);
    assert_eq!(mv["passthrough"], 6);
    assert_eq!(mv["net"]["sizes"][0], 16);
    assert_eq!(mv["feature_columns"][351], "field_rms_px");
    assert_eq!(mv["projection"]["mean"].as_array().unwrap().len(), 351);
    // --field no: the markers' features alone; --field only: the summary alone.
    let no = d.join("no.json");
    ok(&tr(&f, &no, &["--field", "no"]));
    assert_eq!(model(&no)["net"]["sizes"][0], 10);
    assert!(model(&no).get("passthrough").is_none());
    let only = d.join("only.json");
    ok(&tr(&f, &only, &["--field", "only"]));
    let ov = model(&only);
    assert_eq!(ov["net"]["sizes"][0], 6);
    assert_eq!(ov["feature_columns"].as_array().unwrap().len(), 6);
    // Each model estimates from the table and from the frames alike.
    for mm in [&m, &only] {
        let (pt, pf) = (d.join("pt.csv"), d.join("pf.csv"));
        ok(&predict(mm, s(&pt), &["--features", s(&f)]));
        ok(&predict(
            mm,
            s(&pf),
            &["--sensor", s(&sensor), s(&d.join("frames"))],
        ));
        let (a, b) = (
            std::fs::read_to_string(&pt).unwrap(),
            std::fs::read_to_string(&pf).unwrap(),
        );
        assert_eq!(a.lines().count(), 61);
        for (ra, rb) in a.lines().zip(b.lines()).skip(1) {
            let va: Vec<&str> = ra.split(',').collect();
            let vb: Vec<&str> = rb.split(',').collect();
            for j in 1..4 {
                let (x, y): (f64, f64) = (va[j].parse().unwrap(), vb[j].parse().unwrap());
                assert!((x - y).abs() < 1e-6, "{ra} / {rb}");
            }
        }
    }
    assert!(model(&only)
        .get("training")
        .unwrap()
        .get("selection")
        .is_none());
    // A table without the field columns (an older extraction): the markers' features, said.
    let old = d.join("old.csv");
    let text = std::fs::read_to_string(&f).unwrap();
    let cut: String = text
        .lines()
        .map(|line| {
            let c: Vec<&str> = line.split(',').collect();
            let n = c.len();
            [&c[..n - 7], &c[n - 1..]].concat().join(",") + "\n"
        })
        .collect();
    std::fs::write(&old, cut).unwrap();
    let err = ok(&tr(&old, &d.join("o.json"), &[]));
    assert!(err.contains("has no field-summary columns"), "{err}");
    assert!(
        err.contains("351 inputs (the markers' 351 as 10 principal components) → 6 → 3"),
        "{err}"
    );
    let err = fails(&tr(&old, &d.join("o.json"), &["--field", "only"]));
    assert!(
        err.contains("no field-summary columns (field_rms_px …)"),
        "{err}"
    );
}

#[test]
fn lost_markers_are_filled_from_the_markers_found() {
    let (d, _, f) = iats_features(&fresh_dir("filling"), "120", "5");
    // Frames 0–19 lose markers 10 and 50 (3 cells each); frame 20 loses 40 markers.
    let lost = d.join("lost.csv");
    blank_markers(&f, &lost, 0..20, &[10, 50]);
    let half = d.join("half.csv");
    blank_markers(&lost, &half, 20..21, &(0..40).collect::<Vec<_>>());
    let l = d.join("labels.csv");
    let args = |feat: &Path, model: &Path| -> Vec<String> {
        [
            "train",
            "--features",
            s(feat),
            "--labels",
            s(&l),
            "--targets",
            "x_mm,y_mm,depth_mm",
            "--hidden",
            "10",
            "--field",
            "yes",
            "-o",
            s(model),
        ]
        .map(str::to_string)
        .to_vec()
    };
    let m = d.join("m.json");
    let a = args(&lost, &m);
    let err = ok(&vt(&a.iter().map(String::as_str).collect::<Vec<_>>()));
    assert!(
        err.contains(
            "357 inputs (the markers' 351 as 10 principal components, 6 more as they are) → 10 → 3"
        ),
        "{err}"
    );
    // 20 frames lose 6 cells each, besides what the tracker itself could not find.
    let count = |text: &str, after: &str| -> usize {
        let at = text
            .find(after)
            .unwrap_or_else(|| panic!("{after:?} in {text}"));
        let before = text[..at].split_whitespace().last().unwrap();
        before.trim_start_matches('(').parse().unwrap()
    };
    assert!(count(&err, "frames with lost markers kept") >= 20, "{err}");
    let cells = err
        .split("kept: ")
        .nth(1)
        .unwrap()
        .split(' ')
        .next()
        .unwrap();
    assert!(cells.parse::<usize>().unwrap() >= 120, "{err}");
    // Every frame but the one missing 40 markers is estimated; the filled ones say so and
    // stay close to the estimates from their complete rows.
    let (pc, pl) = (d.join("pc.csv"), d.join("pl.csv"));
    ok(&predict(&m, s(&pc), &["--features", s(&f)]));
    let err = ok(&predict(&m, s(&pl), &["--features", s(&half)]));
    assert!(err.contains("119 estimates ("), "{err}");
    assert!(count(&err, "with lost markers filled") >= 19, "{err}");
    assert!(err.contains("1 frames without"), "{err}");
    let rows = |p: &Path| -> Vec<Vec<String>> {
        std::fs::read_to_string(p)
            .unwrap()
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(str::to_string).collect())
            .collect()
    };
    let (complete, filled) = (rows(&pc), rows(&pl));
    for k in 0..19 {
        assert!(
            filled[k].last().unwrap().starts_with("filled "),
            "{:?}",
            filled[k]
        );
        let v = |r: &[String], j: usize| r[j].parse::<f64>().unwrap();
        let dd =
            (v(&filled[k], 1) - v(&complete[k], 1)).hypot(v(&filled[k], 2) - v(&complete[k], 2));
        assert!(dd < 0.5, "frame {k}: contact moved {dd} mm by the filling");
    }
    assert!(
        filled[20]
            .last()
            .unwrap()
            .contains("of 357 inputs missing (over a quarter)"),
        "{:?}",
        filled[20]
    );
    assert!(filled[20][1].is_empty());
    // Without components nothing fills them: the frame is named.
    let mut a = args(&lost, &d.join("raw.json"));
    a.extend(["--components".to_string(), "0".to_string()]);
    let err = fails(&vt(&a.iter().map(String::as_str).collect::<Vec<_>>()));
    assert!(err.contains("line 2, frame frame_000000.png"), "{err}");
}

#[test]
fn gauge_reading_as_an_extra_input() {
    let d = session("train-gauge");
    let (f, l, m) = (d.join("f.csv"), d.join("labels.csv"), d.join("model.json"));
    let labels = std::fs::read_to_string(&l).unwrap();
    assert!(labels.starts_with("frame,force_n,fx_n,fy_n,fz_n,pressure_kpa,gauge_kpa\n"));
    let train =
        |extra: &[&str], model: &Path| train(&f, &l, model, &[&["--hidden", "8"], extra].concat());
    // The gauge is not in the feature table: without --readings the error says where to look.
    let err = fails(&train(&["--inputs", "gauge_kpa"], &m));
    assert!(
        err.contains("f.csv: no column `gauge_kpa` (give the table that has it with --readings)"),
        "{err}"
    );
    let err = fails(&train(&["--inputs", "gauge", "--readings", s(&l)], &m));
    assert!(err.contains("no column `gauge` nor in"), "{err}");
    let err = fails(&train(&["--inputs", "m000_dx_px"], &m));
    assert!(err.contains("marker features are inputs already"), "{err}");
    let err = ok(&train(&["--inputs", "gauge_kpa", "--readings", s(&l)], &m));
    assert!(err.contains("training 7 → 8 → 1"), "{err}");
    let model: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&m).unwrap()).unwrap();
    let cols = model["feature_columns"].as_array().unwrap();
    assert_eq!((cols.len(), cols[6].as_str()), (7, Some("gauge_kpa")));

    // Estimates need the reading too; frames alone cannot give it.
    let err = fails(&predict(&m, "-", &["--features", s(&f)]));
    assert!(err.contains("no column `gauge_kpa`"), "{err}");
    let err = fails(&predict(
        &m,
        "-",
        &["--sensor", s(&d.join("s.json")), s(&d.join("frames"))],
    ));
    assert!(
        err.contains("needs the input `gauge_kpa`, which is not a marker feature"),
        "{err}"
    );
    let err = fails(&vt(&[
        "run",
        "--source",
        "sim:cone",
        "--sensor",
        s(&d.join("s.json")),
        "--model",
        s(&m),
        "--duration-s",
        "1",
    ]));
    assert!(err.contains("needs the input `gauge_kpa`"), "{err}");

    // A frame whose reading is missing: no estimate for it rather than a wrong one; training
    // names the frame unless told to leave such frames out.
    let mut lines: Vec<&str> = labels.lines().collect();
    let gone = lines.remove(11);
    let frame = gone.split(',').next().unwrap().to_string();
    let partial = d.join("partial_readings.csv");
    std::fs::write(&partial, lines.join("\n") + "\n").unwrap();
    let err = fails(&train(
        &["--inputs", "gauge_kpa", "--readings", s(&partial)],
        &d.join("x.json"),
    ));
    assert!(
        err.contains(&format!("frame {frame}, column `gauge_kpa`: missing value (no reading `gauge_kpa` for this frame)")),
        "{err}"
    );
    let p = d.join("p.csv");
    let err = ok(&predict(
        &m,
        s(&p),
        &["--features", s(&f), "--readings", s(&partial)],
    ));
    assert!(err.contains("149 estimates, 1 frames without"), "{err}");
    let pred = std::fs::read_to_string(&p).unwrap();
    let row = pred.lines().find(|r| r.starts_with(&frame)).unwrap();
    assert!(row.ends_with("missing reading"), "{row}");

    // With every reading: the estimates are close to the truth.
    let o = predict(&m, s(&p), &["--features", s(&f), "--readings", s(&l)]);
    ok(&o);
    let o = eval(&p, &l, &["--json"]);
    ok(&o);
    let ev: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let t = &ev["targets"][0];
    assert_eq!(t["n"], 150);
    assert!(t["r"].as_f64().unwrap() > 0.99, "{t}");

    // Replay over the session's frames takes the gauge from its labels.csv: the same
    // estimates as from the feature table.
    let r = d.join("replay.csv");
    let replay = |input: &str, extra: &[&str]| {
        let sensor = d.join("s.json");
        let mut args = vec![
            "replay",
            "--model",
            s(&m),
            "--sensor",
            s(&sensor),
            input,
            "-o",
            s(&r),
        ];
        args.extend_from_slice(extra);
        vt(&args)
    };
    let err = ok(&replay(s(&d), &[]));
    assert!(err.contains("0 without an estimate"), "{err}");
    assert_eq!(std::fs::read(&r).unwrap(), std::fs::read(&p).unwrap());
    // With a readings table that lacks a frame, that frame has no estimate.
    let err = ok(&replay(s(&d), &["--readings", s(&partial)]));
    assert!(err.contains("1 without an estimate"), "{err}");
    // A table without the input, or a video with no table at all: clear errors.
    let err = fails(&replay(s(&d), &["--readings", s(&f)]));
    assert!(
        err.contains("f.csv: no column `gauge_kpa`, an input of the model"),
        "{err}"
    );
    let err = fails(&replay(s(&d.join("frames")), &[]));
    assert!(
        err.contains("needs gauge_kpa besides the marker features: give --readings"),
        "{err}"
    );
}

#[test]
fn contact_map_of_literal_tables() {
    let d = fresh_dir("contact-map");
    let (p, l) = (d.join("p.csv"), d.join("l.csv"));
    std::fs::write(
        &p,
        "frame,x_mm,y_mm,depth_mm,flags\na,1,2,1,\nb,10,5,2.5,\nc,,,,missing features\n",
    )
    .unwrap();
    std::fs::write(&l, "frame,x_mm,y_mm,depth_mm\na,1,1,1\nb,14,8,3\nc,3,3,3\n").unwrap();
    let map = d.join("map.svg");
    let o = eval(&p, &l, &["--map", s(&map)]);
    ok(&o);
    // D: 1 mm and 5 mm (a 3-4-5 triangle); the frame without an estimate is not drawn.
    assert!(String::from_utf8_lossy(&o.stdout)
        .contains("distance D (x, y): mean 3.000 mm, max 5.000 mm"));
    let svg = std::fs::read_to_string(&map).unwrap();
    assert!(
        svg.contains("D mean 3.000 mm") && svg.contains("radius ∝ depth"),
        "{svg}"
    );
    assert_eq!(
        svg.matches("<circle").count(),
        4,
        "two touches, actual and estimate"
    );
    // The same evaluation as one HTML page: the error table, both figures inline.
    let report = d.join("report.html");
    ok(&eval(&p, &l, &["--report", s(&report)]));
    let html = std::fs::read_to_string(&report).unwrap();
    assert!(html.contains("<td>x_mm</td><td>2</td>"), "{html}");
    assert!(html.contains("Contact distance D (x, y): mean 3.000 mm, max 5.000 mm."));
    assert_eq!(
        html.matches("<svg").count(),
        2,
        "regression plot and contact map"
    );
    assert!(!html.contains("src=") && !html.contains("href="));
    assert!(!html.contains("stated spread"), "no <target>_std column");
    // A spread beside the estimates is checked against the errors, printed and in the page.
    let (p2, l2) = (d.join("p2.csv"), d.join("l2.csv"));
    std::fs::write(
        &p2,
        "frame,force_n,force_n_std\na,1,0.5\nb,2,0.5\nc,3,2\nd,0,0.1\n",
    )
    .unwrap();
    std::fs::write(&l2, "frame,force_n\na,1.2\nb,2\nc,0\nd,0.5\n").unwrap();
    let o = eval(&p2, &l2, &["--report", s(&report)]);
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    let row = out
        .lines()
        .skip_while(|l| !l.starts_with("the stated spread"))
        .find(|l| l.starts_with("force_n "))
        .unwrap_or_default();
    let cells: Vec<&str> = row.split_whitespace().collect();
    // Within one spread: a and b; within two: c too (3 off at 2).
    assert_eq!(cells[..4], ["force_n", "0.7750", "50.0", "75.0"], "{out}");
    let html = std::fs::read_to_string(&report).unwrap();
    assert!(
        html.contains("stated spread")
            && html.contains("<td>force_n</td><td>0.7750</td><td>50.0</td><td>75.0</td>"),
        "{html}"
    );
    // Without positions there is nothing to map.
    std::fs::write(&p, "frame,force_n\na,1\n").unwrap();
    std::fs::write(&l, "frame,force_n\na,1.2\n").unwrap();
    let err = fails(&eval(&p, &l, &["--map", s(&map)]));
    assert!(
        err.contains("--map needs contact positions: columns x_mm and y_mm"),
        "{err}"
    );
}

/// The sweep of `sw` again in three shards merged, and through the SLURM scripts (their bodies
/// run here by bash with the array index set, as SLURM would): the same sweep.csv and best
/// model, byte for byte.
fn sharded_sweep_equals_the_single_machine(d: &Path, f: &Path, l: &Path, sw: &Path) {
    let common = [
        "sweep",
        "--features",
        s(f),
        "--labels",
        s(l),
        "--targets",
        "force_n",
        "--hidden",
        "1..4",
        "--repeats",
        "3",
    ];
    let parts = d.join("parts");
    for k in 1..=3 {
        let shard = format!("{k}/3");
        let mut a = common.to_vec();
        a.extend(["--shard", &shard, "-o", s(&parts)]);
        let err = ok(&vt(&a));
        assert!(err.contains(&format!("shard {k}/3: 4 trainings")), "{err}");
    }
    let merged = d.join("merged");
    let p = |k: usize| parts.join(format!("part-{k}-of-3.json"));
    let (p1, p2, p3) = (p(1), p(2), p(3));
    ok(&vt(&[
        "sweep",
        "merge",
        s(&p3),
        s(&p1),
        s(&p2),
        "-o",
        s(&merged),
        "--keep",
        "3",
    ]));
    let same = |a: &Path, b: &Path, name: &str| {
        assert_eq!(
            std::fs::read(a.join(name)).unwrap(),
            std::fs::read(b.join(name)).unwrap(),
            "{name}"
        );
    };
    for name in ["sweep.csv", "best_model.json", "ensemble/model_3.json"] {
        same(sw, &merged, name);
    }
    let err = fails(&vt(&[
        "sweep",
        "merge",
        s(&p1),
        s(&p2),
        "-o",
        s(&d.join("m2")),
    ]));
    assert!(err.contains("shards missing: 3/3"), "{err}");

    let slurm = d.join("slurm");
    let mut a = common.to_vec();
    a.extend([
        "--keep",
        "3",
        "--slurm",
        "2",
        "--slurm-cpus",
        "1",
        "-o",
        s(&slurm),
    ]);
    ok(&vt(&a));
    for name in ["sweep.sbatch", "merge.sbatch", "submit.sh"] {
        let o = std::process::Command::new("bash")
            .args(["-n", s(&slurm.join(name))])
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    let text = std::fs::read_to_string(slurm.join("sweep.sbatch")).unwrap();
    assert!(
        text.contains("#SBATCH --array=1-2") && !text.contains("--slurm"),
        "{text}"
    );
    for k in ["1", "2"] {
        let o = std::process::Command::new("bash")
            .arg(slurm.join("sweep.sbatch"))
            .env("SLURM_ARRAY_TASK_ID", k)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let o = std::process::Command::new("bash")
        .arg(slurm.join("merge.sbatch"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for name in ["sweep.csv", "best_model.json"] {
        same(sw, &slurm, name);
    }

    // A two-layer sweep also draws the surface of mean test MSE over both sizes.
    let two = d.join("two_layers");
    let mut a = common.to_vec();
    a[8] = "1..2x1..3";
    a[10] = "1";
    a.extend(["-o", s(&two)]);
    let err = ok(&vt(&a));
    assert!(err.contains("surface.svg, surface.png"), "{err}");
    let svg = std::fs::read_to_string(two.join("surface.svg")).unwrap();
    assert!(
        svg.contains("second hidden layer") && svg.contains("<circle"),
        "{svg}"
    );
    let png = visuotact_io::frames::read_image(&two.join("surface.png")).unwrap();
    assert_eq!((png.width(), png.height()), (760, 640));
    assert!(
        !sw.join("surface.svg").exists(),
        "one-layer sweeps have no surface"
    );
}

/// `calibrate --pitch-mm`: the sensor file holds the scale (pitch mm / pitch px), `extract`
/// writes each length in millimetres beside the pixels (× scale, areas × scale²), `train`
/// trains on the millimetres (the model's inputs are named so), `predict` from frames
/// estimates with that sensor, and a sensor without a scale is refused naming `--pitch-mm`.
#[test]
fn a_pitch_in_mm_gives_features_and_models_in_millimetres() {
    let d = fresh_dir("pitch-mm");
    let (session, sensor_px, _) = iats_features(&d, "40", "5");
    let sensor = d.join("sensor-mm.json");
    let said = ok(&vt(&[
        "calibrate",
        s(&session.join("reference")),
        "--pitch-mm",
        "5",
        "-o",
        s(&sensor),
    ]));
    assert!(said.contains("scale: "), "{said}");
    let cal: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&sensor).unwrap()).unwrap();
    let scale = cal["scale"]["mm_per_px"].as_f64().unwrap();
    assert!((scale * cal["pitch_px"].as_f64().unwrap() - 5.0).abs() < 1e-9);
    let bad = fails(&vt(&[
        "calibrate",
        s(&session.join("reference")),
        "--pitch-mm=-1",
        "-o",
        s(&d.join("never.json")),
    ]));
    assert!(
        bad.contains("--pitch-mm") && bad.contains("positive"),
        "{bad}"
    );
    assert!(!d.join("never.json").exists());

    let f = d.join("f-mm.csv");
    ok(&vt(&[
        "extract",
        "--sensor",
        s(&sensor),
        s(&session.join("frames")),
        "-o",
        s(&f),
    ]));
    let text = std::fs::read_to_string(&f).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
    let mut checked = 0;
    for line in lines {
        let cells: Vec<&str> = line.split(',').collect();
        for (px, mm, k) in [
            ("m060_dx_px", "m060_dx_mm", scale),
            ("m060_dy_px", "m060_dy_mm", scale),
            ("m060_darea_px", "m060_darea_mm2", scale * scale),
            ("field_rms_px", "field_rms_mm", scale),
        ] {
            let (a, b) = (cells[col(px)], cells[col(mm)]);
            if a.is_empty() {
                assert!(b.is_empty(), "{px} empty but {mm} {b}");
                continue;
            }
            let (a, b): (f64, f64) = (a.parse().unwrap(), b.parse().unwrap());
            assert!(
                (b - a * k).abs() <= 1e-9 * (1.0 + b.abs()),
                "{px} {a} → {mm} {b}"
            );
            checked += 1;
        }
    }
    assert!(checked > 100, "{checked}");

    let model = d.join("m.json");
    let said = ok(&vt(&[
        "train",
        "--features",
        s(&f),
        "--labels",
        s(&session.join("labels.csv")),
        "--targets",
        "x_mm",
        "--sensor",
        s(&sensor),
        "--ensemble",
        "1",
        "-o",
        s(&model),
    ]));
    assert!(said.contains("displacements in millimetres"), "{said}");
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    let inputs: Vec<&str> = m["feature_columns"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_str().unwrap())
        .collect();
    assert!(
        !inputs.is_empty() && inputs.iter().all(|c| c.ends_with("_mm")),
        "{inputs:?}"
    );

    // From frames with the model's sensor: the same estimates as from the table.
    let (p_table, p_frames) = (d.join("p-table.csv"), d.join("p-frames.csv"));
    ok(&predict(&model, s(&p_table), &["--features", s(&f)]));
    ok(&predict(
        &model,
        s(&p_frames),
        &["--sensor", s(&sensor), s(&session.join("frames"))],
    ));
    assert_eq!(
        std::fs::read_to_string(&p_table).unwrap(),
        std::fs::read_to_string(&p_frames).unwrap()
    );
    // A sensor without a scale cannot measure the model's millimetres.
    let p = d.join("never.csv");
    let bad = fails(&predict(
        &model,
        s(&p),
        &["--sensor", s(&sensor_px), s(&session.join("frames"))],
    ));
    assert!(
        bad.contains("--pitch-mm") && bad.contains(&format!("`{}`", inputs[0])),
        "{bad}"
    );
    assert!(!p.exists());

    // The markers' own displacements in mm as inputs (`--field yes`): from frames too.
    let model = d.join("m-markers.json");
    ok(&vt(&[
        "train",
        "--features",
        s(&f),
        "--labels",
        s(&session.join("labels.csv")),
        "--targets",
        "x_mm",
        "--sensor",
        s(&sensor),
        "--field",
        "yes",
        "--ensemble",
        "1",
        "-o",
        s(&model),
    ]));
    let m = std::fs::read_to_string(&model).unwrap();
    assert!(m.contains("\"m000_dx_mm\"") && m.contains("\"m000_darea_mm2\""));
    assert!(!m.contains("_dx_px\""));
    ok(&predict(&model, s(&p_table), &["--features", s(&f)]));
    ok(&predict(
        &model,
        s(&p_frames),
        &["--sensor", s(&sensor), s(&session.join("frames"))],
    ));
    assert_eq!(
        std::fs::read_to_string(&p_table).unwrap(),
        std::fs::read_to_string(&p_frames).unwrap()
    );
    std::fs::remove_dir_all(&d).unwrap();
}
