//! The pipeline driven as a library, as a Python package, a ROS node or a script would, with
//! no command line: simulate a session, calibrate on its references, extract its features,
//! record a simulated rig with live features, run the live runner into a sink, replay.

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use visuotact_experiments::synth::{simulate, SimKind, SimulateConfig};
use visuotact_io::frames::FrameStream;
use visuotact_io::table::{KeyedTable, TableFormat};
use visuotact_pipeline::calibrate::{calibrate_frames, ReferenceSource};
use visuotact_pipeline::extract::{extract, features_table};
use visuotact_pipeline::record::{record, RecordConfig};
use visuotact_pipeline::runner::{run, RunConfig};
use visuotact_pipeline::sink::{FrameSink, SinkError, SinkFrame};
use visuotact_pipeline::{Estimator, LiveConfig, LiveEstimate, LiveEstimator};
use visuotact_vision::calibration::{Preset, SensorCalibration};
use visuotact_vision::features::FeatureExtractor;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("visuotact-lib-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// A simulated seed-000 session of `touches` random touches and its calibration.
fn session(dir: &Path, touches: usize) -> SensorCalibration {
    let done = simulate(&SimulateConfig {
        sensor: SimKind::Iats,
        protocol: "random".into(),
        output: dir.to_path_buf(),
        touches,
        references: 3,
        ..SimulateConfig::default()
    })
    .unwrap();
    assert_eq!(done.frames, touches);
    let refs = [dir.join("reference")];
    let open = || FrameStream::open(&refs, 25.0);
    let c = calibrate_frames(
        open,
        ReferenceSource::Still,
        &Preset::Iats.config(),
        &mut |_, _| std::ops::ControlFlow::Continue(()),
    )
    .unwrap();
    assert_eq!((c.frames, c.calibration.markers.len()), (3, 117));
    c.calibration
}

#[test]
fn simulate_calibrate_extract_as_a_library() {
    let d = tmp("extract");
    let cal = session(&d, 12);
    let mut ex = FeatureExtractor::new(cal.clone(), cal.features).unwrap();
    let frames = [d.join("frames")];
    let mut warnings = Vec::new();
    let out = d.join("features.csv");
    let done = extract(
        &mut ex,
        &frames,
        25.0,
        (&out, TableFormat::Csv),
        &mut |w: &str| warnings.push(w.to_string()),
    )
    .unwrap();
    assert_eq!((done.written, done.skipped), (12, 0));
    // The table written and the one kept in memory hold the same numbers.
    let written = KeyedTable::read(&out, &["flags"]).unwrap();
    let mut ex = FeatureExtractor::new(cal.clone(), cal.features).unwrap();
    let kept = features_table(&mut ex, &frames, 25.0, &mut |_: &str| {}).unwrap();
    assert_eq!(written.keys, kept.keys);
    let n_lead = visuotact_pipeline::schema::LEAD_COLUMNS.len();
    for (w, k) in written.rows.iter().zip(&kept.rows) {
        for (a, b) in w[n_lead..].iter().zip(k) {
            assert!(
                (a - b).abs() < 1e-9 || (a.is_nan() && b.is_nan()),
                "{a} vs {b}"
            );
        }
    }
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn record_a_simulated_rig_with_live_features() {
    let d = tmp("record");
    let cal = session(&d.join("s"), 1);
    let cfg = RecordConfig {
        output: d.join("rec"),
        source: "sim:iats".into(),
        fps: 200.0,
        max_frames: Some(15),
        references: 2,
        ..RecordConfig::default()
    };
    let est = Estimator::new(Some(cal), None).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let s = record(&cfg, Some(est), &stop, &mut |w| panic!("{w}")).unwrap();
    assert_eq!(s.frames, s.written);
    assert!(s.written + s.dropped >= 15 && s.written > 0, "{s:?}");
    let rows = |name: &str| {
        std::fs::read_to_string(cfg.output.join(name))
            .unwrap()
            .lines()
            .count()
            - 1
    };
    assert_eq!(rows("frames.csv"), s.written);
    assert_eq!(rows("features.csv"), s.written);
    assert_eq!(rows("labels.csv"), s.written);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(cfg.output.join("session.json")).unwrap())
            .unwrap();
    assert_eq!(json["complete"], true);
    // A second run into the same folder is refused unless it resumes.
    let again = record(&cfg, None, &stop, &mut |_| {});
    assert!(again
        .unwrap_err()
        .to_string()
        .contains("already holds a session"));
    std::fs::remove_dir_all(&d).unwrap();
}

/// Keeps every estimate.
#[derive(Default)]
struct Keep(Vec<LiveEstimate>);

impl FrameSink for Keep {
    fn frame(&mut self, f: &SinkFrame<'_>) -> Result<ControlFlow<()>, SinkError> {
        assert!(f.json.unwrap().starts_with('{'));
        self.0.push(f.estimate.unwrap().clone());
        Ok(ControlFlow::Continue(()))
    }
}

/// Contact and health only, on `cal`.
fn live_of(cal: &SensorCalibration) -> LiveEstimator {
    let est = Estimator::new(Some(cal.clone()), None).unwrap();
    LiveEstimator::new(est, Vec::new(), &LiveConfig::default()).unwrap()
}

/// Twenty frames of the simulated membrane's five-frame loop, every one estimated.
fn twenty_unpaced() -> RunConfig {
    RunConfig {
        source: "sim:iats".into(),
        unpaced: true,
        max_frames: Some(20),
        sim_frames: 5,
        ..RunConfig::default()
    }
}

#[test]
fn the_live_runner_feeds_every_frame_to_its_sinks() {
    let d = tmp("live");
    let cal = session(&d, 1);
    let mut live = live_of(&cal);
    let cfg = twenty_unpaced();
    let mut keep = Keep::default();
    let stop = Arc::new(AtomicBool::new(false));
    let summary = run(&mut live, &cfg, &stop, &mut [&mut keep], |w| panic!("{w}")).unwrap();
    // Unpaced: the source waits for the estimator, so every frame is estimated, in order.
    assert_eq!(
        (summary.frames_captured, summary.frames_estimated),
        (20, 20)
    );
    assert_eq!(summary.frames_dropped, 0);
    let idx: Vec<u64> = keep.0.iter().map(|e| e.index).collect();
    assert_eq!(idx, (0..20).collect::<Vec<_>>());
    assert!(keep.0.iter().all(|e| e.health.ok + e.health.lost > 100));
    std::fs::remove_dir_all(&d).unwrap();
}

/// Fails on its `n`th frame with a disk-full error.
struct FailsAt(usize);

impl FrameSink for FailsAt {
    fn frame(&mut self, _: &SinkFrame<'_>) -> Result<ControlFlow<()>, SinkError> {
        self.0 -= 1;
        if self.0 == 0 {
            return Err(std::io::Error::new(std::io::ErrorKind::StorageFull, "disk full").into());
        }
        Ok(ControlFlow::Continue(()))
    }
}

/// A sink's failure stops the run at that frame and is the run's error; the other sinks heard
/// every frame up to it. A recording's sink hears each frame it writes, its rows and its
/// estimate, and its failure ends the recording with the frames written kept.
#[test]
fn a_failing_sink_stops_the_loop_with_its_error() {
    let d = tmp("failing-sink");
    let cal = session(&d, 6);
    let cfg = twenty_unpaced();
    let (mut keep, mut fails) = (Keep::default(), FailsAt(7));
    let stop = Arc::new(AtomicBool::new(false));
    let err = run(
        &mut live_of(&cal),
        &cfg,
        &stop,
        &mut [&mut keep, &mut fails],
        |_| {},
    )
    .unwrap_err()
    .to_string();
    assert_eq!(err, "disk full");
    assert_eq!(keep.0.len(), 7);
    /// Keeps what a recording tells.
    #[derive(Default)]
    struct Rows(Vec<(String, usize, bool)>);
    impl FrameSink for Rows {
        fn frame(&mut self, f: &SinkFrame<'_>) -> Result<ControlFlow<()>, SinkError> {
            let width = f.rows.and_then(|r| r.features).map_or(0, |(c, v)| {
                assert_eq!(c.len(), v.len());
                v.len()
            });
            self.0.push((f.id.to_string(), width, f.estimate.is_some()));
            if self.0.len() == 4 {
                return Err(SinkError::other(std::io::Error::other("bag closed")));
            }
            Ok(ControlFlow::Continue(()))
        }
    }
    let rows = Arc::new(std::sync::Mutex::new(Rows::default()));
    let rec = RecordConfig {
        source: d
            .join("frames")
            .into_os_string()
            .into_string()
            .unwrap()
            .into(),
        output: d.join("recorded"),
        ..RecordConfig::default()
    };
    let est = Estimator::new(Some(cal.clone()), None).unwrap();
    let shared: visuotact_pipeline::sink::SharedSink = rows.clone();
    // The run above set its stop flag when its sink failed.
    let stop = Arc::new(AtomicBool::new(false));
    let err = visuotact_pipeline::record::record_observed(
        &rec,
        Some(est),
        &stop,
        &mut |_| {},
        Some(shared),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("bag closed"), "{err}");
    let told = &rows.lock().unwrap().0;
    assert_eq!(told.len(), 4);
    assert!(
        told.iter()
            .all(|(_, width, estimated)| *width > 100 && *estimated),
        "{told:?}"
    );
    let kept = std::fs::read_to_string(d.join("recorded").join("features.csv")).unwrap();
    assert_eq!(kept.lines().count(), 1 + 4, "the frames written stay");
    std::fs::remove_dir_all(&d).unwrap();
}
